// SPIDAR-G kinematics: string lengths from a grip pose (inverse) and a grip pose from string
// lengths (forward). Frame D, metres, radians. Real-time safe: no allocation, no exceptions
// in InverseKinematics, StringJacobian and ForwardKinematics::Solve.
// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#pragma once

#include <cstdint>

#include "spidarcad/haptics/geometry.h"

namespace spidarcad::haptics {

// String lengths l_i = |Q_i − P_(i)| (Eq. 6) for a grip pose, in m. Shape 8.
Vector8d InverseKinematics(const SpidarGeometry& geometry, const GripPose& pose);

// Jacobian ∂l/∂(p0, p1, p2) of the string lengths with respect to the packed pose, 8 by 9.
// Row i: [−c_i, −s_i c_i on the columns of its pole, 0 on the other pole] with s_i = StringEnd(i)
// and c_i the unit vector from P_(i) toward Q_i (Eq. 11).
Matrix89d StringJacobian(const SpidarGeometry& geometry, const GripPose& pose);

// Why ForwardKinematics refused or how it ended.
enum class FkStatus : std::uint8_t {
  kOk = 0,            // converged; the pose is valid
  kInvalidInput,      // a length is NaN, infinite, negative or zero
  kUnreachable,       // no pose reproduces the lengths: residual far above sensor noise
  kNotConverged,      // the iteration budget ran out before convergence
  kSingular,          // the pose is degenerate (poles parallel, grip on a frame face)
};

// One word for a status, as printed by `spidarcad fk --batch` ("ok", "invalid_input", ...).
const char* FkStatusName(FkStatus status);

// Settings for ForwardKinematics (documented defaults tuned for the paper's encoders).
struct FkSettings {
  // Most Gauss-Newton iterations per solve.
  int max_iterations = 10;
  // Stop when the pose update is below this (m for position, rad for angles).
  double step_tolerance = 1e-10;
  // Refuse (kUnreachable) when the RMS string residual exceeds this, in m. The default is
  // about 40 quantization steps of the paper's encoder (0.025 mm per count) plus margin for
  // calibration error; raise it for a poorly calibrated device.
  double max_residual = 1e-3;
  // Use the previous pose as the starting point when it is close (cheap, exact during motion).
  bool warm_start = true;
};

// Result of a forward-kinematics solve. When status != kOk every number is NaN.
struct FkResult {
  GripPose pose;                        // p0, p1, p2 in D, |p1| = |p2| = d exactly
  Eigen::Matrix3d R_DT;                 // grip rotation, columns x, y, z of T in D
  double grasp = 0;                     // angle between p1 and p2, rad
  double residual = 0;                  // RMS of (model length − measured length), m
  int iterations = 0;                   // Gauss-Newton iterations used
  bool used_closed_form = false;        // the closed-form start was needed (no usable warm start)
  FkStatus status = FkStatus::kInvalidInput;
};

// Closed-form pose from 8 lengths (the paper's Index 1, re-derived in ERRATA.md), without
// refinement. Exact for exact lengths; used as the cold start of ForwardKinematics.
// Returns false when no real pose satisfies the equations.
bool ClosedFormPose(const SpidarGeometry& geometry, const Vector8d& lengths, GripPose* pose);

// Forward kinematics: 8 measured lengths -> pose, refined by Gauss-Newton on all 8 strings
// with the pole-length constraints built into the parameterisation (p0, rotation, grasp).
// Keeps the last good pose as the warm start of the next call. No allocation in Solve.
class ForwardKinematics {
 public:
  explicit ForwardKinematics(const SpidarGeometry& geometry, const FkSettings& settings = {});

  // Solves for the pose that best reproduces `lengths` (m, shape 8).
  FkResult Solve(const Vector8d& lengths);
  // Forgets the warm start (the next Solve starts from the closed form).
  void Reset();

  const SpidarGeometry& geometry() const { return geometry_; }
  const FkSettings& settings() const { return settings_; }

 private:
  SpidarGeometry geometry_;
  FkSettings settings_;
  GripPose last_pose_;
  bool has_last_ = false;
};

}  // namespace spidarcad::haptics
