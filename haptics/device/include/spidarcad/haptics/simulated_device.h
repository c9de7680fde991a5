// A simulated SPIDAR-G: a physical model of the strings, encoders and motors, not a stub.
//
// Sensing: true grip pose (set by a simulated hand or the app's mouse) -> true string lengths
// (InverseKinematics) -> the paid-out string is shorter than the geometric length by the
// stretch under the actual tension -> an imperfect encoder (per-string gain, winding
// nonlinearity and offset errors, seeded Gaussian length noise, quantisation to whole counts,
// counters zeroed at a homing pose that the jig only approximately reproduces) -> counts.
// Actuation: commanded tensions -> clamp to [0, tension_max] (motor current / torque
// saturation; strings cannot push) -> first-order motor lag -> actual tensions -> wrench on the
// grip A(true pose) τ (WrenchMatrix at the TRUE pose).
// Time advances only through Step(dt), so a virtual clock drives it deterministically.
// The hidden truth (true encoder parameters, true homing pose) is exposed for tests and for
// evaluating calibrations; the haptic loop must only use the Device interface.
// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#pragma once

#include <cstdint>

#include "spidarcad/haptics/device.h"
#include "spidarcad/haptics/encoder.h"
#include "spidarcad/haptics/geometry.h"

namespace spidarcad::haptics {

// Imperfections and dynamics of the simulated device. Defaults are modelled on the paper's
// device (Sec. 6): 48 cm frame, 4 cm grip, 2000 counts/rev on 8 mm pulleys, and a per-string
// length-per-count error of 6.24 ± 1.54 % (the paper's uncalibrated error, read as the scale
// error of "length per pulse times counter"; string thickness makes the effective pulley
// radius larger than nominal).
struct SimulatedDeviceConfig {
  SpidarGeometry geometry;                    // frame and grip size, m
  EncoderSpec encoder;                        // nominal encoder (what the software assumes)
  GripPose home_pose = GripPose::Rest(0.04);  // nominal homing pose (the jig's), in D

  // Encoder imperfections, drawn once per string from `seed` at construction.
  double gain_error_mean = 0.0624;    // mean of (gain − 1): effective radius error
  double gain_error_sd = 0.0154;      // standard deviation of (gain − 1)
  double quadratic_sd = 0.05;         // winding nonlinearity sd, 1/m (3 mm at 0.25 m paid out)
  double stretch = 4e-4;              // string compliance, strain per N (0.32 % at 8 N)
  double stretch_sd = 1e-4;           // spread of the compliance between strings, 1/N
  double homing_position_sd = 3e-4;   // jig error of the true homing position, per axis, m
  double homing_rotation_sd = 0.003;  // jig error of the true homing rotation, per axis, rad
  double length_noise_sd = 1e-5;      // per-sample length noise before quantisation, m

  // Motors.
  double tension_max = 8.0;              // N; current / torque saturation at the pulley
  double tension_time_constant = 0.002;  // s; first-order lag of the motor (0: none)
  double homing_tension = 0.5;           // N; pretension while the counters are zeroed
  double slack_threshold = 0.05;         // N; commanded tension below this flags slack

  std::uint64_t seed = 1;  // seeds every random draw (parameters and noise)

  // A perfect device: no encoder errors, no noise, no jig error, no stretch (quantisation
  // and motor limits remain). Useful as a reference in tests.
  static SimulatedDeviceConfig Ideal();
  // Throws std::invalid_argument naming the field when a setting is out of range.
  void Validate() const;
};

// The simulated SPIDAR-G. Read/WriteTensions/Step/SetTruePose are noexcept and allocate nothing.
class SimulatedSpidarG final : public Device {
 public:
  // Draws the hidden parameters from config.seed, homes the device (grip at the true homing
  // pose under homing_tension, counters zeroed) and takes the first sample. Throws
  // std::invalid_argument on a bad config.
  explicit SimulatedSpidarG(const SimulatedDeviceConfig& config = {});

  const DeviceInfo& info() const noexcept override { return info_; }
  DeviceStatus Read(EncoderReading* reading) noexcept override;
  DeviceStatus WriteTensions(const Vector8d& tension) noexcept override;
  DeviceStatus status() const noexcept override { return status_; }

  // Moves the grip (the hand holding it) to `pose` in D. Takes effect at the next Step.
  void SetTruePose(const GripPose& pose) noexcept { true_pose_ = pose; }
  // Advances time by dt (s): motor lag, then a new encoder sample (sequence + 1).
  void Step(double dt) noexcept;
  // Injects a device state (fault, unplug, e-stop); kOk clears it.
  void SetStatus(DeviceStatus status) noexcept { status_ = status; }

  // Current true grip pose in D.
  const GripPose& true_pose() const noexcept { return true_pose_; }
  // True geometric string lengths at the current true pose, m.
  Vector8d TrueLengths() const noexcept;
  // Tensions the motors currently apply, N.
  const Vector8d& actual_tensions() const noexcept { return actual_tension_; }
  // Tensions last commanded (after NaN -> 0), N.
  const Vector8d& commanded_tensions() const noexcept { return commanded_tension_; }
  // Wrench on the grip A(true pose) · actual tensions: (f [N], m about p0 [N·m], grasp [N·m]).
  Vector7d TrueWrench() const noexcept;
  // Simulated time, s.
  double time() const noexcept { return time_; }

  // Hidden truth: the true count -> length map of every string (same model as encoder.h).
  const EncoderCalibration& true_encoder() const noexcept { return true_encoder_; }
  // Hidden truth: the pose at which the counters were actually zeroed.
  const GripPose& true_home_pose() const noexcept { return true_home_pose_; }
  const SimulatedDeviceConfig& config() const noexcept { return config_; }

 private:
  double Normal() noexcept;
  void Sample() noexcept;

  SimulatedDeviceConfig config_;
  DeviceInfo info_;
  EncoderCalibration true_encoder_;
  GripPose true_home_pose_;
  GripPose true_pose_;
  Vector8d commanded_tension_ = Vector8d::Zero();
  Vector8d actual_tension_ = Vector8d::Zero();
  EncoderReading reading_;
  DeviceStatus status_ = DeviceStatus::kOk;
  double time_ = 0.0;
  std::uint64_t rng_state_ = 0;
  double spare_normal_ = 0.0;
  bool has_spare_normal_ = false;
};

}  // namespace spidarcad::haptics
