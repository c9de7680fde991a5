// The window's modes behind one interface. Modelling (the default: the scene's solids, felt
// through the proxy or the six-DOF shell tool), FE push, sculpt and assembly each implement Mode;
// AppWindow (gui/app_window.h) holds them, keeps exactly one active, calls the active mode's
// panel, gives every mode the latest ToolState each frame and publishes the haptic scene of the
// mode that stands in for the scene's solids (Mode::live) without knowing which mode it is.
// Main thread only.
// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#pragma once

#include <memory>
#include <string>
#include <vector>

#include "spidarcad/haptics/haptic_loop.h"

namespace spidarcad::app {

class JobQueue;
class SceneModel;
class TreeController;
struct WorkbenchState;

// What the window lends the modes each frame.
struct ModeContext {
  SceneModel* model = nullptr;          // the scene (its Document, solids and meshes)
  JobQueue* jobs = nullptr;             // background jobs (meshing, precomputation)
  TreeController* tree = nullptr;       // the document tree's selection and edits
  WorkbenchState* workbench = nullptr;  // Mesh action state, touch options, status line
  bool select_key = false;              // Enter was pressed in the view this frame
  bool place_key = false;               // P: place the ghost primitive (model mode)
  bool grab_key = false;                // G: grab the selected node, or let it go (model mode)
  // A mode asks the window to switch to the mode with this key() ("fe", ...); the window does it
  // after the mode panel of this frame and clears it.
  std::string switch_to;
};

// One mode of the window.
class Mode {
 public:
  virtual ~Mode() = default;
  // Label in the mode switcher ("Model", "FE push", "Sculpt", "Assembly").
  virtual const char* name() const = 0;
  // The value of --mode that starts in it ("model", "fe", "sculpt", "assembly").
  virtual const char* key() const = 0;
  // Whether the mode can be entered with this scene (assembly: only when it has parts).
  virtual bool available() const { return true; }

  // Becomes the active mode (shows its actors; a field it has becomes publishable).
  virtual void Enter() = 0;
  // Stops being the active mode (hides its actors; its field is no longer published).
  virtual void Leave() = 0;
  // Entered as the mode the window starts in (--mode): Enter, plus the mode's demo set-up
  // (FE: sets up and precomputes the document's FE model). Default: Enter.
  virtual void Launch() { Enter(); }
  // True between Enter and Leave.
  virtual bool active() const = 0;

  // Once per frame, for every mode (active or not), with the latest tool state of the loop.
  virtual void Update(const haptics::ToolState& tool, ModeContext& context) = 0;
  // ImGui widgets of the mode's panel (inside the right-hand panel; no Begin/End).
  virtual void DrawPanel(ModeContext& context) = 0;

  // True when the mode has a force field ready that stands in for the scene's solids (a live
  // mode part usually sits where a scene solid is, and the solid's contact would hold the tool
  // off it). The window publishes the active mode's scene when it is live, else the base mode's.
  virtual bool live() const = 0;
  // The haptic scene the mode contributes (its field(s), shared with earlier scenes so that a
  // republish keeps their state between ticks).
  virtual std::unique_ptr<haptics::HapticScene> BuildScene(ModeContext& context) = 0;
  // True once after the mode's field changed (new field, reset): the scene must be republished.
  virtual bool TakeSceneChanged() = 0;

  // Names of the scene objects the mode acts on (for the panel; with draws_targets(), the
  // window hides their static actors because the mode draws them itself).
  virtual std::vector<std::string> Targets(const SceneModel& model) const = 0;
  // True when the mode draws its targets where they are (assembly parts).
  virtual bool draws_targets() const { return false; }

  // True when a screenshot may be taken (the mode's part is live and has settled).
  virtual bool Settled() const { return true; }
  // Why undo and redo must wait now, or "" when they may run: a gesture is under way whose result
  // becomes a command only when it ends (a carried part, a sculpt stroke), and an undo under the
  // hand would pull the part or the clay away from the grip.
  virtual std::string HistoryHold() const { return ""; }
  // Lines for the end of a scripted run (--frames, --screenshot); "" for none.
  virtual std::string Summary(const haptics::ToolState& tool) {
    (void)tool;
    return "";
  }
};

}  // namespace spidarcad::app
