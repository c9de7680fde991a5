// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
// The substructured solver against the monolithic StaticSolver (a second algorithm: one sparse
// Cholesky of K_ff), on bars partitioned into slabs, random Voronoi cells and random element
// labels, both element orders; and the reuse of unchanged blocks after an edit.
#include "spidarcad/fem/substructure.h"

#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <algorithm>
#include <atomic>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <memory>
#include <numeric>
#include <random>
#include <stdexcept>
#include <string>
#include <thread>
#include <utility>
#include <vector>

#include "spidarcad/fem/cache_file.h"
#include "spidarcad/fem/column_cache.h"
#include "spidarcad/fem/condensation.h"
#include "spidarcad/fem/static_solver.h"

namespace spidarcad::fem {
namespace {

constexpr double kTolerance = 1e-9;
const Material kSteel{2.0e11, 0.3};

TetMesh Bar(int order) {
  BoxMeshSettings s;
  s.upper = Eigen::Vector3d(0.4, 0.1, 0.08);
  s.nx = 8;
  s.ny = 3;
  s.nz = 2;
  s.order = order;
  return MakeBoxMesh(s);
}

// Clamped at x = 0, one node pushed by a prescribed displacement, a load at the far end.
BoundaryConditions BarConditions(const TetMesh& mesh) {
  BoundaryConditions bcs(mesh.num_nodes());
  FixNodesInBox(mesh, Eigen::Vector3d(-1, -1, -1), Eigen::Vector3d(1e-9, 1, 1), &bcs);
  for (int v : NodesInBox(mesh, Eigen::Vector3d(0.4 - 1e-9, -1, -1), Eigen::Vector3d(1, 1, 1)))
    bcs.AddPointLoad(v, Eigen::Vector3d(30.0, -200.0, 500.0));
  // The top node at x = 0.2 with the least y (chosen by position: the edit test renumbers nodes).
  const std::vector<int> mid = NodesInBox(mesh, Eigen::Vector3d(0.2 - 1e-9, -1, 0.08 - 1e-9),
                                          Eigen::Vector3d(0.2 + 1e-9, 1, 1));
  const int pushed = *std::min_element(
      mid.begin(), mid.end(), [&](int a, int b) { return mesh.nodes(a, 1) < mesh.nodes(b, 1); });
  bcs.PrescribeDof(pushed, 2, -2.0e-6);
  return bcs;
}

Eigen::Vector3d Centroid(const TetMesh& mesh, int e) {
  Eigen::Vector3d c = Eigen::Vector3d::Zero();
  for (int j = 0; j < 4; ++j) c += 0.25 * mesh.nodes.row(mesh.elements(e, j)).transpose();
  return c;
}

// Each element to the nearest of k random seeds (connected-ish random blocks).
Eigen::VectorXi VoronoiBlocks(const TetMesh& mesh, int k, unsigned seed) {
  std::mt19937 rng(seed);
  const Eigen::Vector3d lo = mesh.nodes.colwise().minCoeff(), hi = mesh.nodes.colwise().maxCoeff();
  std::uniform_real_distribution<double> u(0.0, 1.0);
  std::vector<Eigen::Vector3d> seeds;
  for (int i = 0; i < k; ++i)
    seeds.push_back(lo + (hi - lo).cwiseProduct(Eigen::Vector3d(u(rng), u(rng), u(rng))));
  Eigen::VectorXi blocks(mesh.num_elements());
  for (int e = 0; e < mesh.num_elements(); ++e) {
    const Eigen::Vector3d c = Centroid(mesh, e);
    int best = 0;
    for (int i = 1; i < k; ++i)
      if ((c - seeds[i]).squaredNorm() < (c - seeds[best]).squaredNorm()) best = i;
    blocks(e) = best;
  }
  return blocks;
}

// Every element to a random block of k: nearly every node is an interface node.
Eigen::VectorXi RandomLabels(const TetMesh& mesh, int k, unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_int_distribution<int> pick(0, k - 1);
  Eigen::VectorXi blocks(mesh.num_elements());
  for (int e = 0; e < mesh.num_elements(); ++e) blocks(e) = pick(rng);
  return blocks;
}

double RelativeDifference(const Eigen::MatrixXd& a, const Eigen::MatrixXd& b) {
  return (a - b).norm() / std::max(b.norm(), 1e-300);
}

struct Partition {
  std::string name;
  Eigen::VectorXi blocks;
};

std::vector<Partition> Partitions(const TetMesh& mesh) {
  return {{"one block", Eigen::VectorXi::Zero(mesh.num_elements())},
          {"4 slabs", SlabBlocks(mesh, 0, EvenPlanes(mesh, 0, 4))},
          {"voronoi 5 seed 1", VoronoiBlocks(mesh, 5, 1)},
          {"voronoi 7 seed 2", VoronoiBlocks(mesh, 7, 2)},
          {"random labels 3", RandomLabels(mesh, 3, 3)}};
}

TEST(SubstructuredSolver, SolveEqualsStaticSolverForPartitionsOfABarBothOrders) {
  for (int order : {1, 2}) {
    const TetMesh mesh = Bar(order);
    const BoundaryConditions bcs = BarConditions(mesh);
    const MaterialTable materials(kSteel);
    const StaticSolver reference(mesh, materials, bcs);
    ASSERT_TRUE(reference.factor_status().converged);
    const StaticSolution ref = reference.Solve();
    std::mt19937 rng(17);
    std::normal_distribution<double> normal;
    Eigen::MatrixXd rhs(reference.num_free(), 3);
    for (Eigen::Index i = 0; i < rhs.size(); ++i) rhs.data()[i] = normal(rng);
    Eigen::MatrixXd x_ref;
    ASSERT_TRUE(reference.SolveFree(rhs, &x_ref).converged);
    for (const Partition& p : Partitions(mesh)) {
      SCOPED_TRACE("order " + std::to_string(order) + ", " + p.name);
      const SubstructuredSolver solver(mesh, materials, bcs, p.blocks);
      ASSERT_TRUE(solver.factor_status().converged) << solver.factor_status().message;
      ASSERT_EQ(solver.num_free(), reference.num_free());
      for (int i = 0; i < solver.num_free(); ++i)
        ASSERT_EQ(solver.FreeDof(i), reference.FreeDof(i));
      const StaticSolution sol = solver.Solve();
      EXPECT_TRUE(sol.status.converged) << sol.status.message;
      EXPECT_LT(sol.status.residual, 1e-12);
      EXPECT_LT(RelativeDifference(sol.displacement, ref.displacement), kTolerance);
      EXPECT_LT(RelativeDifference(sol.reaction, ref.reaction), kTolerance);
      Eigen::MatrixXd x;
      ASSERT_TRUE(solver.SolveFree(rhs, &x).converged);
      EXPECT_LT(RelativeDifference(x, x_ref), kTolerance);
      // Figures: the relative differences from the monolithic solve.
      std::printf(
          "order %d, %-17s: %d blocks, %4d of %5d free dofs on the interface, %.1e %.1e %.1e\n",
          order, p.name.c_str(), solver.num_blocks(), solver.stats().num_interface_dofs,
          solver.num_free(), RelativeDifference(sol.displacement, ref.displacement),
          RelativeDifference(sol.reaction, ref.reaction), RelativeDifference(x, x_ref));
      EXPECT_EQ(solver.stats().factored_blocks, solver.num_blocks());
      EXPECT_EQ(solver.stats().reused_blocks, 0);
      if (p.name != "one block") {
        EXPECT_GT(solver.stats().num_interface_dofs, 0);
      }
    }
  }
}

TEST(SubstructuredSolver, ComplianceColumnsEqualTheMonolithicCondensation) {
  for (int order : {1, 2}) {
    SCOPED_TRACE("order " + std::to_string(order));
    const TetMesh mesh = Bar(order);
    const BoundaryConditions bcs = BarConditions(mesh);
    const MaterialTable materials(kSteel);
    const StaticSolver reference(mesh, materials, bcs);
    const Surface surface = ExtractSurface(mesh);
    // Free surface nodes on the top face (compliance columns of the tool's candidates).
    std::vector<int> condensed;
    for (int v : surface.nodes)
      if (mesh.nodes(v, 2) > 0.08 - 1e-9 && mesh.nodes(v, 0) > 1e-9 &&
          reference.FreeIndex(3 * v) >= 0 && reference.FreeIndex(3 * v + 2) >= 0)
        condensed.push_back(v);
    const Compliance compliance(reference, surface.nodes, condensed);
    ASSERT_TRUE(compliance.status().converged);
    const Eigen::VectorXi blocks = VoronoiBlocks(mesh, 5, 4);
    const SubstructuredSolver solver(mesh, materials, bcs, blocks);
    Eigen::MatrixXd rhs = Eigen::MatrixXd::Zero(solver.num_free(), 3 * condensed.size());
    for (std::size_t b = 0; b < condensed.size(); ++b)
      for (int j = 0; j < 3; ++j) rhs(solver.FreeIndex(3 * condensed[b] + j), 3 * b + j) = 1.0;
    Eigen::MatrixXd x;
    ASSERT_TRUE(solver.SolveFree(rhs, &x).converged);
    Eigen::MatrixXd g(3 * surface.nodes.size(), 3 * condensed.size());
    for (std::size_t a = 0; a < surface.nodes.size(); ++a)
      for (int i = 0; i < 3; ++i) {
        const int fi = solver.FreeIndex(3 * surface.nodes[a] + i);
        g.row(3 * a + i).setZero();
        if (fi >= 0) g.row(3 * a + i) = x.row(fi);
      }
    EXPECT_LT(RelativeDifference(g, compliance.matrix()), kTolerance);
  }
}

TEST(SubstructuredSolver, ColumnCacheOnItEqualsTheCacheOnStaticSolverWhileSolvedConcurrently) {
  const TetMesh mesh = Bar(2);
  const BoundaryConditions bcs = BarConditions(mesh);
  const MaterialTable steel(kSteel);
  const StaticSolver reference(mesh, steel, bcs);
  const SubstructuredSolver solver(mesh, steel, bcs, SlabBlocks(mesh, 0, EvenPlanes(mesh, 0, 4)));
  const Surface surface = ExtractSurface(mesh);
  ColumnCacheSettings settings;
  settings.start_worker = false;
  ColumnCache expected(reference, mesh.nodes, surface.nodes, surface.nodes, settings);
  settings.start_worker = true;
  ColumnCache cache(solver, mesh.nodes, surface.nodes, surface.nodes, settings);
  // The worker solves near the free end while this thread solves with the same factors.
  cache.RequestNear(Eigen::Vector3d(0.4, 0.05, 0.08), 0.12);
  Eigen::MatrixXd rhs = Eigen::MatrixXd::Ones(solver.num_free(), 2), x;
  for (int i = 0; i < 20; ++i) ASSERT_TRUE(solver.SolveFree(rhs, &x).converged);
  ASSERT_TRUE(cache.WaitUntilIdle(120.0));
  cache.Stop();
  EXPECT_LT(RelativeDifference(cache.baseline(), expected.baseline()), kTolerance);
  std::vector<int> ready;
  for (int b = 0; b < cache.num_candidates(); ++b)
    if (cache.IsReady(b)) ready.push_back(b);
  ASSERT_GT(ready.size(), 10u);
  ASSERT_EQ(expected.ComputeNodes(ready), static_cast<int>(ready.size()));
  double max_diff = 0.0, max_value = 0.0;
  for (int b : ready) {
    ASSERT_TRUE(cache.Pin(b));
    ASSERT_TRUE(expected.Pin(b));
    for (int row = 0; row < 3 * cache.num_outputs(); ++row)
      for (int j = 0; j < 3; ++j) {
        max_diff = std::max(max_diff, std::abs(cache.Value(row, b, j) - expected.Value(row, b, j)));
        max_value = std::max(max_value, std::abs(expected.Value(row, b, j)));
      }
    cache.Unpin(b);
    expected.Unpin(b);
  }
  EXPECT_LT(max_diff, kTolerance * max_value);
}

TEST(SubstructuredSolver, SolveInBlocksGivesTheFullSolveOnTheBlocksAskedFor) {
  for (int order : {1, 2}) {
    SCOPED_TRACE("order " + std::to_string(order));
    const TetMesh mesh = Bar(order);
    const BoundaryConditions bcs = BarConditions(mesh);
    const SubstructuredSolver solver(mesh, MaterialTable(kSteel), bcs,
                                     SlabBlocks(mesh, 0, EvenPlanes(mesh, 0, 4)));
    ASSERT_TRUE(solver.factor_status().converged);
    // Unit forces on two free nodes interior to slab 2.
    std::vector<int> in_block;
    for (int v = 0; v < mesh.num_nodes(); ++v)
      if (solver.BlockOfNode(v) == 2 && solver.FreeIndex(3 * v) >= 0) in_block.push_back(v);
    ASSERT_GE(in_block.size(), 2u);
    Eigen::MatrixXd rhs = Eigen::MatrixXd::Zero(solver.num_free(), 6);
    for (int s = 0; s < 2; ++s)
      for (int j = 0; j < 3; ++j)
        rhs(solver.FreeIndex(3 * in_block[s * 3 % in_block.size()] + j), 3 * s + j) = 1.0;
    Eigen::MatrixXd full, part;
    ASSERT_TRUE(solver.SolveFree(rhs, &full).converged);
    ASSERT_TRUE(solver.SolveFreeInBlocks(rhs, {2}, &part).converged);
    double max_diff = 0.0, max_other = 0.0;
    for (int i = 0; i < solver.num_free(); ++i) {
      const int b = solver.BlockOfNode(solver.FreeDof(i) / 3);
      if (b == 2 || b == -1) {
        max_diff = std::max(max_diff, (part.row(i) - full.row(i)).cwiseAbs().maxCoeff());
      } else {
        max_other = std::max(max_other, part.row(i).cwiseAbs().maxCoeff());
      }
    }
    EXPECT_LT(max_diff, kTolerance * full.cwiseAbs().maxCoeff());
    EXPECT_EQ(max_other, 0.0);  // the other slabs' interiors were not solved
    EXPECT_EQ(max_diff, 0.0);   // the same operations as the full solve's, in the same order
    // Completed: the other slabs from the interface rows the part holds, then the residual.
    const SolveStatus done = solver.CompleteSolveFree(rhs, {2}, &part);
    ASSERT_TRUE(done.converged) << done.message;
    EXPECT_EQ(part, full);
    EXPECT_GT(done.residual, 0.0);
    EXPECT_LT(done.residual, StaticSolver::kResidualTolerance);
    // Through the FreeDofSolver interface (as ColumnCacheSettings::near_rows_first uses it).
    const FreeDofSolver& generic = solver;
    EXPECT_EQ(generic.num_row_groups(), 4);
    Eigen::MatrixXd again;
    ASSERT_TRUE(generic.SolveFreeInGroups(rhs, {2}, &again).converged);
    EXPECT_EQ(generic.RowGroupOfNode(in_block[0]), 2);
    Eigen::MatrixXd wrong_shape = Eigen::MatrixXd::Zero(3, 6);
    EXPECT_THROW(solver.CompleteSolveFree(rhs, {2}, &wrong_shape), std::invalid_argument);
    EXPECT_THROW(solver.SolveFreeInBlocks(rhs, {4}, &part), std::invalid_argument);
  }
}

// The bar with slab 2 edited: its interior nodes moved (interface and clamp untouched), its
// material changed, and every node renumbered.
struct EditedBar {
  TetMesh mesh;
  Eigen::VectorXi blocks;
  MaterialTable materials;
};

EditedBar EditSlab(const TetMesh& mesh, const Eigen::VectorXi& blocks,
                   const SubstructuredSolver& solver, int slab, unsigned seed) {
  EditedBar out{mesh, blocks, MaterialTable(kSteel)};
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(-0.008, 0.008);  // of 50 mm cells
  for (int v = 0; v < mesh.num_nodes(); ++v)
    if (solver.BlockOfNode(v) == slab)
      for (int i = 0; i < 3; ++i) out.mesh.nodes(v, i) += u(rng);
  // Midside nodes back on their edges' midpoints (straight-edged quadratic elements).
  if (mesh.NodesPerElement() == 10)
    for (int e = 0; e < mesh.num_elements(); ++e)
      for (int k = 0; k < 6; ++k)
        out.mesh.nodes.row(mesh.elements(e, 4 + k)) =
            0.5 * (out.mesh.nodes.row(mesh.elements(e, kTetEdges[k][0])) +
                   out.mesh.nodes.row(mesh.elements(e, kTetEdges[k][1])));
  for (int e = 0; e < mesh.num_elements(); ++e)
    if (blocks(e) == slab) out.mesh.regions(e) = 1;
  out.materials.Set(1, Material{7.0e10, 0.33});
  // Renumber the nodes by a random permutation: the blocks' content does not see it.
  std::vector<int> perm(mesh.num_nodes());
  std::iota(perm.begin(), perm.end(), 0);
  std::shuffle(perm.begin(), perm.end(), rng);
  TetMesh renumbered = out.mesh;
  for (int v = 0; v < mesh.num_nodes(); ++v) renumbered.nodes.row(perm[v]) = out.mesh.nodes.row(v);
  for (int e = 0; e < mesh.num_elements(); ++e)
    for (int j = 0; j < mesh.NodesPerElement(); ++j)
      renumbered.elements(e, j) = perm[out.mesh.elements(e, j)];
  out.mesh = renumbered;
  return out;
}

TEST(SubstructuredSolver, EditOfOneSlabRefactorsOnlyThatSlabAndEqualsFreshSolves) {
  for (int order : {1, 2}) {
    SCOPED_TRACE("order " + std::to_string(order));
    const TetMesh mesh = Bar(order);
    const Eigen::VectorXi blocks = SlabBlocks(mesh, 0, EvenPlanes(mesh, 0, 4));
    const MaterialTable steel(kSteel);
    const SubstructuredSolver before(mesh, steel, BarConditions(mesh), blocks);
    ASSERT_TRUE(before.factor_status().converged);
    const EditedBar edited = EditSlab(mesh, blocks, before, 2, 5);
    ASSERT_NO_THROW(edited.mesh.Validate());
    const BoundaryConditions bcs = BarConditions(edited.mesh);
    const SubstructuredSolver after(edited.mesh, edited.materials, bcs, edited.blocks, &before);
    ASSERT_TRUE(after.factor_status().converged) << after.factor_status().message;
    EXPECT_EQ(after.stats().factored_blocks, 1);
    EXPECT_EQ(after.stats().reused_blocks, 3);
    for (int b = 0; b < 4; ++b) {
      EXPECT_EQ(after.block_stats(b).reused, b != 2) << "block " << b;
      if (b != 2) {
        EXPECT_EQ(after.block_stats(b).key, before.block_stats(b).key);
      }
    }
    const SubstructuredSolver fresh(edited.mesh, edited.materials, bcs, edited.blocks);
    const StaticSolver monolithic(edited.mesh, edited.materials, bcs);
    const StaticSolution u_after = after.Solve(), u_fresh = fresh.Solve(),
                         u_mono = monolithic.Solve();
    ASSERT_TRUE(u_after.status.converged);
    EXPECT_LT(RelativeDifference(u_after.displacement, u_fresh.displacement), kTolerance);
    EXPECT_LT(RelativeDifference(u_after.displacement, u_mono.displacement), kTolerance);
    EXPECT_LT(RelativeDifference(u_after.reaction, u_mono.reaction), kTolerance);
    // The edit changed the answer (the test would pass trivially otherwise).
    const StaticSolution u_before = before.Solve();
    EXPECT_GT(RelativeDifference(u_mono.reaction.cwiseAbs(), u_before.reaction.cwiseAbs()), 1e-3);

    // A second edit of the same slab, reusing the edited solver: again one block.
    const EditedBar again = EditSlab(edited.mesh, edited.blocks, after, 2, 6);
    const SubstructuredSolver third(again.mesh, again.materials, BarConditions(again.mesh),
                                    again.blocks, &after);
    EXPECT_EQ(third.stats().factored_blocks, 1);
    const StaticSolver third_mono(again.mesh, again.materials, BarConditions(again.mesh));
    EXPECT_LT(RelativeDifference(third.Solve().displacement, third_mono.Solve().displacement),
              kTolerance);
  }
}

// A cache directory keeps factored blocks between solvers that share nothing in memory (two
// runs of a program): a second solver loads every block, solves bit for bit as the first, and
// after an edit of one slab loads the other three and factors that one. A damaged file (one
// flipped byte, or cut short) is refused with a note naming it, and its block is factored anew.
TEST(SubstructuredSolver, CacheDirectoryKeepsBlocksBetweenSolversAndRefusesDamagedFiles) {
  const std::filesystem::path dir =
      std::filesystem::path(::testing::TempDir()) / "spidarcad-substructure-cache";
  std::filesystem::remove_all(dir);
  for (int order : {1, 2}) {
    SCOPED_TRACE("order " + std::to_string(order));
    const TetMesh mesh = Bar(order);
    const Eigen::VectorXi blocks = SlabBlocks(mesh, 0, EvenPlanes(mesh, 0, 4));
    const MaterialTable steel(kSteel);
    const BoundaryConditions bcs = BarConditions(mesh);
    SubstructuredSolver first(mesh, steel, bcs, blocks, nullptr, dir);
    ASSERT_TRUE(first.factor_status().converged);
    EXPECT_EQ(first.stats().saved_blocks, 0);  // written in the background until waited for
    first.FinishCacheWrites();
    EXPECT_EQ(first.stats().factored_blocks, 4);
    EXPECT_EQ(first.stats().saved_blocks, 4);
    EXPECT_TRUE(first.stats().cache_notes.empty());

    const SubstructuredSolver second(mesh, steel, bcs, blocks, nullptr, dir);
    ASSERT_TRUE(second.factor_status().converged) << second.factor_status().message;
    EXPECT_EQ(second.stats().loaded_blocks, 4);
    EXPECT_EQ(second.stats().factored_blocks, 0);
    EXPECT_EQ(first.stats().saved_interface_groups, 3);  // the three planes
    EXPECT_EQ(second.stats().loaded_interface_groups, 3);
    EXPECT_EQ(second.stats().reused_blocks, 0);
    for (int b = 0; b < 4; ++b) {
      EXPECT_TRUE(second.block_stats(b).loaded) << "block " << b;
      // At least the diagonal of K_II and the dense Γ triangle; as the block that was saved.
      const double ni = first.block_stats(b).num_interior_dofs;
      const double ng = first.block_stats(b).num_interface_dofs;
      EXPECT_GE(first.block_stats(b).factor_nonzeros, ni + 0.5 * ng * (ng + 1)) << "block " << b;
      EXPECT_EQ(second.block_stats(b).factor_nonzeros, first.block_stats(b).factor_nonzeros);
    }
    const StaticSolution u1 = first.Solve(), u2 = second.Solve();
    ASSERT_TRUE(u2.status.converged);
    EXPECT_TRUE((u1.displacement.array() == u2.displacement.array()).all());
    EXPECT_TRUE((u1.reaction.array() == u2.reaction.array()).all());

    // An edit of slab 2: three blocks from the files, one factored (and saved).
    const EditedBar edited = EditSlab(mesh, blocks, first, 2, 5);
    const BoundaryConditions bcs2 = BarConditions(edited.mesh);
    SubstructuredSolver after(edited.mesh, edited.materials, bcs2, edited.blocks, nullptr, dir);
    ASSERT_TRUE(after.factor_status().converged);
    EXPECT_EQ(after.FinishCacheWrites().saved_blocks, 1);
    // Plane 0 lies between slabs 0 and 1, which kept their content: read; planes 1 and 2 made.
    EXPECT_EQ(after.stats().loaded_interface_groups, 1);
    EXPECT_EQ(after.stats().saved_interface_groups, 2);
    EXPECT_EQ(after.stats().loaded_blocks, 3);
    EXPECT_EQ(after.stats().factored_blocks, 1);
    EXPECT_FALSE(after.block_stats(2).loaded);
    const StaticSolver monolithic(edited.mesh, edited.materials, bcs2);
    EXPECT_LT(RelativeDifference(after.Solve().displacement, monolithic.Solve().displacement),
              kTolerance);

    // Damage the files of blocks 0 (a flipped byte in the factor values) and 3 (cut short).
    const std::filesystem::path f0 = dir / (HexKey(first.block_stats(0).key) + ".block");
    const std::filesystem::path f3 = dir / (HexKey(first.block_stats(3).key) + ".block");
    ASSERT_TRUE(std::filesystem::exists(f0));
    {
      const auto middle = static_cast<std::streamoff>(std::filesystem::file_size(f0) / 2);
      std::fstream f(f0, std::ios::in | std::ios::out | std::ios::binary);
      f.seekg(middle);
      const char c = static_cast<char>(f.get());
      f.seekp(middle);
      f.put(static_cast<char>(c ^ 0x5a));
    }
    std::filesystem::resize_file(f3, std::filesystem::file_size(f3) - 100);
    SubstructuredSolver damaged(mesh, steel, bcs, blocks, nullptr, dir);
    ASSERT_TRUE(damaged.factor_status().converged);
    damaged.FinishCacheWrites();
    EXPECT_EQ(damaged.stats().loaded_blocks, 2);
    EXPECT_EQ(damaged.stats().factored_blocks, 2);
    ASSERT_EQ(damaged.stats().cache_notes.size(), 2u);
    EXPECT_NE(damaged.stats().cache_notes[0].find("block 0: refused " + f0.string()),
              std::string::npos)
        << damaged.stats().cache_notes[0];
    EXPECT_NE(damaged.stats().cache_notes[0].find("checksum"), std::string::npos);
    EXPECT_NE(damaged.stats().cache_notes[1].find("block 3: refused " + f3.string()),
              std::string::npos)
        << damaged.stats().cache_notes[1];
    EXPECT_TRUE((damaged.Solve().displacement.array() == u1.displacement.array()).all());
    // The refused files were rewritten: a fourth solver loads all four again.
    const SubstructuredSolver fourth(mesh, steel, bcs, blocks, nullptr, dir);
    EXPECT_EQ(fourth.stats().loaded_blocks, 4);
  }
  // A directory that cannot be written (a file in its place) is noted, not thrown.
  const std::filesystem::path blocked = dir / "not-a-directory";
  { std::ofstream(blocked) << "x"; }
  const TetMesh mesh = Bar(1);
  SubstructuredSolver unsaved(mesh, MaterialTable(kSteel), BarConditions(mesh),
                              SlabBlocks(mesh, 0, EvenPlanes(mesh, 0, 2)), nullptr, blocked);
  EXPECT_TRUE(unsaved.factor_status().converged);
  unsaved.FinishCacheWrites();
  EXPECT_EQ(unsaved.stats().saved_blocks, 0);
  ASSERT_EQ(unsaved.stats().cache_notes.size(), 3u);  // two blocks, one plane
  EXPECT_NE(unsaved.stats().cache_notes[0].find("block 0: not saved"), std::string::npos)
      << unsaved.stats().cache_notes[0];
  EXPECT_NE(unsaved.stats().cache_notes[2].find("interface plane 0: not saved"), std::string::npos)
      << unsaved.stats().cache_notes[2];
  std::filesystem::remove_all(dir);
}

// Slabs make the interface a chain of planes (three for four slabs), factored plane by plane
// from both ends. An edit keeps the reuse solver's forward factor of the planes before it and its
// backward factor of the planes after it, refactors only the planes the edited slab touches
// (the first or last slab: one plane; a middle one: two) and twists the factor at the first
// plane it changed, and the solves equal the monolithic solve of the edited bar. Edits made one
// after the other each reuse the solver of the edit before. Voronoi blocks are no chain: CHOLMOD
// factors S.
TEST(SubstructuredSolver, EditOfASlabRefactorsOnlyThePlanesItTouches) {
  for (int order : {1, 2}) {
    const TetMesh mesh = Bar(order);
    const Eigen::VectorXi blocks = SlabBlocks(mesh, 0, EvenPlanes(mesh, 0, 4));
    const MaterialTable steel(kSteel);
    const SubstructuredSolver before(mesh, steel, BarConditions(mesh), blocks);
    ASSERT_TRUE(before.factor_status().converged);
    EXPECT_EQ(before.stats().interface_groups, 3);
    EXPECT_EQ(before.stats().reused_interface_groups, 0);
    EXPECT_EQ(before.stats().factored_interface_groups, 3);
    EXPECT_EQ(before.stats().interface_twist, 2);
    for (int slab = 0; slab < 4; ++slab) {
      SCOPED_TRACE("order " + std::to_string(order) + ", slab " + std::to_string(slab));
      const EditedBar edited = EditSlab(mesh, blocks, before, slab, 7 + slab);
      const BoundaryConditions bcs = BarConditions(edited.mesh);
      const SubstructuredSolver after(edited.mesh, edited.materials, bcs, edited.blocks, &before);
      ASSERT_TRUE(after.factor_status().converged) << after.factor_status().message;
      // The reuse solver's factor was completed from both ends for this.
      EXPECT_EQ(before.PrepareReuse().factored_groups, 3);
      EXPECT_EQ(after.stats().factored_blocks, 1);
      EXPECT_EQ(after.stats().interface_groups, 3);
      EXPECT_EQ(after.stats().factored_interface_groups, slab == 0 || slab == 3 ? 1 : 2);
      EXPECT_EQ(after.stats().reused_interface_groups, std::max(0, slab - 1));
      EXPECT_EQ(after.stats().reused_trailing_interface_groups, std::max(0, 2 - slab));
      EXPECT_EQ(after.stats().interface_twist, slab <= 1 ? 0 : 2);
      // The first plane refactored from each side keeps its coupling to the plane beyond it
      // when the slab between them is unchanged (every edit here has one such plane).
      EXPECT_EQ(after.stats().kept_interface_couplings, 1);
      const SubstructuredSolver fresh(edited.mesh, edited.materials, bcs, edited.blocks);
      EXPECT_EQ(fresh.stats().kept_interface_couplings, 0);
      const StaticSolver monolithic(edited.mesh, edited.materials, bcs);
      const StaticSolution u_after = after.Solve(), u_mono = monolithic.Solve();
      ASSERT_TRUE(u_after.status.converged) << u_after.status.message;
      // Twisted at the last plane the factor is the one made from scratch, bit for bit.
      if (slab >= 2) {
        EXPECT_EQ(fresh.Solve().displacement, u_after.displacement);
      }
      EXPECT_LT(RelativeDifference(u_after.displacement, u_mono.displacement), kTolerance);
      EXPECT_LT(RelativeDifference(u_after.reaction, u_mono.reaction), kTolerance);
      EXPECT_GT(RelativeDifference(u_mono.reaction.cwiseAbs(), before.Solve().reaction.cwiseAbs()),
                1e-4);
      // A solver reusing `after` with nothing changed shares every plane and the twist.
      const SubstructuredSolver same(edited.mesh, edited.materials, bcs, edited.blocks, &after);
      EXPECT_EQ(same.stats().reused_interface_groups, 3);
      EXPECT_EQ(same.stats().factored_interface_groups, 0);
      EXPECT_EQ(same.stats().factored_blocks, 0);
      EXPECT_EQ(same.Solve().displacement, u_after.displacement);
    }
    // Edits one after the other, each reusing the last: the clamped slab, the free end, a
    // middle slab, the clamped slab again.
    std::vector<std::unique_ptr<SubstructuredSolver>> chain;
    std::vector<EditedBar> meshes;
    meshes.reserve(4);  // the edits below point into it
    const SubstructuredSolver* last = &before;
    const TetMesh* last_mesh = &mesh;
    const Eigen::VectorXi* last_blocks = &blocks;
    for (const auto& [slab, planes] :
         std::vector<std::pair<int, int>>{{0, 1}, {3, 1}, {1, 2}, {0, 1}}) {
      SCOPED_TRACE("order " + std::to_string(order) + ", then slab " + std::to_string(slab));
      meshes.push_back(EditSlab(*last_mesh, *last_blocks, *last, slab, 31 + slab));
      const EditedBar& edited = meshes.back();
      const BoundaryConditions bcs = BarConditions(edited.mesh);
      chain.push_back(std::make_unique<SubstructuredSolver>(edited.mesh, edited.materials, bcs,
                                                            edited.blocks, last));
      ASSERT_TRUE(chain.back()->factor_status().converged);
      EXPECT_EQ(chain.back()->stats().factored_blocks, 1);
      EXPECT_EQ(chain.back()->stats().factored_interface_groups, planes);
      const StaticSolution u = chain.back()->Solve();
      const StaticSolution u_mono = StaticSolver(edited.mesh, edited.materials, bcs).Solve();
      EXPECT_LT(RelativeDifference(u.displacement, u_mono.displacement), kTolerance);
      EXPECT_LT(RelativeDifference(u.reaction, u_mono.reaction), kTolerance);
      last = chain.back().get();
      last_mesh = &edited.mesh;
      last_blocks = &edited.blocks;
    }
  }
  const TetMesh mesh = Bar(1);
  const SubstructuredSolver voronoi(mesh, MaterialTable(kSteel), BarConditions(mesh),
                                    VoronoiBlocks(mesh, 7, 2));
  ASSERT_TRUE(voronoi.factor_status().converged);
  EXPECT_EQ(voronoi.stats().interface_groups, 0);
}

// PrepareReuse fills in what a twisted factor's solves do not read, so it may run beside them:
// solves during it and after it equal the solve before it bit for bit, and it runs once.
TEST(SubstructuredSolver, PrepareReuseRunsBesideSolvesAndOnce) {
  const TetMesh mesh = Bar(1);
  const Eigen::VectorXi blocks = SlabBlocks(mesh, 0, EvenPlanes(mesh, 0, 4));
  const SubstructuredSolver before(mesh, MaterialTable(kSteel), BarConditions(mesh), blocks);
  const EditedBar edited = EditSlab(mesh, blocks, before, 1, 5);
  const SubstructuredSolver after(edited.mesh, edited.materials, BarConditions(edited.mesh),
                                  edited.blocks, &before);
  ASSERT_TRUE(after.factor_status().converged);
  ASSERT_EQ(after.stats().interface_twist, 0);  // the middle of the chain: not a plain factor
  const StaticSolution first = after.Solve();
  std::atomic<bool> done{false};
  std::thread prepare([&] {
    after.PrepareReuse();
    done = true;
  });
  do {
    EXPECT_EQ(after.Solve().displacement, first.displacement);
  } while (!done);
  prepare.join();
  // Both factors whole: the three forward planes from the twist on, and the backward one at
  // the twist (plane 1 was factored backward by the constructor, plane 2 kept).
  const InterfacePreparation& p = after.PrepareReuse();
  EXPECT_EQ(p.factored_groups, 4);
  EXPECT_TRUE(p.notes.empty());
  EXPECT_EQ(after.Solve().displacement, first.displacement);
}

// A twisted factor writes no forward planes to the cache directory when it is made (it has none
// past the twist); PrepareReuse factors them and writes them there, so that a solver in another
// process, sharing nothing in memory, reads every block and every plane of the edited bar.
TEST(SubstructuredSolver, PrepareReuseWritesTheForwardPlanesOfATwistedFactor) {
  const std::filesystem::path dir =
      std::filesystem::path(::testing::TempDir()) / "spidarcad-substructure-twist-cache";
  std::filesystem::remove_all(dir);
  const TetMesh mesh = Bar(1);
  const Eigen::VectorXi blocks = SlabBlocks(mesh, 0, EvenPlanes(mesh, 0, 4));
  SubstructuredSolver before(mesh, MaterialTable(kSteel), BarConditions(mesh), blocks, nullptr,
                             dir);
  EXPECT_EQ(before.FinishCacheWrites().saved_interface_groups, 3);
  const EditedBar edited = EditSlab(mesh, blocks, before, 0, 3);  // the clamped slab
  const BoundaryConditions bcs = BarConditions(edited.mesh);
  SubstructuredSolver after(edited.mesh, edited.materials, bcs, edited.blocks, &before, dir);
  ASSERT_TRUE(after.factor_status().converged);
  EXPECT_EQ(after.stats().interface_twist, 0);
  EXPECT_EQ(after.stats().factored_interface_groups, 1);
  EXPECT_EQ(after.stats().loaded_interface_groups, 0);  // every plane file names plane 0's slab
  EXPECT_EQ(after.FinishCacheWrites().saved_blocks, 1);
  EXPECT_EQ(after.stats().saved_interface_groups, 0);
  const InterfacePreparation& p = after.PrepareReuse();
  EXPECT_EQ(p.factored_groups, 4);  // three forward, the backward one at the twist
  EXPECT_EQ(p.saved_planes, 3);
  EXPECT_TRUE(p.notes.empty());
  const SubstructuredSolver reread(edited.mesh, edited.materials, bcs, edited.blocks, nullptr, dir);
  ASSERT_TRUE(reread.factor_status().converged);
  EXPECT_EQ(reread.stats().loaded_blocks, 4);
  EXPECT_EQ(reread.stats().loaded_interface_groups, 3);
  EXPECT_EQ(reread.stats().factored_interface_groups, 0);
  const StaticSolution u = reread.Solve(), u_twisted = after.Solve();
  const StaticSolution u_mono = StaticSolver(edited.mesh, edited.materials, bcs).Solve();
  EXPECT_LT(RelativeDifference(u.displacement, u_mono.displacement), kTolerance);
  EXPECT_LT(RelativeDifference(u_twisted.displacement, u.displacement), kTolerance);
  std::filesystem::remove_all(dir);
}

TEST(SubstructuredSolver, ChangedClampRefactorsTheBlocksItTouches) {
  const TetMesh mesh = Bar(1);
  const Eigen::VectorXi blocks = SlabBlocks(mesh, 0, EvenPlanes(mesh, 0, 4));
  const MaterialTable steel(kSteel);
  const SubstructuredSolver before(mesh, steel, BarConditions(mesh), blocks);
  // Same constraints with other values and loads: everything is reused.
  BoundaryConditions other_loads(mesh.num_nodes());
  const BoundaryConditions original = BarConditions(mesh);
  for (const auto& [d, value] : original.prescribed())
    other_loads.PrescribeDof(d / 3, d % 3, 3.0 * value);
  other_loads.AddPointLoad(mesh.num_nodes() - 1, Eigen::Vector3d(0, 0, -1e3));
  const SubstructuredSolver same(mesh, steel, other_loads, blocks, &before);
  EXPECT_EQ(same.stats().factored_blocks, 0);
  EXPECT_EQ(same.stats().reused_blocks, 4);
  EXPECT_LT(RelativeDifference(same.Solve().displacement,
                               StaticSolver(mesh, steel, other_loads).Solve().displacement),
            kTolerance);
  // A node of the last slab held as well: that slab is factored again.
  BoundaryConditions held = BarConditions(mesh);
  const std::vector<int> end =
      NodesInBox(mesh, Eigen::Vector3d(0.4 - 1e-9, -1, -1), Eigen::Vector3d(1, 1, 1));
  held.FixNode(end.front());
  const SubstructuredSolver clamped(mesh, steel, held, blocks, &before);
  EXPECT_EQ(clamped.stats().factored_blocks, 1);
  EXPECT_FALSE(clamped.block_stats(3).reused);
}

// Strips: the first of four slabs of the bar cut across y into two blocks that share the slab's
// place. Their common dofs (the strip plane) join the first plane's group, so S is a chain of
// three groups (without places, no chain: CHOLMOD factors S), and both solve as the monolithic
// solver does. An edit of one strip refactors that strip and the first group only.
TEST(SubstructuredSolver, StripsOfASlabSharingItsPlaceKeepTheChain) {
  for (int order : {1, 2}) {
    SCOPED_TRACE("order " + std::to_string(order));
    const TetMesh mesh = Bar(order);
    const Eigen::VectorXi slabs = SlabBlocks(mesh, 0, EvenPlanes(mesh, 0, 4));
    Eigen::VectorXi blocks = slabs;
    for (int e = 0; e < mesh.num_elements(); ++e)
      blocks(e) = slabs(e) == 0 ? (Centroid(mesh, e).y() < 0.05 ? 0 : 1) : slabs(e) + 1;
    const std::vector<int> places = {0, 0, 1, 2, 3};
    const MaterialTable steel(kSteel);
    const BoundaryConditions bcs = BarConditions(mesh);
    const StaticSolution u_mono = StaticSolver(mesh, steel, bcs).Solve();
    const SubstructuredSolver chain(mesh, steel, bcs, blocks, nullptr, {}, nullptr, places);
    const SubstructuredSolver general(mesh, steel, bcs, blocks);
    ASSERT_TRUE(chain.factor_status().converged) << chain.factor_status().message;
    EXPECT_EQ(chain.stats().interface_groups, 3);
    EXPECT_EQ(general.stats().interface_groups, 0);
    for (const SubstructuredSolver* s : {&chain, &general}) {
      const StaticSolution u = s->Solve();
      ASSERT_TRUE(u.status.converged) << u.status.message;
      EXPECT_LT(RelativeDifference(u.displacement, u_mono.displacement), kTolerance);
      EXPECT_LT(RelativeDifference(u.reaction, u_mono.reaction), kTolerance);
    }
    // Strip 1 (y > 0.05) made of another material: it and the first group are factored again.
    MaterialTable edited(kSteel);
    edited.Set(1, Material{7.0e10, 0.33});
    TetMesh regions = mesh;
    for (int e = 0; e < mesh.num_elements(); ++e)
      if (blocks(e) == 1) regions.regions(e) = 1;
    const SubstructuredSolver after(regions, edited, bcs, blocks, &chain, {}, nullptr, places);
    ASSERT_TRUE(after.factor_status().converged) << after.factor_status().message;
    EXPECT_EQ(after.stats().factored_blocks, 1);
    EXPECT_EQ(after.stats().factored_interface_groups, 1);
    EXPECT_EQ(after.stats().reused_trailing_interface_groups, 2);
    const StaticSolution u_after = after.Solve();
    const StaticSolution u_after_mono = StaticSolver(regions, edited, bcs).Solve();
    EXPECT_LT(RelativeDifference(u_after.displacement, u_after_mono.displacement), kTolerance);
    // Places: one per block, none negative.
    EXPECT_THROW(SubstructuredSolver(mesh, steel, bcs, blocks, nullptr, {}, nullptr, {0, 0, 1}),
                 std::invalid_argument);
    EXPECT_THROW(
        SubstructuredSolver(mesh, steel, bcs, blocks, nullptr, {}, nullptr, {0, -1, 1, 2, 3}),
        std::invalid_argument);
  }
}

TEST(SubstructuredSolver, RefusesBadBlockLabelsAndUnconstrainedModels) {
  const TetMesh mesh = Bar(1);
  const MaterialTable steel(kSteel);
  const BoundaryConditions bcs = BarConditions(mesh);
  EXPECT_THROW(SubstructuredSolver(mesh, steel, bcs, Eigen::VectorXi::Zero(3)),
               std::invalid_argument);
  Eigen::VectorXi negative = Eigen::VectorXi::Zero(mesh.num_elements());
  negative(7) = -1;
  try {
    SubstructuredSolver solver(mesh, steel, bcs, negative);
    FAIL() << "a negative label was accepted";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("element 7"), std::string::npos) << e.what();
  }
  try {
    SubstructuredSolver solver(mesh, steel, BoundaryConditions(mesh.num_nodes()),
                               Eigen::VectorXi::Zero(mesh.num_elements()));
    FAIL() << "an unconstrained model was accepted";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("no constraint"), std::string::npos) << e.what();
  }
  EXPECT_THROW(SlabBlocks(mesh, 3, {}), std::invalid_argument);
  EXPECT_THROW(SlabBlocks(mesh, 0, {0.2, 0.1}), std::invalid_argument);
}

