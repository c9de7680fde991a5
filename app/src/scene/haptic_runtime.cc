// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#include "scene/haptic_runtime.h"

#include <Eigen/Geometry>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

#include "doc/input_error.h"
#include "scene/calibration_collector.h"
#include "scene/calibration_file.h"
#include "spidarcad/haptics/kinematics.h"
#include "spidarcad/haptics/realtime_memory.h"
#include "spidarcad/haptics/tension.h"

namespace spidarcad::app {

namespace {

// The device rig of `settings.device`.
std::unique_ptr<DeviceRig> MakeRig(const RuntimeSettings& settings) {
  RigOptions options;
  options.device = settings.device == RuntimeDevice::kIdeal
                       ? haptics::SimulatedDeviceConfig::Ideal()
                       : haptics::SimulatedDeviceConfig{};
  options.device.seed = settings.seed;
  options.device.geometry = settings.geometry;
  options.device.home_pose = haptics::GripPose::Rest(options.device.geometry.d);
  options.device.Validate();
  options.usb = settings.usb;
  // The tick must not open libusb (it allocates): a lost board is re-opened off the tick.
  options.reconnect_off_tick = true;
  options.make_transport = settings.usb_transport;
  switch (settings.device) {
    case RuntimeDevice::kBoardSim:
      return MakeDeviceRig(RigKind::kBoardSim, options);
    case RuntimeDevice::kUsb:
      return MakeDeviceRig(RigKind::kUsb, options);
    case RuntimeDevice::kSimulated:
    case RuntimeDevice::kIdeal:
      break;
  }
  return MakeDeviceRig(RigKind::kSimulated, options);
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

bool ParseRuntimeDevice(const std::string& name, RuntimeDevice* device) {
  // The names of `run`'s rigs (ParseRigKind) plus the window's "ideal".
  if (name == "ideal") {
    *device = RuntimeDevice::kIdeal;
    return true;
  }
  RigKind kind = RigKind::kSimulated;
  if (!ParseRigKind(name, &kind)) return false;
  *device = kind == RigKind::kBoardSim ? RuntimeDevice::kBoardSim
            : kind == RigKind::kUsb    ? RuntimeDevice::kUsb
                                       : RuntimeDevice::kSimulated;
  return true;
}

const char* RuntimeDeviceName(RuntimeDevice device) {
  switch (device) {
    case RuntimeDevice::kSimulated:
      return "simulated";
    case RuntimeDevice::kIdeal:
      return "ideal";
    case RuntimeDevice::kBoardSim:
      return "board-sim";
    case RuntimeDevice::kUsb:
      return "usb";
  }
  return "unknown";
}

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
      rig_(MakeRig(settings)),
      device_(rig_->physical()),
      hand_((settings.hand.Validate(), settings.hand), TargetFromPose(initial_target),
            rig_->info().geometry.d),
      targets_(TargetFromPose(initial_target)),
      step_time_(1e-7, 100000),
      runner_(settings.runner),
      last_measured_(initial_target) {
  const haptics::DeviceInfo& info = rig_->info();
  calibration_ = NominalCalibration(info);
  if (settings.device == RuntimeDevice::kIdeal && !settings.calibration_file.empty()) {
    throw InputError(
        "--calibration: not with --device ideal (the ideal device has no encoder "
        "errors to calibrate); use --device simulated, board-sim or usb");
  }
  // A calibration file replaces the start-up fit (kSimulated) and the nominal model (kBoardSim);
  // kUsb applies it after the handshake, which reports the board's serial number.
  const bool file_applied = settings.device != RuntimeDevice::kUsb &&
                            settings.device != RuntimeDevice::kIdeal &&
                            ApplyCalibrationFile(info, "");
  char text[240];
  if (file_applied) {
    // description_ was set by ApplyCalibrationFile.
  } else if (settings.device == RuntimeDevice::kIdeal) {
    description_ = "ideal simulated SPIDAR-G (no encoder errors), rigid hand";
  } else if (settings.device == RuntimeDevice::kBoardSim ||
             settings.device == RuntimeDevice::kUsb) {
    // What `spidarcad run` uses on these paths: the nominal calibration, so FK accepts
    // millimetre residuals.
    settings_.loop.fk.max_residual =
        std::max(settings_.loop.fk.max_residual, kNominalFkMaxResidual);
    if (settings.device == RuntimeDevice::kBoardSim) {
      std::snprintf(text, sizeof(text),
                    "board-sim: USB driver over the board simulator (simulated SPIDAR-G, seed "
                    "%llu), nominal calibration, simulated hand %.0f N/m",
                    static_cast<unsigned long long>(settings.seed), settings.hand.stiffness);
    } else {
      std::snprintf(text, sizeof(text),
                    "usb: SPIDAR-G controller board over %s, nominal geometry and calibration",
                    settings.usb_transport ? "a test transport" : "libusb");
    }
    description_ = text;
  } else {
    // The start-up calibration (device_rig.h), shared with `spidarcad run --calibrate`.
    const SimulatedCalibration fit = CalibrateSimulated(device_);
    calibration_ = fit.calibration;
    if (fit.ok) {
      std::snprintf(text, sizeof(text),
                    "simulated SPIDAR-G (seed %llu), %s, simulated hand %.0f N/m",
                    static_cast<unsigned long long>(settings.seed), fit.description.c_str(),
                    settings.hand.stiffness);
    } else {
      std::snprintf(text, sizeof(text), "simulated SPIDAR-G (seed %llu), %s",
                    static_cast<unsigned long long>(settings.seed), fit.description.c_str());
      settings_.loop.fk.max_residual =
          std::max(settings_.loop.fk.max_residual, kNominalFkMaxResidual);
    }
    description_ = text;
  }
  loop_ = std::make_unique<haptics::HapticLoop>(info, calibration_,
                                                LoopSettingsFor(settings_, info.geometry.d));
  if (settings.device == RuntimeDevice::kSimulated || settings.device == RuntimeDevice::kIdeal) {
    // The hand holds the grip at the target; the motors start at the minimum tension.
    device_->SetTruePose(initial_target);
    device_->WriteTensions(haptics::Vector8d::Constant(loop_->settings().tension.tau_min));
    device_->Step(settings_.runner.period);
  } else if (!rig_->Start(initial_target)) {
    // No board (yet): the window runs at zero force and the link is retried.
    link_at_start_ = rig_->StartFailure();
    if (settings.device == RuntimeDevice::kUsb && !settings.calibration_file.empty()) {
      throw InputError("--calibration: " + settings.calibration_file +
                       ": the board must answer at start to check that the file is its own (" +
                       link_at_start_ + ")");
    }
  } else {
    serial_ = rig_->Serial();
    if (settings.device == RuntimeDevice::kUsb && ApplyCalibrationFile(info, serial_)) {
      // The loop has not run yet: rebuild it to read the board through the file.
      loop_ = std::make_unique<haptics::HapticLoop>(info, calibration_,
                                                    LoopSettingsFor(settings_, info.geometry.d));
    }
  }
  // Self-calibration sessions: the schedule and the ring, allocated here, off the tick.
  calibration_schedule_ = CalibrationTensionSchedule(info, kCalibrationHolds, settings.seed);
  calibration_ticks_per_hold_ =
      std::max(1, static_cast<int>(std::lround(kCalibrationHoldSeconds / settings_.runner.period)));
  calibration_ring_ = std::make_unique<CalibrationReading[]>(kCalibrationRingSize);
  RuntimeFrame initial;
  initial.hand_pose = initial_target;
  initial.tool.pose_D = initial_target;
  initial.lengths = haptics::InverseKinematics(info.geometry, initial_target);
  rig_->Link(&initial.link);
  for (int k = 0; k < 3; ++k) frames_.Write(initial);
}

HapticRuntime::~HapticRuntime() { Stop(); }

std::string HapticRuntime::serial() const { return rig_ != nullptr ? rig_->Serial() : serial_; }

bool HapticRuntime::ApplyCalibrationFile(const haptics::DeviceInfo& info,
                                         const std::string& serial) {
  CalibrationDevice device;
  device.kind = RuntimeDeviceName(settings_.device);
  device.seed = settings_.seed;
  device.serial = serial;
  device.geometry = info.geometry;
  device.encoder = info.encoder;
  std::string path = settings_.calibration_file;
  const bool remembered = path.empty();
  if (remembered) {
    if (settings_.device != RuntimeDevice::kUsb || !settings_.use_remembered_calibration) {
      return false;
    }
    path = RememberedCalibration(device);
    if (path.empty()) return false;
  }
  CalibrationFile file;
  std::string why;
  try {
    file = LoadCalibrationFile(path);
  } catch (const InputError& e) {
    // A remembered file that went missing or bad is not an error: the nominal model is used.
    if (!remembered) throw InputError(std::string("--calibration: ") + e.what());
    calibration_note_ = "remembered calibration not used: " + std::string(e.what());
    return false;
  }
  why = CalibrationMismatch(file, device);
  if (!why.empty()) {
    if (!remembered) throw InputError("--calibration: " + path + " does not fit: " + why);
    calibration_note_ = "remembered calibration " + path + " not used: " + why;
    return false;
  }
  calibration_ = file.calibration;
  // Calibrated: FK's default acceptance, as after the start-up fit.
  settings_.loop.fk.max_residual = haptics::FkSettings().max_residual;
  description_ = std::string(RuntimeDeviceName(settings_.device)) + ": " + device.Describe() +
                 ", " + (file.method == "self" ? "self-calibration" : "line-fit calibration") +
                 " " + path + (remembered ? " (remembered for this board)" : "") + " of " +
                 file.date;
  return true;
}

void HapticRuntime::Start() {
  // Before the first tick, once per process: the pages the tick touches stay in RAM, and the
  // allocations made later (scenes published while running) are faulted in by whoever makes
  // them, not by the haptic thread (realtime_memory.h). One line on stderr when that is not
  // possible; the runner then touches its stack (RunnerSettings::prefault_stack_bytes).
  static const haptics::MemoryLockResult lock = [] {
    haptics::MemoryLockResult r = haptics::LockProcessMemory();
    if (r.status != haptics::MemoryLockStatus::kLocked)
      std::fprintf(stderr, "%s\n", r.message.c_str());
    return r;
  }();
  (void)lock;
  runner_.Start([this](const haptics::TickTiming& timing) { Tick(timing); });
  // Created here, on the main thread: threads inherit SCHED_FIFO from a real-time creator.
  if (!service_) service_ = std::make_unique<RigServiceThread>(rig_.get());
}

void HapticRuntime::Stop() {
  runner_.Stop();
  service_.reset();
}

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
  if (device_ != nullptr) {
    if (settings_.device == RuntimeDevice::kIdeal) {
      frame.hand_pose = haptics::GripPose::FromFrame(target.p_DT, target.q_DT.toRotationMatrix(),
                                                     target.grasp, rig_->info().geometry.d);
    } else {
      hand_.Step(target, device_->TrueWrench(), dt);
      frame.hand_pose = hand_.pose();
    }
    device_->SetTruePose(frame.hand_pose);
  }
  haptics::TickInputs inputs;
  rig_->Read(dt, &inputs.reading);
  inputs.lateness = timing.lateness;
  const auto start = std::chrono::steady_clock::now();
  frame.tool = loop_->Step(inputs, dt);
  const auto stop = std::chrono::steady_clock::now();
  if (calibration_on_.load(std::memory_order_acquire) &&
      inputs.reading.status == haptics::DeviceStatus::kOk &&
      !haptics::IsZeroForceEvent(frame.tool.events) && frame.tool.ramp >= 1.0) {
    // A self-calibration session: the schedule's tensions instead of the loop's.
    if (calibration_hold_ticks_ >= calibration_ticks_per_hold_) {
      calibration_hold_ = (calibration_hold_ + 1) % kCalibrationHolds;
      calibration_hold_ticks_ = 0;
    }
    frame.tool.tau = calibration_schedule_[static_cast<std::size_t>(calibration_hold_)];
    const std::uint64_t written = ring_written_.load(std::memory_order_relaxed);
    if (written - ring_read_.load(std::memory_order_acquire) <
        static_cast<std::uint64_t>(kCalibrationRingSize)) {
      CalibrationReading& slot = calibration_ring_[written % kCalibrationRingSize];
      slot.reading = inputs.reading;
      slot.tension = frame.tool.tau;
      slot.held = calibration_hold_ticks_ * dt;
      ring_written_.store(written + 1, std::memory_order_release);
    } else {
      ring_dropped_.fetch_add(1, std::memory_order_relaxed);
    }
    ++calibration_hold_ticks_;
  } else {
    calibration_hold_ticks_ = 0;  // the next session tick starts its hold again
  }
  rig_->Write(frame.tool.tau);
  if (device_ == nullptr) {
    // A real board: the user's hand is where the encoders say (the last pose FK accepted).
    if (frame.tool.fk_status == haptics::FkStatus::kOk &&
        inputs.reading.status == haptics::DeviceStatus::kOk) {
      last_measured_ = frame.tool.pose_D;
    }
    frame.hand_pose = last_measured_;
  }
  rig_->Link(&frame.link);
  frame.step_seconds = std::chrono::duration<double>(stop - start).count();
  step_time_.Add(frame.step_seconds);
  frame.lengths = calibration_.Lengths(inputs.reading.counts, frame.tool.tau);
  frames_.Publish();
  ticks_.fetch_add(1, std::memory_order_relaxed);
}

long HapticRuntime::TakeCalibrationReadings(std::vector<CalibrationReading>* out) {
  const std::uint64_t written = ring_written_.load(std::memory_order_acquire);
  std::uint64_t read = ring_read_.load(std::memory_order_relaxed);
  for (; read < written; ++read) out->push_back(calibration_ring_[read % kCalibrationRingSize]);
  ring_read_.store(read, std::memory_order_release);
  const std::uint64_t dropped = ring_dropped_.load(std::memory_order_relaxed);
  const long lost = static_cast<long>(dropped - ring_dropped_reported_);
  ring_dropped_reported_ = dropped;
  return lost;
}

void HapticRuntime::UseCalibration(const haptics::EncoderCalibration& calibration,
                                   const std::string& description) {
  calibration.Validate();  // throws before anything changes
  const haptics::DeviceInfo& info = rig_->info();
  haptics::LoopSettings loop_settings;
  {
    RuntimeSettings calibrated = settings_;
    // Calibrated: FK's default acceptance, as after the start-up fit or a calibration file.
    calibrated.loop.fk.max_residual = haptics::FkSettings().max_residual;
    loop_settings = LoopSettingsFor(calibrated, info.geometry.d);
  }
  auto loop = std::make_unique<haptics::HapticLoop>(info, calibration, loop_settings);
  const bool running = runner_.running();
  runner_.Stop();  // between two ticks
  if (loop_->emergency_stop()) loop->RequestEmergencyStop();
  loop_ = std::move(loop);
  calibration_ = calibration;
  settings_.loop.fk.max_residual = haptics::FkSettings().max_residual;
  description_ = description;
  calibration_note_.clear();
  if (running) runner_.Start([this](const haptics::TickTiming& timing) { Tick(timing); });
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
  s.link = latest.link;
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
                s.step[2] * 1e6, s.step[3] * 1e6, s.tick[0] * 1e6, s.tick[1] * 1e6, s.tick[2] * 1e6,
                s.tick[3] * 1e6, s.jitter[0] * 1e6, s.jitter[1] * 1e6, s.jitter[2] * 1e6,
                s.jitter[3] * 1e6);
  std::string out = line;
  out += "safety events [ticks]:";
  for (int i = 0; i < haptics::kNumSafetyEvents; ++i) {
    out += std::string(" ") + haptics::SafetyEventName(i) + "=" + std::to_string(s.events[i]);
  }
  out += s.emergency_stop ? "\nemergency stop: latched\n" : "\nemergency stop: released\n";
  if (s.link.has_driver) out += "device link: " + DescribeLink(s.link) + "\n";
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
