// What the window shows of the device for one frame (DeviceFrame, filled from the haptic
// runtime's latest tick: scene/haptic_runtime.h) and the demo field's centring springs. No
// rendering or ImGui here. Frame D, SI units.
// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#pragma once

#include <string>

#include "spidarcad/haptics/encoder.h"
#include "spidarcad/haptics/geometry.h"
#include "spidarcad/haptics/kinematics.h"
#include "spidarcad/haptics/tension.h"

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
  double fk_residual = 0.0;  // RMS string residual of the FK solve, m
  int fk_iterations = 0;
  haptics::Vector8d lengths = haptics::Vector8d::Zero();   // measured string lengths, m
  haptics::Vector8d tensions = haptics::Vector8d::Zero();  // commanded tensions, N
  haptics::Vector7d wrench = haptics::Vector7d::Zero();    // requested q = (f, m, g)
  haptics::Vector7d achieved = haptics::Vector7d::Zero();  // displayed A τ
  haptics::TensionStatus tension_status = haptics::TensionStatus::kInvalidInput;
  std::string source;  // where the lengths come from (shown in the panel)
};

}  // namespace spidarcad::app
