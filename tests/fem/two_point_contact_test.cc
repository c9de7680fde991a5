// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
//
// Grasp: a part squeezed between the two grip poles gives two contact patches on opposite
// faces, solved together in one condensed system.
#include <gtest/gtest.h>

#include <memory>
#include <vector>

#include "spidarcad/fem/column_cache.h"
#include "spidarcad/fem/condensation.h"

namespace spidarcad::fem {
namespace {

constexpr double kLength = 0.3, kSide = 0.1, kSqueeze = 1e-4;

// A bar 0.3 × 0.1 × 0.1 m held at mid-length by two clamped lines of nodes (bottom and top
// edges of the section x = 0.15), so that its two halves stay coupled through the section.
// Candidates: the nodes of the end faces x = 0 and x = 0.3.
struct Bar {
  TetMesh mesh;
  MaterialTable materials{Material{2.0e9, 0.3}};
  std::unique_ptr<BoundaryConditions> bcs;
  std::unique_ptr<StaticSolver> solver;
  std::unique_ptr<Compliance> compliance;
  std::vector<int> outputs, candidates, left, right;

  explicit Bar(int order) {
    BoxMeshSettings s;
    s.upper = Eigen::Vector3d(kLength, kSide, kSide);
    s.nx = 12;
    s.ny = s.nz = 4;
    s.order = order;
    mesh = MakeBoxMesh(s);
    bcs = std::make_unique<BoundaryConditions>(mesh.num_nodes());
    const double mid = kLength / 2;
    FixNodesInBox(mesh, Eigen::Vector3d(mid, -1, -1e-9), Eigen::Vector3d(mid, 1, 1e-9), bcs.get());
    FixNodesInBox(mesh, Eigen::Vector3d(mid, -1, kSide), Eigen::Vector3d(mid, 1, kSide), bcs.get());
    solver = std::make_unique<StaticSolver>(mesh, materials, *bcs);
    outputs = ExtractSurface(mesh).nodes;
    std::vector<int> faces =
        NodesInBox(mesh, Eigen::Vector3d(-1, -1, -1), Eigen::Vector3d(0, 1, 1));
    const auto far = NodesInBox(mesh, Eigen::Vector3d(kLength, -1, -1), Eigen::Vector3d(2, 1, 1));
    faces.insert(faces.end(), far.begin(), far.end());
    // Patches: the face centre and its four nearest face nodes (a plus of five nodes). Only
    // the patch nodes are condensed.
    const double radius = order == 1 ? 0.026 : 0.013;
    for (int v : faces) {
      const Eigen::Vector3d p = mesh.nodes.row(v).transpose();
      if ((p.tail<2>() - Eigen::Vector2d(kSide / 2, kSide / 2)).norm() > radius) continue;
      (p.x() < mid ? left : right).push_back(static_cast<int>(candidates.size()));
      candidates.push_back(v);
    }
    compliance = std::make_unique<Compliance>(*solver, outputs, candidates);
  }
  // Squeeze: the left patch moves +x, the right one −x (into the part).
  Eigen::Vector3d Target(int b) const {
    const double x = mesh.nodes(candidates[b], 0);
    return Eigen::Vector3d(x < kLength / 2 ? kSqueeze : -kSqueeze, 0, 0);
  }
};

// Forces (N, on the body) at the pushed nodes and surface displacements from a full sparse
// solve in which the pushed nodes are prescribed.
void FullSolve(const Bar& bar, const std::vector<int>& pushed, Eigen::VectorXd* forces,
               Eigen::VectorXd* surface) {
  BoundaryConditions bcs = *bar.bcs;
  for (int b : pushed) bcs.PrescribeNode(bar.candidates[b], bar.Target(b));
  const StaticSolver full(bar.mesh, bar.materials, bcs);
  const StaticSolution sol = full.Solve();
  ASSERT_TRUE(sol.status.converged) << sol.status.message;
  forces->resize(3 * pushed.size());
  for (size_t s = 0; s < pushed.size(); ++s)
    forces->segment<3>(3 * s) = sol.reaction.segment<3>(3 * bar.candidates[pushed[s]]);
  surface->resize(3 * bar.outputs.size());
  for (size_t a = 0; a < bar.outputs.size(); ++a)
    surface->segment<3>(3 * a) = sol.displacement.segment<3>(3 * bar.outputs[a]);
}

// Condensed solve of the pushed nodes together (eager compliance).
void CondensedSolve(const Bar& bar, const std::vector<int>& pushed, Eigen::VectorXd* forces,
                    Eigen::VectorXd* surface) {
  ContactSolver solver(*bar.compliance, static_cast<int>(pushed.size()));
  Eigen::VectorXd target(3 * pushed.size());
  for (size_t s = 0; s < pushed.size(); ++s) {
    ASSERT_EQ(solver.Add(pushed[s]), ContactStatus::kOk);
    target.segment<3>(3 * s) = bar.Target(pushed[s]);
  }
  forces->resize(target.size());
  ASSERT_TRUE(solver.Solve(target.data(), forces->data()));
  surface->resize(3 * bar.outputs.size());
  solver.OutputDisplacement(forces->data(), surface);
}

std::vector<int> Both(const Bar& bar) {
  std::vector<int> both = bar.left;
  both.insert(both.end(), bar.right.begin(), bar.right.end());
  return both;
}

class TwoPointContact : public ::testing::TestWithParam<int> {};

TEST_P(TwoPointContact, JointCondensedSolveEqualsFullSparseSolveWhenSqueezed) {
  const Bar bar(GetParam());
  ASSERT_EQ(bar.left.size(), 5u);
  ASSERT_EQ(bar.right.size(), 5u);
  const std::vector<int> both = Both(bar);
  Eigen::VectorXd f_full, u_full, f_cond, u_cond;
  FullSolve(bar, both, &f_full, &u_full);
  CondensedSolve(bar, both, &f_cond, &u_cond);
  EXPECT_LT((f_cond - f_full).norm(), 1e-9 * f_full.norm());
  EXPECT_LT((u_cond - u_full).norm(), 1e-9 * u_full.norm());
  // A squeeze: the body pushes back on each pole (forces on the body point into it).
  double left_x = 0.0, right_x = 0.0;
  for (size_t s = 0; s < both.size(); ++s)
    (s < bar.left.size() ? left_x : right_x) += f_cond(3 * s);
  EXPECT_GT(left_x, 0.0);
  EXPECT_LT(right_x, 0.0);
}

TEST_P(TwoPointContact, DiffersFromSolvingEachPatchAlone) {
  const Bar bar(GetParam());
  const std::vector<int> both = Both(bar);
  Eigen::VectorXd f_joint, u_joint, f_left, u_left, f_right, u_right;
  CondensedSolve(bar, both, &f_joint, &u_joint);
  CondensedSolve(bar, bar.left, &f_left, &u_left);
  CondensedSolve(bar, bar.right, &f_right, &u_right);
  const int nl = 3 * static_cast<int>(bar.left.size());
  const Eigen::VectorXd joint_left = f_joint.head(nl),
                        joint_right = f_joint.tail(f_joint.size() - nl);
  // Each pole feels the other through the part: the coupled forces differ measurably.
  EXPECT_GT((joint_left - f_left).norm(), 1e-3 * f_left.norm());
  EXPECT_GT((joint_right - f_right).norm(), 1e-3 * f_right.norm());
  // And superposing the two single-patch solutions does not satisfy the joint targets:
  // the displacement at the left patch under both single-patch forces overshoots or undershoots.
  Eigen::VectorXd f_super(f_joint.size());
  f_super << f_left, f_right;
  ContactSolver solver(*bar.compliance, 10);
  for (int b : both) ASSERT_EQ(solver.Add(b), ContactStatus::kOk);
  const Eigen::MatrixXd g = solver.ContactBlock();
  Eigen::VectorXd target(f_joint.size());
  for (size_t s = 0; s < both.size(); ++s) target.segment<3>(3 * s) = bar.Target(both[s]);
  EXPECT_LT((g * f_joint - target).norm(), 1e-9 * target.norm());
  EXPECT_GT((g * f_super - target).norm(), 1e-3 * target.norm());
}

TEST_P(TwoPointContact, CachedContactSolverMatchesTheFullSolveWhenColumnsAreReady) {
  const Bar bar(GetParam());
  const std::vector<int> both = Both(bar);
  ColumnCacheSettings settings;
  settings.start_worker = false;
  ColumnCache cache(*bar.solver, bar.mesh.nodes, bar.outputs, bar.candidates, settings);
  EXPECT_EQ(cache.ComputeNodes(both), static_cast<int>(both.size()));
  CachedContactSolver solver(&cache, 10);
  Eigen::VectorXd target(3 * both.size()), forces(3 * both.size()), u(3 * bar.outputs.size());
  for (size_t s = 0; s < both.size(); ++s) {
    ASSERT_EQ(solver.Add(both[s]), CachedContactStatus::kOk);
    target.segment<3>(3 * s) = bar.Target(both[s]);
  }
  ASSERT_TRUE(solver.Solve(target.data(), forces.data()));
  solver.OutputDisplacement(forces.data(), &u);
  Eigen::VectorXd f_full, u_full;
  FullSolve(bar, both, &f_full, &u_full);
  EXPECT_LT((forces - f_full).norm(), 1e-9 * f_full.norm());
  EXPECT_LT((u - u_full).norm(), 1e-9 * u_full.norm());
}

INSTANTIATE_TEST_SUITE_P(LinearAndQuadratic, TwoPointContact, ::testing::Values(1, 2));

}  // namespace
}  // namespace spidarcad::fem
