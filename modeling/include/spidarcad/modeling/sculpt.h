// Freeform sculpting of a closed triangle mesh with tools driven by the 7-DOF grip pose (the
// paper's freeform design: amorphous shapes stretched, twisted and bent, material adjustable,
// volume conservation optional).
//
// Design: a stroke is Lagrangian. BeginStroke finds, through a uniform spatial grid, the vertices
// within the tool radius R of the grab centre c (the grip position at the start of the stroke)
// and freezes their start positions, falloff weights and normals. Each UpdateStroke maps every
// affected vertex from its START position through a deformation field of the grip's motion since
// the start (never incrementally), so the result depends only on the current pose and grasp, not
// on how many updates came before, and a step costs O(affected vertices). Refinement (splitting
// stretched edges) runs when the stroke ends, only on the triangles the stroke touched.
//
// Deformation fields (our own; none is a Kelvinlet): a compactly supported polynomial falloff
//   w(r) = (1 - (r/R)^2)^n for r < R, 0 beyond, with r = |p_start - c|,
// whose exponent n grows with the tool's stiffness (stiffer material: sharper falloff), blended
// into rigid motions of the grip:
//   grab      p = p0 + s w Δp                       (Δp: grip translation since the start)
//   twist     p = c + Rot(z, s w α) (p0 - c)        (α: twist of the grip about its start z axis)
//   bend      p = c + Rot(u, s w φ t) (p0 - c),     t = clamp((p0 - c)·x / R, -1, 1)
//             (φ u: angle-axis of the grip's rotation; x: the grip's start x axis; both sides of
//             the grab centre turn the same way, like a rod bent by a moment)
//   push/pull p = p0 + s w h n0                     (h = Δp·n_c, n_c the mean normal at the grab
//             centre: pulling the grip outward raises a bump, pushing it in makes a dent)
//   smooth    p = p0 + s w τ (T(p0) - p0)           (T: Taubin λ/μ smoothing of the region,
//             computed once at the start; τ = min(1, |Δp| / R): rubbing further smooths more)
// with s the grab strength in [0, 1] from the grasp angle θ: s = clamp((π/2 - θ)/(π/2 - θ_closed),
// 0, 1): an open grip (rest, θ = π/2) holds nothing, closing it picks up the material.
//
// Volume conservation (optional): after the field, every affected vertex moves by λ c n0 along its
// start normal, with the ring weight c = 4 w (1 - w) (zero at the grab centre, so the grabbed
// material still follows the grip exactly, and at the rim; a weight of w itself would have the
// push/pull field's shape and undo it), and λ from Newton's method on the enclosed volume, which
// is computed incrementally over the affected triangles only (the rest of the mesh does not
// move). Pulling a bump out thus sinks a shallow moat around it, as clay does.
//
// Haptics: StrokeForceModel is a small copyable value the app can hand to the haptic thread;
// ComputeStrokeWrench evaluates the resisting wrench without allocating.
//
// Self-intersection: with SculptToolSettings::prevent_self_intersection (the default), each update
// checks the moved triangles against each other and against every triangle near them; when the
// full stroke would make the surface cross itself, the strength is scaled down by bisection to
// the largest share (to 1/256) that does not, so the clay stops where it would fold (the share is
// StrokeStats::limit). A region that already intersects itself at the start is not checked.
// Limits: short edges are not collapsed; refinement splits at straight
// midpoints (it does not add curvature); the grab centre is the grip position, so the app should
// put the grip on the surface (or snap it) before BeginStroke.
//
// Frames and units: every position is in the world frame W (m); the grip pose is X_WT (the tool
// frame T of ARCHITECTURE.md: x, y in the plane of the poles, z = a × b); grasp angles in rad.
// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <array>
#include <cstdint>
#include <numbers>
#include <unordered_map>
#include <utility>
#include <vector>

#include "spidarcad/modeling/surface_mesher.h"

