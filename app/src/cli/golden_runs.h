// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
// The golden runs: every `spidarcad run` whose CSV is frozen in tests/golden/<name>.csv, with its
// exact options, in one list. The regression test (tests/app/regression_test.cc) runs each
// through the CLI and compares it with its golden; the tick table (cli/report_tick.h, `spidarcad
// report --only tick`, bench/app_scene_tick_bench) drives each through ScriptedRun and times
// exactly the ticks it runs. Neither keeps a second copy of the options.
#pragma once

#include <string>
#include <vector>

#include "scene/scripted_run.h"

namespace spidarcad::app {

// One golden run.
struct GoldenRun {
  // The golden's name: tests/golden/<name>.csv.
  std::string name;
  // `spidarcad run`'s arguments after "run" and before --out, one per element; a path into the
  // source tree's assets is written "assets/..." (GoldenRunArguments makes it absolute).
  std::vector<std::string> arguments;
};

// Every golden run, in the order of tests/app/regression_test.cc.
const std::vector<GoldenRun>& GoldenRuns();

// The golden run called `name`. Throws std::out_of_range naming it when there is none.
const GoldenRun& FindGoldenRun(const std::string& name);

// The run's arguments with each "assets/..." argument (and each "...=assets/..." value) made a
// path under `assets_dir` (the directory that holds scenes/ and trajectories/).
std::vector<std::string> GoldenRunArguments(const GoldenRun& run, const std::string& assets_dir);

// The ScriptedRunOptions `spidarcad run` makes of the run's arguments (parsed with run's own
// option definitions: the scene, --trajectory, --device, --seed and AddScriptedRunOptions), assets
// under `assets_dir`. Throws InputError when the arguments do not parse.
ScriptedRunOptions GoldenRunOptions(const GoldenRun& run, const std::string& assets_dir);

}  // namespace spidarcad::app
