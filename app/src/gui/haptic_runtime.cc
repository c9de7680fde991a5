// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#include "gui/haptic_runtime.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <stdexcept>
#include <vector>

#include <Eigen/Geometry>

#include "spidarcad/haptics/calibration.h"
#include "spidarcad/haptics/kinematics.h"
#include "spidarcad/haptics/tension.h"

namespace spidarcad::app {

namespace {

// Jig poses and their tension for the start-up calibration of the simulated device.
constexpr int kJigPoses = 24;
constexpr double kJigTension = 1.0;

std::unique_ptr<haptics::SimulatedSpidarG> MakeDevice(const RuntimeSettings& settings) {
  haptics::SimulatedDeviceConfig config = settings.device == RuntimeDevice::kIdeal
                                              ? haptics::SimulatedDeviceConfig::Ideal()
                                              : haptics::SimulatedDeviceConfig{};
  config.seed = settings.seed;
  config.home_pose = haptics::GripPose::Rest(config.geometry.d);
  config.Validate();
  return std::make_unique<haptics::SimulatedSpidarG>(config);
}

// The loop settings with the tension weights scaled for the device's grip.
haptics::LoopSettings LoopSettingsFor(const RuntimeSettings& settings, double d) {
  haptics::LoopSettings loop = settings.loop;
  const haptics::TensionSettings scaled = haptics::TensionSettings::ForPoleLength(d);
  loop.tension.s0 = scaled.s0;
  loop.tension.s1 = scaled.s1;
  return loop;
}

}  // namespace

haptics::TrajectorySample TargetFromPose(const haptics::GripPose& pose) {
  haptics::TrajectorySample sample;
  sample.p_DT = pose.p0;
  sample.q_DT = Eigen::Quaterniond(pose.Rotation()).normalized();
  sample.grasp = pose.Grasp();
  return sample;
}

HapticRuntime::HapticRuntime(const RuntimeSettings& settings,
                             const haptics::GripPose& initial_target)
    : settings_(settings),
      device_(MakeDevice(settings)),
      hand_((settings.hand.Validate(), settings.hand), TargetFromPose(initial_target),
            device_->info().geometry.d),
      targets_(TargetFromPose(initial_target)),
      step_time_(1e-7, 100000),
      runner_(settings.runner) {
  const haptics::DeviceInfo& info = device_->info();
  const haptics::Vector8d home_lengths = haptics::InverseKinematics(info.geometry, info.home_pose);
  const haptics::EncoderCalibration nominal =
      haptics::EncoderCalibration::Nominal(info.encoder, home_lengths);
  calibration_ = nominal;
  char text[200];
  if (settings.device == RuntimeDevice::kIdeal) {
    description_ = "ideal simulated SPIDAR-G (no encoder errors), rigid hand";
  } else {
    const haptics::SpidarGeometry& g = info.geometry;
    const std::vector<haptics::GripPose> jig = haptics::RandomGripPoses(
        g, kJigPoses, 0.5 * std::min({g.a, g.b, g.c}), 0.5, 0.4, /*seed=*/7);
    const haptics::CalibrationResult fit = haptics::FitLinesPerString(
        g, nominal, haptics::GatherKnownSamples(device_.get(), jig, kJigTension));
    if (fit.status == haptics::CalibrationStatus::kOk) {
      calibration_ = fit.calibration;
      std::snprintf(text, sizeof(text),
                    "simulated SPIDAR-G (seed %llu), line-fit calibration on %d jig poses "
                    "(rms %.3f mm), simulated hand %.0f N/m",
                    static_cast<unsigned long long>(settings.seed), kJigPoses,
                    fit.rms_residual * 1e3, settings.hand.stiffness);
    } else {
      std::snprintf(text, sizeof(text),
                    "simulated SPIDAR-G (seed %llu), NOMINAL calibration (line fit failed: %s)",
                    static_cast<unsigned long long>(settings.seed),
                    haptics::CalibrationStatusName(fit.status));
      settings_.loop.fk.max_residual = std::max(settings_.loop.fk.max_residual, 5e-3);
    }
    description_ = text;
  }
  loop_ = std::make_unique<haptics::HapticLoop>(info, calibration_,
                                                LoopSettingsFor(settings_, info.geometry.d));
  // The hand holds the grip at the target; the motors start at the minimum tension.
  device_->SetTruePose(initial_target);
  device_->WriteTensions(haptics::Vector8d::Constant(loop_->settings().tension.tau_min));
  device_->Step(settings_.runner.period);
  RuntimeFrame initial;
  initial.hand_pose = initial_target;
  initial.tool.pose_D = initial_target;
  initial.lengths = haptics::InverseKinematics(info.geometry, initial_target);
  for (int k = 0; k < 3; ++k) frames_.Write(initial);
}

HapticRuntime::~HapticRuntime() { Stop(); }

void HapticRuntime::Start() {
  runner_.Start([this](const haptics::TickTiming& timing) { Tick(timing); });
}

void HapticRuntime::Stop() { runner_.Stop(); }

void HapticRuntime::SetTarget(const haptics::GripPose& target_D) noexcept {
  targets_.Write(TargetFromPose(target_D));
}

void HapticRuntime::Publish(std::unique_ptr<haptics::HapticScene> scene) {
  loop_->Publish(std::move(scene));
}

void HapticRuntime::Tick(const haptics::TickTiming& timing) noexcept {
  const double dt = timing.period;
  const haptics::TrajectorySample& target = targets_.Latest();
  RuntimeFrame& frame = frames_.WriteSlot();
  if (settings_.device == RuntimeDevice::kIdeal) {
    frame.hand_pose = haptics::GripPose::FromFrame(target.p_DT, target.q_DT.toRotationMatrix(),
                                                   target.grasp, device_->info().geometry.d);
  } else {
    hand_.Step(target, device_->TrueWrench(), dt);
    frame.hand_pose = hand_.pose();
  }
  device_->SetTruePose(frame.hand_pose);
  device_->Step(dt);
  haptics::TickInputs inputs;
  device_->Read(&inputs.reading);
  inputs.lateness = timing.lateness;
  const auto start = std::chrono::steady_clock::now();
  frame.tool = loop_->Step(inputs, dt);
  const auto stop = std::chrono::steady_clock::now();
  device_->WriteTensions(frame.tool.tau);
  frame.step_seconds = std::chrono::duration<double>(stop - start).count();
  step_time_.Add(frame.step_seconds);
  frame.lengths = calibration_.Lengths(inputs.reading.counts, frame.tool.tau);
  frames_.Publish();
  ticks_.fetch_add(1, std::memory_order_relaxed);
}

LoopStats CollectLoopStats(const HapticRuntime& runtime, const RuntimeFrame& latest) {
  LoopStats s;
  const haptics::LoopRunner& r = runtime.runner();
  s.realtime = r.realtime_status();
  s.ticks = runtime.ticks();
  s.overruns = r.overruns();
  auto fill = [](const haptics::LatencyHistogram& h, std::array<double, 4>* out) {
    *out = {h.Percentile(0.5), h.Percentile(0.99), h.Percentile(0.999), h.max()};
  };
  fill(runtime.step_time(), &s.step);
  fill(r.compute(), &s.tick);
  fill(r.jitter(), &s.jitter);
  s.events = runtime.loop().event_counts();
  s.emergency_stop = runtime.emergency_stopped();
  s.ramp = latest.tool.ramp;
  return s;
}

std::string FormatLoopSummary(const LoopStats& s) {
  char line[400];
  std::snprintf(line, sizeof(line),
                "loop: %llu ticks, scheduling %s, overruns %llu\n"
                "loop step [us]: p50 %.1f  p99 %.1f  p99.9 %.1f  max %.1f\n"
                "tick incl. simulation [us]: p50 %.1f  p99 %.1f  p99.9 %.1f  max %.1f\n"
                "period jitter [us]: p50 %.1f  p99 %.1f  p99.9 %.1f  max %.1f\n",
                static_cast<unsigned long long>(s.ticks), haptics::RealtimeStatusName(s.realtime),
                static_cast<unsigned long long>(s.overruns), s.step[0] * 1e6, s.step[1] * 1e6,
                s.step[2] * 1e6, s.step[3] * 1e6, s.tick[0] * 1e6, s.tick[1] * 1e6,
                s.tick[2] * 1e6, s.tick[3] * 1e6, s.jitter[0] * 1e6, s.jitter[1] * 1e6,
                s.jitter[2] * 1e6, s.jitter[3] * 1e6);
  std::string out = line;
  out += "safety events [ticks]:";
  for (int i = 0; i < haptics::kNumSafetyEvents; ++i) {
    out += std::string(" ") + haptics::SafetyEventName(i) + "=" + std::to_string(s.events[i]);
  }
  out += s.emergency_stop ? "\nemergency stop: latched\n" : "\nemergency stop: released\n";
  return out;
}

DeviceFrame MakeDeviceFrame(const RuntimeFrame& frame, const haptics::SpidarGeometry& geometry,
                            const std::string& source) {
  DeviceFrame f;
  f.true_pose = frame.hand_pose;
  f.measured_pose = frame.tool.pose_D;
  f.fk_status = frame.tool.fk_status;
  f.lengths = frame.lengths;
  f.tensions = frame.tool.tau;
  f.wrench = frame.tool.wrench_D;
  f.achieved = frame.tool.displayed_D;
  f.tension_status = frame.tool.tension_status;
  f.source = source;
  if (f.fk_status == haptics::FkStatus::kOk) {
    const haptics::Vector8d model = haptics::InverseKinematics(geometry, f.measured_pose);
    f.fk_residual = std::sqrt((model - f.lengths).squaredNorm() / haptics::kNumStrings);
  }
  f.fk_iterations = -1;
  return f;
}

}  // namespace spidarcad::app
