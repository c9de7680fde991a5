// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
// FE contact as a haptic force field: the tool pushes an FeModel and feels its reaction.
//
// Two contact models (FeTouchSettings::patch_contact). FE mode and `run` use the tool patch;
// the node-to-sphere model is kept for the tests and benchmarks that study single-node contact.
//
// Tool patch (patch_contact; docs/design/2026-12-04-fe-tool-patch.md): the tool is a ball of a
// physical radius R around its contact point c (the tool origin, the coupled point, or each pole
// tip). Where it meets the part it covers a patch, the free surface nodes within R of its touch
// point p that face it (outward normal n_b with n_b·n > 0): the patch whose stiffness `spidarcad
// felt` reports (scene/felt_stiffness.h, ToolPatchNodes). The local surface is a plane: its normal
// n the patch's dominant design normal (FeModel::design_normals: the gradient of the solid the
// mesh was made from where the model has it, else the mesh's node normal; the one most patch
// nodes' normals agree with; a flat face's normal exactly, also where a coarse mesh's facets
// slope next to a rounded edge the design has and the mesh cannot follow), its height the mean
// over the nodes agreeing with n of the loaded positions X_b + u0_b;
// c is h above it, p = c − h n, and the tool is δ = R − h deep (two fixed-point passes from the
// previous tick's n and p, or, entering, from the nearest free node within 2R). While δ > 0 the
// whole patch is pushed rigidly along −n by δ: each patch node's displacement is prescribed to u0_b
// − δ n (sticking, as felt's K is defined; frictionless: only its normal part n·u_b = n·u0_b − δ,
// the tangential parts free), so the force on the tool is K δ with K the patch stiffness, whatever
// the mesh resolves of it. A patch larger than max_contacts keeps its max_contacts nodes nearest p
// (a smaller punch: softer, never a jolt) and FeContactState::refused counts the rest. A contact
// point whose patch would pull (its force on the tool along n < 0, two contact points squeezing one
// part) is released and the rest solved again. The tool slides over the patch: what it feels is
// each patch's normal force (n·F) n (FeContactState::felt_normal_W; the sticking patch's tangential
// reaction holds the patch rigid and is published in f_tool_W, not felt), so the felt stiffness
// along n is K in series with the coupling. With the virtual coupling below, the coupled point out
// of contact stops where the plane fitted ahead of it is first reached (δ = 0), so contact begins
// at a vanishing depth.
//
// Node-to-sphere (sticking or frictionless): the tool is a sphere
// of radius r around a contact point (the tool origin p_WT, or, with grasp contact, each pole
// tip). Every undeformed surface node X inside a sphere (|X − c| < r) is a contact node (at
// most max_contacts of them, nearest the centre first; clamped nodes excluded). It is pushed
// along its inward normal −n (the area-weighted face normal) until it leaves the sphere:
// n·d = −t, |X − t n − c| = r, t > 0. Frictionless (default): the tangential displacements
// are left free, i.e. the contact forces are normal, f_s = β_s n_s, with n_s·u_s = −t_s (a k by
// k solve, CachedContactSolver::SolveNormal);
// sticking: the tangential displacement is held at zero. Either way the contact nodes end up
// with a full prescribed displacement d (published as the target) and the forces on the body
// f (N) solve Ĝ_cc f = d − u0_c with fem::CachedContactSolver (exact columns once ready, the
// nearest ready column until then). Nodes whose force would pull the body (n·f > 0) are
// released and the rest solved again (up to 4 passes a tick). A node inside the sphere that is
// not in contact is admitted only while the sphere reaches it on the deformed surface (its
// displacement predicted from the current contact forces is not already past the sphere). The
// force on the sphere is F = −Σ f_s (no moment: the contact sphere is centred on its point;
// grasp contact adds a squeeze torque, below). The published numbers are the unscaled FE ones.
//
// Felt force. Without coupling (coupling_stiffness = 0, and always with grasp contact) the
// sphere is centred on the tool and the felt force is σF, σ = force_scale, clamped to
// max_force. With a virtual coupling k_c > 0 (Colgate et al. 1995) the contact sphere sits at a
// point x_c of its own, joined to the tool point x_t by a spring k_c and in quasi-static
// equilibrium r(x_c) = k_c (x_t − x_c) + σF(x_c) = 0; the tool feels k_c (x_c − x_t), which
// equals σF(x_c) at equilibrium. So the felt stiffness is that of k_c and σK in series: never
// above k_c, however stiff the part's contact (local indentation of a steel node is ~1e8 N/m,
// and the encoders' 25 µm quantum times that made the force jump by newtons every tick), and
// close to σK where the part is soft (a cantilever's tip), which is what the engineer should
// feel. While in contact, each tick takes one Newton step on r from the previous x_c with the
// contact set's stiffness K along n̄ = F/|F| (one extra solve: the contact nodes moved rigidly
// along −n̄, sticking: the patch stiffness of scene/felt_stiffness.h, published as
// FeContactState::stiffness; an upper bound of the frictionless stiffness, so the step
// undershoots rather than overshoots and contact is not lost and regained every tick). Out of
// contact, x_c moves to x_t in one step (no drag in free space) unless a node would enter the
// sphere on the way: it then stops just past that point (conservative advancement), so contact
// always starts at a vanishing depth and a fast move cannot carry the sphere through a wall.
//
// Threads: Evaluate runs on the haptic thread and is real-time safe (no allocation, lock,
// I/O or exception; bounded work): the node lookup uses a uniform grid built at construction.
// The haptic thread is the single producer of the ColumnCache focus (RequestNear, sent when the
// tool moved by more than a quarter of the focus radius). Each tick's contact state goes to
// the main thread through a lock-free triple buffer in an FeContactChannel, which the field and
// the FE mode share (shared_ptr), so that the mode can draw the deformed part at 60 Hz with
// ContactDisplacement.
#pragma once

