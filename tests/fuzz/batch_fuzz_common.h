// The body of the `fk`, `ik` and `tension` batch harnesses: the input is the CSV fed on stdin
// to `spidarcad NAME --batch`, run in process through the CLI11 registration of the command
// (cli/commands.h), with stdout and stderr discarded. Bad lines end in an InputError (exit
// status 2) or a per-line "invalid" answer; nothing else may escape or crash.
// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#pragma once

#include <CLI/CLI.hpp>
#include <cstddef>
#include <cstdint>
#include <string>

#include "cli/cli_common.h"
#include "cli/commands.h"
#include "fuzz_support.h"

namespace spidarcad::fuzz {

inline int RunBatchHarness(const char* name, void (*register_command)(CLI::App&),
                           const std::uint8_t* data, std::size_t size) {
  // Lines past this many bytes add nothing but time (every line is solved on its own).
  constexpr std::size_t kMaxInput = 4096;
  const std::string input(reinterpret_cast<const char*>(data), std::min(size, kMaxInput));
  CLI::App app{"fuzz", "spidarcad"};
  register_command(app);
  std::string command = name;
  std::string batch = "--batch";
  std::string program = "spidarcad";
  char* argv[] = {program.data(), command.data(), batch.data(), nullptr};
  RedirectedStdio stdio(input);
  try {
    app.parse(3, argv);
  } catch (const app::CommandExit&) {
  } catch (const app::InputError&) {
  }
  return 0;
}

}  // namespace spidarcad::fuzz
