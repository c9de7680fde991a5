// ImGui side of the workbench: the menu bar (File → New, Open, Save, Import, Export, Edit, Mesh,
// Haptics, View, Help), the document panel (the tree panel of gui/tree_panel.h: objects, nodes,
// parameters, stale meshes and their Refresh; jobs with progress bars and Cancel, status line),
// the Mesh action's controls (its result lands in the Document as a mesh object), the
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
  int selected = 0;              // scene object (solid) the Mesh action works on
  ObjectId selected_object = 0;  // the tree's selected Document object (Export: a mesh object)
  float resolution_mm = 4.0f;    // grid cell of the Mesh action, mm (in W)
  bool sharp_edges = false;      // the Mesh action sharpens the grid surface onto the creases
  bool lattice = false;          // the Mesh action's surface is the lattice route's (not CGAL)
  bool cgal = false;             // Tetrahedra by CGAL Mesh_3 (else TetGen on the grid surface)
  bool show_edges = false;       // draw the selected object's mesh edges
  bool show_figures = true;      // the device and loop figures strip is open (else collapsed)
  char export_path[512] = "";    // path field of the export dialog
  bool export_tets = false;      // the dialog exports tetrahedra (else the surface)
  bool open_export = false;      // request to open the export dialog this frame
  std::string export_message;    // result of the last export (error or "wrote ...")
  bool export_failed = false;
  std::string status;  // status line (last job outcome)
  bool status_error = false;
  // How the grip touches the solids (Haptics menu, Touch): the options of
  // SceneModel::BuildHapticScene, `spidarcad run`'s defaults; set when the user changed them
  // this frame (publish a new scene).
  SceneHapticsOptions contact;
  bool contact_changed = false;
  // The snap settings Haptics → Snap forces turns back on with (the document's last ones when
  // it was turned off; modeling::SceneSnap's defaults at first).
  modeling::SceneSnap snap_settings;
  // A Mesh action past the budget waits for an answer (the "Large mesh" question of the
  // document panel): the question ("" none), and what Proceed starts.
  std::string pending_mesh_text;
  MeshKind pending_mesh_kind = MeshKind::kSurface;
  int pending_mesh_index = -1;
  MeshSettings pending_mesh_settings;
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
// selects the object of the Mesh action and of Export) or, without `tree`, "no solids"; the
// preview of the selected solid, running jobs with progress bar and Cancel, the status line.
// A mesh the Mesh action landed (SceneModel::TakeLandedMesh) is selected in the tree; a Refresh
// asked for in the tree (TreeController::TakeRefreshRequest) starts its job (StartRefreshAction).
void DrawScenePanel(SceneModel* model, JobQueue* jobs, WorkbenchState* state, float x, float y,
                    float width, float height, TreeController* tree = nullptr,
                    TreePanelState* tree_state = nullptr);

// Draws the Mesh action's controls (the solid it meshes, cell size, sharp edges, TetGen or CGAL,
// Surface and Tetrahedra buttons; no Begin/End).
void DrawMeshControls(SceneModel* model, JobQueue* jobs, WorkbenchState* state);

// Draws the running jobs (progress bar, Cancel) and the status line (no Begin/End).
void DrawJobs(JobQueue* jobs, WorkbenchState* state, float width);

// Draws the Touch controls (tool model "Point (proxy)" / "Grip (six-DOF)", stiffness, damping
// and, for the proxy, friction; values as felt at the grip) into the current menu (the menu
// bar's Haptics menu draws them: a panel line would hide part of the view); sets
// state->contact_changed when the user changed one. The shell's coupling stiffness follows the
// stiffness as in `spidarcad run` (min(k, 1000 N/m)).
void DrawContactControls(WorkbenchState* state);

// Haptics → Snap forces: turns the document's snap forces off (it had them) or on (with
// state->snap_settings) as one undoable command ("Remove snap forces" / "Set snap forces"); the
// scene is republished when the document changes. Returns the new state (true: on). Throws what
// Document::Execute throws (nothing changes then).
bool ToggleSnapForces(Document* doc, WorkbenchState* state);

// Draws the loop statistics and the emergency stop / re-arm buttons (no Begin/End).
void DrawLoopFigures(const LoopStats& stats, WorkbenchActions* actions);

// Draws a red "EMERGENCY STOP" banner centred at the top of the view (x0..x1 at y).
void DrawStopBanner(float x0, float x1, float y);

// Opens (when requested) and draws the export dialog: the selected mesh object's surface (or the
// boundary of its tetrahedra) or tetrahedra, else the selected solid's preview surface.
void DrawExportDialog(const SceneModel& model, WorkbenchState* state);

// Starts the Mesh action of `kind` on the selected solid with the state's cell size, sharp edges
// and mesher (SceneModel::StartMeshJob); errors (no solid, bad settings) go to the status line.
// The estimate (as SceneModel::MeshJobOverBudget) runs first in a Job "Estimate the mesh of
// NAME" (phase box, cancellable: nothing changes); when it lands, a mesh within `spidarcad
// mesh`'s budget starts, one past it is not started: state->pending_mesh_text asks first (the
// document panel shows the question), and AnswerMeshQuestion starts it or drops it.
void StartMeshAction(SceneModel* model, JobQueue* jobs, WorkbenchState* state, MeshKind kind);
// The answer to the pending "Large mesh" question: Proceed starts the job as asked, Cancel
// changes nothing (the status line says so). No effect without a pending question.
void AnswerMeshQuestion(SceneModel* model, JobQueue* jobs, WorkbenchState* state, bool proceed);

// Starts meshing object `id` again from its source with its stored settings: a mesh object made
// from a source, or an FE model (its mesh) (SceneModel::StartRefreshJob). Errors (nothing to
// refresh, source deleted) go to the status line. True when a job started.
bool StartRefreshAction(SceneModel* model, JobQueue* jobs, WorkbenchState* state, ObjectId id);

}  // namespace spidarcad::app
