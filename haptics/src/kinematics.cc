// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#include "spidarcad/haptics/kinematics.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>

#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>
#include <Eigen/Geometry>

namespace spidarcad::haptics {

namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
constexpr double kSqrt1_2 = 0.70710678118654752440;
using Matrix7d = Eigen::Matrix<double, 7, 7>;

// --- Inverse kinematics helpers ------------------------------------------------------------

// Sum of squared residuals (model − measured) of a pose; optionally the residuals and the
// 8 by 7 Jacobian of PoseJacobian.
double EvaluatePose(const SpidarGeometry& geometry, const GripPose& pose,
                    const Vector8d& lengths, Vector8d* residual, Matrix87d* jacobian) {
  Eigen::Vector3d n = pose.p1.cross(pose.p2);
  const double n_norm = n.norm();
  if (n_norm > 0) n /= n_norm;
  double cost = 0;
  for (int i = 0; i < kNumStrings; ++i) {
    const Eigen::Vector3d r = pose.LeverArm(i);
    const Eigen::Vector3d diff = geometry.Corner(i) - (pose.p0 + r);
    const double l = diff.norm();
    const double res = l - lengths(i);
    cost += res * res;
    if (residual != nullptr) (*residual)(i) = res;
    if (jacobian != nullptr) {
      const Eigen::Vector3d c = diff / l;
      const Eigen::Vector3d rc = r.cross(c);
      jacobian->row(i) << -c.transpose(), -rc.transpose(),
          0.5 * StringDelta(i) * n.dot(rc);
    }
  }
  return cost;
}

// --- Minimal pose parameterisation ---------------------------------------------------------

// The 7 pose coordinates: centre, grip rotation R_DT and grasp angle.
struct PoseParams {
  Eigen::Vector3d p0;
  Eigen::Matrix3d R;
  double grasp;
};

// Pose of GripPose::FromFrame, written out (p1_T = d/√2 (ch − sh, ch + sh, 0), etc.).
GripPose PoseFromParams(const PoseParams& q, double d) {
  const double ch = std::cos(0.5 * q.grasp);
  const double sh = std::sin(0.5 * q.grasp);
  const double k = d * kSqrt1_2;
  GripPose pose;
  pose.p0 = q.p0;
  pose.p1 = k * ((ch - sh) * q.R.col(0) + (ch + sh) * q.R.col(1));
  pose.p2 = k * ((ch + sh) * q.R.col(0) + (ch - sh) * q.R.col(1));
  return pose;
}

PoseParams ParamsFromPose(const GripPose& pose) {
  return PoseParams{pose.p0, pose.Rotation(), pose.Grasp()};
}

// Applies the update (δp0, δω, δθ) to q.
PoseParams Apply(const PoseParams& q, const Vector7d& delta) {
  PoseParams out = q;
  out.p0 += delta.head<3>();
  const Eigen::Vector3d w = delta.segment<3>(3);
  const double angle = w.norm();
  if (angle > 0) out.R = Eigen::AngleAxisd(angle, w / angle).toRotationMatrix() * q.R;
  out.grasp += delta(6);
  return out;
}

// Largest motion of an attachment point (m) for a step in scaled coordinates.
double StepSize(const Vector7d& step) {
  return step.head<3>().norm() + step.segment<3>(3).norm() + 0.5 * std::abs(step(6));
}

struct GnOutcome {
  PoseParams q;
  double cost = kNaN;        // sum of squared residuals at q
  int iterations = 0;        // linear solves
  bool converged = false;
  double error_gain = kNaN;  // 1/σ_min of the scaled Jacobian at the last linearisation
};

// 1/σ_min of Js from H = Jsᵀ Js (smallest eigenvalue of a fixed-size 7 by 7: no allocation).
double ErrorGain(const Matrix7d& H) {
  const Eigen::SelfAdjointEigenSolver<Matrix7d> eigen(H, Eigen::EigenvaluesOnly);
  const double lambda_min = eigen.eigenvalues()(0);
  return lambda_min > 0 ? 1 / std::sqrt(lambda_min) : std::numeric_limits<double>::infinity();
}

// Gauss-Newton on the 8 string residuals over the 7 pose coordinates, with step halving when
// a full step would increase the cost (never needed near the solution; it only guards starts
// far away). Columns of the rotation and grasp coordinates are scaled by 1/d so that every
// unknown is in metres of attachment-point motion.
GnOutcome GaussNewton(const SpidarGeometry& geometry, const Vector8d& lengths,
                      const PoseParams& start, const FkSettings& settings) {
  constexpr int kMaxHalvings = 12;
  // Sum of squared residuals above which Newton steps are used: 8 strings at 0.1 mm RMS,
  // four encoder counts. Below it Gauss-Newton converges in 2–3 steps.
  constexpr double kNewtonCost = 8 * 1e-4 * 1e-4;
  const double d = geometry.d;
  GnOutcome out;
  out.q = start;
  Vector8d res;
  Matrix87d J;
  out.cost = EvaluatePose(geometry, PoseFromParams(out.q, d), lengths, &res, &J);
  if (!std::isfinite(out.cost)) return out;
  Eigen::LDLT<Matrix7d> ldlt;
  double last_size = 0;  // length of the last accepted step
  for (int it = 0; it < settings.max_iterations; ++it) {
    Matrix87d Js = J;
    Js.rightCols<4>() /= d;
    const Matrix7d H = Js.transpose().lazyProduct(Js);
    const Vector7d g = Js.transpose().lazyProduct(res);
    ldlt.compute(H);
    ++out.iterations;
    Vector7d step = -ldlt.solve(g);
    if (ldlt.info() != Eigen::Success || !step.allFinite()) return out;
    double size = StepSize(step);
    if (size <= settings.step_tolerance) {
      out.converged = true;
      out.error_gain = ErrorGain(H);
      return out;
    }
    if (out.cost > kNewtonCost || (it > 0 && size > 0.01 * last_size)) {
      // Large residual, or slow (linear) progress near singular poses: Gauss-Newton alone
      // converges slowly there, its model lacking the residual curvature Σ res_i ∇²l_i. Take a
      // Newton step with the Hessian from differences of the gradient when it is positive
      // definite.
      constexpr double kH = 1e-7;  // m of attachment-point motion
      Matrix7d H_full;
      for (int k = 0; k < 7; ++k) {
        Vector7d e = Vector7d::Zero();
        e(k) = k < 3 ? kH : kH / d;
        Vector8d res_k;
        Matrix87d J_k;
        EvaluatePose(geometry, PoseFromParams(Apply(out.q, e), d), lengths, &res_k, &J_k);
        J_k.rightCols<4>() /= d;
        H_full.col(k) = (J_k.transpose().lazyProduct(res_k) - g) / kH;
      }
      const Matrix7d H_sym = 0.5 * (H_full + H_full.transpose());
      const Eigen::LDLT<Matrix7d> newton(H_sym);
      if (newton.info() == Eigen::Success && newton.isPositive() &&
          (newton.vectorD().array() > 0).all()) {
        const Vector7d newton_step = -newton.solve(g);
        if (newton_step.allFinite()) {
          step = newton_step;
          size = StepSize(step);
        }
      }
    }
    step.tail<4>() /= d;  // back to rad
    bool accepted = false;
    double lambda = 1.0;
    for (int h = 0; h <= kMaxHalvings; ++h) {
      const PoseParams trial = Apply(out.q, lambda * step);
      Vector8d trial_res;
      Matrix87d trial_J;
      const double trial_cost =
          EvaluatePose(geometry, PoseFromParams(trial, d), lengths, &trial_res, &trial_J);
      // Accept any decrease; equality to rounding also counts (at the noise floor the cost
      // no longer changes).
      if (std::isfinite(trial_cost) && trial_cost <= out.cost * (1 + 1e-12) + 1e-30) {
        accepted = true;
        out.q = trial;
        out.cost = trial_cost;
        res = trial_res;
        J = trial_J;
        break;
      }
      lambda *= 0.5;
    }
    if (!accepted) {
      // No descent along the Gauss-Newton direction: a minimum to rounding when the step is
      // tiny (far below the sensor floor), otherwise a failure.
      out.converged = size <= 100 * settings.step_tolerance;
      out.error_gain = ErrorGain(H);
      return out;
    }
    last_size = lambda * size;
    if (last_size <= settings.step_tolerance) {
      out.converged = true;
      out.error_gain = ErrorGain(H);
      return out;
    }
  }
  return out;
}

// --- Closed form ---------------------------------------------------------------------------

double Cubic(const double k[4], double w) { return ((k[3] * w + k[2]) * w + k[1]) * w + k[0]; }
double CubicSlope(const double k[4], double w) { return (3 * k[3] * w + 2 * k[2]) * w + k[1]; }

// Root of the cubic in [lo, hi] where f(lo) and f(hi) differ in sign: Newton's method kept
// inside the bracket, bisection when Newton leaves it.
double BracketedRoot(const double k[4], double lo, double hi) {
  double f_lo = Cubic(k, lo);
  if (f_lo == 0) return lo;
  double w = 0.5 * (lo + hi);
  for (int it = 0; it < 100; ++it) {
    const double f = Cubic(k, w);
    if (f == 0) return w;
    if ((f < 0) == (f_lo < 0)) {
      lo = w;
      f_lo = f;
    } else {
      hi = w;
    }
    const double slope = CubicSlope(k, w);
    double next = slope != 0 ? w - f / slope : 0.5 * (lo + hi);
    if (!(next > lo && next < hi)) next = 0.5 * (lo + hi);
    // Converged when Newton's correction or the bracket reaches rounding level.
    const double scale = 4e-16 * std::max(std::abs(w), 1e-300);
    if (std::abs(next - w) <= scale || hi - lo <= scale) return next;
    w = next;
  }
  return w;
}

// Real roots and stationary points of k3 w³ + k2 w² + k1 w + k0 (k3 > 0) in [lo, hi].
// Writes at most 5 values to out and returns their number.
int CubicCandidates(const double k[4], double lo, double hi, double out[5]) {
  double breaks[4];
  int num_breaks = 0;
  breaks[num_breaks++] = lo;
  int count = 0;
  // Stationary points: 3 k3 w² + 2 k2 w + k1 = 0.
  const double qa = 3 * k[3], qb = 2 * k[2], qc = k[1];
  const double disc = qb * qb - 4 * qa * qc;
  if (disc >= 0) {
    const double sq = std::sqrt(disc);
    // Numerically stable pair of roots.
    const double t = -0.5 * (qb + std::copysign(sq, qb));
    double s1 = t / qa;
    double s2 = t != 0 ? qc / t : s1;
    if (s1 > s2) std::swap(s1, s2);
    for (double s : {s1, s2}) {
      if (s > lo && s < hi) {
        breaks[num_breaks++] = s;
        out[count++] = s;
      }
    }
  }
  breaks[num_breaks++] = hi;
  for (int j = 0; j + 1 < num_breaks; ++j) {
    const double f0 = Cubic(k, breaks[j]);
    const double f1 = Cubic(k, breaks[j + 1]);
    if ((f0 <= 0 && f1 >= 0) || (f0 >= 0 && f1 <= 0)) {
      out[count++] = BracketedRoot(k, breaks[j], breaks[j + 1]);
    }
  }
  return count;
}

// Reduced unknowns of one pole as a function of the squared distance W of the grip centre
// from the frame face its strings go to: along = alpha + beta W, across = (gamma − delta W)/Z
// with Z = ±√W; the pole-length constraint is along² + across² = e.
struct PoleReduction {
  double alpha, beta, gamma, delta, e;
  // Coefficients (k0..k3) of (alpha + beta W)² W + (gamma − delta W)² − e W.
  void Coefficients(double k[4]) const {
    k[3] = beta * beta;
    k[2] = 2 * alpha * beta + delta * delta;
    k[1] = alpha * alpha - 2 * gamma * delta - e;
    k[0] = gamma * gamma;
  }
};

}  // namespace

