// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
// Sculpt mode (modes.md contract): the grip sculpts a sculpt object of the Document. The logic
// (strokes, the force field) is SculptSession (scene/sculpt_field.h); this class binds it to the
// Document and draws: the clay actor, updated in place during a stroke (the touched vertices'
// positions and normals copied into the VTK arrays, then Modified()), rebuilt whole when the
// session's revision changes (new clay, stroke end with refinement, reload), and a translucent
// sphere at the grip showing the tool radius (green: idle, orange: stroking, red: the trigger
// fired out of the clay's reach).
//
// The Document (issue 12): the mode sculpts one sculpt object (its target), chosen in the panel
// or by selecting a sculpt object in the tree; the panel also makes a sculpt copy of an implicit
// solid (surface-meshed by a Job; the result lands as one AddSculpt, dropped when the solid
// changed meanwhile) or of a mesh object with a closed surface (one AddSculpt at once). Each
// frame Update compares the target's revision with the one the session was loaded from; when it
// moved (undo, redo, an edit in the tree, a reload) the session reloads the mesh from the
// Document and republishes its field. A stroke is recorded when it ends, on the main thread, as
// one command (scene/sculpt_document.h MakeStrokeCommand) titled "Sculpt stroke (TOOL) on NAME",
// so Ctrl+Z undoes it whatever the mode. Without a ModeContext (OnFrame, LoadMesh) the mode
// works on a clay of its own, as the headless tests use it.
//
// Stroke trigger: close the grasp below the panel's "begin" angle (device, or mouse wheel / [ ]
// keys with the simulated hand), or hold G when the mouse drives (full strength while held).
//
// Frames: the session works in W; the actors are placed in the view frame D by the inverse of
// X_WD (p_D = (p_W − p_WDo) / s), set with SetWorldToView.
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <memory>
#include <string>
#include <unordered_map>
#include <utility>
#include <vector>

#include "doc/document.h"
#include "scene/sculpt_field.h"
#include "spidarcad/haptics/device_to_world.h"
#include "spidarcad/haptics/haptic_loop.h"

class vtkRenderer;

namespace spidarcad::app {

class Job;
class JobQueue;
struct ModeContext;

// The sculpt mode's actors and panel around a SculptSession.
class SculptMode {
 public:
  // Adds its actors to renderer (hidden until active); jobs runs the meshing and TetGen Jobs.
  // Both must outlive this mode.
  SculptMode(vtkRenderer* renderer, JobQueue* jobs);
  ~SculptMode();
  SculptMode(const SculptMode&) = delete;
  SculptMode& operator=(const SculptMode&) = delete;

  // Shows/hides the actors. Activation makes the next Update choose the target again (the
  // sculpt object selected in the tree, else the one it had, else the Document's first);
  // deactivation cancels a stroke (the field then renders zero force).
  void SetActive(bool active);
  bool active() const { return active_; }
  // The start-up set-up of `--mode sculpt`, done at the next Update: the Document's first sculpt
  // object, else a sculpt copy of its first solid (a Job), else nothing.
  void Launch() { launch_pending_ = true; }
  // ImGui widgets of the side panel (no Begin/End); `context` null: the clay of its own only.
  void DrawPanel(ModeContext* context = nullptr);
  // Each frame with the window's context (active mode only): syncs with the Document, runs the
  // stroke logic (OnFrame) and records a stroke that ended as one command.
  void Update(const haptics::ToolState& tool, ModeContext& context);
  // Latest tool state: runs the stroke logic and updates the actors (tool.tool_W in W).
  void OnFrame(const haptics::ToolState& tool);
  // The sculpt tool field, once after each activation; else nullptr.
  std::unique_ptr<haptics::ForceField> TakeField();

  // Places the actors in the view frame: p_D = (p_W − p_WDo) / s (s > 0), and sets the clay
  // width's pole length to s times the grip's pole length (SetGripPoleLength).
  void SetWorldToView(const haptics::DeviceToWorld& X_WD);
  // The grip's pole half-length d (m in D, > 0; default 0.04), for the clay width.
  void SetGripPoleLength(double d) {
    if (d > 0.0) grip_d_ = d;
    SetWorldToView(X_WD_);
  }
  // Uses a given mesh as a clay of its own, bound to no Document object (throws
  // std::invalid_argument when it is not closed).
  void LoadMesh(const modeling::TriangleMesh& mesh);

