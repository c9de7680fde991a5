// State side of the window: one update of the simulated SPIDAR-G per frame. The mouse sets the
// TRUE grip pose; the device reports string lengths; forward kinematics gives the MEASURED pose
// (what the app uses); a demo force field gives the wrench request q, and the tension solver
// turns it into 8 string tensions. No rendering or ImGui here. Frame D, SI units.
// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#pragma once

#include <memory>
#include <string>

#include "spidarcad/haptics/encoder.h"
#include "spidarcad/haptics/geometry.h"
#include "spidarcad/haptics/kinematics.h"
#include "spidarcad/haptics/tension.h"

namespace spidarcad::haptics {
class SimulatedSpidarG;
}  // namespace spidarcad::haptics

namespace spidarcad::app {

// The demo force field: springs pulling the grip back to the rest pose.
struct DemoFieldSettings {
  bool enabled = true;
  double k_translation = 100.0;  // N/m, force f = −k p0
  double k_rotation = 0.2;       // N·m/rad, moment m = −k φ u for R_DT = Rot(u, φ)
  double k_grasp = 0.05;         // N·m/rad about the rest grasp angle π/2 (see DemoSpringWrench)
};

// Wrench request q = (f, m, g) of the demo field at `pose` (shape 7): f = −k_t p0,
// m = −k_r φ u where (u, φ) is the axis-angle of the pose's rotation, and g = 2 k_g (θ − π/2),
// since the generalised force on θ is −g/2 (tension.h). Zero when disabled.
haptics::Vector7d DemoSpringWrench(const DemoFieldSettings& field, const haptics::GripPose& pose);

// Everything the scene and the panel show for one frame.
struct DeviceFrame {
  haptics::GripPose true_pose;      // pose of the simulated hand (set by the mouse), D
  haptics::GripPose measured_pose;  // pose from forward kinematics: what the app uses, D
  haptics::FkStatus fk_status = haptics::FkStatus::kInvalidInput;
  double fk_residual = 0.0;         // RMS string residual of the FK solve, m
  int fk_iterations = 0;
  haptics::Vector8d lengths = haptics::Vector8d::Zero();   // measured string lengths, m
  haptics::Vector8d tensions = haptics::Vector8d::Zero();  // commanded tensions, N
  haptics::Vector7d wrench = haptics::Vector7d::Zero();    // requested q = (f, m, g)
  haptics::Vector7d achieved = haptics::Vector7d::Zero();  // displayed A τ
  haptics::TensionStatus tension_status = haptics::TensionStatus::kInvalidInput;
  std::string source;               // where the lengths come from (shown in the panel)
};

// Where the window's string lengths come from.
enum class LengthSource {
  // haptics::SimulatedSpidarG (encoder errors, noise, quantisation, stretch, motor lag), read
  // through an encoder calibration fitted at start-up on simulated jig poses.
  kSimulatedDevice,
  // Exact lengths of the hand pose (InverseKinematics): an ideal device.
  kIdeal,
};

// The simulated device pipeline of the window (one call per frame, main thread).
class DeviceSession {
 public:
  // With kSimulatedDevice, builds the device (seed 1) and calibrates it (FitLinesPerString on
  // 24 jig poses; the nominal calibration if that fails, see calibration_note()).
  DeviceSession(const haptics::SpidarGeometry& geometry,
                const haptics::TensionSettings& tension_settings, LengthSource source);
  ~DeviceSession();

  // Runs one update with the hand at `true_pose`, `dt` seconds after the previous one, and
  // returns the frame to show.
  const DeviceFrame& Update(const haptics::GripPose& true_pose, double dt = 1.0 / 60.0);

  // How the encoder calibration was obtained (empty for kIdeal).
  const std::string& calibration_note() const { return calibration_note_; }

  const haptics::SpidarGeometry& geometry() const { return geometry_; }
  const haptics::TensionSettings& tension_settings() const { return solver_.settings(); }
  DemoFieldSettings& field() { return field_; }
  const DeviceFrame& frame() const { return frame_; }

 private:
  // Lengths the device reports for the hand at `true_pose` (m, shape 8), after dt seconds.
  haptics::Vector8d MeasureLengths(const haptics::GripPose& true_pose, double dt);

  haptics::SpidarGeometry geometry_;
  haptics::ForwardKinematics fk_;
  haptics::TensionSolver solver_;
  DemoFieldSettings field_;
  DeviceFrame frame_;
  bool has_measured_ = false;
  std::unique_ptr<haptics::SimulatedSpidarG> device_;  // null for LengthSource::kIdeal
  haptics::EncoderCalibration calibration_;
  std::string calibration_note_;
};

}  // namespace spidarcad::app
