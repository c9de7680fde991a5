// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#include "cli/commands.h"

namespace spidarcad::app {
void RegisterCalibrateCommand(CLI::App& app) {
  app.add_subcommand("calibrate", "(not yet implemented)");
}
}  // namespace spidarcad::app
