// Tick time of the haptic loop (HapticLoop::Step: calibration, FK, force fields, safety,
// tension solve) on readings of the simulated SPIDAR-G along a moving grip path, for the empty
// scene and the demo wall scene. Besides Google Benchmark's mean, each run reports the tick
// time percentiles p50/p99/p99.9/max (µs) from a per-tick histogram.
// Run: build/bench/haptic_loop_bench
// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#include <benchmark/benchmark.h>

#include <Eigen/Geometry>
#include <chrono>
#include <cmath>
#include <vector>

#include "bench_cli.h"
#include "spidarcad/haptics/haptic_loop.h"
#include "spidarcad/haptics/kinematics.h"
#include "spidarcad/haptics/loop_runner.h"
#include "spidarcad/haptics/simulated_device.h"

namespace spidarcad::haptics {
namespace {

// Readings of a grip moving along a circle that dips 5 mm into the demo floor (z = −0.03).
std::vector<EncoderReading> Readings(SimulatedSpidarG* device, int count) {
  std::vector<EncoderReading> readings(count);
  for (int k = 0; k < count; ++k) {
    const double t = 1e-3 * k;
    const Eigen::Vector3d p0(0.04 * std::cos(t), 0.04 * std::sin(t),
                             -0.03 + 0.005 * std::cos(3 * t));
    const Eigen::Matrix3d R =
        Eigen::AngleAxisd(0.2 * std::sin(t), Eigen::Vector3d(0.3, 0.5, 0.8).normalized())
            .toRotationMatrix();
    device->SetTruePose(GripPose::FromFrame(p0, R, M_PI / 2 + 0.1 * std::sin(2 * t), 0.04));
    device->Step(1e-3);
    device->Read(&readings[k]);
  }
  return readings;
}

void RunTicks(benchmark::State& state, bool demo) {
  SimulatedSpidarG device{SimulatedDeviceConfig{}};
  const DeviceInfo& info = device.info();
  LoopSettings settings;
  settings.fk.max_residual = 5e-3;
  HapticLoop loop(
      info,
      EncoderCalibration::Nominal(info.encoder, InverseKinematics(info.geometry, info.home_pose)),
      settings);
  loop.Publish(demo ? MakeDemoScene() : std::make_unique<HapticScene>());
  // 6.3 s: one full circle, so the path closes and the FK warm start stays valid on wrap.
  const std::vector<EncoderReading> readings = Readings(&device, 6283);
  LatencyHistogram histogram(1e-8, 100000);
  std::size_t k = 0;
  TickInputs inputs;
  for (auto _ : state) {
    inputs.reading = readings[k];
    k = (k + 1) % readings.size();
    const auto start = std::chrono::steady_clock::now();
    const TickOutputs out = loop.Step(inputs, 1e-3);
    const auto stop = std::chrono::steady_clock::now();
    benchmark::DoNotOptimize(out.tau.data());
    histogram.Add(std::chrono::duration<double>(stop - start).count());
  }
  state.counters["p50_us"] = histogram.Percentile(0.5) * 1e6;
  state.counters["p99_us"] = histogram.Percentile(0.99) * 1e6;
  state.counters["p99.9_us"] = histogram.Percentile(0.999) * 1e6;
  state.counters["max_us"] = histogram.max() * 1e6;
}

void BM_TickEmptyScene(benchmark::State& state) { RunTicks(state, false); }
void BM_TickWallScene(benchmark::State& state) { RunTicks(state, true); }
BENCHMARK(BM_TickEmptyScene)->Iterations(60000)->Unit(benchmark::kMicrosecond);
BENCHMARK(BM_TickWallScene)->Iterations(60000)->Unit(benchmark::kMicrosecond);

}  // namespace
}  // namespace spidarcad::haptics

// What this program measures (its --help).
constexpr const char* kBenchDescription =
    "Tick time of the haptic loop (HapticLoop::Step: calibration, FK, force fields, safety,\n"
    "tension solve) on readings of the simulated SPIDAR-G along a moving grip path, for the empty\n"
    "scene and the demo wall scene. Besides Google Benchmark's mean, each run reports the tick\n"
    "time percentiles p50/p99/p99.9/max (µs) from a per-tick histogram.\n"
    "Run: build/bench/haptic_loop_bench";

int main(int argc, char** argv) {
  return spidarcad::bench::RunBenchmarkMain(argc, argv, kBenchDescription);
}
