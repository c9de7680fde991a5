// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#include "scene/device_session.h"

#include <Eigen/Geometry>

namespace spidarcad::app {

namespace {
constexpr double kHalfPi = 0.5 * 3.14159265358979323846;
}  // namespace

haptics::Vector7d DemoSpringWrench(const DemoFieldSettings& field, const haptics::GripPose& pose) {
  haptics::Vector7d q = haptics::Vector7d::Zero();
  if (!field.enabled) return q;
  q.head<3>() = -field.k_translation * pose.p0;
  const Eigen::AngleAxisd aa(pose.Rotation());
  q.segment<3>(3) = -field.k_rotation * aa.angle() * aa.axis();
  q[6] = 2.0 * field.k_grasp * (pose.Grasp() - kHalfPi);
  return q;
}

}  // namespace spidarcad::app
