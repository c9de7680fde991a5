// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
// Force fields: what a scene object contributes to the wrench on the tool. The haptic loop
// evaluates every field of the current HapticScene once per tick, on the haptic thread.
//
// Frames and units (ARCHITECTURE.md): W world (the scene), T tool (the grip). Positions in m,
// velocities in m/s and rad/s, forces in N, moments in N·m, all expressed in W. The moment is
// about the tool origin p_WT. Grasp: angle θ between the poles (rad, π/2 at rest); the grasp
// torque g [N·m] follows tension.h: g > 0 squeezes the grip closed.
#pragma once

#include <Eigen/Core>

namespace spidarcad::haptics {

// State of the tool handed to the force fields, in W.
struct ToolKinematics {
  double time = 0.0;                                   // loop time, s
  Eigen::Vector3d p_WT = Eigen::Vector3d::Zero();      // tool origin (grip centre), m
  Eigen::Matrix3d R_WT = Eigen::Matrix3d::Identity();  // tool rotation (grip frame)
  double grasp = 1.5707963267948966;                   // grasp angle θ, rad
  Eigen::Vector3d v_WT = Eigen::Vector3d::Zero();      // velocity of p_WT, m/s (filtered)
  Eigen::Vector3d w_WT = Eigen::Vector3d::Zero();      // angular velocity, rad/s (filtered)
  double grasp_rate = 0.0;                             // dθ/dt, rad/s (filtered)
};

// Wrench on the tool, in W: force, moment about p_WT, grasp torque.
struct ToolWrench {
  Eigen::Vector3d f_T_W = Eigen::Vector3d::Zero();  // N
  Eigen::Vector3d m_T_W = Eigen::Vector3d::Zero();  // N·m about p_WT
  double g = 0.0;                                   // N·m, > 0 squeezes the grip closed
  ToolWrench& operator+=(const ToolWrench& o) {
    f_T_W += o.f_T_W;
    m_T_W += o.m_T_W;
    g += o.g;
    return *this;
  }
};

// A scene object as the haptic loop feels it. Built (and any precomputation done) on the app
// side before its scene is published; after that only the haptic thread calls Evaluate.
// Evaluate must be real-time safe: no allocation, locks, I/O or exceptions, bounded time.
// Fields that keep state between ticks (a proxy, say) keep it in members sized at
// construction; Evaluate is therefore non-const.
class ForceField {
 public:
  virtual ~ForceField() = default;
  // Wrench this field puts on the tool in state `tool`. Return finite numbers; a NaN makes the
  // loop command zero force for the tick (and counts a safety event).
  virtual ToolWrench Evaluate(const ToolKinematics& tool) noexcept = 0;
  // Short name for logs and summaries (static storage).
  virtual const char* name() const noexcept = 0;
};

// A damped spring pulling the tool origin toward an anchor point:
//   f = −k (p_WT − p_WA) − b v_WT.
class SpringField final : public ForceField {
 public:
  // Anchor p_WA [m], stiffness k [N/m] >= 0, damping b [N·s/m] >= 0. Throws
  // std::invalid_argument naming the parameter when out of range.
  SpringField(const Eigen::Vector3d& p_WA, double stiffness, double damping);
  ToolWrench Evaluate(const ToolKinematics& tool) noexcept override;
  const char* name() const noexcept override { return "spring"; }

 private:
  Eigen::Vector3d p_WA_;
  double stiffness_;
  double damping_;
};

// A stiff one-sided wall: the half-space n·(p − p_WP) < 0 is solid. While the tool origin
// penetrates by depth δ = −n·(p_WT − p_WP) > 0 it is pushed out along n by
//   f = max(0, k δ − b n·v_WT) n
// (the damping acts only inside and never pulls the tool into the wall).
class PlaneWallField final : public ForceField {
 public:
  // A point p_WP on the plane [m], outward normal n_W (normalised here), stiffness k [N/m] >= 0,
  // damping b [N·s/m] >= 0. Throws std::invalid_argument naming the parameter when out of
  // range (including a zero normal).
  PlaneWallField(const Eigen::Vector3d& p_WP, const Eigen::Vector3d& n_W, double stiffness,
                 double damping);
  ToolWrench Evaluate(const ToolKinematics& tool) noexcept override;
  const char* name() const noexcept override { return "plane_wall"; }

 private:
  Eigen::Vector3d p_WP_;
  Eigen::Vector3d n_W_;
  double stiffness_;
  double damping_;
};

}  // namespace spidarcad::haptics
