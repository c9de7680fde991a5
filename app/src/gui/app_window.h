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

class DeviceView;
class GripControl;
class HapticRuntime;
class Mode;
class ModelMode;
class SceneModel;
class SceneView;
class TreeController;

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
  // the solid under it (a VTK cell picker on the scene's actors). True when one was selected.
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
  ModelMode& model_mode();
  SceneModel& model();
  TreeController& tree();
  HapticRuntime& runtime();
  GripControl& grip();
  DeviceView& view();
  SceneView& scene_view();
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
  void ApplyHidden();
  void FitView();
  bool CaptureScreenshot();
  void RenderFrame();

  std::unique_ptr<State> s_;
};

}  // namespace spidarcad::app
