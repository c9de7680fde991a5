// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
// The rotation update of the haptic side, written once: integrating an angular velocity (the
// virtual-coupling bodies of PointShellField and AssemblyField, the simulated hand, the Newton
// steps of forward kinematics and calibration, the window's grip drag) and its inverse, the
// rotation vector of a rotation.
//
// Convention: left (spatial) update. A body with orientation R_AB (frame B in frame A) turning
// at angular velocity ω (rad/s, expressed in A) for h seconds moves to
//     R_AB ← exp([ω h]×) R_AB,
// exp(v) the rotation by the angle |v| about the unit axis v/|v| (the identity for v = 0). A
// Newton step's rotation vector δ (rad) is the case ω = δ, h = 1; a rotation by the angle h about
// the unit axis u is ω = u (h may be negative). The angle is computed as |ω|·h and the axis as
// ω/|ω|, the same way for every caller; a zero or NaN angle leaves the rotation as it is.
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>

namespace spidarcad::haptics {

// q ← exp(ω h) q, then normalised (q need not be exactly unit). ω in rad/s in the frame q maps
// to, h in s; a zero or NaN angle |ω|·h only normalises.
Eigen::Quaterniond IntegrateRotation(const Eigen::Quaterniond& q, const Eigen::Vector3d& w,
                                     double h);
// R ← exp(ω h) R (3 by 3 rotation; not re-orthonormalised). A zero or NaN angle returns R.
Eigen::Matrix3d IntegrateRotation(const Eigen::Matrix3d& R, const Eigen::Vector3d& w, double h);
// The rotation vector angle·axis (rad, angle in [0, π]) of the unit quaternion q, the inverse of
// exp: the shorter of q and −q is taken. Below |vec(q)| = 1e-12 the first-order 2·vec(q).
Eigen::Vector3d RotationVector(Eigen::Quaterniond q);

}  // namespace spidarcad::haptics
