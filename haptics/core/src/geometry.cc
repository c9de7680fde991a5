// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#include "spidarcad/haptics/geometry.h"

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace spidarcad::haptics {

namespace {
void CheckPositive(double v, const char* name) {
  if (!std::isfinite(v) || v <= 0.0) {
    throw std::invalid_argument(std::string("SpidarGeometry: field '") + name +
                                "' must be a finite positive length in metres, got " +
                                std::to_string(v));
  }
}
}  // namespace

void SpidarGeometry::Validate() const {
  CheckPositive(a, "a");
  CheckPositive(b, "b");
  CheckPositive(c, "c");
  CheckPositive(d, "d");
  if (d >= std::min({a, b, c})) {
    throw std::invalid_argument(
        "SpidarGeometry: pole half-length d = " + std::to_string(d) +
        " m does not fit inside the frame (half-sides a, b, c = " + std::to_string(a) + ", " +
        std::to_string(b) + ", " + std::to_string(c) + " m); d must be smaller than all three");
  }
}

Eigen::Vector3d SpidarGeometry::Corner(int i) const {
  // Eq. 3: x alternates +,-; y is + for corners 1,2,5,6; z is + for the top four.
  const double sx = (i % 2 == 0) ? 1.0 : -1.0;
  const double sy = (i == 0 || i == 1 || i == 4 || i == 5) ? 1.0 : -1.0;
  const double sz = (i < 4) ? 1.0 : -1.0;
  return {sx * a, sy * b, sz * c};
}

int StringPole(int i) { return i < 4 ? 0 : 1; }

int StringEnd(int i) {
  // Strings 1,2 -> P+1; 3,4 -> P-1; 5,7 -> P+2; 6,8 -> P-2 (1-based).
  static constexpr std::array<int, kNumStrings> kEnd = {+1, +1, -1, -1, +1, -1, +1, -1};
  return kEnd[i];
}

int StringDelta(int i) { return i < 4 ? 1 : -1; }

GripPose GripPose::Rest(double d) {
  GripPose pose;
  pose.p0.setZero();
  pose.p1 = Eigen::Vector3d(0, d, 0);
  pose.p2 = Eigen::Vector3d(d, 0, 0);
  return pose;
}

PoleDirections GripPoleDirections(double grasp) {
  const double s = std::sin(0.5 * grasp);
  const double c = std::cos(0.5 * grasp);
  const Eigen::Vector3d b_T = Eigen::Vector3d(1, 1, 0) / std::sqrt(2.0);
  const Eigen::Vector3d a_T = Eigen::Vector3d(1, -1, 0) / std::sqrt(2.0);
  PoleDirections poles;
  poles.u_T[0] = c * b_T - s * a_T;
  poles.u_T[1] = c * b_T + s * a_T;
  poles.du_T[0] = 0.5 * (-s * b_T - c * a_T);
  poles.du_T[1] = 0.5 * (-s * b_T + c * a_T);
  return poles;
}

GripPose GripPose::FromFrame(const Eigen::Vector3d& p0_DT, const Eigen::Matrix3d& R_DT,
                             double grasp, double d) {
  const PoleDirections poles = GripPoleDirections(grasp);
  GripPose pose;
  pose.p0 = p0_DT;
  pose.p1 = d * (R_DT * poles.u_T[0]);
  pose.p2 = d * (R_DT * poles.u_T[1]);
  return pose;
}

Eigen::Vector3d GripPose::Attachment(int i) const {
  const Eigen::Vector3d& pole = StringPole(i) == 0 ? p1 : p2;
  return p0 + StringEnd(i) * pole;
}

Eigen::Vector3d GripPose::LeverArm(int i) const {
  const Eigen::Vector3d& pole = StringPole(i) == 0 ? p1 : p2;
  return StringEnd(i) * pole;
}

Eigen::Matrix3d GripPose::Rotation() const {
  const Eigen::Vector3d u1 = p1.normalized();
  const Eigen::Vector3d u2 = p2.normalized();
  const Eigen::Vector3d b = (u1 + u2).normalized();
  const Eigen::Vector3d a = (u2 - u1).normalized();
  Eigen::Matrix3d R;
  R.col(0) = (b + a) / std::sqrt(2.0);
  R.col(1) = (b - a) / std::sqrt(2.0);
  R.col(2) = a.cross(b);
  return R;
}

double GripPose::Grasp() const {
  // atan2 of |cross| and dot is accurate at every angle, unlike acos near 0 and π.
  return std::atan2(p1.cross(p2).norm(), p1.dot(p2));
}

Eigen::Vector3d GripPose::Normal() const { return p1.cross(p2).normalized(); }

Vector9d GripPose::Packed() const {
  Vector9d v;
  v << p0, p1, p2;
  return v;
}

GripPose GripPose::Unpacked(const Vector9d& v) {
  GripPose pose;
  pose.p0 = v.segment<3>(0);
  pose.p1 = v.segment<3>(3);
  pose.p2 = v.segment<3>(6);
  return pose;
}

double RotationAngleBetween(const Eigen::Matrix3d& R_a, const Eigen::Matrix3d& R_b) {
  const Eigen::Matrix3d R = R_a.transpose() * R_b;
  // Robust angle: atan2 of the skew part's norm and the trace.
  const Eigen::Vector3d w(R(2, 1) - R(1, 2), R(0, 2) - R(2, 0), R(1, 0) - R(0, 1));
  return std::atan2(0.5 * w.norm(), 0.5 * (R.trace() - 1.0));
}

}  // namespace spidarcad::haptics
