// Force display with strings: the wrench matrix A (Eq. 10-15) and the tension distribution
// (Eq. 16-17 as re-derived in docs/architecture.md). Real-time safe: no allocation or exceptions in
// WrenchMatrix and TensionSolver::Solve.
//
// Wrench on the grip q = (f, m, g), a 7-vector: force f [N] in D, moment m about p0 [N·m] in D,
// grasp torque g [N·m] = Σ τ_i δ_i n·(r_i × c_i). Sign convention: g > 0 squeezes the grip
// closed (drives the grasp angle θ down); the generalised force conjugate to θ is −g/2, i.e.
// for any motion of the grip the power of the strings is Σ τ_i c_i·Ṗ_i = f·ṗ0 + m·ω − (g/2) θ̇.
// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#pragma once

#include <cstdint>

#include "spidarcad/haptics/geometry.h"

namespace spidarcad::haptics {

// A = [w_1 ... w_8], 7 by 8: column i is w_i = [c_i; r_i × c_i; δ_i n·(r_i × c_i)], the wrench
// on the grip from unit tension in string i (Eq. 10). q = A τ (Eq. 15). c_i is the unit vector
// from the attachment point P_(i) toward the corner Q_i, r_i = P_(i) − p0, n = p̂1 × p̂2.
// A string of zero length or parallel poles give non-finite entries (TensionSolver::Solve
// then reports kInvalidInput).
Matrix78d WrenchMatrix(const SpidarGeometry& geometry, const GripPose& pose);

// Force closure of the strings at a pose: whether tensions within bounds can display every
// small wrench. It holds when A has rank 7 and its null vector n (A n = 0, 8 strings, 7 DOF)
// can be taken strictly positive: then adding a multiple of n raises every tension without
// changing the wrench, so any wrench is displayed with high enough tensions. Without closure
// some wrench directions need a negative tension (a string pushing) and are lost whatever
// τ_max is.
struct ForceClosure {
  bool closure = false;  // rank 7 and every component of null_vector > 0
  // min_i n_i / max_i |n_i| of the unit null vector oriented so Σ n_i ≥ 0: in (0, 1] with
  // closure, ≤ 0 without (the most negative string's share). NaN for non-finite A.
  double margin = 0;
  // Unit null vector of the scaled A (moment and grasp rows times 1/d), oriented as above.
  Vector8d null_vector = Vector8d::Zero();
  // Smallest singular value of the scaled A (N per N of tension): near 0 the strings lose a
  // wrench direction altogether (rank < 7).
  double sigma_min = 0;
};

// Force closure of the wrench matrix A (7 by 8, from WrenchMatrix) for pole half-length d [m]
// (the moment and grasp rows are scaled by 1/d so every row is in N per N). No allocation.
ForceClosure ForceClosureAt(const Matrix78d& A, double d);

// Weights and bounds of the tension distribution problem
//   J = |f − F τ|² + S0 |m − M τ|² + S1 (g − G τ)² + S2 |τ|²,  τ_min ≤ τ_i ≤ τ_max,
// where F (3 by 8), M (3 by 8) and G (1 by 8) are the force, moment and grasp rows of A.
struct TensionSettings {
  // N; positive keeps every string taut (a slack string loses the pose).
  double tau_min = 0.2;
  // N; motor limit.
  double tau_max = 8.0;
  // S0 [m⁻²] weighs moment error (N·m)² against force error N². Every lever arm is d long, so a
  // unit tension changes the moment by ~d N·m but the force by ~1 N: with S0 = 1/d² a commanded
  // moment counts as much as a commanded force of the same "string effort". With S0 ~ 1 the
  // moment rows are ~d² = 1/625 as important as the force rows and most of a commanded moment is
  // silently dropped whenever it competes with a force or a bound. Default 1/(0.04 m)².
  double s0 = 625.0;
  // S1 [m⁻²] weighs grasp-torque error; same lever arm d, same reasoning and default.
  double s1 = 625.0;
  // S2 [dimensionless] (continuity) penalises large tensions: it makes the problem strictly
  // convex (A has a one-dimensional null space), hence the optimum unique and continuous in q,
  // and picks the lowest string pretension that displays q. Its bias on the displayed wrench is
  // about S2/σ² relative (σ ~ 1 the singular values of the weighted A): 0.1 % for 1e-3.
  double s2 = 1e-3;

  // Throws std::invalid_argument naming the field and value when a setting is out of range:
  // 0 <= tau_min < tau_max (finite), s0 > 0, s1 > 0, s2 > 0 (finite).
  void Validate() const;
  // Defaults scaled for a grip of pole half-length d [m] (S0 = S1 = 1/d²).
  static TensionSettings ForPoleLength(double d);
};

// Outcome of a tension solve.
enum class TensionStatus : std::uint8_t {
  // Exact optimum; weighted |lost| <= 1 % of (weighted |q| + |τ|) + 1 mN. The |τ| term
  // covers the S2 bias, which scales with the tensions (the pretension that keeps strings taut
  // off centre), not with q: at q = 0 and 5 cm off centre it is ~3 mN.
  kOk = 0,
  kSaturated,     // exact optimum, but part of the request lies outside what the strings can
                  // deliver within [τ_min, τ_max] (see TensionResult::lost)
  kInvalidInput,  // q or A contained NaN or infinity: τ = τ_min everywhere
  kNotConverged,  // iteration cap reached (not expected: 8 variables); τ is feasible
};

// One word for a status ("ok", "saturated", "invalid_input", "not_converged").
const char* TensionStatusName(TensionStatus status);

// Result of TensionSolver::Solve.
struct TensionResult {
  Vector8d tau = Vector8d::Zero();       // string tensions, N, shape 8, in [τ_min, τ_max]
  Vector7d achieved = Vector7d::Zero();  // A τ, the wrench actually displayed
  Vector7d lost = Vector7d::Zero();      // q − A τ, the part of the request not displayed
  double objective = 0;                  // J at τ (NaN when the input was invalid)
  int iterations = 0;                    // active-set changes (adds + drops)
  int num_at_min = 0;                    // strings held at τ_min
  int num_at_max = 0;                    // strings held at τ_max
  TensionStatus status = TensionStatus::kInvalidInput;
};

// Exact solver of the bounded least-squares problem above: a primal active-set method on the
// 8 tensions (strictly convex since S2 > 0), warm-started from the previous call's active set.
// Each iteration solves the 8 by 8 reduced normal equations with a fixed-size Cholesky
// factorisation. No heap allocation and no exceptions in Solve.
class TensionSolver {
 public:
  // Throws std::invalid_argument when the settings are invalid (see TensionSettings::Validate).
  explicit TensionSolver(const TensionSettings& settings = {});

  // Tensions for the wrench request q (shape 7: f, m, g) given the wrench matrix A (7 by 8).
  TensionResult Solve(const Matrix78d& A, const Vector7d& q);
  // Forgets the warm-start active set (the next Solve starts with every string free).
  void Reset();

  const TensionSettings& settings() const { return settings_; }

  // Most active-set changes per Solve before giving up with kNotConverged.
  static constexpr int kMaxIterations = 64;

 private:
  TensionSettings settings_;
  // Active set of the last solve: 0 free, -1 at τ_min, +1 at τ_max.
  Eigen::Matrix<std::int8_t, 8, 1> active_ = Eigen::Matrix<std::int8_t, 8, 1>::Zero();
};

}  // namespace spidarcad::haptics
