// spidarcad: engineering design by touch with a SPIDAR-G haptic device.
// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#include <CLI/CLI.hpp>
#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <iostream>
#include <string>
#include <vector>

#include "cli/cli_common.h"
#include "cli/commands.h"
#include "gui/gui.h"
#include "scene/worker_process.h"
#include "spidarcad/fem/blas_kernels.h"

namespace {

// Edits (insertions, deletions, substitutions) that turn a into b.
std::size_t EditDistance(const std::string& a, const std::string& b) {
  std::vector<std::size_t> row(b.size() + 1);
  for (std::size_t j = 0; j <= b.size(); ++j) row[j] = j;
  for (std::size_t i = 1; i <= a.size(); ++i) {
    std::size_t diagonal = row[0];
    row[0] = i;
    for (std::size_t j = 1; j <= b.size(); ++j) {
      const std::size_t up = row[j];
      row[j] = std::min({row[j] + 1, row[j - 1] + 1, diagonal + (a[i - 1] == b[j - 1] ? 0 : 1)});
      diagonal = up;
    }
  }
  return row[b.size()];
}

// The first argument `word` is taken for the window's scene when it is not a subcommand. A word
// that is neither a subcommand, 'demo', 'none', nor a path (no '.' or '/', no such file) is
// most likely a mistyped subcommand: the error names the subcommands and the nearest one (two
// edits or fewer). Empty when `word` may be a scene.
std::string UnknownWordError(const std::string& word, const std::vector<std::string>& commands) {
  if (word.empty() || word[0] == '-' || word == "demo" || word == "none") return "";
  if (std::find(commands.begin(), commands.end(), word) != commands.end()) return "";
  if (word.find_first_of("./") != std::string::npos) return "";
  std::error_code ec;
  if (std::filesystem::exists(word, ec)) return "";
  std::string list, nearest;
  std::size_t best = 3;
  for (const std::string& c : commands) {
    list += (list.empty() ? "" : ", ") + c;
    const std::size_t d = EditDistance(word, c);
    if (d < best) best = d, nearest = c;
  }
  std::string message = "'" + word + "' is not a subcommand, and no scene file of that name exists";
  if (!nearest.empty()) message += " (did you mean '" + nearest + "'?)";
  return message + ". The subcommands: " + list +
         "; `spidarcad --help` explains them. To open the window on a scene, give its file "
         "(e.g. assets/scenes/platform.json), 'demo' or 'none'.";
}

}  // namespace

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
  // The BLAS line: which OpenBLAS kernels the factorisations run on (fem/blas_kernels.h).
  app.set_version_flag("--version",
                       "spidarcad 0.1.0\nBLAS: " + spidarcad::fem::BlasKernelDescription());
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

  if (argc >= 2) {
    std::vector<std::string> commands;
    for (const CLI::App* c : app.get_subcommands([](const CLI::App*) { return true; }))
      commands.push_back(c->get_name());
    const std::string error = UnknownWordError(argv[1], commands);
    if (!error.empty()) {
      std::cerr << "spidarcad: error: " << error << "\n";
      return kExitBadInput;
    }
  }
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
