// The spidarcad window: GLFW + VTK + Dear ImGui. Shows the SPIDAR-G frame, its 8 strings
// coloured by tension and the cross grip, driven by the simulated device when no device is
// plugged in.
// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#pragma once

#include <string>

#include <CLI/CLI.hpp>

namespace spidarcad::app {

struct GuiOptions {
  int width = 1280;              // window size in pixels
  int height = 800;
  std::string screenshot;        // when set: render, write this PNG and exit
  int frames = 0;                // when > 0: exit after this many frames
  std::string device = "simulated";
};

// True when an X display is available (DISPLAY set and reachable): VTK aborts without one.
bool DisplayAvailable();

// Opens the window and runs until closed. Returns the process exit status.
int RunGui(const GuiOptions& options);

// Adds the window options (--screenshot, --frames, --size) to the top-level app.
void AddGuiOptions(CLI::App& app, GuiOptions* options);

}  // namespace spidarcad::app
