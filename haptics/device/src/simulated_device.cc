// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#include "spidarcad/haptics/simulated_device.h"

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <numbers>
#include <stdexcept>
#include <string>

#include "spidarcad/haptics/kinematics.h"
#include "spidarcad/haptics/tension.h"

namespace spidarcad::haptics {

namespace {

void CheckNonNegative(double v, const char* name) {
  if (!std::isfinite(v) || v < 0.0) {
    throw std::invalid_argument(std::string("SimulatedDeviceConfig: field '") + name +
                                "' must be finite and non-negative, got " + std::to_string(v));
  }
}

// SplitMix64: a small, portable generator, so that a seed gives the same numbers with every
// standard library (std::normal_distribution's algorithm is implementation-defined).
std::uint64_t NextRandom(std::uint64_t* state) noexcept {
  std::uint64_t z = (*state += 0x9E3779B97F4A7C15ULL);
  z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ULL;
  z = (z ^ (z >> 27)) * 0x94D049BB133111EBULL;
  return z ^ (z >> 31);
}

// Uniform in (0, 1].
double Uniform(std::uint64_t* state) noexcept {
  return (static_cast<double>(NextRandom(state) >> 11) + 1.0) * 0x1.0p-53;
}

}  // namespace

SimulatedDeviceConfig SimulatedDeviceConfig::Ideal() {
  SimulatedDeviceConfig config;
  config.gain_error_mean = 0.0;
  config.gain_error_sd = 0.0;
  config.quadratic_sd = 0.0;
  config.stretch = 0.0;
  config.stretch_sd = 0.0;
  config.homing_position_sd = 0.0;
  config.homing_rotation_sd = 0.0;
  config.length_noise_sd = 0.0;
  return config;
}

void SimulatedDeviceConfig::Validate() const {
  geometry.Validate();
  encoder.Validate();
  const double d = geometry.d;
  if (std::abs(home_pose.p1.norm() - d) > 1e-9 * std::max(1.0, d) ||
      std::abs(home_pose.p2.norm() - d) > 1e-9 * std::max(1.0, d)) {
    throw std::invalid_argument(
        "SimulatedDeviceConfig: field 'home_pose' must have |p1| = |p2| = geometry.d = " +
        std::to_string(d) + " m");
  }
  if (!std::isfinite(gain_error_mean) || gain_error_mean <= -0.5) {
    throw std::invalid_argument(
        "SimulatedDeviceConfig: field 'gain_error_mean' must be finite and above -0.5, got " +
        std::to_string(gain_error_mean));
  }
  CheckNonNegative(gain_error_sd, "gain_error_sd");
  CheckNonNegative(quadratic_sd, "quadratic_sd");
  CheckNonNegative(stretch, "stretch");
  CheckNonNegative(stretch_sd, "stretch_sd");
  CheckNonNegative(homing_position_sd, "homing_position_sd");
  CheckNonNegative(homing_rotation_sd, "homing_rotation_sd");
  CheckNonNegative(length_noise_sd, "length_noise_sd");
  CheckNonNegative(tension_time_constant, "tension_time_constant");
  CheckNonNegative(homing_tension, "homing_tension");
  CheckNonNegative(slack_threshold, "slack_threshold");
  if (!std::isfinite(tension_max) || tension_max <= 0.0) {
    throw std::invalid_argument(
        "SimulatedDeviceConfig: field 'tension_max' must be finite and positive, got " +
        std::to_string(tension_max));
  }
}

SimulatedSpidarG::SimulatedSpidarG(const SimulatedDeviceConfig& config) : config_(config) {
  config_.Validate();
  rng_state_ = config_.seed;

  info_.geometry = config_.geometry;
  info_.encoder = config_.encoder;
  info_.home_pose = config_.home_pose;
  info_.tension_min = 0.0;
  info_.tension_max = config_.tension_max;

  // The jig puts the grip near, not exactly at, the nominal homing pose.
  const Eigen::Vector3d dp(Normal(), Normal(), Normal());
  const Eigen::Vector3d dw(Normal(), Normal(), Normal());
  const Eigen::Matrix3d R_err =
      dw.norm() > 0.0 && config_.homing_rotation_sd > 0.0
          ? Eigen::AngleAxisd(config_.homing_rotation_sd * dw.norm(), dw.normalized())
                .toRotationMatrix()
          : Eigen::Matrix3d::Identity();
  const GripPose& home = config_.home_pose;
  true_home_pose_.p0 = home.p0 + config_.homing_position_sd * dp;
  true_home_pose_.p1 = R_err * home.p1;
  true_home_pose_.p2 = R_err * home.p2;

  // Per-string encoder truth; the offset makes the counters read zero at the true homing pose
  // under the homing pretension.
  const Vector8d home_lengths = InverseKinematics(config_.geometry, true_home_pose_);
  true_encoder_.spec = config_.encoder;
  for (int i = 0; i < kNumStrings; ++i) {
    StringEncoderParams& p = true_encoder_.strings[i];
    p.gain = 1.0 + config_.gain_error_mean + config_.gain_error_sd * Normal();
    p.quadratic = config_.quadratic_sd * Normal();
    p.stretch = std::max(0.0, config_.stretch + config_.stretch_sd * Normal());
    p.offset = home_lengths[i] / (1.0 + p.stretch * config_.homing_tension);
  }

  true_pose_ = true_home_pose_;
  commanded_tension_.setConstant(config_.homing_tension);
  actual_tension_ = commanded_tension_;
  reading_.sequence = 0;
  Sample();
}

double SimulatedSpidarG::Normal() noexcept {
  // Box-Muller, keeping the second variate.
  if (has_spare_normal_) {
    has_spare_normal_ = false;
    return spare_normal_;
  }
  const double u1 = Uniform(&rng_state_);
  const double u2 = Uniform(&rng_state_);
  const double radius = std::sqrt(-2.0 * std::log(u1));
  const double angle = 2.0 * std::numbers::pi * u2;
  spare_normal_ = radius * std::sin(angle);
  has_spare_normal_ = true;
  return radius * std::cos(angle);
}

Vector8d SimulatedSpidarG::TrueLengths() const noexcept {
  return InverseKinematics(config_.geometry, true_pose_);
}

void SimulatedSpidarG::Sample() noexcept {
  const Vector8d lengths = TrueLengths();
  for (int i = 0; i < kNumStrings; ++i) {
    const double noisy = lengths[i] + config_.length_noise_sd * Normal();
    reading_.counts[i] =
        LengthToCounts(true_encoder_.spec, true_encoder_.strings[i], noisy, actual_tension_[i]);
  }
  std::uint8_t slack = 0;
  for (int i = 0; i < kNumStrings; ++i) {
    if (commanded_tension_[i] < config_.slack_threshold)
      slack |= static_cast<std::uint8_t>(1u << i);
  }
  reading_.slack_mask = slack;
  reading_.time = time_;
  ++reading_.sequence;
}

void SimulatedSpidarG::Step(double dt) noexcept {
  if (!(dt >= 0.0)) dt = 0.0;
  time_ += dt;
  // Motors: saturate, then a first-order lag toward the saturated command. With the device in
  // an error state the drivers are disabled and the tensions decay to zero.
  Vector8d target = Vector8d::Zero();
  if (status_ == DeviceStatus::kOk) {
    for (int i = 0; i < kNumStrings; ++i) {
      target[i] = std::clamp(commanded_tension_[i], 0.0, config_.tension_max);
    }
  }
  const double T = config_.tension_time_constant;
  const double alpha = T > 0.0 ? 1.0 - std::exp(-dt / T) : 1.0;
  actual_tension_ += alpha * (target - actual_tension_);
  if (status_ == DeviceStatus::kOk) Sample();
}

DeviceStatus SimulatedSpidarG::Read(EncoderReading* reading) noexcept {
  if (reading != nullptr) {
    *reading = reading_;
    reading->status = status_;
  }
  return status_;
}

DeviceStatus SimulatedSpidarG::WriteTensions(const Vector8d& tension) noexcept {
  if (status_ != DeviceStatus::kOk) return status_;
  for (int i = 0; i < kNumStrings; ++i) {
    commanded_tension_[i] = std::isnan(tension[i]) ? 0.0 : tension[i];
  }
  return status_;
}

Vector7d SimulatedSpidarG::TrueWrench() const noexcept {
  return WrenchMatrix(config_.geometry, true_pose_) * actual_tension_;
}

}  // namespace spidarcad::haptics
