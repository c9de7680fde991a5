// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
// The implicit proxy ("god-object") field: a proxy point that stays on the free side of a
// DistanceField's surface while the tool point penetrates it; the user feels a spring from the
// tool point to the proxy (Zilles & Salisbury 1995; Salisbury & Tarr 1997 for implicit
// surfaces; Ruspini et al. 1997 for the constraint planes).
//
// One tick (ProxyField::Evaluate), with x the proxy and x_t = p_WT + R_WT·tip_T the tool point:
//  1. Free: sweep x → x_t. If the segment is free and x_t is outside (φ(x_t) >= 0), x = x_t and
//     the force is zero. The sweep steps by max(φ, min_step) (φ is a distance lower bound, so
//     steps of φ never cross the surface) and bisects where φ drops below −surface_tolerance,
//     so it cannot tunnel through a wall thicker than min_step whatever the tool speed. Points
//     with −tol <= φ < 0 are the surface itself (projection lands only within tol), so a proxy
//     a rounding error inside slides on; whether the tool is inside is decided by the sign of
//     φ(x_t) alone.
//  2. Contact: the proxy's tangent plane (point, unit gradient) becomes a constraint. The goal
//     is the point closest to x_t on the free side of the constraint planes (an exact QP over
//     at most 3 planes: every subset's equality projection, keep the closest feasible one).
//     Coulomb friction moves the goal back toward x: the proxy sticks while the tangential
//     offset |goal − x| ≤ μs·|x_t − goal| (tangential spring force within μs × normal force);
//     beyond, it slides and stays on the μd cone. The proxy then sweeps toward the goal; a new
//     surface met on the way (a concave edge or corner of a boolean) adds its tangent plane
//     (at most 3, oldest replaced) and the goal is recomputed, up to kMaxIterations times.
//     Finally Newton steps along the gradient put the proxy back on the surface (|φ| ≤ tol).
//  3. The proxy leaves the surface as soon as the tool point is outside and the segment from
//     the proxy to it is free.
// Force on the tool at x_t, in W:
//   f = k (x − x_t) − b (n·v_t) n, with the normal part never negative (never pulls inward),
// n the unit normal at the proxy and v_t the tool point's velocity; moment about p_WT is
// (R_WT·tip_T) × f. Zero force while not in contact.
//
// Stiffness and damping (defaults 1500 N/m, 1 N·s/m) at 1 kHz: a sampled spring k with hold is
// passive when the physical damping of hand plus device exceeds k·T/2 + b (Colgate & Schenkel
// 1997): 0.75 + 1 = 1.75 N·s/m at T = 1 ms, less than a relaxed human grasp (~2-10 N·s/m) and
// far less than the simulated hand's 20 N·s/m; the haptic loop's passivity observer covers the
// rest. Stiffer walls (2-3 kN/m) need LoopSettings::linear_damping of a few N·s/m.
#pragma once

#include <Eigen/Core>
#include <memory>

#include "spidarcad/haptics/distance_field.h"
#include "spidarcad/haptics/force_field.h"
#include "spidarcad/haptics/triple_buffer.h"

namespace spidarcad::haptics {

// Parameters of a ProxyField. SI units.
struct ProxySettings {
  double stiffness = 1500.0;      // k, N/m, > 0
  double damping = 1.0;           // b along the contact normal, N·s/m, >= 0 (contact only)
  double static_friction = 0.0;   // μs >= 0
  double dynamic_friction = 0.0;  // μd, 0 <= μd <= μs
  Eigen::Vector3d tip_T = Eigen::Vector3d::Zero();  // tool point offset in T, m
  double min_step = 2e-4;           // sweep step floor, m: thinner walls may be crossed
  int max_sweep_steps = 256;        // sweep step budget per sweep (then stops short, free side)
  double surface_tolerance = 1e-9;  // Newton projection stops when |φ| <= this, m
  // Throws std::invalid_argument naming the field and value when out of range.
  void Validate() const;
};

// What the proxy field publishes for the app (rendering the proxy).
struct ProxyState {
  Eigen::Vector3d proxy_W = Eigen::Vector3d::Zero();  // proxy position, m
  Eigen::Vector3d tool_W = Eigen::Vector3d::Zero();   // tool point x_t, m
  bool contact = false;                               // proxy held on the surface
};

// A god-object field on a DistanceField (see the file comment). State between ticks lives in
// members; Evaluate allocates nothing.
class ProxyField final : public ForceField {
 public:
  // Most constraint planes held at once (a corner).
  static constexpr int kMaxPlanes = 3;
  // Most goal-sweep-constrain rounds per tick.
  static constexpr int kMaxIterations = 6;

  // `environment` (not null) is the solid, in W. Throws std::invalid_argument on a null field
  // or bad settings.
  ProxyField(std::shared_ptr<const DistanceField> environment, const ProxySettings& settings = {});
  ToolWrench Evaluate(const ToolKinematics& tool) noexcept override;
  const char* name() const noexcept override { return "proxy"; }

  // Haptic thread (or tests): the proxy position, m, and whether it is held on the surface.
  const Eigen::Vector3d& proxy_W() const noexcept { return proxy_; }
  bool in_contact() const noexcept { return contact_; }
  bool sliding() const noexcept { return sliding_; }
  // App side (one reader thread): the state published by the latest Evaluate.
  const ProxyState& LatestState() noexcept { return published_.Latest(); }
  const ProxySettings& settings() const noexcept { return settings_; }

 private:
  struct Plane {
    Eigen::Vector3d point;
    Eigen::Vector3d normal;  // unit, pointing to the free side
  };
  // Moves from `from` toward `to` through passable points (φ >= −surface_tolerance: free
  // space and the surface); returns true when `to` is reached, with *phi_to (if not null) =
  // φ(to), m; else false with *stop passable just before the solid (or short of `to`) and,
  // when the solid blocked the way, *blocked (if not null) at the first sample deeper in it.
  bool Sweep(const Eigen::Vector3d& from, const Eigen::Vector3d& to, Eigen::Vector3d* stop,
             Eigen::Vector3d* blocked = nullptr, double* phi_to = nullptr) const noexcept;
  // Newton steps along the gradient onto φ = 0.
  void Project(Eigen::Vector3d* x) const noexcept;
  // Adds the plane through x with the unit gradient at `probe` as its normal (the tangent
  // plane when probe = x), merging one with nearly the same normal.
  void AddPlane(const Eigen::Vector3d& x, const Eigen::Vector3d& probe) noexcept;
  // The point closest to p on the free side of every plane (p itself when none is active).
  Eigen::Vector3d ConstrainedGoal(const Eigen::Vector3d& p,
                                  const Eigen::Vector3d& fallback) const noexcept;
  // Moves the frictionless goal g0 back toward the proxy x by the friction cone; updates sliding_.
  Eigen::Vector3d FrictionGoal(const Eigen::Vector3d& x, const Eigen::Vector3d& g0,
                               const Eigen::Vector3d& x_t) noexcept;
  ToolWrench Publish(const Eigen::Vector3d& x_t, const ToolWrench& w) noexcept;

  std::shared_ptr<const DistanceField> env_;
  ProxySettings settings_;
  // Tick state.
  bool initialized_ = false;
  bool contact_ = false;
  bool sliding_ = false;
  Eigen::Vector3d proxy_ = Eigen::Vector3d::Zero();
  Plane planes_[kMaxPlanes];
  int num_planes_ = 0;
  int oldest_plane_ = 0;
  mutable bool sweep_exhausted_ = false;  // a sweep of this tick ran out of its step budget
  TripleBuffer<ProxyState> published_;
};

}  // namespace spidarcad::haptics
