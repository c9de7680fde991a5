// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
// The haptic tick (ARCHITECTURE.md): encoder counts -> calibration -> forward kinematics ->
// tool pose in W (X_WD) -> force fields of the scene -> damping / passivity -> wrench q (7) in D
// -> safety -> tension solve -> tensions out. HapticLoop::Step is a pure step function of its
// inputs and its own state: the same sequence of inputs gives bit-identical outputs, whether a
// real-time thread (loop_runner.h) or a virtual clock (the headless runner) calls it. Step
// allocates nothing, takes no lock, does no I/O and throws nothing.
//
// Scene exchange: the app builds an immutable HapticScene and hands it over with
// HapticLoop::Publish, through a Handover (handover.h: three atomic raw pointers; the haptic
// thread takes the newest scene at the start of a tick and hands the previous one back, and the
// app frees it in Publish / CollectRetired, so no destructor ever runs on the haptic thread; a
// scene published twice before the haptic thread picked the first one up replaces it).
// ToolState goes the other way through a lock-free TripleBuffer.
#pragma once

#include <array>
#include <atomic>
#include <cstdint>
#include <memory>
#include <vector>

#include "spidarcad/haptics/device.h"
#include "spidarcad/haptics/device_to_world.h"
#include "spidarcad/haptics/encoder.h"
#include "spidarcad/haptics/force_field.h"
#include "spidarcad/haptics/handover.h"
#include "spidarcad/haptics/kinematics.h"
#include "spidarcad/haptics/tension.h"
#include "spidarcad/haptics/triple_buffer.h"

namespace spidarcad::haptics {

// An immutable set of force fields, built on the app side and then published to the loop.
class HapticScene {
 public:
  HapticScene() = default;
  // Adds a field (before publishing only).
  void Add(std::unique_ptr<ForceField> field) { fields_.push_back(std::move(field)); }
  // Number of fields.
  int size() const noexcept { return static_cast<int>(fields_.size()); }
  // Sum of every field's wrench at `tool`, in W (real-time safe).
  ToolWrench Evaluate(const ToolKinematics& tool) const noexcept;

 private:
  std::vector<std::unique_ptr<ForceField>> fields_;
};

// The demo scene of `spidarcad run demo`: a floor wall (plane z = −0.03 m, normal +z,
// 2000 N/m, 5 N·s/m) and a weak spring (20 N/m, 0.5 N·s/m) toward (0.05, 0, 0) m. In W with the
// default X_WD (identity), i.e. device coordinates.
std::unique_ptr<HapticScene> MakeDemoScene();

// Safety events, as bits of TickOutputs::events. Ticks with each event are counted in
// HapticLoop::event_counts().
enum SafetyEvent : std::uint32_t {
  kEventNan = 1u << 0,               // NaN/inf in the lengths, pose or field wrench: zero force
  kEventFkRefused = 1u << 1,         // forward kinematics refused the reading: zero force
  kEventDeviceError = 1u << 2,       // device status not ok: zero force
  kEventDeadlineMissed = 1u << 3,    // tick later than LoopSettings::max_lateness: zero force
  kEventEmergencyStop = 1u << 4,     // the stop flag is set (latched): zero force
  kEventBadDt = 1u << 5,             // dt not finite or outside (0, max_dt]: zero force
  kEventWrenchLimited = 1u << 6,     // the requested wrench was scaled down to the limits
  kEventTensionSaturated = 1u << 7,  // the tension solve could not display all of q
  kEventRamping = 1u << 8,           // the force ramp is below 1
  kEventEnergyLimited = 1u << 9,     // the passivity observer added damping
  kEventSlack = 1u << 10,            // the device flagged a slack string
};
// Number of SafetyEvent kinds.
inline constexpr int kNumSafetyEvents = 11;
// One word for event bit `index` (0 .. kNumSafetyEvents−1): "nan", "fk_refused", ...
const char* SafetyEventName(int index);
// True when `events` contains one of the events that force zero force.
constexpr bool IsZeroForceEvent(std::uint32_t events) {
  return (events & (kEventNan | kEventFkRefused | kEventDeviceError | kEventDeadlineMissed |
                    kEventEmergencyStop | kEventBadDt)) != 0;
}

// Settings of the loop. Units SI.
struct LoopSettings {
  // X_WD (device_to_world.h): the grip's pose and velocity in D reach the fields in W as
  // p_WT = s·p0 + p_WDo, v_WT = s·v_D, R_WT = R_DT, ω_WT = ω_D.
  DeviceToWorld X_WD;
  // A world force f_W is displayed as force_scale · f_W in D, moments likewise; the grasp torque
  // as is.
  double force_scale = 1.0;
  // Cut-off of the first-order low-pass on finite-difference velocities, Hz.
  double velocity_cutoff = 100.0;
  // Viscous damping on the grip in D (always on, dissipative): N·s/m, N·m·s/rad, N·m·s/rad.
  double linear_damping = 0.0;
  double angular_damping = 0.0;
  double grasp_damping = 0.0;
  // Wrench limits in D: |f| [N], |m| [N·m], |g| [N·m]. The wrench is scaled down to meet them.
  double max_force = 10.0;
  double max_moment = 0.3;
  double max_grasp_torque = 0.3;
  // Force ramp: after start and after every zero-force event the output ramps from 0 to 1
  // linearly over this time, s.
  double ramp_time = 0.5;
  // A tick later than this (TickInputs::lateness, s) commands zero force.
  double max_lateness = 3e-3;
  // dt above this (s) is treated as a fault (zero force for the tick).
  double max_dt = 0.05;
  // Passivity observer on the translational port (Hannaford-Ryu): the energy the scene has
  // absorbed from the user, E = Σ −f·v dt, must not go negative; when it would, damping
  // α = −E / (|v|² dt) is added for the tick, at most max_observer_damping (so velocity noise
  // at rest cannot produce large forces; the unremoved deficit stays in E for later ticks).
  bool passivity_observer = true;
  double max_observer_damping = 50.0;  // N·s/m
  // FK and tension settings (tau bounds are clamped to the device's range at construction).
  FkSettings fk;
  TensionSettings tension;
  // Throws std::invalid_argument naming the field when a setting is out of range.
  void Validate() const;
};

// What the loop publishes for the app each tick (triple buffer) and returns from Step.
struct ToolState {
  std::uint64_t tick = 0;                   // ticks since start
  double time = 0.0;                        // loop time, s (sum of dt)
  GripPose pose_D;                          // measured grip pose in D (FK)
  ToolKinematics tool_W;                    // tool state in W as fed to the fields
  Vector7d wrench_D = Vector7d::Zero();     // q commanded (after safety), D
  Vector7d displayed_D = Vector7d::Zero();  // A τ, what the strings display
  Vector8d tau = Vector8d::Zero();          // tensions sent to the device, N
  std::uint32_t events = 0;                 // SafetyEvent bits of this tick
  double ramp = 0.0;                        // force ramp factor in [0, 1]
  double energy = 0.0;                      // passivity observer energy, J
  FkStatus fk_status = FkStatus::kInvalidInput;
  TensionStatus tension_status = TensionStatus::kInvalidInput;
};

// Inputs of one tick.
struct TickInputs {
  EncoderReading reading;       // the device sample of this tick (status included)
  double lateness = 0.0;        // how late the tick started against its schedule, s
  bool emergency_stop = false;  // a stop request from the caller (ORed with the loop flag)
};

// Outputs of one tick (τ goes to Device::WriteTensions).
using TickOutputs = ToolState;

// The haptic loop. Construct on the app side; Step on the haptic thread only.
class HapticLoop {
 public:
  // `info` is the device's description, `calibration` its count -> length map. Throws
  // std::invalid_argument on bad settings.
  HapticLoop(const DeviceInfo& info, const EncoderCalibration& calibration,
             const LoopSettings& settings = {});
  ~HapticLoop();
  HapticLoop(const HapticLoop&) = delete;
  HapticLoop& operator=(const HapticLoop&) = delete;

