// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
// Assembly by touch (issue 5, the toy robot of the paper's Fig. 9): N rigid parts that the
// user picks up with the grasp (the 7th DOF), carries with six-DOF contact and seats peg in
// hole.
//
// Each part P has a body-frame DistanceField φ_P, a point shell sampled from its surface (in
// P), a pose X_WP, a kind (fixed: the body on the table, never moves; graspable) and seats:
// where it fits on another part O (X_OS, the pose of P in O's frame when seated, with position
// and angle tolerances).
//
// Per tick (Evaluate):
//  * Not carrying: the grip's two poles (grasp_field.h: pole k along u_k in T, from −d to +d
//    about p_WT) are sampled against every graspable part near the tool. When both poles push
//    into one part while closing, the grasp torque g = −2Q < 0 renders the part's width
//    (Q = 2 k_n m (−a_j) − b_n r min(θ̇, 0) of the shallower pole j, m = min(δ_1, δ_2):
//    grasp_field.h's SqueezeQ, continuous as the second pole touches); once both depths reach
//    `grab_depth` the part is picked up at its current relative pose X_TP = X_WT⁻¹ X_WP.
//    The tool itself touches the parts through its own point shell (`tool_shell`, in T, may
//    be empty): a direct penalty, each point inside part j pushed out along ∇φ_j,
//    f_i = s·k_p·max(0, −φ_j) n, s = min(1, N_ref/N_contact), moment about p_WT.
//  * Carrying part c: the part is a virtual object V (pose X_WV, mass m, inertia diag(I))
//    coupled to the target pose X_WT·X_TP through a 6-DOF spring-damper (as PointShellField,
//    with the coupling at the part's origin):
//      f_c = k_c (p_target − p_WV) + b_c (v_target − v_WV),
//      τ_c = k_r log(R_target R_WVᵀ) + b_r (ω_WT − ω_WV);
//    its shell points x_i = p_WV + R_WV r_i against every other part j get penalty forces
//      f_ij = s·max(0, k_p (−φ_j(x_i)) − b_p n·v(x_i)) n   (n = unit ∇φ_j, s as above).
//    V is integrated with semi-implicit Euler in `substeps` steps. The shell points within
//    `contact_margin` (plus the tick's travel) of another part are found once per tick (the
//    shell's clusters of nearby points, cells of 1 cm, are skipped whole when their centre is
//    farther from the part than their radius plus that reach, and a point of a cluster when the
//    centre is farther than its offset from the centre plus the reach: φ is 1-Lipschitz; and a
//    point while φ_j at the point where this carry's search last evaluated it, less its travel
//    since, is beyond the reach: the other parts do not move during a carry), where φ_j and ∇φ_j
//    are evaluated once; the substeps use the first-order expansion
//    φ_j(x) ≈ φ_j(x0) + ∇φ_j(x0)·(x − x0) (the part moves well under a millimetre per tick) and
//    expand only the candidates whose bound φ_j(x0) − |∇φ_j| |x − x0| can reach 0. So a tick
//    costs one φ and ∇φ per shell point that may be near another part; the cluster centres
//    (φ alone) and the points of each part j are each evaluated in one
//    DistanceField::EvaluateBatch (several points at a time where φ_j supports it), as are the
//    tool shell's points against each part. The user
//    feels the coupling's reaction at the target point: f_T_W = −f_c, m_T_W = (p_target − p_WT) ×
//    (−f_c) − τ_c, plus the grasp torque of the poles on the part at its target pose (the fingers
//    keep squeezing while it is held). The part is released as soon as the two poles no longer both
//    push into it (the grip opened): it stays at X_WV. If it then lies within a seat's
//    tolerance (|p_WP − p_WS| <= position_tolerance and the angle of R_WSᵀ R_WP <=
//    angle_tolerance, X_WS = X_WO·X_OS) its pose snaps to X_WS exactly and `seated` is set.
//    A part built within a seat's tolerance (a document saved with the part seated) starts
//    seated, at the pose it was given; `seated` is cleared when a part is picked up.
//    While a part is carried and the document's snap is on (AlignmentSnapSettings.enabled), each
//    of its seats within capture (|p_WV − p_WS| < capture_distance and the angle between the
//    part's axis R_WV e_z and the seat's axis a = R_WS e_z below capture_angle) draws the part
//    toward the seat (alignment snap): the seat's axis is the line through p_WS along a, the z
//    axis of the seat frame S (the peg toward the hole's axis); the part's axis is the z axis of
//    P, which lies on it when seated (X_WP = X_WS). With e = p_WV − p_WS, e_⊥ = e − (e·a) a and
//    the misalignment ρ = α (z_V × a)/|z_V × a| (α the angle between z_V = R_WV e_z and a),
//      f_a = −k_a w e_⊥,  τ_a = k_α w ρ,
//      w = S(1 − |e|/capture_distance) · S(1 − α/capture_angle),  S(x) = x²(3 − 2x) on [0, 1],
//    summed over the seats in capture, then capped at max_force and max_torque (scaled along
//    their direction). w is zero at the capture boundary with its slope, so the pull grows from
//    nothing (no jump). Nothing pulls along the axis: the user pushes the peg home. f_a and τ_a
//    act on V in every substep beside the contact forces, so the user feels them through the
//    coupling, that is through the grip (at rest in free space −f_c = f_a).
//    A released part cannot be picked up again until the poles have stopped squeezing it (so
//    a snap into the seat does not grab it back). There is no gravity: a part released in the air
//    stays where it was let go. Parts not carried never move (the tool does not push them around).
//
// Publishing: every tick the poses and seated flags go to the app through a TripleBuffer of a
// fixed-size AssemblyState. Evaluate is real-time safe: every buffer is sized at construction.
#pragma once
#include <Eigen/Core>
#include <Eigen/Geometry>
#include <array>
#include <atomic>
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "spidarcad/haptics/distance_field.h"
#include "spidarcad/haptics/force_field.h"
#include "spidarcad/haptics/grasp_field.h"
#include "spidarcad/haptics/point_shell_field.h"
#include "spidarcad/haptics/triple_buffer.h"

