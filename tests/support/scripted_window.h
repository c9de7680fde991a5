// Helpers of the window tests in app_tests: whether there is an X display, a fresh scratch folder
// under the test output directory, and the options of a scripted window (ideal device, a fixed
// size, frames driven by the test).
// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#pragma once

#include <cstdlib>
#include <filesystem>
#include <string>

#include "gui/gui.h"
#include "support/paths.h"
#include "support/scoped_env.h"

namespace spidarcad::test_support {

// True when $DISPLAY names a display (the window tests skip themselves otherwise).
inline bool HaveDisplay() {
  const char* display = std::getenv("DISPLAY");
  return display != nullptr && display[0] != '\0';
}

// An empty folder SPIDARCAD_TEST_OUTPUT_DIR/name (whatever was there is removed).
inline std::filesystem::path FreshScratchDir(const std::string& name) {
  const std::filesystem::path dir = std::filesystem::path(SPIDARCAD_TEST_OUTPUT_DIR) / name;
  std::filesystem::remove_all(dir);
  std::filesystem::create_directories(dir);
  return dir;
}

// A fresh scratch folder for one window test (FreshScratchDir), with the window's settings
// ($XDG_CONFIG_HOME) and recovery files ($SPIDARCAD_RECOVERY_DIR) pointed into it while it lives.
class WindowScratch {
 public:
  explicit WindowScratch(const std::string& name)
      : dir(FreshScratchDir(name)),
        config_("XDG_CONFIG_HOME", (dir / "config").c_str()),
        recovery_("SPIDARCAD_RECOVERY_DIR", (dir / "recovery").c_str()) {}
  const std::filesystem::path dir;  // the folder

 private:
  ScopedEnv config_, recovery_;
};

// Options of a scripted 1000×700 window on `scene` with the ideal device; the test calls Frame.
inline app::GuiOptions ScriptedWindowOptions(const std::string& scene) {
  app::GuiOptions options;
  options.scene = scene;
  options.device = "ideal";
  options.width = 1000;
  options.height = 700;
  options.frames = 1 << 30;
  return options;
}

}  // namespace spidarcad::test_support
