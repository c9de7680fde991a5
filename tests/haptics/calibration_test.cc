// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#include "spidarcad/haptics/calibration.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <cmath>

#include "spidarcad/haptics/kinematics.h"
#include "spidarcad/haptics/simulated_device.h"

namespace spidarcad::haptics {
namespace {

constexpr double kDeg = M_PI / 180.0;

// Calibration poses: a 40 cm cube, rotations to 30°, grasp 90 ± 17°.
std::vector<GripPose> CalibrationPoses(const SpidarGeometry& g, int count, std::uint64_t seed) {
  return RandomGripPoses(g, count, 0.2, 30 * kDeg, 0.3, seed);
}

EncoderCalibration NominalOf(const SimulatedSpidarG& dev) {
  return EncoderCalibration::Nominal(dev.info().encoder,
                                     InverseKinematics(dev.info().geometry, dev.info().home_pose));
}

// A device with linear encoders (no winding nonlinearity, no stretch), for the line fit.
SimulatedDeviceConfig LinearConfig() {
  SimulatedDeviceConfig config;
  config.quadratic_sd = 0.0;
  config.stretch = 0.0;
  config.stretch_sd = 0.0;
  config.length_noise_sd = 0.0;
  return config;
}

TEST(RandomGripPoses, StayInsideTheCubeAndFrame) {
  const SpidarGeometry g;
  const auto poses = RandomGripPoses(g, 200, 0.2, 30 * kDeg, 0.3, 3);
  ASSERT_EQ(poses.size(), 200u);
  for (const GripPose& pose : poses) {
    EXPECT_LE(pose.p0.cwiseAbs().maxCoeff(), 0.2);
    EXPECT_NEAR(pose.p1.norm(), g.d, 1e-12);
    EXPECT_LE(RotationAngleBetween(Eigen::Matrix3d::Identity(), pose.Rotation()), 30 * kDeg + 1e-9);
    for (int i = 0; i < kNumStrings; ++i) {
      EXPECT_LT(pose.Attachment(i).cwiseAbs().maxCoeff(), 0.24 - 0.01 + 1e-12);
    }
  }
  EXPECT_EQ(RandomGripPoses(g, 5, 0.2, 0.1, 0.1, 9)[4].p0,
            RandomGripPoses(g, 5, 0.2, 0.1, 0.1, 9)[4].p0);
}

TEST(FitLinesPerString, RecoversGainAndOffsetOfLinearEncoders) {
  SimulatedSpidarG dev(LinearConfig());
  const auto jig = GatherKnownSamples(&dev, CalibrationPoses(dev.info().geometry, 40, 1), 0.5);
  const CalibrationResult r = FitLinesPerString(dev.info().geometry, NominalOf(dev), jig);
  ASSERT_EQ(r.status, CalibrationStatus::kOk) << r.message;
  for (int i = 0; i < kNumStrings; ++i) {
    const StringEncoderParams& truth = dev.true_encoder().strings[i];
    const StringEncoderParams& est = r.calibration.strings[i];
    // Quantisation (25 µm) over ~30 cm of travel: gain to 1e-4, offset to 20 µm.
    EXPECT_NEAR(est.gain, truth.gain, 1e-4) << "string " << i + 1;
    EXPECT_NEAR(est.offset, truth.offset, 2e-5) << "string " << i + 1;
  }
  EXPECT_LT(r.rms_residual, 2e-5);
}

TEST(FitLinesPerString, QuadraticFitRecoversWindingNonlinearity) {
  SimulatedDeviceConfig config = LinearConfig();
  config.quadratic_sd = 0.1;
  SimulatedSpidarG dev(config);
  const auto jig = GatherKnownSamples(&dev, CalibrationPoses(dev.info().geometry, 60, 2), 0.5);
  LineFitSettings settings;
  settings.fit_quadratic = true;
  const CalibrationResult r = FitLinesPerString(dev.info().geometry, NominalOf(dev), jig, settings);
  ASSERT_EQ(r.status, CalibrationStatus::kOk) << r.message;
  for (int i = 0; i < kNumStrings; ++i) {
    EXPECT_NEAR(r.calibration.strings[i].quadratic, dev.true_encoder().strings[i].quadratic, 2e-3)
        << "string " << i + 1;
  }
}

TEST(FitLinesPerString, RefusesTooFewOrRepeatedPoses) {
  SimulatedSpidarG dev;
  const SpidarGeometry& g = dev.info().geometry;
  const auto one = GatherKnownSamples(&dev, CalibrationPoses(g, 1, 3), 0.5);
  const CalibrationResult few = FitLinesPerString(g, NominalOf(dev), one);
  EXPECT_EQ(few.status, CalibrationStatus::kTooFewSamples);
  EXPECT_THAT(few.message, testing::HasSubstr("need at least 2"));
  // Ten samples at one pose: no spread in any string.
  const std::vector<GripPose> same(10, CalibrationPoses(g, 1, 4)[0]);
  const CalibrationResult degenerate =
      FitLinesPerString(g, NominalOf(dev), GatherKnownSamples(&dev, same, 0.5));
  EXPECT_EQ(degenerate.status, CalibrationStatus::kDegenerate);
  EXPECT_THAT(degenerate.message, testing::HasSubstr("string 1"));
  // A failed calibration hands back the initial one, not garbage.
  EXPECT_EQ(degenerate.calibration.strings[0].gain, 1.0);
}

struct SelfCalData {
  std::vector<GripPose> poses;
  std::vector<KnownPoseSample> home;
  std::vector<UnknownPoseSample> wave;
};

SelfCalData Gather(SimulatedSpidarG* dev, int count, std::uint64_t seed) {
  SelfCalData data;
  data.poses = CalibrationPoses(dev->info().geometry, count, seed);
  data.home = GatherKnownSamples(dev, {dev->info().home_pose}, 0.5);
  data.wave = GatherUnknownSamples(dev, data.poses, 0.5);
  return data;
}

TEST(SelfCalibrate, RecoversHiddenParametersAndPoses) {
  SimulatedDeviceConfig config;  // paper-like errors, noise, stretch, jig error
  config.seed = 21;
  SimulatedSpidarG dev(config);
  const SelfCalData data = Gather(&dev, 80, 5);
  const CalibrationResult r =
      SelfCalibrate(dev.info().geometry, NominalOf(dev), data.home, data.wave);
  ASSERT_EQ(r.status, CalibrationStatus::kOk) << r.message;
  EXPECT_LT(r.condition, 1e4);
  for (int i = 0; i < kNumStrings; ++i) {
    const StringEncoderParams& truth = dev.true_encoder().strings[i];
    const StringEncoderParams& est = r.calibration.strings[i];
    // The offset inherits the homing jig's error (0.3 mm sd); the stretch at the 0.5 N
    // pretension (~0.02 %) is absorbed in the gain.
    EXPECT_NEAR(est.offset, truth.offset, 1e-3) << "string " << i + 1;
    EXPECT_NEAR(est.gain, truth.gain, 1e-3) << "string " << i + 1;
    EXPECT_NEAR(est.quadratic, truth.quadratic, 1e-2) << "string " << i + 1;
  }
  ASSERT_EQ(r.poses.size(), data.poses.size());
  for (size_t k = 0; k < data.poses.size(); ++k) {
    EXPECT_LT((r.poses[k].p0 - data.poses[k].p0).norm(), 1.5e-3) << "pose " << k;
  }
}

TEST(SelfCalibrate, GainsAreIdentifiableFromUnknownPosesAlone) {
  // Offsets given, no known pose at all: the frame's size fixes the scale.
  SimulatedDeviceConfig config = LinearConfig();
  config.homing_position_sd = 0.0;
  config.homing_rotation_sd = 0.0;
  SimulatedSpidarG dev(config);
  const SelfCalData data = Gather(&dev, 60, 6);
  EncoderCalibration initial = NominalOf(dev);
  for (int i = 0; i < kNumStrings; ++i)
    initial.strings[i].offset = dev.true_encoder().strings[i].offset;
  SelfCalibrationSettings settings;
  settings.estimate_offset = false;
  settings.estimate_quadratic = false;
  const CalibrationResult r = SelfCalibrate(dev.info().geometry, initial, {}, data.wave, settings);
  ASSERT_EQ(r.status, CalibrationStatus::kOk) << r.message;
  for (int i = 0; i < kNumStrings; ++i) {
    EXPECT_NEAR(r.calibration.strings[i].gain, dev.true_encoder().strings[i].gain, 2e-4);
  }
}

TEST(SelfCalibrate, IsRobustToTenTimesTheNoise) {
  SimulatedDeviceConfig config;
  config.length_noise_sd = 1e-4;  // 0.1 mm: four counts
  config.seed = 8;
  SimulatedSpidarG dev(config);
  const SelfCalData data = Gather(&dev, 120, 7);
  const CalibrationResult r =
      SelfCalibrate(dev.info().geometry, NominalOf(dev), data.home, data.wave);
  ASSERT_EQ(r.status, CalibrationStatus::kOk) << r.message;
  for (int i = 0; i < kNumStrings; ++i) {
    EXPECT_NEAR(r.calibration.strings[i].gain, dev.true_encoder().strings[i].gain, 3e-3);
    EXPECT_NEAR(r.calibration.strings[i].offset, dev.true_encoder().strings[i].offset, 1.5e-3);
  }
  // The fit explains the data down to the noise: with 7 of each pose's 8 lengths absorbed by
  // the pose, the expected RMS residual is σ sqrt(redundancy / residuals).
  const double residuals = 8.0 * (120 + 1);
  const double redundancy = residuals - 7.0 * 120 - 24;
  EXPECT_NEAR(r.rms_residual, 1e-4 * std::sqrt(redundancy / residuals), 1e-5);
}

TEST(SelfCalibrate, RefusesTooFewPoses) {
  SimulatedSpidarG dev;
  const SelfCalData data = Gather(&dev, 5, 8);
  const CalibrationResult r =
      SelfCalibrate(dev.info().geometry, NominalOf(dev), data.home, data.wave);
  EXPECT_EQ(r.status, CalibrationStatus::kTooFewSamples);
  EXPECT_THAT(r.message, testing::HasSubstr("unknown poses"));
  EXPECT_EQ(r.calibration.strings[3].gain, 1.0);
  // Offsets without any known pose cannot be anchored.
  const SelfCalData more = Gather(&dev, 60, 9);
  const CalibrationResult no_home =
      SelfCalibrate(dev.info().geometry, NominalOf(dev), {}, more.wave);
  EXPECT_EQ(no_home.status, CalibrationStatus::kTooFewSamples);
  EXPECT_THAT(no_home.message, testing::HasSubstr("known pose"));
}

TEST(SelfCalibrate, ReportsDegenerateWhenThePosesDoNotMove) {
  SimulatedSpidarG dev;
  const SpidarGeometry& g = dev.info().geometry;
  const std::vector<GripPose> same(60, CalibrationPoses(g, 1, 10)[0]);
  const auto home = GatherKnownSamples(&dev, {dev.info().home_pose}, 0.5);
  const auto wave = GatherUnknownSamples(&dev, same, 0.5);
  const CalibrationResult r = SelfCalibrate(g, NominalOf(dev), home, wave);
  EXPECT_EQ(r.status, CalibrationStatus::kDegenerate) << r.message;
  EXPECT_EQ(r.calibration.strings[0].gain, 1.0);
  EXPECT_STREQ(CalibrationStatusName(r.status), "degenerate");
}

TEST(SelfCalibrate, RejectsNonFiniteInput) {
  SimulatedSpidarG dev;
  SelfCalData data = Gather(&dev, 40, 11);
  data.wave[3].tension[2] = std::nan("");
  const CalibrationResult r =
      SelfCalibrate(dev.info().geometry, NominalOf(dev), data.home, data.wave);
  EXPECT_EQ(r.status, CalibrationStatus::kInvalidInput);
  EXPECT_THAT(r.message, testing::HasSubstr("unknown sample 3"));
}

// A self-calibration session as a device runs it: the homing sample (counters zero at the
// jig's pose, which the jig reproduces only to 0.3 mm and 0.17°), then `count` waved poses
// with the tensions varied per string in [0.3, 3] N.
struct Session {
  std::vector<GripPose> poses;
  std::vector<KnownPoseSample> home;
  std::vector<UnknownPoseSample> wave;
};
Session WaveSession(SimulatedSpidarG* dev, int count, std::uint64_t seed) {
  Session s;
  s.poses = CalibrationPoses(dev->info().geometry, count, seed);
  s.home = {HomingSample(dev->info(), dev->config().homing_tension)};
  s.wave = GatherUnknownSamples(dev, s.poses, CalibrationTensions(count, 0.3, 3.0, seed));
  return s;
}

TEST(HomingSample, IsZeroCountsAtTheNominalHomePose) {
  SimulatedSpidarG dev;
  const KnownPoseSample h = HomingSample(dev.info(), 0.5);
  EXPECT_EQ(h.counts, EncoderCounts{});
  EXPECT_EQ(h.pose.p0, dev.info().home_pose.p0);
  EXPECT_EQ(h.tension, Vector8d::Constant(0.5));
  // The simulator zeroed its counters at its true homing pose under the same pretension.
  dev.SetTruePose(dev.true_home_pose());
  dev.WriteTensions(Vector8d::Constant(dev.config().homing_tension));
  dev.Step(0.05);
  EncoderReading reading;
  dev.Read(&reading);
  for (int i = 0; i < kNumStrings; ++i) EXPECT_LE(std::abs(reading.counts[i]), 2) << i;
}

TEST(CalibrationTensions, AreSeededAndSpanTheRangePerString) {
  const auto a = CalibrationTensions(200, 0.3, 3.0, 4);
  ASSERT_EQ(a.size(), 200u);
  EXPECT_EQ(a[17], CalibrationTensions(200, 0.3, 3.0, 4)[17]);
  EXPECT_NE(a[17], CalibrationTensions(200, 0.3, 3.0, 5)[17]);
  for (int i = 0; i < kNumStrings; ++i) {
    double lo = 10, hi = -10;
    for (const Vector8d& t : a) lo = std::min(lo, t[i]), hi = std::max(hi, t[i]);
    EXPECT_GE(lo, 0.3);
    EXPECT_LE(hi, 3.0);
    EXPECT_GT(hi - lo, 2.4) << "string " << i + 1;  // 200 uniform draws span ~99 % of 2.7 N
  }
  EXPECT_NE(a[0][0], a[0][1]);  // independent per string
}

TEST(GatherUnknownSamples, RefusesATensionCountThatDoesNotMatchThePoses) {
  SimulatedSpidarG dev;
  const auto poses = CalibrationPoses(dev.info().geometry, 3, 1);
  EXPECT_THROW(GatherUnknownSamples(&dev, poses, CalibrationTensions(2, 0.3, 3.0, 1)),
               std::invalid_argument);
  const auto wave = GatherUnknownSamples(&dev, poses, CalibrationTensions(3, 0.3, 3.0, 1));
  EXPECT_EQ(wave[2].tension, CalibrationTensions(3, 0.3, 3.0, 1)[2]);
}

TEST(SelfCalibrate, EstimatesStretchWhenTheTensionsVary) {
  SimulatedDeviceConfig config;
  config.seed = 4;
  SimulatedSpidarG dev(config);
  const Session s = WaveSession(&dev, 100, 21);
  const CalibrationResult r = SelfCalibrate(dev.info().geometry, NominalOf(dev), s.home, s.wave);
  ASSERT_EQ(r.status, CalibrationStatus::kOk) << r.message;
  EXPECT_THAT(r.message, testing::HasSubstr("stretch estimated"));
  for (int i = 0; i < kNumStrings; ++i) {
    const StringEncoderParams& truth = dev.true_encoder().strings[i];
    const StringEncoderParams& est = r.calibration.strings[i];
    // The simulator's compliance is 4e-4 ± 1e-4 per N; 0.25 mm noise-free over 2.7 N.
    EXPECT_NEAR(est.stretch, truth.stretch, 6e-5) << "string " << i + 1;
    EXPECT_NEAR(est.gain, truth.gain, 3e-4) << "string " << i + 1;
    EXPECT_NEAR(est.offset, truth.offset, 1e-4) << "string " << i + 1;
  }
}

TEST(SelfCalibrate, KeepsTheStretchAndSaysWhyWhenTheTensionIsConstant) {
  SimulatedSpidarG dev;
  const SelfCalData data = Gather(&dev, 60, 22);
  EncoderCalibration initial = NominalOf(dev);
  for (auto& p : initial.strings) p.stretch = 3e-4;
  const CalibrationResult r = SelfCalibrate(dev.info().geometry, initial, data.home, data.wave);
  ASSERT_EQ(r.status, CalibrationStatus::kOk) << r.message;
  EXPECT_THAT(r.message, testing::HasSubstr("stretch kept"));
  EXPECT_THAT(r.message, testing::HasSubstr("spans 0 N"));
  for (const auto& p : r.calibration.strings) EXPECT_EQ(p.stretch, 3e-4);
}

TEST(SelfCalibrate, ToleranceOnTheHomingPoseRemovesTheJigError) {
  // The homing jig put the simulated grip 0.3 mm / 0.17° (sd) off its nominal pose. Held
  // exactly, the nominal pose puts that error into the offsets; with a tolerance the waved
  // poses determine the offsets and the true homing pose.
  SimulatedDeviceConfig config;
  config.seed = 3;
  SimulatedSpidarG dev(config);
  const Session s = WaveSession(&dev, 100, 23);
  SelfCalibrationSettings exact;
  exact.known_position_sd = 0.0;
  exact.known_rotation_sd = 0.0;
  const CalibrationResult held =
      SelfCalibrate(dev.info().geometry, NominalOf(dev), s.home, s.wave, exact);
  const CalibrationResult soft = SelfCalibrate(dev.info().geometry, NominalOf(dev), s.home, s.wave);
  ASSERT_EQ(held.status, CalibrationStatus::kOk) << held.message;
  ASSERT_EQ(soft.status, CalibrationStatus::kOk) << soft.message;
  double held_error = 0.0, soft_error = 0.0;
  for (int i = 0; i < kNumStrings; ++i) {
    const double truth = dev.true_encoder().strings[i].offset;
    held_error = std::max(held_error, std::abs(held.calibration.strings[i].offset - truth));
    soft_error = std::max(soft_error, std::abs(soft.calibration.strings[i].offset - truth));
  }
  // The jig error of this device moves the home lengths by up to ~0.5 mm.
  const Vector8d jig = InverseKinematics(dev.info().geometry, dev.true_home_pose()) -
                       InverseKinematics(dev.info().geometry, dev.info().home_pose);
  EXPECT_GT(jig.cwiseAbs().maxCoeff(), 2e-4);
  EXPECT_GT(held_error, 0.5 * jig.cwiseAbs().maxCoeff());
  EXPECT_LT(soft_error, 1e-4);
}

TEST(SelfCalibrate, RejectsBadToleranceSettings) {
  SimulatedSpidarG dev;
  const SelfCalData data = Gather(&dev, 40, 24);
  SelfCalibrationSettings settings;
  settings.known_position_sd = 1e-3;
  settings.known_rotation_sd = 0.0;
  CalibrationResult r =
      SelfCalibrate(dev.info().geometry, NominalOf(dev), data.home, data.wave, settings);
  EXPECT_EQ(r.status, CalibrationStatus::kInvalidInput);
  EXPECT_THAT(r.message, testing::HasSubstr("known_rotation_sd"));
  settings = {};
  settings.length_sd = std::nan("");
  r = SelfCalibrate(dev.info().geometry, NominalOf(dev), data.home, data.wave, settings);
  EXPECT_EQ(r.status, CalibrationStatus::kInvalidInput);
  EXPECT_THAT(r.message, testing::HasSubstr("length_sd"));
}

// Issue 15: at most 0.2 mm of maximum pose error on five simulated devices, with the protocol
// of `spidarcad calibrate --simulated` (100 waved poses in the 40 cm cube, tensions varied,
// the homing sample as the device gives it), judged on 200 other poses at 0.2–3 N against the
// simulator's hidden truth. The floor (true parameters) is ~0.04 mm.
TEST(HardSelfCalibrate, ReachesTwoTenthsOfAMillimetreOnFiveSeeds) {
  double worst = 0.0, worst_floor = 0.0;
  for (std::uint64_t seed = 1; seed <= 5; ++seed) {
    SimulatedDeviceConfig config;
    config.seed = seed;
    SimulatedSpidarG dev(config);
    const SpidarGeometry& g = dev.info().geometry;
    const Session s = WaveSession(&dev, 100, seed * 104729 + 2);
    const CalibrationResult r = SelfCalibrate(g, NominalOf(dev), s.home, s.wave);
    ASSERT_EQ(r.status, CalibrationStatus::kOk) << "seed " << seed << ": " << r.message;
    const auto eval = CalibrationPoses(g, 200, seed * 7919 + 1);
    const AccuracyReport after = EvaluateAccuracy(&dev, r.calibration, eval, 0.2, 3.0, 1);
    const AccuracyReport floor = EvaluateAccuracy(&dev, dev.true_encoder(), eval, 0.2, 3.0, 1);
    EXPECT_EQ(after.fk_failures, 0) << "seed " << seed;
    EXPECT_LE(after.position_error_max, 2e-4) << "seed " << seed;
    // Rotation: 0.1-0.5° here (the true parameters 0.1-0.2°), 2.7-4° before stretch was fitted.
    EXPECT_LT(after.rotation_error_max, 1.0 * kDeg) << "seed " << seed;
    worst = std::max(worst, after.position_error_max);
    worst_floor = std::max(worst_floor, floor.position_error_max);
  }
  RecordProperty("figure", "max position error " + std::to_string(worst * 1e3) +
                               " mm over seeds 1-5 (true parameters: " +
                               std::to_string(worst_floor * 1e3) + " mm)");
  RecordProperty("bar", "<= 0.2 mm on every seed");
}

TEST(EvaluateAccuracy, CalibrationBringsErrorsToThePapersFigures) {
  // Before: millimetres of error; after: the paper's 0.80 % length error and 4 mm position
  // error in a 40 cm cube are met.
  SimulatedDeviceConfig config;
  config.seed = 3;
  SimulatedSpidarG dev(config);
  const SpidarGeometry& g = dev.info().geometry;
  const auto eval = CalibrationPoses(g, 150, 99);
  const EncoderCalibration nominal = NominalOf(dev);
  const AccuracyReport before = EvaluateAccuracy(&dev, nominal, eval, 0.2, 3.0, 1);
  const auto jig = GatherKnownSamples(&dev, CalibrationPoses(g, 60, 12), 0.5);
  const CalibrationResult line = FitLinesPerString(g, nominal, jig);
  ASSERT_EQ(line.status, CalibrationStatus::kOk);
  const SelfCalData data = Gather(&dev, 60, 13);
  const CalibrationResult self = SelfCalibrate(g, nominal, data.home, data.wave);
  ASSERT_EQ(self.status, CalibrationStatus::kOk);
  const AccuracyReport after_line = EvaluateAccuracy(&dev, line.calibration, eval, 0.2, 3.0, 1);
  const AccuracyReport after_self = EvaluateAccuracy(&dev, self.calibration, eval, 0.2, 3.0, 1);

  EXPECT_GT(before.position_error_max, 0.02);
  EXPECT_GT(before.length_error_mean, 0.005);
  for (const AccuracyReport* r : {&after_line, &after_self}) {
    EXPECT_EQ(r->fk_failures, 0);
    EXPECT_LT(r->length_error_mean + r->length_error_sd, 0.008);
    EXPECT_LT(r->position_error_mean, 2e-3);
  }
  EXPECT_LT(after_self.position_error_max, 4e-3);
  EXPECT_LT(after_self.length_abs_error_rms, after_line.length_abs_error_rms);
  // The perfect calibration bounds what any method can reach (stretch is not modelled).
  const AccuracyReport truth = EvaluateAccuracy(&dev, dev.true_encoder(), eval, 0.2, 3.0, 1);
  EXPECT_LT(truth.position_error_max, 2e-4);
  EXPECT_LE(truth.length_abs_error_rms, after_self.length_abs_error_rms);
}

}  // namespace
}  // namespace spidarcad::haptics
