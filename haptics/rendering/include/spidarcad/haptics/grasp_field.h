// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
// Grasp rendering, the SPIDAR-G's 7th DOF: closing the grip on an object renders its width.
//
// The grip's poles (geometry.h; in T, pole 1 along u1 = c·b − s·a, pole 2 along
// u2 = c·b + s·a, c = cos θ/2, s = sin θ/2, b = (x+y)/√2, a = (x−y)/√2, each from −d to +d about
// p_WT) are sampled against the object's DistanceField (in its body frame O, placed by X_WO).
// Per pole k the deepest point (samples, then a golden-section refinement along the pole) gives
// the depth δ_k = max(0, −φ) at t_k along the pole, the object's outward unit normal n_k and
// the velocity of that point per unit of closing (−dθ): w_k = R_WT·t_k·∂u_k/∂(−θ), |w_k| = |t_k|/2.
// Closing pushes pole k into the object when a_k = n_k·w_k < 0. When BOTH poles touch that way
// the fingers squeeze the object. The squeeze depth is the shallower pole's, m = min(δ_1, δ_2),
// with a penalty energy k_n m², so the generalised force on θ is
//   Q = 2 k_n m (−a_j) − b_n r min(θ̇, 0),   j the shallower pole, r = min(1, m / grab_depth)
// (> 0, opening; damping only while closing, ramped in over grab_depth), and, since the
// generalised force on θ is −g/2 (tension.h), the grasp torque g = −2Q < 0: the grip stops
// where the fingers meet the object and pushes back; opening is free. One pole alone touching
// gives no grasp torque (the object would be pushed, not squeezed: six-DOF contact renders
// that). Q is continuous when the second pole touches or leaves (m = 0 there), though the first
// may be deep already: a sum over the poles, Σ_k k_n δ_k (−a_k), would jump by k_n δ_1 (−a_1)
// there, which a hand holding the grip at that angle feels as a buzz. Where both poles sink
// equally the two are the same. SqueezeQ below is the formula, shared with the clay width
// (app/src/scene/clay_width.h) and the assembly (assembly_field.h).
//
// Grasping: when both depths reach `grab_depth`, grasped() turns true and the object's pose
// relative to the tool X_TO is recorded; while grasped the object moves with the grip
// (X_WO = X_WT·X_TO, published for the app through LatestState()). It is released, where it
// is, as soon as the two poles no longer both touch it (the grip opened).
//
// Closed form for a check: a sphere of radius r centred at distance L from p_WT on the grip's
// bisector b (with L·cos(θ/2) ≤ d) meets both poles at θ* = 2·asin(r/L), and
//   Q(θ) = k_n (r − L sin θ/2) L cos θ/2 for θ < θ*.
// Stability: the angular stiffness on θ is k_n L² cos²(θ/2)/2 (3.4 N·m/rad for the defaults,
// L = 3 cm); with the grasp inertia of a hand (~1e-5 kg·m²) that is ω ≈ 580 rad/s, ω·T = 0.58
// at 1 kHz, stable with a hand's grasp damping above k_θ·T/2 ≈ 1.7e-3 N·m·s/rad.
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <atomic>
#include <cmath>
#include <limits>
#include <memory>

#include "spidarcad/haptics/distance_field.h"
#include "spidarcad/haptics/force_field.h"
#include "spidarcad/haptics/geometry.h"
#include "spidarcad/haptics/triple_buffer.h"

