// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
// FE grab as a haptic force field: closing the grip on an FE part grabs the surface patch under
// the tool, which then follows the grip rigidly in six DOF; the user feels the force and torque
// that hold the patch there. A sibling of FeTouchField (fe_touch_field.h) on the same FeModel and
// its ColumnCache.
//
// Frames and units: W world (the part's mesh frame), T tool (grip). Positions m, forces N,
// moments N·m about the point named, angles rad. All vectors in W.
//
// Grab. The grasp angle θ (ToolKinematics::grasp, π/2 at rest) closes the grip when it drops
// below close_angle and opens it when it rises above open_angle (hysteresis, as sculpt strokes).
// On the tick the grip closes, the patch is the unclamped surface nodes (ColumnCache candidates)
// inside the grab sphere(s) — one of radius tool_radius around the grip centre p_WT, or, with
// `grasp` set, one around each pole tip (FeTouchField::PoleTip's geometry) — nearest first, at
// most max_patch (<= kMaxFeGrabNodes) nodes. No node inside: nothing is grabbed until the grip
// opens and closes again. Opening the grip lets go: the force is zero from that tick on.
//
// Motion. The patch is attached to the grip: with p_0, R_0 the tool pose of the grab tick and
// p, R the current one, each grabbed node (rest position x_v) is held at
//   x_v + u0_v + (R_rel − I)(x_v − p_0) + (p − p_0),   R_rel = R R_0ᵀ,
// u0 its displacement under the model's own loads (so the grab starts without a jolt). In the
// terms of fem::GrabPatch (rotation about the patch centroid c): rotation vector r = log(R_rel)
// and translation t = (p − p_0) + (R_rel − I)(c − p_0).
//
// Wrench. The forces ON the body at the grabbed nodes, f = Ĝ_gg⁻¹ (u_g − u0_g), come from the
// condensed block Ĝ_gg of the patch (3n by 3n, the ColumnCache's columns; exact when every
// patch node's columns are ready, else the nearest ready column as FeTouchField reads it). They
// equal the reactions of fem::SolveGrab with the same (t, r) on the full model (loads aside). The
// published FE wrench is F = Σ f_v and M = Σ (x_v − c) × f_v about c; the tool feels the
// reaction −F, and the moment −Σ (x_v + u_v − p) × f_v about p_WT, each scaled by force_scale and
// clamped to max_force and max_torque (magnitudes; direction kept). No grasp torque.
//
// Virtual coupling (coupling_stiffness k_c > 0, as FeTouchField's, in six DOF). Held rigidly, a
// steel part is far too stiff to render (σ·EA/L of the platform is ~1e5 N/m: the grip chatters
// at the force limit). With a coupling, the patch is held at a coupled motion ξ_c = (t_c, r_c)
// of its own, joined to the grip's motion ξ = (t, r) by springs K_c = diag(k_c I, k_r I) (N/m,
// N·m/rad) in quasi-static equilibrium K_c (ξ − ξ_c) = σ K₆ ξ_c, K₆ the patch's 6 by 6 grab
// stiffness (wrench about c per unit (t, r), linear kinematics u = t + r × (x − c)), computed with
// the factor (six solves). So ξ_c = (K_c + σK₆)⁻¹ K_c ξ (a 6 by 6 matrix made with the factor):
// the felt stiffness is that of K_c and σK₆ in series, never above K_c. The FE state (targets,
// forces, t and r published) is that of ξ_c; the felt wrench is σ times its reaction, as without
// coupling.
//
// Threads. Factoring Ĝ_gg (up to 192 by 192, about a millisecond) is not done on the tick: the
// field owns a worker thread that does it into the one preallocated CachedContactSolver and hands
// it over with a generation counter (atomics, acquire/release; the haptic thread issues a patch
// only while the worker is idle and reads the solver only once the worker published the patch's
// generation). Until then the grab gives zero force; afterwards the felt wrench ramps in over
// ramp_seconds (linear in tick time), so the hand-over does not jolt. The worker first waits (at
// most column_wait_seconds) for the patch's own columns; meanwhile the haptic thread focuses the
// ColumnCache on the patch. With `worker` off (scripted runs on a virtual clock, tests), the grab
// tick factors the patch itself (no allocation, but O(n³) time): the forces are then a function
// of the trajectory alone.
//
// Evaluate is real-time safe: no allocation, lock, I/O or exception (the worker's hand-over is
// atomics only). Each tick's state goes to the main thread through an FeGrabChannel (triple
// buffer) for drawing (GrabDisplacement).
#pragma once

