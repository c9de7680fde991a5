// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#include "spidarcad/haptics/kinematics.h"

#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>
#include <Eigen/Geometry>
#include <Eigen/SVD>
#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>
#include <stdexcept>
#include <string>

#include "spidarcad/haptics/rotation.h"

namespace spidarcad::haptics {

namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
constexpr double kSqrt1_2 = 0.70710678118654752440;
using Matrix7d = Eigen::Matrix<double, 7, 7>;

// --- Inverse kinematics helpers ------------------------------------------------------------

// Sum of squared residuals (model − measured) of a pose; optionally the residuals and the
// 8 by 7 Jacobian of PoseJacobian.
double EvaluatePose(const SpidarGeometry& geometry, const GripPose& pose, const Vector8d& lengths,
                    Vector8d* residual, Matrix87d* jacobian) {
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
      jacobian->row(i) << -c.transpose(), -rc.transpose(), 0.5 * StringDelta(i) * n.dot(rc);
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
  out.R = IntegrateRotation(q.R, delta.segment<3>(3), 1.0);
  out.grasp += delta(6);
  return out;
}

// Largest motion of an attachment point (m) for a step in scaled coordinates.
double StepSize(const Vector7d& step) {
  return step.head<3>().norm() + step.segment<3>(3).norm() + 0.5 * std::abs(step(6));
}

// Largest distance between corresponding centres and pole tips of two poses, m.
double PoseSeparation(const GripPose& a, const GripPose& b) {
  return std::max({(a.p0 - b.p0).norm(), (a.p1 - b.p1).norm(), (a.p2 - b.p2).norm()});
}

struct GnOutcome {
  PoseParams q;
  double cost = kNaN;  // sum of squared residuals at q
  int iterations = 0;  // linear solves
  bool converged = false;
  double error_gain = kNaN;  // 1/σ_min of the scaled Jacobian at the last linearisation
};

// Cholesky factor H = L Lᵀ of a symmetric positive definite 7 by 7, written out for the fixed
// size (Eigen's LDLT and eigen solver spend most of their time on block bookkeeping at n = 7).
struct Cholesky7 {
  double L[7][7] = {};
  // Factors A (lower triangle read); false when a pivot is not positive and finite.
  bool Compute(const Matrix7d& A) {
    for (int j = 0; j < 7; ++j) {
      double diag = A(j, j);
      for (int k = 0; k < j; ++k) diag -= L[j][k] * L[j][k];
      if (!(diag > 0) || !std::isfinite(diag)) return false;
      const double ljj = std::sqrt(diag);
      L[j][j] = ljj;
      for (int i = j + 1; i < 7; ++i) {
        double v = A(i, j);
        for (int k = 0; k < j; ++k) v -= L[i][k] * L[j][k];
        L[i][j] = v / ljj;
      }
    }
    return true;
  }
  // x = A⁻¹ b.
  Vector7d Solve(const Vector7d& b) const {
    double y[7];
    for (int i = 0; i < 7; ++i) {
      double v = b(i);
      for (int k = 0; k < i; ++k) v -= L[i][k] * y[k];
      y[i] = v / L[i][i];
    }
    Vector7d x;
    for (int i = 6; i >= 0; --i) {
      double v = y[i];
      for (int k = i + 1; k < 7; ++k) v -= L[k][i] * x(k);
      x(i) = v / L[i][i];
    }
    return x;
  }
};

// 1/√λ for the smallest eigenvalue λ of H (∞ when λ ≤ 0).
double GainFromEigenvalue(double lambda_min) {
  return lambda_min > 0 ? 1 / std::sqrt(lambda_min) : std::numeric_limits<double>::infinity();
}

// Relative accuracy of the smallest eigenvalue the fast path of ErrorGain accepts: the gain it
// returns is at most half of this above the exact one (never below). The gain is a
// sensitivity (docs/kinematics.md) compared with max_error_gain = 1e3: 0.05 % is far below
// anything it is used for. A tighter bound needs many more steps when the two weakest
// directions have nearly equal eigenvalues (ratio about 0.75 along the benchmark's paths).
constexpr double kGainEigenTolerance = 1e-3;

// 1/σ_min of Js from H = Jsᵀ Js, the smallest eigenvalue λ of a fixed-size 7 by 7 (no
// allocation). Fast path: inverse iteration with `chol` (the factor of H) from *weak (the
// weakest direction of the previous solve; updated), up to 8 steps, accepted when the
// Rayleigh quotient ρ has residual r = |Hx − ρx| ≤ kGainEigenTolerance·ρ and H − (ρ − r)I is
// positive definite: then no eigenvalue lies below ρ − r, and λ ≤ ρ (Rayleigh), so
// λ ∈ (ρ − r, ρ]. Otherwise (or without a factor) Eigen's symmetric eigen solver.
double ErrorGain(const Matrix7d& H, const Cholesky7* chol, Vector7d* weak) {
  if (chol != nullptr && weak != nullptr) {
    Vector7d x = *weak;
    const double norm0 = x.norm();
    if (!(norm0 > 0) || !std::isfinite(norm0)) {
      x = Vector7d::Constant(1 / std::sqrt(7.0));
    } else {
      x /= norm0;
    }
    constexpr int kMaxSteps = 8;
    for (int step = 0; step < kMaxSteps; ++step) {
      x = chol->Solve(x);
      const double n = x.norm();
      if (!(n > 0) || !std::isfinite(n)) break;
      x /= n;
      const Vector7d Hx = H * x;
      const double rho = x.dot(Hx);
      const double r = (Hx - rho * x).norm();
      if (!(rho > 0) || !(r <= kGainEigenTolerance * rho)) continue;
      Cholesky7 shifted;
      Matrix7d A = H;
      A.diagonal().array() -= rho - r;
      if (!shifted.Compute(A)) break;
      *weak = x;
      return GainFromEigenvalue(rho);
    }
  }
  const Eigen::SelfAdjointEigenSolver<Matrix7d> eigen(H);
  if (eigen.info() != Eigen::Success) return GainFromEigenvalue(kNaN);
  if (weak != nullptr) *weak = eigen.eigenvectors().col(0);
  return GainFromEigenvalue(eigen.eigenvalues()(0));
}

// Gauss-Newton on the 8 string residuals over the 7 pose coordinates, with step halving when
// a full step would increase the cost (never needed near the solution; it only guards starts
// far away). Columns of the rotation and grasp coordinates are scaled by 1/d so that every
// unknown is in metres of attachment-point motion.
// `weak` (may be null) is the start of the error gain's inverse iteration, and receives the
// weakest direction at the solution (see ErrorGain).
GnOutcome GaussNewton(const SpidarGeometry& geometry, const Vector8d& lengths,
                      const PoseParams& start, const FkSettings& settings,
                      Vector7d* weak = nullptr) {
  constexpr int kMaxHalvings = 12;
  const double d = geometry.d;
  GnOutcome out;
  out.q = start;
  Vector8d res;
  Matrix87d J;
  out.cost = EvaluatePose(geometry, PoseFromParams(out.q, d), lengths, &res, &J);
  if (!std::isfinite(out.cost)) return out;
  Cholesky7 chol;
  double last_size = 0;  // length of the last accepted step
  for (int it = 0; it < settings.max_iterations; ++it) {
    Matrix87d Js = J;
    Js.rightCols<4>() /= d;
    const Matrix7d H = Js.transpose().lazyProduct(Js);
    const Vector7d g = Js.transpose().lazyProduct(res);
    ++out.iterations;
    if (!chol.Compute(H)) return out;
    Vector7d step = -chol.Solve(g);
    if (!step.allFinite()) return out;
    double size = StepSize(step);
    if (size <= settings.step_tolerance) {
      out.converged = true;
      out.error_gain = ErrorGain(H, &chol, weak);
      return out;
    }
    if (it > 0 && size > 0.01 * last_size) {
      // Slow (linear) progress: a large residual (length errors) or a pose near the singular
      // set, where Gauss-Newton's model lacks the residual curvature Σ res_i ∇²l_i. Take a
      // Newton step with the Hessian from differences of the gradient when it is positive
      // definite. Where Gauss-Newton converges quadratically (exact, quantized or noisy lengths,
      // and a warm start 0.2 mm off during motion), no Newton step is taken: deciding on the
      // size of the residual instead cost a Newton step on nearly every warm tick and on every
      // tick of a calibrated device (docs/design/2026-12-05-fk-warm-start.md).
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
      out.error_gain = ErrorGain(H, &chol, weak);
      return out;
    }
    last_size = lambda * size;
    if (last_size <= settings.step_tolerance) {
      out.converged = true;
      out.error_gain = ErrorGain(H, &chol, weak);
      return out;
    }
  }
  return out;
}

// The two directions of least length change at q (unit, scaled pose coordinates): the
// eigenvectors of Jsᵀ Js with the two smallest eigenvalues. Along them lie the flat valleys
// of the fit near the singular set, and the minima a noisy fit can jump between.
void WeakDirections(const SpidarGeometry& geometry, const PoseParams& q, Vector7d* v1,
                    Vector7d* v2) {
  Matrix87d J;
  EvaluatePose(geometry, PoseFromParams(q, geometry.d), Vector8d::Zero(), nullptr, &J);
  J.rightCols<4>() /= geometry.d;
  const Eigen::SelfAdjointEigenSolver<Matrix7d> eigen(J.transpose().lazyProduct(J));
  *v1 = eigen.eigenvectors().col(0);
  *v2 = eigen.eigenvectors().col(1);
}

// Start `index` (0..47) of the branch check's orientation grid at centre p0.
PoseParams OrientationStart(const Eigen::Vector3d& p0, int index) {
  const int axis = index % 6, spin = (index / 6) % 4, grasp = index / 24;
  Eigen::Vector3d normal = Eigen::Vector3d::Zero();
  normal(axis / 2) = (axis % 2 == 0) ? 1.0 : -1.0;
  const Eigen::Matrix3d tilt =
      Eigen::Quaterniond::FromTwoVectors(Eigen::Vector3d::UnitZ(), normal).toRotationMatrix();
  PoseParams q;
  q.p0 = p0;
  q.R =
      tilt *
      Eigen::AngleAxisd(spin * 0.5 * std::numbers::pi, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  q.grasp = grasp == 0 ? std::numbers::pi / 3 : 2 * std::numbers::pi / 3;
  return q;
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
    case FkStatus::kAmbiguous:
      return "ambiguous";
  }
  return "unknown";
}

namespace {

// Most closed-form candidates (5 per pole).
constexpr int kMaxCandidates = 10;

// Every closed-form candidate pose (see ClosedFormPose) with its sum of squared residuals,
// sorted by that cost, best first. Returns their number.
int ClosedFormCandidates(const SpidarGeometry& geometry, const Vector8d& lengths,
                         GripPose poses[kMaxCandidates], double costs[kMaxCandidates]) {
  const double a = geometry.a, b = geometry.b, c = geometry.c, d = geometry.d;
  const Vector8d L = lengths.array().square();
  // Pairwise differences (docs/architecture.md, Reading the paper): u = P+1, v = P−1, s = P+2, t =
  // P−2.
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

  int count = 0;
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
    if (!std::isfinite(cost)) continue;
    // Insertion by cost.
    int at = count;
    while (at > 0 && costs[at - 1] > cost) {
      costs[at] = costs[at - 1];
      poses[at] = poses[at - 1];
      --at;
    }
    costs[at] = cost;
    poses[at] = candidate;
    ++count;
  }
  return count;
}

}  // namespace