namespace spidarcad::haptics {

// The deepest point of a field along a pole, t ∈ [−d, d] (m along the pole's unit vector from the
// grip centre): `samples` (>= 2) evenly spaced values of phi(t), then `refine_iterations` steps of
// golden-section search around the best sample. The search stays within a sample spacing h of
// the best sample, so for a 1-Lipschitz φ (a signed distance or a bound of one) it cannot end
// below the best sample's value less h: when that is above `no_refinement_above` (m; with 1e-9 m
// of slack), the best sample is returned unrefined (an exact answer to "is the minimum below
// no_refinement_above?", at `samples` evaluations instead of samples + 2 + refine_iterations).
// Real-time safe (phi must be too).
struct PoleMinimum {
  double t = 0.0;    // where, m
  double phi = 0.0;  // the field's value there, m (< 0: inside)
};
template <class Phi>
PoleMinimum FindPoleMinimum(
    const Phi& phi, double d, int samples, int refine_iterations,
    double no_refinement_above = std::numeric_limits<double>::infinity()) noexcept {
  const double spacing = 2.0 * d / (samples - 1);
  PoleMinimum best{-d, phi(-d)};
  for (int j = 1; j < samples; ++j) {
    const double t = -d + j * spacing;
    const double v = phi(t);
    if (v < best.phi) best = {t, v};
  }
  if (best.phi - spacing > no_refinement_above + 1e-9) return best;
  double lo = best.t - spacing > -d ? best.t - spacing : -d;
  double hi = best.t + spacing < d ? best.t + spacing : d;
  constexpr double kInvPhi = 0.6180339887498949;
  double x1 = hi - kInvPhi * (hi - lo), x2 = lo + kInvPhi * (hi - lo);
  double f1 = phi(x1), f2 = phi(x2);
  for (int i = 0; i < refine_iterations; ++i) {
    if (f1 < f2) {
      hi = x2;
      x2 = x1;
      f2 = f1;
      x1 = hi - kInvPhi * (hi - lo);
      f1 = phi(x1);
    } else {
      lo = x1;
      x1 = x2;
      f1 = f2;
      x2 = lo + kInvPhi * (hi - lo);
      f2 = phi(x2);
    }
  }
  if (f1 < best.phi) best = {x1, f1};
  if (f2 < best.phi) best = {x2, f2};
  return best;
}

// One pole's contact with a solid, as GraspField and the clay width (app/src/scene/clay_width.h)
// see it: the deepest point along pole k (FindPoleMinimum), its depth δ = max(0, −φ) (m), where
// it is along the pole (t, m from p_WT), the solid's outward unit normal there n (W; zero when
// the field's gradient vanishes) and a = n·w, w = R_WT·t·∂u_k/∂(−θ) the velocity of that point
// per unit of closing (m/rad). `pushing`: δ > 0 and a < 0 (closing drives the pole deeper).
struct PoleContact {
  double t = 0.0;      // m along the pole's unit vector
  double depth = 0.0;  // δ, m
  double a = 0.0;      // n·w, m/rad
  Eigen::Vector3d normal_W = Eigen::Vector3d::Zero();
  bool pushing = false;
};
// The contact of pole k (0: pole 1, 1: pole 2) of the grip at p_WT, R_WT (poles = the grip's
// GripPoleDirections at its grasp angle), pole half-length d (m), with the solid whose signed
// distance at a point of W is phi(p_W, gradient_W or nullptr). `no_refinement_above` as
// FindPoleMinimum's (0: skip the refinement when the pole cannot reach inside, where the depth
// is 0 either way). Real-time safe (phi must be too).
template <class Phi>
PoleContact FindPoleContact(
    const Phi& phi, const Eigen::Vector3d& p_WT, const Eigen::Matrix3d& R_WT,
    const PoleDirections& poles, int k, double d, int samples, int refine_iterations,
    double no_refinement_above = std::numeric_limits<double>::infinity()) noexcept {
  PoleContact c;
  const Eigen::Vector3d u_W = R_WT * poles.u_T[k];
  auto phi_at = [&](double t) { return phi(Eigen::Vector3d(p_WT + t * u_W), nullptr); };
  const PoleMinimum m = FindPoleMinimum(phi_at, d, samples, refine_iterations, no_refinement_above);
  c.t = m.t;
  c.depth = m.phi < 0.0 ? -m.phi : 0.0;
  if (c.depth <= 0.0) return c;
  Eigen::Vector3d g;
  phi(Eigen::Vector3d(p_WT + m.t * u_W), &g);
  const double gn = g.norm();
  if (!(gn > 0.0)) return c;
  c.normal_W = g / gn;
  c.a = c.normal_W.dot(R_WT * (m.t * -poles.du_T[k]));
  c.pushing = c.a < 0.0;
  return c;
}

// Parameters of a GraspField. SI units, lengths in W.
struct GraspSettings {
  double pole_length = 0.04;   // d in W (world_scale × the device's d), m
  int samples = 17;            // samples per pole over [−d, d], >= 3
  int refine_iterations = 20;  // golden-section steps around the deepest sample
  double stiffness = 1e4;      // k_n, finger contact stiffness, N/m
  double damping = 2e-3;       // b_n, on θ while closing in contact, N·m·s/rad
  double grab_depth = 1e-4;    // both poles this deep: grasped, m
  // Throws std::invalid_argument naming the field and value when out of range.
  void Validate() const;
};

// The squeeze of two poles that both push (see the top of this file): the generalised force on
// θ, Q = 2 k_n m (−a) − b_n min(1, m / grab_depth) min(θ̇, 0) (N·m, > 0 opening), for the
// shallower pole's depth m >= 0 (m) and its a < 0 (m/rad), grasp_rate θ̇ (rad/s). Real-time
// safe; 0 for a non-finite result.
inline double SqueezeQ(double m, double a, double grasp_rate, const GraspSettings& s) noexcept {
  const double ramp = m < s.grab_depth ? m / s.grab_depth : 1.0;
  const double q =
      2.0 * s.stiffness * m * (-a) - s.damping * ramp * (grasp_rate < 0.0 ? grasp_rate : 0.0);
  return std::isfinite(q) ? q : 0.0;
}

// SqueezeQ of the shallower of two poles' contacts when both push; 0 otherwise.
inline double SqueezeOf(const PoleContact& pole1, const PoleContact& pole2, double grasp_rate,
                        const GraspSettings& s) noexcept {
  if (!(pole1.pushing && pole2.pushing)) return 0.0;
  const PoleContact& shallower = pole1.depth <= pole2.depth ? pole1 : pole2;
  return SqueezeQ(shallower.depth, shallower.a, grasp_rate, s);
}

// What the grasp field publishes for the app.
struct GraspState {
  bool grasped = false;
  Eigen::Isometry3d X_WO = Eigen::Isometry3d::Identity();  // the object's current pose
  double depth1 = 0.0, depth2 = 0.0;                       // δ per pole, m
};

// The grasp field (see the file comment). Evaluate keeps state; allocates nothing.
class GraspField final : public ForceField {
 public:
  // `object_O` (not null) in the object's frame O, placed at X_WO (rigid). Throws
  // std::invalid_argument on a null field, a non-rigid X_WO or bad settings.
  GraspField(std::shared_ptr<const DistanceField> object_O, const Eigen::Isometry3d& X_WO,
             const GraspSettings& settings = {});
  ToolWrench Evaluate(const ToolKinematics& tool) noexcept override;
  const char* name() const noexcept override { return "grasp"; }

