// SPIDAR-G kinematics: string lengths from a grip pose (inverse) and a grip pose from string
// lengths (forward). Frame D, metres, radians. Real-time safe: no allocation, no exceptions
// in InverseKinematics, StringJacobian, PoseJacobian, ClosedFormPose and
// ForwardKinematics::Solve (fixed-size Eigen types only).
//
// String numbering is 0-based in code (string i in code is string i+1 in the paper).
// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <limits>

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
  kOk = 0,        // converged; the pose is valid
  kInvalidInput,  // a length is NaN, infinite, negative or zero
  kUnreachable,   // no pose with its centre inside the frame reproduces the lengths:
                  // RMS residual above FkSettings::max_residual
  kNotConverged,  // the iteration budget ran out before convergence
  kSingular,      // the pose is degenerate: grasp below FkSettings::min_grasp or above
                  // π − min_grasp (poles nearly parallel), or error gain above
                  // FkSettings::max_error_gain (lengths barely determine the pose)
  kAmbiguous,     // two distinct poses (branches of the closed form) both reproduce the
                  // lengths within FkSettings::branch_residual: the lengths cannot tell
                  // which one the grip is in (checked on closed-form starts only, see Solve)
};

// One word for a status, as printed by `spidarcad fk --batch`: "ok", "invalid_input",
// "unreachable", "not_converged", "singular", "ambiguous".
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
  // Branch check (FkStatus::kAmbiguous), off when branch_residual is 0 (the default): a
  // second refined pose farther than branch_separation from the chosen one (m, largest
  // distance between corresponding centres and pole tips) whose RMS residual is below
  // branch_residual (m) is a competing branch. Set branch_residual to a bound on the RMS of
  // the real length errors: a wrong branch can only fit better than the true one when its RMS
  // residual is below that of the errors, and then so is the true branch's, so the check sees
  // both. Half an encoder count (1.26e-5 m) covers quantized lengths, ~5e-3 (with
  // max_residual 5e-3) 0.8 % length error. Such near-duplicates exist: e.g. a pose at a 160°
  // grasp whose lengths a pose at a 56° grasp, 5 cm lower, reproduces to 7 µm RMS. Near the
  // singular set the fit's valley is so flat that poses far apart fit within such errors:
  // those are refused too.
  double branch_separation = 1e-3;
  double branch_residual = 0;
};

// Result of a forward-kinematics solve. When status != kOk every number is NaN.
struct FkResult {
  GripPose pose;  // p0, p1, p2 in D, |p1| = |p2| = d to rounding
  Eigen::Matrix3d R_DT = Eigen::Matrix3d::Identity();  // grip rotation (GripPose::Rotation)
  double grasp = 0;                                    // angle between p1 and p2, rad
  double residual = 0;  // RMS of (model length − measured length), m
  // Sensitivity of the pose to length errors: 1/σ_min of ∂l/∂(p0, d·ω, d·θ), i.e. the largest
  // motion of the pose coordinates (m of attachment-point motion) per metre of length error
  // (Euclidean norms). About 2–5 in the middle of the frame; it grows without bound near the
  // singular poses of the SPIDAR-G (see README) and as the grasp approaches 0 or π.
  double error_gain = 0;
  int iterations = 0;             // Gauss-Newton iterations used (all attempts)
  int branch_iterations = 0;      // further iterations spent on the branch check
  bool used_closed_form = false;  // the closed-form start was needed (no usable warm start)
  FkStatus status = FkStatus::kInvalidInput;
};

// Closed-form pose from 8 lengths (the paper's Index 1, re-derived in docs/architecture.md),
// without refinement. x, x1, y, y2 come from pairwise differences; each pole then gives a cubic in
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
// warm start of the next call; falls back to ClosedFormPose when that start fails (and tries
// the next closed-form candidates when the best one does not converge to a fitting pose).
// Branch check, on a closed-form start with FkSettings::branch_residual > 0: from the other
// closed-form candidates (RMS residual below 10 × max_residual), the chosen pose moved 1 and
// 4 cm along its two weakest directions, and 48 orientations at the chosen centre (grip normal
// along ±x, ±y, ±z, four turns about it, grasps 60° and 120°), Gauss-Newton looks for a second
// pose inside the frame, farther than branch_separation from the chosen one, with RMS
// residual below branch_residual; if one exists the solve refuses with kAmbiguous rather than
// pick a branch by a residual difference the noise can flip. The check costs up to ~60 more
// refinements (about 0.1–3 ms); a converged warm start follows the branch of the previous pose
// and skips it. No allocation in Solve.
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
  // The weakest direction (scaled pose coordinates) of the last refinement: the start of the
  // next error gain's inverse iteration (zero: none yet).
  Vector7d weak_ = Vector7d::Zero();
};

// ---------------------------------------------------------------------------------------------
// Conditioning, singular set and error bound of forward kinematics (docs/kinematics.md).

// How well the 8 lengths determine the pose near `pose`, from the 8 by 7 Jacobian Js of the
// lengths with respect to the scaled pose coordinates (δp0 [m], d·δω [m], d·δθ [m]) (columns of
// PoseJacobian with the last four times 1/d). The interior singular set of the SPIDAR-G is where
// Js loses rank (sigma_min = 0): a combination of centre, rotation and grasp motion changes no
// length to first order. Any pose is accepted; |p1| = |p2| = d is assumed. No allocation.
struct FkConditioning {
  double sigma_min = 0;  // smallest singular value of Js (m of length per m of pose motion)
  double sigma_max = 0;  // largest singular value of Js
  // 1/sigma_min: largest pose motion (m) per m of length error, Euclidean norms; the same
  // number as FkResult::error_gain. Infinite on the singular set.
  double error_gain = 0;
  // First-order worst case of the error of p0 along x, y, z (m) per m of error bound on each
  // string (|δl_i| ≤ 1): the 1-norms of the first three rows of the pseudo-inverse of Js.
  Eigen::Vector3d position_gain = Eigen::Vector3d::Zero();
};

