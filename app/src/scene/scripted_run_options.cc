// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#include "scene/scripted_run_options.h"

namespace spidarcad::app {

std::vector<CLI::Option*> AddScriptedRunOptions(CLI::App& cmd, ScriptedRunOptions* options) {
  std::vector<CLI::Option*> added;
  added.push_back(cmd.add_option("--hand", options->hand,
                                 "Hand spring stiffness,damping [N/m,N·s/m] (default 300,20)")
                      ->delimiter(',')
                      ->expected(2));
  added.push_back(cmd.add_flag(
      "--calibrate", options->calibrate,
      "Calibrate the simulated device first (line fit on 24 jig poses, as the window) and read "
      "it through that fit; for scripts that must hit mm targets"));
  added.push_back(
      cmd.add_option("--tool", options->tool, "Scene files: tool model proxy (default) or shell"));
  added.push_back(cmd.add_option("--stiffness", options->stiffness,
                                 "Scene files: contact stiffness at the grip, N/m (default 1500; "
                                 "shell coupling min(K, 1000))"));
  added.push_back(
      cmd.add_option("--damping", options->damping,
                     "Scene files: proxy normal damping at the grip, N·s/m (default 1)"));
  added.push_back(cmd.add_option("--friction", options->friction,
                                 "Scene files: proxy friction static,dynamic (default 0.3,0.2)")
                      ->delimiter(',')
                      ->expected(2));
  added.push_back(cmd.add_option("--world-scale", options->world_scale,
                                 "Scene files: world metres per grip metre (default: fitted)"));
  added.push_back(
      cmd.add_option("--world-origin", options->world_origin,
                     "Scene files: world position of the device origin x,y,z, m (default: fitted)")
          ->delimiter(',')
          ->expected(3));
  added.push_back(cmd.add_option("--max-duration", options->max_duration,
                                 "Longest run accepted, s: the trajectory's last minus first time "
                                 "(default 3600; at most 1e7)"));
  added.push_back(cmd.add_flag("--fe-grab", options->fe_grab,
                               "Documents: FE models are grabbed by closing the grasp on them and "
                               "follow the grip rigidly (FE mode's grab) instead of being pushed"));
  added.push_back(cmd.add_flag("--fe-grasp", options->fe_grasp,
                               "Documents: FE models are squeezed between the pole tips "
                               "(two-point grasp contact, as FE mode's checkbox) instead of pushed "
                               "by the sphere on the grip centre"));
  added.push_back(cmd.add_option("--fe-tool-radius", options->fe_tool_radius,
                                 "Documents: the FE tool's physical radius, m on the part (W, "
                                 "not scaled by the world scale): the patch every FE push and "
                                 "grab covers (default 0.01)"));
  added.push_back(cmd.add_option("--sculpt-tool", options->sculpt_tool,
                                 "Documents: the tool of the sculpt objects' strokes: grab "
                                 "(default), twist, bend, push_pull or smooth"));
  added.push_back(
      cmd.add_option("--sculpt-radius", options->sculpt_radius,
                     "Documents: the sculpt tool's falloff radius, m (W; default 0.02)"));
  added.push_back(cmd.add_flag("--conserve-volume", options->conserve_volume,
                               "Documents: each sculpt stroke keeps the clay's enclosed volume"));
  added.push_back(cmd.add_option("--link-loss", options->link_loss,
                                 "board-sim: probability that a packet of the link (either "
                                 "direction) is lost, in [0, 1) (default 0)"));
  added.push_back(cmd.add_option("--link-corruption", options->link_corruption,
                                 "board-sim: probability that a packet arrives with 1..3 bits "
                                 "flipped, in [0, 1) (default 0)"));
  added.push_back(cmd.add_option("--link-seed", options->link_seed,
                                 "board-sim: seed of the link faults' draws (default: --seed)"));
  added.push_back(cmd.add_option("--unplug", options->unplug_at,
                                 "board-sim: pull the board's cable at this trajectory time, s")
                      ->type_name("T1"));
  added.push_back(cmd.add_option("--replug", options->replug_at,
                                 "board-sim: put the cable back at this trajectory time, s (after "
                                 "--unplug; the board power-cycles and the driver reconnects)")
                      ->type_name("T2"));
  return added;
}

}  // namespace spidarcad::app
