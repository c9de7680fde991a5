// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
// Sculpt mode without a window: the clay (a modeling::SculptMesh), strokes driven by the tool
// state the haptic loop reports, undo/redo of strokes, and the force field that renders the
// active stroke's resistance on the haptic thread.
//
// Stroke trigger (SculptSession::Step), three kinds:
//  - squeeze: both poles squeeze the clay (clay_width.h) at least clay_width.grasp.grab_depth
//    deep. The grab centre is the midpoint of the two poles' deepest points (the pinch); the
//    stroke ends as soon as the poles no longer both push into the clay (the fingers opened).
//    The felt stroke wrench scales with the squeeze strength S now (so it fades to zero as the
//    fingers open: no jump when the stroke begins or ends), the clay's deformation with the
//    largest S of the stroke so far (opening the fingers lets go of the clay where it is, rather
//    than letting it spring back).
//  - angle: the grasp angle θ drops below stroke_begin_angle (the grip closes) and the grip
//    centre is within snap_distance of the clay (nearest vertex); it ends when θ rises above
//    stroke_end_angle (hysteresis). Strength max(SculptGrabStrength(θ), S) for both the
//    deformation and the felt wrench: the angle's as before, raised by a squeeze.
//  - key: the caller says a key is held (mouse driving: the window maps the G key to it); full
//    strength, ends when the key is up.
// It updates every frame from the tool pose and grasp; ends run EndStroke + refinement.
//
// Clay width: the session keeps a ClayDistanceGrid of the clay (clay_grid.h), rebuilt after
// every change (a new clay: built whole; a stroke's end, undo or redo: updated locally around
// what moved) and offered to the field through a ClayGridChannel; with set_async_grids(true)
// (the window) the rebuild runs on a thread of its own and lands at a later Step, else (run,
// tests: deterministic) at once. The field renders the clay's width on the grasp (g <= 0).
//
// Snap: the grab centre is the clay vertex nearest the grip at the start (a squeeze stroke's: the
// pinch, above); the stroke is driven by the grip pose translated by the constant offset (grab
// centre − grip centre), so the grabbed point follows the grip's motion exactly. The published
// force model is shifted back by the same offset, so the haptic side evaluates it on the
// unshifted tool pose.
//
// Thread hand-off: SculptForceChannel is a triple buffer of SculptHapticModel (plain fixed-size
// values). The main thread writes it on stroke begin/end; SculptToolField (in the HapticScene)
// reads the latest value every tick: no lock, no allocation. Only one field instance may read a
// channel at a time (the haptic thread evaluates one scene at a time, so a republished field
// sharing the channel is fine).
//
// Frames and units: W (the scene), m, N, N·m, rad. Stiffness is N per m of world displacement.
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <atomic>
#include <functional>
#include <future>
#include <memory>
#include <numbers>
#include <string>
#include <vector>

#include "scene/clay_width.h"
#include "spidarcad/haptics/force_field.h"
#include "spidarcad/haptics/triple_buffer.h"
#include "spidarcad/modeling/sculpt.h"
#include "spidarcad/modeling/surface_mesher.h"
#include "spidarcad/modeling/tet_mesh.h"
#include "spidarcad/modeling/tetgen_mesher.h"

namespace spidarcad::app {

class JobQueue;
class JobContext;

// The active stroke as handed to the haptic thread (copyable, no heap memory).
struct SculptHapticModel {
  modeling::StrokeForceModel stroke;  // active = false: no stroke
  bool squeeze = false;               // a squeeze stroke (see the file comment)
};
using SculptForceChannel = haptics::TripleBuffer<SculptHapticModel>;

// Strength of the active stroke's felt wrench (and, for angle strokes, of its deformation): 1
// when the grasp does not control it (key strokes), the squeeze strength S for a squeeze stroke,
// else max(SculptGrabStrength(θ), S).
double StrokeStrength(const SculptHapticModel& model, double grasp, double squeeze_strength);

// The clay under the grip: the resisting wrench of the active stroke (ComputeStrokeWrench at
// StrokeStrength on the current tool pose) plus the clay's width on the grasp (clay_width.h;
// g <= 0). Zero force without a stroke, zero g without clay between the fingers. Real-time safe.
class SculptToolField final : public haptics::ForceField {
 public:
  // Reads models from `channel` and grids from `clay` (both shared with the SculptSession that
  // writes them; non-null), with the clay width `settings` (validated).
  SculptToolField(std::shared_ptr<SculptForceChannel> channel,
                  std::shared_ptr<ClayGridChannel> clay, const ClayWidthSettings& settings);
  haptics::ToolWrench Evaluate(const haptics::ToolKinematics& tool) noexcept override;
  const char* name() const noexcept override { return "sculpt_tool"; }
  // Haptic thread (or tests): the squeeze of the last Evaluate.
  const ClaySqueeze& last_squeeze() const noexcept { return squeeze_; }