namespace spidarcad::modeling {

namespace internal {
// One triangle of SculptMesh's self-intersection check (sculpt_intersection.cc): scratch data
// computed once per check from the current positions (m, W).
struct SculptCheckTriangle {
  Eigen::Vector3d lo, hi;            // bounding box corners, m
  Eigen::Vector3d normal;            // (p1 - p0) × (p2 - p0), m²
  double normal_norm = 0.0;          // |normal|, m²
  double edge_product = 0.0;         // |p1 - p0| |p2 - p0|, m²
  double diagonal = 0.0;             // |hi - lo|, m
  Eigen::Vector3i corners;           // vertex indices p0, p1, p2
  std::array<Eigen::Vector3d, 3> p;  // their positions, m
  std::array<int, 3> cell_lo{};      // broad-phase cells spanned by the box, per axis
  std::array<int, 3> cell_hi{};
};
}  // namespace internal

// The sculpting tools.
enum class SculptTool { kGrab, kTwist, kBend, kPushPull, kSmooth };

// Name of a tool ("grab", "twist", "bend", "push_pull", "smooth").
const char* SculptToolName(SculptTool tool);

// Stiffness at which the falloff exponent is 3 (the classic (1 - q²)³ bump), N/m.
inline constexpr double kReferenceSculptStiffness = 300.0;

// Falloff exponent n of w(r) = (1 - (r/R)²)^n for a stiffness (N/m): 3 (k / kReference)^(1/3),
// clamped to [1.5, 12]. Soft material spreads the motion widely, hard material keeps it local.
double SculptFalloffExponent(double stiffness);

// Falloff weight for distance r (m), radius R (m) and exponent n: (1 - (r/R)²)^n inside, 0 outside.
double SculptFalloffWeight(double r, double radius, double exponent);

// Grab strength in [0, 1] for grasp angle theta (rad): 0 at or above π/2 (rest or opened),
// 1 at or below closed_angle, linear between.
double SculptGrabStrength(double theta, double closed_angle);

// Settings of one stroke (one tool).
struct SculptToolSettings {
  SculptTool tool = SculptTool::kGrab;
  // Falloff radius R (m), > 0: vertices farther than R from the grab centre never move.
  double radius = 0.02;
  // Material stiffness (N/m), > 0: sets the falloff exponent (SculptFalloffExponent) and the force
  // the haptic side feels (N per m of grabbed-material displacement; N·m/rad is stiffness × R²).
  double stiffness = kReferenceSculptStiffness;
  // When true the grab strength follows the grasp angle (SculptGrabStrength); when false it is 1.
  bool grasp_controls_strength = true;
  // Grasp angle (rad) at which the strength reaches 1; must be < π/2.
  double grasp_closed_angle = std::numbers::pi / 4;
  // Keep the enclosed volume equal to the stroke-start volume (see the file comment).
  bool conserve_volume = false;
  // Smooth tool: Taubin iterations (λ = 0.5, μ = -0.53) computing the target shape.
  int smooth_iterations = 10;
  // Refinement at EndStroke: edges of touched triangles longer than this (m) are split at their
  // midpoints until none is; 0 disables refinement.
  double max_edge_length = 0.0;
  // Refinement stops after this many splits (a guard against a huge stretch).
  int max_splits = 2000000;
  // Stop the stroke short of making the surface intersect itself (see the file comment).
  bool prevent_self_intersection = true;
};

// What the haptic thread needs to compute the resisting wrench of the active stroke: a plain,
// fixed-size value without heap memory (copy it into the haptic scene).
struct StrokeForceModel {
  // False when no stroke is active: the wrench is zero.
  bool active = false;
  SculptTool tool = SculptTool::kGrab;
  double stiffness = kReferenceSculptStiffness;  // N/m
  double radius = 0.02;                          // m
  bool grasp_controls_strength = true;
  double grasp_closed_angle = std::numbers::pi / 4;  // rad
  // Grip pose at the start of the stroke.
  Eigen::Isometry3d X_WT_start = Eigen::Isometry3d::Identity();
  // Unit mean surface normal at the grab centre at the start (push/pull direction), in W.
  Eigen::Vector3d normal_W = Eigen::Vector3d::UnitZ();
};

// Resisting wrench on the grip. Sign convention: the force and moment act ON the grip and oppose
// the motion that deforms the material (a spring pulling the grip back to its start pose).
struct SculptWrench {
  Eigen::Vector3d f_T_W = Eigen::Vector3d::Zero();  // force on the grip, in W (N)
  Eigen::Vector3d m_T_W = Eigen::Vector3d::Zero();  // moment about the grip centre p0, in W (N·m)
  double grasp_torque = 0.0;                        // N·m (0: the tools do not resist the grasp)
};

// Wrench of the stroke for grip pose X_WT and grasp angle theta (rad), with k = stiffness,
// s = grab strength, Δp, α, φ u as in the file comment:
//   grab f = -k s Δp; push/pull f = -k s (Δp·n) n; smooth f = -0.1 k s Δp;
//   twist m = -k R² s α z; bend m = -k R² s φ u.
// Real-time safe: no allocation, no exceptions; zero wrench when !model.active.
SculptWrench ComputeStrokeWrench(const StrokeForceModel& model, const Eigen::Isometry3d& X_WT,
                                 double theta) noexcept;
// The same wrench for a grab strength s in [0, 1] given by the caller (the app's squeeze, say)
// instead of the grasp angle. Real-time safe; zero wrench when !model.active.
SculptWrench ComputeStrokeWrenchAtStrength(const StrokeForceModel& model,
                                           const Eigen::Isometry3d& X_WT, double s) noexcept;

// A change of a SculptMesh made by one stroke (positions and refinement), enough to undo and
// redo it. Triangles are 3-vectors of vertex indices (CCW from outside).
struct SculptEdit {
  // Existing vertices the stroke moved, with their positions before and after (m, W).
  std::vector<int> moved;
  std::vector<Eigen::Vector3d> old_positions;
  std::vector<Eigen::Vector3d> new_positions;
  // Vertices appended by refinement (indices old_vertex_count ...).
  int old_vertex_count = 0;
  std::vector<Eigen::Vector3d> added_positions;
  // Existing triangles refinement rewrote, before and after.
  std::vector<int> rewritten;
  std::vector<Eigen::Vector3i> old_triangles;
  std::vector<Eigen::Vector3i> new_triangles;
  // Triangles appended by refinement (indices old_triangle_count ...).
  int old_triangle_count = 0;
  std::vector<Eigen::Vector3i> added_triangles;
  // Enclosed volume before and after (m³).
  double old_volume = 0.0;
  double new_volume = 0.0;
  // Edges split by refinement.
  long splits = 0;
};

// Figures of the last UpdateStroke.
struct StrokeStats {
  int affected_vertices = 0;   // vertices within the radius (the ones the field moves)
  int affected_triangles = 0;  // triangles with an affected corner
  int normal_updates = 0;      // vertices whose normal was recomputed
  int volume_iterations = 0;   // Newton iterations of the volume correction
  double start_volume = 0.0;   // enclosed volume at BeginStroke (m³)
  double volume = 0.0;         // enclosed volume now (m³), incremental
  double strength = 0.0;       // grab strength s used
  // Share of the strength applied, in [0, 1]: below 1 when the full stroke would have made the
  // surface intersect itself (prevent_self_intersection).
  double limit = 1.0;
  int intersection_checks = 0;  // self-intersection checks run by the update (0 when off)
};

// A closed, edge-manifold, consistently oriented triangle mesh being sculpted: positions,
// triangles, vertex-to-triangle adjacency, per-vertex normals (area weighted, kept up to date
// only where a stroke moves vertices) and a uniform grid over the vertices for the region query.
class SculptMesh {
 public:
  // From a closed mesh (every directed edge once, its reverse once). grid_cell (m) is the edge
  // of the spatial grid's cells (> 0; about the typical tool radius / 3 is good). Throws
  // std::invalid_argument naming the bad index, edge or setting.
  explicit SculptMesh(const TriangleMesh& mesh, double grid_cell = 0.005);

