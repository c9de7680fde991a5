// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
// The window's command-line options (gui/gui.h): parsing and registration, and the display check.
#include <cmath>
#include <cstdlib>
#include <sstream>
#include <stdexcept>

#define GLFW_INCLUDE_NONE
#include <GLFW/glfw3.h>

#include "gui/gui.h"
#include "scene/haptic_runtime.h"
#include "scene/scripted_run_options.h"

namespace spidarcad::app {

bool DisplayAvailable() {
  const char* display = std::getenv("DISPLAY");
  if (display == nullptr || display[0] == '\0') return false;
  // glfwInit connects to the X server and fails cleanly when it cannot. The connection is
  // kept (RunGui's glfwInit is then a no-op): closing it would let an Xvfb with no other
  // client reset, and a connection opened during the reset fails.
  glfwSetErrorCallback(nullptr);
  return glfwInit() == GLFW_TRUE;
}

void ParseWindowSize(const std::string& text, int* width, int* height) {
  int w = 0, h = 0;
  char x = 0;
  std::istringstream in(text);
  if (!(in >> w >> x >> h) || (x != 'x' && x != 'X') || !(in >> std::ws).eof() || w < 200 ||
      h < 200 || w > 8192 || h > 8192) {
    throw CLI::ValidationError("--size",
                               "expected WxH with both in [200, 8192] pixels, got '" + text + "'");
  }
  *width = w;
  *height = h;
}

void ParseGripPose(const std::string& text, std::array<double, 7>* grip) {
  static const char* kFields[7] = {"x [mm]",      "y [mm]",    "z [mm]",     "roll [deg]",
                                   "pitch [deg]", "yaw [deg]", "grasp [deg]"};
  std::array<double, 7> out = *grip;
  std::stringstream in(text);
  std::string field;
  int k = 0;
  while (std::getline(in, field, ',')) {
    if (k >= 7) {
      throw CLI::ValidationError(
          "--grip", "at most 7 fields (x,y,z,roll,pitch,yaw,grasp), got '" + text + "'");
    }
    try {
      size_t used = 0;
      out[k] = std::stod(field, &used);
      if (used != field.size() || !std::isfinite(out[k])) throw std::invalid_argument(field);
    } catch (const std::exception&) {
      throw CLI::ValidationError("--grip", std::string("field ") + std::to_string(k + 1) + " (" +
                                               kFields[k] + ") is not a number: '" + field + "'");
    }
    ++k;
  }
  if (k != 3 && k != 6 && k != 7) {
    throw CLI::ValidationError("--grip",
                               "expected 3, 6 or 7 comma-separated fields "
                               "(x,y,z[,roll,pitch,yaw[,grasp]]), got '" +
                                   text + "'");
  }
  *grip = out;
}

SetFieldEdit ParseSetField(const std::string& text) {
  const size_t equals = text.find('=');
  const size_t colon = equals == std::string::npos ? std::string::npos : text.rfind(':', equals);
  if (equals == std::string::npos || colon == std::string::npos || colon == 0 ||
      colon + 1 == equals || equals + 1 == text.size()) {
    throw CLI::ValidationError(
        "--set", "expected NODE:FIELD=VALUE (e.g. knob:radius=0.04), got '" + text + "'");
  }
  return {text.substr(0, colon), text.substr(colon + 1, equals - colon - 1),
          text.substr(equals + 1)};
}

void AddGuiOptions(CLI::App& app, GuiOptions* options) {
  auto* recover = app.add_flag_callback(
      "--recover", [options] { options->recover = 1; },
      "At start, when an autosave of the document is newer than its file (the last session "
      "ended without saving), recover it without asking (the document opens with the unsaved "
      "work, still unsaved)");
  auto* no_recover = app.add_flag_callback(
      "--no-recover", [options] { options->recover = 0; },
      "At start, discard (delete) such an autosave without asking and open the file as saved");
  recover->excludes(no_recover);
  app.add_option("--autosave-interval", options->autosave_interval,
                 "Seconds between autosaves of a document with unsaved changes into the recovery "
                 "directory (default 60; $SPIDARCAD_RECOVERY_DIR overrides the directory)")
      ->check(CLI::PositiveNumber)
      ->type_name("SECONDS");
  app.add_option("--set", options->set_fields,
                 "Edit a node once the document is open, as one undoable step (repeatable): "
                 "NODE:FIELD=VALUE with NODE as for --select and VALUE in SI units as the scene "
                 "format has it, e.g. --set knob:radius=0.04. A bad edit: exit status 2")
      ->type_name("NODE:FIELD=VALUE")
      ->expected(1)
      ->multi_option_policy(CLI::MultiOptionPolicy::TakeAll)
      ->each([](const std::string& text) { ParseSetField(text); });
  app.add_option("--show", options->show,
                 "Start with the File menu ('file-menu'), the Open dialog ('open') or the Import "
                 "mesh dialog ('import') open, or the calibration wizard collecting while it "
                 "waves the simulated grip itself ('calibrate'), e.g. for a --screenshot of it")
      ->check(CLI::IsMember({"file-menu", "open", "import", "calibrate"}));
  app.add_option("--place", options->place,
                 "Model mode starts placing this primitive (sphere, box or cylinder): its ghost "
                 "follows the grip, the grasp sets its size (s·d·θ, the arc between the pole "
                 "tips), it aligns to faces, edges and axes it comes near, and P, the panel's "
                 "Place button or a squeeze of the grasp adds it as a new solid (one undo step). "
                 "Not with --mode. Another name: exit status 2")
      ->type_name("KIND");
  app.add_option("--select", options->select,
                 "Select this solid, node or object in the tree panel at start, showing its "
                 "parameters: a solid's name, a node's name or id, SOLID/i/j for child j of child "
                 "i of the solid's root, or the name of a mesh, FE model or sculpt object "
                 "(default: the first solid). Not in the scene: exit status 2")
      ->type_name("NAME");
  app.add_option("scene", options->scene,
                 "Scene to open: a scene file (JSON, e.g. assets/scenes/platform.json), 'demo' "
                 "(built-in, the default) or 'none'; with --mode fe the default is "
                 "assets/scenes/platform.json, with --mode sculpt assets/scenes/clay.json. The "
                 "file is re-read when it changes on disk.");
  app.add_option(
         "--mode", options->mode,
         "Start in a mode: 'fe' precomputes the document's first FE model, else sets up the "
         "selected (or first) solid (TetGen, steel, clamped at the minimum-x face; the default "
         "scene is assets/scenes/platform.json) and lets the grip push it; 'sculpt' sculpts the "
         "document's first sculpt object, else a sculpt copy of its first solid (the default "
         "scene is assets/scenes/clay.json; close the grasp or hold G). Both are also in the mode "
         "switcher (right panel). While a mode's part "
         "is live, it alone is felt: the scene's solids are shown but not touched.")
      ->check(CLI::IsMember({"fe", "sculpt"}));
  app.add_option("--estop-frame", options->estop_frame,
                 "Press the emergency stop (Space) at this frame (scripted runs and tests)")
      ->check(CLI::NonNegativeNumber);
  app.add_option("--trajectory", options->trajectory,
                 "Scripted grip: the simulated hand's target follows this trajectory CSV "
                 "(t,x,y,z,qw,qx,qy,qz,grasp in D, as `spidarcad run --trajectory`) in wall-clock "
                 "time from the first frame, then holds its last sample and the mouse takes over; "
                 "the grip starts at its first sample. --screenshot waits until it has ended "
                 "(+0.5 s), --frames runs at least that long.");
  CLI::Option* clock =
      app.add_option("--clock", options->clock,
                     "'wall' (default) or 'virtual': with --trajectory T.csv --out R.csv the "
                     "window steps `spidarcad run`'s session tick by tick on its virtual clock "
                     "(the same document, fields and options: --world-scale, --world-origin, "
                     "--fe-grab, --fe-grasp, --sculpt-tool, --calibrate, ... as `spidarcad run`), "
                     "renders a frame every 16 ticks, writes the same CSV as `spidarcad run` "
                     "(tick_us aside) and exits")
          ->check(CLI::IsMember({"wall", "virtual"}));
  app.add_option("--out", options->out,
                 "With --clock virtual: the run's CSV, one row per tick (as `spidarcad run --out`)")
      ->needs(clock);
  for (CLI::Option* option : AddScriptedRunOptions(app, &options->run)) {
    option->needs(clock);
    option->group("Scripted run (with --clock virtual; see `spidarcad run --help`)");
  }
  app.add_option("--screenshot", options->screenshot,
                 "Render a few frames, write the window (scene and panel) to this PNG and exit");
  app.add_option("--frames", options->frames, "Exit after this many frames (0: run until closed)")
      ->check(CLI::NonNegativeNumber);
  app.add_option("--device", options->device,
                 "The device the 1 kHz haptic loop drives: 'simulated' (default: the simulated "
                 "SPIDAR-G with encoder errors, calibrated at start-up, held by a simulated hand "
                 "that follows the mouse); 'ideal' (no encoder errors, the grip exactly where the "
                 "mouse puts it); 'board-sim' (the same simulated SPIDAR-G behind the controller "
                 "board's firmware simulator, driven by the USB driver byte for byte, no "
                 "hardware; the panel can unplug it); 'usb' (a real controller board over libusb: "
                 "your hand moves the grip, the mouse does not; without a board the window runs "
                 "at zero force, says 'not connected' and retries every 0.2 s: see `spidarcad "
                 "device list` and assets/udev/99-spidarcad.rules)")
      ->check(CLI::Validator(
          [](std::string& name) -> std::string {
            RuntimeDevice device;
            if (ParseRuntimeDevice(name, &device)) return {};
            return "'" + name + "' is not a device; use simulated, ideal, board-sim or usb";
          },
          "DEVICE"));
  app.add_option("--seed", options->seed,
                 "Seed of the simulated device's encoder errors and noise (simulated, board-sim; "
                 "default 1)");
  app.add_option_function<std::vector<double>>(
         "--frame",
         [options](const std::vector<double>& v) {
           options->geometry.a = v[0];
           options->geometry.b = v[1];
           options->geometry.c = v[2];
           options->geometry_given = true;
         },
         "The device's frame half-sides A,B,C in metres (default 0.24,0.24,0.24: the paper's "
         "48 cm frame); as `spidarcad run --frame`")
      ->delimiter(',')
      ->expected(3)
      ->type_name("A,B,C");
  app.add_option_function<double>(
      "--pole",
      [options](double d) {
        options->geometry.d = d;
        options->geometry_given = true;
      },
      "The grip's pole half-length D in metres (default 0.04: the paper's 4 cm grip)");
  app.add_option("--calibration", options->calibration,
                 "Read the encoders through this calibration file (written by `spidarcad "
                 "calibrate --out`, docs/calibration-format.md) instead of the start-up fit "
                 "(simulated) or the nominal model (board-sim, usb). It must have been made on "
                 "this device (kind, --seed or board serial, --frame/--pole): otherwise exit "
                 "status 2 with the reason. With --device usb and no --calibration, the window "
                 "uses the file `spidarcad calibrate --device usb --out` (or the calibration "
                 "wizard's Save) last wrote for the connected board (remembered per serial "
                 "number)")
      ->type_name("FILE");
  app.add_option_function<std::string>(
         "--size",
         [options](const std::string& s) { ParseWindowSize(s, &options->width, &options->height); },
         "Window size WxH in pixels (default 1280x800)")
      ->type_name("WxH");
  app.add_option_function<std::string>(
         "--grip", [options](const std::string& s) { ParseGripPose(s, &options->grip); },
         "Starting hand pose in the device frame: x,y,z[,roll,pitch,yaw[,grasp]] "
         "(mm and degrees; grasp 20..160, default 90)")
      ->type_name("X,Y,Z[,R,P,Y[,G]]");
}

}  // namespace spidarcad::app
