// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#include "spidarcad/fem/static_solver.h"

#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <cmath>
#include <cstdio>
#include <random>
#include <stdexcept>
#include <string>
#include <vector>

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
    EXPECT_GT(eig.eigenvalues().minCoeff(), 1e-8 * eig.eigenvalues().maxCoeff())
        << "order " << order;
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
// z-displacement of the end-face nodes (positive down), or with work_conjugate the
// load-weighted mean fᵀu / P (the work-conjugate deflection, consistent across meshes).
struct Cantilever {
  double length = 1.0, width = 0.1, height = 0.1, force = 1000.0;
  Material material{2.0e11, 0.3};
  bool work_conjugate = false;
  // Expect the support reactions to balance the load to 1e-6 (thin plates measure it instead).
  bool check_equilibrium = true;
  // Accept a refusal of the factorisation (the caller checks its message) instead of expecting
  // a converged solve: for a stiffness matrix at the edge of double precision.
  bool may_refuse = false;
  // |Σ reactions − P| / P of the last solve.
  mutable double equilibrium_error = 0.0;
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
    if (may_refuse && !sol.status.converged) return 0.0;
    EXPECT_TRUE(sol.status.converged) << sol.status.message;
    // Support reactions balance the load.
    Eigen::Vector3d total = Eigen::Vector3d::Zero();
    for (int v = 0; v < mesh.num_nodes(); ++v) total += sol.reaction.segment<3>(3 * v);
    equilibrium_error = std::abs(total.z() - force) / force;
    if (check_equilibrium) {
      EXPECT_NEAR(total.z(), force, 1e-6 * force);
    }
    if (work_conjugate) return bcs.loads().dot(sol.displacement) / force;
    const auto tip =
        NodesInBox(mesh, Eigen::Vector3d(length - 1e-9, -1, -1), Eigen::Vector3d(2, 2, 2));
    double sum = 0.0;
    for (int v : tip) sum += sol.displacement(3 * v + 2);
    return -sum / static_cast<double>(tip.size());
  }
};

TEST(StaticSolver, CantileverConvergesToTimoshenkoWhenRefined) {
  const Cantilever beam;
  const double timo = beam.Timoshenko();
  const double eb = beam.EulerBernoulli();
  std::printf("cantilever L/h = 10, nu = 0.3: Euler-Bernoulli %.4e m, Timoshenko %.4e m\n", eb,
              timo);
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
    std::printf(
        "nu = %.3f, 10 x 2 x 2 cells: linear %.4f, quadratic %.4f of Timoshenko "
        "(residuals %.1e, %.1e)\n",
        nu, lin, quad, status_lin.residual, status_quad.residual);
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
    std::printf(
        "contrast 1e6, order %d: axial error %.1e, lateral error %.1e of u_max, backward "
        "error %.1e\n",
        order, axial / u_max, lateral / u_max, sol.status.residual);
    EXPECT_LT(axial, 1e-6 * u_max);
    EXPECT_LT(lateral, 1e-5 * u_max);
    EXPECT_LT(sol.status.residual, 1e-15);
  }
}

// ---------------------------------------------------------------------------------------------
// Near incompressibility (issue 14).

