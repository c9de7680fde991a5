// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#include "spidarcad/haptics/simulated_hand.h"

#include <cmath>
#include <stdexcept>
#include <string>

#include "spidarcad/haptics/rotation.h"

namespace spidarcad::haptics {

namespace {
void Positive(double v, const char* field) {
  if (!(v > 0 && std::isfinite(v))) {
    throw std::invalid_argument(std::string("HandSettings.") + field + " = " + std::to_string(v) +
                                ": must be finite and > 0");
  }
}
}  // namespace

void HandSettings::Validate() const {
  Positive(mass, "mass");
  Positive(stiffness, "stiffness");
  Positive(damping, "damping");
  Positive(inertia, "inertia");
  Positive(rot_stiffness, "rot_stiffness");
  Positive(rot_damping, "rot_damping");
  Positive(grasp_inertia, "grasp_inertia");
  Positive(grasp_stiffness, "grasp_stiffness");
  Positive(grasp_damping, "grasp_damping");
  if (substeps < 1) throw std::invalid_argument("HandSettings.substeps must be >= 1");
}

SimulatedHand::SimulatedHand(const HandSettings& settings, const TrajectorySample& initial,
                             double d)
    : settings_(settings),
      d_(d),
      p_(initial.p_DT),
      q_(initial.q_DT.normalized()),
      grasp_(initial.grasp) {
  settings_.Validate();
}

void SimulatedHand::Step(const TrajectorySample& target,
                         const Eigen::Matrix<double, 7, 1>& wrench_D, double dt) noexcept {
  const HandSettings& s = settings_;
  const double h = dt / s.substeps;
  const Eigen::Vector3d f = wrench_D.head<3>();
  const Eigen::Vector3d m = wrench_D.segment<3>(3);
  const double g = wrench_D(6);
  for (int i = 0; i < s.substeps; ++i) {
    const Eigen::Vector3d force = s.stiffness * (target.p_DT - p_) - s.damping * v_ + f;
    v_ += h * force / s.mass;
    p_ += h * v_;

    Eigen::Quaterniond error = target.q_DT * q_.conjugate();
    if (error.w() < 0) error.coeffs() *= -1;  // shortest way
    const Eigen::AngleAxisd aa(error);
    const Eigen::Vector3d moment =
        s.rot_stiffness * aa.angle() * aa.axis() - s.rot_damping * w_ + m;
    w_ += h * moment / s.inertia;
    q_ = IntegrateRotation(q_, w_, h);

    const double torque =
        s.grasp_stiffness * (target.grasp - grasp_) - s.grasp_damping * grasp_rate_ - 0.5 * g;
    grasp_rate_ += h * torque / s.grasp_inertia;
    grasp_ += h * grasp_rate_;
    grasp_ = std::min(M_PI - 0.05, std::max(0.05, grasp_));  // fingers cannot cross the poles
  }
}

GripPose SimulatedHand::pose() const noexcept {
  return GripPose::FromFrame(p_, q_.toRotationMatrix(), grasp_, d_);
}

double SimulatedHand::KineticEnergy() const noexcept {
  const HandSettings& s = settings_;
  return 0.5 * s.mass * v_.squaredNorm() + 0.5 * s.inertia * w_.squaredNorm() +
         0.5 * s.grasp_inertia * grasp_rate_ * grasp_rate_;
}

}  // namespace spidarcad::haptics