namespace spidarcad::haptics {

// Most parts an AssemblyField manages (the size of the published state).
inline constexpr int kMaxAssemblyParts = 16;

// Where a part fits on another part.
struct AssemblySeat {
  int other = -1;                                          // index of the other part O
  Eigen::Isometry3d X_OS = Eigen::Isometry3d::Identity();  // this part's pose in O when seated
  double position_tolerance = 2e-3;                        // m
  double angle_tolerance = 0.1;                            // rad
};

// One rigid part.
struct AssemblyPart {
  std::string name;                              // for logs and the app
  std::shared_ptr<const DistanceField> field_P;  // φ in the part's frame P
  PointShell shell_P;                            // surface samples in P (may be empty if fixed)
  Eigen::Isometry3d X_WP = Eigen::Isometry3d::Identity();  // initial pose
  bool fixed = false;                                      // true: never moves, cannot be grasped
  std::vector<AssemblySeat> seats;                         // where it fits
};

// Alignment snap of a carried part toward its seats (see the file comment). SI units.
struct AlignmentSnapSettings {
  bool enabled = false;             // on where the document enables snap
  double capture_distance = 0.015;  // |p_WV − p_WS| below which a seat pulls, m
  double capture_angle = 0.35;      // axis angle below which a seat pulls, rad (20°)
  double stiffness = 200.0;         // k_a, N/m (toward the axis)
  double rot_stiffness = 0.05;      // k_α, N·m/rad (axis alignment)
  double max_force = 1.0;           // cap of |f_a|, N
  double max_torque = 0.01;         // cap of |τ_a|, N·m
};

// Parameters of an AssemblyField. SI units, lengths in W.
struct AssemblySettings {
  GraspSettings grasp;                                        // poles, finger stiffness, grab depth
  double mass = 0.05;                                         // carried part's virtual mass, kg
  Eigen::Vector3d inertia = Eigen::Vector3d::Constant(2e-5);  // its body inertia diag, kg·m²
  double coupling_stiffness = 1000.0;                         // k_c, N/m
  double coupling_damping = 3.0;                              // b_c, N·s/m
  double rot_coupling_stiffness = 2.0;                        // k_r, N·m/rad
  double rot_coupling_damping = 0.01;                         // b_r, N·m·s/rad
  double contact_stiffness = 1000.0;                          // k_p per point, N/m
  double contact_damping = 1.0;                               // b_p per point, N·s/m
  int reference_contacts = 10;                                // N_ref (force averaging)
  int substeps = 10;                                          // integration steps per tick
  double contact_margin = 2e-3;                               // candidate margin, m
  int max_points = 4096;                                      // largest shell per part
  double max_dt = 0.01;                                       // longer ticks are clamped, s
  bool cull_shell_search =
      true;  // false: test every shell point each tick (same result, slower; for tests)
  bool batch_evaluation =
      true;  // false: evaluate the shell search's points and the tool shell's one Evaluate at
             // a time instead of through DistanceField::EvaluateBatch (the same result, bit for
             // bit; slower; for tests)
  bool skip_far_candidates =
      true;  // false: expand every candidate in every substep, not only those whose bound
             // φ0 − |∇φ| |x − x0| can reach 0 (the same result, bit for bit; slower; for tests)
  AlignmentSnapSettings align;  // alignment snap while carrying (off by default)
  // Throws std::invalid_argument naming the field and value when out of range.
  void Validate() const;
};

// What the field publishes for the app (fixed size: no allocation to copy).
struct AssemblyState {
  // All poses identity, nothing seated.
  AssemblyState() { X_WP.fill(Eigen::Isometry3d::Identity()); }
  int count = 0;                                          // number of parts
  int carried = -1;                                       // index of the carried part, −1 none
  int contacts = 0;                                       // penetrating shell points, last tick
  std::array<Eigen::Isometry3d, kMaxAssemblyParts> X_WP;  // poses (carried: its virtual pose)
  std::array<bool, kMaxAssemblyParts> seated{};           // seated flags
};

// The assembly field (see the file comment).
class AssemblyField final : public ForceField {
 public:
  // 1..kMaxAssemblyParts parts with non-null fields, rigid poses, shells of at most
  // settings.max_points points (a graspable part needs a non-empty shell) and seats naming
  // another existing part. `tool_shell` (in T) may be empty. Throws std::invalid_argument
  // naming the part and field otherwise.
  AssemblyField(std::vector<AssemblyPart> parts, PointShell tool_shell = {},
                const AssemblySettings& settings = {});