#include <Eigen/Core>
#include <array>
#include <atomic>
#include <memory>
#include <thread>
#include <vector>

#include "scene/fe_model.h"
#include "spidarcad/fem/column_cache.h"
#include "spidarcad/haptics/force_field.h"
#include "spidarcad/haptics/triple_buffer.h"

namespace spidarcad::app {

// Largest patch an FeGrabField holds, nodes.
inline constexpr int kMaxFeGrabNodes = 64;

// One tick's grab state, as published to the main thread (fixed size).
struct FeGrabState {
  // Loop time of the tick, s.
  double time = 0.0;
  // The grip is closed (θ hysteresis), and it holds a patch (num_nodes > 0).
  bool closed = false;
  bool held = false;
  // The patch's factored block is in use (false while the worker factors it: zero force).
  bool ready = false;
  // Ramp factor of the felt wrench in [0, 1].
  double ramp = 0.0;
  // Patch nodes n (<= kMaxFeGrabNodes) and those reading a substitute column.
  int num_nodes = 0;
  int num_substituted = 0;
  // Per node i < n: candidate index (FeModel::cache()) and the candidate whose column it reads.
  std::array<int, kMaxFeGrabNodes> candidate{};
  std::array<int, kMaxFeGrabNodes> substitute{};
  // Per node: prescribed total displacement (3, m) and force ON the body (3, N); forces are zero
  // until ready.
  std::array<double, 3 * kMaxFeGrabNodes> target{};
  std::array<double, 3 * kMaxFeGrabNodes> force{};
  // Patch centroid c (rest, W, m) and the grab as fem::GrabPatch terms: translation t (m) and
  // rotation vector r (rad) about c, of the FE state (the coupled motion with a coupling), and
  // the grip's own motion in the same terms.
  Eigen::Vector3d centroid = Eigen::Vector3d::Zero();
  Eigen::Vector3d t = Eigen::Vector3d::Zero();
  Eigen::Vector3d r = Eigen::Vector3d::Zero();
  Eigen::Vector3d t_grip = Eigen::Vector3d::Zero();
  Eigen::Vector3d r_grip = Eigen::Vector3d::Zero();
  // FE wrench ON the body (unscaled): force F (N) and moment about c (N·m).
  Eigen::Vector3d force_body = Eigen::Vector3d::Zero();
  Eigen::Vector3d moment_body = Eigen::Vector3d::Zero();
  // FE reaction on the tool (unscaled): force (N) and moment about p_WT (N·m).
  Eigen::Vector3d f_tool_W = Eigen::Vector3d::Zero();
  Eigen::Vector3d m_tool_W = Eigen::Vector3d::Zero();
  // Tool origin of the tick, W, m.
  Eigen::Vector3d p_WT = Eigen::Vector3d::Zero();
};

// Hand-off of grab states from the haptic thread (single writer) to the main thread.
struct FeGrabChannel {
  haptics::TripleBuffer<FeGrabState> buffer;
};

// Settings of an FeGrabField.
struct FeGrabSettings {
  // Radius of the grab sphere(s), m (> 0).
  double tool_radius = 0.01;
  // Patch nodes at most (1..kMaxFeGrabNodes).
  int max_patch = kMaxFeGrabNodes;
  // Felt wrench = force_scale · FE reaction (>= 0).
  double force_scale = 1.0;
  // Magnitude bounds of the felt force (N, > 0) and moment (N·m, > 0).
  double max_force = 10.0;
  double max_torque = 0.5;
  // Virtual coupling: translational k_c (felt N/m, >= 0; 0: the patch is held rigidly at the
  // grip) and rotational k_r (felt N·m/rad, > 0 when k_c > 0).
  double coupling_stiffness = 0.0;
  double coupling_rot_stiffness = 0.0;
  // Grip closes below close_angle and opens above open_angle (rad, 0 < close <= open).
  double close_angle = 70.0 * 3.14159265358979323846 / 180.0;
  double open_angle = 80.0 * 3.14159265358979323846 / 180.0;
  // Grab spheres at the pole tips (pole_length from p_WT, m, > 0) instead of one on p_WT.
  bool grasp = false;
  double pole_length = 0.02;
  // Ramp of the felt wrench once the patch is factored, s (>= 0; 0: none).
  double ramp_seconds = 0.005;
  // Factor patches on the field's worker thread (see the header); false: on the grab tick.
  bool worker = true;
  // How long the worker waits for the patch's own columns before using substitutes, s.
  double column_wait_seconds = 2.0;
};

// The FE grab as a haptic force field (see the header comment).
class FeGrabField final : public haptics::ForceField {
 public:
  // Field on `model`, publishing to `channel` (may be null). Starts the worker when
  // settings.worker. Throws std::invalid_argument naming the setting when out of range.
  FeGrabField(std::shared_ptr<FeModel> model, const FeGrabSettings& settings,
              std::shared_ptr<FeGrabChannel> channel);
  // Stops and joins the worker.
  ~FeGrabField() override;
  FeGrabField(const FeGrabField&) = delete;
  FeGrabField& operator=(const FeGrabField&) = delete;

