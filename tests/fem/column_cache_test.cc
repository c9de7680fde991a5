// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#include "spidarcad/fem/column_cache.h"

#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <memory>
#include <new>
#include <random>
#include <string>
#include <thread>
#include <utility>
#include <vector>

#include "spidarcad/fem/condensation.h"
#include "spidarcad/fem/substructure.h"

// Allocation counter for the calling thread only (the cache's worker thread allocates freely).
// fem_tests already replaces malloc (condensation_test.cc) with a counter private to that file,
// so this one counts operator new; the code under test holds no dynamic Eigen temporaries
// (which would go to malloc directly).
namespace {
thread_local bool t_count_new = false;
thread_local long t_new_count = 0;
void* CountedNew(std::size_t n) {
  if (t_count_new) ++t_new_count;
  if (void* p = std::malloc(n ? n : 1)) return p;
  throw std::bad_alloc();
}
}  // namespace

// The whole unaligned set, nothrow forms included: under AddressSanitizer a form left out is the
// sanitizer's own, and a block from its nothrow new (std::stable_sort's buffer) freed by the
// delete below is reported as an alloc-dealloc mismatch.
void* operator new(std::size_t n) { return CountedNew(n); }
void* operator new[](std::size_t n) { return CountedNew(n); }
void* operator new(std::size_t n, const std::nothrow_t&) noexcept {
  try {
    return CountedNew(n);
  } catch (const std::bad_alloc&) {
    return nullptr;
  }
}
void* operator new[](std::size_t n, const std::nothrow_t& tag) noexcept {
  return operator new(n, tag);
}
void operator delete(void* p) noexcept { std::free(p); }
void operator delete[](void* p) noexcept { std::free(p); }
void operator delete(void* p, std::size_t) noexcept { std::free(p); }
void operator delete[](void* p, std::size_t) noexcept { std::free(p); }
void operator delete(void* p, const std::nothrow_t&) noexcept { std::free(p); }
void operator delete[](void* p, const std::nothrow_t&) noexcept { std::free(p); }

namespace spidarcad::fem {
namespace {

const Material kMaterial{5.0e7, 0.35};

// A block clamped at x = 0 with a baseline point load; outputs: the surface; candidates: the
// top face (z = h). Eager compliance of the candidates for reference.
struct Scene {
  TetMesh mesh;
  MaterialTable materials{kMaterial};
  std::unique_ptr<BoundaryConditions> bcs;
  std::unique_ptr<StaticSolver> solver;
  std::unique_ptr<Compliance> eager;
  std::vector<int> outputs, candidates;