  // One tick of length dt (s). Real-time safe. See the file comment for the chain.
  TickOutputs Step(const TickInputs& inputs, double dt) noexcept;

  // App side: hands `scene` to the loop (taken at the start of the next tick) and frees any
  // scene the haptic thread has retired. Not real-time; never call from the haptic thread.
  void Publish(std::unique_ptr<HapticScene> scene);
  // App side: frees the scene the haptic thread retired, if any. Returns true if one was freed.
  bool CollectRetired();

  // Any thread: latches the emergency stop (zero force until ClearEmergencyStop).
  void RequestEmergencyStop() noexcept { stop_.store(true, std::memory_order_release); }
  // Any thread: releases the stop; forces come back through the ramp.
  void ClearEmergencyStop() noexcept { stop_.store(false, std::memory_order_release); }
  bool emergency_stop() const noexcept { return stop_.load(std::memory_order_acquire); }

  // App side: the latest ToolState (lock-free; one reader thread).
  const ToolState& LatestToolState() noexcept { return tool_state_.Latest(); }
  // Ticks (since construction) in which each SafetyEvent occurred, indexed by bit number.
  // Written by the haptic thread; read it when the loop is stopped or accept torn counts.
  const std::array<std::uint64_t, kNumSafetyEvents>& event_counts() const noexcept {
    return event_counts_;
  }
  const LoopSettings& settings() const noexcept { return settings_; }
  const DeviceInfo& info() const noexcept { return info_; }

 private:
  void ZeroForce(ToolState* out) noexcept;

  DeviceInfo info_;
  EncoderCalibration calibration_;
  LoopSettings settings_;
  ForwardKinematics fk_;
  TensionSolver solver_;

  Handover<HapticScene> scenes_;
  std::atomic<bool> stop_{false};

  // Haptic-thread state.
  std::uint64_t tick_ = 0;
  double time_ = 0.0;
  Vector8d last_tau_;
  bool has_previous_ = false;
  GripPose previous_pose_;
  Eigen::Vector3d v_D_ = Eigen::Vector3d::Zero();
  Eigen::Vector3d w_D_ = Eigen::Vector3d::Zero();
  double grasp_rate_ = 0.0;
  double ramp_ = 0.0;
  double energy_ = 0.0;
  std::array<std::uint64_t, kNumSafetyEvents> event_counts_{};
  TripleBuffer<ToolState> tool_state_;
};

}  // namespace spidarcad::haptics
