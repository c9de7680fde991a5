// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
// Six-DOF contact of the grip as a rigid tool: a point shell of the tool against the scene's
// DistanceField, with a virtual tool and virtual coupling (McNeely, Puterbaugh & Troy 1999,
// voxel/point-shell rendering; Colgate, Stanley & Brown 1995, virtual coupling).
//
// The tool's surface is a point shell: points r_i in the tool frame with inward unit normals
// (kept for the app and for generators; the force direction comes from the environment's
// gradient). A virtual tool V (pose X_WV, mass m, body inertia diag(I)) is simulated inside
// the field; the grip pose X_WT (what the user holds) pulls it through a 6-DOF spring-damper:
//   f_c = k_c (p_WT − p_WV) + b_c (v_WT − v_WV)                       (force on V, at p_WV)
//   τ_c = k_r log(R_WT R_WVᵀ) + b_r (ω_WT − ω_WV)                      (torque on V)
// with a soft zone (below): within `coupling_soft_zone` of the grip the spring and the damper
// act at `soft_zone_ratio` of their strength. Each shell point x_i = p_WV + R_WV r_i with
// φ_i = φ(x_i) < 0 gets a penalty force along the environment's unit gradient n_i,
//   f_i = s · max(0, k_p (−φ_i) − b_p n_i·v(x_i)) n_i,  torque (x_i − p_WV) × f_i,
// where s = min(1, N_ref / N_contact) averages the force when many points touch (McNeely's
// trick: the contact stiffness never exceeds N_ref·k_p, which bounds the integration's
// stiffness whatever the shell size). V is integrated with semi-implicit Euler in `substeps`
// steps per tick (gyroscopic term neglected); the grip pose is held over the tick. The user
// feels the coupling's reaction: f_T_W = −f_c, m_T_W = −τ_c (the spring joins p_WT and p_WV,
// so no moment arm about p_WT), grasp torque 0.
//
// Soft zone (free-space noise). The grip pose comes from quantised encoders: held still, p_WT
// jitters by about one encoder quantum (0.025 mm per string; ~0.02 mm rms in p_WT on the
// simulated device) and the loop's finite-difference velocity by ~7 mm/s rms. V does not
// follow that jitter (its coupling resonance is ~22 Hz), so a full-strength coupling renders
// k_c·jitter + b_c·v_noise ≈ 0.03 N rms (0.09 N peaks) of chatter in free space, where the
// proxy renders nothing. Inside a zone of radius δ = coupling_soft_zone (2 quanta) around the
// grip the spring and the damper both act at ε = soft_zone_ratio of their strength; beyond δ
// the spring has its full slope k_c and the damping ramps to b_c over [δ, 2δ]:
//   F_s(r) = ε k_c r                 (r ≤ δ)      F_s(r) = k_c r − (1 − ε) k_c δ   (r > δ)
// along the stretch, r = |p_WT − p_WV| (likewise for rotation with rot_coupling_soft_zone).
// The spring stays conservative (a convex radial potential) and the damper dissipative (a
// non-negative coefficient), so the coupling stays passive; contact keeps its stiffness (the
// slope beyond δ is k_c; the felt force is only offset by (1 − ε) k_c δ = 0.045 N).
//
// Tunnelling (conservative advancement). Each substep's motion of V is limited so that no
// shell point ends deeper than `max_penetration` in the environment: for a point at distance
// φ_i moving by at most μ_i = |Δp| + |Δθ| |r_i| (Δp = h v, Δθ = h ω), φ is 1-Lipschitz, so the
// move is safe while μ_i ≤ φ_i + d_max; a point near the surface may also use the local
// plane, n_i·δx_i ≥ −(φ_i + d_max), for moves up to `min_step`. Points that are not
// candidates this tick stay free while V's accumulated motion in the tick is below the reach
// they were selected with. A point that would pass the depth limit receives an inelastic
// impulse along n_i (its inward velocity is cut to what reaches the limit; rigid-body
// effective mass); what is still blocked after a few impulses scales the whole substep's
// motion and V's velocities (both only remove energy). So a grip that jumps 4 or 10 cm in one
// tick (a glitch, a fast flick) pulls V against a 2 mm plate, never through it; the felt
// force is then the coupling's k_c·stretch, which the loop's wrench limit caps. Keep
// max_penetration + min_step below half of the thinnest wall of the scene. The limit also
// holds ordinary contacts once the penalty runs out of depth (beyond s·k_p·d_max per point:
// 0.6 N for a single touching point, 6 N for a face): V then rests on the limit and the user
// feels the coupling alone (k_c, stiffer than the coupling and penalty in series).
//
// Cost: once per tick the shell points are tested at V's pose (a broad phase first: when
// φ(p_WV) exceeds the shell's radius plus a margin nothing is tested); points within
// `contact_margin` plus the distance V can travel in a tick become candidates, and only they
// are evaluated in the substeps. The test skips a point whose last φ, less the most V's motion
// since can have moved it (|Δp| + |Δθ| |r_i|, summed over the substeps), is still beyond the
// reach (`cull_by_motion`): the same candidates as testing every point, at the cost of the
// points near the environment. Likewise, in a substep a candidate whose bound keeps it out of
// contact is evaluated only if the conservative advancement needs its exact φ. Each of these
// evaluations is one DistanceField::EvaluateBatch over all the points concerned (the solids' tapes
// run several points per pass, bit-identical to one at a time). Buffers are sized at construction:
// Evaluate allocates nothing.
//
// Defaults (0.05 kg, k_c = 1000 N/m, b_c = 3 N·s/m, k_r = 2 N·m/rad, b_r = 0.01 N·m·s/rad,
// k_p = 1000 N/m per point, N_ref = 10, 10 substeps): the coupling is what the device renders
// (1 kN/m, within what a 1 kHz loop renders stably with a hand's damping; see proxy_field.h);
// the contact (at most 10 kN/m) and the coupling give ω·h < 0.05 per substep, far inside the
// explicit integrator's stability bound of 2. Lengths (soft zone, margin, max_penetration,
// min_step) are in W: scale them with the world scale.
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <memory>
#include <vector>