// Tip deflection (work conjugate of the tip load) of the 10 x 2 x 2 cantilever above
// (10r x 2r x 2r cells at refinement r) at ν = 0.49, 0.499, 0.4999 with linear, quadratic and
// quadratic mean-dilatation (P2–P0) elements. "Converged" is the mean-dilatation result at
// r = 3 (30 x 6 x 6 cells) once it differs from r = 2 by less than 0.2 %: the mixed element
// converges non-monotonically (too flexible at r = 1, a hair stiff at r = 2), so Richardson
// extrapolation does not apply; the limit is also checked against Timoshenko's formula.
// Linear elements lock; mean dilatation stays within 5 % at r = 1.
TEST(HardIncompressible, MeanDilatationStaysWithinFivePercentOfConvergedTipDeflection) {
  double worst_md = 0.0, locked_linear = 1.0, locked_quadratic = 1.0;
  for (double nu : {0.49, 0.499, 0.4999}) {
    Cantilever beam;
    beam.material.poisson_ratio = nu;
    beam.work_conjugate = true;
    Cantilever md = beam;
    md.material.formulation = Formulation::kMeanDilatation;
    SolveStatus status;
    const double d1 = md.Solve(2, 10, 2, &status), d2 = md.Solve(2, 20, 4), d3 = md.Solve(2, 30, 6);
    const double converged = d3, change = std::abs(d3 / d2 - 1.0);
    const double lin = beam.Solve(1, 10, 2) / converged;
    const double quad = beam.Solve(2, 10, 2) / converged;
    const double mean = d1 / converged;
    std::printf(
        "nu = %.4f: mean dilatation %.6e, %.6e, %.6e m at r = 1, 2, 3 (last change %.1e; "
        "Timoshenko %.6e m); 10x2x2 of converged: linear %.4f, quadratic %.4f, mean dilatation "
        "%.4f (backward error %.1e)\n",
        nu, d1, d2, d3, change, beam.Timoshenko(), lin, quad, mean, status.residual);
    // Converged: the last refinement changes it by < 0.2 %, and it agrees with beam theory
    // (which ignores the clamp's 3D restraint) to 3 %.
    EXPECT_LT(change, 2e-3) << "nu = " << nu;
    EXPECT_NEAR(converged / beam.Timoshenko(), 1.0, 0.03);
    EXPECT_NEAR(mean, 1.0, 0.05) << "nu = " << nu;
    worst_md = std::max(worst_md, std::abs(mean - 1.0));
    locked_linear = std::min(locked_linear, lin);
    locked_quadratic = std::min(locked_quadratic, quad);
    EXPECT_LT(status.residual, 1e-12);
  }
  EXPECT_LT(locked_linear, 0.05);  // linear tetrahedra lock at ν = 0.4999
  char figure[200];
  std::snprintf(figure, sizeof(figure),
                "mean dilatation 10x2x2 worst %.2f %% off converged (nu 0.49..0.4999); linear "
                "%.1f %%, plain quadratic %.1f %% of converged at nu = 0.4999",
                100.0 * worst_md, 100.0 * locked_linear, 100.0 * locked_quadratic);
  RecordProperty("figure", figure);
  RecordProperty("bar",
                 "mean dilatation 10x2x2 within 5 % of the converged (30x6x6) tip deflection");
}

// ---------------------------------------------------------------------------------------------
// Hard cases (issue 14): rigid modes, slivers, stiffness contrast, thin plates.

// The coordinates "(x, y, z)" that follow `prefix` in text.
Eigen::Vector3d PointAfter(const std::string& text, const std::string& prefix) {
  const size_t at = text.find(prefix);
  Eigen::Vector3d p = Eigen::Vector3d::Constant(std::nan(""));
  if (at == std::string::npos) return p;
  std::sscanf(text.c_str() + at + prefix.size(), "(%lf, %lf, %lf)", &p.x(), &p.y(), &p.z());
  return p;
}

