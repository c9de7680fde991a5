// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#include "cli/golden_runs.h"

#include <CLI/CLI.hpp>
#include <stdexcept>

#include "cli/run_command.h"
#include "doc/input_error.h"

namespace spidarcad::app {

const std::vector<GoldenRun>& GoldenRuns() {
  static const std::vector<GoldenRun> runs = [] {
    const std::string press = "assets/trajectories/press.csv";
    std::vector<GoldenRun> r = {
        {"demo_press", {"demo", "--trajectory", press}},
        {"platform_press",
         {"assets/scenes/platform.json", "--trajectory", press, "--world-scale", "1",
          "--world-origin", "0.1,0,0.04"}},
        {"clay_circle",
         {"assets/scenes/clay.json", "--trajectory", "assets/trajectories/circle.csv",
          "--world-scale", "1", "--world-origin", "0,0,0.095"}},
        {"platform_shell_twist",
         {"assets/scenes/platform.json", "--tool", "shell", "--trajectory",
          "assets/trajectories/twist.csv", "--world-scale", "1", "--world-origin",
          "0.043,0.2,-0.1"}},
        {"assembly_seat_right_leg",
         {"assets/scenes/assembly.json", "--trajectory", "assets/trajectories/seat_right_leg.csv",
          "--calibrate"}},
        {"assembly_whole_robot",
         {"assets/scenes/assembly.json", "--trajectory", "assets/trajectories/whole_robot.csv",
          "--calibrate"}},
        {"snap_tour",
         {"assets/scenes/snap_box.json", "--trajectory", "assets/trajectories/snap_tour.csv",
          "--world-scale", "1", "--world-origin", "0,0,0", "--calibrate"}},
        {"platform_fe_press",
         {"assets/scenes/platform_fe.json", "--trajectory", press, "--world-scale", "1",
          "--world-origin", "0.1,0,0.04"}},
        {"platform_fe_p2_press",
         {"assets/scenes/platform_fe_p2.json", "--trajectory", press, "--world-scale", "1",
          "--world-origin", "0.1,0,0.04"}},
        {"block_fe_squeeze",
         {"assets/scenes/squeeze_block_fe.json", "--trajectory", "assets/trajectories/squeeze.csv",
          "--world-scale", "1", "--world-origin", "0,0,0", "--fe-grasp", "--fe-tool-radius",
          "0.002"}},
    };
    for (const char* tool : {"grab", "twist", "bend"}) {
      for (bool conserve : {false, true}) {
        GoldenRun run{std::string("clay_sculpt_") + tool + (conserve ? "_conserved" : ""),
                      {"assets/scenes/clay_sculpt.json", "--trajectory",
                       std::string("assets/trajectories/sculpt_") + tool + ".csv", "--world-origin",
                       "0,-0.038,0.0739", "--sculpt-radius", "0.03", "--sculpt-tool", tool}};
        if (conserve) run.arguments.push_back("--conserve-volume");
        r.push_back(run);
      }
    }
    for (const char* which : {"hard", "light"}) {
      r.push_back({std::string("clay_sculpt_pinch_") + which,
                   {"assets/scenes/clay_sculpt.json", "--trajectory",
                    std::string("assets/trajectories/sculpt_pinch_") + which + ".csv",
                    "--world-origin", "0,-0.038,0.0739", "--sculpt-radius", "0.03"}});
    }
    r.push_back(
        {"platform_fe_grab_twist",
         {"assets/scenes/platform_fe.json", "--trajectory", "assets/trajectories/grab_twist.csv",
          "--world-scale", "1", "--world-origin", "0.28,0,0.005", "--fe-grab"}});
    r.push_back(
        {"demo_press_board_faults",
         {"demo", "--trajectory", press, "--device", "board-sim", "--link-loss", "0.002",
          "--link-corruption", "0.002", "--link-seed", "3", "--unplug", "1.7", "--replug", "1.8"}});
    r.push_back(
        {"touch_place_sphere",
         {"assets/scenes/touch_box.json", "--trajectory", "assets/trajectories/touch_place.csv",
          "--world-scale", "1", "--world-origin", "0,0,0", "--calibrate", "--place", "sphere"}});
    return r;
  }();
  return runs;
}

const GoldenRun& FindGoldenRun(const std::string& name) {
  for (const GoldenRun& run : GoldenRuns())
    if (run.name == name) return run;
  throw std::out_of_range("no golden run named '" + name + "' (cli/golden_runs.cc)");
}

std::vector<std::string> GoldenRunArguments(const GoldenRun& run, const std::string& assets_dir) {
  const std::string prefix = "assets/";
  std::string dir = assets_dir;
  if (!dir.empty() && dir.back() != '/') dir += '/';
  std::vector<std::string> out;
  for (const std::string& a : run.arguments) {
    const std::size_t eq = a.find('=');
    const std::size_t at =
        a.rfind(prefix, 0) == 0 ? 0
        : eq != std::string::npos && a.compare(eq + 1, prefix.size(), prefix) == 0
            ? eq + 1
            : std::string::npos;
    out.push_back(at == std::string::npos ? a
                                          : a.substr(0, at) + dir + a.substr(at + prefix.size()));
  }
  return out;
}

ScriptedRunOptions GoldenRunOptions(const GoldenRun& run, const std::string& assets_dir) {
  ScriptedRunOptions options;
  CLI::App app("golden run " + run.name);
  AddRunCommandOptions(&app, &options);
  std::vector<std::string> args = GoldenRunArguments(run, assets_dir);
  std::vector<std::string> reversed(args.rbegin(), args.rend());  // CLI11 parses a reversed vector
  try {
    app.parse(reversed);
  } catch (const CLI::ParseError& e) {
    throw InputError("golden run '" + run.name + "': " + e.what());
  }
  return options;
}

}  // namespace spidarcad::app