  // Any thread: whether the object is held.
  bool grasped() const noexcept { return grasped_flag_.load(std::memory_order_acquire); }
  // Haptic thread (or tests): the object's pose, its pose in the tool frame while grasped,
  // and the last depths per pole (m).
  const Eigen::Isometry3d& X_WO() const noexcept { return X_WO_; }
  const Eigen::Isometry3d& X_TO() const noexcept { return X_TO_; }
  double depth(int pole) const noexcept { return pole == 0 ? depth_[0] : depth_[1]; }
  // App side (one reader thread): the state published by the latest Evaluate.
  const GraspState& LatestState() noexcept { return published_.Latest(); }
  const GraspSettings& settings() const noexcept { return settings_; }

 private:
  // φ of the object at p_W.
  double Phi(const Eigen::Vector3d& p_W, Eigen::Vector3d* gradient_W) const noexcept;

  std::shared_ptr<const DistanceField> object_;
  GraspSettings settings_;
  Eigen::Isometry3d X_WO_;
  Eigen::Isometry3d X_OW_;
  Eigen::Isometry3d X_TO_ = Eigen::Isometry3d::Identity();
  bool grasped_ = false;
  double depth_[2] = {0.0, 0.0};
  std::atomic<bool> grasped_flag_{false};
  TripleBuffer<GraspState> published_;
};

}  // namespace spidarcad::haptics
