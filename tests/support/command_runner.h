// Runs a program as a separate process for the CLI tests: feeds stdin, captures stdout, stderr
// and the exit status.
// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#pragma once

#include <string>

namespace spidarcad::test_support {

// What a process printed and how it ended.
struct CommandRun {
  int status = -1;  // exit status, -1 when it did not exit normally (signal)
  std::string out;  // standard output
  std::string err;  // standard error
  // stdout followed by stderr.
  std::string all() const { return out + err; }
};

// Runs `command` through /bin/sh with `input` on stdin. `scratch_prefix` names the temporary
// files (prefix.in, prefix.out, prefix.err) that hold the streams; they are left for inspection.
CommandRun RunCommand(const std::string& command, const std::string& input,
                      const std::string& scratch_prefix);

// Whole contents of a file ("" when it cannot be read).
std::string ReadWholeFile(const std::string& path);

}  // namespace spidarcad::test_support
