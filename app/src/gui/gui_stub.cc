// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
// Placeholder until the window lands (replaced by app_window.cc).
#include <cstdlib>
#include <iostream>

#include "gui/gui.h"

namespace spidarcad::app {
bool DisplayAvailable() { return std::getenv("DISPLAY") != nullptr; }
int RunGui(const GuiOptions&) {
  std::cerr << "spidarcad: the window is not built yet\n";
  return 1;
}
void AddGuiOptions(CLI::App& app, GuiOptions* options) {
  app.add_option("--screenshot", options->screenshot, "Render, save this PNG and exit");
}
}  // namespace spidarcad::app
