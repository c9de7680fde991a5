// spidarcad: engineering design by touch with a SPIDAR-G haptic device.
// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#include <CLI/CLI.hpp>
#include <cstdio>
#include <iostream>
#include <string>

#include "cli/cli_common.h"
#include "cli/commands.h"
#include "gui/gui.h"
#include "scene/worker_process.h"

int main(int argc, char** argv) {
  using namespace spidarcad::app;
  // The hidden worker (a child of a window job; scene/worker_process.h).
  if (argc >= 2 && std::string(argv[1]) == kWorkerCommand) return RunWorkerCommand(argc, argv);
  // Window jobs run TetGen, CGAL and CHOLMOD in a child process of this executable, which Cancel
  // can kill.
  SetWorkerProgram("/proc/self/exe");
  CLI::App app{
      "spidarcad: engineering design by touch with a SPIDAR-G (7-DOF string haptic device).\n"
      "\n"
      "Without a subcommand it opens the window on the demo scene with the simulated device\n"
      "(drag the grip with the left mouse button, wheel for grasp). Every capability also runs\n"
      "headless as a subcommand; `spidarcad SUBCOMMAND --help` explains each one.\n"
      "\n"
      "Units are SI everywhere: metres, radians, newtons. Frame D is the device frame: origin\n"
      "at the frame centre, corners at (±a, ±b, ±c).\n"
      "\n"
      "Examples:\n"
      "  # the rest pose: all 8 strings 0.3939543 m long\n"
      "  echo 0.3939543,0.3939543,0.3939543,0.3939543,0.3939543,0.3939543,0.3939543,0.3939543 \\\n"
      "    | spidarcad fk --batch\n"
      "  spidarcad workspace --out-csv ws.csv --out-png ws.png\n"
      "  spidarcad calibrate --simulated\n"
      "  spidarcad mesh assets/scenes/platform.json --out platform.stl\n"
      "  spidarcad fem assets/scenes/platform.json --resolution 0.01 --fix=-1,-1,-1,0.0005,1,1 \\\n"
      "    --push 0.29,0,0.01 --disp 0,0,-0.001 --out platform.vtu\n"
      "  spidarcad trajectory press --depth 0.005 --out press.csv\n"
      "  spidarcad run demo --trajectory press.csv --out press_result.csv\n"
      "  spidarcad device list\n",
      "spidarcad"};
  app.set_version_flag("--version", "spidarcad 0.1.0");
  app.require_subcommand(0, 1);

  GuiOptions gui_options;
  AddGuiOptions(app, &gui_options);
  RegisterFkCommand(app);
  RegisterIkCommand(app);
  RegisterTensionCommand(app);
  RegisterWorkspaceCommand(app);
  RegisterCalibrateCommand(app);
  RegisterMeshCommand(app);
  RegisterFemCommand(app);
  RegisterFeltCommand(app);
  RegisterRunCommand(app);
  RegisterTrajectoryCommand(app);
  RegisterDeviceCommand(app);
  RegisterReportCommand(app);
  RegisterInfoCommand(app);
  RegisterImportCommand(app);

  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    const int status = app.exit(e);
    return status == 0 ? 0 : kExitBadInput;
  } catch (const CommandExit& e) {
    return e.status;
  } catch (const InputError& e) {
    std::fflush(stdout);
    std::cerr << "spidarcad: error: " << e.what() << "\n";
    return kExitBadInput;
  } catch (const std::exception& e) {
    std::fflush(stdout);
    std::cerr << "spidarcad: error: " << e.what() << "\n";
    return 1;
  }
  if (app.get_subcommands().empty()) {
    if (!DisplayAvailable()) {
      std::cerr << "spidarcad: no X display (DISPLAY is unset or unreachable), so the window "
                   "cannot open.\n"
                   "  Run the window under a virtual display:  xvfb-run -a spidarcad\n"
                   "  or use the headless subcommands:          spidarcad --help\n";
      return 1;
    }
    try {
      return RunGui(gui_options);
    } catch (const std::exception& e) {
      std::cerr << "spidarcad: error: " << e.what() << "\n";
      return 1;
    }
  }
  return 0;
}