TEST(SubstructuredSolver, ReportsTheBlockWhoseInteriorIsAMechanism) {
  // Tetrahedron A (block 0, three corners clamped) and tetrahedron B (block 1) share the edge
  // 0-1 only: B turns about that edge, a mechanism the rigid-mode check cannot see (A and B are
  // one part through nodes 0 and 1, and the part is held).
  TetMesh mesh;
  mesh.nodes.resize(6, 3);
  mesh.nodes << 0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0, 1,  // A: 0 1 2 3
      0, -1, 0, 0, 0, -1;                            // B: 0 1 4 5
  mesh.elements.resize(2, 4);
  mesh.elements << 0, 1, 2, 3, 0, 5, 1, 4;
  if (mesh.CornerVolume(1) < 0) std::swap(mesh.elements(1, 2), mesh.elements(1, 3));
  mesh.regions = Eigen::VectorXi::Zero(2);
  BoundaryConditions bcs(6);
  bcs.FixNodes({0, 2, 3});
  Eigen::VectorXi blocks(2);
  blocks << 0, 1;
  // Node 1 is the interface; block 1's interior (nodes 4, 5) hinges on the edge 0-1.
  const SubstructuredSolver solver(mesh, MaterialTable(kSteel), bcs, blocks);
  EXPECT_FALSE(solver.factor_status().converged);
  EXPECT_NE(solver.factor_status().message.find("block 1"), std::string::npos)
      << solver.factor_status().message;
  Eigen::MatrixXd x;
  EXPECT_FALSE(solver.SolveFree(Eigen::MatrixXd::Zero(solver.num_free(), 1), &x).converged);
}