// Conditioning of forward kinematics at `pose` (see FkConditioning).
FkConditioning FkConditioningAt(const SpidarGeometry& geometry, const GripPose& pose);

// Pose coordinates that a slice of the workspace can run along. The grip rotation is
// R_DT = Rz(yaw)·Ry(pitch)·Rx(roll) (rad, axes of D); the grasp is the angle between the poles.
enum class PoseAxis : std::uint8_t { kX, kY, kZ, kRoll, kPitch, kYaw, kGrasp };

// One word per axis: "x", "y", "z", "roll", "pitch", "yaw", "grasp".
const char* PoseAxisName(PoseAxis axis);

// A two-dimensional slice of the 7-dimensional pose space: a regular grid over two coordinates
// (u along columns, v along rows), the other five fixed at the base pose.
struct FkSlice {
  Eigen::Vector3d p0 = Eigen::Vector3d::Zero();   // base centre in D, m
  Eigen::Vector3d rpy = Eigen::Vector3d::Zero();  // base roll, pitch, yaw, rad
  double grasp = 1.5707963267948966;              // base grasp angle, rad
  PoseAxis u_axis = PoseAxis::kZ;                 // coordinate along the columns
  double u_min = -0.2, u_max = 0.2;               // its range (m or rad), inclusive
  int u_count = 81;                               // number of samples, >= 2
  PoseAxis v_axis = PoseAxis::kPitch;             // coordinate along the rows
  double v_min = -1.5, v_max = 1.5;
  int v_count = 61;
  // FkSettings::branch_residual of the FK solves behind FkConditioningMap::fk_status (m):
  // half a count of the paper's encoder, so the map shows where FK on quantized lengths
  // refuses as ambiguous.
  double branch_residual = 1.2566370614359173e-5;
};

// The pose of the slice's grid point (u, v) (m or rad as the axes say), pole half-length d.
GripPose SlicePose(const FkSlice& slice, double u, double v, double d);

// The conditioning sampled on a slice, for plotting. Matrices are v_count rows by u_count
// columns: entry (j, k) belongs to (u(k), v(j)).
struct FkConditioningMap {
  Eigen::VectorXd u;           // column coordinates (u_count)
  Eigen::VectorXd v;           // row coordinates (v_count)
  Eigen::MatrixXd error_gain;  // FkConditioning::error_gain (m/m; inf on the singular set)
  // Euclidean norm of FkConditioning::position_gain (m of p0 error per m of length error
  // bound): times the length tolerance Q, the first-order part of FkPositionBound.
  Eigen::MatrixXd position_gain;
  // Outcome of a cold ForwardKinematics::Solve (default settings but FkSlice::branch_residual)
  // on the exact lengths of the grid pose, as the FkStatus number (0 ok, 4 singular,
  // 5 ambiguous): where FK refuses, and why.
  Eigen::MatrixXd fk_status;
  // Grid points outside the frame or with a string shorter than 1 mm hold NaN (status NaN).
};

// Samples FkConditioningAt and a cold FK solve over the slice's grid. Throws
// std::invalid_argument when a count is below 2, a range is empty or not finite, or the
// geometry is invalid. Allocates (not for the haptic tick).
FkConditioningMap SampleFkConditioning(const SpidarGeometry& geometry, const FkSlice& slice);

// Worst-case bound on the error of a forward-kinematics pose when every measured length is
// within ±tolerance of the true length (see docs/kinematics.md for the derivation):
//  - x and y: exact intervals of x = (−l1² + l2² − l3² + l4²)/(8a) and
//    y = (−l5² − l6² + l7² + l8²)/(8b) over the box of lengths (docs/architecture.md);
//  - every coordinate: J⁺ applied to the residual and to the error box, plus a rigorous bound
//    on the second-order Taylor remainder of the lengths along the path from the estimate to
//    the true pose (|∂²l_i| ≤ 2.25·(1/d + 1/l_i) per squared scaled step), solved as
//    δ ≤ A + B δ² for the distance δ to the true pose; per coordinate the smaller bound wins.
// The bound covers every true pose within `uniqueness_radius` of the estimate (the small root
// of the quadratic; beyond its large root lies only another branch, which the kAmbiguous check
// of ForwardKinematics looks for). No allocation.
struct FkBound {
  // Bound on |p0_true − p0_estimate| along x, y, z, m; +inf when 4AB ≥ 1 (the pose is too
  // poorly conditioned for the tolerance: no useful bound exists, treat the pose as
  // unreliable); NaN for NaN input.
  Eigen::Vector3d axis = Eigen::Vector3d::Constant(std::numeric_limits<double>::quiet_NaN());
  // Bound on the Euclidean position error |p0_true − p0_estimate|, m: the norm of `axis`.
  double position = std::numeric_limits<double>::quiet_NaN();
  // Bound δ on the whole scaled pose error (m of attachment-point motion), and the radius of
  // the region around the estimate that the bound covers (m, scaled pose coordinates).
  double pose = std::numeric_limits<double>::quiet_NaN();
  double uniqueness_radius = std::numeric_limits<double>::quiet_NaN();
};

// Bound for an estimated pose (normally FkResult::pose, |p1| = |p2| = d) of the measured
// `lengths` (m, shape 8), each known to ±tolerance m (tolerance >= 0; half an encoder count for
// quantized lengths).
FkBound FkPositionBound(const SpidarGeometry& geometry, const GripPose& estimate,
                        const Vector8d& lengths, double tolerance);

}  // namespace spidarcad::haptics