Vector8d InverseKinematics(const SpidarGeometry& geometry, const GripPose& pose) {
  Vector8d l;
  for (int i = 0; i < kNumStrings; ++i) l(i) = (geometry.Corner(i) - pose.Attachment(i)).norm();
  return l;
}

Matrix89d StringJacobian(const SpidarGeometry& geometry, const GripPose& pose) {
  Matrix89d J = Matrix89d::Zero();
  for (int i = 0; i < kNumStrings; ++i) {
    const Eigen::Vector3d diff = geometry.Corner(i) - pose.Attachment(i);
    const Eigen::Vector3d c = diff / diff.norm();
    J.block<1, 3>(i, 0) = -c.transpose();
    J.block<1, 3>(i, 3 + 3 * StringPole(i)) = -StringEnd(i) * c.transpose();
  }
  return J;
}

Matrix87d PoseJacobian(const SpidarGeometry& geometry, const GripPose& pose) {
  Matrix87d J;
  EvaluatePose(geometry, pose, InverseKinematics(geometry, pose), nullptr, &J);
  return J;
}

const char* FkStatusName(FkStatus status) {
  switch (status) {
    case FkStatus::kOk:
      return "ok";
    case FkStatus::kInvalidInput:
      return "invalid_input";
    case FkStatus::kUnreachable:
      return "unreachable";
    case FkStatus::kNotConverged:
      return "not_converged";
    case FkStatus::kSingular:
      return "singular";
  }
  return "unknown";
}