  haptics::ToolWrench Evaluate(const haptics::ToolKinematics& tool) noexcept override;
  const char* name() const noexcept override { return "fe_grab"; }

  // The last tick's state (the haptic thread's copy).
  const FeGrabState& last_state() const { return state_; }
  const FeGrabSettings& settings() const { return settings_; }
  // Position (W) of the tip of pole i (0, 1) for a tool state (FeTouchField::PoleTip's geometry).
  Eigen::Vector3d PoleTip(const haptics::ToolKinematics& tool, int i) const;

 private:
  // Collects the patch for the tool state into pending_nodes_ (nearest first); returns its size.
  int CollectPatch(const haptics::ToolKinematics& tool);
  // Factors the requested patch into solver_ (worker thread, or the tick without a worker).
  void BuildSolver();
  void WorkerLoop();

  std::shared_ptr<FeModel> model_;
  fem::ColumnCache* cache_;
  FeGrabSettings settings_;
  std::shared_ptr<FeGrabChannel> channel_;
  std::unique_ptr<fem::CachedContactSolver> solver_;
  // Made with the factor (worker or grab tick): ξ_c = couple_ ξ (identity without coupling).
  Eigen::Matrix<double, 6, 6> couple_ = Eigen::Matrix<double, 6, 6>::Identity();
  // Made with it too: the centroid c of the held patch's rest positions (W, m).
  Eigen::Vector3d centroid_ = Eigen::Vector3d::Zero();
  std::array<double, 3 * kMaxFeGrabNodes> probe_target_{}, probe_force_{};

  // Patch request (written by the haptic thread only while the worker is idle).
  std::array<int, kMaxFeGrabNodes> request_{};
  int request_count_ = 0;
  std::atomic<unsigned> request_gen_{0};  // haptic thread: generation of the last request
  std::atomic<unsigned> built_gen_{0};    // worker: generation whose patch solver_ holds
  std::atomic<bool> stop_{false};
  std::thread worker_;

  // Haptic-thread state.
  bool closed_ = false;
  bool pending_ = false;  // closed on the part, request not issued yet (worker busy)
  unsigned held_gen_ = 0;
  double ready_time_ = 0.0;
  bool was_ready_ = false;
  Eigen::Vector3d p0_ = Eigen::Vector3d::Zero();
  Eigen::Matrix3d R0_ = Eigen::Matrix3d::Identity();
  haptics::ToolKinematics grab_tool_;
  // Patch found on the close tick, waiting to be issued as a request.
  std::array<int, kMaxFeGrabNodes> pending_nodes_{};
  std::array<double, kMaxFeGrabNodes> pending_dist_{};
  int pending_count_ = 0;
  // Candidate rest positions (W, m), copied at construction.
  std::vector<Eigen::Vector3d> positions_;
  FeGrabState state_;
};

// Displacement of the output nodes (3·#outputs, m) under a published grab state:
// u = u0 + Σ_i Ĝ(:, i) f_i (columns read as ContactDisplacement does). Columns evicted meanwhile
// are skipped (returns how many). Main thread; u_out is resized.
int GrabDisplacement(fem::ColumnCache* cache, const FeGrabState& state, Eigen::VectorXd* u_out);

}  // namespace spidarcad::app
