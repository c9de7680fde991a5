// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#include "spidarcad/fem/condensation.h"

#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <algorithm>
#include <cstddef>
#include <cstdio>
#include <random>

#include "support/malloc_counter.h"

namespace spidarcad::fem {
namespace {

// A clamped block (x = 0 fixed) with a baseline point load, condensed on its top face.
struct Scene {
  TetMesh mesh;
  MaterialTable materials{Material{5.0e7, 0.35}};
  std::unique_ptr<BoundaryConditions> bcs;
  std::unique_ptr<StaticSolver> solver;
  std::unique_ptr<Compliance> compliance;

  explicit Scene(int order, int nx = 4, int nyz = 2) {
    BoxMeshSettings s;
    s.upper = Eigen::Vector3d(0.2, 0.1, 0.1);
    s.nx = nx;
    s.ny = nyz;
    s.nz = nyz;
    s.order = order;
    mesh = MakeBoxMesh(s);
    bcs = std::make_unique<BoundaryConditions>(mesh.num_nodes());
    FixNodesInBox(mesh, Eigen::Vector3d(-1, -1, -1), Eigen::Vector3d(1e-9, 1, 1), bcs.get());
    bcs->AddPointLoad(
        NodesInBox(mesh, Eigen::Vector3d(0.2, 0, 0), Eigen::Vector3d(0.2, 0, 0)).at(0),
        Eigen::Vector3d(0.0, 3.0, -2.0));
    solver = std::make_unique<StaticSolver>(mesh, materials, *bcs);
    const Surface surf = ExtractSurface(mesh);
    const auto top = NodesInBox(mesh, Eigen::Vector3d(-1, -1, 0.1), Eigen::Vector3d(1, 1, 1));
    CondensationSettings settings;
    settings.block_nodes = 5;  // several blocks
    compliance = std::make_unique<Compliance>(*solver, surf.nodes, top, settings);
  }

