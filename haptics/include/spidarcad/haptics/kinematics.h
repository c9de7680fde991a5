// SPIDAR-G kinematics: string lengths from a grip pose (inverse) and a grip pose from string
// lengths (forward). Frame D, metres, radians. Real-time safe: no allocation, no exceptions
// in InverseKinematics, StringJacobian, PoseJacobian, ClosedFormPose and
// ForwardKinematics::Solve (fixed-size Eigen types only).
//
// String numbering is 0-based in code (string i in code is string i+1 in the paper).
// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#pragma once

#include <cstdint>

#include "spidarcad/haptics/geometry.h"

namespace spidarcad::haptics {

using Matrix87d = Eigen::Matrix<double, 8, 7>;

// String lengths l_i = |Q_i − P_(i)| (Eq. 6) for a grip pose, in m. Shape 8. Any pose is
// accepted (|p1| = |p2| = d is not checked); NaN in gives NaN out.
Vector8d InverseKinematics(const SpidarGeometry& geometry, const GripPose& pose);

// Jacobian ∂l/∂(p0, p1, p2) of the string lengths with respect to the packed pose, 8 by 9.
// Row i: [−c_i, −s_i c_i on the columns of its pole, 0 on the other pole] with s_i = StringEnd(i)
// and c_i the unit vector from P_(i) toward Q_i (Eq. 11).
Matrix89d StringJacobian(const SpidarGeometry& geometry, const GripPose& pose);

// Jacobian of the string lengths with respect to the 7 pose coordinates of the grip, 8 by 7:
// columns (δp0 [m], δω [rad], δθ [rad]) where δω is a small rotation of the whole grip about
// p0 expressed in D (P ← p0 + exp(δω×) r) and δθ opens the grasp angle (p1 turns by −δθ/2 and
// p2 by +δθ/2 about n). Row i = [−c_iᵀ, −(r_i × c_i)ᵀ, ½ δ_i n·(r_i × c_i)]: the force and
// moment rows of the wrench matrix (Eq. 10) with a minus sign and the grasp row times ½
// (virtual work: τᵀ δl = −qᵀ (δp0, δω, −δθ/2)).
Matrix87d PoseJacobian(const SpidarGeometry& geometry, const GripPose& pose);

// Why ForwardKinematics refused or how it ended.
enum class FkStatus : std::uint8_t {
  kOk = 0,            // converged; the pose is valid
  kInvalidInput,      // a length is NaN, infinite, negative or zero
  kUnreachable,       // no pose with its centre inside the frame reproduces the lengths:
                      // RMS residual above FkSettings::max_residual
  kNotConverged,      // the iteration budget ran out before convergence
  kSingular,          // the pose is degenerate: grasp below FkSettings::min_grasp or above
                      // π − min_grasp (poles nearly parallel), or error gain above
                      // FkSettings::max_error_gain (lengths barely determine the pose)
};

// One word for a status, as printed by `spidarcad fk --batch`: "ok", "invalid_input",
// "unreachable", "not_converged", "singular".
const char* FkStatusName(FkStatus status);

// Settings for ForwardKinematics (defaults tuned for the paper's encoders and device).
struct FkSettings {
  // Most Gauss-Newton iterations per attempt (warm start, then closed-form start). Typical use
  // needs 2–4; near singular poses and with large length errors convergence is linear and
  // can take 10 or more. Each iteration costs about 1 µs (2-core test machine).
  int max_iterations = 20;
  // Converged when the last update moved every attachment point by less than this, in m
  // (|δp0| + d|δω| + d|δθ|/2). Far below the encoder's 25 µm count.
  double step_tolerance = 1e-9;
  // Refuse (kUnreachable) when the RMS string residual exceeds this, in m. The default is
  // about 40 quantization steps of the paper's encoder (0.025 mm per count): it accepts a
  // calibrated device with sub-millimetre length error and refuses a string off by about a
  // centimetre. Raise it for a poorly calibrated device (0.8 % length error, as the paper
  // measured after calibration, gives RMS residuals near 1 mm: use ~5e-3).
  double max_residual = 1e-3;
  // Refuse (kSingular) when the grasp angle is below this or above π minus this, in rad:
  // with (nearly) parallel poles the roll of the grip about them is unobservable.
  double min_grasp = 0.0175;  // 1°
  // Refuse (kSingular) when FkResult::error_gain exceeds this: near such poses a length error
  // of one encoder count moves the fitted pose by more than max_error_gain counts.
  double max_error_gain = 1e3;
  // Start from the previous good pose (exact and cheap during motion); fall back to the closed
  // form when that start does not converge to an acceptable pose.
  bool warm_start = true;
};

// Result of a forward-kinematics solve. When status != kOk every number is NaN.
struct FkResult {
  GripPose pose;                        // p0, p1, p2 in D, |p1| = |p2| = d to rounding
  Eigen::Matrix3d R_DT = Eigen::Matrix3d::Identity();  // grip rotation (GripPose::Rotation)
  double grasp = 0;                     // angle between p1 and p2, rad
  double residual = 0;                  // RMS of (model length − measured length), m
  // Sensitivity of the pose to length errors: 1/σ_min of ∂l/∂(p0, d·ω, d·θ), i.e. the largest
  // motion of the pose coordinates (m of attachment-point motion) per metre of length error
  // (Euclidean norms). About 2–5 in the middle of the frame; it grows without bound near the
  // singular poses of the SPIDAR-G (see README) and as the grasp approaches 0 or π.
  double error_gain = 0;
  int iterations = 0;                   // Gauss-Newton iterations used (all attempts)
  bool used_closed_form = false;        // the closed-form start was needed (no usable warm start)
  FkStatus status = FkStatus::kInvalidInput;
};

// Closed-form pose from 8 lengths (the paper's Index 1, re-derived in ERRATA.md), without
// refinement. x, x1, y, y2 come from pairwise differences; each pole then gives a cubic in
// W = (z − c)² (pole 1) or V = (z + c)² (pole 2). Every real root (and every stationary point,
// which stands in for a pair of roots lost to noise) with the grip centre inside the frame
// (|z| < c) is a candidate; the candidate whose pose best reproduces all 8 lengths wins. The
// pole vectors are rescaled to length d. Exact (to rounding) for exact lengths.
// Returns false (pose untouched) when no candidate exists.
bool ClosedFormPose(const SpidarGeometry& geometry, const Vector8d& lengths, GripPose* pose);

// Forward kinematics: 8 measured lengths -> pose, refined by Gauss-Newton on all 8 strings
// over the 7 pose coordinates (p0, rotation increment, grasp angle), so |p1| = |p2| = d holds
// exactly. With a large residual (> 0.1 mm RMS) or slow progress near a singular pose, steps
// use the full Hessian (differences of the gradient) instead. Keeps the last good pose as the
// warm start of the next call; falls back to ClosedFormPose when that start fails. No
// allocation in Solve.
class ForwardKinematics {
 public:
  // The geometry must be valid (SpidarGeometry::Validate); settings are used as given.
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
