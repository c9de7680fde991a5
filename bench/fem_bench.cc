// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
//
// FE benchmarks on a cantilever (L = 1 m, 0.1 m × 0.1 m section, clamped at x = 0, 1 kN tip
// shear) meshed with 10r × r × r cells, six tetrahedra each, linear or quadratic:
//   BM_Precompute/order/r      assembly + CHOLMOD factorisation time and memory, compliance
//                              column time, tip deflection against Timoshenko.
//   BM_ContactTick/order/r/k   one haptic tick: contact forces for k pushed nodes.
//   BM_GrabTick/order/r/k      one haptic tick of a rigid grab of k nodes (CondensedGrab::Solve:
//                              targets from (t, r), forces, wrench; grab.h).
//   BM_ContactTickUpdate/...   one node leaves and re-enters contact (incremental factor
//                              update) plus the solve.
//   BM_SurfaceDisplacement/... displacement of every surface node by superposition (display).
//   BM_FullSparseSolve/...     the same contact problem as a full sparse solve per tick
//                              (re-factor with the contact nodes prescribed, then solve), and
//                              the lower bound of one back-substitution with a kept factor.
//   BM_ColumnCacheWorker/order/r/float   lazy columns: the background worker computes the
//                              columns of the top-face nodes near the tip; columns per second,
//                              memory per node, and what the whole surface would take.
//   BM_CachedContactTick/order/r/k       the tick on lazy columns (CachedContactSolver).
//   BM_FallbackError/order/r   force error of a single push when the column of a node 1..4
//                              cells away stands in for the pushed node's.
//   BM_FloatError/order/r      contact force error of float columns against double, k = 16.
//   BM_Incompressible/f/r      ν = 0.4999, 10r × 2r × 2r cells, formulation f (0 linear,
//                              1 quadratic, 2 quadratic mean dilatation = --incompressible):
//                              assembly + factor, one solve, 64 condensed columns, and the tip
//                              error against the converged (r = 3) deflection.
//   BM_AssembleStiffness/order/r  AssembleStiffness alone on the cantilever's mesh (element
//                              matrices, pattern and scatter); CPU time per element.
// After the run, markdown tables of the figures are printed (speed against error; column
// cache; fallback error) for the README.
// Run e.g.: build/bench/fem_bench --benchmark_filter='Precompute|/1/12/' (see README).
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <ctime>
#include <map>
#include <memory>
#include <string>
#include <thread>
#include <vector>

#include "bench_cli.h"
#include "spidarcad/fem/column_cache.h"
#include "spidarcad/fem/condensation.h"
#include "spidarcad/fem/grab.h"
#include "spidarcad/workloads/fe.h"

