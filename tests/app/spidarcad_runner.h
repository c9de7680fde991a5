// Runs the built spidarcad executable for the app's CLI tests (SPIDARCAD_EXE and
// SPIDARCAD_TEST_OUTPUT_DIR are set by tests/CMakeLists.txt for app_tests).
// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#pragma once

#include <gtest/gtest.h>

#include <atomic>
#include <string>

#include "support/command_runner.h"

namespace spidarcad::test_support {

// Path of a file in the test output directory.
inline std::string TestOutputPath(const std::string& name) {
  return std::string(SPIDARCAD_TEST_OUTPUT_DIR) + "/" + name;
}

// Runs `env spidarcad args < input`; `env` is a prefix such as "env -u DISPLAY" (empty for
// none). The scratch files are named after the running test, `tag` and a call counter, so
// tests that ctest runs in parallel never share them.
inline CommandRun RunSpidarcad(const std::string& args, const std::string& input = "",
                               const std::string& tag = "run", const std::string& env = "") {
  static std::atomic<int> calls{0};
  const ::testing::TestInfo* test = ::testing::UnitTest::GetInstance()->current_test_info();
  std::string name = test != nullptr ? std::string(test->test_suite_name()) + "." + test->name()
                                     : std::string("no_test");
  for (char& c : name) {
    if (c == '/') c = '_';
  }
  const std::string command = (env.empty() ? "" : env + " ") + "'" + SPIDARCAD_EXE + "' " + args;
  return RunCommand(command, input,
                    TestOutputPath("cmd_" + name + "_" + tag + "_" + std::to_string(calls++)));
}

}  // namespace spidarcad::test_support
