// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
// fem::SubstructuredSolver on the platform (assets/scenes/platform.json, meshed for FE as FE mode
// meshes it, clamped at its wall face as FeModel::Build clamps it, 200 N down on the free end):
// slabs cut across its long axis x, both element orders, against the monolithic StaticSolver,
// and an edit of one slab (its interior nodes moved, its material changed) that re-does only
// that slab and the interface system.
#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <random>
#include <string>
#include <vector>

#include "scene/fe_model.h"
#include "spidarcad/fem/boundary.h"
#include "spidarcad/fem/condensation.h"
#include "spidarcad/fem/static_solver.h"
#include "spidarcad/fem/substructure.h"

namespace spidarcad::app {
namespace {

constexpr double kCell = 0.0125;  // FE mode's default cell for the platform
constexpr double kTolerance = 1e-9;
constexpr int kSlabs = 5;

// The mesh with every region label 0 (FeModel::Build's single material).
fem::TetMesh LinearPlatform() {
  fem::TetMesh mesh = MeshSceneSolidForFe(PlatformScenePath(), "platform", kCell);
  mesh.regions.setZero();
  return mesh;
}

const fem::TetMesh& PlatformMesh(int order) {
  static const fem::TetMesh linear = LinearPlatform();
  static const fem::TetMesh quadratic = fem::MakeQuadratic(linear);
  return order == 1 ? linear : quadratic;
}

fem::BoundaryConditions PlatformConditions(const fem::TetMesh& mesh) {
  fem::BoundaryConditions bcs(mesh.num_nodes());
  bcs.FixNodes(MinXFaceNodes(mesh));
  const std::vector<int> end =
      fem::NodesInBox(mesh, Eigen::Vector3d(0.296, -1, -1), Eigen::Vector3d(1, 1, 1));
  for (int v : end) bcs.AddPointLoad(v, Eigen::Vector3d(0, 0, -200.0 / end.size()));
  return bcs;
}

double RelativeDifference(const Eigen::MatrixXd& a, const Eigen::MatrixXd& b) {
  return (a - b).norm() / std::max(b.norm(), 1e-300);
}

TEST(SubstructurePlatform, SlabSolveAndColumnsEqualTheMonolithicSolveBothOrders) {
  for (int order : {1, 2}) {
    SCOPED_TRACE("order " + std::to_string(order));
    const fem::TetMesh& mesh = PlatformMesh(order);
    const fem::BoundaryConditions bcs = PlatformConditions(mesh);
    const fem::MaterialTable steel(fem::Material{2.0e11, 0.3});
    const fem::StaticSolver reference(mesh, steel, bcs);
    ASSERT_TRUE(reference.factor_status().converged);
    const Eigen::VectorXi blocks = fem::SlabBlocks(mesh, 0, fem::EvenPlanes(mesh, 0, kSlabs));
    const fem::SubstructuredSolver solver(mesh, steel, bcs, blocks);
    ASSERT_TRUE(solver.factor_status().converged) << solver.factor_status().message;
    const fem::StaticSolution ref = reference.Solve(), sol = solver.Solve();
    ASSERT_TRUE(sol.status.converged) << sol.status.message;
    EXPECT_LT(RelativeDifference(sol.displacement, ref.displacement), kTolerance);
    EXPECT_LT(RelativeDifference(sol.reaction, ref.reaction), kTolerance);
    // Compliance columns of plate-top nodes in each slab, observed on the whole surface.
    const fem::Surface surface = fem::ExtractSurface(mesh);
    std::vector<int> condensed;
    std::vector<char> slab_seen(kSlabs, 0);
    for (int v : surface.nodes) {
      const int b = solver.BlockOfNode(v);
      if (b < 0 || slab_seen[b] || mesh.nodes(v, 2) < 0.0099 || reference.FreeIndex(3 * v) < 0)
        continue;
      slab_seen[b] = 1;
      condensed.push_back(v);
    }
    ASSERT_GE(condensed.size(), 4u);
    const fem::Compliance compliance(reference, surface.nodes, condensed);
    Eigen::MatrixXd rhs = Eigen::MatrixXd::Zero(solver.num_free(), 3 * condensed.size());
    for (std::size_t c = 0; c < condensed.size(); ++c)
      for (int j = 0; j < 3; ++j) rhs(solver.FreeIndex(3 * condensed[c] + j), 3 * c + j) = 1.0;
    Eigen::MatrixXd x;
    ASSERT_TRUE(solver.SolveFree(rhs, &x).converged);
    Eigen::MatrixXd g(3 * surface.nodes.size(), x.cols());
    for (std::size_t a = 0; a < surface.nodes.size(); ++a)
      for (int i = 0; i < 3; ++i) {
        const int fi = solver.FreeIndex(3 * surface.nodes[a] + i);
        g.row(3 * a + i).setZero();
        if (fi >= 0) g.row(3 * a + i) = x.row(fi);
      }
    EXPECT_LT(RelativeDifference(g, compliance.matrix()), kTolerance);
    // The contact block of one node from its own slab's factor and S alone.
    const int v = condensed[1], b = solver.BlockOfNode(v);
    Eigen::MatrixXd one = rhs.middleCols(3, 3), local;
    ASSERT_TRUE(solver.SolveFreeInBlocks(one, {b}, &local).converged);
    Eigen::Matrix3d g_vv;
    for (int i = 0; i < 3; ++i) g_vv.row(i) = local.row(solver.FreeIndex(3 * v + i));
    EXPECT_LT((g_vv - compliance.Block(1, 1)).norm(), kTolerance * compliance.Block(1, 1).norm());
  }
}

TEST(SubstructurePlatform, EditOfOneSlabRefactorsOnlyThatSlabBothOrders) {
  for (int order : {1, 2}) {
    SCOPED_TRACE("order " + std::to_string(order));
    const fem::TetMesh& mesh = PlatformMesh(order);
    const fem::MaterialTable steel(fem::Material{2.0e11, 0.3});
    const Eigen::VectorXi blocks = fem::SlabBlocks(mesh, 0, fem::EvenPlanes(mesh, 0, kSlabs));
    const fem::SubstructuredSolver before(mesh, steel, PlatformConditions(mesh), blocks);
    ASSERT_TRUE(before.factor_status().converged);
    // Edit slab 3: interior nodes moved by up to 0.4 mm, material aluminium.
    fem::TetMesh edited = mesh;
    std::mt19937 rng(7);
    std::uniform_real_distribution<double> u(-4e-4, 4e-4);
    for (int v = 0; v < mesh.num_nodes(); ++v)
      if (before.BlockOfNode(v) == 3)
        for (int i = 0; i < 3; ++i) edited.nodes(v, i) += u(rng);
    if (order == 2)  // midside nodes back on their edges' midpoints
      for (int e = 0; e < mesh.num_elements(); ++e)
        for (int k = 0; k < 6; ++k)
          edited.nodes.row(mesh.elements(e, 4 + k)) =
              0.5 * (edited.nodes.row(mesh.elements(e, fem::kTetEdges[k][0])) +
                     edited.nodes.row(mesh.elements(e, fem::kTetEdges[k][1])));
    for (int e = 0; e < mesh.num_elements(); ++e)
      if (blocks(e) == 3) edited.regions(e) = 1;
    fem::MaterialTable materials(fem::Material{2.0e11, 0.3});
    materials.Set(1, fem::Material{7.0e10, 0.33});
    ASSERT_NO_THROW(edited.Validate());
    const fem::BoundaryConditions bcs = PlatformConditions(edited);
    const fem::SubstructuredSolver after(edited, materials, bcs, blocks, &before);
    ASSERT_TRUE(after.factor_status().converged) << after.factor_status().message;
    EXPECT_EQ(after.stats().factored_blocks, 1);
    EXPECT_EQ(after.stats().reused_blocks, kSlabs - 1);
    EXPECT_FALSE(after.block_stats(3).reused);
    const fem::StaticSolver monolithic(edited, materials, bcs);
    const fem::StaticSolution u_after = after.Solve(), u_mono = monolithic.Solve();
    ASSERT_TRUE(u_after.status.converged) << u_after.status.message;
    EXPECT_LT(RelativeDifference(u_after.displacement, u_mono.displacement), kTolerance);
    EXPECT_LT(RelativeDifference(u_after.reaction, u_mono.reaction), kTolerance);
    std::printf(
        "order %d: %d free dofs, %d interface dofs; update %.3f s (block assembly %.3f, "
        "factor %.3f, S_b %.3f, S %.3f), full %.3f s\n",
        order, after.num_free(), after.stats().num_interface_dofs, after.stats().wall_seconds,
        after.stats().block_assembly_seconds, after.stats().block_factor_seconds,
        after.stats().block_schur_seconds, after.stats().interface_seconds,
        before.stats().wall_seconds);
  }
}

}  // namespace
}  // namespace spidarcad::app
