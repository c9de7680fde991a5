// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
// Sculpt mode (modes.md contract): the grip sculpts a lump of clay. The logic (strokes, undo, the
// force field) is SculptSession (scene/sculpt_field.h); this class only draws: the clay actor,
// updated in place during a stroke (the touched vertices' positions and normals copied into the
// VTK arrays, then Modified()), rebuilt whole when the session's revision changes (new clay,
// stroke end with refinement, undo, redo), and a translucent sphere at the grip showing the tool
// radius (green: idle, orange: stroking, red: the trigger fired out of the clay's reach).
//
// Stroke trigger: close the grasp below the panel's "begin" angle (device, or mouse wheel / [ ]
// keys with the simulated hand), or hold G when the mouse drives (full strength while held).
//
// Frames: the session works in W; the actors are placed in the view frame D by the inverse of
// X_WD (p_D = (p_W − p_WDo) / s), set with SetWorldToView.
#pragma once

#include <Eigen/Core>
#include <memory>
#include <string>

#include "scene/sculpt_field.h"
#include "spidarcad/haptics/device_to_world.h"
#include "spidarcad/haptics/haptic_loop.h"

class vtkRenderer;

namespace spidarcad::app {

class JobQueue;

// The sculpt mode's actors and panel around a SculptSession.
class SculptMode {
 public:
  // Adds its actors to renderer (hidden until active); jobs runs the meshing and TetGen Jobs.
  // Both must outlive this mode.
  SculptMode(vtkRenderer* renderer, JobQueue* jobs);
  ~SculptMode();
  SculptMode(const SculptMode&) = delete;
  SculptMode& operator=(const SculptMode&) = delete;

  // Shows/hides the actors. Activation without clay starts meshing the scene file; deactivation
  // cancels a stroke (the field then renders zero force).
  void SetActive(bool active);
  bool active() const { return active_; }
  // ImGui widgets of the side panel (no Begin/End).
  void DrawPanel();
  // Latest tool state: runs the stroke logic and updates the actors (tool.tool_W in W).
  void OnFrame(const haptics::ToolState& tool);
  // The sculpt tool field, once after each activation; else nullptr.
  std::unique_ptr<haptics::ForceField> TakeField();

  // Places the actors in the view frame: p_D = (p_W − p_WDo) / s (s > 0).
  void SetWorldToView(const haptics::DeviceToWorld& X_WD);
  // Scene file whose first solid becomes the clay (default assets/scenes/clay.json).
  void SetScenePath(const std::string& path);
  // Uses a given mesh as the clay instead (throws std::invalid_argument when it is not closed).
  void LoadMesh(const modeling::TriangleMesh& mesh);
  // The logic, for the window and tests.
  SculptSession& session() { return session_; }
  // Wall time of the last OnFrame's display update (stroke step + VTK arrays), ms.
  double last_frame_ms() const { return last_frame_ms_; }

 private:
  struct Vtk;
  void Rebuild();
  void UpdateMarker(const Eigen::Vector3d& p_W, SculptFrameEvent event);

  vtkRenderer* renderer_;
  JobQueue* jobs_;
  SculptSession session_;
  std::unique_ptr<Vtk> vtk_;
  bool active_ = false;
  bool field_pending_ = false;
  std::uint64_t shown_revision_ = ~std::uint64_t{0};
  haptics::DeviceToWorld X_WD_;
  std::string scene_path_;
  std::string export_path_ = "sculpt.stl";
  std::string message_;
  double mesh_cell_ = 0.002;
  bool mesh_requested_ = false;
  SculptFrameEvent last_event_ = SculptFrameEvent::kIdle;
  double last_frame_ms_ = 0.0;
};

}  // namespace spidarcad::app
