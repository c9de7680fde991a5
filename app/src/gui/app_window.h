// The spidarcad window as a class. Construction sets up the scene (a bad file fails before any
// window opens), the haptic runtime on its 1 kHz thread, VTK in the GLFW window's OpenGL context,
// Dear ImGui and the modes (gui/modes.h); Run() is the frame loop. Each frame: GLFW events →
// input (grip control, camera, picking, keys) → the hand's target → the latest ToolState → every
// mode's Update → panels in the fixed docked layout (gui/window_layout.h) → the haptic scene
// republished when something changed → VTK renders the viewport, ImGui the panels → screenshot.
// Main thread only.
// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#pragma once

#include <memory>
#include <stdexcept>
#include <string>
#include <vector>

#include "gui/gui.h"
#include "gui/window_layout.h"

class vtkRenderer;

namespace spidarcad::app {

class Autosaver;
class CalibrationWizard;
class DeviceView;
class RecentFiles;
class GripControl;
class HapticRuntime;
class JobQueue;
class Mode;
class ModelMode;
struct OpenWork;
class SceneModel;
class SceneView;
class TreeController;
struct WorkbenchState;

// Why the window could not start: the text for stderr and the process exit status (2: bad input
// such as a scene, --select or --trajectory; 1: no display, no OpenGL 3.2).
class WindowStartError : public std::runtime_error {
 public:
  WindowStartError(int status, const std::string& message)
      : std::runtime_error(message), status_(status) {}
  int status() const { return status_; }

 private:
  int status_;
};

// The window (see the file comment).
class AppWindow {
 public:
  // Opens the window on options.scene (see GuiOptions). Throws WindowStartError.
  explicit AppWindow(const GuiOptions& options);
  ~AppWindow();
  AppWindow(const AppWindow&) = delete;
  AppWindow& operator=(const AppWindow&) = delete;

  // Runs frames until the window closes (Esc, Quit, --frames, --screenshot), then stops the
  // loop and, for scripted runs, prints the loop, FE and assembly summaries. Returns the exit
  // status.
  int Run();
  // Runs one frame. False when the run is over (quit, closed, screenshot written, frames done).
  bool Frame();

  // ---- the parts, for scripted use and tests ----
  // The layout of the latest frame (window pixels, y down).
  const WindowLayout& layout() const;
  // The rectangle the ImGui panel `name` ("Document", "Mode", "Device and haptic loop") was
  // drawn in at the latest frame; empty when it was not drawn.
  Rect DrawnPanel(const std::string& name) const;
  // Resizes the window (screen pixels); the next frame lays the panels out again.
  void Resize(int width, int height);
  // A click at window pixel (x, y) (origin top left, y down) in the viewport: selects in the tree
  // the solid, imported mesh or assembly part under it (a VTK cell picker on their actors). True
  // when one was selected.
  bool ClickAt(double x, double y);
  // What Enter does in the view: selects the solid the grip touches (modelling mode). True when
  // one was selected.
  bool SelectTouched();
  // The modes (modelling first) and the active one.
  std::vector<Mode*> modes() const;
  Mode* active_mode() const;
  // The mode whose key() is `key` ("model", "fe", "sculpt", "assembly"), or null.
  Mode* FindMode(const std::string& key) const;
  // Leaves the active mode, enters `mode` (one of modes()) and republishes the haptic scene.
  void SwitchMode(Mode* mode);
  // Adds a mode after the built-in ones (a plug-in or a test's mode).
  Mode* AddMode(std::unique_ptr<Mode> mode);
  // How many haptic scenes were published since construction.
  int publish_count() const;

