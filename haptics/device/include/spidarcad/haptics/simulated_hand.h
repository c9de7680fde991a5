// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
// A simulated hand holding the grip, for headless runs and stability tests: the grip is a rigid
// body (mass, rotational inertia, and an inertia for the grasp angle) tied to the hand's
// intended pose (a trajectory sample) by springs and dampers, and pushed by the wrench the
// device puts on it. Frame D, SI units. Semi-implicit Euler with substeps; stable for the
// defaults against walls up to ~10 kN/m at 1 kHz.
//
// Equations (f, m, g: the device wrench on the grip, tension.h's conventions):
//   M v̇ = k (p_target − p) − b v + f
//   I ω̇ = k_r log(R_target Rᵀ) − b_r ω + m            (ω, m in D)
//   I_g θ̈ = k_g (θ_target − θ) − b_g θ̇ − g/2         (−g/2 is the generalised force on θ)
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>

#include "spidarcad/haptics/geometry.h"
#include "spidarcad/haptics/trajectory.h"

namespace spidarcad::haptics {

// Parameters of the simulated hand.
struct HandSettings {
  double mass = 0.3;             // kg, grip plus the fingers moving with it
  double stiffness = 300.0;      // N/m, hand spring toward the intended position
  double damping = 20.0;         // N·s/m
  double inertia = 2e-4;         // kg·m², about every axis
  double rot_stiffness = 1.0;    // N·m/rad
  double rot_damping = 0.02;     // N·m·s/rad
  double grasp_inertia = 1e-5;   // kg·m² for the grasp angle
  double grasp_stiffness = 0.5;  // N·m/rad
  double grasp_damping = 0.01;   // N·m·s/rad
  int substeps = 4;              // integration substeps per Step
  // Throws std::invalid_argument naming the field when a value is not finite and positive.
  void Validate() const;
};

// The hand-and-grip rigid body.
class SimulatedHand {
 public:
  // Starts at rest at `initial` with pole half-length d (m). Throws on bad settings.
  SimulatedHand(const HandSettings& settings, const TrajectorySample& initial, double d);
  // Advances by dt (s) toward `target` under the device wrench `wrench_D` (f, m, g). Real-time
  // safe.
  void Step(const TrajectorySample& target, const Eigen::Matrix<double, 7, 1>& wrench_D,
            double dt) noexcept;
  // The grip pose for the device (GripPose::FromFrame of the state).
  GripPose pose() const noexcept;
  const Eigen::Vector3d& position() const noexcept { return p_; }
  const Eigen::Vector3d& velocity() const noexcept { return v_; }
  const Eigen::Vector3d& angular_velocity() const noexcept { return w_; }
  const Eigen::Quaterniond& rotation() const noexcept { return q_; }
  double grasp() const noexcept { return grasp_; }
  double grasp_rate() const noexcept { return grasp_rate_; }
  // Kinetic energy of the grip, J.
  double KineticEnergy() const noexcept;
  const HandSettings& settings() const noexcept { return settings_; }

 private:
  HandSettings settings_;
  double d_;
  Eigen::Vector3d p_;
  Eigen::Vector3d v_ = Eigen::Vector3d::Zero();
  Eigen::Quaterniond q_;
  Eigen::Vector3d w_ = Eigen::Vector3d::Zero();
  double grasp_;
  double grasp_rate_ = 0.0;
};

}  // namespace spidarcad::haptics