  ToolWrench Evaluate(const ToolKinematics& tool) noexcept override;
  const char* name() const noexcept override { return "assembly"; }

  // Haptic thread (or tests): number of parts, their current poses (the carried one at its
  // virtual pose), seated flags, the carried part (−1 none), its pose in T.
  int size() const noexcept { return static_cast<int>(parts_.size()); }
  const Eigen::Isometry3d& X_WP(int i) const noexcept { return poses_[i]; }
  bool seated(int i) const noexcept { return seated_[i]; }
  int carried() const noexcept { return carried_; }
  const Eigen::Isometry3d& X_TP() const noexcept { return X_TP_; }
  // Penetrating shell points in the last tick.
  int contacts() const noexcept { return contacts_; }
  // Shell points of the carried part found within reach of another part in the last carrying
  // tick (the candidates its substeps test; 0 when nothing is carried).
  int candidates() const noexcept { return carried_ >= 0 ? num_candidates_ : 0; }
  // The parts as given (names, seats, initial poses).
  const AssemblyPart& part(int i) const noexcept { return parts_[i]; }
  // Whether pose X_WP of part i is within the tolerance of one of its seats (with the other
  // parts at their current poses); writes the seated pose to *X_WS when it is. Real-time safe.
  bool FindSeat(int i, const Eigen::Isometry3d& X_WP, Eigen::Isometry3d* X_WS) const noexcept;
  // The alignment snap wrench (f_a at the part's origin, τ_a; W, N and N·m) on part i at pose
  // X_WP, with the other parts at their current poses: zero when align.enabled is false or no
  // seat is within capture. Returns whether a seat is within capture. Real-time safe.
  bool AlignmentWrench(int i, const Eigen::Isometry3d& X_WP, Eigen::Vector3d* f_W,
                       Eigen::Vector3d* tau_W) const noexcept;
  // App side (one reader thread): the state published by the latest Evaluate.
  const AssemblyState& LatestState() noexcept { return published_.Latest(); }
  const AssemblySettings& settings() const noexcept { return settings_; }