  Scene(double length, int nx, int nyz) {
    BoxMeshSettings s;
    s.upper = Eigen::Vector3d(length, 0.1, 0.1);
    s.nx = nx;
    s.ny = s.nz = nyz;
    mesh = MakeBoxMesh(s);
    bcs = std::make_unique<BoundaryConditions>(mesh.num_nodes());
    FixNodesInBox(mesh, Eigen::Vector3d(-1, -1, -1), Eigen::Vector3d(1e-9, 1, 1), bcs.get());
    bcs->AddPointLoad(
        NodesInBox(mesh, Eigen::Vector3d(length, 0, 0), Eigen::Vector3d(length, 0, 0)).at(0),
        Eigen::Vector3d(0.0, 3.0, -2.0));
    solver = std::make_unique<StaticSolver>(mesh, materials, *bcs);
    outputs = ExtractSurface(mesh).nodes;
    candidates = NodesInBox(mesh, Eigen::Vector3d(-1, -1, 0.1), Eigen::Vector3d(1, 1, 1));
    // The eager reference is computed before any cache exists (one solver user at a time).
    eager = std::make_unique<Compliance>(*solver, outputs, candidates);
  }
  double BytesPerNode(ColumnPrecision p) const { return 9.0 * outputs.size() * BytesPerValue(p); }
  Eigen::Vector3d Position(int b) const { return mesh.nodes.row(candidates[b]).transpose(); }
};

double MaxAbs(const Eigen::MatrixXd& m) { return m.cwiseAbs().maxCoeff(); }

// Largest |cache − eager| over the pinned columns of candidate b, and the largest violation
// of |cache − eager| <= rel·|eager| + tiny.
void CompareColumns(ColumnCache* cache, const Compliance& eager, int b, double* max_diff,
                    double* worst_ratio) {
  ASSERT_TRUE(cache->Pin(b)) << "candidate " << b;
  for (int j = 0; j < 3; ++j)
    for (int r = 0; r < 3 * cache->num_outputs(); ++r) {
      const double g = eager.matrix()(r, 3 * b + j), v = cache->Value(r, b, j);
      *max_diff = std::max(*max_diff, std::abs(v - g));
      if (g != 0.0)
        *worst_ratio = std::max(*worst_ratio, std::abs(v - g) / std::abs(g));
      else
        *worst_ratio = std::max(*worst_ratio, v == 0.0 ? 0.0 : 1.0);
    }
  cache->Unpin(b);
}

TEST(ColumnCache, LazyColumnsEqualEagerComplianceWhenStoredInDouble) {
  const Scene scene(0.2, 4, 2);
  ColumnCacheSettings settings;
  settings.block_nodes = 3;
  ColumnCache cache(*scene.solver, scene.mesh.nodes, scene.outputs, scene.candidates, settings);
  EXPECT_EQ(cache.ready_nodes(), 0);  // nothing is computed before a request
  cache.RequestNear(Eigen::Vector3d(0.1, 0.05, 0.1), 1.0);
  ASSERT_TRUE(cache.WaitUntilIdle(30.0));
  const double scale = MaxAbs(scene.eager->matrix());
  double diff = 0.0, ratio = 0.0;
  int free_nodes = 0;
  for (int b = 0; b < cache.num_candidates(); ++b) {
    EXPECT_EQ(cache.IsFixed(b), scene.eager->IsFixed(b));
    if (cache.IsFixed(b)) {
      EXPECT_FALSE(cache.IsReady(b)) << "a constrained node is never condensed";
      continue;
    }
    ++free_nodes;
    CompareColumns(&cache, *scene.eager, b, &diff, &ratio);
  }
  EXPECT_EQ(cache.ready_nodes(), free_nodes);
  EXPECT_LT(diff, 1e-12 * scale);
  EXPECT_LT((cache.baseline() - scene.eager->baseline()).norm(),
            1e-12 * scene.eager->baseline().norm());
  EXPECT_EQ(cache.stats().computed_nodes, free_nodes);
}

TEST(ColumnCache, FloatColumnsAreWithinHalfAnUlpAndHalveTheMemory) {
  const Scene scene(0.2, 4, 2);
  ColumnCacheSettings settings;
  settings.precision = ColumnPrecision::kFloat;
  settings.start_worker = false;
  ColumnCache cache(*scene.solver, scene.mesh.nodes, scene.outputs, scene.candidates, settings);
  std::vector<int> all(cache.num_candidates());
  for (int b = 0; b < cache.num_candidates(); ++b) all[b] = b;
  cache.ComputeNodes(all);
  double diff = 0.0, ratio = 0.0;
  for (int b = 0; b < cache.num_candidates(); ++b)
    if (!cache.IsFixed(b)) CompareColumns(&cache, *scene.eager, b, &diff, &ratio);
  // Round to nearest: relative error at most 2^-24 per entry (no entry is subnormal here).
  EXPECT_LE(ratio, std::ldexp(1.0, -24));
  EXPECT_GT(ratio, 0.0);  // it did round
  EXPECT_DOUBLE_EQ(cache.BytesPerNode(), scene.BytesPerNode(ColumnPrecision::kFloat));
  EXPECT_DOUBLE_EQ(2.0 * cache.BytesPerNode(), scene.BytesPerNode(ColumnPrecision::kDouble));

  // Contact forces for 4 pushed nodes from float columns against the eager double solve.
  ContactSolver exact(*scene.eager, 4);
  CachedContactSolver approx(&cache, 4);
  std::vector<double> target, f_exact(12), f_float(12);
  int added = 0;
  for (int b = 0; b < cache.num_candidates() && added < 4; ++b) {
    if (cache.IsFixed(b) || b % 2) continue;
    ASSERT_EQ(exact.Add(b), ContactStatus::kOk);
    ASSERT_EQ(approx.Add(b), CachedContactStatus::kOk);
    for (int i = 0; i < 3; ++i) target.push_back(i == 2 ? -1e-4 : 2e-5 * added);
    ++added;
  }
  ASSERT_TRUE(exact.Solve(target.data(), f_exact.data()));
  ASSERT_TRUE(approx.Solve(target.data(), f_float.data()));
  const Eigen::Map<Eigen::VectorXd> fe(f_exact.data(), 12), ff(f_float.data(), 12);
  // Measured ~1e-7; the bound is cond(G_cc)·2^-24 with a margin.
  EXPECT_LT((fe - ff).norm(), 1e-5 * fe.norm());
}

TEST(ColumnCache, ComputesTheNodesNearestTheFocusFirst) {
  const Scene scene(0.4, 8, 2);
  ColumnCacheSettings settings;
  settings.block_nodes = 4;
  ColumnCache cache(*scene.solver, scene.mesh.nodes, scene.outputs, scene.candidates, settings);
  const Eigen::Vector3d focus(0.4, 0.0, 0.1);
  cache.RequestNear(focus, 0.25);
  ASSERT_TRUE(cache.WaitUntilIdle(30.0));
  int inside = 0, compared = 0;
  for (int a = 0; a < cache.num_candidates(); ++a) {
    if (cache.IsFixed(a)) continue;
    const double da = (scene.Position(a) - focus).norm();
    EXPECT_EQ(cache.IsReady(a), da <= 0.25) << "candidate " << a << " at " << da << " m";
    if (!cache.IsReady(a)) continue;
    ++inside;
    for (int b = 0; b < cache.num_candidates(); ++b) {
      if (!cache.IsReady(b)) continue;
      const double db = (scene.Position(b) - focus).norm();
      if (da < db - 1e-12) {
        EXPECT_LE(cache.ReadyBlock(a), cache.ReadyBlock(b)) << a << " (" << da << " m) vs " << b;
        ++compared;
      }
    }
  }
  EXPECT_GT(inside, 8);
  EXPECT_GT(compared, 20);
  EXPECT_GE(cache.stats().blocks, 3);
}

// A smaller first block: the nearest nodes come first in a block of their own, the rest in
// blocks of block_nodes; a negative size is refused, naming the field.
TEST(ColumnCache, FirstBlockHoldsTheFirstBlockNodesNearestTheFocus) {
  const Scene scene(0.4, 8, 2);
  ColumnCacheSettings settings;
  settings.block_nodes = 6;
  settings.first_block_nodes = 2;
  settings.start_worker = false;
  ColumnCache cache(*scene.solver, scene.mesh.nodes, scene.outputs, scene.candidates, settings);
  const Eigen::Vector3d focus(0.4, 0.0, 0.1);
  cache.RequestNear(focus, 0.25);
  cache.Start();
  ASSERT_TRUE(cache.WaitUntilIdle(30.0));
  std::vector<std::pair<double, int>> ready;  // (distance, candidate)
  for (int b = 0; b < cache.num_candidates(); ++b)
    if (cache.IsReady(b)) ready.emplace_back((scene.Position(b) - focus).norm(), b);
  std::sort(ready.begin(), ready.end());
  ASSERT_GT(ready.size(), 8u);
  const long first = cache.ReadyBlock(ready[0].second);
  EXPECT_EQ(cache.ReadyBlock(ready[1].second), first);
  EXPECT_GT(cache.ReadyBlock(ready[2].second), first) << "the third nearest is in the next block";
  int in_second = 0;
  for (const auto& [d, b] : ready) in_second += cache.ReadyBlock(b) == first + 1;
  EXPECT_EQ(in_second, 6);
  settings.first_block_nodes = -1;
  try {
    ColumnCache bad(*scene.solver, scene.mesh.nodes, scene.outputs, scene.candidates, settings);
    ADD_FAILURE() << "a negative first block was taken";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("first_block_nodes >= 0 (got -1)"), std::string::npos)
        << e.what();
  }
}

// A paused worker computes nothing more (and counts as idle); let go, it carries on.
// Neighbour lists made on the worker: none until it has run (a scan finds the nearest ready
// node, a shift stays on r), then the same lists as a cache that made them at construction.
TEST(ColumnCache, NeighbourListsMadeOnTheWorkerEqualThoseMadeAtConstruction) {
  const Scene scene(0.4, 8, 2);
  ColumnCacheSettings settings;
  settings.start_worker = false;
  const ColumnCache eager(*scene.solver, scene.mesh.nodes, scene.outputs, scene.candidates,
                          settings);
  settings.neighbours_on_worker = true;
  ColumnCache lazy(*scene.solver, scene.mesh.nodes, scene.outputs, scene.candidates, settings);
  EXPECT_LT(lazy.MemoryBytes(), eager.MemoryBytes());
  const int n = lazy.num_candidates();
  int free_a = -1, free_b = -1;
  for (int b = 0; b < n && free_b < 0; ++b)
    if (!lazy.IsFixed(b)) (free_a < 0 ? free_a : free_b) = b;
  ASSERT_GE(free_b, 0);
  EXPECT_EQ(lazy.ShiftedCandidate(free_a, free_b, free_b), free_b);
  EXPECT_EQ(lazy.ReadyNodeNearest(free_a), -1);
  lazy.RequestNear(Eigen::Vector3d(0.4, 0.0, 0.1), 0.1);
  lazy.Start();
  ASSERT_TRUE(lazy.WaitUntilIdle(30.0));
  lazy.Stop();
  EXPECT_GT(lazy.ready_nodes(), 0);
  int differ = 0, shifted = 0;
  for (int a = 0; a < n; a += 3)
    for (int b = 1; b < n; b += 7) {
      const int r = (a + b) % n;
      const int s = lazy.ShiftedCandidate(a, b, r);
      differ += s != eager.ShiftedCandidate(a, b, r);
      shifted += s != r;
    }
  EXPECT_EQ(differ, 0);
  EXPECT_GT(shifted, 0);
}

// A SubstructuredSolver whose CompleteSolveFree waits until the test opens the gate: the state
// between the two passes of near_rows_first can be looked at.
class GatedSolver final : public FreeDofSolver {
 public:
  explicit GatedSolver(const SubstructuredSolver& s) : s_(s) {}
  const SolveStatus& factor_status() const override { return s_.factor_status(); }
  const BoundaryConditions& bcs() const override { return s_.bcs(); }
  int FreeIndex(int dof) const override { return s_.FreeIndex(dof); }
  int num_free() const override { return s_.num_free(); }
  SolveStatus SolveFree(const Eigen::MatrixXd& rhs, Eigen::MatrixXd* x) const override {
    return s_.SolveFree(rhs, x);
  }
  StaticSolution Solve() const override { return s_.Solve(); }
  int num_row_groups() const override { return s_.num_row_groups(); }
  int RowGroupOfNode(int v) const override { return s_.RowGroupOfNode(v); }
  SolveStatus SolveFreeInGroups(const Eigen::MatrixXd& rhs, const std::vector<int>& groups,
                                Eigen::MatrixXd* x) const override {
    return s_.SolveFreeInGroups(rhs, groups, x);
  }
  SolveStatus CompleteSolveFree(const Eigen::MatrixXd& rhs, const std::vector<int>& groups,
                                Eigen::MatrixXd* x) const override {
    waiting.store(true);
    while (!open.load()) std::this_thread::sleep_for(std::chrono::milliseconds(1));
    return s_.CompleteSolveFree(rhs, groups, x);
  }
  mutable std::atomic<bool> waiting{false}, open{false};

