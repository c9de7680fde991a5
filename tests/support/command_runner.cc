// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#include "support/command_runner.h"

#include <sys/wait.h>

#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <sstream>

namespace spidarcad::test_support {

std::string ReadWholeFile(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  std::stringstream contents;
  contents << in.rdbuf();
  return contents.str();
}

CommandRun RunCommand(const std::string& command, const std::string& input,
                      const std::string& scratch_prefix) {
  const std::string in_path = scratch_prefix + ".in";
  const std::string out_path = scratch_prefix + ".out";
  const std::string err_path = scratch_prefix + ".err";
  std::ofstream(in_path, std::ios::binary) << input;
  const std::string shell =
      command + " < '" + in_path + "' > '" + out_path + "' 2> '" + err_path + "'";
  const int raw = std::system(shell.c_str());
  CommandRun run;
  run.status = (raw != -1 && WIFEXITED(raw)) ? WEXITSTATUS(raw) : -1;
  run.out = ReadWholeFile(out_path);
  run.err = ReadWholeFile(err_path);
  return run;
}

CommandRun InterruptOnceShown(const std::string& program_and_args, const std::string& err_path,
                              const std::string& marker, const std::string& scratch_prefix,
                              int wait_s, int kill_s) {
  std::remove(err_path.c_str());
  const std::string polls = std::to_string(wait_s * 20);
  // The braces give the whole script the scratch files RunCommand redirects; the guard's trap
  // ends its sleep when the guard is told to stop.
  const std::string script =
      "{ " + program_and_args + " 2> '" + err_path + "' & pid=$!; i=0; while ! grep -q '" + marker +
      "' '" + err_path + "' 2>/dev/null && [ $i -lt " + polls +
      " ]; do sleep 0.05; i=$((i+1)); done; kill -INT $pid; "
      "( sleep " +
      std::to_string(kill_s) +
      " & s=$!; trap 'kill $s; exit 0' TERM; wait $s; kill -KILL $pid 2>/dev/null ) & guard=$!; "
      "wait $pid; status=$?; kill $guard 2>/dev/null; wait $guard 2>/dev/null; "
      "echo status=$status; }";
  CommandRun run = RunCommand(script, "", scratch_prefix);
  const auto at = run.out.rfind("status=");
  if (at != std::string::npos) {
    run.status = std::atoi(run.out.c_str() + at + 7);
  }
  run.err = ReadWholeFile(err_path);
  return run;
}

}  // namespace spidarcad::test_support