 private:
  // φ of part j at p_W with the gradient in W (when not null).
  double Phi(int j, const Eigen::Vector3d& p_W, Eigen::Vector3d* gradient_W) const noexcept;
  // Puts p_W, in part j's frame, at position m of the batch.
  void Gather(int j, int m, const Eigen::Vector3d& p_W) noexcept;
  // φ of part j at the batch's first m points (∇φ in P too when `gradient`), one EvaluateBatch
  // or, without settings.batch_evaluation, m Evaluate calls.
  void EvaluateGathered(int j, int m, bool gradient) noexcept;
  // The gradient EvaluateGathered left at batch position k, turned into W as Phi turns it.
  Eigen::Vector3d GatheredGradient_W(int j, int k) const noexcept;
  // Grasp generalised force Q (>= 0, SqueezeQ) of the poles on part j at pose X_WP_j (for the
  // carried part, its target pose); *both_pushing tells whether both poles push into it; depths to
  // *depths (m; when both push: once one pole does not, the other is not searched and Q is 0).
  double PoleGrasp(int j, const Eigen::Isometry3d& X_WPj, const ToolKinematics& tool,
                   bool* both_pushing, double depths[2]) const noexcept;
  // Tool shell penalty against all parts at the grip pose.
  ToolWrench ToolContact(const ToolKinematics& tool) noexcept;
  // One tick of the carried part's virtual coupling; returns the coupling wrench on the user.
  ToolWrench CarryStep(const ToolKinematics& tool, double dt) noexcept;
  // Publishes the state.
  void Publish() noexcept;

  std::vector<AssemblyPart> parts_;
  PointShell tool_shell_;
  AssemblySettings settings_;
  std::vector<Eigen::Isometry3d> poses_;    // X_WP per part
  std::vector<Eigen::Isometry3d> inverse_;  // X_PW per part
  std::vector<double> radius_;              // shell radius per part
  std::vector<char> seated_;
  // Each part's shell in clusters of nearby points (cells of kClusterCell in P), for the carried
  // part's per-tick candidate search: a cluster whose centre lies at φ_j >= its radius + reach
  // from part j holds no candidate (φ_j is 1-Lipschitz), so its points are not evaluated.
  struct ShellCluster {
    Eigen::Vector3d centre_P = Eigen::Vector3d::Zero();  // m, in P
    double radius = 0.0;                                 // largest |r_i − centre|, m
    int begin = 0, end = 0;  // its points: cluster_points_[part][begin, end)
  };
  static constexpr double kClusterCell = 0.01;       // m
  std::vector<std::vector<ShellCluster>> clusters_;  // per part
  std::vector<std::vector<int>> cluster_points_;     // per part: shell indices in cluster order
  std::vector<std::vector<double>>
      cluster_point_offset_;                     // per part, cluster order: |r_i − centre|, m
  std::vector<std::uint64_t> near_;              // bit i: shell point i is in a cluster near part j
  std::vector<int> candidate_point_;             // capacity max shell × parts
  std::vector<double> candidate_phi_;            // φ at the tick's start, m
  std::vector<Eigen::Vector3d> candidate_grad_;  // ∇φ there (W)
  std::vector<Eigen::Vector3d> candidate_x0_;    // the point there (W), m
  std::vector<double> candidate_grad_norm_;      // |∇φ| there
  std::vector<double> candidate_reach_;          // |∇φ| |r_i|, m
  std::vector<std::vector<double>> shell_point_norm_;  // per part: |r_i| of its shell points, m
  // The batches of the searches and of the tool shell (structure of arrays, in the frame of the
  // part evaluated), capacity the largest shell: points, φ, ∇φ, and the shell index of each
  // point.
  std::vector<double> batch_x_, batch_y_, batch_z_, batch_phi_, batch_gx_, batch_gy_, batch_gz_;
  std::vector<int> batch_point_;
  std::vector<Eigen::Vector3d> batch_x_W_;  // the batch's points in W, m
  // Per (part j, shell point i of the carried part), at index j · (largest shell) + i: φ_j
  // where the search last evaluated it during carry number last_epoch_ (m), and that point (W,
  // m). Other parts do not move while one is carried, so φ_j(x) >= last φ − |x − last x|.
  std::vector<double> last_phi_;
  std::vector<Eigen::Vector3d> last_x_;
  std::vector<int> last_epoch_;
  int search_epoch_ = 0;  // carries so far (0: none; last_epoch_ starts at 0, which never holds)
  int num_candidates_ = 0;
  int carried_ = -1;
  int released_ = -1;  // just released: not grasped again until the poles stop squeezing it
  int contacts_ = 0;
  Eigen::Isometry3d X_TP_ = Eigen::Isometry3d::Identity();
  Eigen::Quaterniond q_ = Eigen::Quaterniond::Identity();  // carried part's rotation R_WV
  Eigen::Vector3d v_ = Eigen::Vector3d::Zero();            // carried part's velocity (origin), W
  Eigen::Vector3d w_ = Eigen::Vector3d::Zero();            // its angular velocity, W
  bool initialized_ = false;
  double last_time_ = 0.0;
  TripleBuffer<AssemblyState> published_;
};

}  // namespace spidarcad::haptics
