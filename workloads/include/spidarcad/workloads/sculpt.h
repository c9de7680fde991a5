// Sculpting workloads: where a stroke of each tool takes the grip. Shared by
// bench/modeling_sculpt_bench.cc and the report's sculpting section. Uses spidarcad::modeling.
// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#pragma once

#include <Eigen/Geometry>

#include "spidarcad/modeling/sculpt.h"

namespace spidarcad::workloads {

// The grip pose a stroke of `tool` with brush `radius` (m) reaches from X0 at `amount` (1: a
// full stroke): grab, push/pull and smooth move the grip along its axes, twist and bend turn it.
inline Eigen::Isometry3d SculptTargetPose(modeling::SculptTool tool, const Eigen::Isometry3d& X0,
                                          double radius, double amount) {
  using modeling::SculptTool;
  Eigen::Isometry3d X = X0;
  const Eigen::Vector3d z = X0.linear().col(2), y = X0.linear().col(1);
  switch (tool) {
    case SculptTool::kGrab:
      X.translation() += amount * radius * (0.8 * z + 0.3 * y);
      break;
    case SculptTool::kTwist:
      X.linear() = Eigen::AngleAxisd(amount * 0.6, z) * X0.linear();
      break;
    case SculptTool::kBend:
      X.linear() = Eigen::AngleAxisd(amount * 0.4, y) * X0.linear();
      break;
    case SculptTool::kPushPull:
      X.translation() += amount * 0.5 * radius * z;
      break;
    case SculptTool::kSmooth:
      X.translation() += amount * radius * y;
      break;
  }
  return X;
}

}  // namespace spidarcad::workloads