bool ClosedFormPose(const SpidarGeometry& geometry, const Vector8d& lengths, GripPose* pose) {
  GripPose poses[kMaxCandidates];
  double costs[kMaxCandidates];
  if (ClosedFormCandidates(geometry, lengths, poses, costs) == 0) return false;
  *pose = poses[0];
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
    gn = GaussNewton(geometry_, lengths, ParamsFromPose(last_pose_), settings_, &weak_);
    iterations += gn.iterations;
    status = judge(gn);
  }
  if (status != FkStatus::kOk) {
    result.used_closed_form = true;
    GripPose starts[kMaxCandidates];
    double costs[kMaxCandidates];
    const int num_starts = ClosedFormCandidates(geometry_, lengths, starts, costs);
    if (num_starts == 0) {
      result.iterations = iterations;
      return refuse(FkStatus::kUnreachable);
    }
    // Closed-form candidates worth refining: RMS residual within 10 × max_residual (a wrong
    // branch of exact lengths is typically centimetres off; noise moves a right one by less).
    const double screen = kNumStrings * std::pow(10 * settings_.max_residual, 2);
    bool refined[kMaxCandidates] = {};
    int chosen = -1;
    for (int j = 0; j < num_starts; ++j) {
      // The best start is always tried; further ones only when it did not converge to a pose
      // that fits (a singular or degenerate fit is refused as such, never replaced).
      if (j > 0 && !(costs[j] <= screen)) break;
      if (!(std::sin(starts[j].Grasp()) > 1e-9)) {
        if (j == 0) {
          status = FkStatus::kSingular;
          break;
        }
        continue;
      }
      const GnOutcome trial =
          GaussNewton(geometry_, lengths, ParamsFromPose(starts[j]), settings_, &weak_);
      iterations += trial.iterations;
      refined[j] = true;
      const FkStatus trial_status = judge(trial);
      if (j == 0 || trial_status == FkStatus::kOk) {
        gn = trial;
        status = trial_status;
      }
      if (trial_status == FkStatus::kOk) {
        chosen = j;
        break;
      }
      if (trial_status != FkStatus::kNotConverged && trial_status != FkStatus::kUnreachable) {
        break;
      }
    }
    if (chosen >= 0 && settings_.branch_residual > 0) {
      // Branch check: another candidate converging to a second acceptable pose. Starts: the
      // other closed-form candidates, then the chosen pose moved 1 and 4 cm (scaled) both
      // ways along its two weakest directions.
      const GripPose pose = PoseFromParams(gn.q, d);
      Vector7d weak[2];
      WeakDirections(geometry_, gn.q, &weak[0], &weak[1]);
      constexpr int kWeakStarts = 8;
      constexpr int kOrientationStarts = 48;
      for (int j = 0; j < num_starts + kWeakStarts + kOrientationStarts; ++j) {
        GripPose start;
        if (j < num_starts) {
          if (refined[j] || !(costs[j] <= screen)) continue;
          start = starts[j];
        } else if (j < num_starts + kWeakStarts) {
          const int w = j - num_starts;
          Vector7d step = ((w & 1) ? -1.0 : 1.0) * ((w & 2) ? 0.04 : 0.01) * weak[w >> 2];
          step.tail<4>() /= d;
          start = PoseFromParams(Apply(gn.q, step), d);
        } else {
          // The chosen centre with the grip normal along each of ±x, ±y, ±z, turned by
          // multiples of 90° about it, at grasps of 60° and 120°: a shallow minimum of a
          // wrong-looking branch (the true one under noise) is often far in rotation.
          const int o = j - num_starts - kWeakStarts;
          start = PoseFromParams(OrientationStart(gn.q.p0, o), d);
        }
        if (PoseSeparation(start, pose) <= settings_.branch_separation) continue;
        if (!(std::sin(start.Grasp()) > 1e-9)) continue;
        const GnOutcome other = GaussNewton(geometry_, lengths, ParamsFromPose(start), settings_);
        result.branch_iterations += other.iterations;
        if (!other.converged) continue;
        const Eigen::Vector3d& c0 = other.q.p0;
        const bool inside = std::abs(c0.x()) < geometry_.a && std::abs(c0.y()) < geometry_.b &&
                            std::abs(c0.z()) < geometry_.c;
        if (inside &&
            std::sqrt(other.cost / kNumStrings) <=
                std::min(settings_.branch_residual, settings_.max_residual) &&
            PoseSeparation(PoseFromParams(other.q, d), pose) > settings_.branch_separation) {
          status = FkStatus::kAmbiguous;
          break;
        }
      }
    }
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

// --- Conditioning, singular set, error bound ------------------------------------------------

namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();

// Js = ∂l/∂(δp0, d·δω, d·δθ), 8 by 7, and its pseudo-inverse (7 by 8). Returns false (G
// untouched) when Js is not finite or loses rank to rounding.
bool ScaledJacobianPseudoInverse(const SpidarGeometry& geometry, const GripPose& pose,
                                 Vector7d* singular_values, Matrix78d* pinv) {
  Matrix87d Js = PoseJacobian(geometry, pose);
  Js.rightCols<4>() /= geometry.d;
  if (!Js.allFinite()) return false;
  const Eigen::JacobiSVD<Matrix87d> svd(Js, Eigen::ComputeFullU | Eigen::ComputeFullV);
  *singular_values = svd.singularValues();
  const double s_max = (*singular_values)(0), s_min = (*singular_values)(6);
  if (!(s_min > 1e-13 * s_max)) return false;
  const Vector7d inv = singular_values->cwiseInverse();
  *pinv = svd.matrixV() * inv.asDiagonal() * svd.matrixU().leftCols<7>().transpose();
  return true;
}

}  // namespace

