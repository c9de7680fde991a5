// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#include "gui/scene_fields.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>

#include <Eigen/Geometry>

namespace spidarcad::app {

namespace {
constexpr double kHalfPi = 0.5 * 3.14159265358979323846;

void RequireNonNegative(double value, const char* name) {
  if (!(value >= 0.0) || !std::isfinite(value)) {
    throw std::invalid_argument(std::string(name) + " must be finite and >= 0, got " +
                                std::to_string(value));
  }
}
}  // namespace

SolidPenaltyField::SolidPenaltyField(std::shared_ptr<const modeling::CompiledSolid> solid,
                                     double stiffness, double damping)
    : solid_(std::move(solid)), stiffness_(stiffness), damping_(damping) {
  if (!solid_) throw std::invalid_argument("SolidPenaltyField: solid is null");
  RequireNonNegative(stiffness, "SolidPenaltyField stiffness");
  RequireNonNegative(damping, "SolidPenaltyField damping");
}

haptics::ToolWrench SolidPenaltyField::Evaluate(const haptics::ToolKinematics& tool) noexcept {
  haptics::ToolWrench w;
  Eigen::Vector3d gradient;
  const double value = solid_->ValueAndGradient(tool.p_WT, &gradient);
  const double norm = gradient.norm();
  if (!(value < 0.0) || !(norm > 1e-12)) return w;  // outside, or no direction to push
  const Eigen::Vector3d n = gradient / norm;
  const double push = std::max(0.0, stiffness_ * (-value) - damping_ * n.dot(tool.v_WT));
  w.f_T_W = push * n;
  return w;
}

CentringSpringField::CentringSpringField(const DemoFieldSettings& field, double world_scale,
                                         const Eigen::Vector3d& p_WDo)
    : field_(field), world_scale_(world_scale), p_WDo_(p_WDo) {
  if (!(world_scale > 0.0) || !std::isfinite(world_scale)) {
    throw std::invalid_argument("CentringSpringField: world_scale must be > 0, got " +
                                std::to_string(world_scale));
  }
}

haptics::ToolWrench CentringSpringField::Evaluate(const haptics::ToolKinematics& tool) noexcept {
  haptics::ToolWrench w;
  if (!field_.enabled) return w;
  w.f_T_W = -field_.k_translation * (tool.p_WT - p_WDo_) / world_scale_;
  const Eigen::AngleAxisd aa(tool.R_WT);
  w.m_T_W = -field_.k_rotation * aa.angle() * aa.axis();
  w.g = 2.0 * field_.k_grasp * (tool.grasp - kHalfPi);
  return w;
}

}  // namespace spidarcad::app