  // ---- the Document ----
  // Sculpts sculpt object `id` (loaded from the Document at the next Update).
  void SetTarget(ObjectId id);
  // The sculpt object sculpted (0: none).
  ObjectId target() const { return target_; }
  // Its name when last seen in the Document.
  const std::string& target_name() const { return target_name_; }
  // Makes a sculpt copy of object `source` (a solid: meshed by a Job at the panel's cell size,
  // the copy added and sculpted when it lands; a mesh object with a closed surface: added at
  // once) named "<source> sculpt". False with message() when that is not possible.
  bool StartCopy(ModeContext& context, ObjectId source);
  // Asks the next Update to StartCopy(source) (the panel's "Sculpt a copy" button).
  void RequestCopy(ObjectId source) { copy_request_ = source; }
  // Asks the next Update to send the target to FE mode: selects it in the tree and asks the
  // window to switch to FE mode (ModeContext::switch_to = "fe"; the panel's "Send to FE").
  void RequestSendToFe() { send_to_fe_ = true; }
  // True while a copy's meshing Job runs (a screenshot waits for it).
  bool copy_pending() const { return copy_job_ != nullptr; }
  // Grid cell (m) of the surface mesh of a solid's copy (default 2 mm).
  double mesh_cell() const { return mesh_cell_; }
  // Sets that grid cell (m, > 0).
  void set_mesh_cell(double cell) { mesh_cell_ = cell; }
  // The last message of the panel (errors, outcomes).
  const std::string& message() const { return message_; }
  // The logic, for the window and tests.
  SculptSession& session() { return session_; }
  // True while a stroke is under way (the grasp is closed on the clay).
  bool stroke_active() const { return session_.stroke_active(); }
  // Off: OnFrame runs no stroke of its own (the clay and the marker are still drawn): the
  // window on the virtual clock, whose sculpt objects the scripted run sculpts. On by default.
  void set_strokes_enabled(bool on) { strokes_enabled_ = on; }
  // Wall time of the last OnFrame's display update (stroke step + VTK arrays), ms.
  double last_frame_ms() const { return last_frame_ms_; }

 private:
  struct Vtk;
  void Rebuild();
  void UpdateMarker(const Eigen::Vector3d& p_W, SculptFrameEvent event);
  // Brings the session in line with the Document (target choice, reload after a change).
  void SyncDocument(ModeContext& context);
  // Records the stroke that just ended as a command on the target.
  void RecordStroke(ModeContext& context);
  // Whether a sculpt copy can be made of `object` (cached per object revision).
  bool CopyableCached(const DocObject& object);
  // The panel's top: the sculpt object chosen, the "Sculpt a copy of" controls.
  void DrawDocumentPanel(ModeContext& context);

  vtkRenderer* renderer_;
  JobQueue* jobs_;
  SculptSession session_;
  std::unique_ptr<Vtk> vtk_;
  bool active_ = false;
  bool strokes_enabled_ = true;
  bool field_pending_ = false;
  std::uint64_t shown_revision_ = ~std::uint64_t{0};
  haptics::DeviceToWorld X_WD_;
  double grip_d_ = 0.04;
  std::string export_path_ = "sculpt.stl";
  std::string message_;
  double mesh_cell_ = 0.002;
  SculptFrameEvent last_event_ = SculptFrameEvent::kIdle;
  double last_frame_ms_ = 0.0;
  modeling::SculptTool stroke_tool_ = modeling::SculptTool::kGrab;  // tool of the active stroke
  // The Document binding.
  ObjectId target_ = 0;                // sculpt object sculpted (0: none)
  std::string target_name_;            // its name when last seen
  std::uint64_t synced_revision_ = 0;  // its revision the session holds (0: not loaded)
  // The target's revisions (before, after) of each stroke on the session's undo list, and of
  // each on its redo list: an undo or redo in the Document that moves between them is applied
  // to the session by SculptSession::Undo/Redo instead of a reload.
  std::vector<std::pair<std::uint64_t, std::uint64_t>> recorded_;
  std::vector<std::pair<std::uint64_t, std::uint64_t>> undone_;
  int generation_ = -1;            // SceneModel::generation() the ids belong to
  bool choose_target_ = false;     // choose the target at the next Update
  bool launch_pending_ = false;    // Launch asked for its set-up
  bool have_selection_ = false;    // the tree had a selection when last looked at
  ObjectId seen_selection_ = 0;    // the object selected in the tree then
  ObjectId copy_source_ = 0;       // object the "Sculpt a copy of" list shows
  ObjectId copy_request_ = 0;      // RequestCopy for the next Update
  bool send_to_fe_ = false;        // RequestSendToFe for the next Update
  const Job* copy_job_ = nullptr;  // copy meshing in flight (compared, never dereferenced)
  std::string copy_job_title_;     // its title
  std::unordered_map<ObjectId, std::pair<std::uint64_t, bool>> copyable_;  // revision, result
  // Alive flag shared with job finishers, so a finisher of a destroyed mode does nothing.
  std::shared_ptr<bool> alive_ = std::make_shared<bool>(true);
};

}  // namespace spidarcad::app