TEST(HardRigidMode, RefusedBeforeFactorisationWithTheFreeModeNamed) {
  const TetMesh mesh = SmallBox(2);  // 0.2 x 0.1 x 0.1 m
  // Clamped along the line y = z = 0.05 only: the rotation about that line is free.
  BoundaryConditions line(mesh.num_nodes());
  line.FixNodes(NodesInBox(mesh, Eigen::Vector3d(-1, 0.05, 0.05), Eigen::Vector3d(1, 0.05, 0.05)));
  const std::string line_error = ErrorOf(mesh, line);
  EXPECT_NE(line_error.find("1 of 6"), std::string::npos) << line_error;
  const Eigen::Vector3d p = PointAfter(line_error, "free rotation about x through ");
  EXPECT_NEAR(p.y(), 0.05, 1e-9) << line_error;
  EXPECT_NEAR(p.z(), 0.05, 1e-9) << line_error;
  // Held only normal to the base z = 0: sliding along x and y and turning about z are free.
  BoundaryConditions base(mesh.num_nodes());
  for (int v : NodesInBox(mesh, Eigen::Vector3d(-1, -1, -1e-9), Eigen::Vector3d(1, 1, 1e-9)))
    base.PrescribeDof(v, 2, 0.0);
  const std::string base_error = ErrorOf(mesh, base);
  for (const char* mode : {"3 of 6", "free translation along x", "free translation along y",
                           "free rotation about z"}) {
    EXPECT_NE(base_error.find(mode), std::string::npos) << mode << " in " << base_error;
  }
  // Every node clamped: nothing to solve (refused, not handed to CHOLMOD).
  BoundaryConditions all(mesh.num_nodes());
  for (int v = 0; v < mesh.num_nodes(); ++v) all.FixNode(v);
  EXPECT_NE(ErrorOf(mesh, all).find("nothing is left to solve"), std::string::npos)
      << ErrorOf(mesh, all);
  // Two separate blocks, only the first clamped: the second is named with its six modes.
  TetMesh two = SmallBox(1);
  const int n = two.num_nodes(), t = two.num_elements();
  two.nodes.conservativeResize(2 * n, 3);
  two.nodes.bottomRows(n) = two.nodes.topRows(n).rowwise() + Eigen::RowVector3d(1.0, 0.0, 0.0);
  two.elements.conservativeResize(2 * t, 4);
  two.elements.bottomRows(t) = two.elements.topRows(t).array() + n;
  two.regions = Eigen::VectorXi::Zero(2 * t);
  BoundaryConditions first(two.num_nodes());
  FixNodesInBox(two, Eigen::Vector3d(-1, -1, -1), Eigen::Vector3d(1e-9, 1, 1), &first);
  const std::string two_error = ErrorOf(two, first);
  EXPECT_NE(two_error.find("part 2 of 2"), std::string::npos) << two_error;
  EXPECT_NE(two_error.find("6 of 6"), std::string::npos) << two_error;
  // A point in no element is undetermined: named.
  TetMesh stray = SmallBox(1);
  stray.nodes.conservativeResize(stray.num_nodes() + 1, 3);
  stray.nodes.bottomRows(1) << 5.0, 5.0, 5.0;
  BoundaryConditions clamp(stray.num_nodes());
  FixNodesInBox(stray, Eigen::Vector3d(-1, -1, -1), Eigen::Vector3d(1e-9, 1, 1), &clamp);
  const std::string stray_error = ErrorOf(stray, clamp);
  EXPECT_NE(stray_error.find("belongs to no element"), std::string::npos) << stray_error;
  RecordProperty("figure",
                 "5 of 5 under-constrained models refused before factorisation, mode named");
  RecordProperty("bar", "refused with the free mode (axis, point) or the part named");
}

// A linear field prescribed on the boundary of a cube whose centre node is pushed to 1e-6 of
// the edge above the bottom face: the elements on the bottom face become flat slivers (volume
// ratio ~1e-6). The patch test must still hold (the FE space contains the field).
TEST(HardSliver, LinearFieldReproducedWithBackwardErrorReportedWhenElementsAreFlat) {
  double worst_error = 0.0, worst_backward = 0.0, min_ratio = 1.0;
  for (int order : {1, 2}) {
    BoxMeshSettings s;
    s.nx = s.ny = s.nz = 2;
    TetMesh lin = MakeBoxMesh(s);
    int centre = -1;
    for (int v = 0; v < lin.num_nodes(); ++v)
      if ((lin.nodes.row(v) - Eigen::RowVector3d(0.5, 0.5, 0.5)).norm() < 1e-12) centre = v;
    ASSERT_GE(centre, 0);
    lin.nodes(centre, 2) = 1e-6;
    double vmin = 1e300, vmax = 0.0;
    for (int e = 0; e < lin.num_elements(); ++e) {
      ASSERT_GT(lin.CornerVolume(e), 0.0);
      vmin = std::min(vmin, lin.CornerVolume(e));
      vmax = std::max(vmax, lin.CornerVolume(e));
    }
    min_ratio = std::min(min_ratio, vmin / vmax);
    const TetMesh mesh = order == 2 ? MakeQuadratic(lin) : lin;
    Eigen::Matrix3d a;
    a << 1e-3, 2e-4, -3e-4, 5e-4, -2e-3, 1e-4, -1e-4, 4e-4, 3e-3;
    const Eigen::Vector3d c(1e-4, -2e-4, 3e-4);
    BoundaryConditions bcs(mesh.num_nodes());
    for (int v : ExtractSurface(mesh).nodes)
      bcs.PrescribeNode(v, a * mesh.nodes.row(v).transpose() + c);
    StaticSolver solver(mesh, MaterialTable(Material{1e9, 0.3}), bcs);
    const StaticSolution sol = solver.Solve();
    ASSERT_TRUE(sol.status.converged) << sol.status.message;
    double error = 0.0, scale = 0.0;
    for (int v = 0; v < mesh.num_nodes(); ++v) {
      const Eigen::Vector3d exact = a * mesh.nodes.row(v).transpose() + c;
      error = std::max(error, (sol.displacement.segment<3>(3 * v) - exact).norm());
      scale = std::max(scale, exact.norm());
    }
    std::printf(
        "sliver volume ratio %.1e, order %d: field error %.1e of max, backward error %.1e\n",
        vmin / vmax, order, error / scale, sol.status.residual);
    worst_error = std::max(worst_error, error / scale);
    worst_backward = std::max(worst_backward, sol.status.residual);
  }
  EXPECT_LT(worst_error, 1e-8);
  EXPECT_LT(worst_backward, 1e-14);
  char figure[160];
  std::snprintf(figure, sizeof(figure),
                "volume ratio %.0e: field error %.1e relative, backward error %.1e", min_ratio,
                worst_error, worst_backward);
  RecordProperty("figure", figure);
  RecordProperty("bar", "field error < 1e-8 relative, backward error < 1e-14");
}

