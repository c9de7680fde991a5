// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#include "spidarcad/haptics/tension.h"

#include <Eigen/Cholesky>
#include <Eigen/Geometry>
#include <Eigen/SVD>
#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>

namespace spidarcad::haptics {

namespace {

using Matrix8d = Eigen::Matrix<double, 8, 8>;

void CheckFinite(double v, const char* name) {
  if (!std::isfinite(v)) {
    throw std::invalid_argument(std::string("TensionSettings: field '") + name +
                                "' must be finite, got " + std::to_string(v));
  }
}

void CheckPositive(double v, const char* name) {
  CheckFinite(v, name);
  if (v <= 0.0) {
    throw std::invalid_argument(std::string("TensionSettings: field '") + name +
                                "' must be positive, got " + std::to_string(v));
  }
}

// Row weights diag(1, 1, 1, S0, S0, S0, S1) of the objective.
Vector7d RowWeights(const TensionSettings& s) {
  Vector7d w;
  w << 1.0, 1.0, 1.0, s.s0, s.s0, s.s0, s.s1;
  return w;
}

}  // namespace

Matrix78d WrenchMatrix(const SpidarGeometry& geometry, const GripPose& pose) {
  const Eigen::Vector3d n = pose.Normal();
  Matrix78d A;
  for (int i = 0; i < kNumStrings; ++i) {
    const Eigen::Vector3d v = geometry.Corner(i) - pose.Attachment(i);
    const Eigen::Vector3d c = v / v.norm();
    const Eigen::Vector3d rc = pose.LeverArm(i).cross(c);
    A.block<3, 1>(0, i) = c;
    A.block<3, 1>(3, i) = rc;
    A(6, i) = StringDelta(i) * n.dot(rc);
  }
  return A;
}

ForceClosure ForceClosureAt(const Matrix78d& A, double d) {
  ForceClosure out;
  if (!A.allFinite() || !(d > 0)) {
    out.margin = out.sigma_min = std::nan("");
    out.null_vector.setConstant(std::nan(""));
    return out;
  }
  Matrix78d scaled = A;
  scaled.bottomRows<4>() /= d;
  // Square 8 by 8 (a zero last row) so the full right singular basis has fixed size.
  Matrix8d padded = Matrix8d::Zero();
  padded.topRows<7>() = scaled;
  const Eigen::JacobiSVD<Matrix8d> svd(padded, Eigen::ComputeFullV);
  out.sigma_min = svd.singularValues()(6);
  Vector8d n = svd.matrixV().col(7);
  if (n.sum() < 0) n = -n;
  out.null_vector = n;
  out.margin = n.minCoeff() / n.cwiseAbs().maxCoeff();
  out.closure = out.margin > 0 && out.sigma_min > 1e-9 * svd.singularValues()(0);
  return out;
}

void TensionSettings::Validate() const {
  CheckFinite(tau_min, "tau_min");
  CheckFinite(tau_max, "tau_max");
  if (tau_min < 0.0) {
    throw std::invalid_argument(
        "TensionSettings: field 'tau_min' must be >= 0 N (strings can "
        "only pull), got " +
        std::to_string(tau_min));
  }
  if (!(tau_min < tau_max)) {
    throw std::invalid_argument("TensionSettings: field 'tau_max' (" + std::to_string(tau_max) +
                                " N) must be larger than 'tau_min' (" + std::to_string(tau_min) +
                                " N)");
  }
  CheckPositive(s0, "s0");
  CheckPositive(s1, "s1");
  CheckPositive(s2, "s2");
}

TensionSettings TensionSettings::ForPoleLength(double d) {
  TensionSettings s;
  s.s0 = 1.0 / (d * d);
  s.s1 = 1.0 / (d * d);
  return s;
}

const char* TensionStatusName(TensionStatus status) {
  switch (status) {
    case TensionStatus::kOk:
      return "ok";
    case TensionStatus::kSaturated:
      return "saturated";
    case TensionStatus::kInvalidInput:
      return "invalid_input";
    case TensionStatus::kNotConverged:
      return "not_converged";
  }
  return "unknown";
}

TensionSolver::TensionSolver(const TensionSettings& settings) : settings_(settings) {
  settings_.Validate();
}

void TensionSolver::Reset() { active_.setZero(); }

TensionResult TensionSolver::Solve(const Matrix78d& A, const Vector7d& q) {
  const double lo = settings_.tau_min;
  const double hi = settings_.tau_max;
  TensionResult result;
  result.tau.setConstant(lo);
  if (!A.allFinite() || !q.allFinite()) {
    // Safe output: every string at its minimum tension, no wrench is trusted.
    result.achieved = A.allFinite() ? Vector7d(A * result.tau) : Vector7d::Constant(std::nan(""));
    result.lost = q - result.achieved;
    result.objective = std::nan("");
    result.num_at_min = kNumStrings;
    result.status = TensionStatus::kInvalidInput;
    return result;
  }

  // J(τ) = τᵀHτ − 2bᵀτ + qᵀWq with H = AᵀWA + S2 I, b = AᵀWq, W = diag(1,1,1,S0,S0,S0,S1).
  const Vector7d w = RowWeights(settings_);
  const Matrix78d WA = w.asDiagonal() * A;
  Matrix8d H = A.transpose() * WA;
  H.diagonal().array() += settings_.s2;
  const Vector8d b = WA.transpose() * q;
  // Scale for the multiplier test: gradients are compared against this.
  const double grad_tol =
      1e-12 * (1.0 + b.cwiseAbs().maxCoeff() + H.cwiseAbs().maxCoeff() * std::max(hi, 1.0));

  Eigen::Matrix<std::int8_t, 8, 1> state = active_;
  Vector8d tau;
  for (int i = 0; i < kNumStrings; ++i) tau(i) = state(i) < 0 ? lo : (state(i) > 0 ? hi : 0.0);

  // Minimiser over the free tensions with the bound ones held: rows of bound tensions become
  // identity rows, so one 8 by 8 SPD system covers every working set.
  Matrix8d K;
  Vector8d rhs;
  Eigen::LLT<Matrix8d> llt;
  auto solve_subproblem = [&](Vector8d* x) {
    for (int i = 0; i < kNumStrings; ++i) {
      if (state(i) != 0) {
        K.row(i).setZero();
        K.col(i).setZero();
        K(i, i) = 1.0;
        rhs(i) = tau(i);
      } else {
        rhs(i) = b(i);
        for (int j = 0; j < kNumStrings; ++j) {
          if (state(j) != 0) {
            rhs(i) -= H(i, j) * tau(j);
          } else {
            K(i, j) = H(i, j);
          }
        }
      }
    }
    llt.compute(K);
    *x = llt.solve(rhs);
  };

  Vector8d x;
  solve_subproblem(&x);
  // Feasible start: the free tensions at the clamped subproblem minimiser.
  for (int i = 0; i < kNumStrings; ++i) {
    if (state(i) == 0) tau(i) = std::clamp(x(i), lo, hi);
  }

  bool converged = false;
  int iterations = 0;
  while (iterations <= kMaxIterations) {
    solve_subproblem(&x);
    // Longest feasible step from τ toward the subproblem minimiser.
    double alpha = 1.0;
    int block = -1;
    std::int8_t block_side = 0;
    for (int i = 0; i < kNumStrings; ++i) {
      if (state(i) != 0) continue;
      const double p = x(i) - tau(i);
      if (p < 0.0 && x(i) < lo) {
        const double a = (lo - tau(i)) / p;
        if (a < alpha) {
          alpha = a;
          block = i;
          block_side = -1;
        }
      } else if (p > 0.0 && x(i) > hi) {
        const double a = (hi - tau(i)) / p;
        if (a < alpha) {
          alpha = a;
          block = i;
          block_side = +1;
        }
      }
    }
    alpha = std::max(alpha, 0.0);
    for (int i = 0; i < kNumStrings; ++i) {
      if (state(i) == 0) tau(i) = std::clamp(tau(i) + alpha * (x(i) - tau(i)), lo, hi);
    }
    if (block >= 0) {
      state(block) = block_side;
      tau(block) = block_side < 0 ? lo : hi;
      ++iterations;
      continue;
    }
    // τ minimises J on the working set: check the signs of the bound multipliers.
    const Vector8d grad = H * tau - b;  // half the gradient of J
    int worst = -1;
    double worst_violation = grad_tol;
    for (int i = 0; i < kNumStrings; ++i) {
      if (state(i) == 0) continue;
      // At τ_min J must not decrease when τ_i grows (grad >= 0); at τ_max the reverse.
      const double violation = state(i) < 0 ? -grad(i) : grad(i);
      if (violation > worst_violation) {
        worst_violation = violation;
        worst = i;
      }
    }
    if (worst < 0) {
      converged = true;
      break;
    }
    state(worst) = 0;
    ++iterations;
  }

  result.tau = tau;
  result.achieved = A * tau;
  result.lost = q - result.achieved;
  result.objective =
      result.lost.dot(w.asDiagonal() * result.lost) + settings_.s2 * tau.squaredNorm();
  result.iterations = iterations;
  for (int i = 0; i < kNumStrings; ++i) {
    if (state(i) < 0) ++result.num_at_min;
    if (state(i) > 0) ++result.num_at_max;
  }
  if (!converged) {
    result.status = TensionStatus::kNotConverged;
    active_.setZero();
    return result;
  }
  active_ = state;
  const double lost_norm = std::sqrt(result.lost.dot(w.asDiagonal() * result.lost));
  const double q_norm = std::sqrt(q.dot(w.asDiagonal() * q));
  // The S2 term biases the displayed wrench by about S2/σ² times the tensions in play, not
  // times q: at q = 0 off centre the pretension alone leaves a few mN (see kOk in
  // tension.h). Only a loss beyond 1 % of both is a saturation.
  const double tau_norm = tau.norm();
  result.status = lost_norm <= 0.01 * (q_norm + tau_norm) + 1e-3 ? TensionStatus::kOk
                                                                 : TensionStatus::kSaturated;
  return result;
}

}  // namespace spidarcad::haptics
