// Tests of the SPIDAR-G geometry conventions (geometry.h) against the paper's Eq. 3 and the
// string attachment of docs/architecture.md (Reading the paper), written out independently here.
// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#include "spidarcad/haptics/geometry.h"

#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <cmath>
#include <numbers>
#include <random>
#include <stdexcept>
#include <string>

namespace spidarcad::haptics {
namespace {

constexpr double kPi = std::numbers::pi;

Eigen::Matrix3d RandomRotation(std::mt19937& rng) {
  std::normal_distribution<double> normal;
  Eigen::Quaterniond q(normal(rng), normal(rng), normal(rng), normal(rng));
  return q.normalized().toRotationMatrix();
}

TEST(SpidarGeometry, CornersFollowEq3) {
  SpidarGeometry g;
  g.a = 0.3;
  g.b = 0.2;
  g.c = 0.1;
  // Eq. 3a-h, typed from the paper.
  const double expected[8][3] = {{0.3, 0.2, 0.1},   {-0.3, 0.2, 0.1},  {0.3, -0.2, 0.1},
                                 {-0.3, -0.2, 0.1}, {0.3, 0.2, -0.1},  {-0.3, 0.2, -0.1},
                                 {0.3, -0.2, -0.1}, {-0.3, -0.2, -0.1}};
  for (int i = 0; i < kNumStrings; ++i) {
    const Eigen::Vector3d q = g.Corner(i);
    for (int k = 0; k < 3; ++k) EXPECT_EQ(q(k), expected[i][k]) << "corner " << i + 1;
  }
}

TEST(StringAttachment, FollowsErrataTable) {
  // Attachment (docs/architecture.md): strings 1,2 -> P+1; 3,4 -> P-1; 5,7 -> P+2; 6,8 -> P-2
  // (1-based).
  const int pole[8] = {0, 0, 0, 0, 1, 1, 1, 1};
  const int end[8] = {+1, +1, -1, -1, +1, -1, +1, -1};
  const int delta[8] = {1, 1, 1, 1, -1, -1, -1, -1};
  GripPose pose;
  pose.p0 = Eigen::Vector3d(0.01, -0.02, 0.03);
  pose.p1 = Eigen::Vector3d(0.001, 0.039, 0.002);
  pose.p2 = Eigen::Vector3d(0.04, 0.0, -0.001);
  const Eigen::Vector3d P[8] = {pose.p0 + pose.p1, pose.p0 + pose.p1, pose.p0 - pose.p1,
                                pose.p0 - pose.p1, pose.p0 + pose.p2, pose.p0 - pose.p2,
                                pose.p0 + pose.p2, pose.p0 - pose.p2};
  for (int i = 0; i < kNumStrings; ++i) {
    EXPECT_EQ(StringPole(i), pole[i]) << "string " << i + 1;
    EXPECT_EQ(StringEnd(i), end[i]) << "string " << i + 1;
    EXPECT_EQ(StringDelta(i), delta[i]) << "string " << i + 1;
    EXPECT_TRUE(pose.Attachment(i).isApprox(P[i], 1e-15)) << "string " << i + 1;
    EXPECT_TRUE(pose.LeverArm(i).isApprox(P[i] - pose.p0, 1e-15)) << "string " << i + 1;
  }
}

TEST(GripPose, RestIsIdentityRotationWithRightAngleGrasp) {
  const GripPose rest = GripPose::Rest(0.04);
  EXPECT_EQ(rest.p1, Eigen::Vector3d(0, 0.04, 0));
  EXPECT_EQ(rest.p2, Eigen::Vector3d(0.04, 0, 0));
  EXPECT_TRUE(rest.Rotation().isApprox(Eigen::Matrix3d::Identity(), 1e-15));
  EXPECT_NEAR(rest.Grasp(), kPi / 2, 1e-15);
  // n = p1 × p2 / |p1 × p2| = ŷ × x̂ = −ẑ.
  EXPECT_TRUE(rest.Normal().isApprox(Eigen::Vector3d(0, 0, -1), 1e-15));
  const GripPose from_frame =
      GripPose::FromFrame(Eigen::Vector3d::Zero(), Eigen::Matrix3d::Identity(), kPi / 2, 0.04);
  EXPECT_LT((from_frame.p1 - rest.p1).norm(), 1e-17);
  EXPECT_LT((from_frame.p2 - rest.p2).norm(), 1e-17);
}

TEST(GripPose, FromFrameRoundTripsThroughRotationAndGrasp) {
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> grasp_dist(0.05, kPi - 0.05);
  for (int trial = 0; trial < 500; ++trial) {
    const Eigen::Matrix3d R = RandomRotation(rng);
    const double grasp = grasp_dist(rng);
    const Eigen::Vector3d p0(0.01 * trial / 500.0, -0.02, 0.05);
    const GripPose pose = GripPose::FromFrame(p0, R, grasp, 0.04);
    EXPECT_NEAR(pose.p1.norm(), 0.04, 1e-15);
    EXPECT_NEAR(pose.p2.norm(), 0.04, 1e-15);
    EXPECT_NEAR(pose.Grasp(), grasp, 1e-13);
    // Independent: the angle between p1 and p2 from the dot product.
    EXPECT_NEAR(std::acos(pose.p1.dot(pose.p2) / (0.04 * 0.04)), grasp, 1e-7);
    EXPECT_LT(RotationAngleBetween(pose.Rotation(), R), 1e-12);
    EXPECT_TRUE(pose.Rotation().isApprox(R, 1e-12));
    // The grip plane normal is −z of T (p1 × p2 points along −z_T for 0 < θ < π).
    EXPECT_TRUE(pose.Normal().isApprox(-R.col(2), 1e-12));
    EXPECT_EQ(pose.p0, p0);
  }
}

// Closed form: p̂1 = (cos θ/2 − sin θ/2, cos θ/2 + sin θ/2, 0)/√2 and p̂2 = (cos θ/2 + sin θ/2,
// cos θ/2 − sin θ/2, 0)/√2, the poles ±θ/2 about the bisector (1, 1, 0)/√2 in the x-y plane.
TEST(GripPoleDirections, MatchesTheClosedFormAndItsDerivative) {
  for (int i = 0; i <= 20; ++i) {
    const double theta = 0.1 + (kPi - 0.2) * i / 20;
    const double c = std::cos(theta / 2), s = std::sin(theta / 2), r = 1 / std::sqrt(2.0);
    const PoleDirections poles = GripPoleDirections(theta);
    EXPECT_LT((poles.u_T[0] - r * Eigen::Vector3d(c - s, c + s, 0)).norm(), 1e-15) << theta;
    EXPECT_LT((poles.u_T[1] - r * Eigen::Vector3d(c + s, c - s, 0)).norm(), 1e-15) << theta;
    EXPECT_NEAR(poles.u_T[0].norm(), 1.0, 1e-15);
    EXPECT_NEAR(std::acos(poles.u_T[0].dot(poles.u_T[1])), theta, 1e-12);
    // Derivatives against central differences of the closed form.
    const double h = 1e-6;
    auto u = [&](double t, int k) {
      const double ct = std::cos(t / 2), st = std::sin(t / 2);
      return k == 0 ? Eigen::Vector3d(r * (ct - st), r * (ct + st), 0)
                    : Eigen::Vector3d(r * (ct + st), r * (ct - st), 0);
    };
    for (int k = 0; k < 2; ++k) {
      const Eigen::Vector3d fd = (u(theta + h, k) - u(theta - h, k)) / (2 * h);
      EXPECT_LT((poles.du_T[k] - fd).norm(), 1e-9) << theta << " pole " << k;
    }
  }
  // Rest: p̂1 = y, p̂2 = x.
  const PoleDirections rest = GripPoleDirections(kPi / 2);
  EXPECT_LT((rest.u_T[0] - Eigen::Vector3d::UnitY()).norm(), 1e-15);
  EXPECT_LT((rest.u_T[1] - Eigen::Vector3d::UnitX()).norm(), 1e-15);
}

TEST(GripPoleDirections, GiveThePoleVectorsOfFromFrame) {
  const Eigen::Matrix3d R = Eigen::AngleAxisd(0.8, Eigen::Vector3d(1, 2, -1).normalized()).matrix();
  const double d = 0.04, theta = 1.2;
  const GripPose pose = GripPose::FromFrame(Eigen::Vector3d(0.01, 0, 0), R, theta, d);
  const PoleDirections poles = GripPoleDirections(theta);
  EXPECT_LT((pose.p1 - d * R * poles.u_T[0]).norm(), 1e-16);
  EXPECT_LT((pose.p2 - d * R * poles.u_T[1]).norm(), 1e-16);
  EXPECT_NEAR(pose.Grasp(), theta, 1e-14);
}

TEST(GripPose, PackedRoundTrips) {
  GripPose pose;
  pose.p0 = Eigen::Vector3d(1, 2, 3);
  pose.p1 = Eigen::Vector3d(4, 5, 6);
  pose.p2 = Eigen::Vector3d(7, 8, 9);
  const Vector9d v = pose.Packed();
  for (int k = 0; k < 9; ++k) EXPECT_EQ(v(k), k + 1);
  const GripPose back = GripPose::Unpacked(v);
  EXPECT_EQ(back.p0, pose.p0);
  EXPECT_EQ(back.p1, pose.p1);
  EXPECT_EQ(back.p2, pose.p2);
}

TEST(RotationAngleBetween, ReturnsAngleOfRelativeRotation) {
  std::mt19937 rng(3);
  for (double angle : {0.0, 1e-6, 0.3, 1.5, 3.0, kPi}) {
    const Eigen::Matrix3d Ra = RandomRotation(rng);
    const Eigen::Vector3d axis = Eigen::Vector3d(1, 2, -0.5).normalized();
    const Eigen::Matrix3d Rb = Ra * Eigen::AngleAxisd(angle, axis).toRotationMatrix();
    EXPECT_NEAR(RotationAngleBetween(Ra, Rb), angle, 1e-12) << angle;
  }
}

// Expects Validate to throw std::invalid_argument mentioning `fragment`.
void ExpectInvalid(const SpidarGeometry& g, const std::string& fragment) {
  try {
    g.Validate();
    ADD_FAILURE() << "no exception, expected one mentioning " << fragment;
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find(fragment), std::string::npos) << e.what();
  }
}

TEST(SpidarGeometry, ValidateAcceptsPaperDeviceAndRejectsBadSizes) {
  SpidarGeometry g;
  EXPECT_NO_THROW(g.Validate());
  SpidarGeometry bad = g;
  bad.a = -0.1;
  ExpectInvalid(bad, "'a'");
  bad = g;
  bad.b = 0;
  ExpectInvalid(bad, "'b'");
  bad = g;
  bad.c = std::nan("");
  ExpectInvalid(bad, "'c'");
  bad = g;
  bad.d = INFINITY;
  ExpectInvalid(bad, "'d'");
  bad = g;
  bad.d = 0.3;  // longer than the half-sides: the grip does not fit
  ExpectInvalid(bad, "does not fit");
  bad = g;
  bad.c = 0.04;  // d == c is not allowed either
  ExpectInvalid(bad, "does not fit");
}

}  // namespace
}  // namespace spidarcad::haptics
