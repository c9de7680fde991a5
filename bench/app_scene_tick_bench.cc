// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
// Tick time per scene type: the compute time of HapticLoop::Step (calibration, FK, the scene's
// force fields, safety, tension solve) on the simulated SPIDAR-G gripped by the simulated hand,
// as in `spidarcad run`, over N ticks (default 20 000; the trajectory repeats). Prints p50,
// p99, p99.9 and max per scene as a markdown table for the README.
//   build/bench/app_scene_tick_bench [ticks]
// Scenes: empty; demo (plane wall + spring); implicit proxy (assets/scenes/platform.json, two
// ProxyFields, press onto the plate); six-DOF shell tool (platform.json, cross-grip point shell
// against the union of both solids, twist against the wall). FE k = 16 and sculpt rows come
// from other fields later ("not yet").
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <memory>
#include <string>
#include <ctime>
#include <vector>

#include "runtime/scene_haptics.h"
#include "spidarcad/haptics/haptic_loop.h"
#include "spidarcad/haptics/kinematics.h"
#include "spidarcad/haptics/simulated_device.h"
#include "spidarcad/haptics/simulated_hand.h"
#include "spidarcad/haptics/trajectory.h"
#include "spidarcad/modeling/scene_io.h"

namespace {

namespace haptics = spidarcad::haptics;
namespace app = spidarcad::app;

std::string AssetDir() {
  std::string file = __FILE__;  // .../bench/app_scene_tick_bench.cc
  file = file.substr(0, file.rfind('/'));
  return file.substr(0, file.rfind('/')) + "/assets/";
}

struct Row {
  std::string name;
  double p50 = 0, p99 = 0, p999 = 0, max = 0, mean = 0;
  double cpu_p50 = 0, cpu_p99 = 0, cpu_p999 = 0, cpu_max = 0;
};

// CPU time of the calling thread, µs (not advanced while the thread is preempted).
double ThreadCpuMicros() {
  timespec ts;
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
  return ts.tv_sec * 1e6 + ts.tv_nsec * 1e-3;
}

double Quantile(std::vector<double> v, double p) {
  const std::size_t k = std::min(v.size() - 1, static_cast<std::size_t>(std::ceil(p * v.size())) - 1);
  std::nth_element(v.begin(), v.begin() + k, v.end());
  return v[k];
}

Row Measure(const std::string& name, std::unique_ptr<haptics::HapticScene> scene,
            const haptics::LoopSettings& loop_settings, const std::string& trajectory_file, long ticks) {
  const haptics::Trajectory trajectory = haptics::Trajectory::Load(AssetDir() + trajectory_file);
  haptics::SimulatedDeviceConfig config;
  config.seed = 1;
  haptics::SimulatedSpidarG device(config);
  const haptics::DeviceInfo& info = device.info();
  const haptics::EncoderCalibration calibration = haptics::EncoderCalibration::Nominal(
      info.encoder, haptics::InverseKinematics(info.geometry, info.home_pose));
  haptics::HapticLoop loop(info, calibration, loop_settings);
  loop.Publish(std::move(scene));
  const double dt = 1e-3, t0 = trajectory.start_time();
  const double duration = trajectory.end_time() - t0;
  haptics::SimulatedHand hand(haptics::HandSettings{}, trajectory.Sample(t0), info.geometry.d);
  std::vector<double> us, cpu;
  us.reserve(ticks);
  cpu.reserve(ticks);
  for (long k = 0; k < ticks; ++k) {
    const double t = t0 + std::fmod(k * dt, duration);
    hand.Step(trajectory.Sample(t), device.TrueWrench(), dt);
    device.SetTruePose(hand.pose());
    device.Step(dt);
    haptics::TickInputs inputs;
    device.Read(&inputs.reading);
    const double cpu_start = ThreadCpuMicros();
    const auto start = std::chrono::steady_clock::now();
    const haptics::TickOutputs out = loop.Step(inputs, dt);
    const auto stop = std::chrono::steady_clock::now();
    cpu.push_back(ThreadCpuMicros() - cpu_start);
    device.WriteTensions(out.tau);
    us.push_back(std::chrono::duration<double, std::micro>(stop - start).count());
  }
  Row row;
  row.name = name;
  row.p50 = Quantile(us, 0.5);
  row.p99 = Quantile(us, 0.99);
  row.p999 = Quantile(us, 0.999);
  row.max = *std::max_element(us.begin(), us.end());
  row.cpu_p50 = Quantile(cpu, 0.5);
  row.cpu_p99 = Quantile(cpu, 0.99);
  row.cpu_p999 = Quantile(cpu, 0.999);
  row.cpu_max = *std::max_element(cpu.begin(), cpu.end());
  double sum = 0;
  for (double v : us) sum += v;
  row.mean = sum / us.size();
  return row;
}

haptics::LoopSettings BaseSettings() {
  haptics::LoopSettings s;
  s.fk.max_residual = 5e-3;  // as `spidarcad run`: nominal calibration
  return s;
}

Row MeasureScene(const std::string& name, app::ToolModel tool, const Eigen::Vector3d& p_WDo,
                 const std::string& trajectory_file, long ticks) {
  const spidarcad::modeling::Scene scene =
      spidarcad::modeling::LoadScene(AssetDir() + "scenes/platform.json");
  app::SceneHapticsOptions options;
  options.tool = tool;
  options.world_scale = 1.0;
  options.p_WDo = p_WDo;
  app::SceneHaptics built = app::BuildHapticScene(scene, options);
  haptics::LoopSettings settings = BaseSettings();
  built.ApplyTo(&settings);
  return Measure(name, std::move(built.scene), settings, trajectory_file, ticks);
}

}  // namespace

