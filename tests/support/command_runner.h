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

// Starts `program_and_args` (a shell command line, e.g. "'exe' mesh 'a.json' --progress") in the
// background with its stderr in `err_path`, sends it one SIGINT as soon as that file holds
// `marker` (or after `wait_s` seconds without it), and SIGKILL if it is still running `kill_s`
// seconds after the SIGINT. Returns its exit status as the shell saw it (130 after a clean
// Ctrl+C, 137 when killed) in `status`, its stdout in `out` and the text of err_path in `err`.
// Every process the script starts writes to the scratch files, and the guard that would send
// SIGKILL ends with it, so nothing holds the test's own output open afterwards (ctest waits
// for that).
CommandRun InterruptOnceShown(const std::string& program_and_args, const std::string& err_path,
                              const std::string& marker, const std::string& scratch_prefix,
                              int wait_s = 300, int kill_s = 120);

// Whole contents of a file ("" when it cannot be read).
std::string ReadWholeFile(const std::string& path);

}  // namespace spidarcad::test_support
