// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#include "spidarcad/haptics/rotation.h"

#include <gtest/gtest.h>

#include <cmath>
#include <random>

namespace spidarcad::haptics {
namespace {

// Rodrigues' formula for the rotation by `angle` about the unit `axis`, written out.
Eigen::Matrix3d Rodrigues(const Eigen::Vector3d& axis, double angle) {
  Eigen::Matrix3d k;
  k << 0, -axis.z(), axis.y(), axis.z(), 0, -axis.x(), -axis.y(), axis.x(), 0;
  return Eigen::Matrix3d::Identity() + std::sin(angle) * k + (1 - std::cos(angle)) * k * k;
}

Eigen::Vector3d RandomUnit(std::mt19937* rng) {
  std::normal_distribution<double> normal;
  Eigen::Vector3d v(normal(*rng), normal(*rng), normal(*rng));
  return v.normalized();
}

TEST(IntegrateRotation, MatrixStepIsRodriguesTimesTheRotation) {
  std::mt19937 rng(4);
  for (int trial = 0; trial < 50; ++trial) {
    const Eigen::Matrix3d R0 = Rodrigues(RandomUnit(&rng), 2.0 * trial / 50);
    const Eigen::Vector3d axis = RandomUnit(&rng);
    const double rate = 0.3 + 0.1 * trial, h = 0.01 * (1 + trial % 7);  // rad/s, s
    const Eigen::Matrix3d R = IntegrateRotation(R0, rate * axis, h);
    EXPECT_LT((R - Rodrigues(axis, rate * h) * R0).norm(), 1e-14) << trial;
  }
}

TEST(IntegrateRotation, QuaternionStepIsTheHalfAngleQuaternionTimesTheRotation) {
  std::mt19937 rng(8);
  for (int trial = 0; trial < 50; ++trial) {
    const Eigen::Vector3d a0 = RandomUnit(&rng);
    const double t0 = 0.05 * trial;
    const Eigen::Quaterniond q0(std::cos(t0 / 2), std::sin(t0 / 2) * a0.x(),
                                std::sin(t0 / 2) * a0.y(), std::sin(t0 / 2) * a0.z());
    const Eigen::Vector3d axis = RandomUnit(&rng);
    const double rate = 5.0 - 0.1 * trial, h = 1e-3 * (1 + trial % 5);
    const double t = rate * h;
    const Eigen::Quaterniond dq(std::cos(t / 2), std::sin(t / 2) * axis.x(),
                                std::sin(t / 2) * axis.y(), std::sin(t / 2) * axis.z());
    const Eigen::Quaterniond q = IntegrateRotation(q0, rate * axis, h);
    EXPECT_LT((q.coeffs() - (dq * q0).coeffs()).norm(), 1e-14) << trial;
    EXPECT_NEAR(q.norm(), 1.0, 1e-15);
    // The matrix form agrees.
    EXPECT_LT(
        (q.toRotationMatrix() - IntegrateRotation(q0.toRotationMatrix(), rate * axis, h)).norm(),
        1e-14);
  }
}

// A constant angular velocity about a fixed axis, integrated over many steps, is the rotation by
// the whole angle (rotations about one axis commute, so the steps compose exactly).
TEST(IntegrateRotation, ConstantRateAboutAFixedAxisSumsToTheTotalAngle) {
  const Eigen::Vector3d axis = Eigen::Vector3d(1, -2, 2) / 3.0;
  const double rate = 2.5, h = 1e-3;
  const int steps = 1000;
  Eigen::Quaterniond q = Eigen::Quaterniond::Identity();
  Eigen::Matrix3d R = Eigen::Matrix3d::Identity();
  for (int i = 0; i < steps; ++i) {
    q = IntegrateRotation(q, rate * axis, h);
    R = IntegrateRotation(R, rate * axis, h);
  }
  const Eigen::Matrix3d expected = Rodrigues(axis, rate * h * steps);
  EXPECT_LT((q.toRotationMatrix() - expected).norm(), 1e-12);
  EXPECT_LT((R - expected).norm(), 1e-12);
}

TEST(IntegrateRotation, NegativeStepRotatesTheOtherWay) {
  const Eigen::Vector3d axis = Eigen::Vector3d(0, 0.6, 0.8);
  const Eigen::Matrix3d R0 = Rodrigues(Eigen::Vector3d::UnitX(), 0.4);
  EXPECT_LT((IntegrateRotation(R0, axis, -0.3) - Rodrigues(axis, -0.3) * R0).norm(), 1e-15);
  const Eigen::Quaterniond q = IntegrateRotation(Eigen::Quaterniond(R0), axis, -0.3);
  EXPECT_LT((q.toRotationMatrix() - Rodrigues(axis, -0.3) * R0).norm(), 1e-15);
}

TEST(IntegrateRotation, ZeroOrNonFiniteRateOnlyNormalises) {
  const Eigen::Matrix3d R = Rodrigues(Eigen::Vector3d::UnitY(), 0.7);
  EXPECT_EQ(IntegrateRotation(R, Eigen::Vector3d::Zero(), 1e-3), R);
  EXPECT_EQ(IntegrateRotation(R, Eigen::Vector3d(1, 0, 0), 0.0), R);
  EXPECT_EQ(IntegrateRotation(R, Eigen::Vector3d(NAN, 0, 0), 1e-3), R);
  const Eigen::Quaterniond q(2.0, 0.0, 0.0, 0.0);  // not unit
  const Eigen::Quaterniond out = IntegrateRotation(q, Eigen::Vector3d::Zero(), 1e-3);
  EXPECT_EQ(out.coeffs(), Eigen::Quaterniond::Identity().coeffs());
}

TEST(RotationVector, IsTheAngleTimesTheAxisAndInvertsTheUpdate) {
  std::mt19937 rng(2);
  for (int trial = 0; trial < 40; ++trial) {
    const Eigen::Vector3d axis = RandomUnit(&rng);
    const double angle = 3.1 * (trial + 0.5) / 40;  // (0, π)
    const Eigen::Quaterniond q(std::cos(angle / 2), std::sin(angle / 2) * axis.x(),
                               std::sin(angle / 2) * axis.y(), std::sin(angle / 2) * axis.z());
    EXPECT_LT((RotationVector(q) - angle * axis).norm(), 1e-13) << trial;
    // −q is the same rotation.
    EXPECT_LT((RotationVector(Eigen::Quaterniond(-q.coeffs())) - angle * axis).norm(), 1e-13);
    const Eigen::Quaterniond stepped =
        IntegrateRotation(Eigen::Quaterniond::Identity(), axis * angle / 0.5, 0.5);
    EXPECT_LT((RotationVector(stepped) - angle * axis).norm(), 1e-13) << trial;
  }
  // Tiny rotations: first order.
  const Eigen::Quaterniond tiny(1.0, 1e-14, -2e-14, 0.0);
  EXPECT_LT((RotationVector(tiny) - Eigen::Vector3d(2e-14, -4e-14, 0)).norm(), 1e-27);
  EXPECT_EQ(RotationVector(Eigen::Quaterniond::Identity()), Eigen::Vector3d::Zero());
}

}  // namespace
}  // namespace spidarcad::haptics