FkConditioning FkConditioningAt(const SpidarGeometry& geometry, const GripPose& pose) {
  FkConditioning out;
  Vector7d sv = Vector7d::Zero();
  Matrix78d pinv;
  if (!ScaledJacobianPseudoInverse(geometry, pose, &sv, &pinv)) {
    const bool finite = pose.p0.allFinite() && pose.p1.allFinite() && pose.p2.allFinite();
    out.sigma_max = finite ? sv(0) : kNaN;
    out.sigma_min = finite ? 0.0 : kNaN;
    out.error_gain = finite ? kInf : kNaN;
    out.position_gain.setConstant(finite ? kInf : kNaN);
    return out;
  }
  out.sigma_max = sv(0);
  out.sigma_min = sv(6);
  out.error_gain = 1 / sv(6);
  for (int k = 0; k < 3; ++k) out.position_gain(k) = pinv.row(k).cwiseAbs().sum();
  return out;
}

const char* PoseAxisName(PoseAxis axis) {
  switch (axis) {
    case PoseAxis::kX:
      return "x";
    case PoseAxis::kY:
      return "y";
    case PoseAxis::kZ:
      return "z";
    case PoseAxis::kRoll:
      return "roll";
    case PoseAxis::kPitch:
      return "pitch";
    case PoseAxis::kYaw:
      return "yaw";
    case PoseAxis::kGrasp:
      return "grasp";
  }
  return "unknown";
}

