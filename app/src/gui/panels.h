// ImGui side of the window: the device panel (string lengths, pose, tensions with bars and the
// colour legend, wrench, centring-spring settings, controls help). Reads a DeviceFrame; returns
// what the user asked for. No VTK and no device computation here. Copyright the spidarcad authors.
// SPDX-License-Identifier: AGPL-3.0-or-later
#pragma once

#include "scene/device_rig.h"
#include "scene/device_session.h"
#include "spidarcad/haptics/geometry.h"

namespace spidarcad::app {

// Width of the document panel docked on the left of the window, pixels.
inline constexpr float kPanelWidth = 380.0f;

// What the panel needs besides the frame.
struct PanelContext {
  const haptics::SpidarGeometry* geometry = nullptr;
  double tau_min = 0.0;  // N, ends of the colour legend
  double tau_max = 1.0;
  double fps = 0.0;            // frames per second of the window
  const char* drag_mode = "";  // current mouse action ("", "moving grip", "orbit", ...)
  float top = 0.0f;            // y of the panel's top edge (below the menu bar), pixels
  // The device link (board-sim, usb): status, counters, "not connected — retrying ..."; null
  // or !has_driver: no link line.
  const RigLink* link = nullptr;
  bool real_hand = false;  // usb: the user's hand holds the grip; the mouse does not move it
  bool board_sim = false;  // board-sim: offer the simulated cable's plug checkbox
};

// What the user asked for through the panel this frame.
struct PanelActions {
  bool reset_grip = false;
  bool reset_camera = false;
  bool quit = false;
  bool field_changed = false;  // the centring springs were edited (publish a new scene)
  int board_plug = 0;          // board-sim: +1 plug the simulated board in, -1 unplug it
};

// Draws the device figures (inside a window or child; no Begin/End): device and link line,
// the grip pose measured by forward kinematics, the wrench asked and shown, the tension solve.
PanelActions DrawDeviceFigures(const DeviceFrame& frame, const PanelContext& context);
// Draws the strings' lengths and tensions (bars in the tension colours) and the colour legend,
// `width` pixels wide (no Begin/End).
void DrawStringFigures(const DeviceFrame& frame, const PanelContext& context, float width);
// Draws the centring springs' checkbox and stiffness sliders; true when one was edited (publish
// a new scene).
bool DrawSpringControls(DemoFieldSettings* field);
// Draws the list of mouse and key controls (no Begin/End).
void DrawControlsHelp();

// Applies the window's colour style (light, engineering look) to the current ImGui context.
void ApplyPanelStyle();

}  // namespace spidarcad::app
