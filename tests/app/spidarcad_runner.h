// Runs the built spidarcad executable for the app's CLI tests (SPIDARCAD_EXE and
// SPIDARCAD_TEST_OUTPUT_DIR are set by tests/CMakeLists.txt for app_tests).
// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#pragma once

#include <string>

#include "support/command_runner.h"

namespace spidarcad::test_support {

// Path of a file in the test output directory.
inline std::string TestOutputPath(const std::string& name) {
  return std::string(SPIDARCAD_TEST_OUTPUT_DIR) + "/" + name;
}

// Runs `env spidarcad args < input`; `tag` names the scratch files in the output directory;
// `env` is a prefix such as "env -u DISPLAY" (empty for none).
inline CommandRun RunSpidarcad(const std::string& args, const std::string& input = "",
                               const std::string& tag = "run", const std::string& env = "") {
  const std::string command =
      (env.empty() ? "" : env + " ") + "'" + SPIDARCAD_EXE + "' " + args;
  return RunCommand(command, input, TestOutputPath("cmd_" + tag));
}

}  // namespace spidarcad::test_support