int main(int argc, char** argv) {
  const long ticks = argc > 1 ? std::max(1000L, std::atol(argv[1])) : 20000L;
  std::vector<Row> rows;
  rows.push_back(Measure("empty", std::make_unique<haptics::HapticScene>(), BaseSettings(),
                         "trajectories/press.csv", ticks));
  rows.push_back(Measure("demo (plane wall + spring)", haptics::MakeDemoScene(), BaseSettings(),
                         "trajectories/press.csv", ticks));
  rows.push_back(MeasureScene("implicit proxy (platform.json, 2 solids, press)", app::ToolModel::kProxy,
                              Eigen::Vector3d(0.1, 0, 0.04), "trajectories/press.csv", ticks));
  rows.push_back(MeasureScene("six-DOF shell tool (platform.json, 196 points, twist)",
                              app::ToolModel::kShell, Eigen::Vector3d(0.043, 0.2, -0.1),
                              "trajectories/twist.csv", ticks));
  std::printf("HapticLoop::Step compute time, %ld ticks per scene, simulated device + hand\n\n", ticks);
  std::printf("| scene | p50 µs | p99 µs | p99.9 µs | max µs | mean µs |\n|---|---|---|---|---|---|\n");
  for (const Row& r : rows) {
    std::printf("| %s | %.1f | %.1f | %.1f | %.1f | %.1f |\n", r.name.c_str(), r.p50, r.p99, r.p999,
                r.max, r.mean);
  }
  std::printf("| FE contact, k = 16 | not yet | | | | |\n| sculpt tool | not yet | | | | |\n");
  std::printf("\nThe same ticks in thread CPU time (CLOCK_THREAD_CPUTIME_ID: preemption by other "
              "processes excluded)\n\n| scene | p50 µs | p99 µs | p99.9 µs | max µs |\n|---|---|---|---|---|\n");
  for (const Row& r : rows) {
    std::printf("| %s | %.1f | %.1f | %.1f | %.1f |\n", r.name.c_str(), r.cpu_p50, r.cpu_p99,
                r.cpu_p999, r.cpu_max);
  }
  return 0;
}
