// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
// Sculpt mode without a window: the clay (a modeling::SculptMesh), strokes driven by the tool
// state the haptic loop reports, undo/redo of strokes, and the force field that renders the
// active stroke's resistance on the haptic thread.
//
// Stroke trigger (SculptSession::Step): a stroke begins when the grasp angle θ drops below
// stroke_begin_angle (the grip closes) or when the caller says a key is held (mouse driving: the
// window maps the G key to it), and the grip centre is within snap_distance of the clay (nearest
// vertex). It updates every frame from the tool pose and grasp, and ends (EndStroke + refinement)
// when θ rises above stroke_end_angle (hysteresis) and the key is up. A key-held stroke uses full
// strength (the grasp does not scale it).
//
// Snap: the grab centre is the clay vertex nearest the grip at the start; the stroke is driven by
// the grip pose translated by the constant offset (nearest vertex − grip centre), so the grabbed
// point follows the grip's motion exactly. The published force model is shifted back by the
// same offset, so the haptic side evaluates it on the unshifted tool pose.
//
// Thread hand-off: SculptForceChannel is a triple buffer of StrokeForceModel (plain fixed-size
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
#include <memory>
#include <numbers>
#include <string>
#include <vector>

#include "spidarcad/haptics/force_field.h"
#include "spidarcad/haptics/triple_buffer.h"
#include "spidarcad/modeling/sculpt.h"
#include "spidarcad/modeling/surface_mesher.h"
#include "spidarcad/modeling/tet_mesh.h"
#include "spidarcad/modeling/tetgen_mesher.h"

namespace spidarcad::app {

class JobQueue;
class JobContext;

// The active stroke's force model as handed to the haptic thread (copyable, no heap memory).
using SculptForceChannel = haptics::TripleBuffer<modeling::StrokeForceModel>;

// The resisting wrench of the active stroke: ComputeStrokeWrench on the current tool pose and
// grasp; zero when no stroke is active. Real-time safe.
class SculptToolField final : public haptics::ForceField {
 public:
  // Reads models from `channel` (shared with the SculptSession that writes it; non-null).
  explicit SculptToolField(std::shared_ptr<SculptForceChannel> channel);
  // f_T_W, m_T_W (about p_WT) and g of the stroke wrench; finite, zero without a stroke.
  haptics::ToolWrench Evaluate(const haptics::ToolKinematics& tool) noexcept override;
  const char* name() const noexcept override { return "sculpt_tool"; }

 private:
  std::shared_ptr<SculptForceChannel> channel_;
};

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
  const modeling::StrokeForceModel& published_model() const { return published_; }

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
  void Publish(const modeling::StrokeForceModel& model);
  void BeginStroke(const haptics::ToolKinematics& tool, bool key_held, SculptFrameEvent* event);
  Eigen::Isometry3d StrokePose(const haptics::ToolKinematics& tool) const;

  std::unique_ptr<modeling::SculptMesh> mesh_;
  SculptModeSettings settings_;
  std::uint64_t revision_ = 0;
  std::vector<modeling::SculptEdit> undo_;
  std::vector<modeling::SculptEdit> redo_;
  std::shared_ptr<SculptForceChannel> channel_;
  modeling::StrokeForceModel published_;
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
