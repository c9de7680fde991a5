// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#include "cli/commands.h"

namespace spidarcad::app {
void RegisterTensionCommand(CLI::App& app) {
  app.add_subcommand("tension", "(not yet implemented)");
}
}  // namespace spidarcad::app
