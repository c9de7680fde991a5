// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#include "support/command_runner.h"

#include <sys/wait.h>

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

}  // namespace spidarcad::test_support
