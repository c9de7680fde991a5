// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#include "gui/device_session.h"

#include <algorithm>
#include <cmath>
#include <cstdio>

#include <Eigen/Geometry>

#include "spidarcad/haptics/calibration.h"
#include "spidarcad/haptics/simulated_device.h"

namespace spidarcad::app {

namespace {
constexpr double kHalfPi = 0.5 * 3.14159265358979323846;
// Haptic-rate step of the simulated device, s: each window frame advances it in 1 ms steps.
constexpr double kDeviceStep = 1e-3;
// Jig poses and their tension for the start-up calibration.
constexpr int kJigPoses = 24;
constexpr double kJigTension = 1.0;
}  // namespace

haptics::Vector7d DemoSpringWrench(const DemoFieldSettings& field,
                                   const haptics::GripPose& pose) {
  haptics::Vector7d q = haptics::Vector7d::Zero();
  if (!field.enabled) return q;
  q.head<3>() = -field.k_translation * pose.p0;
  const Eigen::AngleAxisd aa(pose.Rotation());
  q.segment<3>(3) = -field.k_rotation * aa.angle() * aa.axis();
  q[6] = 2.0 * field.k_grasp * (pose.Grasp() - kHalfPi);
  return q;
}

DeviceSession::DeviceSession(const haptics::SpidarGeometry& geometry,
                             const haptics::TensionSettings& tension_settings,
                             LengthSource source)
    : geometry_(geometry), fk_(geometry), solver_(tension_settings) {
  frame_.measured_pose = haptics::GripPose::Rest(geometry.d);
  frame_.true_pose = frame_.measured_pose;
  frame_.tensions.setConstant(tension_settings.tau_min);
  if (source == LengthSource::kIdeal) {
    frame_.source = "ideal device (exact lengths)";
    return;
  }
  haptics::SimulatedDeviceConfig config;
  config.geometry = geometry;
  config.home_pose = haptics::GripPose::Rest(geometry.d);
  config.tension_max = tension_settings.tau_max;
  device_ = std::make_unique<haptics::SimulatedSpidarG>(config);
  const haptics::Vector8d home_lengths =
      haptics::InverseKinematics(geometry, device_->info().home_pose);
  const haptics::EncoderCalibration nominal =
      haptics::EncoderCalibration::Nominal(device_->info().encoder, home_lengths);
  const std::vector<haptics::GripPose> jig =
      haptics::RandomGripPoses(geometry, kJigPoses, 0.5 * std::min({geometry.a, geometry.b,
                                                                    geometry.c}),
                               0.5, 0.4, /*seed=*/7);
  const haptics::CalibrationResult fit = haptics::FitLinesPerString(
      geometry, nominal, haptics::GatherKnownSamples(device_.get(), jig, kJigTension));
  char note[160];
  if (fit.status == haptics::CalibrationStatus::kOk) {
    calibration_ = fit.calibration;
    std::snprintf(note, sizeof(note), "line fit on %d jig poses, rms %.3f mm", kJigPoses,
                  fit.rms_residual * 1e3);
  } else {
    calibration_ = nominal;
    std::snprintf(note, sizeof(note), "nominal (line fit failed: %s)",
                  haptics::CalibrationStatusName(fit.status));
  }
  calibration_note_ = note;
  frame_.source = "SimulatedSpidarG encoders, calibration: " + calibration_note_;
  device_->SetTruePose(frame_.true_pose);
  device_->WriteTensions(haptics::Vector8d::Constant(tension_settings.tau_min));
  device_->Step(kDeviceStep);
}

DeviceSession::~DeviceSession() = default;

haptics::Vector8d DeviceSession::MeasureLengths(const haptics::GripPose& true_pose, double dt) {
  if (!device_) return haptics::InverseKinematics(geometry_, true_pose);
  device_->SetTruePose(true_pose);
  device_->WriteTensions(frame_.tensions);
  const int steps = std::clamp(static_cast<int>(std::lround(dt / kDeviceStep)), 1, 100);
  for (int k = 0; k < steps; ++k) device_->Step(kDeviceStep);
  haptics::EncoderReading reading;
  device_->Read(&reading);
  // The stretch correction uses the tensions the app commanded (what it knows).
  return calibration_.Lengths(reading.counts, frame_.tensions);
}

const DeviceFrame& DeviceSession::Update(const haptics::GripPose& true_pose, double dt) {
  frame_.true_pose = true_pose;
  frame_.lengths = MeasureLengths(true_pose, dt);
  const haptics::FkResult fk = fk_.Solve(frame_.lengths);
  frame_.fk_status = fk.status;
  frame_.fk_residual = fk.residual;
  frame_.fk_iterations = fk.iterations;
  if (fk.status == haptics::FkStatus::kOk) {
    frame_.measured_pose = fk.pose;
    has_measured_ = true;
  } else if (!has_measured_) {
    frame_.measured_pose = haptics::GripPose::Rest(geometry_.d);
  }
  // Without a trustworthy measurement the field commands nothing (safe: minimum tensions).
  frame_.wrench = fk.status == haptics::FkStatus::kOk
                      ? DemoSpringWrench(field_, frame_.measured_pose)
                      : haptics::Vector7d::Zero();
  const haptics::Matrix78d A = haptics::WrenchMatrix(geometry_, frame_.measured_pose);
  const haptics::TensionResult tension = solver_.Solve(A, frame_.wrench);
  frame_.tensions = tension.tau;
  frame_.achieved = tension.achieved;
  frame_.tension_status = tension.status;
  return frame_;
}

}  // namespace spidarcad::app
