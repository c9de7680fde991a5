// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#include "spidarcad/haptics/rotation.h"

#include <cmath>

namespace spidarcad::haptics {

Eigen::Quaterniond IntegrateRotation(const Eigen::Quaterniond& q, const Eigen::Vector3d& w,
                                     double h) {
  Eigen::Quaterniond out = q;
  const double angle = w.norm() * h;
  if (angle > 0 || angle < 0) out = Eigen::Quaterniond(Eigen::AngleAxisd(angle, w / w.norm())) * q;
  out.normalize();
  return out;
}

Eigen::Matrix3d IntegrateRotation(const Eigen::Matrix3d& R, const Eigen::Vector3d& w, double h) {
  const double angle = w.norm() * h;
  if (!(angle > 0 || angle < 0)) return R;
  return Eigen::AngleAxisd(angle, w / w.norm()).toRotationMatrix() * R;
}

Eigen::Vector3d RotationVector(Eigen::Quaterniond q) {
  if (q.w() < 0) q.coeffs() *= -1;
  const double s = q.vec().norm();
  if (s < 1e-12) return 2.0 * q.vec();
  return (2.0 * std::atan2(s, q.w()) / s) * q.vec();
}

}  // namespace spidarcad::haptics