#include "spidarcad/haptics/distance_field.h"
#include "spidarcad/haptics/force_field.h"
#include "spidarcad/haptics/triple_buffer.h"

namespace spidarcad::haptics {

// A tool surface as points with inward normals, both in the tool frame T (m; unit normals).
struct PointShell {
  std::vector<Eigen::Vector3d> points_T;   // #P points
  std::vector<Eigen::Vector3d> normals_T;  // #P inward unit normals

  // Given points and inward normals (normalised here). Throws std::invalid_argument when the
  // sizes differ, a value is not finite or a normal is zero.
  static PointShell FromPoints(const std::vector<Eigen::Vector3d>& points_T,
                               const std::vector<Eigen::Vector3d>& normals_T);
  // About `count` points spread evenly (Fibonacci spiral) on a sphere of `radius` centred at
  // the tool origin.
  static PointShell Sphere(double radius, int count);
  // A box centred at the tool origin with half sides h: on each face a grid of cells about
  // `spacing` wide, one point at each cell centre (edges and corners are not sampled).
  static PointShell Box(const Eigen::Vector3d& half_sides, double spacing);
  // The cross grip at rest as two capsules of radius `radius` around the poles (pole 1 along
  // y, pole 2 along x, each from −d to +d; geometry.h), `rings` rings of `around` points per
  // pole plus a point at each pole end.
  static PointShell CrossGrip(double d, double radius, int rings, int around);
  // Number of points.
  int size() const noexcept { return static_cast<int>(points_T.size()); }
  // Largest |r_i|, m.
  double Radius() const noexcept;
};

// Parameters of a PointShellField. SI units.
struct PointShellSettings {
  double mass = 0.05;                                         // virtual tool mass, kg
  Eigen::Vector3d inertia = Eigen::Vector3d::Constant(2e-5);  // body inertia diag, kg·m²
  double coupling_stiffness = 1000.0;                         // k_c, N/m
  double coupling_damping = 3.0;                              // b_c, N·s/m
  double rot_coupling_stiffness = 2.0;                        // k_r, N·m/rad
  double rot_coupling_damping = 0.01;                         // b_r, N·m·s/rad
  double contact_stiffness = 1000.0;                          // k_p per point, N/m
  double contact_damping = 1.0;                               // b_p per point, N·s/m
  int reference_contacts = 10;                                // N_ref (force averaging)
  int substeps = 10;                                          // integration steps per tick
  double contact_margin = 2e-3;                               // candidate margin, m
  int max_points = 4096;                                      // shell size bound
  double max_dt = 0.01;                                       // longer ticks are clamped, s
  double coupling_soft_zone = 5e-5;  // δ: radius of the soft zone (2 encoder quanta), m; 0: off
  double rot_coupling_soft_zone = 2e-3;  // rotational soft zone, rad; 0: off
  double soft_zone_ratio = 0.1;          // ε in [0, 1]: coupling strength inside the zone
  double max_penetration = 6e-4;         // d_max: deepest a shell point may go, m
  double min_step = 2e-4;                // longest substep move judged by the local plane, m
  // Narrow phase by motion bounds: a point whose φ, when last evaluated, minus the most V can
  // have moved it since, still exceeds the tick's reach is not evaluated again (φ is
  // 1-Lipschitz, so it cannot be a candidate). The candidates, hence every result, are the same
  // as with every point evaluated each tick (false), which tests compare against.
  bool cull_by_motion = true;
  // Throws std::invalid_argument naming the field and value when out of range.
  void Validate() const;
};

// Contact wrench on a tool pose, about the tool's centre, in W.
struct ShellContact {
  Eigen::Vector3d force_W = Eigen::Vector3d::Zero();   // N
  Eigen::Vector3d torque_W = Eigen::Vector3d::Zero();  // N·m about the tool centre
  int contacts = 0;                                    // penetrating points
};

// What the field publishes for the app (to draw the virtual tool).
struct PointShellState {
  Eigen::Vector3d p_WV = Eigen::Vector3d::Zero();
  Eigen::Quaterniond q_WV = Eigen::Quaterniond::Identity();
  int contacts = 0;
};

// The six-DOF point-shell field (see the file comment).
class PointShellField final : public ForceField {
 public:
  // `environment` (not null) in W. Throws std::invalid_argument on a null field, an empty
  // shell, a shell larger than settings.max_points, or bad settings.
  PointShellField(std::shared_ptr<const DistanceField> environment, PointShell shell,
                  const PointShellSettings& settings = {});
  ToolWrench Evaluate(const ToolKinematics& tool) noexcept override;
  const char* name() const noexcept override { return "point_shell"; }

