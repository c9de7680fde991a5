// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
// `spidarcad run`'s option definitions, shared with the golden runs' list (cli/golden_runs.h),
// which parses each golden's arguments with them.
#pragma once

#include <CLI/CLI.hpp>

#include "scene/scripted_run.h"

namespace spidarcad::app {

// The options of `spidarcad run` that make its ScriptedRunOptions (the scene, --trajectory,
// --device, --seed, --calibration, --frame/--pole, AddScriptedRunOptions, --save, --export),
// written into *run (which must outlive the parse): all of run's options but --out and
// --progress (cli/run_command.cc).
void AddRunCommandOptions(CLI::App* command, ScriptedRunOptions* run);

}  // namespace spidarcad::app
