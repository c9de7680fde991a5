// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
// `spidarcad __worker --parent PID`: the hidden subcommand that runs TetGen, CGAL or CHOLMOD for a
// window job in a child process (scene/worker_process.h). Not listed in --help: spidarcad starts
// it with a socket on stdin (and a factor request's shared memory as fd kSharedFd); run by hand (a
// terminal on stdin, or without its arguments) it refuses.
#include <sys/prctl.h>
#include <unistd.h>

#include <csignal>
#include <cstdio>
#include <cstdlib>
#include <string>

#include "cli/cli_common.h"
#include "cli/commands.h"
#include "scene/worker_process.h"

namespace spidarcad::app {

int RunWorkerCommand(int argc, char** argv) {
  const auto refuse = [](const char* why) {
    std::fprintf(stderr,
                 "spidarcad: %s is internal (spidarcad starts it for a cancellable library call); "
                 "%s\n",
                 kWorkerCommand, why);
    return kExitBadInput;
  };
  if (argc != 4 || std::string(argv[2]) != "--parent")
    return refuse("it takes exactly --parent PID");
  char* end = nullptr;
  const long parent = std::strtol(argv[3], &end, 10);
  if (end == argv[3] || *end != '\0' || parent <= 1) return refuse("--parent needs a process id");
  if (isatty(0) || isatty(1)) return refuse("its input must be the socket spidarcad gives it");
  // Die with the parent (the job's thread waits for this process, so its end means the
  // parent's); the parent may already have gone before this call.
  prctl(PR_SET_PDEATHSIG, SIGKILL);
  if (getppid() != static_cast<pid_t>(parent)) return refuse("its parent is gone");
  std::fflush(stdout);
  return RunWorker(0, 0, kSharedFd);
}

}  // namespace spidarcad::app
