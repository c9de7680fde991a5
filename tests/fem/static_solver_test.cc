// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#include "spidarcad/fem/static_solver.h"

#include <cmath>
#include <cstdio>
#include <random>
#include <stdexcept>
#include <string>

#include <Eigen/Dense>
#include <gtest/gtest.h>

namespace spidarcad::fem {
namespace {

std::string ErrorOf(const TetMesh& mesh, const BoundaryConditions& bcs) {
  try {
    StaticSolver solver(mesh, MaterialTable(Material{1e9, 0.3}), bcs);
  } catch (const std::invalid_argument& e) {
    return e.what();
  }
  return "";
}

TetMesh SmallBox(int order) {
  BoxMeshSettings s;
  s.nx = 2;
  s.ny = 2;
  s.nz = 2;
  s.order = order;
  s.upper = Eigen::Vector3d(0.2, 0.1, 0.1);
  return MakeBoxMesh(s);
}

TEST(StaticSolver, RefusesModelWhenUnconstrainedOrRigidModeFree) {
  const TetMesh mesh = SmallBox(1);
  BoundaryConditions bcs(mesh.num_nodes());
  EXPECT_NE(ErrorOf(mesh, bcs).find("no constraint"), std::string::npos) << ErrorOf(mesh, bcs);
  bcs.FixNode(0);  // one point: rotations free
  EXPECT_NE(ErrorOf(mesh, bcs).find("rigid-body mode free"), std::string::npos);
  bcs.FixNode(2);  // two points: rotation about their line free
  EXPECT_NE(ErrorOf(mesh, bcs).find("rigid-body mode free"), std::string::npos);
  // All nodes on the plane z = 0 held in z only: in-plane motions are free.
  BoundaryConditions plane(mesh.num_nodes());
  for (int v : NodesInBox(mesh, Eigen::Vector3d(-1, -1, -1e-9), Eigen::Vector3d(1, 1, 1e-9)))
    plane.PrescribeDof(v, 2, 0.0);
  EXPECT_NE(ErrorOf(mesh, plane).find("rigid-body mode free"), std::string::npos);
  // Three non-collinear points fully fixed (the third through a list): accepted.
  bcs.FixNodes({mesh.num_nodes() - 1});
  EXPECT_EQ(ErrorOf(mesh, bcs), "");
  // A boundary condition for the wrong number of nodes is refused.
  EXPECT_NE(ErrorOf(mesh, BoundaryConditions(3)).find("nodes"), std::string::npos);
  EXPECT_THROW(bcs.FixNode(mesh.num_nodes()), std::invalid_argument);
}

TEST(StaticSolver, ConstrainedStiffnessIsSymmetricPositiveDefiniteWhenClamped) {
  for (int order : {1, 2}) {
    const TetMesh mesh = SmallBox(order);
    BoundaryConditions bcs(mesh.num_nodes());
    FixNodesInBox(mesh, Eigen::Vector3d(-1, -1, -1), Eigen::Vector3d(1e-9, 1, 1), &bcs);
    StaticSolver solver(mesh, MaterialTable(Material{1e9, 0.3}), bcs);
    ASSERT_TRUE(solver.factor_status().converged) << solver.factor_status().message;
    const Eigen::MatrixXd k(solver.free_stiffness());
    EXPECT_EQ((k - k.transpose()).norm(), 0.0);
    Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> eig(k);
    EXPECT_GT(eig.eigenvalues().minCoeff(), 1e-8 * eig.eigenvalues().maxCoeff()) << "order " << order;
  }
}

// Patch test: a linear field u = A x + c prescribed on every boundary node of a mesh with
// distorted interior nodes is reproduced exactly inside, with zero reactions' resultant.
TEST(StaticSolver, ReproducesLinearFieldInsideWhenPrescribedOnBoundary) {
  Eigen::Matrix3d a;
  a << 1e-3, 2e-4, -3e-4, -1e-4, 5e-4, 2e-4, 3e-4, -2e-4, -4e-4;
  const Eigen::Vector3d c(1e-4, -2e-4, 3e-5);
  for (int order : {1, 2}) {
    for (HexSplit split : {HexSplit::kFive, HexSplit::kSix}) {
      BoxMeshSettings s;
      s.nx = s.ny = s.nz = 3;
      s.split = split;
      TetMesh lin = MakeBoxMesh(s);
      std::mt19937 rng(42);
      std::uniform_real_distribution<double> jitter(-0.12, 0.12);
      for (int v = 0; v < lin.num_nodes(); ++v) {
        const Eigen::Vector3d p = lin.nodes.row(v).transpose();
        if ((p.array() > 1e-9).all() && (p.array() < 1 - 1e-9).all())
          lin.nodes.row(v) += Eigen::RowVector3d(jitter(rng), jitter(rng), jitter(rng));
      }
      const TetMesh mesh = order == 2 ? MakeQuadratic(lin) : lin;
      const Surface surf = ExtractSurface(mesh);
      BoundaryConditions bcs(mesh.num_nodes());
      for (int v : surf.nodes) bcs.PrescribeNode(v, a * mesh.nodes.row(v).transpose() + c);
      ASSERT_LT(static_cast<int>(surf.nodes.size()), mesh.num_nodes());
      StaticSolver solver(mesh, MaterialTable(Material{2e11, 0.3}), bcs);
      const StaticSolution sol = solver.Solve();
      ASSERT_TRUE(sol.status.converged) << sol.status.message;
      double max_err = 0.0;
      for (int v = 0; v < mesh.num_nodes(); ++v) {
        const Eigen::Vector3d exact = a * mesh.nodes.row(v).transpose() + c;
        max_err = std::max(max_err, (sol.displacement.segment<3>(3 * v) - exact).norm());
      }
      EXPECT_LT(max_err, 1e-12) << "order " << order;
      // Self-equilibrated reactions: zero resultant force.
      Eigen::Vector3d resultant = Eigen::Vector3d::Zero();
      for (int v = 0; v < mesh.num_nodes(); ++v) resultant += sol.reaction.segment<3>(3 * v);
      EXPECT_LT(resultant.norm(), 1e-6 * sol.reaction.norm());
    }
  }
}

// Cantilever along x (length L, section b × h), clamped at x = 0, tip shear P along −z
// spread as a uniform traction over the end face. Returns the tip deflection: the mean
// z-displacement of the end-face nodes (positive down).
struct Cantilever {
  double length = 1.0, width = 0.1, height = 0.1, force = 1000.0;
  Material material{2.0e11, 0.3};
  double EulerBernoulli() const {
    const double i = width * std::pow(height, 3) / 12.0;
    return force * std::pow(length, 3) / (3.0 * material.youngs_modulus * i);
  }
  double Timoshenko() const {
    const double nu = material.poisson_ratio;
    const double kappa = 10.0 * (1.0 + nu) / (12.0 + 11.0 * nu);
    return EulerBernoulli() + force * length / (kappa * material.Mu() * width * height);
  }
  double Solve(int order, int nx, int nyz, SolveStatus* status = nullptr) const {
    BoxMeshSettings s;
    s.upper = Eigen::Vector3d(length, width, height);
    s.nx = nx;
    s.ny = s.nz = nyz;
    s.order = order;
    const TetMesh mesh = MakeBoxMesh(s);
    BoundaryConditions bcs(mesh.num_nodes());
    FixNodesInBox(mesh, Eigen::Vector3d(-1, -1, -1), Eigen::Vector3d(1e-9, 1, 1), &bcs);
    const Surface surf = ExtractSurface(mesh);
    const double area = AddTractionInBox(mesh, surf, Eigen::Vector3d(length - 1e-9, -1, -1),
                                         Eigen::Vector3d(2, 2, 2),
                                         Eigen::Vector3d(0, 0, -force / (width * height)), &bcs);
    EXPECT_NEAR(area, width * height, 1e-12);
    StaticSolver solver(mesh, MaterialTable(material), bcs);
    const StaticSolution sol = solver.Solve();
    if (status) *status = sol.status;
    EXPECT_TRUE(sol.status.converged) << sol.status.message;
    // Support reactions balance the load.
    Eigen::Vector3d total = Eigen::Vector3d::Zero();
    for (int v = 0; v < mesh.num_nodes(); ++v) total += sol.reaction.segment<3>(3 * v);
    EXPECT_NEAR(total.z(), force, 1e-6 * force);
    const auto tip = NodesInBox(mesh, Eigen::Vector3d(length - 1e-9, -1, -1), Eigen::Vector3d(2, 2, 2));
    double sum = 0.0;
    for (int v : tip) sum += sol.displacement(3 * v + 2);
    return -sum / static_cast<double>(tip.size());
  }
};

TEST(StaticSolver, CantileverConvergesToTimoshenkoWhenRefined) {
  const Cantilever beam;
  const double timo = beam.Timoshenko();
  const double eb = beam.EulerBernoulli();
  std::printf("cantilever L/h = 10, nu = 0.3: Euler-Bernoulli %.4e m, Timoshenko %.4e m\n", eb, timo);
  double prev_err_lin = 1e9, prev_err_quad = 1e9;
  for (int r : {1, 2, 4}) {
    const double lin = beam.Solve(1, 5 * r, r);
    const double quad = beam.Solve(2, 5 * r, r);
    const double err_lin = std::abs(lin / timo - 1.0), err_quad = std::abs(quad / timo - 1.0);
    std::printf("  %2d x %d x %d cells: linear %.4f, quadratic %.4f of Timoshenko\n", 5 * r, r, r,
                lin / timo, quad / timo);
    EXPECT_LT(err_lin, prev_err_lin);
    EXPECT_LT(err_quad, prev_err_quad);
    EXPECT_LT(lin, timo);  // displacement elements are too stiff
    prev_err_lin = err_lin;
    prev_err_quad = err_quad;
  }
  // Finest mesh: quadratic within 2 % of Timoshenko (and 3 % of Euler–Bernoulli, which
  // ignores shear); linear tetrahedra still lock (> 25 % too stiff).
  EXPECT_LT(prev_err_quad, 0.02);
  EXPECT_NEAR(beam.Solve(2, 20, 4) / eb, 1.0, 0.03);
  EXPECT_GT(prev_err_lin, 0.25);
}

// Near-incompressible material: linear tetrahedra lock much harder (volumetric locking on top
// of shear locking); quadratic ones stay close to Timoshenko on the same mesh.
TEST(StaticSolver, LinearTetrahedraLockWhenNearlyIncompressible) {
  double prev_lin = 1.0;
  for (double nu : {0.3, 0.49, 0.499}) {
    Cantilever beam;
    beam.material.poisson_ratio = nu;
    const double timo = beam.Timoshenko();
    SolveStatus status_lin, status_quad;
    const double lin = beam.Solve(1, 10, 2, &status_lin) / timo;
    const double quad = beam.Solve(2, 10, 2, &status_quad) / timo;
    std::printf("nu = %.3f, 10 x 2 x 2 cells: linear %.4f, quadratic %.4f of Timoshenko "
                "(residuals %.1e, %.1e)\n", nu, lin, quad, status_lin.residual, status_quad.residual);
    EXPECT_LT(lin, prev_lin);
    EXPECT_GT(quad, 0.85);
    EXPECT_LT(quad, 1.01);
    prev_lin = lin;
  }
  EXPECT_LT(prev_lin, 0.1);
}

// Bar along x of two regions in series, E and 1e6·E, ν = 0, clamped at x = 0 and pulled by a
// uniform traction at x = L: the exact field is piecewise linear, so both orders reproduce
// the series-spring elongation P (L1/(E1 A) + L2/(E2 A)) up to the conditioning of K.
TEST(StaticSolver, MatchesSeriesSpringsWhenRegionsDifferBySixOrders) {
  for (int order : {1, 2}) {
    BoxMeshSettings s;
    s.upper = Eigen::Vector3d(1.0, 0.1, 0.1);
    s.nx = 10;
    s.ny = s.nz = 1;
    s.order = order;
    TetMesh mesh = MakeBoxMesh(s);
    LabelRegionInBox(Eigen::Vector3d(0.6, -1, -1), Eigen::Vector3d(2, 2, 2), 1, &mesh);
    MaterialTable mats;
    const double e_soft = 1.0e5, e_hard = 1.0e11;
    mats.Set(0, Material{e_soft, 0.0});
    mats.Set(1, Material{e_hard, 0.0});
    BoundaryConditions bcs(mesh.num_nodes());
    FixNodesInBox(mesh, Eigen::Vector3d(-1, -1, -1), Eigen::Vector3d(1e-9, 1, 1), &bcs);
    const double p = 10.0, area = 0.01;
    AddTractionInBox(mesh, ExtractSurface(mesh), Eigen::Vector3d(1 - 1e-9, -1, -1),
                     Eigen::Vector3d(2, 2, 2), Eigen::Vector3d(p / area, 0, 0), &bcs);
    StaticSolver solver(mesh, mats, bcs);
    const StaticSolution sol = solver.Solve();
    ASSERT_TRUE(sol.status.converged) << sol.status.message;
    // The solve is backward stable (backward error ~1e-17) but the contrast costs about six
    // digits of forward accuracy: errors ~1e-8 of the largest displacement (see README).
    const double u_max = p * 0.6 / (e_soft * area) + p * 0.4 / (e_hard * area);
    double axial = 0.0, lateral = 0.0;
    for (int v = 0; v < mesh.num_nodes(); ++v) {
      const double x = mesh.nodes(v, 0);
      const double exact = x <= 0.6 ? p * x / (e_soft * area)
                                    : p * 0.6 / (e_soft * area) + p * (x - 0.6) / (e_hard * area);
      axial = std::max(axial, std::abs(sol.displacement(3 * v) - exact));
      lateral = std::max(lateral, sol.displacement.segment<2>(3 * v + 1).norm());
    }
    std::printf("contrast 1e6, order %d: axial error %.1e, lateral error %.1e of u_max, backward "
                "error %.1e\n", order, axial / u_max, lateral / u_max, sol.status.residual);
    EXPECT_LT(axial, 1e-6 * u_max);
    EXPECT_LT(lateral, 1e-5 * u_max);
    EXPECT_LT(sol.status.residual, 1e-15);
  }
}

}  // namespace
}  // namespace spidarcad::fem