  // The penalty contact wrench (without damping, s included) on the whole shell at pose X_WV,
  // about p_WV. Real-time safe; for tests and tools.
  ShellContact ContactAt(const Eigen::Isometry3d& X_WV) const noexcept;
  // Haptic thread (or tests): the virtual tool's state.
  const Eigen::Vector3d& p_WV() const noexcept { return p_; }
  const Eigen::Quaterniond& q_WV() const noexcept { return q_; }
  const Eigen::Vector3d& v_WV() const noexcept { return v_; }
  const Eigen::Vector3d& w_WV() const noexcept { return w_; }
  // Contact points in the last substep.
  int contacts() const noexcept { return contacts_; }
  // App side (one reader thread): the state published by the latest Evaluate.
  const PointShellState& LatestState() noexcept { return published_.Latest(); }
  const PointShell& shell() const noexcept { return shell_; }
  const PointShellSettings& settings() const noexcept { return settings_; }

 private:
  // Contact wrench from the candidate points at the current state (damping included); stores
  // each candidate's φ, gradient and lever r = R_WV r_T.
  ShellContact CandidateContact(const Eigen::Matrix3d& R_WV) noexcept;
  // Coupling force and torque on V (soft zone included) for the grip state `tool` (q_T its
  // rotation) at V's current state.
  void Coupling(const ToolKinematics& tool, const Eigen::Quaterniond& q_T, Eigen::Vector3d* f_c,
                Eigen::Vector3d* tau_c) const noexcept;
  // Conservative advancement of one substep of length h: applies impulses and scales v_, w_
  // so that moving by h v_, h w_ keeps every point above −max_penetration and the tick's
  // travel (`travelled` so far) within `budget` (m). `inv_inertia_W` is R I⁻¹ Rᵀ.
  // Lower bound of shell point i's φ now from its last evaluation and V's travel since, with
  // the slack kCullMargin (−∞ when it has none).
  double PhiLowerBound(int i) const noexcept;
  // Candidate k's exact φ and gradient at the current state, evaluated now if CandidateContact
  // left it at a lower bound.
  void MakeExact(int k) noexcept;
  void ConstrainMotion(double h, double budget, double travelled,
                       const Eigen::Matrix3d& inv_inertia_W) noexcept;