// Two strips side by side (y < 0.05 soft, y > 0.05 stiff, E ratio 1e6, ν = 0) stretched by a
// prescribed end displacement: the exact field is u_x = δ x / L in both, so the end reaction
// is δ/L (E1 A1 + E2 A2) and the soft strip's stress E1 δ/L, six orders below the stiff one's.
TEST(HardContrast, SoftStressRecoveredNextToAMillionTimesStifferStrip) {
  double worst_stress = 0.0, worst_backward = 0.0;
  for (int order : {1, 2}) {
    BoxMeshSettings s;
    s.upper = Eigen::Vector3d(1.0, 0.1, 0.1);
    s.nx = 10;
    s.ny = 2;
    s.nz = 1;
    s.order = order;
    TetMesh mesh = MakeBoxMesh(s);
    LabelRegionInBox(Eigen::Vector3d(-1, 0.05, -1), Eigen::Vector3d(2, 2, 2), 1, &mesh);
    const double e_soft = 1.0e5, e_hard = 1.0e11, delta = 1e-3;
    MaterialTable mats;
    mats.Set(0, Material{e_soft, 0.0});
    mats.Set(1, Material{e_hard, 0.0});
    BoundaryConditions bcs(mesh.num_nodes());
    FixNodesInBox(mesh, Eigen::Vector3d(-1, -1, -1), Eigen::Vector3d(1e-9, 1, 1), &bcs);
    const std::vector<int> end =
        NodesInBox(mesh, Eigen::Vector3d(1 - 1e-9, -1, -1), Eigen::Vector3d(2, 2, 2));
    for (int v : end) bcs.PrescribeNode(v, Eigen::Vector3d(delta, 0, 0));
    StaticSolver solver(mesh, mats, bcs);
    const StaticSolution sol = solver.Solve();
    ASSERT_TRUE(sol.status.converged) << sol.status.message;
    double pull = 0.0;
    for (int v : end) pull += sol.reaction(3 * v);
    const double exact_pull = delta * (e_soft + e_hard) * 0.005;
    EXPECT_NEAR(pull / exact_pull, 1.0, 1e-9);
    double stress_error = 0.0;
    for (int e = 0; e < mesh.num_elements(); ++e) {
      if (mesh.regions(e) != 0) continue;
      const double sxx = ElementStress(mesh, mats, sol.displacement, e)(0);
      stress_error = std::max(stress_error, std::abs(sxx / (e_soft * delta) - 1.0));
    }
    std::printf(
        "contrast 1e6 side by side, order %d: soft stress error %.1e, backward error %.1e\n", order,
        stress_error, sol.status.residual);
    worst_stress = std::max(worst_stress, stress_error);
    worst_backward = std::max(worst_backward, sol.status.residual);
  }
  EXPECT_LT(worst_stress, 1e-3);
  EXPECT_LT(worst_backward, 1e-14);
  char figure[160];
  std::snprintf(figure, sizeof(figure), "soft-strip stress error %.1e, backward error %.1e",
                worst_stress, worst_backward);
  RecordProperty("figure", figure);
  RecordProperty("bar", "soft stress within 1e-3, backward error < 1e-14");
}