  // The current mesh (vertices 3 by V, triangles 3 by F).
  TriangleMesh ToTriangleMesh() const;

  int vertex_count() const { return static_cast<int>(positions_.size()); }
  int triangle_count() const { return static_cast<int>(triangles_.size()); }
  // Vertex positions (m, W) and unit vertex normals (outward).
  const std::vector<Eigen::Vector3d>& positions() const { return positions_; }
  const std::vector<Eigen::Vector3d>& normals() const { return normals_; }
  const std::vector<Eigen::Vector3i>& triangles() const { return triangles_; }
  // Triangles incident to vertex v.
  const std::vector<int>& VertexTriangles(int v) const { return vertex_triangles_[v]; }

  // Enclosed volume (m³), tracked incrementally through strokes.
  double volume() const { return volume_; }
  // Enclosed volume summed over every triangle now (m³): O(F), for checks.
  double ComputeVolume() const;

  // Vertices whose current position lies within radius of centre (m, W), via the grid. Appends
  // to *out (cleared first).
  void QueryBall(const Eigen::Vector3d& centre_W, double radius, std::vector<int>* out) const;

  // Starts a stroke of tool settings with grip pose X_WT and grasp angle theta (rad). Throws
  // std::invalid_argument for bad settings and std::logic_error if a stroke is active.
  void BeginStroke(const SculptToolSettings& settings, const Eigen::Isometry3d& X_WT, double theta);
  // Deforms the affected region for the current grip pose and grasp (relative to the start).
  // Allocates nothing once the self-intersection check's scratch buffers have grown to the
  // region's size; a non-finite pose is ignored. Throws std::logic_error without an active stroke.
  void UpdateStroke(const Eigen::Isometry3d& X_WT, double theta);
  // The same for a grab strength s in [0, 1] given by the caller instead of the grasp angle.
  void UpdateStrokeAtStrength(const Eigen::Isometry3d& X_WT, double s);
  // Ends the stroke: refines stretched edges of the touched region (if max_edge_length > 0),
  // re-bins the moved vertices in the grid and returns the edit for undo.
  SculptEdit EndStroke();
  // Ends the stroke by putting every affected vertex back (no edit).
  void CancelStroke();
  bool stroke_active() const { return stroke_active_; }