#include <Eigen/Core>
#include <array>
#include <memory>
#include <vector>

#include "scene/fe_model.h"
#include "spidarcad/fem/column_cache.h"
#include "spidarcad/haptics/force_field.h"
#include "spidarcad/haptics/triple_buffer.h"

namespace spidarcad::app {

// Largest number of contact nodes a touch field handles (per field, both poles together). 64
// holds the whole footprint of the default 10 mm tool on the platform at FE mode's default cell
// (P1 and P2) and down to about 5 mm cells with P1 (`spidarcad felt` prints the patch sizes;
// docs/fem.md, "Felt stiffness"); a 64-node contact solve takes about 22 µs
// (fem_bench BM_ContactTick/.../64), a few % of the 1 ms tick. Beyond it the nearest nodes are
// kept and FeContactState::refused counts the rest.
inline constexpr int kMaxFeContacts = 64;
// Felt force per FE newton that FE mode starts with (σ, per metre of grip motion in D: FE mode
// divides it by the world scale). With the coupling below, σ sets how much of the part's
// structural compliance is felt: the felt stiffness is k_c and σK in series. On the 12 mm steel
// platform (K ≈ 7e6 N/m at the free corner, including the local indentation) 1e-4 makes the corner
// feel several times softer than the plate over its gusset, which is felt near k_c
// (fe_mode_test, CouplingSettles...); 1e-3 makes the whole plate feel nearly rigid.
inline constexpr double kDefaultFeForceScale = 1e-4;
// Virtual coupling FE mode starts with, N/m of grip motion in D: the stiffest the contact is
// ever felt. The window's demo solids are felt at 1000 N/m.
inline constexpr double kDefaultFeCoupling = 1500.0;

// One tick's contact state, as published to the main thread (fixed size, copy without allocation).
struct FeContactState {
  // Loop time of the tick, s.
  double time = 0.0;
  // Number of contact nodes k (<= kMaxFeContacts).
  int num_contacts = 0;
  // Contacts whose column is still a substitute (nearest ready node).
  int num_substituted = 0;
  // Per slot s < k: candidate index (FeModel::cache()), the candidate whose column it reads.
  std::array<int, kMaxFeContacts> candidate{};
  std::array<int, kMaxFeContacts> substitute{};
  // Per slot: prescribed total displacement (3 per slot, m) and force ON the body (3, N).
  std::array<double, 3 * kMaxFeContacts> target{};
  std::array<double, 3 * kMaxFeContacts> force{};
  // FE force on the tool, −Σ f_s, N, in W (unscaled).
  Eigen::Vector3d f_tool_W = Eigen::Vector3d::Zero();
  // The FE force the tool feels, N, W (unscaled): f_tool_W for node-to-sphere contact; with the
  // tool patch, each patch's normal component (n·F) n, the tool sliding over the patch it holds
  // rigid (the tangential reaction of the sticking patch is not felt).
  Eigen::Vector3d felt_normal_W = Eigen::Vector3d::Zero();
  // Tool origin of the tick, W, m.
  Eigen::Vector3d p_WT = Eigen::Vector3d::Zero();
  // Centre of the contact sphere, W, m: the coupled point x_c with a virtual coupling, else p_WT.
  Eigen::Vector3d p_WC = Eigen::Vector3d::Zero();
  // Nodes inside the sphere(s) that could not be taken this tick (full, refused, no column).
  int refused = 0;
  // With a virtual coupling: the part stiffness K of the contact set (N/m, unscaled FE), the
  // force per metre that moves the contact nodes rigidly along −stiffness_normal (sticking; what
  // fem::SolveGrab gives for the same nodes, scene/felt_stiffness.h), and that unit normal n̄
  // (W; the direction of the FE force on the tool). The tool feels k_c and σK in series. 0 and
  // zero when not computed this tick.
  double stiffness = 0.0;
  Eigen::Vector3d stiffness_normal = Eigen::Vector3d::Zero();
  // True when no column at all is ready yet (no force could be computed).
  bool waiting_for_columns = false;
  // Tool patch (FeTouchSettings::patch_contact): the first contact point's depth δ (m, > 0 in
  // contact, else 0) and its patch's unit outward normal n (W; zero out of contact).
  double depth = 0.0;
  Eigen::Vector3d normal = Eigen::Vector3d::Zero();
};

// The hand-off of contact states from the haptic thread (single writer) to the main thread
// (single reader).
struct FeContactChannel {
  haptics::TripleBuffer<FeContactState> buffer;
};

// Settings of an FeTouchField.
struct FeTouchSettings {
  // Radius of the tool sphere, m (> 0), in W. Node-to-sphere: a radius near the mesh's surface
  // edge length makes contact smooth; smaller spheres slip between nodes. Tool patch: the tool's
  // physical radius R on the part (the patch's radius; FE mode and `run` do not scale it with
  // X_WD, scene/fe_part.h).
  double tool_radius = 0.01;
  // Contact model: the tool patch (true) or node-to-sphere (false); see the header comment.
  bool patch_contact = false;
  // Contact nodes at most (1..kMaxFeContacts). The tool's footprint is covered while the nodes
  // inside the sphere are no more than this (FeContactState::refused counts the others).
  int max_contacts = kMaxFeContacts;
  // Felt force = force_scale · FE force (>= 0).
  double force_scale = 1.0;
  // Magnitude bound of the felt force, N (> 0).
  double max_force = 10.0;
  // Virtual coupling stiffness k_c between the tool and the contact sphere, felt newtons per
  // metre of tool motion in W (>= 0; 0: no coupling, the sphere is on the tool). Ignored with
  // grasp contact.
  double coupling_stiffness = 0.0;
  // Frictionless contact (tangential forces zero); false: sticking nodes.
  bool frictionless = true;
  // Radius of the column focus around the tool, m; <= 0: 3 × tool_radius.
  double focus_radius = -1.0;
  // Two-point grasp contact: one sphere at each pole tip p_WT + pole_length·R_WT·p̂_i(θ), with
  // p̂_1 = cos(θ/2) b − sin(θ/2) a, p̂_2 = cos(θ/2) b + sin(θ/2) a, b = (x + y)/√2,
  // a = (x − y)/√2 in T (ARCHITECTURE.md grip frame; p̂_1 = y, p̂_2 = x at rest). The wrench
  // then has the moment of the tip forces about p_WT and the grasp torque
  // g = −Σ_i F_i · ∂tip_i/∂θ (N·m; g < 0 when the part pushes the poles apart).
  bool grasp = false;
  // Pole length in W, m (distance from the grip centre to each tip), for grasp contact.
  double pole_length = 0.02;
};

// The FE part as a haptic force field (see the header comment).
class FeTouchField final : public haptics::ForceField {
 public:
  // Field on `model` (shared with the app), publishing to `channel` (may be null: nothing
  // published). Throws std::invalid_argument naming the setting when out of range.
  FeTouchField(std::shared_ptr<FeModel> model, const FeTouchSettings& settings,
               std::shared_ptr<FeContactChannel> channel);
  ~FeTouchField() override;