  std::shared_ptr<const DistanceField> env_;
  PointShell shell_;
  PointShellSettings settings_;
  double shell_radius_;
  std::vector<int> candidates_;               // capacity #P, sized at construction
  std::vector<double> candidate_phi_;         // φ of candidate k at the substep's start, m
  std::vector<Eigen::Vector3d> candidate_g_;  // ∇φ of candidate k (normalised where used)
  std::vector<Eigen::Vector3d> candidate_r_;  // lever R_WV r_T of candidate k, m
  std::vector<double> point_radius_;          // |r_T| of each shell point, m
  int num_candidates_ = 0;
  int contacts_ = 0;
  bool initialized_ = false;
  double last_time_ = 0.0;
  Eigen::Vector3d p_ = Eigen::Vector3d::Zero();
  Eigen::Quaterniond q_ = Eigen::Quaterniond::Identity();
  Eigen::Vector3d v_ = Eigen::Vector3d::Zero();
  Eigen::Vector3d w_ = Eigen::Vector3d::Zero();
  TripleBuffer<PointShellState> published_;
  // Scratch of the batch evaluations (capacity #P): points in W (m), φ, gradients, and which
  // shell point each entry of the narrow phase's batch is.
  std::vector<double> batch_x_, batch_y_, batch_z_, batch_phi_;
  std::vector<double> batch_gx_, batch_gy_, batch_gz_;
  std::vector<int> batch_index_;
  // Narrow phase by motion bounds: per point, φ at its last evaluation (−∞: none since the
  // last reset) and the travel accumulators then; the accumulators sum |Δp| (m) and |Δθ| (rad)
  // of V over every substep.
  std::vector<double> last_phi_, last_travel_p_, last_travel_theta_;
  double travel_p_ = 0.0, travel_theta_ = 0.0;
  // Per candidate: candidate_phi_ is exact (1) or a lower bound >= 0 (0, cull_by_motion: a
  // candidate that cannot touch in this substep is evaluated only if ConstrainMotion needs it).
  std::vector<char> candidate_exact_;
  // Sphere clusters of the shell (cull_by_motion): the points binned on a grid in the tool
  // frame, each cluster's centre (T, m) and radius (m, the farthest of its points), and each
  // point's cluster. When the motion bounds leave many points unbounded (the first tick near
  // a part), φ at the cluster centres bounds every point of a cluster at once
  // (φ(x) >= φ(c) − ρ), so the far side of the shell is not evaluated point by point.
  void BuildClusters();
  std::vector<Eigen::Vector3d> cluster_centre_T_;
  std::vector<double> cluster_radius_;
  std::vector<int> point_cluster_;
};

}  // namespace spidarcad::haptics