  // True when a triangle the active stroke moves (one with an affected corner) crosses another
  // triangle of the mesh at the current positions: the check UpdateStroke runs when
  // prevent_self_intersection is set (see the file comment). False without an active stroke.
  // Allocates nothing once its scratch buffers have grown to the region's size.
  bool MovedRegionIntersects();

  // Vertices the last UpdateStroke moved (for partial redraws).
  const std::vector<int>& stroke_vertices() const { return affected_; }
  // Figures of the last UpdateStroke.
  const StrokeStats& stroke_stats() const { return stats_; }
  // The active stroke's force model (active = false without a stroke).
  const StrokeForceModel& force_model() const { return force_model_; }

  // Reverts an edit returned by EndStroke (it must be the last one applied).
  void Undo(const SculptEdit& edit);
  // Re-applies an edit reverted by Undo.
  void Redo(const SculptEdit& edit);

  // Splits every edge of the given triangles (and of the triangles the splits create) longer
  // than max_edge_length (m) at its midpoint, keeping the mesh closed and consistently oriented.
  // Records the changes into *edit when given. Returns the number of splits (at most max_splits).
  long Refine(const std::vector<int>& triangles, double max_edge_length, int max_splits,
              SculptEdit* edit = nullptr);

 private:
  using CellKey = std::uint64_t;
  CellKey KeyOf(const Eigen::Vector3d& p) const;
  // Appends every vertex binned in a grid cell that overlaps box (m, W): a superset of those
  // inside it (vertices are binned where they were at the last EndStroke).
  void VerticesInCellBox(const Eigen::AlignedBox3d& box, std::vector<int>* out) const;
  void GridInsert(int v);
  void GridRemove(int v);
  void SetTriangle(int t, const Eigen::Vector3i& tri);
  int AddVertex(const Eigen::Vector3d& p);
  int AddTriangle(const Eigen::Vector3i& tri);
  void RecomputeNormal(int v);
  void RefreshNormalsAround(const std::vector<int>& vertices);
  bool SplitEdge(int a, int b, SculptEdit* edit, std::vector<int>* new_triangles);
  double AffectedVolume() const;
  void ApplyField(const Eigen::Isometry3d& X_WT, double strength);
  void ConserveVolume();
  // Field (and volume correction) at strength s.
  void Deform(const Eigen::Isometry3d& X_WT, double s);
  // The check of MovedRegionIntersects, also run by BeginStroke before the stroke is active
  // (sculpt_intersection.cc).
  bool CheckMovedRegion();
  // Raises longest_edge_ to the longest edge of triangle t.
  void BoundEdges(int t);

