// ImGui side of the workbench: the menu bar (File → New, Open, Save, Import, Export, Edit, Mesh,
// Haptics, View, Help), the document panel (the tree panel of gui/tree_panel.h: objects, nodes,
// parameters; jobs with progress bars and Cancel, status line), the Mesh action's controls, the
// loop figures (tick time and period jitter percentiles, safety events, scheduling, emergency stop)
// and the export dialog. They act on SceneModel and JobQueue directly and return the rest.
// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#pragma once

#include <string>
#include <vector>

#include "doc/job.h"
#include "doc/recent_files.h"
#include "gui/tree_panel.h"
#include "scene/haptic_runtime.h"
#include "scene/scene_model.h"

namespace spidarcad::app {

// UI state of the workbench that lives across frames.
struct WorkbenchState {
  int selected = 0;            // scene object the Mesh action and Export work on
  float resolution_mm = 4.0f;  // grid cell of the Mesh action, mm (in W)
  bool show_edges = false;     // draw the selected object's mesh edges
  bool show_figures = true;    // the device and loop figures strip is open (else collapsed)
  char export_path[512] = "";  // path field of the export dialog
  bool export_tets = false;    // the dialog exports tetrahedra (else the surface)
  bool open_export = false;    // request to open the export dialog this frame
  std::string export_message;  // result of the last export (error or "wrote ...")
  bool export_failed = false;
  std::string status;  // status line (last job outcome)
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
  bool fit_view = false;   // View → Fit (F)
  int standard_view = -1;  // View → Front, Right, Top, Iso (0..3; StandardView), −1: none
  bool quit = false;
  bool file_new = false;      // File → New (Ctrl+N)
  bool file_open = false;     // File → Open... (Ctrl+O): the file browser
  bool file_import = false;   // File → Import mesh... (Ctrl+I): the file browser
  std::string open_recent;    // File → Open Recent → this path
  bool clear_recent = false;  // File → Open Recent → Clear the list
  bool calibrate = false;     // Haptics → Calibrate device...: the calibration wizard
};

// Draws the main menu bar: File (New, Open..., Open Recent from `recent` (missing files
// disabled), Save / Save As when `tree` is given, Import mesh..., Export, Quit), Edit from
// `tree`, Mesh, Haptics, View, Help; returns its height in pixels.
float DrawMenuBar(SceneModel* model, JobQueue* jobs, WorkbenchState* state,
                  WorkbenchActions* actions, TreeController* tree = nullptr,
                  TreePanelState* tree_state = nullptr,
                  const std::vector<RecentEntry>* recent = nullptr);

// Draws the document panel docked at (x, y), `width` × `height` pixels: source, the tree panel
// (gui/tree_panel.h: objects and their node trees, the selected node's parameters; it also
// selects the object of the Mesh action) or, without `tree`, "no solids"; the mesh of the
// selected object, running jobs with progress bar and Cancel, the status line.
void DrawScenePanel(SceneModel* model, JobQueue* jobs, WorkbenchState* state, float x, float y,
                    float width, float height, TreeController* tree = nullptr,
                    TreePanelState* tree_state = nullptr);

// Draws the Mesh action's controls (cell size, Surface and Tetrahedra buttons; no Begin/End).
void DrawMeshControls(SceneModel* model, JobQueue* jobs, WorkbenchState* state);

// Draws the running jobs (progress bar, Cancel) and the status line (no Begin/End).
void DrawJobs(JobQueue* jobs, WorkbenchState* state, float width);

// Draws the Touch controls (tool model "Point (proxy)" / "Grip (six-DOF)", stiffness, damping
// and, for the proxy, friction; values as felt at the grip) into the current menu (the menu
// bar's Haptics menu draws them: a panel line would hide part of the view); sets
// state->contact_changed when the user changed one. The shell's coupling stiffness follows the
// stiffness as in `spidarcad run` (min(k, 1000 N/m)).
void DrawContactControls(WorkbenchState* state);

// Draws the loop statistics and the emergency stop / re-arm buttons (no Begin/End).
void DrawLoopFigures(const LoopStats& stats, WorkbenchActions* actions);

// Draws a red "EMERGENCY STOP" banner centred at the top of the view (x0..x1 at y).
void DrawStopBanner(float x0, float x1, float y);

// Opens (when requested) and draws the export dialog.
void DrawExportDialog(const SceneModel& model, WorkbenchState* state);

// Starts the Mesh action of `kind` on the selected object at the state's resolution; errors
// (no object) go to the status line.
void StartMeshAction(SceneModel* model, JobQueue* jobs, WorkbenchState* state, MeshKind kind);

}  // namespace spidarcad::app
