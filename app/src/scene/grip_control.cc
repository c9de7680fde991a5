// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#include "scene/grip_control.h"

#include <Eigen/Geometry>
#include <Eigen/SVD>
#include <algorithm>
#include <cmath>

#include "spidarcad/haptics/rotation.h"

namespace spidarcad::app {

bool IntersectRayPlane(const Ray& ray, const Eigen::Vector3d& point, const Eigen::Vector3d& normal,
                       Eigen::Vector3d* hit) {
  const double denom = normal.dot(ray.direction);
  if (std::abs(denom) < 1e-12 * ray.direction.norm() * normal.norm()) return false;
  const double s = normal.dot(point - ray.origin) / denom;
  if (!(s >= 0.0)) return false;
  *hit = ray.origin + s * ray.direction;
  return true;
}

bool IntersectRaySphere(const Ray& ray, const Eigen::Vector3d& centre, double radius,
                        double* distance) {
  const double n = ray.direction.norm();
  if (!(n > 0.0)) return false;
  const Eigen::Vector3d u = ray.direction / n;
  const Eigen::Vector3d oc = ray.origin - centre;
  const double c = oc.squaredNorm() - radius * radius;
  if (c <= 0.0) {
    *distance = 0.0;
    return true;
  }
  const double b = oc.dot(u);
  const double disc = b * b - c;
  if (disc < 0.0 || b > 0.0) return false;  // misses, or the sphere is behind the origin
  *distance = -b - std::sqrt(disc);
  return true;
}

Eigen::Vector3d RollPitchYaw(const Eigen::Matrix3d& R) {
  const double pitch = std::asin(std::clamp(-R(2, 0), -1.0, 1.0));
  const double roll = std::atan2(R(2, 1), R(2, 2));
  const double yaw = std::atan2(R(1, 0), R(0, 0));
  return {roll, pitch, yaw};
}

GripControl::GripControl(const haptics::SpidarGeometry& geometry) : geometry_(geometry) {
  const double clearance = geometry.d + kMargin;
  limits_ = Eigen::Vector3d(geometry.a, geometry.b, geometry.c).array() - clearance;
  limits_ = limits_.cwiseMax(0.0);
  Reset();
}

void GripControl::Reset() {
  p0_.setZero();
  R_.setIdentity();
  grasp_ = 0.5 * 3.14159265358979323846;
  dragging_ = false;
}

void GripControl::SetPose(const Eigen::Vector3d& p0_DT, const Eigen::Matrix3d& R_DT, double grasp) {
  p0_ = p0_DT;
  // Nearest rotation (polar decomposition) keeps R orthonormal after repeated products.
  Eigen::JacobiSVD<Eigen::Matrix3d> svd(R_DT, Eigen::ComputeFullU | Eigen::ComputeFullV);
  Eigen::Matrix3d R = svd.matrixU() * svd.matrixV().transpose();
  if (R.determinant() < 0) {
    Eigen::Matrix3d U = svd.matrixU();
    U.col(2) *= -1.0;
    R = U * svd.matrixV().transpose();
  }
  R_ = R;
  grasp_ = grasp;
  Clamp();
}

bool GripControl::BeginTranslate(const Ray& ray, const Eigen::Vector3d& plane_normal) {
  Eigen::Vector3d hit;
  if (!IntersectRayPlane(ray, p0_, plane_normal, &hit)) return false;
  plane_point_ = p0_;
  plane_normal_ = plane_normal;
  grab_offset_ = p0_ - hit;
  dragging_ = true;
  return true;
}

void GripControl::Translate(const Ray& ray) {
  if (!dragging_) return;
  Eigen::Vector3d hit;
  if (!IntersectRayPlane(ray, plane_point_, plane_normal_, &hit)) return;
  p0_ = hit + grab_offset_;
  Clamp();
}

void GripControl::Rotate(const Eigen::Vector3d& axis_D, double angle) {
  const double n = axis_D.norm();
  if (!(n > 0.0) || !std::isfinite(angle)) return;
  SetPose(p0_, haptics::IntegrateRotation(R_, axis_D / n, angle), grasp_);
}

void GripControl::AdjustGrasp(double delta) {
  if (!std::isfinite(delta)) return;
  grasp_ += delta;
  Clamp();
}

haptics::GripPose GripControl::Pose() const {
  return haptics::GripPose::FromFrame(p0_, R_, grasp_, geometry_.d);
}

void GripControl::Clamp() {
  for (int k = 0; k < 3; ++k) {
    if (!std::isfinite(p0_[k])) p0_[k] = 0.0;
    p0_[k] = std::clamp(p0_[k], -limits_[k], limits_[k]);
  }
  if (!std::isfinite(grasp_)) grasp_ = 0.5 * 3.14159265358979323846;
  grasp_ = std::clamp(grasp_, kMinGrasp, kMaxGrasp);
}

}  // namespace spidarcad::app