GripPose SlicePose(const FkSlice& slice, double u, double v, double d) {
  double coords[7] = {slice.p0.x(),  slice.p0.y(),  slice.p0.z(), slice.rpy.x(),
                      slice.rpy.y(), slice.rpy.z(), slice.grasp};
  coords[static_cast<int>(slice.u_axis)] = u;
  coords[static_cast<int>(slice.v_axis)] = v;
  const Eigen::Matrix3d R = (Eigen::AngleAxisd(coords[5], Eigen::Vector3d::UnitZ()) *
                             Eigen::AngleAxisd(coords[4], Eigen::Vector3d::UnitY()) *
                             Eigen::AngleAxisd(coords[3], Eigen::Vector3d::UnitX()))
                                .toRotationMatrix();
  return GripPose::FromFrame(Eigen::Vector3d(coords[0], coords[1], coords[2]), R, coords[6], d);
}

FkConditioningMap SampleFkConditioning(const SpidarGeometry& geometry, const FkSlice& slice) {
  geometry.Validate();
  if (slice.u_count < 2 || slice.v_count < 2) {
    throw std::invalid_argument("FkSlice: u_count and v_count must be at least 2, got " +
                                std::to_string(slice.u_count) + " and " +
                                std::to_string(slice.v_count));
  }
  if (!(std::isfinite(slice.u_min) && std::isfinite(slice.u_max) && slice.u_min < slice.u_max &&
        std::isfinite(slice.v_min) && std::isfinite(slice.v_max) && slice.v_min < slice.v_max)) {
    throw std::invalid_argument("FkSlice: ranges must be finite with min < max, got u [" +
                                std::to_string(slice.u_min) + ", " + std::to_string(slice.u_max) +
                                "], v [" + std::to_string(slice.v_min) + ", " +
                                std::to_string(slice.v_max) + "]");
  }
  if (slice.u_axis == slice.v_axis) {
    throw std::invalid_argument(std::string("FkSlice: u_axis and v_axis are both ") +
                                PoseAxisName(slice.u_axis));
  }
  FkConditioningMap map;
  map.u = Eigen::VectorXd::LinSpaced(slice.u_count, slice.u_min, slice.u_max);
  map.v = Eigen::VectorXd::LinSpaced(slice.v_count, slice.v_min, slice.v_max);
  map.error_gain.resize(slice.v_count, slice.u_count);
  map.position_gain.resize(slice.v_count, slice.u_count);
  map.fk_status.resize(slice.v_count, slice.u_count);
  FkSettings settings;
  settings.branch_residual = slice.branch_residual;
  ForwardKinematics fk(geometry, settings);
  for (int j = 0; j < slice.v_count; ++j) {
    for (int k = 0; k < slice.u_count; ++k) {
      const GripPose pose = SlicePose(slice, map.u(k), map.v(j), geometry.d);
      const Vector8d l = InverseKinematics(geometry, pose);
      const bool inside = std::abs(pose.p0.x()) < geometry.a &&
                          std::abs(pose.p0.y()) < geometry.b && std::abs(pose.p0.z()) < geometry.c;
      if (!inside || !(l.minCoeff() >= 1e-3)) {
        map.error_gain(j, k) = map.position_gain(j, k) = map.fk_status(j, k) = kNaN;
        continue;
      }
      const FkConditioning cond = FkConditioningAt(geometry, pose);
      map.error_gain(j, k) = cond.error_gain;
      map.position_gain(j, k) = cond.position_gain.norm();
      fk.Reset();
      map.fk_status(j, k) = static_cast<double>(fk.Solve(l).status);
    }
  }
  return map;
}

