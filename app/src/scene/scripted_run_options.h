// The command-line options of a scripted run that `spidarcad run` and the window's
// `--clock virtual` share (scene/scripted_run.h): the tool, hand, calibration, world map, FE,
// sculpt and board-sim link-fault options, registered once so that both spell and check them
// alike. Each command adds its own SCENE, --trajectory, --out, --device, --seed, --frame/--pole
// and --calibration.
// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#pragma once

#include <CLI/CLI.hpp>
#include <vector>

#include "scene/scripted_run.h"

namespace spidarcad::app {

// Adds --hand, --calibrate, --tool, --stiffness, --damping, --friction, --world-scale,
// --world-origin, --max-duration, --fe-grab, --fe-grasp, --fe-tool-radius, --sculpt-tool,
// --sculpt-radius,
// --conserve-volume, --link-loss, --link-corruption, --link-seed, --unplug and --replug to
// `command`, writing into *options (which must outlive the parse). Returns the options added,
// so that a caller can make them depend on another (the window: on --clock).
std::vector<CLI::Option*> AddScriptedRunOptions(CLI::App& command, ScriptedRunOptions* options);

}  // namespace spidarcad::app