namespace spidarcad::fem {
namespace {

// The cantilever of workloads/fe.h (1 m steel beam, 0.1 m square section, 1 kN tip shear).
constexpr double kLength = workloads::kCantileverLength, kSide = workloads::kCantileverSide,
                 kForce = workloads::kCantileverForce;
constexpr int kMaxContacts = 64;
using Model = workloads::CantileverModel;

// Figures gathered for the tables printed after the run, by (order, r).
struct Row {
  int tets = 0, dofs = 0, surface_nodes = 0;
  double precompute_s = 0.0, column_ms_per_node = 0.0, factor_peak_mb = 0.0;
  double g_mb_per_node = 0.0, tip_error_pct = -1.0;
  std::map<int, double> tick_us, cached_tick_us;
  double full_solve_ms = -1.0, backsub_ms = -1.0, tick16_us = -1.0;
};
std::map<std::pair<int, int>, Row>& Rows() {
  static std::map<std::pair<int, int>, Row> rows;
  return rows;
}
struct CacheRow {
  int order = 0, r = 0;
  bool single = false;
  int nodes = 0;
  double seconds = 0.0, columns_per_s = 0.0, columns_per_cpu_s = 0.0, kb_per_node = 0.0,
         memory_mb = 0.0, full_surface_gb = 0.0;
};
std::vector<CacheRow>& CacheRows() {
  static std::vector<CacheRow> rows;
  return rows;
}
struct FallbackRow {
  int order = 0, r = 0;
  double cell_mm = 0.0;
  std::vector<double> error;  // at 1, 2, 3, 4 cells
  double float_error = -1.0;
};
std::map<std::pair<int, int>, FallbackRow>& FallbackRows() {
  static std::map<std::pair<int, int>, FallbackRow> rows;
  return rows;
}

// Loads every eager compliance column of a model into a cache (no solves).
void FillFromCompliance(const Compliance& c, ColumnCache* cache) {
  ColumnSet set;
  set.output_nodes = c.output_nodes();
  set.nodes = c.condensed_nodes();
  set.baseline = c.baseline();
  set.columns = c.matrix();
  cache->Import(set);
}

// CPU time of the process, s (the machine may be shared: wall time would count others' work).
double CpuSeconds() {
  timespec ts{};
  clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &ts);
  return ts.tv_sec + 1e-9 * ts.tv_nsec;
}

Model& GetModel(int order, int r) {
  static std::map<std::pair<int, int>, std::unique_ptr<Model>> cache;
  auto& slot = cache[{order, r}];
  if (slot) return *slot;
  CondensationSettings cs;
  cs.block_nodes = 32;
  slot = workloads::BuildCantilever(order, r, kMaxContacts, cs);
  return *slot;
}

void BM_Precompute(benchmark::State& state) {
  const int order = static_cast<int>(state.range(0)), r = static_cast<int>(state.range(1));
  Model* m = nullptr;
  for (auto _ : state) m = &GetModel(order, r);
  const FactorStats& st = m->solver->stats();
  state.counters["tets"] = m->mesh.num_elements();
  state.counters["dofs"] = st.num_free;
  state.counters["assembly_s"] = st.assembly_seconds;
  state.counters["factor_s"] = st.factor_seconds;
  state.counters["factor_nnz"] = st.factor_nonzeros;
  state.counters["cholmod_peak_MB"] = st.factor_peak_bytes / 1e6;
  state.counters["column_ms_per_node"] =
      1e3 * m->compliance->compute_seconds() / m->compliance->condensed_nodes().size();
  state.counters["G_MB_per_node"] = 24.0 * m->compliance->output_nodes().size() * 3 / 1e6;
  state.counters["surface_nodes"] = m->compliance->output_nodes().size();
  state.counters["tip_over_timoshenko"] = m->tip_ratio;
  state.counters["tip_error_pct"] = 100.0 * std::abs(m->tip_ratio - 1.0);
  Row& row = Rows()[{order, r}];
  row.tets = m->mesh.num_elements();
  row.dofs = st.num_free;
  row.surface_nodes = static_cast<int>(m->compliance->output_nodes().size());
  row.precompute_s = st.assembly_seconds + st.factor_seconds + m->compliance->compute_seconds();
  row.column_ms_per_node = state.counters["column_ms_per_node"];
  row.factor_peak_mb = st.factor_peak_bytes / 1e6;
  row.g_mb_per_node = state.counters["G_MB_per_node"];
  row.tip_error_pct = 100.0 * std::abs(m->tip_ratio - 1.0);
}

void BM_AssembleStiffness(benchmark::State& state) {
  const int order = static_cast<int>(state.range(0)), r = static_cast<int>(state.range(1));
  BoxMeshSettings s;
  s.upper = Eigen::Vector3d(1.0, 0.1, 0.1);
  s.nx = 10 * r;
  s.ny = s.nz = r;
  s.order = order;
  const TetMesh mesh = MakeBoxMesh(s);
  const MaterialTable materials(Material{});
  for (auto _ : state) benchmark::DoNotOptimize(AssembleStiffness(mesh, materials));
  state.counters["tets"] = mesh.num_elements();
  state.counters["ns_per_tet"] =
      benchmark::Counter(1e-9 * mesh.num_elements(), benchmark::Counter::kIsIterationInvariantRate |
                                                         benchmark::Counter::kInvert);
}

// Targets: push the contact nodes 0.1 mm down from where the baseline put them.
std::vector<double> Targets(const Model& m, const ContactSolver& solver) {
  std::vector<double> t(3 * solver.num_contacts());
  for (int s = 0; s < solver.num_contacts(); ++s) {
    const int row = 3 * m.compliance->OutputIndexOfCondensed(solver.contact(s));
    for (int i = 0; i < 3; ++i)
      t[3 * s + i] = m.compliance->baseline()(row + i) - (i == 2 ? 1e-4 : 0.0);
  }
  return t;
}

void SetUpContacts(const Model& m, int k, ContactSolver* solver) {
  for (int b = 0;
       b < static_cast<int>(m.compliance->condensed_nodes().size()) && solver->num_contacts() < k;
       ++b)
    solver->Add(b);
}

void BM_ContactTick(benchmark::State& state) {
  const Model& m = GetModel(static_cast<int>(state.range(0)), static_cast<int>(state.range(1)));
  const int k = static_cast<int>(state.range(2));
  ContactSolver solver(*m.compliance, kMaxContacts);
  SetUpContacts(m, k, &solver);
  const auto target = Targets(m, solver);
  std::vector<double> f(target.size());
  const double t0 = CpuSeconds();
  for (auto _ : state) {
    solver.Solve(target.data(), f.data());
    benchmark::DoNotOptimize(f.data());
  }
  const double per_tick =
      (CpuSeconds() - t0) / std::max<double>(1.0, static_cast<double>(state.iterations()));
  state.counters["k"] = solver.num_contacts();
  state.counters["tets"] = m.mesh.num_elements();
  Rows()[{static_cast<int>(state.range(0)), static_cast<int>(state.range(1))}].tick_us[k] =
      1e6 * per_tick;
}

void BM_GrabTick(benchmark::State& state) {
  const Model& m = GetModel(static_cast<int>(state.range(0)), static_cast<int>(state.range(1)));
  const int k = static_cast<int>(state.range(2));
  std::vector<int> nodes;
  for (int b = 0; b < static_cast<int>(m.compliance->condensed_nodes().size()) &&
                  static_cast<int>(nodes.size()) < k;
       ++b)
    if (!m.compliance->IsFixed(b)) nodes.push_back(m.compliance->condensed_nodes()[b]);
  CondensedGrab grab(*m.compliance, GrabPatch(m.mesh.nodes, nodes));
  const Eigen::Vector3d t(0.0, 0.0, -1e-4), r(1e-3, -2e-3, 5e-4);
  const double t0 = CpuSeconds();
  for (auto _ : state) {
    const GrabWrench w = grab.Solve(t, r);
    benchmark::DoNotOptimize(w.force.data());
  }
  const double per_tick =
      (CpuSeconds() - t0) / std::max<double>(1.0, static_cast<double>(state.iterations()));
  state.counters["k"] = static_cast<double>(nodes.size());
  state.counters["cpu_us_per_tick"] = 1e6 * per_tick;
}

void BM_ContactTickUpdate(benchmark::State& state) {
  const Model& m = GetModel(static_cast<int>(state.range(0)), static_cast<int>(state.range(1)));
  const int k = static_cast<int>(state.range(2));
  ContactSolver solver(*m.compliance, kMaxContacts);
  SetUpContacts(m, k, &solver);
  const auto target = Targets(m, solver);
  std::vector<double> f(target.size());
  int next = 0;
  for (auto _ : state) {
    // The node in slot `next` leaves contact and enters again (as the last slot).
    const int b = solver.contact(next % solver.num_contacts());
    solver.Remove(b);
    solver.Add(b);
    solver.Solve(target.data(), f.data());
    benchmark::DoNotOptimize(f.data());
    ++next;
  }
  state.counters["k"] = solver.num_contacts();
}

void BM_SurfaceDisplacement(benchmark::State& state) {
  const Model& m = GetModel(static_cast<int>(state.range(0)), static_cast<int>(state.range(1)));
  const int k = static_cast<int>(state.range(2));
  ContactSolver solver(*m.compliance, kMaxContacts);
  SetUpContacts(m, k, &solver);
  const auto target = Targets(m, solver);
  std::vector<double> f(target.size());
  solver.Solve(target.data(), f.data());
  Eigen::VectorXd u(3 * m.compliance->output_nodes().size());
  for (auto _ : state) {
    solver.OutputDisplacement(f.data(), &u);
    benchmark::DoNotOptimize(u.data());
  }
  state.counters["surface_nodes"] = m.compliance->output_nodes().size();
}

void BM_FullSparseSolve(benchmark::State& state) {
  const Model& m = GetModel(static_cast<int>(state.range(0)), static_cast<int>(state.range(1)));
  const int k = static_cast<int>(state.range(2));
  ContactSolver solver(*m.compliance, kMaxContacts);
  SetUpContacts(m, k, &solver);
  const auto target = Targets(m, solver);
  std::vector<double> f(target.size());
  // Condensed tick, timed here too for the ratio in the same run.
  // CPU time throughout (condensed tick, back-substitution, full solve): on a shared machine
  // wall time counts other processes' work too.
  const int reps = 2000;
  double t0 = CpuSeconds();
  for (int i = 0; i < reps; ++i) solver.Solve(target.data(), f.data());
  const double tick_s = (CpuSeconds() - t0) / reps;
  // Lower bound: one back-substitution with the kept factor.
  Eigen::MatrixXd rhs = Eigen::MatrixXd::Ones(m.solver->num_free(), 1), x;
  t0 = CpuSeconds();
  m.solver->SolveFree(rhs, &x);
  const double backsub_s = CpuSeconds() - t0;
  double max_force_diff = 0.0;
  const double t_full = CpuSeconds();
  for (auto _ : state) {
    BoundaryConditions bcs = *m.bcs;
    for (int s = 0; s < solver.num_contacts(); ++s) {
      const int node = m.compliance->condensed_nodes()[solver.contact(s)];
      bcs.PrescribeNode(node, Eigen::Vector3d(target[3 * s], target[3 * s + 1], target[3 * s + 2]));
    }
    StaticSolver full(m.mesh, m.materials, bcs);
    const StaticSolution sol = full.Solve();
    for (int s = 0; s < solver.num_contacts(); ++s) {
      const int node = m.compliance->condensed_nodes()[solver.contact(s)];
      for (int i = 0; i < 3; ++i)
        max_force_diff =
            std::max(max_force_diff, std::abs(sol.reaction(3 * node + i) - f[3 * s + i]));
    }
  }
  const double full_s = CpuSeconds() - t_full;
  state.counters["condensed_tick_us"] = 1e6 * tick_s;
  state.counters["backsub_ms"] = 1e3 * backsub_s;
  state.counters["backsub_over_tick"] = backsub_s / tick_s;
  state.counters["max_force_diff_N"] = max_force_diff;
  state.counters["k"] = solver.num_contacts();
  Row& row = Rows()[{static_cast<int>(state.range(0)), static_cast<int>(state.range(1))}];
  row.full_solve_ms = 1e3 * full_s / std::max<double>(1.0, static_cast<double>(state.iterations()));
  row.backsub_ms = 1e3 * backsub_s;
  row.tick16_us = 1e6 * tick_s;
  state.counters["full_over_tick"] = full_s / state.iterations() / tick_s;
}

// Top-face nodes of a model (the cache's candidates), and the radius around p that holds the
// n nearest of them.
std::vector<int> TopFace(const Model& m) { return workloads::CantileverTopFace(m.mesh); }
double RadiusForCount(const Model& m, const std::vector<int>& nodes, const Eigen::Vector3d& p,
                      int n) {
  std::vector<double> d;
  for (int v : nodes) d.push_back((m.mesh.nodes.row(v).transpose() - p).norm());
  std::sort(d.begin(), d.end());
  return d[std::min<size_t>(d.size(), n) - 1] * (1.0 + 1e-9);
}

// The worker computes the columns of the `kCacheNodes` top-face nodes nearest the tip in the
// background; the benchmark thread only waits.
constexpr int kCacheNodes = 48;
void BM_ColumnCacheWorker(benchmark::State& state) {
  const int order = static_cast<int>(state.range(0)), r = static_cast<int>(state.range(1));
  const bool single = state.range(2) != 0;
  const Model& m = GetModel(order, r);
  const auto top = TopFace(m);
  const Eigen::Vector3d tip(kLength, kSide / 2, kSide);
  const double radius = RadiusForCount(m, top, tip, kCacheNodes);
  ColumnCacheSettings settings;
  settings.precision = single ? ColumnPrecision::kFloat : ColumnPrecision::kDouble;
  settings.memory_budget_bytes = 4.0e9;
  double seconds = 0.0, memory = 0.0, per_node = 0.0, cpu = 0.0;
  long nodes = 0;
  for (auto _ : state) {
    ColumnCache cache(*m.solver, m.mesh.nodes, m.compliance->output_nodes(), top, settings);
    const auto t0 = std::chrono::steady_clock::now();
    const double c0 = CpuSeconds();
    cache.RequestNear(tip, radius);
    cache.WaitUntilIdle(600.0);
    seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    cpu = CpuSeconds() - c0;  // the worker's (and BLAS threads') CPU: this thread only sleeps
    nodes = cache.stats().computed_nodes;
    memory = cache.MemoryBytes();
    per_node = cache.BytesPerNode();
  }
  CacheRow row;
  row.order = order;
  row.r = r;
  row.single = single;
  row.nodes = static_cast<int>(nodes);
  row.seconds = seconds;
  row.columns_per_s = 3.0 * nodes / seconds;
  row.columns_per_cpu_s = 3.0 * nodes / cpu;
  row.kb_per_node = per_node / 1e3;
  row.memory_mb = memory / 1e6;
  row.full_surface_gb = per_node * m.compliance->output_nodes().size() / 1e9;
  CacheRows().push_back(row);
  state.counters["nodes"] = static_cast<double>(nodes);
  state.counters["columns_per_s"] = row.columns_per_s;
  state.counters["columns_per_cpu_s"] = row.columns_per_cpu_s;
  state.counters["kB_per_node"] = row.kb_per_node;
  state.counters["cache_MB"] = row.memory_mb;
  state.counters["full_surface_GB"] = row.full_surface_gb;
}

// The tick on lazy columns, every column ready (compare BM_ContactTick).
void BM_CachedContactTick(benchmark::State& state) {
  const int order = static_cast<int>(state.range(0)), r = static_cast<int>(state.range(1));
  const int k = static_cast<int>(state.range(2));
  const Model& m = GetModel(order, r);
  ColumnCacheSettings settings;
  settings.start_worker = false;
  ColumnCache cache(*m.solver, m.mesh.nodes, m.compliance->output_nodes(),
                    m.compliance->condensed_nodes(), settings);
  FillFromCompliance(*m.compliance, &cache);
  CachedContactSolver solver(&cache, kMaxContacts);
  for (int b = 0; b < cache.num_candidates() && solver.num_contacts() < k; ++b) solver.Add(b);
  std::vector<double> target(3 * solver.num_contacts()), f(target.size());
  for (int s = 0; s < solver.num_contacts(); ++s)
    for (int i = 0; i < 3; ++i)
      target[3 * s + i] =
          cache.baseline()(3 * cache.OutputIndexOfCandidate(solver.contact(s)) + i) -
          (i == 2 ? 1e-4 : 0.0);
  const double t0 = CpuSeconds();
  for (auto _ : state) {
    solver.Solve(target.data(), f.data());
    benchmark::DoNotOptimize(f.data());
  }
  Rows()[{order, r}].cached_tick_us[k] =
      1e6 * (CpuSeconds() - t0) / std::max<double>(1.0, static_cast<double>(state.iterations()));
  state.counters["k"] = solver.num_contacts();
}

// Single push (0.1 mm down) at the top-face centre line node at mid-span; the column of the
// node 1..4 cells further along x stands in for it. Error of the contact force against the
// exact one.
void BM_FallbackError(benchmark::State& state) {
  const int order = static_cast<int>(state.range(0)), r = static_cast<int>(state.range(1));
  const Model& m = GetModel(order, r);
  FallbackRow row;
  row.order = order;
  row.r = r;
  row.cell_mm = 1e3 * kSide / r;
  for (auto _ : state) row.error = workloads::BorrowedColumnErrors(m);
  for (int c = 0; c < 4; ++c)
    state.counters["err_" + std::to_string(c + 1) + "_cells"] = row.error[c];
  state.counters["cell_mm"] = row.cell_mm;
  const double float_error = FallbackRows()[{order, r}].float_error;
  row.float_error = float_error;
  FallbackRows()[{order, r}] = row;
}

// Contact forces of k = 16 nodes from float columns against double ones.
void BM_FloatError(benchmark::State& state) {
  const int order = static_cast<int>(state.range(0)), r = static_cast<int>(state.range(1));
  const Model& m = GetModel(order, r);
  double error = 0.0;
  for (auto _ : state) {
    std::vector<std::vector<double>> forces;
    for (ColumnPrecision p : {ColumnPrecision::kDouble, ColumnPrecision::kFloat}) {
      ColumnCacheSettings settings;
      settings.start_worker = false;
      settings.precision = p;
      ColumnCache cache(*m.solver, m.mesh.nodes, m.compliance->output_nodes(),
                        m.compliance->condensed_nodes(), settings);
      std::vector<int> first(16);
      for (int b = 0; b < 16; ++b) first[b] = b;
      FillFromCompliance(*m.compliance, &cache);  // rounded to float by the float cache
      CachedContactSolver solver(&cache, 16);
      for (int b : first) solver.Add(b);
      std::vector<double> target(48), f(48);
      for (int s = 0; s < 16; ++s)
        for (int i = 0; i < 3; ++i)
          target[3 * s + i] =
              cache.baseline()(3 * cache.OutputIndexOfCandidate(solver.contact(s)) + i) -
              (i == 2 ? 1e-4 : 0.0);
      solver.Solve(target.data(), f.data());
      forces.push_back(f);
    }
    const Eigen::Map<const Eigen::VectorXd> a(forces[0].data(), 48), b(forces[1].data(), 48);
    error = (a - b).norm() / a.norm();
  }
  state.counters["float_force_rel_error"] = error;
  FallbackRows()[{order, r}].float_error = error;
}

// ν = 0.4999 cantilever with 10r × 2r × 2r cells: tip deflection (mean end-face z) and times.
struct IncompressibleRun {
  int dofs = 0;
  double tip = 0.0, factor_s = 0.0, solve_ms = 0.0, condense_s = 0.0;
};
IncompressibleRun SolveIncompressible(int formulation, int r, bool condense) {
  Material rubber{2.0e11, 0.4999};
  if (formulation == 2) rubber.formulation = Formulation::kMeanDilatation;
  BoxMeshSettings s;
  s.upper = Eigen::Vector3d(kLength, kSide, kSide);
  s.nx = 10 * r;
  s.ny = s.nz = 2 * r;
  s.order = formulation == 0 ? 1 : 2;
  const TetMesh mesh = MakeBoxMesh(s);
  BoundaryConditions bcs(mesh.num_nodes());
  FixNodesInBox(mesh, Eigen::Vector3d(-1, -1, -1), Eigen::Vector3d(1e-9, 1, 1), &bcs);
  const Surface surf = ExtractSurface(mesh);
  AddTractionInBox(mesh, surf, Eigen::Vector3d(kLength - 1e-9, -1, -1), Eigen::Vector3d(2, 2, 2),
                   Eigen::Vector3d(0, 0, -kForce / (kSide * kSide)), &bcs);
  const MaterialTable materials(rubber);
  StaticSolver solver(mesh, materials, bcs);
  IncompressibleRun run;
  run.dofs = solver.num_free();
  run.factor_s = solver.stats().assembly_seconds + solver.stats().factor_seconds;
  const auto t0 = std::chrono::steady_clock::now();
  const StaticSolution sol = solver.Solve();
  run.solve_ms = 1e3 * std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  const auto tip =
      NodesInBox(mesh, Eigen::Vector3d(kLength - 1e-9, -1, -1), Eigen::Vector3d(2, 2, 2));
  for (int v : tip) run.tip -= sol.displacement(3 * v + 2) / tip.size();
  if (condense) {
    std::vector<int> top =
        NodesInBox(mesh, Eigen::Vector3d(0.5, -1, kSide), Eigen::Vector3d(2, 2, 2));
    top.resize(std::min<size_t>(top.size(), kMaxContacts));
    const Compliance c(solver, surf.nodes, top);
    run.condense_s = c.compute_seconds();
  }
  return run;
}

// Converged deflection: mean dilatation at r = 3 (30 x 6 x 6 cells); it converges
// non-monotonically, so no Richardson extrapolation (see docs/fem.md and HardIncompressible).
double ConvergedIncompressibleTip() {
  static const double converged = SolveIncompressible(2, 3, false).tip;
  return converged;
}

struct IncompressibleRow {
  int formulation = 0, r = 0, dofs = 0;
  double factor_s = 0.0, solve_ms = 0.0, condense_s = 0.0, error_pct = 0.0;
};
std::vector<IncompressibleRow>& IncompressibleRows() {
  static std::vector<IncompressibleRow> rows;
  return rows;
}

void BM_Incompressible(benchmark::State& state) {
  const int formulation = static_cast<int>(state.range(0)), r = static_cast<int>(state.range(1));
  const double converged = ConvergedIncompressibleTip();
  IncompressibleRun run;
  for (auto _ : state) run = SolveIncompressible(formulation, r, true);
  IncompressibleRow row{formulation,
                        r,
                        run.dofs,
                        run.factor_s,
                        run.solve_ms,
                        run.condense_s,
                        100.0 * std::abs(run.tip / converged - 1.0)};
  state.counters["dofs"] = row.dofs;
  state.counters["factor_s"] = row.factor_s;
  state.counters["solve_ms"] = row.solve_ms;
  state.counters["condense64_s"] = row.condense_s;
  state.counters["tip_error_pct"] = row.error_pct;
  IncompressibleRows().push_back(row);
}

void PrintTables() {
  double load[3] = {0, 0, 0};
  getloadavg(load, 3);
  std::printf(
      "\nTick, back-substitution and full-solve times are CPU time of this process; wall "
      "times (precompute, worker) include waiting for the CPU (load average %.1f on this "
      "machine at the end of the run).\n",
      load[0]);
  std::printf(
      "\n### Speed against error: cantilever (1 x 0.1 x 0.1 m, clamped, 1 kN tip shear)\n\n");
  std::printf(
      "| order | cells | tets | free dofs | precompute s (assembly+factor+64 nodes) | "
      "CHOLMOD peak MB | G MB/node | tip error %% | tick us k=1 | k=4 | k=16 | k=64 | "
      "full sparse solve ms (k=16) | full / tick |\n");
  std::printf("|---|---|---|---|---|---|---|---|---|---|---|---|---|---|\n");
  for (const auto& [key, row] : Rows()) {
    if (row.tets == 0) continue;
    auto tick = [&](int k) {
      const auto it = row.tick_us.find(k);
      return it == row.tick_us.end() ? std::string("-") : std::to_string(it->second).substr(0, 6);
    };
    std::string full = "-", ratio = "-";
    if (row.full_solve_ms > 0) {
      full = std::to_string(row.full_solve_ms).substr(0, 7);
      ratio = std::to_string(static_cast<long>(1e3 * row.full_solve_ms / row.tick16_us));
    }
    std::printf(
        "| %d | %dx%dx%d | %d | %d | %.2f | %.1f | %.3f | %.2f | %s | %s | %s | %s | %s | %s |\n",
        key.first, 10 * key.second, key.second, key.second, row.tets, row.dofs, row.precompute_s,
        row.factor_peak_mb, row.g_mb_per_node, row.tip_error_pct, tick(1).c_str(), tick(4).c_str(),
        tick(16).c_str(), tick(64).c_str(), full.c_str(), ratio.c_str());
  }
  bool cached = false;
  for (const auto& [key, row] : Rows()) cached = cached || !row.cached_tick_us.empty();
  if (cached) {
    std::printf(
        "\n### Tick on lazy columns (CachedContactSolver, all ready) against eager "
        "(ContactSolver), us\n\n");
    std::printf("| order | cells | k | eager | lazy |\n|---|---|---|---|---|\n");
    for (const auto& [key, row] : Rows())
      for (const auto& [k, us] : row.cached_tick_us) {
        const auto it = row.tick_us.find(k);
        std::printf("| %d | %d | %d | %s | %.3f |\n", key.first, key.second, k,
                    it == row.tick_us.end() ? "-" : std::to_string(it->second).substr(0, 6).c_str(),
                    us);
      }
  }
  if (!CacheRows().empty()) {
    std::printf("\n### Column cache: background worker, %d top-face nodes nearest the tip\n\n",
                kCacheNodes);
    std::printf(
        "| order | cells | precision | nodes | wall s | columns/s (wall) | columns per CPU s | "
        "kB/node | cache MB | whole surface would be GB "
        "|\n|---|---|---|---|---|---|---|---|---|---|\n");
    for (const CacheRow& c : CacheRows())
      std::printf("| %d | %d | %s | %d | %.2f | %.1f | %.1f | %.0f | %.1f | %.2f |\n", c.order, c.r,
                  c.single ? "float" : "double", c.nodes, c.seconds, c.columns_per_s,
                  c.columns_per_cpu_s, c.kb_per_node, c.memory_mb, c.full_surface_gb);
  }
  if (!IncompressibleRows().empty()) {
    std::printf(
        "\n### Near incompressibility, nu = 0.4999: tip error against the converged deflection "
        "(mean dilatation at r = 3: %.5e m)\n\n",
        ConvergedIncompressibleTip());
    std::printf(
        "| formulation | cells | free dofs | assembly+factor s | solve ms | 64 columns s | tip "
        "error %% |\n"
        "|---|---|---|---|---|---|---|\n");
    const char* names[] = {"linear", "quadratic", "quadratic mean dilatation"};
    for (const IncompressibleRow& row : IncompressibleRows())
      std::printf("| %s | %dx%dx%d | %d | %.3f | %.2f | %.3f | %.2f |\n", names[row.formulation],
                  10 * row.r, 2 * row.r, 2 * row.r, row.dofs, row.factor_s, row.solve_ms,
                  row.condense_s, row.error_pct);
  }
  if (!FallbackRows().empty()) {
    std::printf(
        "\n### Nearest-ready fallback: relative force error of a single push at mid-span\n\n");
    std::printf(
        "| order | cells | cell mm | 1 cell away | 2 | 3 | 4 | float columns, k=16 |\n"
        "|---|---|---|---|---|---|---|---|\n");
    for (const auto& [key, f] : FallbackRows()) {
      if (f.error.size() < 4) continue;
      std::printf("| %d | %d | %.1f | %.3f | %.3f | %.3f | %.3f | %.1e |\n", key.first, key.second,
                  f.cell_mm, f.error[0], f.error[1], f.error[2], f.error[3], f.float_error);
    }
  }
}

void PrecomputeArgs(benchmark::internal::Benchmark* b) {
  for (int r : {1, 2, 4, 8, 12}) b->Args({1, r});
  for (int r : {1, 2, 4, 6}) b->Args({2, r});
}
void TickArgs(benchmark::internal::Benchmark* b) {
  for (auto [order, r] : {std::pair{1, 4}, std::pair{1, 12}, std::pair{2, 4}, std::pair{2, 6}})
    for (int k : {1, 4, 16, 64}) b->Args({order, r, k});
}

BENCHMARK(BM_Precompute)->Apply(PrecomputeArgs)->Iterations(1)->Unit(benchmark::kSecond);
BENCHMARK(BM_AssembleStiffness)
    ->Args({1, 8})
    ->Args({1, 16})
    ->Args({2, 8})
    ->Unit(benchmark::kMillisecond);
BENCHMARK(BM_ContactTick)->Apply(TickArgs)->Unit(benchmark::kMicrosecond);
BENCHMARK(BM_GrabTick)->Apply(TickArgs)->Unit(benchmark::kMicrosecond);
BENCHMARK(BM_ContactTickUpdate)->Apply(TickArgs)->Unit(benchmark::kMicrosecond);
BENCHMARK(BM_SurfaceDisplacement)->Apply(TickArgs)->Unit(benchmark::kMicrosecond);
BENCHMARK(BM_FullSparseSolve)
    ->Args({1, 4, 16})
    ->Args({1, 12, 16})
    ->Args({2, 4, 16})
    ->Args({2, 6, 16})
    ->Iterations(1)
    ->Unit(benchmark::kMillisecond);
BENCHMARK(BM_CachedContactTick)
    ->Args({1, 12, 1})
    ->Args({1, 12, 4})
    ->Args({1, 12, 16})
    ->Args({1, 12, 64})
    ->Unit(benchmark::kMicrosecond);
BENCHMARK(BM_ColumnCacheWorker)
    ->Args({1, 4, 0})
    ->Args({1, 12, 0})
    ->Args({1, 12, 1})
    ->Iterations(1)
    ->Unit(benchmark::kSecond);
BENCHMARK(BM_FloatError)->Args({1, 4})->Args({1, 12})->Args({2, 4})->Iterations(1);
BENCHMARK(BM_FallbackError)->Args({1, 4})->Args({1, 12})->Args({2, 4})->Iterations(1);
BENCHMARK(BM_Incompressible)
    ->Args({0, 1})
    ->Args({0, 2})
    ->Args({0, 4})
    ->Args({1, 1})
    ->Args({1, 2})
    ->Args({2, 1})
    ->Args({2, 2})
    ->Iterations(1)
    ->Unit(benchmark::kSecond);

}  // namespace
}  // namespace spidarcad::fem

