// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
// Tick time per scene type: the compute time of HapticLoop::Step (calibration, FK, the scene's
// force fields, safety, tension solve) on the simulated SPIDAR-G gripped by the simulated hand,
// as in `spidarcad run`, over N ticks (default 20 000; the trajectory repeats). Prints p50,
// p99, p99.9 and max per scene as a markdown table for the README. The measurement lives in
// app/src/cli/report_tick.cc (shared with `spidarcad report`, section "tick").
//   build/bench/app_scene_tick_bench [--ticks N]     (--help: what it measures)
// Scenes: empty; demo (plane wall + spring); implicit proxy (assets/scenes/platform.json, two
// ProxyFields, press onto the plate); six-DOF shell tool (platform.json, cross-grip point shell
// against the union of both solids, twist against the wall); FE contact (platform.json meshed
// at 12 mm, FeTouchField on the steel part, the hand driving the tool sphere into the plate;
// one row over every tick, one over the ticks where the field holds k = 16 contact nodes, and
// the k reached is printed; see MeasureFe); sculpt (assets/scenes/clay.json meshed at 3 mm,
// SculptToolField during a grab stroke the closed grip drags up and down; the main-thread stroke
// update, SculptSession::Step, runs every 16th tick outside the timing, as the window does at
// 60 Hz); assembly (assets/scenes/assembly.json, the AssemblyField of the toy robot, X_WD
// identity, the device calibrated at start-up as the window does, the hand following
// assets/trajectories/seat_right_leg.csv: grasp, carry, seat the right leg; one row over every
// tick, one over the ticks while a part is carried).
#include <cerrno>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <string>
#include <vector>

#include "cli/report_tick.h"

namespace {

// What this program measures (its --help).
constexpr const char* kDescription =
    "Tick time per scene type: the compute time of HapticLoop::Step (calibration, FK, the scene's\n"
    "force fields, safety, tension solve) on the simulated SPIDAR-G gripped by the simulated "
    "hand,\n"
    "as in `spidarcad run`, over N ticks (default 20 000; the trajectory repeats). Prints p50,\n"
    "p99, p99.9 and max per scene as a markdown table for the README. The measurement lives in\n"
    "app/src/cli/report_tick.cc (shared with `spidarcad report`, section \"tick\").\n"
    "  build/bench/app_scene_tick_bench [--ticks N]     (--help: what it measures)\n"
    "Scenes: empty; demo (plane wall + spring); implicit proxy (assets/scenes/platform.json, two\n"
    "ProxyFields, press onto the plate); six-DOF shell tool (platform.json, cross-grip point "
    "shell\n"
    "against the union of both solids, twist against the wall); FE contact (platform.json meshed\n"
    "at 12 mm, FeTouchField on the steel part, the hand driving the tool sphere into the plate;\n"
    "one row over every tick, one over the ticks where the field holds k = 16 contact nodes, and\n"
    "the k reached is printed; see MeasureFe); sculpt (assets/scenes/clay.json meshed at 3 mm,\n"
    "SculptToolField during a grab stroke the closed grip drags up and down; the main-thread "
    "stroke\n"
    "update, SculptSession::Step, runs every 16th tick outside the timing, as the window does at\n"
    "60 Hz); assembly (assets/scenes/assembly.json, the AssemblyField of the toy robot, X_WD\n"
    "identity, the device calibrated at start-up as the window does, the hand following\n"
    "assets/trajectories/seat_right_leg.csv: grasp, carry, seat the right leg; one row over every\n"
    "tick, one over the ticks while a part is carried).\n"
    "\n"
    "Options:\n"
    "  --ticks N   ticks per scene, N >= 1000 (default 20000; the assembly trajectory is 18400\n"
    "              ticks long: with fewer the part is never carried to its seat)\n"
    "  --help      this text\n"
    "This program is not a Google Benchmark: --benchmark_* flags are not taken.";

// Parses a tick count (an integer >= 1000); false when `text` is not one.
bool ParseTicks(const char* text, long* ticks) {
  errno = 0;
  char* end = nullptr;
  const long value = std::strtol(text, &end, 10);
  if (errno != 0 || end == text || *end != '\0' || value < 1000) return false;
  *ticks = value;
  return true;
}

}  // namespace

int main(int argc, char** argv) {
  long ticks = 20000;
  for (int i = 1; i < argc; ++i) {
    const std::string arg = argv[i];
    if (arg == "--help" || arg == "-h") {
      std::printf("%s\n", kDescription);
      return 0;
    }
    const char* value = nullptr;
    if (arg == "--ticks" && i + 1 < argc) {
      value = argv[++i];
    } else if (arg.rfind("--ticks=", 0) == 0) {
      value = argv[i] + 8;
    }
    if (value != nullptr) {
      if (!ParseTicks(value, &ticks)) {
        std::fprintf(stderr, "%s: --ticks: '%s' is not an integer >= 1000\n", argv[0], value);
        return 2;
      }
      continue;
    }
    std::fprintf(stderr, "%s: unknown argument '%s' (this program takes --ticks N and --help)\n",
                 argv[0], argv[i]);
    return 2;
  }
  const std::vector<spidarcad::app::SceneTickRow> rows = spidarcad::app::MeasureSceneTicks(ticks);
  std::printf("HapticLoop::Step compute time, %ld ticks per scene, simulated device + hand\n\n",
              ticks);
  std::printf(
      "| scene | p50 µs | p99 µs | p99.9 µs | max µs | mean µs |\n|---|---|---|---|---|---|\n");
  for (const auto& r : rows) {
    std::printf("| %s | %.1f | %.1f | %.1f | %.1f | %.1f |\n", r.name.c_str(), r.p50, r.p99, r.p999,
                r.max, r.mean);
  }
  std::printf(
      "\nThe same ticks in thread CPU time (CLOCK_THREAD_CPUTIME_ID: preemption by other "
      "processes excluded)\n\n| scene | p50 µs | p99 µs | p99.9 µs | max µs "
      "|\n|---|---|---|---|---|\n");
  for (const auto& r : rows) {
    std::printf("| %s | %.1f | %.1f | %.1f | %.1f |\n", r.name.c_str(), r.cpu_p50, r.cpu_p99,
                r.cpu_p999, r.cpu_max);
  }
  std::printf("\n");
  for (const auto& r : rows) {
    if (!r.note.empty()) std::printf("%s\n", r.note.c_str());
  }
  return 0;
}