  haptics::ToolWrench Evaluate(const haptics::ToolKinematics& tool) noexcept override;
  const char* name() const noexcept override { return "fe_touch"; }

  // The last tick's state (the haptic thread's copy; for tests and benchmarks on that thread).
  const FeContactState& last_state() const { return state_; }
  // The settings in use.
  const FeTouchSettings& settings() const { return settings_; }
  // Position (W) of the tip of pole i (0, 1) for a tool state, grasp contact geometry.
  Eigen::Vector3d PoleTip(const haptics::ToolKinematics& tool, int i) const;

 private:
  // Collects up to max_contacts candidates inside the sphere (c, r), nearest first, into
  // found_/found_dist_ (merging with what is there). Returns the number of nodes inside.
  int Collect(const Eigen::Vector3d& c, int sphere);
  // Calls visit(b) for every unclamped candidate b in the grid cells that overlap the box
  // [lo_p, hi_p] (W, m); false when the box misses the grid. Real-time safe.
  template <typename Visit>
  bool ForEachFreeCandidate(const Eigen::Vector3d& lo_p, const Eigen::Vector3d& hi_p,
                            Visit visit) const;
  // The virtual coupling's update of the tick (k contacts solved at the coupled centre, 0: none):
  // moves coupled_ and sets w's force.
  void CoupledStep(const Eigen::Vector3d& p_WT, int k, haptics::ToolWrench* w);
  // Distance λ in [0, length] at which the sphere moving from c along unit d first takes in a
  // free (unclamped) node not inside it already; `length` when none.
  double FirstEntry(const Eigen::Vector3d& c, const Eigen::Vector3d& d, double length) const;
  // Inserts candidate b at distance `dist` from its contact point `sphere` into found_ (nearest
  // first, at most max_contacts; a node found through both points keeps the nearer).
  void InsertFound(int b, double dist, int sphere);

