// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#include "cli/commands.h"

namespace spidarcad::app {
void RegisterFkCommand(CLI::App& app) {
  app.add_subcommand("fk", "(not yet implemented)");
}
}  // namespace spidarcad::app
namespace spidarcad::app {
void RegisterIkCommand(CLI::App& app) { app.add_subcommand("ik", "(not yet implemented)"); }
}  // namespace spidarcad::app
