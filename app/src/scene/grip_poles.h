// Where the grip's pole tips are in the world, for the fields that touch and grab with them.
// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#pragma once

#include <Eigen/Core>

#include "spidarcad/haptics/force_field.h"
#include "spidarcad/haptics/geometry.h"

namespace spidarcad::app {

// Position (W, m) of the tip of pole i (0: pole 1, 1: pole 2) of the grip in state `tool`, with
// poles `pole_length` m long: p_WT + d·R_WT·p̂_i (haptics::PoleDirections). No allocation.
inline Eigen::Vector3d GripPoleTip(const haptics::ToolKinematics& tool, double pole_length, int i) {
  // By value: GripPoleDirections returns a temporary (a reference into it would dangle).
  const Eigen::Vector3d p_hat = haptics::GripPoleDirections(tool.grasp).u_T[i == 0 ? 0 : 1];
  return tool.p_WT + pole_length * (tool.R_WT * p_hat);
}

}  // namespace spidarcad::app