FkBound FkPositionBound(const SpidarGeometry& geometry, const GripPose& estimate,
                        const Vector8d& lengths, double tolerance) {
  FkBound out;
  if (!lengths.allFinite() || !(tolerance >= 0) || !std::isfinite(tolerance) ||
      !estimate.p0.allFinite() || !estimate.p1.allFinite() || !estimate.p2.allFinite()) {
    return out;
  }
  // Rounding of the lengths and of the arithmetic below: a few ulps of the longest length.
  const double q = tolerance + 64 * std::numeric_limits<double>::epsilon() *
                                   std::max(1.0, lengths.cwiseAbs().maxCoeff());
  const double sqrt8 = std::sqrt(8.0);

  // x and y: exact functions of the squared lengths, monotone in each (docs/architecture.md,
  // Reading the paper).
  Vector8d sq_lo, sq_hi;
  for (int i = 0; i < kNumStrings; ++i) {
    const double lo = std::max(0.0, lengths(i) - q);
    sq_lo(i) = lo * lo;
    sq_hi(i) = (lengths(i) + q) * (lengths(i) + q);
  }
  const double x_hi = (-sq_lo(0) + sq_hi(1) - sq_lo(2) + sq_hi(3)) / (8 * geometry.a);
  const double x_lo = (-sq_hi(0) + sq_lo(1) - sq_hi(2) + sq_lo(3)) / (8 * geometry.a);
  const double y_hi = (-sq_lo(4) - sq_lo(5) + sq_hi(6) + sq_hi(7)) / (8 * geometry.b);
  const double y_lo = (-sq_hi(4) - sq_hi(5) + sq_lo(6) + sq_lo(7)) / (8 * geometry.b);
  const double slack = 1e-15;  // rounding of the interval ends, m
  const double x_bound = std::max(x_hi - estimate.p0.x(), estimate.p0.x() - x_lo) + slack;
  const double y_bound = std::max(y_hi - estimate.p0.y(), estimate.p0.y() - y_lo) + slack;
  out.axis = Eigen::Vector3d(x_bound, y_bound, kInf);
  out.pose = kInf;
  out.uniqueness_radius = 0;

  // Every coordinate: Δ = −G r̂ − G e − G R2 with G = Js⁺ (G Js = I), r̂ = l(p̂) − m, |e_i| ≤ q,
  // |R2_i| ≤ ½ M δ², M = 2.25 (1/d + 1/l_min), δ = |Δ| (scaled pose coordinates).
  Vector7d sv;
  Matrix78d G;
  if (ScaledJacobianPseudoInverse(geometry, estimate, &sv, &G)) {
    const Vector8d model = InverseKinematics(geometry, estimate);
    const Vector8d residual = model - lengths;
    const Vector7d g_residual = G * residual;
    const double g_norm = 1 / sv(6);  // |G|₂
    const double l_low = model.minCoeff();
    // Valid while every string stays longer than l_low/2 on the way: 1.5 δ ≤ l_low/2.
    const double M = 2.25 * (1 / geometry.d + 2 / l_low);
    const double A = g_residual.norm() + g_norm * sqrt8 * q;
    const double B = g_norm * sqrt8 * 0.5 * M;
    const double disc = 1 - 4 * A * B;
    if (l_low > 0 && disc > 0) {
      const double root = std::sqrt(disc);
      const double delta = 2 * A / (1 + root);
      if (1.5 * delta <= 0.5 * l_low) {
        out.pose = delta;
        out.uniqueness_radius = (1 + root) / (2 * B);
        const double remainder = 0.5 * M * delta * delta;
        for (int k = 0; k < 3; ++k) {
          const double linear =
              std::abs(g_residual(k)) + G.row(k).cwiseAbs().sum() * (q + remainder) + slack;
          out.axis(k) = std::min(out.axis(k), linear);
        }
      }
    }
  }
  out.position = out.axis.norm();
  return out;
}

}  // namespace spidarcad::haptics