  // Tool patch (see the header comment).
  struct PatchFit {
    Eigen::Vector3d normal = Eigen::Vector3d::Zero();    // n, unit, W
    Eigen::Vector3d point = Eigen::Vector3d::Zero();     // touch point p, W, m
    Eigen::Vector3d centroid = Eigen::Vector3d::Zero();  // a point of the plane, W, m
    double depth = 0.0;                                  // δ = R − h, m
  };
  // Loaded displacement u0 of candidate b (3, m).
  Eigen::Vector3d Baseline(int b) const;
  // The plane of the patch of a ball at c: from `prior` (previous normal and touch point) when
  // given, else from the nearest free node within 2R. False when no facing node is found.
  bool FitPatch(const Eigen::Vector3d& c, const PatchFit* prior, PatchFit* fit) const;
  // Contacts of the tool patch for contact points centre[0..spheres): sets found_ and solves;
  // returns k, sets *inside (patch nodes before the cap) and *solved.
  int PatchContacts(const Eigen::Vector3d* centre, int spheres, int* inside, bool* solved);
  // Per contact point: the patch of the last tick (valid: in contact).
  std::array<PatchFit, 2> patch_{};
  std::array<bool, 2> patch_valid_{};

  std::shared_ptr<FeModel> model_;
  fem::ColumnCache* cache_;
  FeTouchSettings settings_;
  std::shared_ptr<FeContactChannel> channel_;
  std::unique_ptr<fem::CachedContactSolver> solver_;
  // Candidate positions (undeformed, W) and fixed flags, copied for locality.
  std::vector<Eigen::Vector3d> positions_;
  std::vector<char> fixed_;
  // Uniform grid over the candidates: cell of size cell_, CSR lists.
  Eigen::Vector3d grid_min_ = Eigen::Vector3d::Zero();
  double cell_ = 1.0;
  Eigen::Vector3i dims_ = Eigen::Vector3i::Ones();
  std::vector<int> cell_start_, cell_items_;
  // Scratch of a tick (fixed size).
  std::array<int, kMaxFeContacts> found_{};
  std::array<double, kMaxFeContacts> found_dist_{};
  std::array<int, kMaxFeContacts> found_sphere_{};
  std::array<char, kMaxFeContacts> admit_{};
  int num_found_ = 0;
  std::array<int, kMaxFeContacts> sphere_of_slot_{};
  Eigen::Vector3d focus_ = Eigen::Vector3d::Constant(1e30);
  // Coupled sphere centre x_c (W, m) and whether it holds a value (reset by non-finite input).
  Eigen::Vector3d coupled_ = Eigen::Vector3d::Zero();
  bool coupled_valid_ = false;
  // Stiffness probe of the coupling (targets and forces, 3 per slot).
  std::array<double, 3 * kMaxFeContacts> probe_target_{};
  std::array<double, 3 * kMaxFeContacts> probe_force_{};
  // Unit inward normals of the contact slots (3 per slot), for the frictionless solve.
  std::array<double, 3 * kMaxFeContacts> normal_flat_{};
  std::array<Eigen::Vector3d, kMaxFeContacts> normal_{};
  FeContactState state_;
};

// Displacement of the output nodes (3·#outputs, m) under a published contact state:
// u = u0 + Σ_s Ĝ(:, s) f_s, reading each contact's substitute column shifted to the contact node
// as CachedContactSolver::OutputDisplacement does. Columns that were evicted meanwhile are
// skipped (returns how many contacts were skipped). Main thread; u_out is resized.
int ContactDisplacement(fem::ColumnCache* cache, const FeContactState& state,
                        Eigen::VectorXd* u_out);

}  // namespace spidarcad::app
