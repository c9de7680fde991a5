// Tests of the wrench matrix and the tension solver against independent computations: hand
// numbers at rest, the virtual-work identity by finite differences of the kinematics, brute
// force over all 3^8 active sets, and explicit KKT conditions.
// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#include "spidarcad/haptics/tension.h"

#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <limits>
#include <random>
#include <stdexcept>
#include <string>
#include <vector>

namespace spidarcad::haptics {
namespace {

using Eigen::MatrixXd;
using Eigen::Vector3d;
using Eigen::VectorXd;

Eigen::Matrix3d RandomRotation(std::mt19937* rng) {
  std::normal_distribution<double> normal(0.0, 1.0);
  Eigen::Quaterniond q(normal(*rng), normal(*rng), normal(*rng), normal(*rng));
  q.normalize();
  return q.toRotationMatrix();
}

Vector3d RandomVector(std::mt19937* rng, double half_range) {
  std::uniform_real_distribution<double> u(-half_range, half_range);
  return Vector3d(u(*rng), u(*rng), u(*rng));
}

// Objective written out from Eq. 17 as re-derived in docs/architecture.md, term by term.
double Objective(const Matrix78d& A, const Vector7d& q, const TensionSettings& s,
                 const Vector8d& tau) {
  double force_error = 0, moment_error = 0;
  for (int r = 0; r < 3; ++r) {
    double fr = q(r), mr = q(3 + r);
    for (int i = 0; i < 8; ++i) {
      fr -= tau(i) * A(r, i);
      mr -= tau(i) * A(3 + r, i);
    }
    force_error += fr * fr;
    moment_error += mr * mr;
  }
  double grasp_error = q(6);
  for (int i = 0; i < 8; ++i) grasp_error -= tau(i) * A(6, i);
  return force_error + s.s0 * moment_error + s.s1 * grasp_error * grasp_error +
         s.s2 * tau.squaredNorm();
}

// Quadratic form of J: J = τᵀHτ − 2bᵀτ + const, built with dynamic matrices.
void QuadraticForm(const Matrix78d& A, const Vector7d& q, const TensionSettings& s, MatrixXd* H,
                   VectorXd* b) {
  VectorXd w(7);
  w << 1, 1, 1, s.s0, s.s0, s.s0, s.s1;
  const MatrixXd Ad = A;
  *H = Ad.transpose() * w.asDiagonal() * Ad + s.s2 * MatrixXd::Identity(8, 8);
  *b = Ad.transpose() * (w.asDiagonal() * VectorXd(q));
}

struct Reference {
  Vector8d tau;
  double objective = std::numeric_limits<double>::infinity();
};

// Brute force: for each of the 3^8 patterns (free / at τ_min / at τ_max) solve the equality-
// constrained problem; the optimum is the feasible candidate of least objective (the optimum's
// own pattern is among them and yields it).
Reference BruteForce(const Matrix78d& A, const Vector7d& q, const TensionSettings& s) {
  MatrixXd H;
  VectorXd b;
  QuadraticForm(A, q, s, &H, &b);
  Reference best;
  for (int pattern = 0; pattern < 6561; ++pattern) {
    int code = pattern;
    int kind[8];
    std::vector<int> free;
    Vector8d tau = Vector8d::Zero();
    for (int i = 0; i < 8; ++i) {
      kind[i] = code % 3;
      code /= 3;
      if (kind[i] == 0) free.push_back(i);
      if (kind[i] == 1) tau(i) = s.tau_min;
      if (kind[i] == 2) tau(i) = s.tau_max;
    }
    const int k = static_cast<int>(free.size());
    if (k > 0) {
      MatrixXd Hff(k, k);
      VectorXd rhs(k);
      for (int a = 0; a < k; ++a) {
        rhs(a) = b(free[a]);
        for (int j = 0; j < 8; ++j) {
          if (kind[j] != 0) rhs(a) -= H(free[a], j) * tau(j);
        }
        for (int c = 0; c < k; ++c) Hff(a, c) = H(free[a], free[c]);
      }
      const VectorXd x = Hff.ldlt().solve(rhs);
      bool feasible = true;
      for (int a = 0; a < k; ++a) {
        if (x(a) < s.tau_min - 1e-12 || x(a) > s.tau_max + 1e-12) feasible = false;
        tau(free[a]) = std::clamp(x(a), s.tau_min, s.tau_max);
      }
      if (!feasible) continue;
    }
    const double J = Objective(A, q, s, tau);
    if (J < best.objective) {
      best.objective = J;
      best.tau = tau;
    }
  }
  return best;
}

// Explicit KKT conditions of the box-constrained problem at τ: ∂J/∂τ_i = 0 for free strings,
// >= 0 at τ_min, <= 0 at τ_max, within a tolerance scaled by the problem.
::testing::AssertionResult SatisfiesKkt(const Matrix78d& A, const Vector7d& q,
                                        const TensionSettings& s, const Vector8d& tau) {
  MatrixXd H;
  VectorXd b;
  QuadraticForm(A, q, s, &H, &b);
  const VectorXd grad = 2.0 * (H * VectorXd(tau) - b);
  const double tol = 1e-7 * (1.0 + b.cwiseAbs().maxCoeff() + H.cwiseAbs().maxCoeff() * s.tau_max);
  const double bound_tol = 1e-9;
  for (int i = 0; i < 8; ++i) {
    if (tau(i) < s.tau_min - bound_tol || tau(i) > s.tau_max + bound_tol) {
      return ::testing::AssertionFailure() << "tau(" << i << ") = " << tau(i) << " out of bounds";
    }
    const bool at_min = tau(i) <= s.tau_min + bound_tol;
    const bool at_max = tau(i) >= s.tau_max - bound_tol;
    if (at_min && grad(i) < -tol) {
      return ::testing::AssertionFailure()
             << "string " << i << " at tau_min with gradient " << grad(i) << " (should be >= 0)";
    }
    if (at_max && grad(i) > tol) {
      return ::testing::AssertionFailure()
             << "string " << i << " at tau_max with gradient " << grad(i) << " (should be <= 0)";
    }
    if (!at_min && !at_max && std::abs(grad(i)) > tol) {
      return ::testing::AssertionFailure() << "free string " << i << " has gradient " << grad(i);
    }
  }
  return ::testing::AssertionSuccess();
}

TEST(WrenchMatrix, MatchesHandComputedColumnsAtRest) {
  const SpidarGeometry g;  // a = b = c = 0.24 m, d = 0.04 m
  const Matrix78d A = WrenchMatrix(g, GripPose::Rest(g.d));
  // String 1: P+1 = (0, 0.04, 0) to Q1 = (0.24, 0.24, 0.24); v = (0.24, 0.20, 0.24).
  // n = p1 × p2 / |.| = (0, 0, −1). r × c = (0.04·0.24, 0, −0.04·0.24) / L, g = +0.0096 / L.
  const double L = std::sqrt(0.1552);
  Vector7d w1;
  w1 << 0.24 / L, 0.20 / L, 0.24 / L, 0.0096 / L, 0, -0.0096 / L, 0.0096 / L;
  EXPECT_LT((A.col(0) - w1).norm(), 1e-14) << A.col(0).transpose();
  // String 6: P−2 = (−0.04, 0, 0) to Q6 = (−0.24, 0.24, −0.24); v = (−0.20, 0.24, −0.24).
  // r × c = (0, 0.04·cz, −0.04·cy) = (0, −0.0096, −0.0096) / L; δ = −1, n·(r×c) = 0.0096 / L.
  Vector7d w6;
  w6 << -0.20 / L, 0.24 / L, -0.24 / L, 0, -0.0096 / L, -0.0096 / L, -0.0096 / L;
  EXPECT_LT((A.col(5) - w6).norm(), 1e-14) << A.col(5).transpose();
  // String 3: P−1 = (0, −0.04, 0) to Q3 = (0.24, −0.24, 0.24); v = (0.24, −0.20, 0.24).
  // r × c = (−0.04·0.24, 0, 0.04·0.24) / L; δ = +1, n·(r×c) = −0.0096 / L.
  Vector7d w3;
  w3 << 0.24 / L, -0.20 / L, 0.24 / L, -0.0096 / L, 0, 0.0096 / L, -0.0096 / L;
  EXPECT_LT((A.col(2) - w3).norm(), 1e-14) << A.col(2).transpose();
  // By the symmetry of the rest pose equal tensions cancel exactly: A·1 = 0 (force closure).
  EXPECT_LT((A * Vector8d::Ones()).norm(), 1e-14);
}

TEST(WrenchMatrix, SatisfiesVirtualWorkIdentityForSmallMotions) {
  // Power of the strings Σ τ_i c_i·Ṗ_i equals f·ṗ0 + m·ω − (g/2) θ̇ for (f, m, g) = A τ, with Ṗ_i
  // from central differences of the attachment points along a pose path.
  const SpidarGeometry g;
  std::mt19937 rng(20261122);
  std::uniform_real_distribution<double> grasp_dist(0.3, 2.8), tension(0.0, 8.0);
  const double h = 1e-6;
  for (int trial = 0; trial < 50; ++trial) {
    const Vector3d p0 = RandomVector(&rng, 0.1);
    const Eigen::Matrix3d R = RandomRotation(&rng);
    const double theta = grasp_dist(rng);
    const Vector3d v = RandomVector(&rng, 1.0);
    const Vector3d omega = RandomVector(&rng, 1.0);
    const double theta_dot = std::uniform_real_distribution<double>(-1.0, 1.0)(rng);
    auto pose_at = [&](double t) {
      const double angle = omega.norm() * t;
      const Eigen::Matrix3d Rt =
          Eigen::AngleAxisd(angle, omega.normalized()).toRotationMatrix() * R;
      return GripPose::FromFrame(p0 + t * v, Rt, theta + t * theta_dot, g.d);
    };
    const GripPose pose = pose_at(0.0), plus = pose_at(h), minus = pose_at(-h);
    Vector8d tau;
    for (int i = 0; i < 8; ++i) tau(i) = tension(rng);
    const Matrix78d A = WrenchMatrix(g, pose);
    const Vector7d q = A * tau;
    double string_power = 0;
    for (int i = 0; i < 8; ++i) {
      const Vector3d c = (g.Corner(i) - pose.Attachment(i)).normalized();
      const Vector3d P_dot = (plus.Attachment(i) - minus.Attachment(i)) / (2 * h);
      string_power += tau(i) * c.dot(P_dot);
    }
    const double grip_power =
        q.head<3>().dot(v) + q.segment<3>(3).dot(omega) - 0.5 * q(6) * theta_dot;
    EXPECT_NEAR(string_power, grip_power, 1e-7 * (1.0 + std::abs(string_power)))
        << "trial " << trial;
  }
}

TEST(TensionSettings, ValidateRejectsOutOfRangeFields) {
  TensionSettings s;
  EXPECT_NO_THROW(s.Validate());
  auto expect_throw = [](TensionSettings bad) {
    EXPECT_THROW(bad.Validate(), std::invalid_argument);
  };
  s = {};
  s.tau_min = -0.1;
  expect_throw(s);
  s = {};
  s.tau_max = s.tau_min;
  expect_throw(s);
  s = {};
  s.s0 = 0;
  expect_throw(s);
  s = {};
  s.s1 = -1;
  expect_throw(s);
  s = {};
  s.s2 = 0;
  expect_throw(s);
  s = {};
  s.s2 = std::nan("");
  expect_throw(s);
  EXPECT_THROW(TensionSolver{s}, std::invalid_argument);
  const TensionSettings scaled = TensionSettings::ForPoleLength(0.05);
  EXPECT_DOUBLE_EQ(scaled.s0, 400.0);
  EXPECT_DOUBLE_EQ(scaled.s1, 400.0);
}

struct Case {
  GripPose pose;
  Vector7d q;
  const char* kind;
};

std::vector<Case> MakeCases(const SpidarGeometry& g) {
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> grasp_dist(0.4, 2.7), unit(-1.0, 1.0);
  auto random_wrench = [&](double force, double moment) {
    Vector7d q;
    q << force * unit(rng), force * unit(rng), force * unit(rng), moment * unit(rng),
        moment * unit(rng), moment * unit(rng), moment * unit(rng);
    return q;
  };
  std::vector<Case> cases;
  for (int k = 0; k < 30; ++k) {  // ordinary poses, displayable requests
    cases.push_back(
        {GripPose::FromFrame(RandomVector(&rng, 0.1), RandomRotation(&rng), grasp_dist(rng), g.d),
         random_wrench(2.0, 0.04), "feasible"});
  }
  for (int k = 0; k < 15; ++k) {  // huge requests
    cases.push_back(
        {GripPose::FromFrame(RandomVector(&rng, 0.1), RandomRotation(&rng), grasp_dist(rng), g.d),
         random_wrench(200.0, 5.0), "huge"});
  }
  for (int k = 0; k < 10; ++k) {  // grasp near 0 and near π
    const double grasp = (k % 2 == 0) ? 1e-4 * (1 + k) : M_PI - 1e-4 * (1 + k);
    cases.push_back({GripPose::FromFrame(RandomVector(&rng, 0.1), RandomRotation(&rng), grasp, g.d),
                     random_wrench(3.0, 0.06), "grasp_singular"});
  }
  for (int k = 0; k < 6; ++k) {  // grip 1 mm from a frame face, pushing toward that face
    const int axis = k % 3;
    const double sign = k < 3 ? 1.0 : -1.0;
    GripPose pose = GripPose::Rest(g.d);
    const double half = axis == 0 ? g.a : (axis == 1 ? g.b : g.c);
    // At rest pole 2 lies along x and pole 1 along y; along z the poles lie in the xy-plane.
    pose.p0(axis) = sign * (half - (axis == 2 ? 0.0 : g.d) - 1e-3);
    Vector7d q = random_wrench(1.0, 0.02);
    q(axis) = sign * 20.0;
    cases.push_back({pose, q, "near_face_push"});
  }
  cases.push_back({GripPose::Rest(g.d), Vector7d::Zero(), "zero"});
  return cases;
}

TEST(TensionSolver, MatchesBruteForceOverAllActiveSetsAndSatisfiesKkt) {
  const SpidarGeometry g;
  const TensionSettings s;
  TensionSolver solver(s);
  int saturated = 0;
  for (const Case& c : MakeCases(g)) {
    const Matrix78d A = WrenchMatrix(g, c.pose);
    solver.Reset();
    const TensionResult r = solver.Solve(A, c.q);
    ASSERT_NE(r.status, TensionStatus::kInvalidInput) << c.kind;
    ASSERT_NE(r.status, TensionStatus::kNotConverged) << c.kind;
    const Reference ref = BruteForce(A, c.q, s);
    EXPECT_LT((r.tau - ref.tau).cwiseAbs().maxCoeff(), 1e-7)
        << c.kind << "\n solver " << r.tau.transpose() << "\n brute  " << ref.tau.transpose();
    EXPECT_NEAR(r.objective, ref.objective, 1e-9 * (1 + ref.objective)) << c.kind;
    EXPECT_NEAR(r.objective, Objective(A, c.q, s, r.tau), 1e-9 * (1 + ref.objective));
    EXPECT_TRUE(SatisfiesKkt(A, c.q, s, r.tau)) << c.kind;
    EXPECT_LT((r.achieved - A * r.tau).norm(), 1e-12);
    EXPECT_LT((r.lost - (c.q - A * r.tau)).norm(), 1e-12);
    if (std::string(c.kind) == "huge" || std::string(c.kind) == "near_face_push") {
      EXPECT_EQ(r.status, TensionStatus::kSaturated) << c.kind;
    }
    if (r.status == TensionStatus::kSaturated) ++saturated;
  }
  EXPECT_GE(saturated, 21);
}

TEST(TensionSolver, MatchesBruteForceWithWeightsOfOrderOneAndTightBounds) {
  const SpidarGeometry g;
  TensionSettings s;
  s.s0 = 1.0;
  s.s1 = 2.0;
  s.s2 = 0.05;
  s.tau_min = 1.0;
  s.tau_max = 3.0;
  TensionSolver solver(s);
  for (const Case& c : MakeCases(g)) {
    const Matrix78d A = WrenchMatrix(g, c.pose);
    const TensionResult r = solver.Solve(A, c.q);  // warm-started across unrelated cases
    const Reference ref = BruteForce(A, c.q, s);
    EXPECT_LT((r.tau - ref.tau).cwiseAbs().maxCoeff(), 1e-7) << c.kind;
    EXPECT_TRUE(SatisfiesKkt(A, c.q, s, r.tau)) << c.kind;
  }
}

TEST(TensionSolver, DisplaysAFeasibleRequestAlmostExactly) {
  // q = A τ* with τ* strictly inside the bounds: only the S2 bias may remain.
  const SpidarGeometry g;
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> tension(1.0, 6.0);
  TensionSolver solver;
  for (int trial = 0; trial < 20; ++trial) {
    const GripPose pose = GripPose::FromFrame(RandomVector(&rng, 0.08), RandomRotation(&rng),
                                              1.2 + 0.02 * trial, g.d);
    const Matrix78d A = WrenchMatrix(g, pose);
    Vector8d tau_star;
    for (int i = 0; i < 8; ++i) tau_star(i) = tension(rng);
    const Vector7d q = A * tau_star;
    const TensionResult r = solver.Solve(A, q);
    EXPECT_EQ(r.status, TensionStatus::kOk);
    EXPECT_LT(r.lost.head<3>().norm(), 0.01 * q.head<3>().norm() + 1e-3) << trial;
    EXPECT_LT(r.lost.segment<3>(3).norm(), 0.01 * q.segment<3>(3).norm() + 1e-4) << trial;
  }
}

TEST(TensionSolver, ReportsOkWhenOnlyThePretensionBiasRemainsOffCentre) {
  // Off centre, q = 0 (or a small q) is exactly displayable with every string taut, but S2 trades
  // a few mN of it for lower tensions. That bias is not a saturation. Independent check that q
  // is displayable: the exact solutions form the line τ_p + α n (τ_p = A⁺ q, n spanning the
  // null space of the 7 by 8 A); intersect it with the bounds in closed form.
  const SpidarGeometry g;
  const TensionSettings s;
  TensionSolver solver(s);
  for (const double x : {0.02, 0.05, 0.08}) {
    for (const double fz : {0.0, 0.1, -0.3}) {
      GripPose pose = GripPose::Rest(g.d);
      pose.p0 = Eigen::Vector3d(x, 0.3 * x, -0.2 * x);
      const Matrix78d A = WrenchMatrix(g, pose);
      Vector7d q = Vector7d::Zero();
      q(2) = fz;
      solver.Reset();
      const TensionResult r = solver.Solve(A, q);
      const Vector8d particular = A.completeOrthogonalDecomposition().solve(q);
      const Eigen::JacobiSVD<Eigen::MatrixXd> svd(A, Eigen::ComputeFullV);
      const Vector8d n = svd.matrixV().col(7);
      ASSERT_LT((A * n).norm(), 1e-9);
      double lo = -std::numeric_limits<double>::infinity(), hi = -lo;
      for (int i = 0; i < 8; ++i) {
        ASSERT_GT(std::abs(n(i)), 1e-9);
        const double a = (s.tau_min - particular(i)) / n(i), b = (s.tau_max - particular(i)) / n(i);
        lo = std::max(lo, std::min(a, b));
        hi = std::min(hi, std::max(a, b));
      }
      ASSERT_LT(lo, hi) << "not displayable: test premise broken at x " << x << " fz " << fz;
      EXPECT_GT(r.lost.norm(), 1e-4) << "the S2 bias this test is about is absent at " << x;
      EXPECT_EQ(r.status, TensionStatus::kOk)
          << "x " << x << " fz " << fz << " lost " << r.lost.transpose();
      // A request far beyond the motors at the same pose is still a saturation.
      q(2) = 100.0;
      EXPECT_EQ(solver.Solve(A, q).status, TensionStatus::kSaturated) << x;
    }
  }
}

TEST(TensionSolver, ReturnsMinimumTensionsAndInvalidStatusOnNaN) {
  const SpidarGeometry g;
  TensionSolver solver;
  const Matrix78d A = WrenchMatrix(g, GripPose::Rest(g.d));
  for (int k = 0; k < 7; ++k) {
    Vector7d q = Vector7d::Zero();
    q(k) = (k % 2 == 0) ? std::nan("") : std::numeric_limits<double>::infinity();
    const TensionResult r = solver.Solve(A, q);
    EXPECT_EQ(r.status, TensionStatus::kInvalidInput);
    EXPECT_TRUE((r.tau.array() == solver.settings().tau_min).all()) << r.tau.transpose();
    EXPECT_TRUE(std::isnan(r.objective));
  }
  Matrix78d bad = A;
  bad(2, 3) = std::nan("");
  const TensionResult r = solver.Solve(bad, Vector7d::Zero());
  EXPECT_EQ(r.status, TensionStatus::kInvalidInput);
  EXPECT_TRUE((r.tau.array() == solver.settings().tau_min).all());
  // A string of zero length (attachment on its corner) makes A non-finite.
  GripPose on_corner = GripPose::Rest(g.d);
  on_corner.p0 = g.Corner(0) - on_corner.p1;
  EXPECT_EQ(solver.Solve(WrenchMatrix(g, on_corner), Vector7d::Zero()).status,
            TensionStatus::kInvalidInput);
  // The solver recovers on the next valid request.
  EXPECT_NE(solver.Solve(A, Vector7d::Zero()).status, TensionStatus::kInvalidInput);
}

TEST(TensionSolver, WarmStartGivesTheColdAnswerWithFewerIterations) {
  const SpidarGeometry g;
  TensionSolver warm, cold;
  int warm_iterations = 0, cold_iterations = 0;
  for (int k = 0; k < 300; ++k) {
    const double t = 0.01 * k;
    const Eigen::Matrix3d R =
        Eigen::AngleAxisd(0.6 * std::sin(t), Vector3d(1, 2, 3).normalized()).toRotationMatrix();
    const GripPose pose = GripPose::FromFrame(
        Vector3d(0.1 * std::sin(t), 0.05 * std::cos(2 * t), 0.08 * std::sin(3 * t)), R,
        1.5 + 0.5 * std::sin(t), g.d);
    Vector7d q;
    q << 6 * std::sin(t), 4 * std::cos(1.3 * t), -5 + 10 * std::sin(0.7 * t), 0.1 * std::sin(2 * t),
        0.05, -0.08 * std::cos(t), 0.1 * std::sin(4 * t);
    const Matrix78d A = WrenchMatrix(g, pose);
    const TensionResult rw = warm.Solve(A, q);
    cold.Reset();
    const TensionResult rc = cold.Solve(A, q);
    ASSERT_EQ(rw.status, rc.status) << k;
    EXPECT_LT((rw.tau - rc.tau).cwiseAbs().maxCoeff(), 1e-10) << k;
    warm_iterations += rw.iterations;
    cold_iterations += rc.iterations;
  }
  EXPECT_LT(warm_iterations, cold_iterations / 2);
}

// ---------------------------------------------------------------------------------------------
// Force closure and the lost wrench

// Null vector of a 7 by 8 matrix by the generalised cross product: n_i = (−1)^i det(A without
// column i) (independent of ForceClosureAt's SVD).
Vector8d CrossProductNullVector(const MatrixXd& A) {
  Vector8d n;
  for (int i = 0; i < 8; ++i) {
    MatrixXd minor(7, 7);
    for (int j = 0, c = 0; j < 8; ++j) {
      if (j != i) minor.col(c++) = A.col(j);
    }
    n(i) = ((i % 2 == 0) ? 1.0 : -1.0) * minor.determinant();
  }
  return n;
}

// Scales the moment and grasp rows by 1/d (every row in N per N).
MatrixXd ScaledRows(const Matrix78d& A, double d) {
  MatrixXd S = A;
  S.bottomRows(4) /= d;
  return S;
}

TEST(ForceClosureAt, AgreesWithTheSignsOfTheCrossProductNullVector) {
  const SpidarGeometry g;
  std::mt19937 rng(51);
  std::uniform_real_distribution<double> grasp(0.8, 2.3);
  int with = 0, without = 0;
  std::uniform_real_distribution<double> angle(-0.5, 0.5);
  for (int trial = 0; trial < 300; ++trial) {
    // Half near the centre with small turns (closure mostly holds), half anywhere.
    const bool near = trial % 2 == 0;
    const Eigen::Matrix3d R =
        near ? Eigen::AngleAxisd(angle(rng), RandomVector(&rng, 1).normalized()).toRotationMatrix()
             : RandomRotation(&rng);
    const GripPose pose =
        GripPose::FromFrame(RandomVector(&rng, near ? 0.05 : 0.15), R, grasp(rng), g.d);
    const Matrix78d A = WrenchMatrix(g, pose);
    const ForceClosure c = ForceClosureAt(A, g.d);
    Vector8d n = CrossProductNullVector(ScaledRows(A, g.d));
    n /= n.norm();
    if (n.sum() < 0) n = -n;
    EXPECT_LT((c.null_vector - n).norm(), 1e-8) << trial;
    EXPECT_LT((A * c.null_vector).norm(), 1e-12) << trial;
    EXPECT_EQ(c.closure, (n.array() > 0).all()) << trial;
    EXPECT_NEAR(c.margin, n.minCoeff() / n.cwiseAbs().maxCoeff(), 1e-8) << trial;
    (c.closure ? with : without) += 1;
  }
  EXPECT_GT(with, 20);
  EXPECT_GT(without, 20);
  // At rest every string carries the same share; NaN in, NaN out.
  const ForceClosure rest = ForceClosureAt(WrenchMatrix(g, GripPose::Rest(g.d)), g.d);
  EXPECT_TRUE(rest.closure);
  EXPECT_NEAR(rest.margin, 1.0, 1e-12);
  Matrix78d bad = WrenchMatrix(g, GripPose::Rest(g.d));
  bad(2, 3) = std::nan("");
  EXPECT_TRUE(std::isnan(ForceClosureAt(bad, g.d).margin));
  EXPECT_FALSE(ForceClosureAt(bad, g.d).closure);
}

// A direction y with yᵀA ≥ 0 column by column (the strings' cone lies on one side of the plane
// y = 0), found by brute force over the cone's facets: y ⊥ six columns, oriented to be ≥ 0 on
// the other two. Exists exactly when force closure is lost. Returns false when none is found.
bool SeparatingDirection(const Matrix78d& A, double d, Vector7d* y) {
  const MatrixXd S = ScaledRows(A, d);
  for (int a = 0; a < 8; ++a) {
    for (int b = a + 1; b < 8; ++b) {
      MatrixXd six(7, 6);
      for (int j = 0, c = 0; j < 8; ++j) {
        if (j != a && j != b) six.col(c++) = S.col(j);
      }
      const Eigen::JacobiSVD<MatrixXd> svd(six.transpose(), Eigen::ComputeFullV);
      Vector7d v = svd.matrixV().col(6);
      const double va = v.dot(S.col(a)), vb = v.dot(S.col(b));
      if (va < 0 && vb < 0) v = -v;
      if (v.dot(S.col(a)) >= -1e-12 && v.dot(S.col(b)) >= -1e-12) {
        // Back to the unscaled rows: yᵀA = vᵀS with y = diag(1,1,1,1/d,...) v.
        *y = v;
        y->tail<4>() /= d;
        return true;
      }
    }
  }
  return false;
}

TEST(HardTension, ReportsTheLostWrenchWhereForceClosureIsLostAndBeyondTheBounds) {
  // Poses without force closure (random poses off centre with large rotations, and the
  // interior singular family where A loses rank) and with it: requests the strings cannot
  // display (against the strings' cone, or beyond τ_max) and ordinary ones. Every answer must
  // equal the brute-force optimum over all 3^8 active sets, report lost = q − Aτ, flag it as
  // saturated when the loss is real, and, against the cone, lose at least the request's
  // component along the separating direction (no τ ≥ 0 has yᵀAτ < 0).
  const SpidarGeometry g;
  const TensionSettings s = TensionSettings::ForPoleLength(g.d);
  TensionSolver solver(s);
  std::mt19937 rng(52);
  std::uniform_real_distribution<double> grasp(0.9, 2.2);
  std::vector<GripPose> poses;
  while (poses.size() < 16) {
    const GripPose pose =
        GripPose::FromFrame(RandomVector(&rng, 0.15), RandomRotation(&rng), grasp(rng), g.d);
    if (!ForceClosureAt(WrenchMatrix(g, pose), g.d).closure) poses.push_back(pose);
  }
  poses.push_back(GripPose::FromFrame(
      Vector3d(0, 0, 0.05), Eigen::AngleAxisd(M_PI / 2, Vector3d::UnitZ()).toRotationMatrix(),
      M_PI / 2, g.d));  // rank 6
  double worst_tau = 0, worst_lost = 0, worst_cone = 0;
  int cone_cases = 0, saturated = 0;
  for (const GripPose& pose : poses) {
    const Matrix78d A = WrenchMatrix(g, pose);
    const ForceClosure closure = ForceClosureAt(A, g.d);
    ASSERT_FALSE(closure.closure);
    Vector7d y;
    ASSERT_TRUE(SeparatingDirection(A, g.d, &y));
    std::vector<Vector7d> requests;
    requests.push_back(-5.0 * y / y.head<3>().norm());  // straight against the cone
    Vector7d huge = Vector7d::Zero();
    huge(0) = 60;  // beyond what eight 8 N strings can give along x
    requests.push_back(huge);
    Vector7d ordinary;
    for (int k = 0; k < 7; ++k)
      ordinary(k) = (k < 3 ? 2.0 : 0.04) * std::uniform_real_distribution<double>(-1, 1)(rng);
    requests.push_back(ordinary);
    for (std::size_t r = 0; r < requests.size(); ++r) {
      const Vector7d& q = requests[r];
      solver.Reset();
      const TensionResult result = solver.Solve(A, q);
      ASSERT_NE(result.status, TensionStatus::kNotConverged);
      const Reference ref = BruteForce(A, q, s);
      worst_tau = std::max(worst_tau, (result.tau - ref.tau).cwiseAbs().maxCoeff());
      worst_lost = std::max(worst_lost, (result.lost - (q - A * ref.tau)).cwiseAbs().maxCoeff());
      if (r == 0) {
        ++cone_cases;
        // y·lost = y·q − y·Aτ ≤ y·q < 0: all of the request along y (at least) is lost.
        const double excess = y.dot(result.lost) - y.dot(q);
        worst_cone = std::max(worst_cone, excess / std::abs(y.dot(q)));
        EXPECT_EQ(result.status, TensionStatus::kSaturated);
      }
      if (r == 1) {
        EXPECT_EQ(result.status, TensionStatus::kSaturated);
      }
      saturated += result.status == TensionStatus::kSaturated;
    }
  }
  RecordProperty(
      "figure",
      "tensions off brute force by " + std::to_string(worst_tau) + " N, lost wrench by " +
          std::to_string(worst_lost) + " over " + std::to_string(poses.size()) +
          " poses without closure; lost along the separating direction exceeds the request's "
          "component by " +
          std::to_string(worst_cone) + " (relative, must be <= 0) in " +
          std::to_string(cone_cases) + " cases; " + std::to_string(saturated) + " saturated");
  RecordProperty(
      "bar",
      "tensions and lost wrench within 1e-7 of brute force; all of the request along the "
      "separating direction lost; infeasible requests flagged saturated");
  EXPECT_LT(worst_tau, 1e-7);
  EXPECT_LT(worst_lost, 1e-6);
  EXPECT_LE(worst_cone, 1e-9);
}

}  // namespace
}  // namespace spidarcad::haptics