 private:
  std::shared_ptr<SculptForceChannel> channel_;
  std::shared_ptr<ClayGridChannel> clay_;
  ClayWidthSettings settings_;
  ClaySqueeze squeeze_;
};

// Where the clay's grid lies while `model`'s stroke is under way and the grip is at X_WT: carried
// by the grip, X_WC = X_WT · X_WT_start⁻¹; the identity without a stroke.
Eigen::Isometry3d ClayPlacement(const modeling::StrokeForceModel& model,
                                const Eigen::Isometry3d& X_WT);

// Settings of the sculpt mode (tool settings and the stroke trigger).
struct SculptModeSettings {
  // Tool, radius R (m), stiffness (N/m), conserve_volume, refinement max_edge_length (m), ...
  modeling::SculptToolSettings tool;
  // A stroke begins when the grasp angle drops below this (rad; rest is π/2).
  double stroke_begin_angle = 70.0 * std::numbers::pi / 180.0;
  // ... and ends when it rises above this (rad, >= stroke_begin_angle).
  double stroke_end_angle = 80.0 * std::numbers::pi / 180.0;
  // The grip centre must be within this distance (m) of a clay vertex to begin a stroke;
  // <= 0: the tool radius.
  double snap_distance = 0.0;
  // The clay's width on the grasp and the squeeze strokes (clay_width.h). Set
  // clay_width.grasp.pole_length to the device's d times the world scale.
  ClayWidthSettings clay_width;
  // Throws std::invalid_argument naming the field and value when out of range.
  void Validate() const;
};

// What SculptSession::Step did this frame.
enum class SculptFrameEvent {
  kIdle,           // no stroke, none begun
  kBegan,          // a stroke began (and was updated once)
  kUpdated,        // the active stroke was updated
  kEnded,          // the stroke ended (refinement done, edit recorded): redraw everything
  kNoClayInReach,  // the trigger fired but no clay vertex is within snap distance
};

// Sculpt mode logic: the clay, strokes, undo/redo, the force channel. Main thread only.
class SculptSession {
 public:
  SculptSession();

  // Replaces the clay by `mesh` (closed, consistently oriented; see SculptMesh) with a spatial
  // grid of cell grid_cell (m; <= 0: a third of the tool radius). Cancels any stroke, clears
  // undo/redo and the tetrahedral mesh. Throws std::invalid_argument when the mesh is bad.
  void SetMesh(const modeling::TriangleMesh& mesh, double grid_cell = 0.0);
  // Takes an already built clay (from a Job).
  void SetMesh(std::unique_ptr<modeling::SculptMesh> mesh);
  // Drops the clay (cancelling any stroke), the undo/redo lists and the tetrahedral mesh: no clay.
  void ClearMesh();
  // True once a clay is loaded.
  bool has_mesh() const { return mesh_ != nullptr; }
  // The clay (null before SetMesh).
  const modeling::SculptMesh* mesh() const { return mesh_.get(); }
  // Grows whenever the mesh changed other than through the active stroke's moving vertices (new
  // mesh, stroke end with refinement, undo, redo): the display rebuilds everything then.
  std::uint64_t revision() const { return revision_; }

  // Settings (changes apply to the next stroke).
  SculptModeSettings& settings() { return settings_; }
  const SculptModeSettings& settings() const { return settings_; }

