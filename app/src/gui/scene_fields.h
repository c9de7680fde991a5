// Force fields the window builds for its HapticScene: a penalty contact with an implicit solid
// (the grip centre pushed out along the surface normal) and the centring springs of the demo
// panel. Both evaluate in W and are real-time safe. The god-object proxy and six-DOF contact
// of the haptics module replace the penalty field once the app's runtime adapters use them.
// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#pragma once

#include <memory>

#include <Eigen/Core>

#include "gui/device_session.h"
#include "spidarcad/haptics/force_field.h"
#include "spidarcad/modeling/implicit_evaluator.h"

namespace spidarcad::app {

// Penalty contact of the tool centre with a solid (value < 0 inside, m):
//   f = max(0, k δ − b n·v) n,  δ = −value(p_WT) > 0,  n = ∇value / |∇value|
// (pushes out along the outward normal, damping only while inside and never pulling in). No
// moment, no grasp torque. Zero where the gradient vanishes.
class SolidPenaltyField final : public haptics::ForceField {
 public:
  // `solid` is shared with the window (immutable); k [N/m] >= 0, b [N·s/m] >= 0 in W. Throws
  // std::invalid_argument naming the parameter when out of range or solid is null.
  SolidPenaltyField(std::shared_ptr<const modeling::CompiledSolid> solid, double stiffness,
                    double damping);
  haptics::ToolWrench Evaluate(const haptics::ToolKinematics& tool) noexcept override;
  const char* name() const noexcept override { return "solid_penalty"; }

 private:
  std::shared_ptr<const modeling::CompiledSolid> solid_;
  double stiffness_;
  double damping_;
};

// The demo field's springs (DemoSpringWrench) toward the device centre, expressed in W for the
// loop's X_WD (p_W = s p_D + p_WDo, no rotation, force_scale 1): f_W = −k (p_WT − p_WDo) / s,
// m_W = −k_r φ u, g = 2 k_g (θ − π/2), so that the force felt in D is −k p_D.
class CentringSpringField final : public haptics::ForceField {
 public:
  // world_scale s > 0 and p_WDo of the loop's X_WD. Throws std::invalid_argument for s <= 0.
  CentringSpringField(const DemoFieldSettings& field, double world_scale,
                      const Eigen::Vector3d& p_WDo);
  haptics::ToolWrench Evaluate(const haptics::ToolKinematics& tool) noexcept override;
  const char* name() const noexcept override { return "centring_springs"; }

 private:
  DemoFieldSettings field_;
  double world_scale_;
  Eigen::Vector3d p_WDo_;
};

}  // namespace spidarcad::app
