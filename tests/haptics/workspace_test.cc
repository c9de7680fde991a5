// Tests of the deliverable-wrench LP and the workspace sweep against a brute-force vertex
// enumeration in tension space (no pseudo-inverse, no null space) and device symmetries.
// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#include "spidarcad/haptics/workspace.h"

#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <Eigen/Geometry>
#include <cmath>
#include <limits>
#include <random>

#include "spidarcad/haptics/tension.h"

namespace spidarcad::haptics {
namespace {

using Eigen::Vector3d;

// Brute force in (τ, s): a vertex of {A τ = s e, τ in the box} fixes 2 of the 8 tensions at a
// bound (9 unknowns, 7 equations). Enumerates all 28 pairs × 4 bound choices, solves the 9 by 9
// system by full-pivot LU and keeps the largest feasible s. Returns NaN when none is feasible.
double BruteForceMax(const Matrix78d& A, const Vector7d& e, double lo, double hi) {
  double best = -std::numeric_limits<double>::infinity();
  for (int i = 0; i < 8; ++i) {
    for (int j = i + 1; j < 8; ++j) {
      for (int choice = 0; choice < 4; ++choice) {
        Eigen::Matrix<double, 9, 9> M = Eigen::Matrix<double, 9, 9>::Zero();
        Eigen::Matrix<double, 9, 1> rhs = Eigen::Matrix<double, 9, 1>::Zero();
        M.topLeftCorner<7, 8>() = A;
        M.block<7, 1>(0, 8) = -e;
        M(7, i) = 1;
        rhs(7) = (choice & 1) ? hi : lo;
        M(8, j) = 1;
        rhs(8) = (choice & 2) ? hi : lo;
        const Eigen::FullPivLU<Eigen::Matrix<double, 9, 9>> lu(M);
        if (lu.rank() < 9) continue;
        const Eigen::Matrix<double, 9, 1> x = lu.solve(rhs);
        if ((M * x - rhs).norm() > 1e-9) continue;
        bool feasible = true;
        for (int k = 0; k < 8; ++k) {
          if (x(k) < lo - 1e-9 || x(k) > hi + 1e-9) feasible = false;
        }
        if (feasible) best = std::max(best, x(8));
      }
    }
  }
  return std::isfinite(best) ? best : std::nan("");
}

Eigen::Matrix3d RandomRotation(std::mt19937* rng, double max_angle) {
  std::normal_distribution<double> normal(0.0, 1.0);
  std::uniform_real_distribution<double> angle(-max_angle, max_angle);
  const Vector3d axis = Vector3d(normal(*rng), normal(*rng), normal(*rng)).normalized();
  return Eigen::AngleAxisd(angle(*rng), axis).toRotationMatrix();
}

TEST(MaxWrenchAlong, MatchesBruteForceVertexEnumeration) {
  const SpidarGeometry g;
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> pos(-0.1, 0.1), grasp(0.8, 2.3), unit(-1, 1);
  std::normal_distribution<double> normal(0, 1);
  int compared = 0, infeasible = 0;
  for (int trial = 0; trial < 300; ++trial) {
    const GripPose pose = GripPose::FromFrame(Vector3d(pos(rng), pos(rng), pos(rng)),
                                              RandomRotation(&rng, 0.6), grasp(rng), g.d);
    const Matrix78d A = WrenchMatrix(g, pose);
    Vector7d e = Vector7d::Zero();
    if (trial % 3 == 0) {
      e(trial % 7) = (trial % 2) ? 1 : -1;  // an axis of force, moment or grasp
    } else {
      for (int k = 0; k < 7; ++k) e(k) = normal(rng);
      e.normalize();
    }
    const double lo = 0.2 + 0.5 * (trial % 4), hi = 8.0;
    const DeliverableWrench r = MaxWrenchAlong(A, e, lo, hi);
    const double ref = BruteForceMax(A, e, lo, hi);
    if (std::isnan(ref)) {
      EXPECT_EQ(r.status, DeliverableStatus::kInfeasible) << trial;
      ++infeasible;
      continue;
    }
    ASSERT_EQ(r.status, DeliverableStatus::kOk) << trial;
    EXPECT_NEAR(r.s_max, ref, 1e-8 * (1 + std::abs(ref))) << trial;
    // The returned tensions realise s_max·e exactly and respect the bounds.
    EXPECT_LT((A * r.tau - r.s_max * e).norm(), 1e-8) << trial;
    EXPECT_GE(r.tau.minCoeff(), lo);
    EXPECT_LE(r.tau.maxCoeff(), hi);
    ++compared;
  }
  // Most samples have force closure; some (large τ_min, poses far out) do not.
  EXPECT_GT(compared, 150);
  EXPECT_GT(infeasible, 5);
}

TEST(MaxWrenchAlong, ReportsInfeasibleWhenBoundsAreTooTightAndSingularOnNaN) {
  const SpidarGeometry g;
  GripPose pose = GripPose::Rest(g.d);
  pose.p0 = Vector3d(0.05, 0.02, -0.03);
  const Matrix78d A = WrenchMatrix(g, pose);
  Vector7d e = Vector7d::Zero();
  e(0) = 1;
  // All tensions ≈ 8 N: A τ ≈ 8 A·1, which is not along +x off the centre. (At the centre the
  // null vector of A is exactly (1, ..., 1) by symmetry, so that would be feasible.)
  EXPECT_EQ(MaxWrenchAlong(A, e, 7.999, 8.0).status, DeliverableStatus::kInfeasible);
  EXPECT_TRUE(std::isnan(BruteForceMax(A, e, 7.999, 8.0)));
  Matrix78d bad = A;
  bad(0, 0) = std::nan("");
  EXPECT_EQ(MaxWrenchAlong(bad, e, 0.2, 8.0).status, DeliverableStatus::kSingular);
}

TEST(MaxWrenchAlong, IsMirrorSymmetricInXAtTheCentre) {
  // Reflection x → −x maps the device onto itself at rest (corners 1↔2, 3↔4, 5↔6, 7↔8 and
  // P+2 ↔ P−2), so the force deliverable along +x at +x·t equals that along −x at −x·t.
  const SpidarGeometry g;
  for (double t : {0.0, 0.05, 0.1, 0.15, 0.19}) {
    GripPose plus = GripPose::Rest(g.d), minus = GripPose::Rest(g.d);
    plus.p0.x() = t;
    minus.p0.x() = -t;
    Vector7d ex = Vector7d::Zero();
    ex(0) = 1;
    const double fp = MaxWrenchAlong(WrenchMatrix(g, plus), ex, 0.2, 8).s_max;
    const double fm = MaxWrenchAlong(WrenchMatrix(g, minus), -ex, 0.2, 8).s_max;
    EXPECT_NEAR(fp, fm, 1e-9 * (1 + std::abs(fp))) << t;
  }
}

TEST(SweepWorkspace, SamplesMatchDirectComputationAndFallOffTowardTheFaces) {
  const SpidarGeometry g;
  WorkspaceSweepSettings s;
  s.step = 0.02;
  s.angle_step_deg = 15;
  const std::vector<WorkspaceSample> samples = SweepWorkspace(g, s);
  int translate = 0, rotate = 0;
  for (const WorkspaceSample& w : samples) {
    if (w.sweep == "translate") {
      ++translate;
      const int axis = w.axis - 'x';
      GripPose pose = GripPose::Rest(g.d);
      pose.p0(axis) = w.sign * w.distance;
      Vector7d e = Vector7d::Zero();
      e(axis) = w.sign;
      const double ref = std::max(0.0, BruteForceMax(WrenchMatrix(g, pose), e, 0.2, 8.0));
      EXPECT_NEAR(w.force, ref, 1e-8 * (1 + ref)) << w.axis << w.sign << " " << w.distance;
      EXPECT_LE(w.force_min, w.force + 1e-12);
      // Every attachment point stays inside the frame.
      const double half = axis == 0 ? g.a : (axis == 1 ? g.b : g.c);
      EXPECT_LT(w.distance + (axis == 2 ? 0.0 : g.d), half);
    } else {
      ++rotate;
      EXPECT_LE(w.angle_deg, s.max_angle_deg + 1e-9);
    }
  }
  EXPECT_GT(translate, 40);
  EXPECT_EQ(rotate, 6 * 7);
  // Along each axis the force in the direction of motion drops well below its centre value
  // before the grip reaches the face.
  for (const SweepFalloff& f : SummarizeSweep(samples, "translate")) {
    EXPECT_GT(f.full, 1.0) << f.axis << f.sign;
    double last = 0;
    for (const WorkspaceSample& w : samples) {
      if (w.sweep == "translate" && w.axis == f.axis && w.sign == f.sign) last = w.force;
    }
    EXPECT_LT(last, 0.5 * f.full) << f.axis << f.sign;
    EXPECT_LE(f.last_full, 0.24);
  }
}

TEST(SummarizeSweep, FindsTheNinetyFiveAndOnePercentCrossings) {
  std::vector<WorkspaceSample> samples;
  const double values[] = {10, 9.9, 9.6, 9.0, 5.0, 0.05, 0.0};
  for (int k = 0; k < 7; ++k) {
    WorkspaceSample w;
    w.sweep = "translate";
    w.axis = 'y';
    w.sign = -1;
    w.distance = 0.01 * k;
    w.force = values[k];
    samples.push_back(w);
  }
  const std::vector<SweepFalloff> f = SummarizeSweep(samples, "translate");
  ASSERT_EQ(f.size(), 1u);
  EXPECT_EQ(f[0].axis, 'y');
  EXPECT_DOUBLE_EQ(f[0].full, 10);
  EXPECT_DOUBLE_EQ(f[0].last_full, 0.02);
  EXPECT_DOUBLE_EQ(f[0].first_zero, 0.05);
  // Rated at 5: full is 5, stays >= 4.75 up to 0.04 (value 5.0), and 0.05 at 0.05 m is exactly
  // 1 % of 5.
  const std::vector<SweepFalloff> r = SummarizeSweep(samples, "translate", 5.0);
  ASSERT_EQ(r.size(), 1u);
  EXPECT_DOUBLE_EQ(r[0].centre, 10);
  EXPECT_DOUBLE_EQ(r[0].full, 5);
  EXPECT_DOUBLE_EQ(r[0].last_full, 0.04);
  EXPECT_DOUBLE_EQ(r[0].first_zero, 0.05);
}

TEST(WorkspaceSweepSettings, ValidateRejectsBadFields) {
  WorkspaceSweepSettings s;
  EXPECT_NO_THROW(s.Validate());
  s.step = 0;
  EXPECT_THROW(s.Validate(), std::invalid_argument);
  s = {};
  s.tau_min = 9;
  EXPECT_THROW(s.Validate(), std::invalid_argument);
  s = {};
  s.angle_step_deg = std::nan("");
  EXPECT_THROW(s.Validate(), std::invalid_argument);
}

}  // namespace
}  // namespace spidarcad::haptics