// Cantilever strips 1 m long, 0.1 m wide, t = 10, 1, 0.1 mm thick (L/t up to 10^4), 20 x 2 x 2
// quadratic cells (two layers through the thickness), ν = 0, tip load: Euler–Bernoulli
// δ = P L³ / (3 E I). The backward error stays at rounding level throughout; the forward
// error grows with cond(K) ~ (L/t)² × element aspect: fine to L/t = 1000, not at 10^4
// (measured and recorded, not hidden: the support reactions there miss the load).
// At L/t = 10^4 the matrix is at the edge of double precision, and whether CHOLMOD's supernodal
// factorisation meets a zero pivot depends on the BLAS kernel (measured 2026-12-02 with OpenBLAS
// 0.3.21: its Haswell kernel factors it, tip 1.16 x; its SkylakeX (AVX-512) kernel stops at a
// zero pivot). Both are accepted there: a solve at rounding-level backward error, or a refusal
// that says the matrix is not positive definite and names the pivot. Thinner than that is not
// a use the solver supports.
TEST(HardThinPlate, TipDeflectionAndBackwardErrorWhenPlatesAreThin) {
  double worst_backward = 0.0, worst_ratio_error = 0.0, thinnest_ratio = 0.0, thinnest_eq = 0.0;
  bool thinnest_refused = false;
  for (double t : {1e-2, 1e-3, 1e-4}) {
    Cantilever plate;
    plate.height = t;
    plate.material = Material{2.0e11, 0.0};
    plate.force = 1e-3 * std::pow(t / 1e-3, 3);  // keeps δ around 10 mm
    plate.check_equilibrium = false;
    plate.may_refuse = t < 1e-3;
    SolveStatus status;
    const double ratio = plate.Solve(2, 20, 2, &status) / plate.EulerBernoulli();
    if (!status.converged) {
      ASSERT_TRUE(plate.may_refuse) << status.message;
      EXPECT_NE(status.message.find("not positive definite"), std::string::npos) << status.message;
      EXPECT_NE(status.message.find("first zero pivot is the"), std::string::npos)
          << status.message;
      std::printf("thin plate L/t = %.0f: refused: %s\n", 1.0 / t, status.message.c_str());
      thinnest_refused = true;
      continue;
    }
    std::printf(
        "thin plate L/t = %.0f: tip / Euler-Bernoulli %.4f, backward error %.1e, "
        "support reactions off the load by %.1e\n",
        1.0 / t, ratio, status.residual, plate.equilibrium_error);
    worst_backward = std::max(worst_backward, status.residual);
    if (t >= 1e-3) {
      worst_ratio_error = std::max(worst_ratio_error, std::abs(ratio - 1.0));
    } else {
      thinnest_ratio = ratio;
      thinnest_eq = plate.equilibrium_error;
    }
  }
  EXPECT_LT(worst_backward, 1e-14);
  EXPECT_LT(worst_ratio_error, 0.01);
  char figure[240];
  if (thinnest_refused) {
    std::snprintf(figure, sizeof(figure),
                  "L/t <= 1000: tip within %.2f %% of Euler-Bernoulli, backward error <= %.1e; "
                  "L/t = 1e4 refused as not positive definite (zero pivot)",
                  100.0 * worst_ratio_error, worst_backward);
  } else {
    std::snprintf(figure, sizeof(figure),
                  "L/t <= 1000: tip within %.2f %% of Euler-Bernoulli; backward error <= %.1e up "
                  "to L/t = 1e4, where the tip is %.2f x and reactions miss the load by %.0f %%",
                  100.0 * worst_ratio_error, worst_backward, thinnest_ratio, 100.0 * thinnest_eq);
  }
  RecordProperty("figure", figure);
  RecordProperty("bar",
                 "L/t <= 1000 within 1 % of Euler-Bernoulli; backward error < 1e-14; L/t = 1e4 "
                 "solved at that backward error or refused naming the zero pivot");
}

}  // namespace
}  // namespace spidarcad::fem
