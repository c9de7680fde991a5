// Tests of the self-calibration session taken one reading at a time (scene/calibration_collector.h)
// and of the haptic runtime's side of it (HapticRuntime::SetCalibrationTensions,
// TakeCalibrationReadings, UseCalibration): the octant bookkeeping against a recount of the kept
// samples, the fit against the simulator's hidden truth, the tensions and held times of the
// session's ticks against the schedule computed independently, the ring's overflow, allocation-
// free session ticks, and a calibration used without a restart.
// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#include "scene/calibration_collector.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <memory>
#include <numbers>
#include <stdexcept>
#include <string>
#include <vector>

#include "scene/device_rig.h"
#include "scene/haptic_runtime.h"
#include "spidarcad/haptics/calibration_session.h"
#include "spidarcad/haptics/kinematics.h"
#include "spidarcad/haptics/simulated_device.h"
#include "support/malloc_counter.h"
#include "window_test_support.h"

namespace spidarcad::app {
namespace {

using haptics::GripPose;
using testing::HasSubstr;

// The identity of the runtime's simulated device.
CalibrationDevice IdentityOf(const HapticRuntime& runtime) {
  CalibrationDevice device;
  device.kind = RuntimeDeviceName(runtime.settings().device);
  device.seed = runtime.settings().seed;
  device.geometry = runtime.info().geometry;
  device.encoder = runtime.info().encoder;
  return device;
}

// A session on `runtime` (ticked on a virtual clock): the hand follows the waving trajectory,
// the readings go to `collector` every 16 ticks, until it is done or `seconds` have passed.
// Returns the virtual seconds taken.
double WaveSession(HapticRuntime* runtime, CalibrationCollector* collector, double seconds) {
  const haptics::Trajectory wave =
      haptics::WavingTrajectory(runtime->info().geometry, seconds, runtime->settings().seed);
  const double d = runtime->info().geometry.d;
  runtime->SetCalibrationTensions(true);
  std::vector<CalibrationReading> readings;
  haptics::TickTiming timing;
  double t = 0.0;
  for (; t < seconds && !collector->Done(); t += 0.016) {
    const haptics::TrajectorySample s = wave.Sample(t);
    runtime->SetTarget(GripPose::FromFrame(s.p_DT, s.q_DT.toRotationMatrix(), s.grasp, d));
    for (int k = 0; k < 16; ++k, ++timing.tick) runtime->Tick(timing);
    readings.clear();
    runtime->TakeCalibrationReadings(&readings);
    for (const CalibrationReading& r : readings) collector->Offer(r.reading, r.tension, r.held);
  }
  runtime->SetCalibrationTensions(false);
  return t;
}

RuntimeSettings Simulated(std::uint64_t seed) {
  RuntimeSettings settings;
  settings.device = RuntimeDevice::kSimulated;
  settings.seed = seed;
  return settings;
}

TEST(CalibrationCollector, CountsOctantsAsARecountOfItsSamples) {
  HapticRuntime runtime(Simulated(3), GripPose::Rest(0.04));
  runtime.Publish(std::make_unique<haptics::HapticScene>());
  // More poses than 12 s of waving gives: the session is caught part way, octants still missing.
  CalibrationCollector collector(IdentityOf(runtime), runtime.info(), 400);
  WaveSession(&runtime, &collector, 12.0);
  ASSERT_GT(collector.collected(), 20);
  ASSERT_LT(collector.collected(), 400);
  // Recount: each kept sample placed by a forward kinematics of our own on the nominal lengths.
  haptics::FkSettings fk_settings;
  fk_settings.max_iterations = 50;
  fk_settings.max_residual = kNominalFkMaxResidual;
  fk_settings.warm_start = false;
  haptics::ForwardKinematics fk(runtime.info().geometry, fk_settings);
  const haptics::EncoderCalibration nominal = NominalCalibration(runtime.info());
  std::array<int, 8> recount{};
  for (const haptics::UnknownPoseSample& s : collector.samples()) {
    const haptics::FkResult r = fk.Solve(nominal.Lengths(s.counts, s.tension));
    ASSERT_EQ(r.status, haptics::FkStatus::kOk);
    const Eigen::Vector3d& p = r.pose.p0;
    ++recount[(p.x() >= 0 ? 1 : 0) + (p.y() >= 0 ? 2 : 0) + (p.z() >= 0 ? 4 : 0)];
  }
  EXPECT_EQ(collector.octant_counts(), recount);
  EXPECT_EQ(collector.per_octant(), 400 / 16);
  std::vector<int> needed;
  for (int o = 0; o < 8; ++o) {
    if (recount[o] < 400 / 16) needed.push_back(o);
  }
  EXPECT_EQ(collector.NeededOctants(), needed);
  EXPECT_FALSE(collector.Done());
  EXPECT_THAT(collector.Progress(), HasSubstr("/400 useful poses; more needed in octants"));
  // Every kept reading was taken with settled tensions: the counts add up.
  const haptics::PoseCollectorCounts& c = collector.counts();
  EXPECT_EQ(c.kept, collector.collected());
  EXPECT_EQ(c.offered, c.kept + c.not_ok + c.slack + c.unsettled + c.no_pose + c.too_close);
  EXPECT_GT(c.unsettled, 0);
}

TEST(CalibrationCollector, ARuntimeSessionFitsCloseToTheSimulatorsTruth) {
  HapticRuntime runtime(Simulated(2), GripPose::Rest(0.04));
  runtime.Publish(std::make_unique<haptics::HapticScene>());
  CalibrationCollector collector(IdentityOf(runtime), runtime.info(), 80);
  const double seconds = WaveSession(&runtime, &collector, 180.0);
  ASSERT_TRUE(collector.Done()) << collector.Progress() << " after " << seconds << " s";
  for (int n : collector.octant_counts()) EXPECT_GE(n, 80 / 16);
  // The truth: a twin of the running device (same seed, same hidden parameters).
  haptics::SimulatedSpidarG twin(runtime.physical_device()->config());
  CalibrationFitOptions options;
  options.truth = &twin;
  options.homing_tension = twin.config().homing_tension;
  const CalibrationOutcome outcome = collector.Fit(options);
  ASSERT_TRUE(outcome.ok) << outcome.error;
  ASSERT_EQ(outcome.rows.size(), 3u);
  EXPECT_EQ(outcome.rows[0].key, "uncalibrated");
  EXPECT_EQ(outcome.rows[1].key, "self");
  EXPECT_EQ(outcome.rows[2].key, "true_parameters");
  const double before = outcome.rows[0].accuracy->position_error_max;
  const double after = outcome.rows[1].accuracy->position_error_max;
  EXPECT_GT(before, 3e-3);
  EXPECT_LT(after, 0.5e-3);
  EXPECT_LT(outcome.rows[1].residual.rms, 0.2 * outcome.rows[0].residual.rms);
  // The file: this device, self-calibration, the gains near the truth.
  EXPECT_EQ(outcome.file.method, "self");
  EXPECT_EQ(CalibrationMismatch(outcome.file, IdentityOf(runtime)), "");
  EXPECT_EQ(outcome.file.fit.samples, collector.collected() + 1);  // + the homing sample
  for (int i = 0; i < 8; ++i) {
    EXPECT_NEAR(outcome.file.calibration.strings[i].gain, twin.true_encoder().strings[i].gain,
                2e-3);
  }
  RecordProperty("figure", "max position error " + std::to_string(1e3 * after) + " mm (before " +
                               std::to_string(1e3 * before) + " mm), 80 poses in " +
                               std::to_string(seconds) + " s");
}

TEST(CalibrationCollector, TooFewPosesFailWithTheSolversReason) {
  HapticRuntime runtime(Simulated(1), GripPose::Rest(0.04));
  runtime.Publish(std::make_unique<haptics::HapticScene>());
  CalibrationCollector collector(IdentityOf(runtime), runtime.info(), 200);
  WaveSession(&runtime, &collector, 1.5);  // a few poses near the centre
  ASSERT_LT(collector.collected(), 20);
  const CalibrationOutcome outcome = collector.Fit({});
  EXPECT_FALSE(outcome.ok);
  EXPECT_THAT(outcome.error, HasSubstr("self-calibration: too_few_samples"));
  EXPECT_TRUE(outcome.rows.empty());
  EXPECT_THROW(CalibrationCollector(IdentityOf(runtime), runtime.info(), 0), std::invalid_argument);
}

TEST(HapticRuntimeCalibration, SessionTicksHoldTheScheduleAndPublishHowLong) {
  RuntimeSettings settings;
  settings.device = RuntimeDevice::kBoardSim;
  settings.seed = 5;
  HapticRuntime runtime(settings, GripPose::Rest(0.04));
  runtime.Publish(window_test::SpringScene(DemoFieldSettings{}));
  window_test::RunTicks(&runtime, 600);  // the force ramp completes (0.5 s)
  std::vector<CalibrationReading> readings;
  EXPECT_EQ(runtime.TakeCalibrationReadings(&readings), 0);
  EXPECT_TRUE(readings.empty());  // no session: nothing published
  // The schedule, computed here from the documented range.
  const double hi = std::min(kCalibrationTensionHi, runtime.info().tension_max);
  const std::vector<haptics::Vector8d> schedule =
      haptics::CalibrationTensions(3, kCalibrationTensionLo, hi, 5);
  runtime.SetCalibrationTensions(true);
  EXPECT_TRUE(runtime.calibration_tensions());
  window_test::RunTicks(&runtime, 250);
  EXPECT_EQ(runtime.TakeCalibrationReadings(&readings), 0);
  ASSERT_EQ(readings.size(), 250u);
  for (int k = 0; k < 250; ++k) {
    const CalibrationReading& r = readings[static_cast<std::size_t>(k)];
    EXPECT_EQ(r.tension, schedule[static_cast<std::size_t>(k / 100)]) << k;
    EXPECT_NEAR(r.held, (k % 100) * 1e-3, 1e-12) << k;
    EXPECT_EQ(r.reading.status, haptics::DeviceStatus::kOk);
    if (k > 0) {
      EXPECT_EQ(r.reading.sequence, readings[k - 1].reading.sequence + 1);
    }
  }
  EXPECT_EQ(runtime.Latest().tool.tau, schedule[2]);  // what the strings are told
  for (int i = 0; i < 8; ++i) {
    EXPECT_GE(schedule[2][i], kCalibrationTensionLo);
    EXPECT_LE(schedule[2][i], hi);
  }
  // The emergency stop zeroes them and publishes nothing; after it, the hold starts again.
  runtime.EmergencyStop();
  window_test::RunTicks(&runtime, 20);
  readings.clear();
  runtime.TakeCalibrationReadings(&readings);
  EXPECT_TRUE(readings.empty());
  // Zero force: every string at the loop's minimum tension (0.2 N), below the session's range.
  EXPECT_EQ(runtime.Latest().tool.tau.maxCoeff(), runtime.Latest().tool.tau.minCoeff());
  EXPECT_LT(runtime.Latest().tool.tau.maxCoeff(), kCalibrationTensionLo);
  runtime.Rearm();
  window_test::RunTicks(&runtime, 600);  // the ramp again
  readings.clear();
  runtime.TakeCalibrationReadings(&readings);
  ASSERT_FALSE(readings.empty());
  EXPECT_EQ(readings.front().held, 0.0);
  // Readings not taken pile up to the ring's size; the rest are counted as dropped.
  readings.clear();
  runtime.TakeCalibrationReadings(&readings);
  window_test::RunTicks(&runtime, HapticRuntime::kCalibrationRingSize + 100);
  readings.clear();
  EXPECT_EQ(runtime.TakeCalibrationReadings(&readings), 100);
  EXPECT_EQ(readings.size(), static_cast<std::size_t>(HapticRuntime::kCalibrationRingSize));
  // Off: the loop's tensions again.
  runtime.SetCalibrationTensions(false);
  window_test::RunTicks(&runtime, 5);
  readings.clear();
  runtime.TakeCalibrationReadings(&readings);
  EXPECT_TRUE(readings.empty());
  EXPECT_LT(runtime.Latest().tool.tau.maxCoeff(), kCalibrationTensionLo + 1.0);
}

TEST(HapticRuntimeCalibration, SessionTicksAllocateNothing) {
  ASSERT_TRUE(test_support::MallocCounterActive());
  RuntimeSettings settings;
  settings.device = RuntimeDevice::kBoardSim;
  HapticRuntime runtime(settings, GripPose::Rest(0.04));
  runtime.Publish(window_test::SpringScene(DemoFieldSettings{}));
  window_test::RunTicks(&runtime, 600);
  runtime.SetCalibrationTensions(true);
  long allocations = 0;
  {
    test_support::MallocCounter counter;
    window_test::RunTicks(&runtime, HapticRuntime::kCalibrationRingSize + 500);  // overflowing
    allocations = counter.count();
  }
  EXPECT_EQ(allocations, 0);
}

TEST(HapticRuntimeCalibration, UseCalibrationReadsThroughItWithoutARestart) {
  RuntimeSettings settings;
  settings.device = RuntimeDevice::kBoardSim;
  settings.seed = 4;
  HapticRuntime runtime(settings, GripPose::Rest(0.04));
  runtime.Publish(window_test::SpringScene(DemoFieldSettings{}));
  const GripPose held = GripPose::FromFrame(
      Eigen::Vector3d(0.05, -0.04, 0.03), Eigen::Matrix3d::Identity(), std::numbers::pi / 2, 0.04);
  runtime.SetTarget(held);
  window_test::RunTicks(&runtime, 1500);
  // Length error against the true lengths of the hand's pose (closed form: inverse kinematics).
  const auto length_error = [&runtime] {
    const haptics::Vector8d truth =
        haptics::InverseKinematics(runtime.info().geometry, runtime.Latest().hand_pose);
    return (runtime.Latest().lengths - truth).cwiseAbs().maxCoeff();
  };
  const double nominal_error = length_error();
  EXPECT_GT(nominal_error, 2e-3);  // the simulated encoders' errors, read nominally
  runtime.EmergencyStop();
  const haptics::SimulatedSpidarG twin(runtime.physical_device()->config());
  haptics::EncoderCalibration bad = twin.true_encoder();
  bad.strings[3].gain = -1.0;
  EXPECT_THROW(runtime.UseCalibration(bad, "bad"), std::invalid_argument);
  EXPECT_NE(runtime.description(), "bad");  // nothing changed
  runtime.UseCalibration(twin.true_encoder(), "board-sim: the true parameters");
  EXPECT_EQ(runtime.description(), "board-sim: the true parameters");
  EXPECT_TRUE(runtime.emergency_stopped());  // the stop stays latched
  runtime.Rearm();
  runtime.Publish(window_test::SpringScene(DemoFieldSettings{}));
  window_test::RunTicks(&runtime, 1500);
  EXPECT_LT(length_error(), 0.1 * nominal_error);
  EXPECT_EQ(runtime.Latest().tool.fk_status, haptics::FkStatus::kOk);
}

}  // namespace
}  // namespace spidarcad::app