TEST(SubstructuredSolver, RaisedCancelFlagStopsTheFactorisationAndALoweredOneChangesNothing) {
  const TetMesh mesh = Bar(1);
  const Eigen::VectorXi blocks = SlabBlocks(mesh, 0, EvenPlanes(mesh, 0, 4));
  const MaterialTable steel(kSteel);
  const BoundaryConditions bcs = BarConditions(mesh);
  std::atomic<bool> cancel{true};
  EXPECT_THROW(SubstructuredSolver(mesh, steel, bcs, blocks, nullptr, {}, &cancel),
               SubstructureCancelled);
  // With a cache directory the cancel comes before any block is factored or written.
  const std::filesystem::path dir =
      std::filesystem::path(::testing::TempDir()) / "spidarcad-substructure-cancel";
  std::filesystem::remove_all(dir);
  EXPECT_THROW(SubstructuredSolver(mesh, steel, bcs, blocks, nullptr, dir, &cancel),
               SubstructureCancelled);
  EXPECT_TRUE(!std::filesystem::exists(dir) || std::filesystem::is_empty(dir));
  // Every block reused: nothing left to factor but the interface, which the flag still stops.
  const SubstructuredSolver plain(mesh, steel, bcs, blocks);
  EXPECT_THROW(SubstructuredSolver(mesh, steel, bcs, blocks, &plain, {}, &cancel),
               SubstructureCancelled);
  cancel = false;
  const SubstructuredSolver lowered(mesh, steel, bcs, blocks, nullptr, {}, &cancel);
  ASSERT_TRUE(lowered.factor_status().converged);
  const StaticSolution a = plain.Solve(), b = lowered.Solve();
  EXPECT_EQ(a.displacement, b.displacement);  // bit for bit
}

}  // namespace
}  // namespace spidarcad::fem
