// ImGui side of the workbench: the menu bar (File → Save / Export, Edit, Mesh, Haptics, View),
// the scene panel (the tree panel of gui/tree_panel.h: objects, nodes, parameters; Mesh action with progress bars and Cancel, status line), the loop panel
// (tick time and period jitter percentiles, safety events, scheduling, emergency stop) and the
// export dialog. They act on SceneModel and JobQueue directly and return the rest.
// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#pragma once

#include <string>

#include "doc/job.h"
#include "scene/haptic_runtime.h"
#include "scene/scene_model.h"
#include "gui/tree_panel.h"

namespace spidarcad::app {

// UI state of the workbench that lives across frames.
struct WorkbenchState {
  int selected = 0;               // scene object the Mesh action and Export work on
  float resolution_mm = 4.0f;     // grid cell of the Mesh action, mm (in W)
  bool show_edges = false;        // draw the selected object's mesh edges
  char export_path[512] = "";     // path field of the export dialog
  bool export_tets = false;       // the dialog exports tetrahedra (else the surface)
  bool open_export = false;       // request to open the export dialog this frame
  std::string export_message;     // result of the last export (error or "wrote ...")
  bool export_failed = false;
  std::string status;             // status line (last job outcome)
  bool status_error = false;
  // How the grip touches the solids (Haptics menu, Touch): the options of
  // SceneModel::BuildHapticScene, `spidarcad run`'s defaults; set when the user changed them
  // this frame (publish a new scene).
  SceneHapticsOptions contact;
  bool contact_changed = false;
};

// What the menu bar and panels asked for this frame.
struct WorkbenchActions {
  bool emergency_stop = false;
  bool rearm = false;
  bool reset_grip = false;
  bool reset_camera = false;
  bool quit = false;
};

// Draws the main menu bar (File → Save / Save As when `tree` is given, Edit menu from `tree`);
// returns its height in pixels.
float DrawMenuBar(SceneModel* model, JobQueue* jobs, WorkbenchState* state,
                  WorkbenchActions* actions, TreeController* tree = nullptr,
                  TreePanelState* tree_state = nullptr);

// Draws the scene panel at (x, y), `width` wide: source, the tree panel (objects and their node
// trees, the selected node's parameters; it also selects the object of the Mesh action) or,
// without `tree`, the object list; Mesh action (resolution, Surface / Tetrahedra buttons),
// running jobs with progress bar and Cancel, status line. `max_height` bounds the panel
// (pixels); the tree region scrolls within it.
void DrawScenePanel(SceneModel* model, JobQueue* jobs, WorkbenchState* state, float x, float y,
                    float width, TreeController* tree = nullptr,
                    TreePanelState* tree_state = nullptr, float max_height = 1e5f);

// Draws the Touch controls (tool model "Point (proxy)" / "Grip (six-DOF)", stiffness, damping
// and, for the proxy, friction; values as felt at the grip) into the current menu (the menu
// bar's Haptics menu draws them: a panel line would hide part of the view); sets
// state->contact_changed when the user changed one. The shell's coupling stiffness follows the
// stiffness as in `spidarcad run` (min(k, 1000 N/m)).
void DrawContactControls(WorkbenchState* state);

// Draws the loop panel with its bottom-right corner at (right, bottom): statistics and the
// emergency stop / re-arm buttons.
void DrawLoopPanel(const LoopStats& stats, float right, float bottom, WorkbenchActions* actions);

// Draws a red "EMERGENCY STOP" banner centred at the top of the view (x0..x1 at y).
void DrawStopBanner(float x0, float x1, float y);

// Opens (when requested) and draws the export dialog.
void DrawExportDialog(const SceneModel& model, WorkbenchState* state);

// Starts the Mesh action of `kind` on the selected object at the state's resolution; errors
// (no object) go to the status line.
void StartMeshAction(SceneModel* model, JobQueue* jobs, WorkbenchState* state, MeshKind kind);

}  // namespace spidarcad::app
