// Tests of SPIDAR-G inverse and forward kinematics (kinematics.h). References are independent:
// the paper's Eq. 7 written out, finite differences, least-squares optimality conditions and
// the known poses the lengths were generated from.
// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#include "spidarcad/haptics/kinematics.h"

#include <atomic>
#include <cmath>
#include <cstddef>
#include <cstdlib>
#include <limits>
#include <numbers>
#include <random>
#include <vector>

#include <Eigen/Geometry>
#include <Eigen/SVD>
#include <gtest/gtest.h>

#include "support/malloc_counter.h"

namespace spidarcad::haptics {
namespace {

constexpr double kPi = std::numbers::pi;
constexpr double kQuantum = 2 * kPi * 0.008 / 2000;  // 0.0251327 mm per encoder count
constexpr double kDeg = kPi / 180;

// Eq. 7a-h of the paper, typed out term by term (not through GripPose::Attachment).
Vector8d Eq7Lengths(const SpidarGeometry& g, const GripPose& pose) {
  const double a = g.a, b = g.b, c = g.c;
  const double x = pose.p0.x(), y = pose.p0.y(), z = pose.p0.z();
  const double x1 = pose.p1.x(), y1 = pose.p1.y(), z1 = pose.p1.z();
  const double x2 = pose.p2.x(), y2 = pose.p2.y(), z2 = pose.p2.z();
  auto n = [](double u, double v, double w) { return std::sqrt(u * u + v * v + w * w); };
  Vector8d l;
  l << n(x + x1 - a, y + y1 - b, z + z1 - c),  // 7a
      n(x + x1 + a, y + y1 - b, z + z1 - c),   // 7b
      n(x - x1 - a, y - y1 + b, z - z1 - c),   // 7c
      n(x - x1 + a, y - y1 + b, z - z1 - c),   // 7d
      n(x + x2 - a, y + y2 - b, z + z2 + c),   // 7e
      n(x - x2 + a, y - y2 - b, z - z2 + c),   // 7f
      n(x + x2 - a, y + y2 + b, z + z2 + c),   // 7g
      n(x - x2 + a, y - y2 + b, z - z2 + c);   // 7h
  return l;
}

Eigen::Matrix3d RandomRotation(std::mt19937& rng, double max_angle) {
  std::normal_distribution<double> normal;
  std::uniform_real_distribution<double> uni(0, 1);
  Eigen::Vector3d axis(normal(rng), normal(rng), normal(rng));
  axis.normalize();
  return Eigen::AngleAxisd(max_angle * uni(rng), axis).toRotationMatrix();
}

Eigen::Matrix3d AxisRotation(int axis, double angle) {
  return Eigen::AngleAxisd(angle, Eigen::Vector3d::Unit(axis)).toRotationMatrix();
}

GripPose RandomPose(std::mt19937& rng, const SpidarGeometry& g, double half_box,
                    double max_angle, double grasp_lo, double grasp_hi) {
  std::uniform_real_distribution<double> pos(-half_box, half_box);
  std::uniform_real_distribution<double> grasp(grasp_lo, grasp_hi);
  const Eigen::Vector3d p0(pos(rng), pos(rng), pos(rng));
  return GripPose::FromFrame(p0, RandomRotation(rng, max_angle), grasp(rng), g.d);
}

Vector8d Quantize(const Vector8d& l) {
  Vector8d q;
  for (int i = 0; i < 8; ++i) q(i) = std::round(l(i) / kQuantum) * kQuantum;
  return q;
}

// Largest distance between corresponding attachment points and centres of two poses.
double PoseDistance(const GripPose& a, const GripPose& b) {
  double m = (a.p0 - b.p0).norm();
  m = std::max(m, (a.p1 - b.p1).norm());
  m = std::max(m, (a.p2 - b.p2).norm());
  return m;
}

void ExpectAllNaN(const FkResult& r) {
  EXPECT_TRUE(r.pose.p0.array().isNaN().all());
  EXPECT_TRUE(r.pose.p1.array().isNaN().all());
  EXPECT_TRUE(r.pose.p2.array().isNaN().all());
  EXPECT_TRUE(r.R_DT.array().isNaN().all());
  EXPECT_TRUE(std::isnan(r.grasp));
  EXPECT_TRUE(std::isnan(r.residual));
}

// ---------------------------------------------------------------------------------------------
// Inverse kinematics and Jacobians

TEST(InverseKinematics, MatchesEq7ForRandomPoses) {
  SpidarGeometry g;
  g.a = 0.25;
  g.b = 0.22;
  g.c = 0.2;
  g.d = 0.05;
  std::mt19937 rng(1);
  for (int trial = 0; trial < 200; ++trial) {
    const GripPose pose = RandomPose(rng, g, 0.15, kPi, 0.2, kPi - 0.2);
    const Vector8d expected = Eq7Lengths(g, pose);
    const Vector8d l = InverseKinematics(g, pose);
    for (int i = 0; i < 8; ++i) EXPECT_NEAR(l(i), expected(i), 1e-15) << "string " << i + 1;
  }
}

TEST(InverseKinematics, RestPoseHasPaperSymmetry) {
  // At rest the grip is centred and symmetric: |Q − P| is the same for strings 1, 4 (and 2, 3,
  // etc.) by mirror symmetry, and computable by hand.
  const SpidarGeometry g;
  const Vector8d l = InverseKinematics(g, GripPose::Rest(g.d));
  const double a = g.a, d = g.d;
  // String 1: P+1 = (0, d, 0) to (a, a, a).
  EXPECT_NEAR(l(0), std::sqrt(a * a + (a - d) * (a - d) + a * a), 1e-15);
  // String 5: P+2 = (d, 0, 0) to (a, a, −a).
  EXPECT_NEAR(l(4), std::sqrt((a - d) * (a - d) + a * a + a * a), 1e-15);
  // String 6: P−2 = (−d, 0, 0) to (−a, a, −a).
  EXPECT_NEAR(l(5), l(4), 1e-15);
  // String 3: P−1 = (0, −d, 0) to (a, −a, a).
  EXPECT_NEAR(l(2), l(0), 1e-15);
}

TEST(InverseKinematics, PropagatesNaN) {
  const SpidarGeometry g;
  GripPose pose = GripPose::Rest(g.d);
  pose.p0.x() = std::nan("");
  EXPECT_TRUE(InverseKinematics(g, pose).array().isNaN().all());
}

TEST(StringJacobian, MatchesCentralFiniteDifferences) {
  const SpidarGeometry g;
  std::mt19937 rng(2);
  const double h = 1e-6;
  for (int trial = 0; trial < 50; ++trial) {
    const GripPose pose = RandomPose(rng, g, 0.18, kPi, 0.3, kPi - 0.3);
    const Matrix89d J = StringJacobian(g, pose);
    const Vector9d v = pose.Packed();
    for (int k = 0; k < 9; ++k) {
      Vector9d vp = v, vm = v;
      vp(k) += h;
      vm(k) -= h;
      const Vector8d fd = (Eq7Lengths(g, GripPose::Unpacked(vp)) -
                           Eq7Lengths(g, GripPose::Unpacked(vm))) / (2 * h);
      for (int i = 0; i < 8; ++i) EXPECT_NEAR(J(i, k), fd(i), 1e-8) << i << "," << k;
    }
  }
}

TEST(PoseJacobian, MatchesFiniteDifferencesOfRotationAndGrasp) {
  const SpidarGeometry g;
  std::mt19937 rng(3);
  const double h = 1e-6;
  for (int trial = 0; trial < 50; ++trial) {
    std::uniform_real_distribution<double> pos(-0.15, 0.15), grasp(0.4, kPi - 0.4);
    const Eigen::Vector3d p0(pos(rng), pos(rng), pos(rng));
    const Eigen::Matrix3d R = RandomRotation(rng, kPi);
    const double theta = grasp(rng);
    const GripPose pose = GripPose::FromFrame(p0, R, theta, g.d);
    const Matrix87d J = PoseJacobian(g, pose);
    for (int k = 0; k < 7; ++k) {
      auto perturbed = [&](double eps) {
        Eigen::Vector3d q0 = p0;
        Eigen::Matrix3d Rq = R;
        double t = theta;
        if (k < 3) q0(k) += eps;
        else if (k < 6) Rq = AxisRotation(k - 3, eps) * R;  // rotation about p0, axes of D
        else t += eps;
        return Eq7Lengths(g, GripPose::FromFrame(q0, Rq, t, g.d));
      };
      const Vector8d fd = (perturbed(h) - perturbed(-h)) / (2 * h);
      for (int i = 0; i < 8; ++i) EXPECT_NEAR(J(i, k), fd(i), 1e-8) << i << "," << k;
    }
  }
}

TEST(PoseJacobian, IsMinusTheWrenchColumnsOfEq10WithHalfGraspRow) {
  // w_i = [c_i; r_i × c_i; δ_i n·(r_i × c_i)] (Eq. 10-14), computed here from its definition.
  const SpidarGeometry g;
  std::mt19937 rng(4);
  for (int trial = 0; trial < 20; ++trial) {
    const GripPose pose = RandomPose(rng, g, 0.15, kPi, 0.4, kPi - 0.4);
    const Matrix87d J = PoseJacobian(g, pose);
    const Eigen::Vector3d n = pose.p1.cross(pose.p2).normalized();
    for (int i = 0; i < 8; ++i) {
      const Eigen::Vector3d P = (i < 4 ? pose.p1 : pose.p2) *
                                    ((i == 0 || i == 1 || i == 4 || i == 6) ? 1.0 : -1.0) +
                                pose.p0;
      const Eigen::Vector3d c = (g.Corner(i) - P).normalized();
      const Eigen::Vector3d r = P - pose.p0;
      const double delta = i < 4 ? 1.0 : -1.0;
      Vector7d w;
      w << c, r.cross(c), delta * n.dot(r.cross(c));
      for (int k = 0; k < 6; ++k) EXPECT_NEAR(J(i, k), -w(k), 1e-14);
      EXPECT_NEAR(J(i, 6), 0.5 * w(6), 1e-14);
    }
  }
}

// ---------------------------------------------------------------------------------------------
// Closed form

TEST(ClosedFormPose, IsExactOnExactLengths) {
  const SpidarGeometry g;
  std::mt19937 rng(5);
  double worst = 0;
  for (int trial = 0; trial < 2000; ++trial) {
    const GripPose truth = RandomPose(rng, g, 0.2, kPi / 2, 20 * kDeg, 160 * kDeg);
    GripPose pose;
    ASSERT_TRUE(ClosedFormPose(g, Eq7Lengths(g, truth), &pose)) << trial;
    worst = std::max(worst, PoseDistance(pose, truth));
  }
  EXPECT_LT(worst, 1e-9);
}

TEST(ClosedFormPose, IsExactForNonCubicFrame) {
  SpidarGeometry g;
  g.a = 0.3;
  g.b = 0.2;
  g.c = 0.25;
  g.d = 0.05;
  std::mt19937 rng(6);
  for (int trial = 0; trial < 500; ++trial) {
    const GripPose truth = RandomPose(rng, g, 0.12, kPi / 2, 30 * kDeg, 150 * kDeg);
    GripPose pose;
    ASSERT_TRUE(ClosedFormPose(g, Eq7Lengths(g, truth), &pose));
    EXPECT_LT(PoseDistance(pose, truth), 1e-9) << trial;
  }
}

// ---------------------------------------------------------------------------------------------
// Forward kinematics: exact, quantized and noisy lengths

TEST(ForwardKinematics, InvertsInverseKinematicsOverRandomPoses) {
  const SpidarGeometry g;
  ForwardKinematics fk(g);
  std::mt19937 rng(8);
  for (int trial = 0; trial < 3000; ++trial) {
    // Whole rotations up to 120° and grasps 20°..160° anywhere in a 40 cm cube.
    const GripPose truth = RandomPose(rng, g, 0.2, 120 * kDeg, 20 * kDeg, 160 * kDeg);
    fk.Reset();
    const FkResult r = fk.Solve(Eq7Lengths(g, truth));
    ASSERT_EQ(r.status, FkStatus::kOk) << trial;
    EXPECT_LT(PoseDistance(r.pose, truth), 1e-9) << trial;
    EXPECT_LT(r.residual, 1e-12);
    EXPECT_NEAR(r.pose.p1.norm(), g.d, 1e-15);
    EXPECT_NEAR(r.pose.p2.norm(), g.d, 1e-15);
    EXPECT_NEAR(r.grasp, truth.Grasp(), 1e-9);
    EXPECT_LT(RotationAngleBetween(r.R_DT, truth.Rotation()), 1e-8);
    EXPECT_TRUE(r.used_closed_form);
    EXPECT_LE(r.iterations, 3);
  }
}

TEST(ForwardKinematics, RecoversRotationsOf90DegreesAboutEachAxis) {
  const SpidarGeometry g;
  ForwardKinematics fk(g);
  for (int axis = 0; axis < 3; ++axis) {
    for (double angle : {-kPi / 2, kPi / 2}) {
      for (double grasp_deg = 20; grasp_deg <= 160; grasp_deg += 20) {
        for (const Eigen::Vector3d& p0 :
             {Eigen::Vector3d(0, 0, 0), Eigen::Vector3d(0.1, -0.08, 0.12)}) {
          const Eigen::Matrix3d R = AxisRotation(axis, angle);
          const GripPose truth = GripPose::FromFrame(p0, R, grasp_deg * kDeg, g.d);
          fk.Reset();
          const FkResult r = fk.Solve(Eq7Lengths(g, truth));
          ASSERT_EQ(r.status, FkStatus::kOk) << axis << " " << angle << " " << grasp_deg;
          EXPECT_LT(PoseDistance(r.pose, truth), 1e-9);
          EXPECT_LT(RotationAngleBetween(r.R_DT, R), 1e-8);
          EXPECT_NEAR(r.grasp, grasp_deg * kDeg, 1e-9);
        }
      }
    }
  }
}

TEST(ForwardKinematics, RecoversGripNearEveryFaceAndCorner) {
  const SpidarGeometry g;
  ForwardKinematics fk(g);
  std::mt19937 rng(9);
  std::vector<Eigen::Vector3d> centres;
  const double face = g.a - 0.025;  // 2.5 cm from a face
  for (int axis = 0; axis < 3; ++axis) {
    for (double s : {-1.0, 1.0}) {
      Eigen::Vector3d p = Eigen::Vector3d::Zero();
      p(axis) = s * face;
      centres.push_back(p);
    }
  }
  const double corner = g.a - 0.05;  // 5 cm from each of three faces
  for (int k = 0; k < 8; ++k) {
    centres.emplace_back((k & 1 ? -1 : 1) * corner, (k & 2 ? -1 : 1) * corner,
                         (k & 4 ? -1 : 1) * corner);
  }
  for (const Eigen::Vector3d& p0 : centres) {
    for (int trial = 0; trial < 20; ++trial) {
      const Eigen::Matrix3d R = trial == 0 ? Eigen::Matrix3d::Identity()
                                           : RandomRotation(rng, 45 * kDeg);
      const double grasp = (40 + 5 * trial) * kDeg;
      const GripPose truth = GripPose::FromFrame(p0, R, grasp, g.d);
      fk.Reset();
      const FkResult r = fk.Solve(Eq7Lengths(g, truth));
      ASSERT_EQ(r.status, FkStatus::kOk) << p0.transpose() << " trial " << trial;
      EXPECT_LT(PoseDistance(r.pose, truth), 1e-9) << p0.transpose() << " trial " << trial;
    }
  }
}

// 1/σ_min of the pose Jacobian in metres (rotation and grasp columns times 1/d), by SVD.
double GainBySvd(const SpidarGeometry& g, const GripPose& pose) {
  Matrix87d J = PoseJacobian(g, pose);
  J.rightCols<4>() /= g.d;
  return 1 / Eigen::JacobiSVD<Matrix87d>(J).singularValues()(6);
}

// The least-squares pose can never fit the measured lengths worse than the true pose does, and
// its gradient vanishes. To first order its distance from the truth is J⁺ δl, at most
// gain·|δl| in the scaled coordinates (δl: length error); twice that allows for curvature.
void CheckNoisyFit(const SpidarGeometry& g, const GripPose& truth, const Vector8d& measured,
                   const FkResult& r) {
  ASSERT_EQ(r.status, FkStatus::kOk);
  const Vector8d error = measured - Eq7Lengths(g, truth);
  const double truth_rms = std::sqrt(error.squaredNorm() / 8.0);
  EXPECT_LE(r.residual, truth_rms * (1 + 1e-9) + 1e-15);
  const Vector8d fit_res = Eq7Lengths(g, r.pose) - measured;
  EXPECT_NEAR(std::sqrt(fit_res.squaredNorm() / 8), r.residual, 1e-12);
  Matrix87d J = PoseJacobian(g, r.pose);
  J.rightCols<4>() /= g.d;
  EXPECT_LT((J.transpose() * fit_res).norm(), 1e-8);
  EXPECT_NEAR(r.error_gain, GainBySvd(g, r.pose), 0.05 * r.error_gain);
  const double bound = 2 * GainBySvd(g, truth) * error.norm();
  EXPECT_LT((r.pose.p0 - truth.p0).norm(), bound);
  EXPECT_LT(RotationAngleBetween(r.R_DT, truth.Rotation()), 2 * bound / g.d);
  EXPECT_NEAR(r.pose.p1.norm(), g.d, 1e-15);
  EXPECT_NEAR(r.pose.p2.norm(), g.d, 1e-15);
}

TEST(ForwardKinematics, FitsQuantizedLengthsToTheSensorFloor) {
  const SpidarGeometry g;
  ForwardKinematics fk(g);
  std::mt19937 rng(10);
  for (int trial = 0; trial < 1000; ++trial) {
    const GripPose truth = RandomPose(rng, g, 0.2, 90 * kDeg, 20 * kDeg, 160 * kDeg);
    const Vector8d measured = Quantize(Eq7Lengths(g, truth));
    fk.Reset();
    const FkResult r = fk.Solve(measured);
    CheckNoisyFit(g, truth, measured, r);
    if (HasFailure()) FAIL() << "trial " << trial;
  }
}

TEST(ForwardKinematics, FitsGaussianNoisyLengths) {
  const SpidarGeometry g;
  ForwardKinematics fk(g);
  std::mt19937 rng(11);
  std::normal_distribution<double> noise(0, 1e-5);  // 0.01 mm
  for (int trial = 0; trial < 1000; ++trial) {
    const GripPose truth = RandomPose(rng, g, 0.2, 90 * kDeg, 20 * kDeg, 160 * kDeg);
    Vector8d measured = Eq7Lengths(g, truth);
    for (int i = 0; i < 8; ++i) measured(i) += noise(rng);
    fk.Reset();
    const FkResult r = fk.Solve(measured);
    CheckNoisyFit(g, truth, measured, r);
    if (HasFailure()) FAIL() << "trial " << trial;
  }
}

TEST(ForwardKinematics, FitsCalibratedLevelNoiseWithRaisedResidualLimit) {
  // 0.8 % length error, the paper's calibrated device: the paper reports < 4 mm position error
  // in a 40 cm cube. Needs max_residual raised (see FkSettings).
  const SpidarGeometry g;
  FkSettings settings;
  settings.max_residual = 5e-3;
  ForwardKinematics fk(g, settings);
  std::mt19937 rng(12);
  std::normal_distribution<double> noise(0, 1);
  for (int trial = 0; trial < 300; ++trial) {
    const GripPose truth = RandomPose(rng, g, 0.1, 45 * kDeg, 60 * kDeg, 120 * kDeg);
    Vector8d measured = Eq7Lengths(g, truth);
    for (int i = 0; i < 8; ++i) measured(i) *= 1 + 0.008 * noise(rng);
    fk.Reset();
    const FkResult r = fk.Solve(measured);
    if (r.status != FkStatus::kOk) {
      // Refusal is allowed only for a residual beyond the limit.
      ASSERT_EQ(r.status, FkStatus::kUnreachable) << trial;
      continue;
    }
    const double truth_rms = std::sqrt((Eq7Lengths(g, truth) - measured).squaredNorm() / 8.0);
    EXPECT_LE(r.residual, truth_rms * (1 + 1e-9));
    EXPECT_LT((r.pose.p0 - truth.p0).norm(), 0.05) << trial;
  }
}

// ---------------------------------------------------------------------------------------------
// Warm start during fast motion

// A closed trajectory at 1 kHz: the centre runs round a 10 cm circle at 2 m/s, the grip spins at
// 20 rad/s about a tilted axis and the grasp swings between 50° and 130°.
GripPose FastTrajectory(const SpidarGeometry& g, int tick) {
  const double t = tick * 1e-3;
  const double omega = 20.0;  // rad/s: 0.1 m radius -> 2 m/s
  const Eigen::Vector3d p0(0.1 * std::cos(omega * t), 0.1 * std::sin(omega * t),
                           0.05 * std::sin(2 * omega * t));
  const Eigen::Matrix3d R =
      Eigen::AngleAxisd(omega * t, Eigen::Vector3d(0.3, -0.5, 1).normalized())
          .toRotationMatrix();
  const double grasp = kPi / 2 + 40 * kDeg * std::sin(3 * t * 2 * kPi);
  return GripPose::FromFrame(p0, R, grasp, g.d);
}

TEST(ForwardKinematics, WarmStartTracksFastMotionExactlyLikeColdSolves) {
  const SpidarGeometry g;
  ForwardKinematics warm(g);
  ForwardKinematics cold(g);
  int max_iterations = 0;
  int near_singular = 0;
  for (int tick = 0; tick < 600; ++tick) {
    const GripPose truth = FastTrajectory(g, tick);
    // Consecutive ticks really are fast: ≥ 1.9 mm and ≥ 0.019 rad apart.
    if (tick > 0) {
      const GripPose prev = FastTrajectory(g, tick - 1);
      ASSERT_GT((truth.p0 - prev.p0).norm(), 1.9e-3);
      ASSERT_GT(RotationAngleBetween(truth.Rotation(), prev.Rotation()), 0.019);
    }
    const Vector8d measured = Quantize(Eq7Lengths(g, truth));
    const FkResult r = warm.Solve(measured);
    ASSERT_EQ(r.status, FkStatus::kOk) << tick;
    if (tick > 0) {
      EXPECT_FALSE(r.used_closed_form) << tick;
      max_iterations = std::max(max_iterations, r.iterations);
    }
    cold.Reset();
    const FkResult c = cold.Solve(measured);
    ASSERT_EQ(c.status, FkStatus::kOk);
    // The reported sensitivity agrees with an SVD of the pose Jacobian at the fitted pose.
    EXPECT_NEAR(r.error_gain, GainBySvd(g, r.pose), 0.05 * r.error_gain) << tick;
    const double gain = GainBySvd(g, truth);
    const Vector8d error = measured - Eq7Lengths(g, truth);
    EXPECT_LT((r.pose.p0 - truth.p0).norm(), std::max(0.1e-3, 2 * gain * error.norm())) << tick;
    if (gain > 30) {
      // The trajectory passes near a singular pose of the device (see README): the fit may
      // have two nearby minima there, so warm and cold solves need not agree.
      ++near_singular;
      continue;
    }
    // No lag: the tracked pose is the least-squares pose of this tick's lengths.
    EXPECT_LT(PoseDistance(r.pose, c.pose), 1e-8) << tick;
    EXPECT_LT(RotationAngleBetween(r.R_DT, truth.Rotation()), 1 * kDeg) << tick;
  }
  EXPECT_LE(near_singular, 10);
  EXPECT_LE(max_iterations, 10);
}

TEST(ForwardKinematics, WarmStartFallsBackToClosedFormAfterAJump) {
  const SpidarGeometry g;
  ForwardKinematics fk(g);
  const GripPose a = GripPose::FromFrame(Eigen::Vector3d(0.15, 0.1, -0.1),
                                         Eigen::Matrix3d::Identity(), kPi / 2, g.d);
  const GripPose b = GripPose::FromFrame(Eigen::Vector3d(-0.15, -0.12, 0.15),
                                         AxisRotation(2, 170 * kDeg) * AxisRotation(0, 80 * kDeg),
                                         40 * kDeg, g.d);
  ASSERT_EQ(fk.Solve(Eq7Lengths(g, a)).status, FkStatus::kOk);
  const FkResult r = fk.Solve(Eq7Lengths(g, b));
  ASSERT_EQ(r.status, FkStatus::kOk);
  EXPECT_LT(PoseDistance(r.pose, b), 1e-9);
}

TEST(ForwardKinematics, KeepsWarmStartAcrossARefusedSample) {
  const SpidarGeometry g;
  ForwardKinematics fk(g);
  const GripPose a = GripPose::FromFrame(Eigen::Vector3d(0.05, 0.02, 0.01),
                                         AxisRotation(1, 0.3), 1.4, g.d);
  ASSERT_EQ(fk.Solve(Eq7Lengths(g, a)).status, FkStatus::kOk);
  Vector8d bad = Eq7Lengths(g, a);
  bad(3) = std::nan("");
  EXPECT_EQ(fk.Solve(bad).status, FkStatus::kInvalidInput);
  const FkResult r = fk.Solve(Eq7Lengths(g, a));
  ASSERT_EQ(r.status, FkStatus::kOk);
  EXPECT_FALSE(r.used_closed_form);
  EXPECT_LT(PoseDistance(r.pose, a), 1e-9);
}

// ---------------------------------------------------------------------------------------------
// Refusals and singular poses

TEST(ForwardKinematics, RefusesNaNInfiniteNegativeAndZeroLengths) {
  const SpidarGeometry g;
  ForwardKinematics fk(g);
  const Vector8d good = Eq7Lengths(g, GripPose::Rest(g.d));
  for (double bad : {std::nan(""), std::numeric_limits<double>::infinity(), -0.3, 0.0}) {
    for (int i = 0; i < 8; ++i) {
      Vector8d l = good;
      l(i) = bad;
      const FkResult r = fk.Solve(l);
      EXPECT_EQ(r.status, FkStatus::kInvalidInput) << bad << " at " << i;
      ExpectAllNaN(r);
    }
  }
}

TEST(ForwardKinematics, RefusesLengthsNoPoseCanProduce) {
  const SpidarGeometry g;
  ForwardKinematics fk(g);
  std::vector<Vector8d> cases;
  cases.push_back(Vector8d::Constant(0.05));  // near all eight corners at once
  cases.push_back(Vector8d::Constant(1.0));   // farther than the frame diagonal from all
  Vector8d triangle = Eq7Lengths(g, GripPose::Rest(g.d));
  triangle(0) = triangle(1) = 0.2;  // l1 + l2 < 2a: corners 1, 2 are 48 cm apart
  cases.push_back(triangle);
  std::mt19937 rng(13);
  for (int k = 0; k < 8; ++k) {
    // Exact lengths plus 5 mm along the left null vector of the pose Jacobian: the one
    // combination of length changes that no pose change can produce (8 strings, 7 DOF).
    const GripPose truth = RandomPose(rng, g, 0.1, 30 * kDeg, 60 * kDeg, 120 * kDeg);
    Eigen::JacobiSVD<Matrix87d> svd(PoseJacobian(g, truth), Eigen::ComputeFullU);
    cases.push_back(Eq7Lengths(g, truth) + 5e-3 * svd.matrixU().col(7));
  }
  for (std::size_t k = 0; k < cases.size(); ++k) {
    for (int pass = 0; pass < 2; ++pass) {  // cold, then warm from the rest pose
      fk.Reset();
      if (pass == 1) ASSERT_EQ(fk.Solve(Eq7Lengths(g, GripPose::Rest(g.d))).status, FkStatus::kOk);
      const FkResult r = fk.Solve(cases[k]);
      EXPECT_NE(r.status, FkStatus::kOk) << "case " << k << " pass " << pass;
      EXPECT_NE(r.status, FkStatus::kInvalidInput) << "case " << k;
      ExpectAllNaN(r);
    }
  }
}

TEST(ForwardKinematics, SolvesNearlyParallelPolesDownToTheLimit) {
  const SpidarGeometry g;
  ForwardKinematics fk(g);
  const Eigen::Matrix3d R = AxisRotation(0, 0.4) * AxisRotation(2, 0.3);
  const Eigen::Vector3d p0(0.03, -0.05, 0.02);
  for (double grasp_deg : {3.0, 10.0, 170.0, 177.0}) {
    const GripPose truth = GripPose::FromFrame(p0, R, grasp_deg * kDeg, g.d);
    fk.Reset();
    const FkResult r = fk.Solve(Eq7Lengths(g, truth));
    ASSERT_EQ(r.status, FkStatus::kOk) << grasp_deg;
    EXPECT_LT(PoseDistance(r.pose, truth), 1e-8) << grasp_deg;
    EXPECT_NEAR(r.grasp, grasp_deg * kDeg, 1e-7);
    EXPECT_LT(RotationAngleBetween(r.R_DT, R), 1e-6) << grasp_deg;
  }
  // Quantized lengths at 10°: the pole positions stay accurate while the roll about the poles
  // is only known to ~ quantum / (d sin 5°).
  const GripPose truth = GripPose::FromFrame(p0, R, 10 * kDeg, g.d);
  fk.Reset();
  const FkResult r = fk.Solve(Quantize(Eq7Lengths(g, truth)));
  ASSERT_EQ(r.status, FkStatus::kOk);
  EXPECT_LT((r.pose.p0 - truth.p0).norm(), 0.2e-3);
}

TEST(ForwardKinematics, RefusesPolesParallelWithinTheLimit) {
  const SpidarGeometry g;
  ForwardKinematics fk(g);
  const Eigen::Matrix3d R = AxisRotation(1, 0.2);
  for (double grasp : {0.0, 0.2 * kDeg, 179.8 * kDeg, kPi}) {
    const GripPose truth = GripPose::FromFrame(Eigen::Vector3d(0.02, 0, 0), R, grasp, g.d);
    for (int pass = 0; pass < 2; ++pass) {
      fk.Reset();
      if (pass == 1) ASSERT_EQ(fk.Solve(Eq7Lengths(g, GripPose::Rest(g.d))).status, FkStatus::kOk);
      const FkResult r = fk.Solve(Eq7Lengths(g, truth));
      EXPECT_EQ(r.status, FkStatus::kSingular) << grasp << " pass " << pass;
      ExpectAllNaN(r);
    }
  }
}

TEST(ForwardKinematics, RefusesGripCentreOutsideTheFrame) {
  const SpidarGeometry g;
  ForwardKinematics fk(g);
  const GripPose outside = GripPose::FromFrame(Eigen::Vector3d(0.0, 0.0, 0.3),
                                               Eigen::Matrix3d::Identity(), kPi / 2, g.d);
  const FkResult r = fk.Solve(Eq7Lengths(g, outside));
  EXPECT_NE(r.status, FkStatus::kOk);
  ExpectAllNaN(r);
}

TEST(FkStatusName, GivesOneWordPerStatus) {
  EXPECT_STREQ(FkStatusName(FkStatus::kOk), "ok");
  EXPECT_STREQ(FkStatusName(FkStatus::kInvalidInput), "invalid_input");
  EXPECT_STREQ(FkStatusName(FkStatus::kUnreachable), "unreachable");
  EXPECT_STREQ(FkStatusName(FkStatus::kNotConverged), "not_converged");
  EXPECT_STREQ(FkStatusName(FkStatus::kSingular), "singular");
}

TEST(ForwardKinematics, SolveDoesNotAllocate) {
  const SpidarGeometry g;
  ForwardKinematics fk(g);
  ASSERT_TRUE(test_support::MallocCounterActive()) << "the counting malloc is not in use";

  std::vector<Vector8d> inputs;
  for (int tick = 0; tick < 50; ++tick) inputs.push_back(Quantize(Eq7Lengths(g, FastTrajectory(g, tick))));
  inputs.push_back(Vector8d::Constant(0.05));
  Vector8d nan_input = inputs[0];
  nan_input(2) = std::nan("");
  inputs.push_back(nan_input);
  long ok = 0;
  long allocations = 0;
  {
    test_support::MallocCounter counter;
    for (const Vector8d& l : inputs) ok += fk.Solve(l).status == FkStatus::kOk;
    fk.Reset();
    ok += fk.Solve(inputs[10]).status == FkStatus::kOk;
    allocations = counter.count();
  }
  EXPECT_EQ(allocations, 0);
  EXPECT_EQ(ok, 51);
}

}  // namespace
}  // namespace spidarcad::haptics
