// Speed of the sensing path: the per-tick count -> length conversion and simulated device
// step (haptic thread), and the calibrations (off-line).
// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#include <benchmark/benchmark.h>

#include "bench_cli.h"
#include "spidarcad/haptics/calibration.h"
#include "spidarcad/haptics/encoder.h"
#include "spidarcad/haptics/kinematics.h"
#include "spidarcad/haptics/simulated_device.h"

namespace spidarcad::haptics {
namespace {

EncoderCalibration NominalOf(const SimulatedSpidarG& dev) {
  return EncoderCalibration::Nominal(dev.info().encoder,
                                     InverseKinematics(dev.info().geometry, dev.info().home_pose));
}

// One tick's conversion of 8 counters to lengths (with stretch correction).
void BM_CountsToLengths(benchmark::State& state) {
  SimulatedSpidarG dev;
  const EncoderCalibration cal = dev.true_encoder();
  EncoderReading reading;
  dev.Read(&reading);
  const Vector8d tau = Vector8d::Constant(1.0);
  for (auto _ : state) {
    benchmark::DoNotOptimize(reading.counts);
    Vector8d l = cal.Lengths(reading.counts, tau);
    benchmark::DoNotOptimize(l);
  }
}
BENCHMARK(BM_CountsToLengths);

// One simulated device tick: write tensions, step 1 ms, read.
void BM_SimulatedDeviceTick(benchmark::State& state) {
  SimulatedSpidarG dev;
  const auto poses = RandomGripPoses(dev.info().geometry, 64, 0.2, 0.5, 0.3, 1);
  const Vector8d tau = Vector8d::Constant(1.0);
  EncoderReading reading;
  size_t k = 0;
  for (auto _ : state) {
    dev.SetTruePose(poses[k++ & 63]);
    dev.WriteTensions(tau);
    dev.Step(0.001);
    dev.Read(&reading);
    benchmark::DoNotOptimize(reading);
  }
}
BENCHMARK(BM_SimulatedDeviceTick);

// The paper's line fit with N jig poses.
void BM_FitLinesPerString(benchmark::State& state) {
  SimulatedSpidarG dev;
  const auto poses = RandomGripPoses(dev.info().geometry, state.range(0), 0.2, 0.5, 0.3, 2);
  const auto jig = GatherKnownSamples(&dev, poses, 0.5);
  const EncoderCalibration nominal = NominalOf(dev);
  for (auto _ : state) {
    benchmark::DoNotOptimize(FitLinesPerString(dev.info().geometry, nominal, jig));
  }
}
BENCHMARK(BM_FitLinesPerString)->Arg(100)->Unit(benchmark::kMicrosecond);

// A self-calibration session as `spidarcad calibrate --simulated` runs it: the homing sample
// and N waved poses in the 40 cm cube with the tensions varied per string in 0.3-3 N.
struct Session {
  std::vector<KnownPoseSample> home;
  std::vector<UnknownPoseSample> wave;
};
Session WaveSession(SimulatedSpidarG* dev, int count, std::uint64_t seed) {
  const auto poses = RandomGripPoses(dev->info().geometry, count, 0.2, 0.5236, 0.3, seed);
  return {{HomingSample(dev->info(), dev->config().homing_tension)},
          GatherUnknownSamples(dev, poses, CalibrationTensions(count, 0.3, 3.0, seed))};
}

// Self-calibration (offset, gain, quadratic and stretch per string) with N unknown poses.
void BM_SelfCalibrate(benchmark::State& state) {
  SimulatedSpidarG dev;
  const Session s = WaveSession(&dev, static_cast<int>(state.range(0)), 3);
  const EncoderCalibration nominal = NominalOf(dev);
  for (auto _ : state) {
    benchmark::DoNotOptimize(SelfCalibrate(dev.info().geometry, nominal, s.home, s.wave));
  }
}
BENCHMARK(BM_SelfCalibrate)->Arg(40)->Arg(100)->Arg(300)->Unit(benchmark::kMillisecond);

// Accuracy of self-calibration on the simulated device of seed N (100 poses), as counters:
// position and rotation error (mean, max) over 200 evaluation poses at 0.2-3 N, mm and deg,
// and the floor of the true parameters. Issue 15's bar: pos_max_mm <= 0.2 on seeds 1-5.
void BM_SelfCalibrationAccuracy(benchmark::State& state) {
  const std::uint64_t seed = static_cast<std::uint64_t>(state.range(0));
  SimulatedDeviceConfig config;
  config.seed = seed;
  AccuracyReport after, floor;
  for (auto _ : state) {
    SimulatedSpidarG dev(config);
    const Session s = WaveSession(&dev, 100, seed * 104729 + 2);
    const CalibrationResult r = SelfCalibrate(dev.info().geometry, NominalOf(dev), s.home, s.wave);
    const auto eval = RandomGripPoses(dev.info().geometry, 200, 0.2, 0.5236, 0.3, seed * 7919 + 1);
    after = EvaluateAccuracy(&dev, r.calibration, eval, 0.2, 3.0, 1);
    floor = EvaluateAccuracy(&dev, dev.true_encoder(), eval, 0.2, 3.0, 1);
  }
  constexpr double kDeg = 180.0 / 3.141592653589793;
  state.counters["pos_mean_mm"] = after.position_error_mean * 1e3;
  state.counters["pos_max_mm"] = after.position_error_max * 1e3;
  state.counters["rot_mean_deg"] = after.rotation_error_mean * kDeg;
  state.counters["rot_max_deg"] = after.rotation_error_max * kDeg;
  state.counters["floor_pos_max_mm"] = floor.position_error_max * 1e3;
  state.counters["floor_rot_max_deg"] = floor.rotation_error_max * kDeg;
}
BENCHMARK(BM_SelfCalibrationAccuracy)
    ->DenseRange(1, 5)
    ->Iterations(1)
    ->Unit(benchmark::kMillisecond);

}  // namespace
}  // namespace spidarcad::haptics

// What this program measures (its --help).
constexpr const char* kBenchDescription =
    "Speed of the sensing path: the per-tick count -> length conversion and simulated device\n"
    "step (haptic thread), and the calibrations (off-line).";

int main(int argc, char** argv) {
  return spidarcad::bench::RunBenchmarkMain(argc, argv, kBenchDescription);
}
