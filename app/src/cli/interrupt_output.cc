// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#include "cli/interrupt_output.h"

#include <signal.h>
#include <unistd.h>

#include <atomic>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <iostream>
#include <system_error>

#include "cli/cli_common.h"

namespace spidarcad::app {
namespace {

// The SIGINT handler's state (one InterruptibleOutput at a time per process).
char g_partial[4096];             // the temporary to remove, "" for none
char g_message[256];              // printed on an immediate stop
std::atomic<int> g_mode{0};       // 0 none, 1 exit at once, 2 flag
std::atomic<bool> g_flag{false};  // kFlag: Ctrl+C seen
struct sigaction g_previous = {};
static_assert(std::atomic<int>::is_always_lock_free && std::atomic<bool>::is_always_lock_free,
              "the SIGINT handler uses these atomics");

void OnInterrupt(int) {
  if (g_mode.load() == 2 && !g_flag.load()) {
    g_flag.store(true);
    return;
  }
  // Only async-signal-safe calls from here on.
  if (g_partial[0] != '\0') unlink(g_partial);
  const ssize_t ignored = write(STDERR_FILENO, g_message, std::strlen(g_message));
  (void)ignored;
  _exit(130);
}

}  // namespace

InterruptibleOutput::InterruptibleOutput(const std::string& out, const char* command, Mode mode)
    : out_(out), command_(command) {
  const std::filesystem::path path(out);
  const std::string ext = path.extension().string();
  const std::string name = path.filename().string();
  temporary_ = (path.parent_path() / ("." + name.substr(0, name.size() - ext.size()) + ".partial-" +
                                      std::to_string(getpid()) + ext))
                   .string();
  if (temporary_.size() >= sizeof g_partial)
    throw InputError("--out '" + out + "': the path is too long");
  std::snprintf(g_message, sizeof g_message,
                "\nspidarcad %s: interrupted (Ctrl+C): stopped, nothing written\n", command);
  std::memcpy(g_partial, temporary_.c_str(), temporary_.size() + 1);
  g_flag.store(false);
  g_mode.store(mode == Mode::kFlag ? 2 : 1);
  struct sigaction action = {};
  action.sa_handler = OnInterrupt;
  sigemptyset(&action.sa_mask);
  sigaction(SIGINT, &action, &g_previous);
}

InterruptibleOutput::~InterruptibleOutput() {
  sigaction(SIGINT, &g_previous, nullptr);
  g_mode.store(0);
  g_partial[0] = '\0';
  if (!committed_) {
    std::error_code ec;
    std::filesystem::remove(temporary_, ec);
  }
}

bool InterruptibleOutput::interrupted() const { return g_flag.load(std::memory_order_relaxed); }

void InterruptibleOutput::Commit() {
  std::error_code ec;
  std::filesystem::rename(temporary_, out_, ec);
  if (ec) {
    throw InputError("--out '" + out_ + "': cannot move the finished file into place (" +
                     ec.message() + ")");
  }
  committed_ = true;
  g_partial[0] = '\0';
}

void InterruptibleOutput::Stop() const {
  std::cout.flush();
  std::cerr << "\nspidarcad " << command_ << ": interrupted (Ctrl+C): stopped, nothing written\n"
            << std::flush;
  throw CommandExit{130};
}

}  // namespace spidarcad::app