  // Condensed indices of top nodes that are not fixed.
  std::vector<int> FreeCondensed() const {
    std::vector<int> out;
    for (int b = 0; b < static_cast<int>(compliance->condensed_nodes().size()); ++b)
      if (!compliance->IsFixed(b)) out.push_back(b);
    return out;
  }
};

TEST(Compliance, IsSymmetricPositiveDefiniteWhenRestrictedToCondensedNodes) {
  const Scene scene(1);
  const Compliance& c = *scene.compliance;
  ASSERT_TRUE(c.status().converged) << c.status().message;
  const auto free = scene.FreeCondensed();
  Eigen::MatrixXd gcc(3 * free.size(), 3 * free.size());
  for (size_t a = 0; a < free.size(); ++a)
    for (size_t b = 0; b < free.size(); ++b)
      gcc.block<3, 3>(3 * a, 3 * b) = c.Block(free[a], free[b]);
  // Maxwell–Betti reciprocity.
  EXPECT_LT((gcc - gcc.transpose()).norm(), 1e-12 * gcc.norm());
  Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> eig(gcc);
  EXPECT_GT(eig.eigenvalues().minCoeff(), 0.0);
  // A column equals a direct solve with a unit point load (second computation).
  const int b = free[3];
  const int node = c.condensed_nodes()[b];
  BoundaryConditions unit(scene.mesh.num_nodes());
  FixNodesInBox(scene.mesh, Eigen::Vector3d(-1, -1, -1), Eigen::Vector3d(1e-9, 1, 1), &unit);
  unit.AddPointLoad(node, Eigen::Vector3d(0, 1, 0));
  const StaticSolution direct = StaticSolver(scene.mesh, scene.materials, unit).Solve();
  for (size_t a = 0; a < c.output_nodes().size(); ++a)
    EXPECT_LT((c.matrix().block<3, 1>(3 * a, 3 * b + 1) -
               direct.displacement.segment<3>(3 * c.output_nodes()[a]))
                  .norm(),
              1e-12 * direct.displacement.norm());
}

// The condensed contact solve against a full sparse solve in which the contact nodes are
// prescribed: forces (reactions) and displacements of every surface node agree to 1e-9.
void ExpectMatchesFullSolve(const Scene& scene, const std::vector<int>& contacts) {
  const Compliance& c = *scene.compliance;
  ContactSolver solver(c, 8);
  std::vector<double> target(3 * contacts.size()), forces(3 * contacts.size());
  BoundaryConditions full_bcs = *scene.bcs;
  for (size_t s = 0; s < contacts.size(); ++s) {
    ASSERT_EQ(solver.Add(contacts[s]), ContactStatus::kOk);
    const int node = c.condensed_nodes()[contacts[s]];
    const Eigen::Vector3d d(1e-4 * (s + 1), -2e-4, -5e-4 + 1e-4 * s);
    for (int i = 0; i < 3; ++i) target[3 * s + i] = d(i);
    full_bcs.PrescribeNode(node, d);
  }
  ASSERT_TRUE(solver.Solve(target.data(), forces.data()));
  Eigen::VectorXd u(3 * c.output_nodes().size());
  solver.OutputDisplacement(forces.data(), &u);

  StaticSolver full(scene.mesh, scene.materials, full_bcs);
  const StaticSolution sol = full.Solve();
  ASSERT_TRUE(sol.status.converged) << sol.status.message;
  Eigen::VectorXd f_full(3 * contacts.size()), f_cond(3 * contacts.size());
  for (size_t s = 0; s < contacts.size(); ++s) {
    f_full.segment<3>(3 * s) = sol.reaction.segment<3>(3 * c.condensed_nodes()[contacts[s]]);
    f_cond.segment<3>(3 * s) = Eigen::Map<const Eigen::Vector3d>(&forces[3 * s]);
  }
  EXPECT_LT((f_full - f_cond).norm(), 1e-9 * f_full.norm()) << "k = " << contacts.size();
  Eigen::VectorXd u_full(u.size());
  for (size_t a = 0; a < c.output_nodes().size(); ++a)
    u_full.segment<3>(3 * a) = sol.displacement.segment<3>(3 * c.output_nodes()[a]);
  EXPECT_LT((u_full - u).norm(), 1e-9 * u_full.norm()) << "k = " << contacts.size();
}

TEST(ContactSolver, EqualsFullSparseSolveWhenOneOrSeveralNodesPushed) {
  for (int order : {1, 2}) {
    const Scene scene(order);
    const auto free = scene.FreeCondensed();
    ASSERT_GE(free.size(), 8u);
    ExpectMatchesFullSolve(scene, {free[2]});
    ExpectMatchesFullSolve(scene, {free[0], free[5]});
    ExpectMatchesFullSolve(scene, {free[7], free[1], free[4], free[3], free[6]});
  }
}

// From-scratch reference: Cholesky of the current contact block.
double FactorError(const ContactSolver& solver) {
  const Eigen::MatrixXd g = solver.ContactBlock();
  const Eigen::MatrixXd gs = 0.5 * (g + g.transpose());
  const Eigen::MatrixXd l_ref = gs.llt().matrixL();
  const int n = static_cast<int>(g.rows());
  const Eigen::MatrixXd l = solver.factor().topLeftCorner(n, n).triangularView<Eigen::Lower>();
  return (l - l_ref).norm() / l_ref.norm();
}

TEST(ContactSolver, IncrementalFactorEqualsFromScratchWhenNodesEnterAndLeave) {
  const Scene scene(2);
  const auto free = scene.FreeCondensed();
  ContactSolver solver(*scene.compliance, 6);
  ASSERT_EQ(solver.Add(free[0]), ContactStatus::kOk);
  ASSERT_EQ(solver.Add(free[3]), ContactStatus::kOk);
  ASSERT_EQ(solver.Add(free[5]), ContactStatus::kOk);
  ASSERT_EQ(solver.Add(free[1]), ContactStatus::kOk);
  EXPECT_LT(FactorError(solver), 1e-12);
  ASSERT_EQ(solver.Remove(free[3]), ContactStatus::kOk);  // middle
  EXPECT_EQ(solver.num_contacts(), 3);
  EXPECT_EQ(solver.contact(1), free[5]);
  EXPECT_LT(FactorError(solver), 1e-12);
  ASSERT_EQ(solver.Remove(free[1]), ContactStatus::kOk);  // last
  ASSERT_EQ(solver.Remove(free[0]), ContactStatus::kOk);  // first
  ASSERT_EQ(solver.Add(free[7]), ContactStatus::kOk);
  EXPECT_LT(FactorError(solver), 1e-12);
  // Status codes.
  EXPECT_EQ(solver.Add(free[7]), ContactStatus::kAlreadyInContact);
  EXPECT_EQ(solver.Remove(free[2]), ContactStatus::kNotInContact);
  EXPECT_EQ(solver.Add(-1), ContactStatus::kBadIndex);
  for (int b = 0; b < static_cast<int>(scene.compliance->condensed_nodes().size()); ++b) {
    if (scene.compliance->IsFixed(b)) {
      EXPECT_EQ(solver.Add(b), ContactStatus::kFixedNode);  // contact on a clamped node
      break;
    }
  }
  for (int i = 0; i < 4; ++i) ASSERT_EQ(solver.Add(free[8 + i]), ContactStatus::kOk);
  EXPECT_EQ(solver.Add(free[12]), ContactStatus::kFull);
  solver.Clear();
  EXPECT_EQ(solver.num_contacts(), 0);
  EXPECT_EQ(solver.SlotOf(free[7]), -1);
}

// A long session of random touch and release: the incrementally updated factor does not
// drift from the from-scratch one, and forces match a dense solve.
TEST(ContactSolver, DoesNotDriftWhenTouchedAndReleasedManyTimes) {
  const Scene scene(1);
  const auto free = scene.FreeCondensed();
  ContactSolver solver(*scene.compliance, 12);
  std::mt19937 rng(2024);
  double worst = 0.0;
  for (int step = 0; step < 3000; ++step) {
    const int b = free[rng() % free.size()];
    if (solver.SlotOf(b) >= 0) {
      ASSERT_EQ(solver.Remove(b), ContactStatus::kOk);
    } else if (solver.num_contacts() < 12) {
      ASSERT_EQ(solver.Add(b), ContactStatus::kOk);
    }
    if (step % 500 == 499 && solver.num_contacts() > 0)
      worst = std::max(worst, FactorError(solver));
  }
  ASSERT_GT(solver.num_contacts(), 0);
  EXPECT_LT(worst, 1e-11);
  const int n = 3 * solver.num_contacts();
  Eigen::VectorXd target = Eigen::VectorXd::LinSpaced(n, -1e-4, 2e-4), f(n);
  ASSERT_TRUE(solver.Solve(target.data(), f.data()));
  Eigen::VectorXd rhs(n);
  for (int s = 0; s < solver.num_contacts(); ++s)
    rhs.segment<3>(3 * s) = target.segment<3>(3 * s) -
                            scene.compliance->baseline().segment<3>(
                                3 * scene.compliance->OutputIndexOfCondensed(solver.contact(s)));
  const Eigen::VectorXd f_ref = solver.ContactBlock().ldlt().solve(rhs);
  EXPECT_LT((f - f_ref).norm(), 1e-10 * f_ref.norm());
}

// Hundreds of contact nodes: the whole free surface of a quadratic block is pushed.
TEST(ContactSolver, EqualsFullSparseSolveWhenHundredsOfNodesPushed) {
  Scene scene(2, 6, 3);
  const Surface surf = ExtractSurface(scene.mesh);
  scene.compliance = std::make_unique<Compliance>(*scene.solver, surf.nodes, surf.nodes);
  const Compliance& c = *scene.compliance;
  std::vector<int> contacts;
  for (int b = 0; b < static_cast<int>(c.condensed_nodes().size()); ++b)
    if (!c.IsFixed(b)) contacts.push_back(b);
  ASSERT_GE(contacts.size(), 300u);
  ContactSolver solver(c, static_cast<int>(contacts.size()));
  BoundaryConditions full_bcs = *scene.bcs;
  std::vector<double> target, forces(3 * contacts.size());
  for (int b : contacts) {
    ASSERT_EQ(solver.Add(b), ContactStatus::kOk) << "node " << c.condensed_nodes()[b];
    const int v = c.condensed_nodes()[b];
    // A smooth imposed field: u = 1e-4 (z, x, −y) m/m.
    const Eigen::Vector3d p = scene.mesh.nodes.row(v).transpose();
    const Eigen::Vector3d d = 1e-3 * Eigen::Vector3d(p.z(), p.x(), -p.y());
    target.insert(target.end(), {d.x(), d.y(), d.z()});
    full_bcs.PrescribeNode(v, d);
  }
  ASSERT_TRUE(solver.Solve(target.data(), forces.data()));
  const StaticSolution sol = StaticSolver(scene.mesh, scene.materials, full_bcs).Solve();
  ASSERT_TRUE(sol.status.converged) << sol.status.message;
  Eigen::VectorXd f_full(forces.size());
  for (size_t s = 0; s < contacts.size(); ++s)
    f_full.segment<3>(3 * s) = sol.reaction.segment<3>(3 * c.condensed_nodes()[contacts[s]]);
  const Eigen::VectorXd f_cond = Eigen::Map<const Eigen::VectorXd>(forces.data(), forces.size());
  EXPECT_LT((f_full - f_cond).norm(), 1e-9 * f_full.norm()) << "k = " << contacts.size();
}

TEST(ContactSolver, AllocatesNothingWhenContactsChangeAndSolve) {
  const Scene scene(1);
  const auto free = scene.FreeCondensed();
  ContactSolver solver(*scene.compliance, 16);
  std::vector<double> target(48, -1e-4), forces(48, 0.0);
  Eigen::VectorXd u(3 * scene.compliance->output_nodes().size());
  // Sanity: the counter sees allocations.
  ASSERT_TRUE(test_support::MallocCounterActive());
  long allocations = 0;
  {
    test_support::MallocCounter counter;
    std::vector<int> probe(100, 1);
    EXPECT_EQ(probe[99], 1);
    allocations = counter.count();
  }
  ASSERT_GT(allocations, 0);

  test_support::MallocCounter counter;
  int ok = 0;
  for (int round = 0; round < 20; ++round) {
    for (int i = 0; i < 8; ++i)
      ok += solver.Add(free[(round + 3 * i) % free.size()]) == ContactStatus::kOk;
    ok += solver.Solve(target.data(), forces.data());
    solver.OutputDisplacement(forces.data(), &u);
    ok += solver.Remove(solver.contact(0)) == ContactStatus::kOk;
    ok += solver.Solve(target.data(), forces.data());
    solver.Clear();
  }
  allocations = counter.count();
  EXPECT_EQ(allocations, 0);
  EXPECT_GT(ok, 100);
}

TEST(Compliance, ThrowsWhenCondensedNodeIsNotAnOutputNode) {
  const Scene scene(1);
  EXPECT_THROW(Compliance(*scene.solver, {1, 2, 3}, {4}), std::invalid_argument);
  EXPECT_THROW(Compliance(*scene.solver, {1, 1}, {1}), std::invalid_argument);
  EXPECT_THROW(ContactSolver(*scene.compliance, 0), std::invalid_argument);
}

// The mean-dilatation (P2–P0) cantilever at ν = 0.4999, 10 x 2 x 2 cells, condensed on its
// surface: the tip load applied through the compliance columns, and a push of the tip through
// the contact solve, give the full sparse solve's tip displacement to 1e-9.
TEST(HardIncompressible, CondensationGivesTheFullSolveTipDisplacementAtNu04999) {
  BoxMeshSettings s;
  s.upper = Eigen::Vector3d(1.0, 0.1, 0.1);
  s.nx = 10;
  s.ny = s.nz = 2;
  s.order = 2;
  const TetMesh mesh = MakeBoxMesh(s);
  Material rubber{1.0e7, 0.4999};
  rubber.formulation = Formulation::kMeanDilatation;
  const MaterialTable materials(rubber);
  BoundaryConditions clamp(mesh.num_nodes());
  FixNodesInBox(mesh, Eigen::Vector3d(-1, -1, -1), Eigen::Vector3d(1e-9, 1, 1), &clamp);
  const Surface surf = ExtractSurface(mesh);
  BoundaryConditions loaded = clamp;
  AddTractionInBox(mesh, surf, Eigen::Vector3d(1 - 1e-9, -1, -1), Eigen::Vector3d(2, 2, 2),
                   Eigen::Vector3d(0, 0, -100.0 / 0.01), &loaded);
  const std::vector<int> tip =
      NodesInBox(mesh, Eigen::Vector3d(1 - 1e-9, -1, -1), Eigen::Vector3d(2, 2, 2));
  const StaticSolution full = StaticSolver(mesh, materials, loaded).Solve();
  ASSERT_TRUE(full.status.converged) << full.status.message;

  // Superposition: u = G f over the tip nodes (the clamped model has no load of its own).
  const StaticSolver solver(mesh, materials, clamp);
  const Compliance compliance(solver, surf.nodes, tip);
  ASSERT_TRUE(compliance.status().converged) << compliance.status().message;
  Eigen::VectorXd f(3 * tip.size());
  for (size_t b = 0; b < tip.size(); ++b)
    f.segment<3>(3 * b) = loaded.loads().segment<3>(3 * tip[b]);
  const Eigen::VectorXd u = compliance.baseline() + compliance.matrix() * f;
  double worst = 0.0, scale = 0.0;
  for (size_t b = 0; b < tip.size(); ++b) {
    const int row = compliance.OutputIndexOfCondensed(static_cast<int>(b));
    const Eigen::Vector3d exact = full.displacement.segment<3>(3 * tip[b]);
    worst = std::max(worst, (u.segment<3>(3 * row) - exact).norm());
    scale = std::max(scale, exact.norm());
  }
  EXPECT_LT(worst, 1e-9 * scale);

  // Contact: push the tip centre node 10 mm down; the contact force equals the reaction of a
  // full solve that prescribes the same displacement there.
  const int centre =
      NodesInBox(mesh, Eigen::Vector3d(1, 0.05, 0.05), Eigen::Vector3d(1, 0.05, 0.05)).at(0);
  const int b = compliance.CondensedIndexOfNode(centre);
  ContactSolver contact(compliance, 4);
  ASSERT_EQ(contact.Add(b), ContactStatus::kOk);
  const Eigen::Vector3d target(0.0, 0.0, -0.01);
  Eigen::Vector3d force;
  ASSERT_TRUE(contact.Solve(target.data(), force.data()));
  BoundaryConditions pushed = clamp;
  pushed.PrescribeNode(centre, target);
  const StaticSolution push = StaticSolver(mesh, materials, pushed).Solve();
  ASSERT_TRUE(push.status.converged) << push.status.message;
  const Eigen::Vector3d reaction = push.reaction.segment<3>(3 * centre);
  const double force_error = (force - reaction).norm() / reaction.norm();
  // The reference reaction K u − f of the full solve cancels about λ/μ = 5000 times more.
  EXPECT_LT(force_error, 1e-7);
  char figure[160];
  std::snprintf(figure, sizeof(figure),
                "tip displacement error %.1e, push force error %.1e (relative)", worst / scale,
                force_error);
  RecordProperty("figure", figure);
  RecordProperty("bar", "tip displacement 1e-9, push force 1e-7 relative");
}

}  // namespace
}  // namespace spidarcad::fem
