// Force display with strings: the wrench matrix A (Eq. 10-15) and the tension distribution
// (Eq. 16-17 as corrected in ERRATA.md). Real-time safe: no allocation or exceptions in
// WrenchMatrix and TensionSolver::Solve.
//
// Wrench on the grip q = (f, m, g): force f [N] in D, moment m about p0 [N·m] in D, grasp
// torque g [N·m] = Σ τ_i δ_i n·(r_i × c_i). Sign convention: g > 0 squeezes the grip closed
// (drives the grasp angle θ down); the generalised force conjugate to θ is −g/2.
// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#pragma once

#include <cstdint>

#include "spidarcad/haptics/geometry.h"

namespace spidarcad::haptics {

// A = [w_1 ... w_8], 7 by 8: column i is w_i = [c_i; r_i × c_i; δ_i n·(r_i × c_i)], the wrench
// on the grip from unit tension in string i (Eq. 10). q = A τ (Eq. 15).
Matrix78d WrenchMatrix(const SpidarGeometry& geometry, const GripPose& pose);

// Weights and bounds of the tension distribution problem
//   J = |f − F τ|² + S0 |m − M τ|² + S1 (g − G τ)² + S2 |τ|²,  τ_min ≤ τ_i ≤ τ_max.
struct TensionSettings {
  double tau_min = 0.2;   // N; positive keeps every string taut (slack strings lose the pose)
  double tau_max = 8.0;   // N; motor limit
  // S0 weighs moment error (N·m)² against force error N². Levers are ~d long, so S0 ~ 1/d²
  // makes a commanded moment count as much as a force; default 1/(0.04 m)² = 625 m⁻².
  double s0 = 625.0;
  // S1 weighs grasp-torque error, same reasoning and default.
  double s1 = 625.0;
  // S2 (continuity) penalises large tensions and makes the optimum unique and smooth in q.
  double s2 = 1e-3;

  // Throws std::invalid_argument naming the field when a setting is out of range
  // (0 <= tau_min < tau_max, finite; s0, s1 > 0; s2 >= 0).
  void Validate() const;
  // Defaults scaled for a grip of pole half-length d (S0 = S1 = 1/d²).
  static TensionSettings ForPoleLength(double d);
};

// Outcome of a tension solve.
enum class TensionStatus : std::uint8_t {
  kOk = 0,          // exact optimum found, request displayed within 1 % of |q|
  kSaturated,       // exact optimum found, but part of the request lies outside what the
                    // strings can deliver (see `lost`)
  kInvalidInput,    // q or A contained NaN or infinity: τ = τ_min everywhere
  kNotConverged,    // iteration cap reached (not expected: the problem has 8 variables)
};

struct TensionResult {
  Vector8d tau = Vector8d::Zero();  // string tensions, N
  Vector7d achieved = Vector7d::Zero();  // A τ, the wrench actually displayed
  Vector7d lost = Vector7d::Zero();      // q − A τ, the part of the request not displayed
  double objective = 0;  // J at the optimum
  int iterations = 0;    // active-set changes
  TensionStatus status = TensionStatus::kInvalidInput;
};

// Exact solver of the bounded least-squares problem above: an active-set method on 8
// variables, warm-started from the previous call's active set. No allocation in Solve.
class TensionSolver {
 public:
  explicit TensionSolver(const TensionSettings& settings = {});

  // Tensions for the wrench request q (7) given the wrench matrix A (7 by 8).
  TensionResult Solve(const Matrix78d& A, const Vector7d& q);
  // Forgets the warm-start active set.
  void Reset();

  const TensionSettings& settings() const { return settings_; }

 private:
  TensionSettings settings_;
  // Active set of the last solve: 0 free, -1 at τ_min, +1 at τ_max.
  Eigen::Matrix<int8_t, 8, 1> active_ = Eigen::Matrix<int8_t, 8, 1>::Zero();
};

}  // namespace spidarcad::haptics
