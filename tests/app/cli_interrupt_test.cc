// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
// Issue 15: the CLI stops cleanly on Ctrl+C without half-written output files. `spidarcad fem`,
// `spidarcad run` and `spidarcad mesh` (inside TetGen and inside CGAL Mesh_3, which poll
// nothing) are started as child processes, sent SIGINT while they work, and must end with status
// 130, leave a previous --out file as it was and leave no temporary beside it
// (cli/interrupt_output.h, cli/mesh_command.cc).
#include <fcntl.h>
#include <gtest/gtest.h>
#include <signal.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <functional>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include "spidarcad_runner.h"

extern char** environ;

namespace spidarcad::app {
namespace {

namespace fs = std::filesystem;
using Clock = std::chrono::steady_clock;

std::string Read(const fs::path& path) {
  std::ifstream in(path);
  std::stringstream s;
  s << in.rdbuf();
  return s.str();
}

// A fresh directory for one test's files.
fs::path FreshDir(const std::string& name) {
  const fs::path dir = test_support::TestOutputPath("interrupt_" + name);
  fs::remove_all(dir);
  fs::create_directories(dir);
  return dir;
}

// Starts spidarcad with `args`, stdout and stderr to files in `dir`; SIGINT default.
pid_t Start(const std::vector<std::string>& args, const fs::path& dir) {
  std::vector<std::string> all = {SPIDARCAD_EXE};
  all.insert(all.end(), args.begin(), args.end());
  std::vector<char*> argv;
  for (std::string& a : all) argv.push_back(a.data());
  argv.push_back(nullptr);
  posix_spawn_file_actions_t actions;
  posix_spawn_file_actions_init(&actions);
  posix_spawn_file_actions_addopen(&actions, 0, "/dev/null", O_RDONLY, 0);
  posix_spawn_file_actions_addopen(&actions, 1, (dir / "stdout.txt").c_str(),
                                   O_WRONLY | O_CREAT | O_TRUNC, 0644);
  posix_spawn_file_actions_addopen(&actions, 2, (dir / "stderr.txt").c_str(),
                                   O_WRONLY | O_CREAT | O_TRUNC, 0644);
  posix_spawnattr_t attr;
  posix_spawnattr_init(&attr);
  sigset_t none, all_signals;
  sigemptyset(&none);
  sigfillset(&all_signals);
  posix_spawnattr_setsigmask(&attr, &none);
  posix_spawnattr_setsigdefault(&attr, &all_signals);
  posix_spawnattr_setflags(&attr, POSIX_SPAWN_SETSIGMASK | POSIX_SPAWN_SETSIGDEF);
  pid_t pid = -1;
  const int rc = posix_spawn(&pid, SPIDARCAD_EXE, &actions, &attr, argv.data(), environ);
  posix_spawn_file_actions_destroy(&actions);
  posix_spawnattr_destroy(&attr);
  EXPECT_EQ(rc, 0);
  return rc == 0 ? pid : -1;
}

int Wait(pid_t pid) {
  int status = 0;
  while (waitpid(pid, &status, 0) < 0 && errno == EINTR) {
  }
  return status;
}

// Waits (up to 120 s) until `ready()` or the process ended; true when ready.
template <typename F>
bool WaitUntil(pid_t pid, F ready) {
  const Clock::time_point t0 = Clock::now();
  while (Clock::now() - t0 < std::chrono::seconds(120)) {
    if (ready()) return true;
    int status = 0;
    if (waitpid(pid, &status, WNOHANG) == pid) {
      ADD_FAILURE() << "the command ended before it could be interrupted (status " << status << ")";
      return false;
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
  }
  return false;
}

// True once process `pid` catches SIGINT (its handler is installed: /proc/PID/status SigCgt).
bool CatchesSigint(pid_t pid) {
  std::ifstream status("/proc/" + std::to_string(pid) + "/status");
  for (std::string line; std::getline(status, line);) {
    if (line.rfind("SigCgt:", 0) == 0)
      return (std::stoull(line.substr(7), nullptr, 16) >> (SIGINT - 1)) & 1u;
  }
  return false;
}

std::vector<std::string> FilesIn(const fs::path& dir) {
  std::vector<std::string> names;
  for (const auto& e : fs::directory_iterator(dir)) names.push_back(e.path().filename().string());
  return names;
}

void ExpectInterruptedCleanly(int status, const fs::path& dir, const fs::path& out,
                              const std::vector<std::string>& expected_files) {
  ASSERT_TRUE(WIFEXITED(status)) << "killed by signal " << WTERMSIG(status);
  EXPECT_EQ(WEXITSTATUS(status), 130) << Read(dir / "stderr.txt");
  EXPECT_NE(Read(dir / "stderr.txt").find("interrupted (Ctrl+C)"), std::string::npos);
  EXPECT_EQ(Read(out), "old\n") << "the previous output was changed";
  std::vector<std::string> files = FilesIn(dir);
  std::sort(files.begin(), files.end());
  EXPECT_EQ(files, expected_files) << "a temporary was left";
}

TEST(CliInterrupt, FemStopsWithoutAHalfWrittenOutput) {
  const fs::path dir = FreshDir("fem");
  const fs::path out = dir / "platform.vtu";
  std::ofstream(out) << "old\n";
  const pid_t pid =
      Start({"fem", std::string(SPIDARCAD_SOURCE_DIR) + "/assets/scenes/platform.json",
             "--resolution", "0.004", "--fix=-1,-1,-1,0.0005,1,1", "--push", "0.29,0,0.01",
             "--disp", "0,0,-0.001", "--out", out.string()},
            dir);
  ASSERT_GT(pid, 0);
  // Inside the work (its handler is installed at the start; meshing and solving at 4 mm take
  // seconds).
  const bool working = WaitUntil(pid, [&] { return CatchesSigint(pid); });
  if (working) kill(pid, SIGINT);
  const int status = Wait(pid);
  ASSERT_TRUE(working);
  ExpectInterruptedCleanly(status, dir, out, {"platform.vtu", "stderr.txt", "stdout.txt"});
}

TEST(CliInterrupt, RunStopsWithoutAHalfWrittenOutput) {
  const fs::path dir = FreshDir("run");
  const fs::path trajectory = dir / "press.csv";
  const auto made = test_support::RunSpidarcad(
      "trajectory press --duration 3600 --rate 10 "
      "--out '" +
      trajectory.string() + "'");
  ASSERT_EQ(made.status, 0) << made.all();
  const fs::path out = dir / "result.csv";
  std::ofstream(out) << "old\n";
  const pid_t pid =
      Start({"run", "demo", "--trajectory", trajectory.string(), "--out", out.string()}, dir);
  ASSERT_GT(pid, 0);
  // Inside the tick loop: its temporary exists.
  const std::string partial = ".result.partial-" + std::to_string(pid) + ".csv";
  const bool working = WaitUntil(pid, [&] { return fs::exists(dir / partial); });
  if (working) kill(pid, SIGINT);
  const int status = Wait(pid);
  ASSERT_TRUE(working);
  ExpectInterruptedCleanly(status, dir, out,
                           {"press.csv", "result.csv", "stderr.txt", "stdout.txt"});
}

// `spidarcad mesh` of a 5 cm ball at `resolution` with --tets `tets`, sent SIGINT `after` s
// into the library call (`ready` says when it has been entered). The first Ctrl+C must end it
// at once: the line the command prints when the call returns (`result`) never comes (TetGen at
// 2 mm runs for about 40 s, CGAL's start-up at 0.8 mm for minutes).
void ExpectMeshStopsInsideTheLibrary(const std::string& tets, double resolution, double after,
                                     const std::string& result,
                                     const std::function<bool(pid_t, const fs::path&)>& ready) {
  const fs::path dir = FreshDir("mesh_" + tets);
  const fs::path scene = dir / "ball.json";
  std::ofstream(scene) << R"({"format": "spidarcad-scene", "version": 1, "units": "m",
      "solids": [{"name": "ball", "root": {"type": "sphere", "radius": 0.05}}]})";
  const fs::path out = dir / "ball.vtu";
  std::ofstream(out) << "old\n";
  char res[32];
  std::snprintf(res, sizeof res, "%g", resolution);
  const pid_t pid = Start({"mesh", scene.string(), "--tets", tets, "--resolution", res,
                           "--progress", "--out", out.string()},
                          dir);
  ASSERT_GT(pid, 0);
  const bool working = WaitUntil(pid, [&] { return ready(pid, dir); });
  std::this_thread::sleep_for(std::chrono::duration<double>(after));
  const Clock::time_point t0 = Clock::now();
  if (working) kill(pid, SIGINT);
  const int status = Wait(pid);
  const double seconds = std::chrono::duration<double>(Clock::now() - t0).count();
  ASSERT_TRUE(working);
  std::printf("mesh --tets %s: ended %.3f s after Ctrl+C\n", tets.c_str(), seconds);
  ExpectInterruptedCleanly(status, dir, out, {"ball.json", "ball.vtu", "stderr.txt", "stdout.txt"});
  EXPECT_EQ(Read(dir / "stdout.txt").find(result), std::string::npos)
      << "the library call returned before the command stopped:\n"
      << Read(dir / "stdout.txt");
}

TEST(CliInterrupt, MeshStopsAtOnceInsideTetgen) {
  // Inside TetGen: its progress line is up (the surface is meshed and checked first).
  ExpectMeshStopsInsideTheLibrary("tetgen", 0.002, 1.0, "tetgen -", [](pid_t, const fs::path& dir) {
    return Read(dir / "stderr.txt").find("tetgen") != std::string::npos;
  });
}

TEST(CliInterrupt, MeshStopsAtOnceInsideCgal) {
  // Inside CGAL's start-up: the handler is installed before the (quick) scene compilation, and
  // seeding at 0.8 mm alone takes far longer than the second waited.
  ExpectMeshStopsInsideTheLibrary(
      "cgal", 0.0008, 1.0, "cgal: ", [](pid_t pid, const fs::path&) { return CatchesSigint(pid); });
}

}  // namespace
}  // namespace spidarcad::app