  // One frame: begins, updates or ends the stroke from the tool state (tool.p_WT, R_WT, grasp)
  // and the key (mouse driving). Throws std::invalid_argument for bad settings at stroke begin.
  SculptFrameEvent Step(const haptics::ToolKinematics& tool, bool key_held);
  // True while a stroke is active.
  bool stroke_active() const { return mesh_ && mesh_->stroke_active(); }
  // Cancels the active stroke (vertices back, nothing recorded).
  void CancelStroke();
  // Vertices whose position or normal the active stroke changes (the moved ones and their
  // one-ring), fixed at stroke begin: copy these to the display each frame.
  const std::vector<int>& display_vertices() const { return display_vertices_; }
  // Grab centre of the active stroke (m, W).
  const Eigen::Vector3d& grab_centre() const { return grab_centre_; }
  // Offset added to the grip centre while the stroke is active (m, W).
  const Eigen::Vector3d& snap_offset() const { return snap_offset_; }

  // Undo/redo of strokes (own list of SculptEdits, for a session without a Document; the window
  // records each stroke in the Document instead and calls ForgetHistory).
  bool CanUndo() const { return !undo_.empty() && !stroke_active(); }
  bool CanRedo() const { return !redo_.empty() && !stroke_active(); }
  // Reverts the last stroke; false when there is none or a stroke is active.
  bool Undo();
  // Re-applies the last undone stroke; false when there is none or a stroke is active.
  bool Redo();
  // Number of strokes that can be undone / redone.
  int undo_count() const { return static_cast<int>(undo_.size()); }
  int redo_count() const { return static_cast<int>(redo_.size()); }
  // The last recorded stroke's edit (null when none).
  const modeling::SculptEdit* last_edit() const { return undo_.empty() ? nullptr : &undo_.back(); }
  // Empties the undo and redo lists (the strokes are kept elsewhere, e.g. in a Document).
  void ForgetHistory();

  // The channel the session writes its force model to (for SculptToolField).
  const std::shared_ptr<SculptForceChannel>& channel() const { return channel_; }
  // A new field reading this session's channel.
  std::unique_ptr<haptics::ForceField> MakeField() const;
  // The model last published (active = false outside a stroke).
  const modeling::StrokeForceModel& published_model() const { return published_.stroke; }
  // True while the active stroke is a squeeze stroke.
  bool squeeze_stroke() const { return published_.squeeze; }
  // The squeeze the last Step saw (clay_width.h), and the strength the active stroke deformed
  // the clay with there.
  const ClaySqueeze& squeeze() const { return squeeze_; }
  double stroke_strength() const { return stroke_strength_; }

  // ---- the clay's distance grid (clay width) ----
  // The grid of the clay as last built (null without clay or before the first build lands).
  const std::shared_ptr<const ClayDistanceGrid>& clay_grid() const { return grid_; }
  // The channel the grids are offered through (for SculptToolField).
  const std::shared_ptr<ClayGridChannel>& clay_channel() const { return clay_channel_; }
  // Rebuild grids on a thread of their own (true: the window) or at once (false, the default).
  void set_async_grids(bool on) { async_grids_ = on; }
  // Waits for a rebuild under way (async) and offers it; no-op otherwise.
  void FinishGridBuild();
  // Thread CPU time of the last grid build or update (s) and how many nodes it recomputed.
  double last_grid_seconds() const { return grid_seconds_; }
  long last_grid_nodes() const { return grid_nodes_; }
  // Grid builds and updates landed so far.
  int grid_builds() const { return grid_builds_; }

  // Enclosed volume of the clay now (m³), the active stroke's deformation included (the mesh's
  // own volume() changes only when a stroke ends); 0 without clay.
  double volume() const;

  // The current clay as a triangle mesh (for export or tetrahedralization).
  modeling::TriangleMesh ExportMesh() const;

  // Tetrahedral mesh of the clay from the last successful TetrahedralizeJob (null before).
  const std::shared_ptr<const modeling::TetMesh>& tet_mesh() const { return tet_mesh_; }
  // Message of the last job's outcome ("" before): the error of a failure, or the figures.
  const std::string& job_message() const { return job_message_; }
  // Starts a Job checking (CheckSurface) and tetrahedralizing (TetrahedralizeSurface) the
  // current clay; on success tet_mesh() is replaced, on failure nothing changes and
  // job_message() holds the error. Returns false when there is no clay or a stroke is active.
  bool StartTetrahedralize(JobQueue* jobs, const modeling::TetMeshSettings& settings = {});
  // Starts a Job meshing the first solid of a scene file (MeshSurface, grid cell `cell` m) into
  // a new clay (SetMesh on success; on failure nothing changes and job_message() says why).
  void StartMeshScene(JobQueue* jobs, const std::string& scene_path, double cell);
  // Records a job failure message (called by the window's failure handler or the finisher).
  void SetJobMessage(std::string message) { job_message_ = std::move(message); }