 private:
  const SubstructuredSolver& s_;
};

// Near rows first, on the block in 4 slabs felt in the last: between the passes the first block's
// columns are published with the rows of the last slab and the interface, which a contact solve
// uses on its own columns, while the far rows read NaN and are skipped by AddColumn; completed,
// every column equals the one computed whole, bit for bit.
TEST(ColumnCache, NearRowsFirstPublishesTheFocusSlabsRowsThenTheWholeColumn) {
  const Scene scene(0.4, 8, 2);
  const SubstructuredSolver slabs(scene.mesh, scene.materials, *scene.bcs,
                                  SlabBlocks(scene.mesh, 0, EvenPlanes(scene.mesh, 0, 4)));
  ASSERT_TRUE(slabs.factor_status().converged);
  const GatedSolver gated(slabs);
  ColumnCacheSettings settings;
  settings.start_worker = false;
  settings.first_block_nodes = 4;
  settings.near_rows_first = true;
  ColumnCache cache(gated, scene.mesh.nodes, scene.outputs, scene.candidates, settings);
  const Eigen::Vector3d focus(0.4, 0.05, 0.1);
  cache.RequestNear(focus, 0.06);  // top nodes at x = 0.35 and 0.4: inside the last slab
  cache.Start();
  const auto give_up = std::chrono::steady_clock::now() + std::chrono::seconds(60);
  while (!gated.waiting.load() && std::chrono::steady_clock::now() < give_up)
    std::this_thread::sleep_for(std::chrono::milliseconds(1));
  ASSERT_TRUE(gated.waiting.load());
  std::vector<int> near;
  for (int b = 0; b < cache.num_candidates(); ++b)
    if (cache.HasColumn(b)) near.push_back(b);
  ASSERT_EQ(near.size(), 4u);
  EXPECT_EQ(cache.ready_nodes(), 0);
  int near_rows = 0, far_rows = 0, free_rows = 0;
  for (int b : near) {
    EXPECT_FALSE(cache.IsReady(b));
    EXPECT_EQ(slabs.BlockOfNode(cache.candidate_node(b)), 3);
    ASSERT_TRUE(cache.Pin(b));
    for (int a = 0; a < cache.num_outputs(); ++a) {
      const int g = slabs.BlockOfNode(scene.outputs[a]);
      const bool ready = cache.RowReady(a, b);
      EXPECT_EQ(ready, g == 3 || g == -1) << "output " << a << " in slab " << g;
      (g == -1 ? free_rows : ready ? near_rows : far_rows)++;
      for (int j = 0; j < 3; ++j)
        EXPECT_EQ(std::isnan(cache.Value(3 * a, b, j)), !ready) << "output " << a;
    }
    Eigen::VectorXd u = Eigen::VectorXd::Zero(3 * cache.num_outputs());
    cache.AddColumn(b, 2, 1.0, u.data());
    EXPECT_TRUE(u.allFinite());
    cache.Unpin(b);
  }
  EXPECT_GT(near_rows, 0);
  EXPECT_GT(far_rows, 0);
  EXPECT_GT(free_rows, 0);
  // A contact solve on the near rows: every node on its own column.
  Eigen::MatrixXd felt;
  {
    CachedContactSolver contacts(&cache, 4);
    for (int b : near) ASSERT_EQ(contacts.Add(b), CachedContactStatus::kOk);
    EXPECT_EQ(contacts.num_substituted(), 0);
    felt = contacts.ContactBlock();
    EXPECT_TRUE(felt.allFinite());
    Eigen::VectorXd u(3 * cache.num_outputs());
    const std::vector<double> forces(12, 0.5);
    contacts.OutputDisplacement(forces.data(), &u);
    EXPECT_TRUE(u.allFinite());
  }
  gated.open.store(true);
  ASSERT_TRUE(cache.WaitUntilIdle(60.0));
  cache.Stop();
  {
    CachedContactSolver contacts(&cache, 4);
    for (int b : near) ASSERT_EQ(contacts.Add(b), CachedContactStatus::kOk);
    EXPECT_EQ(contacts.ContactBlock(), felt);  // the near rows were final
  }
  // Whole columns, equal to those of a cache that solves them whole (in other blocks of
  // right-hand sides: to rounding).
  settings.near_rows_first = false;
  ColumnCache whole(slabs, scene.mesh.nodes, scene.outputs, scene.candidates, settings);
  std::vector<int> ready;
  for (int b = 0; b < cache.num_candidates(); ++b)
    if (cache.HasColumn(b)) {
      EXPECT_TRUE(cache.IsReady(b));
      ready.push_back(b);
    }
  EXPECT_EQ(cache.ready_nodes(), static_cast<int>(ready.size()));
  ASSERT_EQ(whole.ComputeNodes(ready), static_cast<int>(ready.size()));
  for (int b : ready) {
    ASSERT_TRUE(cache.Pin(b));
    ASSERT_TRUE(whole.Pin(b));
    double scale = 0.0, diff = 0.0;
    for (int j = 0; j < 3; ++j)
      for (int r = 0; r < 3 * cache.num_outputs(); ++r) {
        scale = std::max(scale, std::abs(whole.Value(r, b, j)));
        diff = std::max(diff, std::abs(cache.Value(r, b, j) - whole.Value(r, b, j)));
      }
    EXPECT_LE(diff, 1e-12 * scale) << "candidate " << b;
    cache.Unpin(b);
    whole.Unpin(b);
  }
}

TEST(ColumnCache, PausedWorkerComputesNothingUntilLetGo) {
  const Scene scene(0.4, 8, 2);
  ColumnCacheSettings settings;
  settings.block_nodes = 2;
  ColumnCache cache(*scene.solver, scene.mesh.nodes, scene.outputs, scene.candidates, settings);
  cache.SetPaused(true);
  EXPECT_TRUE(cache.paused());
  cache.RequestNear(Eigen::Vector3d(0.4, 0.0, 0.1), 0.25);
  std::this_thread::sleep_for(std::chrono::milliseconds(50));
  EXPECT_TRUE(cache.WaitUntilIdle(5.0));
  EXPECT_EQ(cache.ready_nodes(), 0);
  cache.SetPaused(false);
  ASSERT_TRUE(cache.WaitUntilIdle(30.0));
  EXPECT_GT(cache.ready_nodes(), 8);
}

TEST(ColumnCache, EvictsFarColumnsToStayWithinTheMemoryBoundButNeverPinnedOnes) {
  const Scene scene(0.4, 8, 2);
  ColumnCacheSettings settings;
  settings.block_nodes = 3;
  settings.memory_budget_bytes = 10.5 * scene.BytesPerNode(ColumnPrecision::kDouble);
  ColumnCache cache(*scene.solver, scene.mesh.nodes, scene.outputs, scene.candidates, settings);
  ASSERT_EQ(cache.capacity_nodes(), 10);
  const Eigen::Vector3d a(0.0, 0.05, 0.1), b(0.4, 0.05, 0.1);
  auto distance_rank_limit = [&](const Eigen::Vector3d& p) {  // 10th smallest distance
    std::vector<double> d;
    for (int c = 0; c < cache.num_candidates(); ++c)
      if (!cache.IsFixed(c)) d.push_back((scene.Position(c) - p).norm());
    std::sort(d.begin(), d.end());
    return d[9];
  };
  cache.RequestNear(a, 1.0);
  ASSERT_TRUE(cache.WaitUntilIdle(30.0));
  EXPECT_EQ(cache.ready_nodes(), 10);
  const double limit_a = distance_rank_limit(a);
  int pinned = -1;
  for (int c = 0; c < cache.num_candidates(); ++c) {
    if (!cache.IsReady(c)) continue;
    EXPECT_LE((scene.Position(c) - a).norm(), limit_a + 1e-12);
    if (pinned < 0) pinned = c;
  }
  ASSERT_GE(pinned, 0);
  ASSERT_TRUE(cache.Pin(pinned));
  EXPECT_LE(cache.capacity_nodes() * cache.BytesPerNode(), settings.memory_budget_bytes);

  cache.RequestNear(b, 1.0);
  ASSERT_TRUE(cache.WaitUntilIdle(30.0));
  EXPECT_TRUE(cache.IsReady(pinned)) << "a pinned column was evicted";
  double diff = 0.0, ratio = 0.0;
  CompareColumns(&cache, *scene.eager, pinned, &diff, &ratio);  // its data is intact
  EXPECT_LT(diff, 1e-12 * MaxAbs(scene.eager->matrix()));
  cache.Unpin(pinned);
  EXPECT_EQ(cache.ready_nodes(), 10);
  EXPECT_GE(cache.stats().evictions, 9);
  const double limit_b = distance_rank_limit(b);
  for (int c = 0; c < cache.num_candidates(); ++c)
    if (cache.IsReady(c) && c != pinned) {
      EXPECT_LE((scene.Position(c) - b).norm(), limit_b + 1e-12);
    }
  // Allocated column storage never exceeds the bound.
  EXPECT_LE(cache.MemoryBytes() - 8.0 * cache.baseline().size(),
            settings.memory_budget_bytes + 0.1 * scene.BytesPerNode(ColumnPrecision::kDouble) +
                64.0 * 1024);
}

// A reader thread pins, reads and unpins columns while the worker keeps evicting and
// recomputing them (a focus that jumps between the two ends of a bar, memory for 4 nodes):
// every pinned read equals the eager column to 1e-12 (no torn or reused slot is ever read).
TEST(ColumnCache, PinnedReadsAreNeverTornWhileTheWorkerEvicts) {
  const Scene scene(0.4, 8, 2);
  ColumnCacheSettings settings;
  settings.block_nodes = 2;
  settings.memory_budget_bytes = 4.5 * scene.BytesPerNode(ColumnPrecision::kDouble);
  ColumnCache cache(*scene.solver, scene.mesh.nodes, scene.outputs, scene.candidates, settings);
  const double scale = MaxAbs(scene.eager->matrix());
  std::atomic<bool> done{false};
  std::atomic<long> reads{0}, mismatches{0};
  std::thread reader([&] {
    std::mt19937 rng(3);
    while (!done.load()) {
      const int b = static_cast<int>(rng() % cache.num_candidates());
      if (!cache.Pin(b)) continue;
      for (int j = 0; j < 3; ++j)
        for (int r = 0; r < 3 * cache.num_outputs(); r += 7)
          if (std::abs(cache.Value(r, b, j) - scene.eager->matrix()(r, 3 * b + j)) > 1e-12 * scale)
            mismatches.fetch_add(1);
      cache.Unpin(b);
      reads.fetch_add(1);
    }
  });
  for (int round = 0; round < 30; ++round) {
    cache.RequestNear(Eigen::Vector3d(round % 2 ? 0.4 : 0.0, 0.05, 0.1), 1.0);
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
  }
  ASSERT_TRUE(cache.WaitUntilIdle(30.0));
  done.store(true);
  reader.join();
  EXPECT_EQ(mismatches.load(), 0);
  EXPECT_GT(reads.load(), 0);
  EXPECT_GT(cache.stats().evictions, 0);
  EXPECT_LE(cache.ready_nodes(), 4);
}

TEST(CachedContactSolver, EqualsTheEagerContactSolverWhenEveryColumnIsReady) {
  const Scene scene(0.2, 4, 2);
  ColumnCacheSettings settings;
  settings.start_worker = false;
  ColumnCache cache(*scene.solver, scene.mesh.nodes, scene.outputs, scene.candidates, settings);
  std::vector<int> all(cache.num_candidates());
  for (int b = 0; b < cache.num_candidates(); ++b) all[b] = b;
  cache.ComputeNodes(all);
  ContactSolver exact(*scene.eager, 8);
  CachedContactSolver lazy(&cache, 8);
  std::vector<int> free;
  for (int b = 0; b < cache.num_candidates(); ++b)
    if (!cache.IsFixed(b)) free.push_back(b);
  std::mt19937 rng(7);
  std::vector<double> target(24), fe(24), fl(24);
  Eigen::VectorXd ue(3 * scene.outputs.size()), ul(ue.size());
  for (int step = 0; step < 40; ++step) {
    const int b = free[rng() % free.size()];
    if (exact.SlotOf(b) >= 0) {
      ASSERT_EQ(exact.Remove(b), ContactStatus::kOk);
      ASSERT_EQ(lazy.Remove(b), CachedContactStatus::kOk);
    } else if (exact.num_contacts() < 8) {
      ASSERT_EQ(exact.Add(b), ContactStatus::kOk);
      ASSERT_EQ(lazy.Add(b), CachedContactStatus::kOk);
    }
    if (exact.num_contacts() == 0) continue;
    for (int i = 0; i < 3 * exact.num_contacts(); ++i) target[i] = 1e-5 * ((i * 7 + step) % 11 - 5);
    ASSERT_TRUE(exact.Solve(target.data(), fe.data()));
    ASSERT_TRUE(lazy.Solve(target.data(), fl.data()));
    const int n = 3 * exact.num_contacts();
    const Eigen::Map<Eigen::VectorXd> a(fe.data(), n), c(fl.data(), n);
    EXPECT_LT((a - c).norm(), 1e-10 * a.norm()) << "step " << step;
    exact.OutputDisplacement(fe.data(), &ue);
    lazy.OutputDisplacement(fl.data(), &ul);
    EXPECT_LT((ue - ul).norm(), 1e-10 * ue.norm());
    EXPECT_EQ(lazy.num_substituted(), 0);
  }
}

// Single push at node b of the cantilever top face with the column of a node h cells away
// standing in for b's: force error against the exact G_bb⁻¹ d.
TEST(CachedContactSolver, FallbackErrorIsBoundedAndShrinksAsTheReadyNeighbourGetsCloser) {
  const Scene scene(0.4, 16, 4);  // cells of 25 mm
  ColumnCacheSettings settings;
  settings.start_worker = false;
  ColumnCache cache(*scene.solver, scene.mesh.nodes, scene.outputs, scene.candidates, settings);
  auto node_at = [&](double x) {
    return cache.CandidateOfNode(NodesInBox(scene.mesh,
                                            Eigen::Vector3d(x - 1e-9, 0.05 - 1e-9, 0.1 - 1e-9),
                                            Eigen::Vector3d(x + 1e-9, 0.05 + 1e-9, 0.1 + 1e-9))
                                     .at(0));
  };
  const int b = node_at(0.2);
  const Eigen::Vector3d d(0.0, 0.0, -1e-4);
  const int row = cache.OutputIndexOfCandidate(b);
  const Eigen::Vector3d rhs = d - scene.eager->baseline().segment<3>(3 * row);
  const Eigen::Vector3d f_exact = scene.eager->Block(b, b).llt().solve(rhs);
  std::vector<double> errors;
  for (int cells : {4, 2, 1, 0}) {
    cache.EvictAll();
    const int r = node_at(0.2 + 0.025 * cells);
    ASSERT_EQ(cache.ComputeNodes({r}), 1);
    CachedContactSolver contact(&cache, 2);
    ASSERT_EQ(contact.Add(b), CachedContactStatus::kOk);
    EXPECT_EQ(contact.substitute(0), r);
    double f[3];
    const double target[3] = {d.x(), d.y(), d.z()};
    ASSERT_TRUE(contact.Solve(target, f));
    errors.push_back((Eigen::Vector3d(f[0], f[1], f[2]) - f_exact).norm() / f_exact.norm());
  }
  // errors for 4, 2, 1, 0 cells: strictly decreasing, exact at 0, modest at one cell.
  EXPECT_GT(errors[0], errors[1]);
  EXPECT_GT(errors[1], errors[2]);
  EXPECT_LT(errors[3], 1e-10);
  EXPECT_LT(errors[2], 0.25) << "one cell away";
  EXPECT_LT(errors[0], 1.0) << "four cells away";
  ::testing::Test::RecordProperty("fallback_error_1_cell", std::to_string(errors[2]));
  std::printf("fallback force error at 4, 2, 1, 0 cells: %.4f %.4f %.4f %.2g\n", errors[0],
              errors[1], errors[2], errors[3]);
}

TEST(CachedContactSolver, RefreshSwitchesToTheExactColumnOnceReadyAndKeepsTheFactorConsistent) {
  const Scene scene(0.4, 8, 2);
  ColumnCacheSettings settings;
  settings.start_worker = false;
  ColumnCache cache(*scene.solver, scene.mesh.nodes, scene.outputs, scene.candidates, settings);
  std::vector<int> free;
  for (int b = 0; b < cache.num_candidates(); ++b)
    if (!cache.IsFixed(b)) free.push_back(b);
  // Only every third free node is ready: the others borrow a neighbour's column.
  std::vector<int> some;
  for (size_t i = 0; i < free.size(); i += 3) some.push_back(free[i]);
  cache.ComputeNodes(some);
  CachedContactSolver lazy(&cache, 6);
  const std::vector<int> contacts = {free[1], free[4], free[8], free[9], free[13]};
  // With substitutes Ĝ_cc need not be positive definite: a refused node is simply not added.
  for (int b : contacts) {
    const CachedContactStatus st = lazy.Add(b);
    EXPECT_TRUE(st == CachedContactStatus::kOk || st == CachedContactStatus::kNotPositiveDefinite);
  }
  ASSERT_GE(lazy.num_contacts(), 3);
  EXPECT_GT(lazy.num_substituted(), 0);
  // The incremental factor represents the (approximate) block: L Lᵀ = Ĝ_cc.
  auto check_factor = [&] {
    const int n = 3 * lazy.num_contacts();
    const Eigen::MatrixXd g = lazy.ContactBlock();
    Eigen::MatrixXd l = Eigen::MatrixXd::Zero(n, n);
    // Read the factor through solves: Ĝ_cc f = e_i must give f = Ĝ_cc⁻¹ e_i.
    std::vector<double> t(n), f(n);
    for (int i = 0; i < n; ++i) {
      std::fill(t.begin(), t.end(), 0.0);
      for (int s = 0; s < lazy.num_contacts(); ++s)
        for (int a = 0; a < 3; ++a)
          t[3 * s + a] = cache.baseline()(3 * cache.OutputIndexOfCandidate(lazy.contact(s)) + a);
      t[i] += 1e-4;
      ASSERT_TRUE(lazy.Solve(t.data(), f.data()));
      l.col(i) = Eigen::Map<Eigen::VectorXd>(f.data(), n);
    }
    EXPECT_LT((g * l - 1e-4 * Eigen::MatrixXd::Identity(n, n)).norm(), 1e-9 * 1e-4 * std::sqrt(n));
  };
  check_factor();
  ASSERT_EQ(lazy.Remove(lazy.contact(1)), CachedContactStatus::kOk);
  check_factor();
  cache.ComputeNodes(free);  // everything ready now
  EXPECT_GT(lazy.Refresh(), 0);
  EXPECT_EQ(lazy.num_substituted(), 0);
  check_factor();
  // Now exactly the eager contact solve.
  ContactSolver exact(*scene.eager, 6);
  for (int s = 0; s < lazy.num_contacts(); ++s)
    ASSERT_EQ(exact.Add(lazy.contact(s)), ContactStatus::kOk);
  std::vector<double> target(3 * lazy.num_contacts(), -5e-5), fe(target.size()), fl(target.size());
  exact.Solve(target.data(), fe.data());
  lazy.Solve(target.data(), fl.data());
  const Eigen::Map<Eigen::VectorXd> a(fe.data(), fe.size()), c(fl.data(), fl.size());
  EXPECT_LT((a - c).norm(), 1e-10 * a.norm());
}

// Frictionless contact: SolveNormal's forces must lie along the normals and the displacements
// they cause, read back through the columns themselves (OutputDisplacement, exact columns) or
// through the dense block the factor stands for (ContactBlock, substituted columns), must reach
// each target along its normal. Together these fix the solution uniquely (Ĝ_cc is SPD).
TEST(CachedContactSolver, SolveNormalGivesNormalForcesThatReachTheTargetsAlongTheNormals) {
  const Scene scene(0.4, 8, 2);
  ColumnCacheSettings settings;
  settings.start_worker = false;
  for (const bool all_ready : {true, false}) {
    SCOPED_TRACE(all_ready ? "every column ready" : "every third column ready");
    ColumnCache cache(*scene.solver, scene.mesh.nodes, scene.outputs, scene.candidates, settings);
    std::vector<int> free;
    for (int b = 0; b < cache.num_candidates(); ++b)
      if (!cache.IsFixed(b)) free.push_back(b);
    std::vector<int> ready;
    for (size_t i = 0; i < free.size(); i += all_ready ? 1 : 3) ready.push_back(free[i]);
    cache.ComputeNodes(ready);
    CachedContactSolver lazy(&cache, 8);
    std::vector<double> normals(24), target(24), forces(24, 7.0), disp(24, 7.0);
    EXPECT_FALSE(lazy.SolveNormal(normals.data(), target.data(), forces.data(), disp.data()));
    EXPECT_EQ(forces[0], 7.0);
    for (size_t i = 0; i < free.size() && lazy.num_contacts() < 8; i += 2) lazy.Add(free[i]);
    const int k = lazy.num_contacts();
    ASSERT_GE(k, 5);
    EXPECT_EQ(lazy.num_substituted() > 0, !all_ready);
    std::mt19937 rng(11);
    std::normal_distribution<double> gauss;
    for (int s = 0; s < k; ++s) {
      Eigen::Vector3d n(gauss(rng), gauss(rng), 3.0 + gauss(rng));
      n.normalize();
      for (int i = 0; i < 3; ++i) {
        normals[3 * s + i] = n(i);
        target[3 * s + i] = 2e-5 * gauss(rng);
      }
    }
    t_new_count = 0;
    t_count_new = true;
    const bool ok = lazy.SolveNormal(normals.data(), target.data(), forces.data(), disp.data());
    t_count_new = false;
    ASSERT_TRUE(ok);
    EXPECT_EQ(t_new_count, 0);
    const int n3 = 3 * k;
    const Eigen::Map<const Eigen::VectorXd> f(forces.data(), n3), u(disp.data(), n3);
    Eigen::VectorXd u0c(n3);
    for (int s = 0; s < k; ++s)
      u0c.segment<3>(3 * s) =
          cache.baseline().segment<3>(3 * cache.OutputIndexOfCandidate(lazy.contact(s)));
    // u_c − u0_c from an independent path.
    Eigen::VectorXd du(n3);
    if (all_ready) {
      Eigen::VectorXd all(3 * cache.num_outputs());
      lazy.OutputDisplacement(forces.data(), &all);
      for (int s = 0; s < k; ++s)
        du.segment<3>(3 * s) = all.segment<3>(3 * cache.OutputIndexOfCandidate(lazy.contact(s))) -
                               u0c.segment<3>(3 * s);
    } else {
      du = lazy.ContactBlock() * f;
    }
    EXPECT_LT((u - u0c - du).norm(), 1e-9 * du.norm());
    double fmax = 0.0;
    for (int s = 0; s < k; ++s) {
      const Eigen::Vector3d n(normals[3 * s], normals[3 * s + 1], normals[3 * s + 2]);
      const Eigen::Vector3d fs = f.segment<3>(3 * s);
      fmax = std::max(fmax, fs.norm());
      EXPECT_LT(fs.cross(n).norm(), 1e-12 * fs.norm() + 1e-300)
          << "slot " << s << ": tangential force";
      const Eigen::Vector3d ts(target[3 * s], target[3 * s + 1], target[3 * s + 2]);
      EXPECT_NEAR(n.dot(u0c.segment<3>(3 * s) + du.segment<3>(3 * s)), n.dot(ts), 1e-9 * 2e-5)
          << "slot " << s << ": normal displacement";
    }
    EXPECT_GT(fmax, 0.0);
    // Held tangentially instead (Solve, the same targets in full), the forces differ.
    std::vector<double> sticking(24);
    ASSERT_TRUE(lazy.Solve(target.data(), sticking.data()));
    EXPECT_GT((Eigen::Map<const Eigen::VectorXd>(sticking.data(), n3) - f).norm(), 0.1 * f.norm());
    // A non-finite normal is refused and nothing is written.
    normals[0] = std::nan("");
    std::vector<double> untouched(24, 3.0);
    EXPECT_FALSE(
        lazy.SolveNormal(normals.data(), target.data(), untouched.data(), untouched.data()));
    EXPECT_EQ(untouched, std::vector<double>(24, 3.0));
  }
}

TEST(CachedContactSolver, ReportsNoColumnWhenNothingIsReadyAndRefusesFixedNodes) {
  const Scene scene(0.2, 4, 2);
  ColumnCacheSettings settings;
  settings.start_worker = false;
  ColumnCache cache(*scene.solver, scene.mesh.nodes, scene.outputs, scene.candidates, settings);
  CachedContactSolver lazy(&cache, 2);
  int fixed = -1, free = -1;
  for (int b = 0; b < cache.num_candidates(); ++b) (cache.IsFixed(b) ? fixed : free) = b;
  ASSERT_GE(fixed, 0);
  EXPECT_EQ(cache.ReadyNodeNearest(free), -1);
  EXPECT_EQ(lazy.Add(free), CachedContactStatus::kNoColumnReady);
  EXPECT_EQ(lazy.Add(fixed), CachedContactStatus::kFixedNode);
  EXPECT_EQ(lazy.Add(-1), CachedContactStatus::kBadIndex);
  EXPECT_EQ(lazy.Remove(free), CachedContactStatus::kNotInContact);
}

TEST(ColumnCache, HapticSideLookupAndContactAllocateNothing) {
  const Scene scene(0.4, 8, 2);
  ColumnCacheSettings settings;
  settings.block_nodes = 4;
  settings.memory_budget_bytes = 12.5 * scene.BytesPerNode(ColumnPrecision::kFloat);
  settings.precision = ColumnPrecision::kFloat;
  ColumnCache cache(*scene.solver, scene.mesh.nodes, scene.outputs, scene.candidates, settings);
  cache.RequestNear(Eigen::Vector3d(0.4, 0.05, 0.1), 0.2);
  ASSERT_TRUE(cache.WaitUntilIdle(30.0));
  CachedContactSolver lazy(&cache, 16);
  std::vector<double> target(48, -1e-4), forces(48, 0.0);
  Eigen::VectorXd u(3 * scene.outputs.size());
  // Sanity: the counter sees this thread's allocations.
  t_new_count = 0;
  t_count_new = true;
  {
    auto probe = std::make_unique<std::vector<int>>(10);
    EXPECT_EQ(probe->size(), 10u);
  }
  t_count_new = false;
  ASSERT_GT(t_new_count, 0);

  t_new_count = 0;
  t_count_new = true;
  long found = 0, ok = 0;
  for (int round = 0; round < 20; ++round) {
    cache.RequestNear(Eigen::Vector3d(0.4, 0.05, 0.1), 0.2);  // the same focus: no new work
    for (int b = 0; b < cache.num_candidates(); ++b) found += cache.ReadyNodeNearest(b) >= 0;
    for (int i = 0; i < 6; ++i) {
      const int b = (round * 5 + 7 * i) % cache.num_candidates();
      ok += lazy.Add(b) == CachedContactStatus::kOk;
    }
    ok += lazy.Refresh() >= 0;
    ok += lazy.Solve(target.data(), forces.data());
    if (lazy.num_contacts() > 0) {
      lazy.OutputDisplacement(forces.data(), &u);
      ok += lazy.Remove(lazy.contact(0)) == CachedContactStatus::kOk;
    }
    lazy.Clear();
  }
  t_count_new = false;
  EXPECT_EQ(t_new_count, 0);
  EXPECT_GT(found, 0);
  EXPECT_GT(ok, 60);
}

TEST(ColumnCache, ThrowsWhenACandidateIsNotAnOutputNode) {
  const Scene scene(0.2, 4, 2);
  std::vector<int> outputs = scene.outputs;
  const int missing = outputs.back();
  outputs.pop_back();
  try {
    ColumnCache cache(*scene.solver, scene.mesh.nodes, outputs, {missing});
    FAIL() << "no throw";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find(std::to_string(missing)), std::string::npos) << e.what();
  }
  ColumnCacheSettings bad;
  bad.memory_budget_bytes = 0.0;
  EXPECT_THROW(ColumnCache(*scene.solver, scene.mesh.nodes, scene.outputs, scene.candidates, bad),
               std::invalid_argument);
}

}  // namespace
}  // namespace spidarcad::fem