  double grid_cell_;
  std::vector<Eigen::Vector3d> positions_;
  std::vector<Eigen::Vector3d> normals_;
  std::vector<Eigen::Vector3i> triangles_;
  std::vector<std::vector<int>> vertex_triangles_;
  std::unordered_map<CellKey, std::vector<int>> grid_;
  std::vector<CellKey> vertex_cell_;
  double volume_ = 0.0;
  // Scratch marks (one per vertex / triangle) with a stamp, so that sets are built without
  // clearing.
  mutable std::vector<std::uint32_t> vertex_mark_;
  mutable std::vector<std::uint32_t> triangle_mark_;
  mutable std::uint32_t stamp_ = 0;
  std::uint32_t NextStamp() const;

  // Active stroke.
  bool stroke_active_ = false;
  SculptToolSettings settings_;
  StrokeForceModel force_model_;
  StrokeStats stats_;
  Eigen::Vector3d centre_W_ = Eigen::Vector3d::Zero();
  std::vector<int> affected_;                     // vertex indices
  std::vector<Eigen::Vector3d> start_positions_;  // per affected vertex
  std::vector<Eigen::Vector3d> start_normals_;    // per affected vertex
  std::vector<double> weights_;                   // per affected vertex
  std::vector<Eigen::Vector3d> smooth_targets_;   // per affected vertex (smooth tool)
  std::vector<Eigen::Vector3d> field_positions_;  // per affected vertex, scratch
  std::vector<int> affected_triangles_;
  std::vector<int> normal_vertices_;  // corners of affected triangles
  double affected_start_volume_ = 0.0;
  bool check_intersections_ = false;  // this stroke: prevent self-intersection
  // Self-intersection check scratch (kept between updates so that they allocate once).
  double longest_edge_ = 0.0;         // bound on every edge's length, m
  std::vector<int> check_vertices_;   // vertices near the moved region
  std::vector<int> check_triangles_;  // moved triangles first, then nearby ones
  std::vector<internal::SculptCheckTriangle> check_data_;  // per check triangle
  std::vector<int> check_cell_start_;  // per broad-phase cell, its first entry (and one past)
  // Per broad-phase entry, grouped by cell: 8 × (index into check_triangles_) + 3 bits that
  // say along which axes the cell is the lowest of the triangle's box.
  std::vector<int> check_entries_;
};

// A sphere of radius (m) centred at the origin: the icosahedron with each triangle split into
// 4^subdivisions, vertices pushed onto the sphere (10·4^s + 2 vertices), CCW from outside.
TriangleMesh IcosphereMesh(double radius, int subdivisions);

}  // namespace spidarcad::modeling