bool ClosedFormPose(const SpidarGeometry& geometry, const Vector8d& lengths, GripPose* pose) {
  const double a = geometry.a, b = geometry.b, c = geometry.c, d = geometry.d;
  const Vector8d L = lengths.array().square();
  // Pairwise differences (ERRATA): u = P+1, v = P−1, s = P+2, t = P−2.
  const double ux = (L(1) - L(0)) / (4 * a);
  const double vx = (L(3) - L(2)) / (4 * a);
  const double sy = (L(6) - L(4)) / (4 * b);
  const double ty = (L(7) - L(5)) / (4 * b);
  const double x = 0.5 * (ux + vx), x1 = 0.5 * (ux - vx);
  const double y = 0.5 * (sy + ty), y2 = 0.5 * (sy - ty);
  // Pairwise sums: (uy − b)² + (uz − c)² = Au, (vy + b)² + (vz − c)² = Av,
  //                (sx − a)² + (sz + c)² = As, (tx + a)² + (tz + c)² = At.
  const double Au = 0.5 * (L(0) + L(1)) - ux * ux - a * a;
  const double Av = 0.5 * (L(2) + L(3)) - vx * vx - a * a;
  const double As = 0.5 * (L(4) + L(6)) - sy * sy - b * b;
  const double At = 0.5 * (L(5) + L(7)) - ty * ty - b * b;
  // Pole 1, W = (z − c)²: sum and |p1| = d give y1 = alpha + W/(2b); the difference gives
  // y (y1 − b) + (z − c) z1 = (Au − Av)/4.
  PoleReduction pole1;
  pole1.alpha = (y * y + d * d - x1 * x1 + b * b - 0.5 * (Au + Av)) / (2 * b);
  pole1.beta = 1 / (2 * b);
  pole1.gamma = 0.25 * (Au - Av) - y * (pole1.alpha - b);
  pole1.delta = y * pole1.beta;
  pole1.e = d * d - x1 * x1;
  // Pole 2, V = (z + c)²: x2 = alpha + V/(2a); x (x2 − a) + (z + c) z2 = (As − At)/4.
  PoleReduction pole2;
  pole2.alpha = (x * x + d * d - y2 * y2 + a * a - 0.5 * (As + At)) / (2 * a);
  pole2.beta = 1 / (2 * a);
  pole2.gamma = 0.25 * (As - At) - x * (pole2.alpha - a);
  pole2.delta = x * pole2.beta;
  pole2.e = d * d - y2 * y2;

  // Candidate z: grip centre inside the frame, so z − c = −√W and z + c = +√V.
  double z_candidates[10];
  int num_z = 0;
  double k[4], roots[5];
  pole1.Coefficients(k);
  const int n1 = CubicCandidates(k, 0.0, 4 * c * c, roots);
  for (int j = 0; j < n1; ++j) z_candidates[num_z++] = c - std::sqrt(std::max(0.0, roots[j]));
  pole2.Coefficients(k);
  const int n2 = CubicCandidates(k, 0.0, 4 * c * c, roots);
  for (int j = 0; j < n2; ++j) z_candidates[num_z++] = -c + std::sqrt(std::max(0.0, roots[j]));

  double best_cost = std::numeric_limits<double>::infinity();
  GripPose best;
  for (int j = 0; j < num_z; ++j) {
    const double z = z_candidates[j];
    const double Z = z - c, Vp = z + c;
    if (!(Z < 0 && Vp > 0)) continue;
    const double W = Z * Z, V = Vp * Vp;
    GripPose candidate;
    candidate.p0 = Eigen::Vector3d(x, y, z);
    const double y1 = pole1.alpha + pole1.beta * W;
    const double z1 = (pole1.gamma - pole1.delta * W) / Z;
    const double x2 = pole2.alpha + pole2.beta * V;
    const double z2 = (pole2.gamma - pole2.delta * V) / Vp;
    candidate.p1 = Eigen::Vector3d(x1, y1, z1);
    candidate.p2 = Eigen::Vector3d(x2, y2, z2);
    const double n1_norm = candidate.p1.norm(), n2_norm = candidate.p2.norm();
    if (!(n1_norm > 0 && n2_norm > 0)) continue;
    candidate.p1 *= d / n1_norm;
    candidate.p2 *= d / n2_norm;
    const double cost = EvaluatePose(geometry, candidate, lengths, nullptr, nullptr);
    if (cost < best_cost) {
      best_cost = cost;
      best = candidate;
    }
  }
  if (!std::isfinite(best_cost)) return false;
  *pose = best;
  return true;
}