  // ---- documents (the File menu; all on the main thread, between frames) ----
  // What File → New, Open, Open Recent, Quit, Esc and the window's close button ask for. With
  // unsaved changes the window first asks Save / Discard / Cancel (a modal); the action runs at
  // the start of the next frame.
  void RequestNew();
  void RequestOpen(const std::string& path);
  void RequestQuit();
  // True while the Save / Discard / Cancel question is up.
  bool discard_prompt_open() const;
  // Answers it as the buttons do: 0 Save (then the action; Save As first for an untitled
  // document), 1 Discard (the action without saving), 2 Cancel (nothing).
  void AnswerDiscardPrompt(int answer);
  // Replaces the document by the file at `path` now, without asking: new X_WD, haptic runtime,
  // modes and view for it; the file goes first in the recent list. A file that fails to open
  // leaves the current document as it was and returns false; file_error() then names the file,
  // line and field (also shown in the window).
  // The file is read, compiled and boxed on a thread of its own while the window keeps
  // drawing ("Opening FILE", how many solids are done, a Cancel button; Esc and the close
  // button cancel too); cancelled, it returns false with the document as it was and no
  // file_error().
  bool OpenDocument(const std::string& path);
  // Cancels the open in progress, as its Cancel button does; safe from any thread. Nothing
  // when no open is in progress.
  void CancelOpen();
  // True while a document is being read (OpenDocument, a recovery or New has not returned);
  // safe from any thread.
  bool opening() const;
  // Replaces the document by an empty, untitled one now, without asking.
  void NewDocument();
  // Imports a mesh file (STL, OBJ, PLY, VTU, .node) as a mesh object of the document (one
  // undoable step, edit::ImportMesh). False, with file_error(), when it cannot be read.
  bool ImportMesh(const std::string& path);
  // What files dropped on the window do: a document (.json, .spidarcad) opens (asking first
  // when there are unsaved changes), a mesh file is imported; anything else is refused with
  // file_error().
  void DropFiles(const std::vector<std::string>& paths);
  // Why the last open, import or drop failed ("" after a success).
  const std::string& file_error() const;
  // The recent-files list (File → Open Recent).
  RecentFiles& recent();
  // The autosaver of the document (recovery files, doc/autosave.h).
  Autosaver& autosaver();
  // True while the start-up question "Recover unsaved work from <time>?" is up.
  bool recovery_prompt_open() const;
  // Answers it: true recovers the autosave, false deletes it.
  void AnswerRecovery(bool recover);
  ModelMode& model_mode();
  SceneModel& model();
  TreeController& tree();
  HapticRuntime& runtime();
  // The calibration wizard (Haptics → Calibrate device...).
  CalibrationWizard& calibration_wizard();
  GripControl& grip();
  DeviceView& view();
  SceneView& scene_view();
  // The workbench panels' state (the Mesh action's settings, the status line) and the jobs.
  WorkbenchState& workbench();
  JobQueue& jobs();
  vtkRenderer* renderer();

 private:
  struct State;
  void HandleInput();
  void FollowTarget();
  void PollJobs();
  void UpdateModes();
  void DrawPanels();
  void DrawModePanel();
  void DrawFiguresStrip();
  void ApplyActions();
  void PublishScene();
  // The mode whose field is felt when the active one is not live: assembly for a document of
  // rigid parts without solids, else modelling.
  Mode* BaseMode() const;
  void ApplyHidden();
  void FitView();
  bool CaptureScreenshot();
  void RenderFrame();
  // Document lifecycle.
  void MakeRuntime();
  void MakeModes();
  void StartScene(const std::string& mode_key);
  bool ReplaceDocument(const std::string& source, const std::string* recovered_original);
  // Draws frames of a box "Opening `source`" (with how far *work has come; over the panels,
  // drawn disabled, once the window has them) until its thread is done (true) or the user
  // cancels: Cancel, Esc, the close button, CancelOpen or GuiOptions::cancel_open (false,
  // work->cancel raised).
  bool WaitForOpen(const std::string& source, OpenWork* work);
  // Reads (once), compiles and boxes `source` on a thread of its own while WaitForOpen draws;
  // returns the finished work (a failure is in its `failure`), or null when the user cancelled:
  // the thread then ends on its own at its next look at the flag, and is joined when the
  // window goes.
  std::shared_ptr<OpenWork> ReadOffThread(const std::string& source);
  // The scene file changed on disk (SceneModel::SourceChanged): reads it again off the main
  // thread (ReadOffThread) and adopts it, keeping X_WD; a failed or cancelled read keeps the
  // old scene and waits for the file's next change.
  void ReloadSource();
  // Opens GLFW, the window and ImGui (state: window_open); without a display it opens nothing
  // and returns (the constructor throws after its other checks). Throws WindowStartError(1)
  // when the window or ImGui cannot be made.
  void OpenWindow();
  // The panels' rectangles and VTK's viewport for the window's current size.
  void UpdateLayout();
  // Reads the window's framebuffer and window sizes into the state; false when minimised.
  bool ReadWindowSize();
  void ApplySetEdits();
  void RunPendingAction();
  void RequestAction(int kind, const std::string& path);
  void DrawFileMenuItems();
  void DrawFileDialogs();
  void UpdateAutosave();
  void ResetAutosaver();
  void DiscardRecovery();
  void FindRecoveryOffer(const std::string& source);

  std::unique_ptr<State> s_;
};

}  // namespace spidarcad::app
