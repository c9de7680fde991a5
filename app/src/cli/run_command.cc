// `spidarcad run`: a headless haptic session. The full haptic loop (HapticLoop) runs on a
// virtual clock at 1 kHz against the simulated SPIDAR-G (strings, encoders and calibration
// error included), gripped by a simulated hand that follows a scripted trajectory and is pushed
// by the device's wrench. One CSV row per tick; a summary on stdout.
// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#include <chrono>
#include <cmath>
#include <fstream>
#include <iomanip>
#include <iostream>
#include <memory>
#include <sstream>
#include <string>
#include <vector>

#include <Eigen/Geometry>

#include "cli/cli_common.h"
#include "cli/commands.h"
#include "spidarcad/haptics/haptic_loop.h"
#include "spidarcad/haptics/kinematics.h"
#include "spidarcad/haptics/loop_runner.h"
#include "spidarcad/haptics/simulated_device.h"
#include "spidarcad/haptics/simulated_hand.h"
#include "spidarcad/haptics/trajectory.h"

namespace spidarcad::app {

namespace {

constexpr const char* kRunHelp =
    "Runs the 1 kHz haptic loop headless on a virtual clock: the simulated SPIDAR-G (encoder\n"
    "errors, noise, string stretch, motor lag; nominal calibration) is gripped by a simulated\n"
    "hand (mass-spring-damper) that follows the trajectory and is pushed by the device.\n"
    "\n"
    "SCENE: omit it for an empty scene, or 'demo' for the built-in demo: a floor wall at\n"
    "z = -0.03 m (normal +z, 2000 N/m, 5 N·s/m) and a 20 N/m spring toward (0.05, 0, 0) m.\n"
    "Scene files (implicit solids, FE parts) are not rendered by `run` yet.\n"
    "\n"
    "Trajectory CSV: t,x,y,z,qw,qx,qy,qz,grasp (s; m in the device frame D; unit quaternion\n"
    "of the grip frame R_DT; grasp angle in rad, pi/2 at rest); '#' comments allowed.\n"
    "Samples are interpolated (linear, slerp); the run lasts from the first to the last t.\n"
    "\n"
    "Output CSV, one row per tick, header line first:\n"
    "  t                 time, s\n"
    "  x,y,z,qw..qz      true grip pose (the hand's), D\n"
    "  grasp             true grasp angle, rad\n"
    "  fx,fy,fz,mx,my,mz,g  wrench commanded by the loop (after safety), D: N, N·m about p0,\n"
    "                    grasp torque N·m (> 0 squeezes)\n"
    "  tau1..tau8        string tensions sent to the device, N\n"
    "  tick_us           wall-clock compute time of HapticLoop::Step, µs\n"
    "  events            safety event bits of the tick (see summary for names)\n"
    "  fk_x,fk_y,fk_z    grip centre measured by forward kinematics, m\n"
    "\n"
    "Example:\n"
    "  spidarcad run demo --trajectory assets/trajectories/press.csv --out press_result.csv";

struct RunOptions {
  std::string scene;
  std::string trajectory;
  std::string out;
  std::string device = "simulated";
  std::vector<double> hand;
  std::uint64_t seed = 1;
};

std::string Fixed(double v, int digits) {
  std::ostringstream os;
  os << std::fixed << std::setprecision(digits) << v;
  return os.str();
}

void RunRun(const RunOptions& options) {
  if (options.device != "simulated") {
    throw InputError("--device: '" + options.device +
                     "' is not available for `run`; only 'simulated' exists");
  }
  std::unique_ptr<haptics::HapticScene> scene;
  std::string scene_name = "empty";
  if (options.scene.empty() || options.scene == "none") {
    scene = std::make_unique<haptics::HapticScene>();
  } else if (options.scene == "demo") {
    scene = haptics::MakeDemoScene();
    scene_name = "demo";
  } else {
    throw InputError("SCENE: '" + options.scene +
                     "': `run` renders only the built-in 'demo' scene (or none) for now; "
                     "implicit-solid and FE scenes are not yet turned into force fields");
  }
  const int num_fields = scene->size();

  haptics::HandSettings hand_settings;
  if (!options.hand.empty()) {
    if (options.hand.size() != 2) {
      throw InputError("--hand: expected stiffness,damping (N/m,N·s/m), got " +
                       std::to_string(options.hand.size()) + " numbers");
    }
    hand_settings.stiffness = options.hand[0];
    hand_settings.damping = options.hand[1];
  }
  try {
    hand_settings.Validate();
  } catch (const std::invalid_argument& e) {
    throw InputError(std::string("--hand: ") + e.what());
  }

  haptics::Trajectory trajectory;
  try {
    trajectory = haptics::Trajectory::Load(options.trajectory);
  } catch (const std::invalid_argument& e) {
    throw InputError(std::string("--trajectory: ") + e.what());
  }

  std::ofstream out(options.out);
  if (!out) throw InputError("--out: cannot write '" + options.out + "'");

  haptics::SimulatedDeviceConfig config;
  config.seed = options.seed;
  haptics::SimulatedSpidarG device(config);
  const haptics::DeviceInfo& info = device.info();
  const haptics::EncoderCalibration calibration = haptics::EncoderCalibration::Nominal(
      info.encoder, haptics::InverseKinematics(info.geometry, info.home_pose));
  haptics::LoopSettings settings;
  settings.fk.max_residual = 5e-3;  // nominal (uncalibrated) encoder model: mm-level errors
  haptics::HapticLoop loop(info, calibration, settings);
  loop.Publish(std::move(scene));

  const double dt = 1e-3;
  const double t0 = trajectory.start_time();
  const long ticks = static_cast<long>(std::floor((trajectory.end_time() - t0) / dt + 1e-9)) + 1;
  haptics::SimulatedHand hand(hand_settings, trajectory.Sample(t0), info.geometry.d);
  haptics::LatencyHistogram tick_time(1e-7, 100000);

  out << "t,x,y,z,qw,qx,qy,qz,grasp,fx,fy,fz,mx,my,mz,g,tau1,tau2,tau3,tau4,tau5,tau6,tau7,tau8,"
         "tick_us,events,fk_x,fk_y,fk_z\n";
  std::string buffer;
  double max_force = 0.0;
  for (long k = 0; k < ticks; ++k) {
    const double t = t0 + k * dt;
    hand.Step(trajectory.Sample(t), device.TrueWrench(), dt);
    device.SetTruePose(hand.pose());
    device.Step(dt);
    haptics::TickInputs inputs;
    device.Read(&inputs.reading);
    const auto start = std::chrono::steady_clock::now();
    const haptics::TickOutputs result = loop.Step(inputs, dt);
    const auto stop = std::chrono::steady_clock::now();
    device.WriteTensions(result.tau);
    const double seconds = std::chrono::duration<double>(stop - start).count();
    tick_time.Add(seconds);
    max_force = std::max(max_force, result.wrench_D.head<3>().norm());

    const Eigen::Quaterniond q(hand.rotation());
    const double row[] = {t, hand.position().x(), hand.position().y(), hand.position().z(),
                          q.w(), q.x(), q.y(), q.z(), hand.grasp()};
    for (double v : row) buffer += FormatNumber(v) + ',';
    for (int i = 0; i < 7; ++i) buffer += FormatNumber(result.wrench_D(i)) + ',';
    for (int i = 0; i < 8; ++i) buffer += FormatNumber(result.tau(i)) + ',';
    buffer += Fixed(seconds * 1e6, 2) + ',';
    buffer += std::to_string(result.events) + ',';
    const bool has_pose = result.fk_status == haptics::FkStatus::kOk;
    for (int i = 0; i < 3; ++i) {
      buffer += has_pose ? FormatNumber(result.pose_D.p0(i)) : std::string("nan");
      buffer += i < 2 ? ',' : '\n';
    }
    if (buffer.size() > (1 << 16)) {
      out << buffer;
      buffer.clear();
    }
  }
  out << buffer;
  out.close();
  if (!out) throw InputError("--out: failed writing '" + options.out + "'");

  std::cout << "run: " << ticks << " ticks (" << Fixed((ticks - 1) * dt, 3)
            << " s at 1000 Hz, virtual clock), scene " << scene_name << " (" << num_fields
            << " field" << (num_fields == 1 ? "" : "s") << "), device simulated (seed "
            << options.seed << "), hand " << FormatNumber(hand_settings.stiffness) << " N/m, "
            << FormatNumber(hand_settings.damping) << " N·s/m\n";
  std::cout << "tick time [us]: p50 " << Fixed(tick_time.Percentile(0.5) * 1e6, 1) << "  p99 "
            << Fixed(tick_time.Percentile(0.99) * 1e6, 1) << "  p99.9 "
            << Fixed(tick_time.Percentile(0.999) * 1e6, 1) << "  max "
            << Fixed(tick_time.max() * 1e6, 1) << "  mean " << Fixed(tick_time.mean() * 1e6, 1)
            << "\n";
  std::cout << "safety events [ticks]:";
  const auto& counts = loop.event_counts();
  for (int i = 0; i < haptics::kNumSafetyEvents; ++i) {
    std::cout << ' ' << haptics::SafetyEventName(i) << '=' << counts[i] << " (bit " << i << ")"
              << (i + 1 < haptics::kNumSafetyEvents ? "," : "");
  }
  std::cout << "\nmax commanded force: " << Fixed(max_force, 3) << " N\n";
  std::cout << "wrote " << options.out << " (" << ticks << " rows)\n" << std::flush;
  throw CommandExit{0};
}

}  // namespace

void RegisterRunCommand(CLI::App& app) {
  auto options = std::make_shared<RunOptions>();
  CLI::App* cmd = app.add_subcommand("run", "Headless haptic session on a scripted trajectory");
  cmd->footer(kRunHelp);
  cmd->add_option("scene", options->scene, "Scene: omitted (empty) or 'demo'");
  cmd->add_option("--trajectory", options->trajectory, "Trajectory CSV (t,x,y,z,qw,qx,qy,qz,grasp)")
      ->required();
  cmd->add_option("--out", options->out, "Result CSV, one row per tick")->required();
  cmd->add_option("--device", options->device, "Device: simulated (default)");
  cmd->add_option("--hand", options->hand,
                  "Hand spring stiffness,damping [N/m,N·s/m] (default 300,20)")
      ->delimiter(',')
      ->expected(2);
  cmd->add_option("--seed", options->seed, "Seed of the simulated device's errors (default 1)");
  cmd->callback([options]() { RunRun(*options); });
}

}  // namespace spidarcad::app
