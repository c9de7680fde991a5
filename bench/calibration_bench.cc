// Speed of the sensing path: the per-tick count -> length conversion and simulated device
// step (haptic thread), and the calibrations (off-line).
// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#include "bench_cli.h"
#include <benchmark/benchmark.h>

#include "spidarcad/haptics/calibration.h"
#include "spidarcad/haptics/encoder.h"
#include "spidarcad/haptics/kinematics.h"
#include "spidarcad/haptics/simulated_device.h"

namespace spidarcad::haptics {
namespace {

EncoderCalibration NominalOf(const SimulatedSpidarG& dev) {
  return EncoderCalibration::Nominal(
      dev.info().encoder, InverseKinematics(dev.info().geometry, dev.info().home_pose));
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

// Self-calibration (offset, gain, quadratic per string) with N unknown poses.
void BM_SelfCalibrate(benchmark::State& state) {
  SimulatedSpidarG dev;
  const auto poses = RandomGripPoses(dev.info().geometry, state.range(0), 0.2, 0.5, 0.3, 3);
  const auto home = GatherKnownSamples(&dev, {dev.info().home_pose}, 0.5);
  const auto wave = GatherUnknownSamples(&dev, poses, 0.5);
  const EncoderCalibration nominal = NominalOf(dev);
  for (auto _ : state) {
    benchmark::DoNotOptimize(SelfCalibrate(dev.info().geometry, nominal, home, wave));
  }
}
BENCHMARK(BM_SelfCalibrate)->Arg(30)->Arg(100)->Arg(300)->Unit(benchmark::kMillisecond);

}  // namespace
}  // namespace spidarcad::haptics

// What this program measures (its --help).
constexpr const char* kBenchDescription =
    "Speed of the sensing path: the per-tick count -> length conversion and simulated device\n"
    "step (haptic thread), and the calibrations (off-line).";

int main(int argc, char** argv) {
  return spidarcad::bench::RunBenchmarkMain(argc, argv, kBenchDescription);
}
