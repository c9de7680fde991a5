// The spidarcad window: GLFW + VTK + Dear ImGui. Shows the SPIDAR-G frame, its 8 strings
// coloured by tension, the cross grip and the scene's solids, with the 1 kHz haptic loop running
// on its own thread against the simulated device when no device is plugged in.
// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#pragma once

#include <CLI/CLI.hpp>
#include <array>
#include <atomic>
#include <cstdint>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "scene/scripted_run.h"
#include "spidarcad/haptics/geometry.h"
#include "spidarcad/haptics/usb_transport.h"

namespace spidarcad::app {

struct GuiOptions {
  int width = 1280;  // window size in pixels
  int height = 800;
  std::string screenshot;  // when set: render, write this PNG and exit
  int frames = 0;          // when > 0: exit after this many frames
  // --device: simulated, ideal, board-sim or usb (RuntimeDevice, scene/haptic_runtime.h).
  std::string device = "simulated";
  // --seed: the simulated device's errors and noise (simulated, board-sim).
  std::uint64_t seed = 1;
  // --frame, --pole: the device's frame half-sides a, b, c and pole half-length d, m.
  haptics::SpidarGeometry geometry;
  // True when --frame or --pole was given: it overrides the start-up document's own frame.
  bool geometry_given = false;
  // --calibration: a calibration file (`spidarcad calibrate --out`) to read the encoders
  // through; "" for the default (start-up fit, nominal, or usb: the board's remembered file).
  std::string calibration;
  // Scene file, "demo" (built-in) or "none"; empty: the mode's part (platform.json for 'fe',
  // clay.json for 'sculpt') or, without a mode, the demo.
  std::string scene;
  std::string mode;     // 'fe' or 'sculpt': start in that mode (demo, screenshots)
  int estop_frame = 0;  // when > 0: press the emergency stop at this frame
  // When set: a trajectory CSV (haptics/trajectory.h) the hand's target follows instead of the
  // mouse, in wall-clock time from the first frame (the grip starts at its first sample).
  std::string trajectory;
  // --clock: "wall" (the default: the haptic loop runs on its 1 kHz thread, --trajectory is
  // played in wall-clock time) or "virtual" (with --trajectory and --out: the scripted run of
  // `spidarcad run`, scene/scripted_run.h, built from the same document and options and stepped
  // tick by tick in the window's process, one frame per kSculptFrameTicks ticks; at the end
  // its CSV is written, its summary printed, and the window exits).
  std::string clock = "wall";
  // --out (--clock virtual): the run's CSV, the columns of `spidarcad run --out`.
  std::string out;
  // --clock virtual: the options shared with `spidarcad run` (AddScriptedRunOptions); SCENE,
  // --trajectory, --device, --seed, --frame/--pole and --calibration are the window's own.
  ScriptedRunOptions run;
  // Starting pose of the hand: x, y, z (mm), roll, pitch, yaw (deg), grasp (deg), in D.
  std::array<double, 7> grip = {0, 0, 0, 0, 0, 0, 90};
  // --select: the solid or node selected in the tree panel at start (a solid's name, a node's
  // name or id, or SOLID/i/j); empty: the first solid.
  std::string select;
  // --recover / --no-recover: the answer to the start-up question about a recovery file newer
  // than the document (doc/autosave.h): 1 recover it, 0 discard it, -1 ask in the window.
  int recover = -1;
  // --autosave-interval: seconds between autosaves of a document with unsaved changes (> 0).
  double autosave_interval = 60.0;
  // --set NODE:FIELD=VALUE: edits made (as undoable commands) once the document is open.
  std::vector<std::string> set_fields;
  // --show file-menu|open|import|calibrate: the window starts with that menu or dialog open, or
  // with the calibration wizard collecting while it waves the simulated grip itself
  // (screenshots of the documentation); "" for none.
  std::string show;
  // --place sphere|box|cylinder: model mode starts with the ghost of that primitive following
  // the grip (scene/touch_modelling.h); "" for none.
  std::string place;
  // Not an option: what --device usb opens (tests: a LoopbackTransport to a BoardSimulator);
  // empty: libusb (RuntimeSettings::usb_transport).
  std::function<std::unique_ptr<haptics::usb::Transport>()> usb_transport;
  // Not an option: when not null, while it is raised every document being opened is cancelled
  // as by its Cancel button, the start-up document included (tests; once the window exists,
  // AppWindow::CancelOpen cancels the one open in progress). Must outlive the window.
  const std::atomic<bool>* cancel_open = nullptr;
};

// One --set edit: the node (as --select names it), the field (scene-format name) and the value
// (JSON, SI units as the scene format has them).
struct SetFieldEdit {
  std::string node;
  std::string field;
  std::string value;
};

// Parses "NODE:FIELD=VALUE" (the last ':' before the first '=' separates node and field);
// throws CLI::ValidationError naming --set and the text when a part is missing.
SetFieldEdit ParseSetField(const std::string& text);

// True when an X display is available (DISPLAY set and reachable): VTK aborts without one.
// On success GLFW stays initialised (RunGui terminates it), see app_window.cc.
bool DisplayAvailable();

// Opens the window and runs until closed. Returns the process exit status.
int RunGui(const GuiOptions& options);

// Adds the window options (SCENE, --screenshot, --frames, --size, --grip, --device,
// --estop-frame, --recover, --no-recover, --autosave-interval, --set) to the top-level app.
void AddGuiOptions(CLI::App& app, GuiOptions* options);

// Parses "WxH" (e.g. "1280x800") into width and height; throws CLI::ValidationError naming the
// option and value when it is not two integers in [200, 8192].
void ParseWindowSize(const std::string& text, int* width, int* height);

// Parses "x,y,z[,roll,pitch,yaw[,grasp]]" (mm, deg) into `grip` (missing fields keep their
// defaults); throws CLI::ValidationError naming the field and value when a field is not a number.
void ParseGripPose(const std::string& text, std::array<double, 7>* grip);

}  // namespace spidarcad::app
