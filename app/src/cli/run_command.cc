// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
// Placeholder: the subcommand is being written.
#include "cli/commands.h"

namespace spidarcad::app {
void RegisterRunCommand(CLI::App& app) {
  app.add_subcommand("run", "(not yet available)")->group("");
}
}  // namespace spidarcad::app