ForwardKinematics::ForwardKinematics(const SpidarGeometry& geometry, const FkSettings& settings)
    : geometry_(geometry), settings_(settings), last_pose_(GripPose::Rest(geometry.d)) {}

void ForwardKinematics::Reset() { has_last_ = false; }

FkResult ForwardKinematics::Solve(const Vector8d& lengths) {
  FkResult result;
  auto refuse = [&result](FkStatus status) {
    const Eigen::Vector3d nan3 = Eigen::Vector3d::Constant(kNaN);
    result.pose.p0 = result.pose.p1 = result.pose.p2 = nan3;
    result.R_DT.setConstant(kNaN);
    result.grasp = kNaN;
    result.residual = kNaN;
    result.error_gain = kNaN;
    result.status = status;
    return result;
  };
  for (int i = 0; i < kNumStrings; ++i) {
    if (!std::isfinite(lengths(i)) || lengths(i) <= 0) return refuse(FkStatus::kInvalidInput);
  }

  const double d = geometry_.d;
  // Judges one Gauss-Newton outcome; kOk means it is acceptable.
  auto judge = [&](const GnOutcome& gn) {
    if (!gn.converged) return FkStatus::kNotConverged;
    const double rms = std::sqrt(gn.cost / kNumStrings);
    const Eigen::Vector3d& p0 = gn.q.p0;
    if (!(rms <= settings_.max_residual)) return FkStatus::kUnreachable;
    if (!(std::abs(p0.x()) < geometry_.a && std::abs(p0.y()) < geometry_.b &&
          std::abs(p0.z()) < geometry_.c)) {
      return FkStatus::kUnreachable;
    }
    const double grasp = PoseFromParams(gn.q, d).Grasp();
    if (!(grasp >= settings_.min_grasp && grasp <= std::numbers::pi - settings_.min_grasp) ||
        !(gn.error_gain <= settings_.max_error_gain)) {
      return FkStatus::kSingular;
    }
    return FkStatus::kOk;
  };

  GnOutcome gn;
  FkStatus status = FkStatus::kNotConverged;
  int iterations = 0;
  if (settings_.warm_start && has_last_) {
    gn = GaussNewton(geometry_, lengths, ParamsFromPose(last_pose_), settings_);
    iterations += gn.iterations;
    status = judge(gn);
  }
  if (status != FkStatus::kOk) {
    result.used_closed_form = true;
    GripPose start;
    if (!ClosedFormPose(geometry_, lengths, &start)) {
      result.iterations = iterations;
      return refuse(FkStatus::kUnreachable);
    }
    const double grasp = start.Grasp();
    if (!(std::sin(grasp) > 1e-9)) {
      result.iterations = iterations;
      return refuse(FkStatus::kSingular);
    }
    gn = GaussNewton(geometry_, lengths, ParamsFromPose(start), settings_);
    iterations += gn.iterations;
    status = judge(gn);
  }
  result.iterations = iterations;
  if (status != FkStatus::kOk) return refuse(status);

  result.pose = PoseFromParams(gn.q, d);
  result.R_DT = result.pose.Rotation();
  result.grasp = result.pose.Grasp();
  result.residual = std::sqrt(gn.cost / kNumStrings);
  result.error_gain = gn.error_gain;
  result.status = FkStatus::kOk;
  last_pose_ = result.pose;
  has_last_ = true;
  return result;
}

}  // namespace spidarcad::haptics