// What this program measures (its --help).
constexpr const char* kBenchDescription =
    "FE benchmarks on a cantilever (L = 1 m, 0.1 m × 0.1 m section, clamped at x = 0, 1 kN tip\n"
    "shear) meshed with 10r × r × r cells, six tetrahedra each, linear or quadratic:\n"
    "  BM_Precompute/order/r      assembly + CHOLMOD factorisation time and memory, compliance\n"
    "                             column time, tip deflection against Timoshenko.\n"
    "  BM_ContactTick/order/r/k   one haptic tick: contact forces for k pushed nodes.\n"
    "  BM_GrabTick/order/r/k      one haptic tick of a rigid grab of k nodes "
    "(CondensedGrab::Solve:\n"
    "                             targets from (t, r), forces, wrench; grab.h).\n"
    "  BM_ContactTickUpdate/...   one node leaves and re-enters contact (incremental factor\n"
    "                             update) plus the solve.\n"
    "  BM_SurfaceDisplacement/... displacement of every surface node by superposition (display).\n"
    "  BM_FullSparseSolve/...     the same contact problem as a full sparse solve per tick\n"
    "                             (re-factor with the contact nodes prescribed, then solve), and\n"
    "                             the lower bound of one back-substitution with a kept factor.\n"
    "  BM_ColumnCacheWorker/order/r/float   lazy columns: the background worker computes the\n"
    "                             columns of the top-face nodes near the tip; columns per second,\n"
    "                             memory per node, and what the whole surface would take.\n"
    "  BM_CachedContactTick/order/r/k       the tick on lazy columns (CachedContactSolver).\n"
    "  BM_FallbackError/order/r   force error of a single push when the column of a node 1..4\n"
    "                             cells away stands in for the pushed node's.\n"
    "  BM_FloatError/order/r      contact force error of float columns against double, k = 16.\n"
    "After the run, markdown tables of the figures are printed (speed against error; column\n"
    "cache; fallback error) for the README.\n"
    "Run e.g.: build/bench/fem_bench --benchmark_filter='Precompute|/1/12/' (see README).";

// Tables printed after the benchmarks.
void PrintAfterRun() { spidarcad::fem::PrintTables(); }

int main(int argc, char** argv) {
  return spidarcad::bench::RunBenchmarkMain(argc, argv, kBenchDescription, nullptr, PrintAfterRun);
}
