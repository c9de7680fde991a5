// The simulated hand: the grip pose the mouse sets (position, rotation, grasp), with the math
// of dragging it in the camera's view plane and turning it about camera axes. No rendering here.
// Frame D, metres, radians.
// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#pragma once

#include <Eigen/Core>

#include "spidarcad/haptics/geometry.h"

namespace spidarcad::app {

// A ray origin + s·direction (s >= 0) in D; direction need not be unit length.
struct Ray {
  Eigen::Vector3d origin = Eigen::Vector3d::Zero();
  Eigen::Vector3d direction = Eigen::Vector3d::UnitZ();
};

// Point where `ray` meets the plane through `point` with normal `normal`, or false when the ray
// is parallel to the plane or the plane lies behind the origin.
bool IntersectRayPlane(const Ray& ray, const Eigen::Vector3d& point, const Eigen::Vector3d& normal,
                       Eigen::Vector3d* hit);

// Distance along the unit-normalised ray to the first point of the sphere (centre, radius), or
// false when the ray misses it. Origin inside the sphere counts as a hit at distance 0.
bool IntersectRaySphere(const Ray& ray, const Eigen::Vector3d& centre, double radius,
                        double* distance);

// Roll, pitch, yaw (rad) of R = Rz(yaw) Ry(pitch) Rx(roll); pitch in [−π/2, π/2].
Eigen::Vector3d RollPitchYaw(const Eigen::Matrix3d& R);

// Grip pose under mouse control. Keeps the grip inside the frame (centre at least d + margin
// from every face) and the grasp angle in [kMinGrasp, kMaxGrasp].
class GripControl {
 public:
  // Smallest and largest grasp angle the mouse can set, rad (20° and 160°).
  static constexpr double kMinGrasp = 20.0 * 3.14159265358979323846 / 180.0;
  static constexpr double kMaxGrasp = 160.0 * 3.14159265358979323846 / 180.0;
  // Clearance kept between the grip sphere and the frame faces, m.
  static constexpr double kMargin = 0.01;

  explicit GripControl(const haptics::SpidarGeometry& geometry);

  // Back to the rest pose: centre at the origin, R = I, grasp π/2.
  void Reset();
  // Sets the pose (clamped to the limits); R_DT is re-orthonormalised.
  void SetPose(const Eigen::Vector3d& p0_DT, const Eigen::Matrix3d& R_DT, double grasp);

  // Starts a translation drag: the grip moves in the plane through p0 with normal
  // `plane_normal` (the camera's view direction), keeping the grab offset. False (no drag)
  // when the ray does not meet that plane.
  bool BeginTranslate(const Ray& ray, const Eigen::Vector3d& plane_normal);
  // Moves the grip so that the grabbed point follows `ray`; ignored without a drag or when the
  // ray does not meet the plane.
  void Translate(const Ray& ray);
  // Ends the translation drag.
  void EndTranslate() { dragging_ = false; }
  bool dragging() const { return dragging_; }

  // Turns the grip by `angle` (rad, right-handed) about the unit axis `axis_D` through p0:
  // R ← Rot(axis, angle) R.
  void Rotate(const Eigen::Vector3d& axis_D, double angle);
  // Changes the grasp angle by `delta` (rad), clamped.
  void AdjustGrasp(double delta);

  // The pose as centre and pole vectors (GripPose::FromFrame).
  haptics::GripPose Pose() const;
  const Eigen::Vector3d& p0() const { return p0_; }
  const Eigen::Matrix3d& R() const { return R_; }
  double grasp() const { return grasp_; }
  // Largest |p0_x|, |p0_y|, |p0_z| allowed, m.
  const Eigen::Vector3d& limits() const { return limits_; }

 private:
  void Clamp();

  haptics::SpidarGeometry geometry_;
  Eigen::Vector3d limits_;
  Eigen::Vector3d p0_ = Eigen::Vector3d::Zero();
  Eigen::Matrix3d R_ = Eigen::Matrix3d::Identity();
  double grasp_ = 0.5 * 3.14159265358979323846;
  // Translation drag: plane and offset from the grabbed point to p0.
  bool dragging_ = false;
  Eigen::Vector3d plane_point_ = Eigen::Vector3d::Zero();
  Eigen::Vector3d plane_normal_ = Eigen::Vector3d::UnitZ();
  Eigen::Vector3d grab_offset_ = Eigen::Vector3d::Zero();
};

}  // namespace spidarcad::app
