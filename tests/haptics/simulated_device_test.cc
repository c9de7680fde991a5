// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#include "spidarcad/haptics/simulated_device.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <cmath>
#include <stdexcept>

namespace spidarcad::haptics {
namespace {

GripPose TestPose() {
  return GripPose::FromFrame(
      Eigen::Vector3d(0.05, -0.03, 0.08),
      Eigen::AngleAxisd(0.3, Eigen::Vector3d(1, 2, 3).normalized()).toRotationMatrix(), 1.4, 0.04);
}

// Wrench from tensions written out from the paper's Eq. 10-14, independently of WrenchMatrix.
Vector7d WrenchByHand(const SpidarGeometry& g, const GripPose& pose, const Vector8d& tau) {
  Vector7d q = Vector7d::Zero();
  const Eigen::Vector3d n = pose.p1.cross(pose.p2).normalized();
  for (int i = 0; i < kNumStrings; ++i) {
    const Eigen::Vector3d P = pose.p0 + StringEnd(i) * (i < 4 ? pose.p1 : pose.p2);
    const Eigen::Vector3d c = (g.Corner(i) - P).normalized();
    const Eigen::Vector3d r = P - pose.p0;
    q.head<3>() += tau[i] * c;
    q.segment<3>(3) += tau[i] * r.cross(c);
    q[6] += tau[i] * (i < 4 ? 1.0 : -1.0) * n.dot(r.cross(c));
  }
  return q;
}

Vector8d StringLengthsByHand(const SpidarGeometry& g, const GripPose& pose) {
  Vector8d l;
  for (int i = 0; i < kNumStrings; ++i) {
    l[i] = (g.Corner(i) - (pose.p0 + StringEnd(i) * (i < 4 ? pose.p1 : pose.p2))).norm();
  }
  return l;
}

TEST(SimulatedSpidarG, SameSeedGivesIdenticalReadings) {
  SimulatedDeviceConfig config;
  config.seed = 42;
  SimulatedSpidarG a(config), b(config);
  config.seed = 43;
  SimulatedSpidarG c(config);
  bool any_difference = false;
  for (int k = 0; k < 50; ++k) {
    GripPose pose = TestPose();
    pose.p0.x() += 0.002 * k;
    for (SimulatedSpidarG* dev : {&a, &b, &c}) {
      dev->SetTruePose(pose);
      dev->Step(0.001);
    }
    EncoderReading ra, rb, rc;
    a.Read(&ra);
    b.Read(&rb);
    c.Read(&rc);
    EXPECT_EQ(ra.counts, rb.counts);
    EXPECT_EQ(ra.sequence, rb.sequence);
    any_difference = any_difference || ra.counts != rc.counts;
  }
  EXPECT_TRUE(any_difference) << "a different seed should give different noise and parameters";
  EXPECT_NE(a.true_encoder().strings[0].gain, c.true_encoder().strings[0].gain);
}

TEST(SimulatedSpidarG, IdealDeviceCountsAreRoundedLengthChangesSinceHoming) {
  const SimulatedDeviceConfig config = SimulatedDeviceConfig::Ideal();
  SimulatedSpidarG dev(config);
  const double m = config.encoder.MetresPerCount();
  const Vector8d home = StringLengthsByHand(config.geometry, config.home_pose);
  const GripPose pose = TestPose();
  dev.SetTruePose(pose);
  dev.Step(0.001);
  EncoderReading reading;
  ASSERT_EQ(dev.Read(&reading), DeviceStatus::kOk);
  const Vector8d l = StringLengthsByHand(config.geometry, pose);
  for (int i = 0; i < kNumStrings; ++i) {
    EXPECT_EQ(reading.counts[i], std::lround((l[i] - home[i]) / m)) << "string " << i + 1;
    // Quantisation bound of the nominal model.
    EXPECT_LE(std::abs(home[i] + reading.counts[i] * m - l[i]), 0.5 * m + 1e-12);
  }
}

TEST(SimulatedSpidarG, CountsAreZeroAtTheTrueHomingPose) {
  SimulatedDeviceConfig config;
  config.length_noise_sd = 0.0;
  SimulatedSpidarG dev(config);
  EncoderReading reading;
  dev.Read(&reading);
  for (int i = 0; i < kNumStrings; ++i) EXPECT_EQ(reading.counts[i], 0) << "string " << i + 1;
  // The jig error moved the true homing pose away from the nominal one.
  EXPECT_GT((dev.true_home_pose().p0 - config.home_pose.p0).norm(), 0.0);
}

TEST(SimulatedSpidarG, HiddenTruthReproducesTrueLengthsToQuantisation) {
  SimulatedDeviceConfig config;  // every imperfection on, with noise
  config.seed = 5;
  SimulatedSpidarG dev(config);
  const double m = config.encoder.MetresPerCount();
  Vector8d tau;
  tau << 0.5, 1, 2, 3, 4, 5, 6, 7;
  dev.WriteTensions(tau);
  dev.SetTruePose(TestPose());
  dev.Step(0.05);
  EncoderReading reading;
  dev.Read(&reading);
  const Vector8d truth = StringLengthsByHand(config.geometry, TestPose());
  const Vector8d from_truth = dev.true_encoder().Lengths(reading.counts, dev.actual_tensions());
  const Vector8d nominal =
      EncoderCalibration::Nominal(config.encoder,
                                  StringLengthsByHand(config.geometry, config.home_pose))
          .Lengths(reading.counts);
  for (int i = 0; i < kNumStrings; ++i) {
    // Half a count (slope ~1.1) plus 5 sigma of noise.
    EXPECT_NEAR(from_truth[i], truth[i], 0.6 * m + 5 * config.length_noise_sd);
  }
  // The nominal model is off by millimetres (gain error of ~6 % over ~10 cm of travel).
  EXPECT_GT((nominal - truth).cwiseAbs().maxCoeff(), 1e-3);
}

TEST(SimulatedSpidarG, GainErrorsFollowTheConfiguredStatistics) {
  // 60 devices x 8 strings: mean and sd of (gain − 1) match the paper-like defaults.
  double sum = 0, sum_sq = 0;
  int n = 0;
  for (std::uint64_t seed = 1; seed <= 60; ++seed) {
    SimulatedDeviceConfig config;
    config.seed = seed;
    const SimulatedSpidarG dev(config);
    for (const auto& p : dev.true_encoder().strings) {
      sum += p.gain - 1;
      sum_sq += (p.gain - 1) * (p.gain - 1);
      ++n;
    }
  }
  const double mean = sum / n;
  const double sd = std::sqrt(sum_sq / n - mean * mean);
  EXPECT_NEAR(mean, 0.0624, 4 * 0.0154 / std::sqrt(n));
  EXPECT_NEAR(sd, 0.0154, 0.2 * 0.0154);
}

TEST(SimulatedSpidarG, WrenchIsATauAtTheTruePoseWithinMotorLimits) {
  SimulatedSpidarG dev;
  const GripPose pose = TestPose();
  Vector8d tau;
  tau << 0.5, 1.0, 1.5, 2.0, 2.5, 3.0, 3.5, 7.5;
  dev.SetTruePose(pose);
  ASSERT_EQ(dev.WriteTensions(tau), DeviceStatus::kOk);
  dev.Step(1.0);  // 500 time constants: settled
  EXPECT_LT((dev.actual_tensions() - tau).norm(), 1e-12);
  const Vector7d expected = WrenchByHand(dev.info().geometry, pose, tau);
  EXPECT_LT((dev.TrueWrench() - expected).norm(), 1e-10 * expected.norm());
}

TEST(SimulatedSpidarG, TensionsSaturateAtMotorLimitsAndZero) {
  SimulatedDeviceConfig config;
  config.tension_time_constant = 0.0;
  SimulatedSpidarG dev(config);
  Vector8d tau;
  tau << 20.0, -3.0, 1.0, 9.0, 0.0, 4.0, 8.0, 100.0;
  Vector8d clamped;
  clamped << 8.0, 0.0, 1.0, 8.0, 0.0, 4.0, 8.0, 8.0;
  dev.SetTruePose(TestPose());
  dev.WriteTensions(tau);
  dev.Step(0.001);
  EXPECT_EQ(dev.actual_tensions(), clamped);
  const Vector7d expected = WrenchByHand(config.geometry, TestPose(), clamped);
  EXPECT_LT((dev.TrueWrench() - expected).norm(), 1e-10 * expected.norm());
}

TEST(SimulatedSpidarG, MotorLagIsFirstOrder) {
  SimulatedDeviceConfig config;
  config.tension_time_constant = 0.01;
  config.homing_tension = 0.5;
  SimulatedSpidarG dev(config);
  dev.WriteTensions(Vector8d::Constant(4.5));
  dev.Step(0.01);  // one time constant
  const double expected = 0.5 + 4.0 * (1 - std::exp(-1.0));
  EXPECT_NEAR(dev.actual_tensions()[3], expected, 1e-12);
  // Two half steps equal one full step (exact discretisation).
  SimulatedSpidarG dev2(config);
  dev2.WriteTensions(Vector8d::Constant(4.5));
  dev2.Step(0.005);
  dev2.Step(0.005);
  EXPECT_NEAR(dev2.actual_tensions()[3], expected, 1e-12);
}

TEST(SimulatedSpidarG, LowCommandedTensionFlagsSlack) {
  SimulatedSpidarG dev;
  Vector8d tau = Vector8d::Constant(1.0);
  tau[2] = 0.01;
  tau[6] = std::nan("");  // treated as zero
  dev.WriteTensions(tau);
  dev.Step(0.001);
  EncoderReading reading;
  dev.Read(&reading);
  EXPECT_EQ(reading.slack_mask, (1u << 2) | (1u << 6));
  EXPECT_EQ(dev.commanded_tensions()[6], 0.0);
}

TEST(SimulatedSpidarG, StretchShortensThePaidOutStringUnderTension) {
  SimulatedDeviceConfig config = SimulatedDeviceConfig::Ideal();
  config.stretch = 1e-3;  // strain per newton
  config.homing_tension = 0.0;
  config.tension_time_constant = 0.0;
  SimulatedSpidarG dev(config);
  const double m = config.encoder.MetresPerCount();
  dev.SetTruePose(TestPose());
  dev.WriteTensions(Vector8d::Zero());
  dev.Step(0.001);
  EncoderReading slack_reading, taut_reading;
  dev.Read(&slack_reading);
  dev.WriteTensions(Vector8d::Constant(5.0));
  dev.Step(0.001);
  dev.Read(&taut_reading);
  const Vector8d l = StringLengthsByHand(config.geometry, TestPose());
  for (int i = 0; i < kNumStrings; ++i) {
    // Paid-out length l / (1 + 5e-3): fewer counts by l (1 − 1/1.005) / m.
    const double expected = l[i] * (1 - 1 / 1.005) / m;
    EXPECT_NEAR(slack_reading.counts[i] - taut_reading.counts[i], expected, 1.0);
  }
}

TEST(SimulatedSpidarG, ErrorStateStopsMotorsAndFreezesReadings) {
  SimulatedDeviceConfig config;
  config.tension_time_constant = 0.0;
  SimulatedSpidarG dev(config);
  dev.WriteTensions(Vector8d::Constant(3.0));
  dev.Step(0.001);
  EncoderReading before;
  dev.Read(&before);
  dev.SetStatus(DeviceStatus::kFault);
  EXPECT_EQ(dev.WriteTensions(Vector8d::Constant(6.0)), DeviceStatus::kFault);
  EXPECT_EQ(dev.commanded_tensions()[0], 3.0);
  GripPose moved = TestPose();
  dev.SetTruePose(moved);
  dev.Step(0.001);
  EncoderReading after;
  EXPECT_EQ(dev.Read(&after), DeviceStatus::kFault);
  EXPECT_EQ(after.status, DeviceStatus::kFault);
  EXPECT_EQ(after.sequence, before.sequence);
  EXPECT_EQ(after.counts, before.counts);
  EXPECT_EQ(dev.actual_tensions(), Vector8d::Zero());
  EXPECT_STREQ(DeviceStatusName(DeviceStatus::kFault), "fault");
  dev.SetStatus(DeviceStatus::kOk);
  dev.Step(0.001);
  dev.Read(&after);
  EXPECT_EQ(after.sequence, before.sequence + 1);
}

TEST(SimulatedSpidarG, RejectsBadConfigNamingTheField) {
  SimulatedDeviceConfig config;
  config.tension_max = -1;
  EXPECT_THAT([&] { SimulatedSpidarG dev(config); },
              testing::ThrowsMessage<std::invalid_argument>(testing::HasSubstr("tension_max")));
  config = SimulatedDeviceConfig{};
  config.home_pose.p1 *= 2;
  EXPECT_THAT([&] { SimulatedSpidarG dev(config); },
              testing::ThrowsMessage<std::invalid_argument>(testing::HasSubstr("home_pose")));
}

TEST(SimulatedSpidarG, IsUsableThroughTheDeviceInterface) {
  SimulatedSpidarG sim;
  Device& device = sim;
  EXPECT_EQ(device.status(), DeviceStatus::kOk);
  EXPECT_NEAR(device.info().encoder.MetresPerCount(), 0.0251327e-3, 1e-10);
  EXPECT_EQ(device.info().tension_max, 8.0);
  EncoderReading r1, r2;
  device.Read(&r1);
  sim.Step(0.001);
  device.Read(&r2);
  EXPECT_EQ(r2.sequence, r1.sequence + 1);
  EXPECT_NEAR(r2.time - r1.time, 0.001, 1e-15);
}

}  // namespace
}  // namespace spidarcad::haptics
