// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#include "spidarcad/haptics/calibration.h"

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>
#include <sstream>
#include <stdexcept>

#include "spidarcad/haptics/geometry.h"
#include "spidarcad/haptics/kinematics.h"
#include "spidarcad/haptics/rotation.h"
#include "spidarcad/haptics/simulated_device.h"

namespace spidarcad::haptics {

namespace {

using Matrix97d = Eigen::Matrix<double, 9, 7>;
using Matrix87d = Eigen::Matrix<double, 8, 7>;
using Matrix7d = Eigen::Matrix<double, 7, 7>;

// SplitMix64 (same generator as the simulated device): portable, seedable.
std::uint64_t NextRandom(std::uint64_t* state) {
  std::uint64_t z = (*state += 0x9E3779B97F4A7C15ULL);
  z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ULL;
  z = (z ^ (z >> 27)) * 0x94D049BB133111EBULL;
  return z ^ (z >> 31);
}
double Uniform01(std::uint64_t* state) {
  return (static_cast<double>(NextRandom(state) >> 11) + 0.5) * 0x1.0p-53;
}
double UniformIn(std::uint64_t* state, double lo, double hi) {
  return lo + (hi - lo) * Uniform01(state);
}

Eigen::Matrix3d Skew(const Eigen::Vector3d& v) {
  Eigen::Matrix3d S;
  S << 0, -v.z(), v.y(), v.z(), 0, -v.x(), -v.y(), v.x(), 0;
  return S;
}

// Minimal pose coordinates: centre, rotation (updated on the left by exp(ω)), grasp angle.
struct PoseState {
  Eigen::Vector3d p0 = Eigen::Vector3d::Zero();
  Eigen::Matrix3d R = Eigen::Matrix3d::Identity();
  double grasp = std::numbers::pi / 2;
};

PoseState StateFromPose(const GripPose& pose) {
  PoseState s;
  s.p0 = pose.p0;
  s.R = pose.Rotation();
  s.grasp = pose.Grasp();
  return s;
}

GripPose PoseFromState(const PoseState& s, double d) {
  return GripPose::FromFrame(s.p0, s.R, s.grasp, d);
}

PoseState Retract(const PoseState& s, const Vector7d& delta) {
  PoseState out = s;
  out.p0 += delta.head<3>();
  out.R = IntegrateRotation(s.R, delta.segment<3>(3), 1.0);
  out.grasp += delta[6];
  return out;
}

// d(p0, p1, p2)/d(δp0, ω, δθ), 9 by 7, for the left rotation update R <- exp(ω) R.
Matrix97d PoseTangent(const PoseState& s, double d) {
  const GripPose pose = PoseFromState(s, d);
  const PoleDirections poles = GripPoleDirections(s.grasp);
  Matrix97d T = Matrix97d::Zero();
  T.block<3, 3>(0, 0).setIdentity();
  T.block<3, 3>(3, 3) = -Skew(pose.p1);
  T.block<3, 3>(6, 3) = -Skew(pose.p2);
  T.block<3, 1>(3, 6) = d * (s.R * poles.du_T[0]);
  T.block<3, 1>(6, 6) = d * (s.R * poles.du_T[1]);
  return T;
}

bool AllFinite(const Vector8d& v) { return v.allFinite(); }

// Layout of the per-string parameters in the self-calibration, in this order: offset, gain,
// quadratic, stretch (the inactive ones left out).
struct ParamLayout {
  bool offset = true;
  bool quadratic = false;
  bool stretch = false;
  int PerString() const { return 1 + (offset ? 1 : 0) + (quadratic ? 1 : 0) + (stretch ? 1 : 0); }
  int Total() const { return kNumStrings * PerString(); }
};

// ∂h/∂(params of string i) for h = (o + g u + q u²)(1 + s τ): the active entries in layout
// order (the unused tail is zero).
Eigen::Vector4d ModelGradient(const ParamLayout& layout, const StringEncoderParams& p, double u,
                              double tension) {
  const double f = 1.0 + p.stretch * tension;
  Eigen::Vector4d g = Eigen::Vector4d::Zero();
  int j = 0;
  if (layout.offset) g[j++] = f;
  g[j++] = u * f;
  if (layout.quadratic) g[j++] = u * u * f;
  if (layout.stretch) g[j++] = (p.offset + u * (p.gain + p.quadratic * u)) * tension;
  return g;
}

void ApplyParamStep(const ParamLayout& layout, const Eigen::VectorXd& delta,
                    EncoderCalibration* cal) {
  const int np = layout.PerString();
  for (int i = 0; i < kNumStrings; ++i) {
    int j = i * np;
    StringEncoderParams& p = cal->strings[i];
    if (layout.offset) p.offset += delta[j++];
    p.gain += delta[j++];
    if (layout.quadratic) p.quadratic += delta[j++];
    if (layout.stretch) p.stretch += delta[j++];
  }
}

std::string StringName(int i) { return "string " + std::to_string(i + 1); }

// Starts `result` from `initial`. Returns false, with status kInvalidInput and the reason,
// when the geometry or the initial calibration does not validate.
bool StartResult(const SpidarGeometry& geometry, const EncoderCalibration& initial,
                 CalibrationResult* result) {
  result->calibration = initial;
  try {
    geometry.Validate();
    initial.Validate();
  } catch (const std::exception& e) {
    result->status = CalibrationStatus::kInvalidInput;
    result->message = e.what();
    return false;
  }
  return true;
}

}  // namespace

const char* CalibrationStatusName(CalibrationStatus status) {
  switch (status) {
    case CalibrationStatus::kOk:
      return "ok";
    case CalibrationStatus::kInvalidInput:
      return "invalid_input";
    case CalibrationStatus::kTooFewSamples:
      return "too_few_samples";
    case CalibrationStatus::kDegenerate:
      return "degenerate";
    case CalibrationStatus::kNotConverged:
      return "not_converged";
  }
  return "unknown";
}

CalibrationResult FitLinesPerString(const SpidarGeometry& geometry,
                                    const EncoderCalibration& initial,
                                    const std::vector<KnownPoseSample>& samples,
                                    const LineFitSettings& settings) {
  CalibrationResult result;
  if (!StartResult(geometry, initial, &result)) return result;
  const int np = settings.fit_quadratic ? 3 : 2;
  const int K = static_cast<int>(samples.size());
  if (K < np) {
    result.status = CalibrationStatus::kTooFewSamples;
    result.message = "line fit: " + std::to_string(K) + " known-pose samples, need at least " +
                     std::to_string(np) + " (more, spread over the workspace, for accuracy)";
    return result;
  }
  const double m = initial.spec.MetresPerCount();
  std::vector<Vector8d> reference(K);
  for (int k = 0; k < K; ++k) {
    reference[k] = InverseKinematics(geometry, samples[k].pose);
    if (!AllFinite(reference[k]) || !samples[k].tension.allFinite()) {
      result.status = CalibrationStatus::kInvalidInput;
      result.message =
          "line fit: sample " + std::to_string(k) + " has a non-finite pose or tension";
      return result;
    }
  }
  EncoderCalibration fitted = initial;
  double sum_sq = 0.0;
  double worst_condition = 0.0;
  for (int i = 0; i < kNumStrings; ++i) {
    Eigen::MatrixXd X(K, np);
    Eigen::VectorXd y(K);
    double u_min = std::numeric_limits<double>::infinity();
    double u_max = -u_min;
    for (int k = 0; k < K; ++k) {
      const double u = samples[k].counts[i] * m;
      u_min = std::min(u_min, u);
      u_max = std::max(u_max, u);
      X(k, 0) = 1.0;
      X(k, 1) = u;
      if (np == 3) X(k, 2) = u * u;
      y[k] = reference[k][i] / (1.0 + initial.strings[i].stretch * samples[k].tension[i]);
    }
    if (u_max - u_min < settings.min_span) {
      std::ostringstream os;
      os << "line fit: " << StringName(i) << ": the counts span only " << (u_max - u_min) * 1e3
         << " mm of string (need " << settings.min_span * 1e3
         << " mm); move the jig poses further apart";
      result.status = CalibrationStatus::kDegenerate;
      result.message = os.str();
      return result;
    }
    const Eigen::ColPivHouseholderQR<Eigen::MatrixXd> qr(X);
    if (qr.rank() < np) {
      result.status = CalibrationStatus::kDegenerate;
      result.message = "line fit: " + StringName(i) + ": the samples do not determine " +
                       std::to_string(np) + " coefficients (too few distinct lengths)";
      return result;
    }
    const Eigen::VectorXd coef = qr.solve(y);
    const Eigen::JacobiSVD<Eigen::MatrixXd> svd(X);
    const auto& sv = svd.singularValues();
    worst_condition = std::max(worst_condition, sv[0] / sv[sv.size() - 1]);
    const double string_sq = (X * coef - y).squaredNorm();
    sum_sq += string_sq;
    result.string_rms_residual[i] = std::sqrt(string_sq / K);
    StringEncoderParams& p = fitted.strings[i];
    p.offset = coef[0];
    p.gain = coef[1];
    p.quadratic = np == 3 ? coef[2] : 0.0;
  }
  result.rms_residual = std::sqrt(sum_sq / (K * kNumStrings));
  result.condition = worst_condition;
  result.calibration = fitted;
  try {
    fitted.Validate();
  } catch (const std::exception& e) {
    result.status = CalibrationStatus::kDegenerate;
    result.calibration = initial;
    result.message = std::string("line fit produced unusable parameters: ") + e.what();
    return result;
  }
  result.status = CalibrationStatus::kOk;
  std::ostringstream os;
  os << "line fit: " << K << " known poses, RMS residual " << result.rms_residual * 1e3 << " mm";
  result.message = os.str();
  return result;
}

CalibrationResult SelfCalibrate(const SpidarGeometry& geometry, const EncoderCalibration& initial,
                                const std::vector<KnownPoseSample>& known,
                                const std::vector<UnknownPoseSample>& unknown,
                                const SelfCalibrationSettings& settings) {
  CalibrationResult result;
  if (!StartResult(geometry, initial, &result)) return result;
  const auto invalid_setting = [&](const char* field, double value, const char* what) {
    std::ostringstream os;
    os << "self-calibration: setting '" << field << "' " << what << ", got " << value;
    result.status = CalibrationStatus::kInvalidInput;
    result.message = os.str();
    return result;
  };
  if (!(settings.known_position_sd >= 0.0) || !std::isfinite(settings.known_position_sd)) {
    return invalid_setting("known_position_sd", settings.known_position_sd,
                           "must be a finite length >= 0 (m)");
  }
  if (!(settings.known_rotation_sd >= 0.0) || !std::isfinite(settings.known_rotation_sd) ||
      (settings.known_position_sd > 0.0) != (settings.known_rotation_sd > 0.0)) {
    return invalid_setting("known_rotation_sd", settings.known_rotation_sd,
                           "must be finite, and > 0 exactly when known_position_sd is");
  }
  if (!(settings.length_sd > 0.0) || !std::isfinite(settings.length_sd)) {
    return invalid_setting("length_sd", settings.length_sd, "must be a finite length > 0 (m)");
  }
  const int K = static_cast<int>(unknown.size());
  const int Kk = static_cast<int>(known.size());
  const double d = geometry.d;
  const double m = initial.spec.MetresPerCount();

  for (int k = 0; k < Kk; ++k) {
    if (!known[k].pose.Packed().allFinite() || !known[k].tension.allFinite()) {
      result.status = CalibrationStatus::kInvalidInput;
      result.message = "self-calibration: known sample " + std::to_string(k) +
                       " has a non-finite pose or tension";
      return result;
    }
  }
  for (int k = 0; k < K; ++k) {
    if (!unknown[k].tension.allFinite()) {
      result.status = CalibrationStatus::kInvalidInput;
      result.message =
          "self-calibration: unknown sample " + std::to_string(k) + " has a non-finite tension";
      return result;
    }
  }

  // Stretch is estimated only when every string's tension varies enough over the samples:
  // at one tension it cannot be told from the gain and offset.
  ParamLayout layout;
  layout.offset = settings.estimate_offset;
  layout.quadratic = settings.estimate_quadratic;
  std::string stretch_note;
  if (settings.estimate_stretch) {
    double narrowest = std::numeric_limits<double>::infinity();
    int narrowest_string = 0;
    for (int i = 0; i < kNumStrings; ++i) {
      double lo = std::numeric_limits<double>::infinity();
      double hi = -lo;
      for (const auto& s : known) lo = std::min(lo, s.tension[i]), hi = std::max(hi, s.tension[i]);
      for (const auto& s : unknown)
        lo = std::min(lo, s.tension[i]), hi = std::max(hi, s.tension[i]);
      const double spread = hi > lo ? hi - lo : 0.0;
      if (spread < narrowest) narrowest = spread, narrowest_string = i;
    }
    if (narrowest >= settings.min_tension_spread) {
      layout.stretch = true;
    } else {
      std::ostringstream os;
      os << "stretch kept from the initial calibration (" << StringName(narrowest_string)
         << "'s tension spans " << narrowest << " N, estimating it needs "
         << settings.min_tension_spread << " N)";
      stretch_note = os.str();
    }
  }
  const int np = layout.PerString();
  const int P = layout.Total();

  // Counting argument: 8 equations per sample, 7 unknowns per unknown pose, P parameters.
  if (settings.estimate_offset && Kk == 0) {
    result.status = CalibrationStatus::kTooFewSamples;
    result.message =
        "self-calibration: offsets need at least one known pose (the homing pose); got none";
    return result;
  }
  const int redundancy = 8 * (K + Kk) - 7 * K - P;
  const int min_unknown = std::max(0, P - 8 * Kk) + 2 * np;
  if (K < min_unknown || redundancy <= 0) {
    result.status = CalibrationStatus::kTooFewSamples;
    result.message = "self-calibration: " + std::to_string(K) + " unknown poses and " +
                     std::to_string(Kk) + " known poses cannot determine " + std::to_string(P) +
                     " string parameters; need at least " + std::to_string(min_unknown) +
                     " unknown poses (each adds one redundant length), preferably 10 times that";
    return result;
  }

  // The samples as pose blocks. Free blocks (pose estimated) come first: the unknown samples,
  // then, when the known poses have a tolerance, the known samples (pose pulled toward the
  // known one by a prior). Known samples without tolerance are fixed blocks.
  const bool soft_known = settings.known_position_sd > 0.0;
  const int Ks = soft_known ? Kk : 0;  // known samples with a free pose
  const int Kf = soft_known ? 0 : Kk;  // known samples with a fixed pose
  const int F = K + Ks;
  std::vector<const EncoderCounts*> free_counts(F);
  std::vector<const Vector8d*> free_tension(F);
  for (int k = 0; k < K; ++k)
    free_counts[k] = &unknown[k].counts, free_tension[k] = &unknown[k].tension;
  for (int k = 0; k < Ks; ++k) {
    free_counts[K + k] = &known[k].counts;
    free_tension[K + k] = &known[k].tension;
  }
  std::vector<Vector8d> fixed_lengths(Kf);
  for (int k = 0; k < Kf; ++k) fixed_lengths[k] = InverseKinematics(geometry, known[k].pose);
  std::vector<PoseState> prior(Ks);
  for (int k = 0; k < Ks; ++k) prior[k] = StateFromPose(known[k].pose);
  // Prior weights: a pose coordinate off by its sd costs as much as a length off by length_sd.
  Vector7d prior_weight = Vector7d::Zero();
  if (soft_known) {
    prior_weight.head<3>().setConstant(settings.length_sd / settings.known_position_sd);
    prior_weight.tail<4>().setConstant(settings.length_sd / settings.known_rotation_sd);
  }
  // Prior residual (weighted known − estimated) of soft known sample k at state s.
  const auto prior_residual = [&](int k, const PoseState& s) {
    Vector7d e;
    e.head<3>() = prior[k].p0 - s.p0;
    const Eigen::AngleAxisd aa(prior[k].R * s.R.transpose());
    e.segment<3>(3) = aa.angle() * aa.axis();
    e[6] = prior[k].grasp - s.grasp;
    return Vector7d(prior_weight.cwiseProduct(e));
  };

  // Starting poses: forward kinematics on a calibration's lengths. Returns the number of
  // samples FK could not solve; adds the FK residual cost to *fk_cost.
  FkSettings fk_settings;
  fk_settings.max_iterations = 50;
  fk_settings.max_residual = settings.initial_fk_max_residual;
  fk_settings.warm_start = false;
  ForwardKinematics fk(geometry, fk_settings);
  const GripPose fallback_pose = Kk > 0 ? known[0].pose : GripPose::Rest(d);
  const auto seed_poses = [&](const EncoderCalibration& c, std::vector<PoseState>* out,
                              double* fk_cost) {
    int failures = 0;
    double total = 0.0;
    for (int k = 0; k < K; ++k) {
      const Vector8d lengths = c.Lengths(unknown[k].counts, unknown[k].tension);
      const FkResult r = fk.Solve(lengths);
      if (r.status == FkStatus::kOk) {
        if (out != nullptr) (*out)[k] = StateFromPose(r.pose);
        total += kNumStrings * r.residual * r.residual;
        continue;
      }
      ++failures;
      if (out == nullptr) continue;
      GripPose guess;
      if (ClosedFormPose(geometry, lengths, &guess) && guess.Packed().allFinite() &&
          guess.p1.cross(guess.p2).norm() > 1e-6) {
        (*out)[k] = StateFromPose(guess);
      } else {
        (*out)[k] = StateFromPose(fallback_pose);
      }
    }
    if (out != nullptr) {
      for (int k = 0; k < Ks; ++k) (*out)[K + k] = prior[k];
    }
    if (fk_cost != nullptr) *fk_cost = total;
    return failures;
  };

  // A common scale error of all gains (string thickness) bends every pose the same way and is
  // the one large error LM cannot be trusted to walk out of: pick the common gain scale that
  // best explains the data with per-pose FK, on a grid, before the joint refinement.
  EncoderCalibration start = initial;
  {
    double best_cost = std::numeric_limits<double>::infinity();
    double best_scale = 1.0;
    int best_failures = K + 1;
    for (double scale = 0.8; scale <= 1.2 + 1e-9; scale += 0.005) {
      EncoderCalibration c = initial;
      for (auto& p : c.strings) p.gain *= scale;
      double fk_cost = 0.0;
      const int failures = seed_poses(c, nullptr, &fk_cost);
      if (failures < best_failures || (failures == best_failures && fk_cost < best_cost)) {
        best_failures = failures;
        best_cost = fk_cost;
        best_scale = scale;
      }
    }
    for (auto& p : start.strings) p.gain *= best_scale;
  }
  std::vector<PoseState> states(F);
  const int fk_failures = seed_poses(start, &states, nullptr);
  if (fk_failures * 2 > K) {
    result.status = CalibrationStatus::kDegenerate;
    result.message = "self-calibration: forward kinematics found no pose for " +
                     std::to_string(fk_failures) + " of " + std::to_string(K) +
                     " samples with the initial calibration; is it the right device?";
    return result;
  }

  EncoderCalibration cal = start;
  // Length part of the cost: Σ |IK(pose) − h(counts; params)|² over all samples.
  const auto length_cost_of = [&](const EncoderCalibration& c, const std::vector<PoseState>& s) {
    double cost = 0.0;
    for (int k = 0; k < Kf; ++k) {
      cost += (fixed_lengths[k] - c.Lengths(known[k].counts, known[k].tension)).squaredNorm();
    }
    for (int k = 0; k < F; ++k) {
      const Vector8d r = InverseKinematics(geometry, PoseFromState(s[k], d)) -
                         c.Lengths(*free_counts[k], *free_tension[k]);
      cost += r.squaredNorm();
    }
    return cost;
  };
  // Whole cost: lengths plus the known poses' priors.
  const auto cost_of = [&](const EncoderCalibration& c, const std::vector<PoseState>& s) {
    double cost = length_cost_of(c, s);
    for (int k = 0; k < Ks; ++k) cost += prior_residual(k, s[K + k]).squaredNorm();
    return cost;
  };

  // Normal equations: U (P×P) for the parameters, V_k (7×7) per free pose, W_k (P×7) coupling.
  Eigen::MatrixXd U(P, P);
  Eigen::VectorXd bp(P);
  std::vector<Matrix7d> V(F);
  std::vector<Eigen::Matrix<double, Eigen::Dynamic, 7>> W(F);
  std::vector<Vector7d> bx(F);

  // Adds one sample's contribution; pose Jacobian Jx may be null (fixed pose).
  const auto accumulate = [&](const Vector8d& r, const EncoderCounts& counts,
                              const Vector8d& tension, const Matrix87d* Jx, int k) {
    for (int i = 0; i < kNumStrings; ++i) {
      const StringEncoderParams& p = cal.strings[i];
      const double u = counts[i] * m;
      // r_i = IK_i − h_i: ∂r_i/∂params_i = −∂h_i/∂params_i.
      const Eigen::Vector4d gp = -ModelGradient(layout, p, u, tension[i]);
      const int j0 = i * np;
      for (int a = 0; a < np; ++a) {
        for (int b = 0; b < np; ++b) U(j0 + a, j0 + b) += gp[a] * gp[b];
        bp[j0 + a] -= gp[a] * r[i];
        if (Jx != nullptr) W[k].row(j0 + a) += gp[a] * Jx->row(i);
      }
    }
    if (Jx != nullptr) {
      V[k] = Jx->transpose() * (*Jx);
      bx[k] = -Jx->transpose() * r;
    }
  };

  const auto build = [&]() {
    U.setZero();
    bp.setZero();
    for (int k = 0; k < Kf; ++k) {
      const Vector8d r = fixed_lengths[k] - cal.Lengths(known[k].counts, known[k].tension);
      accumulate(r, known[k].counts, known[k].tension, nullptr, -1);
    }
    for (int k = 0; k < F; ++k) {
      const GripPose pose = PoseFromState(states[k], d);
      const Matrix87d Jx = StringJacobian(geometry, pose) * PoseTangent(states[k], d);
      const Vector8d r =
          InverseKinematics(geometry, pose) - cal.Lengths(*free_counts[k], *free_tension[k]);
      W[k].setZero(P, 7);
      accumulate(r, *free_counts[k], *free_tension[k], &Jx, k);
      if (k >= K) {
        // Prior r_p = w ⊙ (known ⊖ pose): ∂r_p/∂δ ≈ −diag(w).
        const Vector7d rp = prior_residual(k - K, states[k]);
        V[k].diagonal() += prior_weight.cwiseAbs2();
        bx[k] += prior_weight.cwiseProduct(rp);
      }
    }
  };

  // Reduced (Schur complement) matrix and right-hand side for damping λ.
  const auto reduce = [&](double lambda, Eigen::MatrixXd* S, Eigen::VectorXd* rhs,
                          std::vector<Matrix7d>* Vinv) {
    *S = U;
    for (int j = 0; j < P; ++j) (*S)(j, j) += lambda * (U(j, j) + 1e-12);
    *rhs = bp;
    for (int k = 0; k < F; ++k) {
      Matrix7d Vd = V[k];
      for (int j = 0; j < 7; ++j) Vd(j, j) += lambda * V[k](j, j) + 1e-14;
      (*Vinv)[k] = Vd.ldlt().solve(Matrix7d::Identity());
      const Eigen::Matrix<double, Eigen::Dynamic, 7> WVinv = W[k] * (*Vinv)[k];
      S->noalias() -= WVinv * W[k].transpose();
      rhs->noalias() -= WVinv * bx[k];
    }
  };

  double cost = cost_of(cal, states);
  const double initial_length_cost = length_cost_of(cal, states);
  double lambda = 1e-4;
  std::vector<Matrix7d> Vinv(F);
  Eigen::MatrixXd S;
  Eigen::VectorXd rhs;
  bool converged = false;
  int iteration = 0;
  // Outer rounds: LM to convergence, then re-seed every pose whose own FK (with the current
  // parameters) fits its lengths better than the joint solution does: a pose caught in the
  // wrong basin early on otherwise drags the parameters into a local minimum.
  for (int round = 0; round < 5; ++round) {
    converged = false;
    for (; iteration < settings.max_iterations && !converged; ++iteration) {
      build();
      bool accepted = false;
      while (!accepted) {
        reduce(lambda, &S, &rhs, &Vinv);
        const Eigen::VectorXd dp = S.ldlt().solve(rhs);
        if (!dp.allFinite()) {
          lambda *= 10.0;
          if (lambda > 1e12) break;
          continue;
        }
        EncoderCalibration trial_cal = cal;
        ApplyParamStep(layout, dp, &trial_cal);
        std::vector<PoseState> trial_states(F);
        for (int k = 0; k < F; ++k) {
          const Vector7d dx = Vinv[k] * (bx[k] - W[k].transpose() * dp);
          trial_states[k] = Retract(states[k], dx);
        }
        const double trial_cost = cost_of(trial_cal, trial_states);
        if (std::isfinite(trial_cost) && trial_cost < cost) {
          const double decrease = cost - trial_cost;
          cal = trial_cal;
          states.swap(trial_states);
          cost = trial_cost;
          lambda = std::max(lambda / 3.0, 1e-12);
          accepted = true;
          if (decrease <= settings.tolerance * cost || cost < 1e-24) converged = true;
        } else {
          lambda *= 4.0;
          if (lambda > 1e12) break;
        }
      }
      if (!accepted) converged = true;  // no step lowers the cost: a minimum, to rounding
    }
    if (!converged) break;
    int reseeded = 0;
    for (int k = 0; k < K; ++k) {
      const Vector8d lengths = cal.Lengths(unknown[k].counts, unknown[k].tension);
      const double current =
          (InverseKinematics(geometry, PoseFromState(states[k], d)) - lengths).squaredNorm();
      const FkResult r = fk.Solve(lengths);
      if (r.status == FkStatus::kOk &&
          kNumStrings * r.residual * r.residual < 0.5 * current - 1e-14) {
        states[k] = StateFromPose(r.pose);
        ++reseeded;
      }
    }
    if (reseeded == 0) break;
    cost = cost_of(cal, states);
    lambda = 1e-4;
  }
  result.iterations = iteration;
  const int total_residuals = kNumStrings * (K + Kk);
  result.rms_residual = std::sqrt(length_cost_of(cal, states) / total_residuals);
  {
    Vector8d sq = Vector8d::Zero();
    for (int k = 0; k < Kf; ++k) {
      sq += (fixed_lengths[k] - cal.Lengths(known[k].counts, known[k].tension)).cwiseAbs2();
    }
    for (int k = 0; k < F; ++k) {
      sq += (InverseKinematics(geometry, PoseFromState(states[k], d)) -
             cal.Lengths(*free_counts[k], *free_tension[k]))
                .cwiseAbs2();
    }
    result.string_rms_residual = (sq / (K + Kk)).cwiseSqrt();
  }

  // Identifiability: condition of the undamped, Jacobi-scaled reduced information matrix.
  build();
  reduce(0.0, &S, &rhs, &Vinv);
  Eigen::VectorXd scale(P);
  for (int j = 0; j < P; ++j) scale[j] = S(j, j) > 0.0 ? 1.0 / std::sqrt(S(j, j)) : 0.0;
  const Eigen::MatrixXd Sn = scale.asDiagonal() * S * scale.asDiagonal();
  const Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> eig(Sn, Eigen::EigenvaluesOnly);
  const double ev_min = eig.eigenvalues().minCoeff();
  const double ev_max = eig.eigenvalues().maxCoeff();
  result.condition = ev_min > 0.0 && scale.minCoeff() > 0.0
                         ? ev_max / ev_min
                         : std::numeric_limits<double>::infinity();

  std::ostringstream os;
  os << "self-calibration: " << K << " unknown + " << Kk << " known poses, " << P << " parameters"
     << (layout.stretch ? " (stretch estimated)" : "") << ", " << iteration
     << " iterations, RMS residual " << result.rms_residual * 1e3 << " mm (start "
     << std::sqrt(initial_length_cost / total_residuals) * 1e3 << " mm), condition "
     << result.condition;
  if (!stretch_note.empty()) os << "; " << stretch_note;
  if (!(result.condition <= settings.max_condition)) {
    result.status = CalibrationStatus::kDegenerate;
    result.message = os.str() +
                     ": the poses do not determine the string parameters (too little spread "
                     "or repeated poses); wave the grip through the whole workspace";
    return result;
  }
  // A string whose compliance is below the noise may come out slightly negative.
  for (auto& p : cal.strings) p.stretch = std::max(0.0, p.stretch);
  try {
    cal.Validate();
  } catch (const std::exception& e) {
    result.status = CalibrationStatus::kDegenerate;
    result.message = os.str() + ": unusable parameters: " + e.what();
    return result;
  }
  if (!converged) {
    result.status = CalibrationStatus::kNotConverged;
    result.message = os.str() + ": iteration budget exhausted";
    return result;
  }
  result.status = CalibrationStatus::kOk;
  result.message = os.str();
  result.calibration = cal;
  result.poses.resize(K);
  for (int k = 0; k < K; ++k) result.poses[k] = PoseFromState(states[k], d);
  return result;
}

std::vector<GripPose> RandomGripPoses(const SpidarGeometry& geometry, int count, double half_side,
                                      double max_rotation, double grasp_range, std::uint64_t seed) {
  std::vector<GripPose> poses;
  poses.reserve(std::max(count, 0));
  std::uint64_t state = seed ^ 0x5DEECE66DULL;
  const double margin = 0.01;
  int attempts = 0;
  while (static_cast<int>(poses.size()) < count && attempts < 1000 * std::max(count, 1)) {
    ++attempts;
    const Eigen::Vector3d p0(UniformIn(&state, -half_side, half_side),
                             UniformIn(&state, -half_side, half_side),
                             UniformIn(&state, -half_side, half_side));
    Eigen::Vector3d axis(UniformIn(&state, -1, 1), UniformIn(&state, -1, 1),
                         UniformIn(&state, -1, 1));
    if (axis.norm() < 1e-3 || axis.norm() > 1.0) continue;  // uniform direction by rejection
    const double angle = UniformIn(&state, 0.0, max_rotation);
    const Eigen::Matrix3d R = Eigen::AngleAxisd(angle, axis.normalized()).toRotationMatrix();
    const double grasp = std::numbers::pi / 2 + UniformIn(&state, -grasp_range, grasp_range);
    const GripPose pose = GripPose::FromFrame(p0, R, grasp, geometry.d);
    bool inside = true;
    for (int i = 0; i < kNumStrings && inside; ++i) {
      const Eigen::Vector3d P = pose.Attachment(i);
      inside = std::abs(P.x()) < geometry.a - margin && std::abs(P.y()) < geometry.b - margin &&
               std::abs(P.z()) < geometry.c - margin;
    }
    if (inside) poses.push_back(pose);
  }
  return poses;
}

KnownPoseSample HomingSample(const DeviceInfo& info, double homing_tension) {
  KnownPoseSample sample;
  sample.pose = info.home_pose;
  sample.counts.fill(0);
  sample.tension = Vector8d::Constant(homing_tension);
  return sample;
}

namespace {
EncoderReading SettleAndRead(SimulatedSpidarG* device, const GripPose& pose,
                             const Vector8d& tension) {
  device->SetTruePose(pose);
  device->WriteTensions(tension);
  // Ten time constants (or 20 ms) let the motors settle before the sample.
  const double settle = std::max(0.02, 10.0 * device->config().tension_time_constant);
  device->Step(settle);
  EncoderReading reading;
  device->Read(&reading);
  return reading;
}
}  // namespace

std::vector<KnownPoseSample> GatherKnownSamples(SimulatedSpidarG* device,
                                                const std::vector<GripPose>& poses,
                                                double tension) {
  std::vector<KnownPoseSample> samples;
  samples.reserve(poses.size());
  const Vector8d tau = Vector8d::Constant(tension);
  for (const GripPose& pose : poses) {
    const EncoderReading reading = SettleAndRead(device, pose, tau);
    samples.push_back({pose, reading.counts, tau});
  }
  return samples;
}

std::vector<UnknownPoseSample> GatherUnknownSamples(SimulatedSpidarG* device,
                                                    const std::vector<GripPose>& poses,
                                                    double tension) {
  std::vector<UnknownPoseSample> samples;
  samples.reserve(poses.size());
  const Vector8d tau = Vector8d::Constant(tension);
  for (const GripPose& pose : poses) {
    const EncoderReading reading = SettleAndRead(device, pose, tau);
    samples.push_back({reading.counts, tau});
  }
  return samples;
}

std::vector<UnknownPoseSample> GatherUnknownSamples(SimulatedSpidarG* device,
                                                    const std::vector<GripPose>& poses,
                                                    const std::vector<Vector8d>& tensions) {
  if (tensions.size() != poses.size()) {
    throw std::invalid_argument("GatherUnknownSamples: " + std::to_string(tensions.size()) +
                                " tension vectors for " + std::to_string(poses.size()) +
                                " poses (need one per pose)");
  }
  std::vector<UnknownPoseSample> samples;
  samples.reserve(poses.size());
  for (size_t k = 0; k < poses.size(); ++k) {
    const Vector8d& tau = tensions[k];
    const EncoderReading reading = SettleAndRead(device, poses[k], tau);
    samples.push_back({reading.counts, tau});
  }
  return samples;
}

std::vector<Vector8d> CalibrationTensions(int count, double lo, double hi, std::uint64_t seed) {
  std::vector<Vector8d> tensions(std::max(count, 0));
  std::uint64_t state = seed ^ 0x7E5510A5ULL;
  for (Vector8d& tau : tensions) {
    for (int i = 0; i < kNumStrings; ++i) tau[i] = UniformIn(&state, lo, hi);
  }
  return tensions;
}

AccuracyReport EvaluateAccuracy(SimulatedSpidarG* device, const EncoderCalibration& calibration,
                                const std::vector<GripPose>& poses, double tension_lo,
                                double tension_hi, std::uint64_t seed) {
  AccuracyReport report;
  const SpidarGeometry& geometry = device->info().geometry;
  FkSettings fk_settings;
  fk_settings.max_iterations = 50;
  fk_settings.max_residual = 0.05;  // accept poorly calibrated lengths: we measure the error
  fk_settings.warm_start = false;
  ForwardKinematics fk(geometry, fk_settings);
  std::uint64_t state = seed ^ 0xA5A5A5A5ULL;
  double sum = 0.0, sum_sq = 0.0, abs_sq = 0.0;
  int n_len = 0, n_pose = 0;
  double pos_sum = 0.0, rot_sum = 0.0;
  for (const GripPose& pose : poses) {
    Vector8d tau;
    for (int i = 0; i < kNumStrings; ++i) tau[i] = UniformIn(&state, tension_lo, tension_hi);
    const EncoderReading reading = SettleAndRead(device, pose, tau);
    const Vector8d truth = device->TrueLengths();
    const Vector8d estimate = calibration.Lengths(reading.counts, tau);
    for (int i = 0; i < kNumStrings; ++i) {
      const double rel = std::abs(estimate[i] - truth[i]) / truth[i];
      sum += rel;
      sum_sq += rel * rel;
      report.length_error_max = std::max(report.length_error_max, rel);
      abs_sq += (estimate[i] - truth[i]) * (estimate[i] - truth[i]);
      ++n_len;
    }
    ++report.num_poses;
    const FkResult r = fk.Solve(estimate);
    if (r.status != FkStatus::kOk) {
      ++report.fk_failures;
      continue;
    }
    const double dp = (r.pose.p0 - pose.p0).norm();
    const double dr = RotationAngleBetween(r.R_DT, pose.Rotation());
    pos_sum += dp;
    rot_sum += dr;
    report.position_error_max = std::max(report.position_error_max, dp);
    report.rotation_error_max = std::max(report.rotation_error_max, dr);
    report.grasp_error_max = std::max(report.grasp_error_max, std::abs(r.grasp - pose.Grasp()));
    ++n_pose;
  }
  if (n_len > 0) {
    report.length_error_mean = sum / n_len;
    report.length_error_sd = std::sqrt(
        std::max(0.0, sum_sq / n_len - report.length_error_mean * report.length_error_mean));
    report.length_abs_error_rms = std::sqrt(abs_sq / n_len);
  }
  if (n_pose > 0) {
    report.position_error_mean = pos_sum / n_pose;
    report.rotation_error_mean = rot_sum / n_pose;
  }
  return report;
}

}  // namespace spidarcad::haptics
