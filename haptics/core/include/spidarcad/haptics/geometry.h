// SPIDAR-G device geometry and grip pose conventions.
//
// Frame D (device): origin at the frame centre, axes as the paper's Fig. 4. Units: metres, rad.
// String numbering is 0-based in code (string k in code is string k+1 in the paper).
// Attachment (docs/architecture.md): strings 1,2 -> P+1; 3,4 -> P-1; 5,7 -> P+2; 6,8 -> P-2, where
// P±1 = p0 ± p1 and P±2 = p0 ± p2. String i runs from its attachment point to corner Q_i.
// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#pragma once

#include <Eigen/Core>
#include <array>
#include <string>

namespace spidarcad::haptics {

// Number of strings and degrees of freedom of the SPIDAR-G.
inline constexpr int kNumStrings = 8;
inline constexpr int kNumDof = 7;

using Vector7d = Eigen::Matrix<double, 7, 1>;
using Vector8d = Eigen::Matrix<double, 8, 1>;
using Vector9d = Eigen::Matrix<double, 9, 1>;
using Matrix78d = Eigen::Matrix<double, 7, 8>;
using Matrix89d = Eigen::Matrix<double, 8, 9>;

// Size of a SPIDAR-G: frame half-sides a, b, c (along x, y, z) and pole half-length d, in m.
// Defaults are the paper's device: 48 cm cube frame, 4 cm grip radius.
struct SpidarGeometry {
  double a = 0.24;
  double b = 0.24;
  double c = 0.24;
  double d = 0.04;

  // Throws std::invalid_argument naming the field when a size is not finite and positive,
  // or when the grip (radius d) cannot fit inside the frame (d >= min(a, b, c)).
  void Validate() const;

  // Corner Q_i of the frame in D (Eq. 3), i in [0, 8).
  Eigen::Vector3d Corner(int i) const;
};

// Which pole string i (0-based) is attached to: 0 for pole 1, 1 for pole 2.
int StringPole(int i);
// Which end of its pole string i is attached to: +1 for P+k, -1 for P-k.
int StringEnd(int i);
// δ_i of the paper's Eq. 13: +1 for the strings of pole 1, -1 for those of pole 2.
int StringDelta(int i);

// The grip's pole frame at grasp angle θ (rad, π/2 at rest): the unit directions in T of the
// poles and their rates, written once for FromFrame, the grasp and assembly fields, the FE
// two-point grasp and calibration:
//   p̂1(θ) = cos(θ/2)·b − sin(θ/2)·a,   p̂2(θ) = cos(θ/2)·b + sin(θ/2)·a,
//   dp̂1/dθ = −(sin(θ/2)·b + cos(θ/2)·a)/2,   dp̂2/dθ = (−sin(θ/2)·b + cos(θ/2)·a)/2,
// with b = (x + y)/√2 (the bisector) and a = (x − y)/√2 in T, so p̂1 = y and p̂2 = x at θ = π/2.
// The pole vectors are p_i = d·R_DT·p̂_i in D (GripPose::FromFrame); a pole tip in W is
// p_WT + d·R_WT·p̂_i.
struct PoleDirections {
  std::array<Eigen::Vector3d, 2> u_T;   // p̂1, p̂2: unit, in T
  std::array<Eigen::Vector3d, 2> du_T;  // dp̂1/dθ, dp̂2/dθ: in T, per rad
};
// The pole frame at grasp angle θ (rad); see PoleDirections.
PoleDirections GripPoleDirections(double grasp);

// Pose of the cross grip in D: centre p0 and pole vectors p1, p2 with |p1| = |p2| = d.
struct GripPose {
  Eigen::Vector3d p0 = Eigen::Vector3d::Zero();
  Eigen::Vector3d p1 = Eigen::Vector3d(0, 0.04, 0);
  Eigen::Vector3d p2 = Eigen::Vector3d(0.04, 0, 0);

  // Rest pose for pole half-length d: centre at the origin, p1 = (0, d, 0), p2 = (d, 0, 0).
  static GripPose Rest(double d);
  // Pose from centre p0_DT, grip rotation R_DT, grasp angle θ (rad, angle between p1 and p2)
  // and pole half-length d. In T, p1 = d(cos θ/2 b − sin θ/2 a), p2 = d(cos θ/2 b + sin θ/2 a)
  // with b = (x + y)/√2, a = (x − y)/√2, so that θ = π/2, R = I gives the rest pose.
  static GripPose FromFrame(const Eigen::Vector3d& p0_DT, const Eigen::Matrix3d& R_DT, double grasp,
                            double d);

  // Attachment point P_(i) of string i in D.
  Eigen::Vector3d Attachment(int i) const;
  // Lever arm r_(i) = P_(i) − p0 of string i (Eq. 12).
  Eigen::Vector3d LeverArm(int i) const;
  // Grip rotation R_DT from the pole vectors (ARCHITECTURE.md): b = normalize(p̂1 + p̂2),
  // a = normalize(p̂2 − p̂1), x = (b + a)/√2, y = (b − a)/√2, z = a × b. Columns x, y, z.
  Eigen::Matrix3d Rotation() const;
  // Grasp angle θ between p1 and p2 (rad), π/2 at rest.
  double Grasp() const;
  // Unit normal n = p1 × p2 / |p1 × p2| of the grip plane (Eq. 14).
  Eigen::Vector3d Normal() const;
  // Packs (p0, p1, p2) as a 9-vector, the variable order of the Jacobian.
  Vector9d Packed() const;
  static GripPose Unpacked(const Vector9d& v);
};

// Angle (rad) of the rotation R_a^T R_b, in [0, π].
double RotationAngleBetween(const Eigen::Matrix3d& R_a, const Eigen::Matrix3d& R_b);

}  // namespace spidarcad::haptics