 private:
  void Publish(const modeling::StrokeForceModel& model, bool squeeze = false);
  // Begins a stroke; `pinch` (non-null: a squeeze stroke) is its grab centre (W, m), else the
  // clay vertex nearest the grip.
  void BeginStroke(const haptics::ToolKinematics& tool, bool key_held, const Eigen::Vector3d* pinch,
                   SculptFrameEvent* event);
  // Asks for a new grid: whole (a new clay) or updated inside `changed` (W, m).
  void RequestGrid(bool whole, const Eigen::AlignedBox3d& changed);
  // Async: takes a finished build (offering it) and starts the next one asked for.
  void PollGridBuild();
  void StartGridBuild();
  // The box an edit's moved vertices span, before and after (W, m).
  static Eigen::AlignedBox3d EditBox(const modeling::SculptEdit& edit);
  Eigen::Isometry3d StrokePose(const haptics::ToolKinematics& tool) const;
  // Deforms the clay for the tool state at the active stroke's strength (file comment).
  void UpdateStroke(const haptics::ToolKinematics& tool);
  // squeeze_ for the tool state (the clay placed as the field places it).
  void SenseClay(const haptics::ToolKinematics& tool);

  std::unique_ptr<modeling::SculptMesh> mesh_;
  SculptModeSettings settings_;
  std::uint64_t revision_ = 0;
  std::vector<modeling::SculptEdit> undo_;
  std::vector<modeling::SculptEdit> redo_;
  std::shared_ptr<SculptForceChannel> channel_;
  SculptHapticModel published_;
  std::shared_ptr<ClayGridChannel> clay_channel_;
  std::shared_ptr<const ClayDistanceGrid> grid_;
  bool async_grids_ = false;
  std::future<std::shared_ptr<const ClayDistanceGrid>> build_;  // async build under way
  std::uint64_t build_generation_ = 0;  // clay generation the build under way is for
  std::uint64_t generation_ = 0;        // grows with every new clay (SetMesh, ClearMesh)
  bool grid_wanted_ = false;            // a build is asked for (async)
  bool grid_whole_ = false;             // ... of the whole clay
  Eigen::AlignedBox3d grid_changed_;    // ... else updated inside this box
  double grid_seconds_ = 0.0;
  double build_seconds_ = 0.0;  // of the async build under way
  long grid_nodes_ = 0;
  int grid_builds_ = 0;
  ClaySqueeze squeeze_;
  double stroke_strength_ = 0.0;
  double held_strength_ = 0.0;  // a squeeze stroke: its largest squeeze strength so far
  std::vector<int> display_vertices_;
  std::vector<int> query_;
  std::vector<std::uint8_t> mark_;
  Eigen::Vector3d grab_centre_ = Eigen::Vector3d::Zero();
  Eigen::Vector3d snap_offset_ = Eigen::Vector3d::Zero();
  bool key_stroke_ = false;  // the active stroke was begun by the key
  std::shared_ptr<const modeling::TetMesh> tet_mesh_;
  std::string job_message_;
  // Alive flag shared with job finishers, so a finisher of a destroyed session does nothing.
  std::shared_ptr<bool> alive_;

 public:
  ~SculptSession();
  SculptSession(const SculptSession&) = delete;
  SculptSession& operator=(const SculptSession&) = delete;
};

// Copies positions and normals of `vertices` of mesh into interleaved float arrays xyz and nxyz
// (each 3 by vertex_count, vertex v at [3v, 3v+2]); nxyz may be null. For in-place display updates.
void CopyVerticesToFloat(const modeling::SculptMesh& mesh, const std::vector<int>& vertices,
                         float* xyz, float* nxyz);

}  // namespace spidarcad::app
