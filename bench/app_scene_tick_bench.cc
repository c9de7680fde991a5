// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
// Tick time per scene type: the compute time of HapticLoop::Step (calibration, FK, the scene's
// force fields, safety, tension solve) on the simulated SPIDAR-G gripped by the simulated hand,
// as in `spidarcad run`, over N ticks (default 20 000; the trajectory repeats). Prints p50,
// p99, p99.9 and max per scene as a markdown table for the README. The measurement lives in
// app/src/cli/report_tick.cc (shared with `spidarcad report`, section "tick").
//   build/bench/app_scene_tick_bench [--ticks N] [--slowest N] [--warm-up N] [--normal]
//                                    [--no-lock]     (--help: what it measures)
// As the window's haptic runtime: the memory locked (mlockall when permitted) and the ticks on a
// SCHED_FIFO thread (when permitted); the CPU table adds page faults and context switches.
// Scenes: empty; demo (plane wall + spring); implicit proxy (assets/scenes/platform.json, two
// ProxyFields, press onto the plate); six-DOF shell tool (platform.json, cross-grip point shell
// against the union of both solids, twist against the wall; 196 points, and 2004 in a second row);
// FE contact (platform.json meshed
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
#include <utility>
#include <vector>

#include "cli/report_tick.h"
#include "spidarcad/haptics/realtime_memory.h"

namespace {

// What this program measures (its --help).
constexpr const char* kDescription =
    "Tick time per scene type: the compute time of HapticLoop::Step (calibration, FK, the scene's\n"
    "force fields, safety, tension solve) on the simulated SPIDAR-G gripped by the simulated "
    "hand,\n"
    "as in `spidarcad run`, over N ticks (default 20 000; the trajectory repeats). Prints p50,\n"
    "p99, p99.9 and max per scene as a markdown table for the README. The measurement lives in\n"
    "app/src/cli/report_tick.cc (shared with `spidarcad report`, section \"tick\").\n"
    "  build/bench/app_scene_tick_bench [--ticks N] [--slowest N] [--warm-up N] [--normal]\n"
    "                                   [--no-lock] [--repeat R]  (--help: what it measures)\n"
    "As the window's haptic runtime: the memory locked (mlockall when permitted) and the ticks\n"
    "on a SCHED_FIFO thread (when permitted); the CPU table adds page faults and context\n"
    "switches.\n"
    "Scenes: empty; demo (plane wall + spring); implicit proxy (assets/scenes/platform.json, two\n"
    "ProxyFields, press onto the plate); six-DOF shell tool (platform.json, cross-grip point "
    "shell\n"
    "against the union of both solids, twist against the wall; 196 points, and 2004 in a second\n"
    "row); FE contact (platform.json meshed\n"
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
    "  --warm-up N untimed ticks run first on the same loop (default 0)\n"
    "  --normal    measure on the main thread with normal scheduling (default: a thread of its\n"
    "              own at SCHED_FIFO 80 when permitted, as the window's haptic thread)\n"
    "  --no-lock   do not lock the process's memory (default: mlockall when permitted, as the\n"
    "              window's haptic runtime)\n"
    "  --slowest N also list the N slowest ticks of each scene (N <= 8) with their page faults\n"
    "              and context switches\n"
    "  --no-golden leave out the golden runs' rows (default: one row per golden run of\n"
    "              tests/golden, every tick of its `spidarcad run`, app/src/cli/golden_runs.cc)\n"
    "  --golden-ticks N  time at most N ticks of each golden run (default: all of them)\n"
    "  --repeat R  run everything R times (R >= 1, default 1) and add a table of the repeatable\n"
    "              tick time: per tick, the least thread CPU time over the R runs. The ticks\n"
    "              are deterministic, so a tick slow in every run is slow by its own work, and\n"
    "              time the machine charged to one run's tick (interrupts, the hypervisor) is\n"
    "              not in it. The tables above it are the first run's.\n"
    "  --help      this text\n"
    "This program is not a Google Benchmark: --benchmark_* flags are not taken.";

// Parses an integer >= `least`; false when `text` is not one.
bool ParseCount(const char* text, long least, long* count) {
  errno = 0;
  char* end = nullptr;
  const long value = std::strtol(text, &end, 10);
  if (errno != 0 || end == text || *end != '\0' || value < least) return false;
  *count = value;
  return true;
}

// The repeatable tick time of every row present in all runs (cli/report_tick.h RepeatableTicks).
void PrintRepeatable(const std::vector<std::vector<spidarcad::app::SceneTickRow>>& runs) {
  std::printf(
      "\nRepeatable tick time: per tick, the least thread CPU time over %zu runs (ticks are "
      "deterministic; time charged to one run's tick by the machine drops out), µs. Last "
      "columns: each run's own maximum, and the slowest repeatable tick's time in each run.\n\n"
      "| scene | ticks in every run | p50 | p99.9 | max | slowest tick | single-run maxima | "
      "that tick per run |\n|---|---|---|---|---|---|---|---|\n",
      runs.size());
  std::vector<const std::vector<spidarcad::app::SceneTickRow>*> all;
  for (const auto& run : runs) all.push_back(&run);
  for (const spidarcad::app::RepeatableRow& rep : spidarcad::app::RepeatableRows(all)) {
    const spidarcad::app::SceneTickRow& row = rep.row;
    std::string maxima, at_tick;
    const long slow = row.slowest.empty() ? -1 : row.slowest.front().index;
    for (const auto* r : rep.runs) {
      char cell[48];
      std::snprintf(cell, sizeof cell, "%s%.1f", maxima.empty() ? "" : ", ", r->cpu_max);
      maxima += cell;
      double t = -1.0;
      for (std::size_t i = 0; i < r->cpu.size(); ++i)
        if (r->TickOf(i) == slow) t = r->cpu[i];
      std::snprintf(cell, sizeof cell, "%s%.1f", at_tick.empty() ? "" : ", ", t);
      at_tick += cell;
    }
    std::printf("| %s | %zu | %.1f | %.1f | %.1f | %ld | %s | %s |\n", row.name.c_str(),
                row.cpu.size(), row.cpu_p50, row.cpu_p999, row.cpu_max, slow, maxima.c_str(),
                at_tick.c_str());
  }
}

}  // namespace

int main(int argc, char** argv) {
  spidarcad::app::SceneTickOptions options;
  options.realtime = true;
  bool lock_memory = true, golden = true;
  long slowest = 0, golden_ticks = 0, repeat = 1;
  for (int i = 1; i < argc; ++i) {
    const std::string arg = argv[i];
    if (arg == "--help" || arg == "-h") {
      std::printf("%s\n", kDescription);
      return 0;
    }
    // --name N or --name=N.
    auto value_of = [&](const char* name) -> const char* {
      const std::string prefix = std::string(name) + "=";
      if (arg == name && i + 1 < argc) return argv[++i];
      if (arg.rfind(prefix, 0) == 0) return argv[i] + prefix.size();
      return nullptr;
    };
    if (arg == "--normal") {
      options.realtime = false;
      continue;
    }
    if (arg == "--no-lock") {
      lock_memory = false;
      continue;
    }
    if (arg == "--no-golden") {
      golden = false;
      continue;
    }
    if (const char* value = value_of("--golden-ticks")) {
      if (!ParseCount(value, 1, &golden_ticks)) {
        std::fprintf(stderr, "%s: --golden-ticks: '%s' is not an integer >= 1\n", argv[0], value);
        return 2;
      }
      continue;
    }
    if (const char* value = value_of("--repeat")) {
      if (!ParseCount(value, 1, &repeat)) {
        std::fprintf(stderr, "%s: --repeat: '%s' is not an integer >= 1\n", argv[0], value);
        return 2;
      }
      continue;
    }
    if (const char* value = value_of("--ticks")) {
      if (!ParseCount(value, 1000, &options.ticks)) {
        std::fprintf(stderr, "%s: --ticks: '%s' is not an integer >= 1000\n", argv[0], value);
        return 2;
      }
    } else if (const char* value = value_of("--warm-up")) {
      if (!ParseCount(value, 0, &options.warm_up_ticks)) {
        std::fprintf(stderr, "%s: --warm-up: '%s' is not an integer >= 0\n", argv[0], value);
        return 2;
      }
    } else if (const char* value = value_of("--slowest")) {
      if (!ParseCount(value, 0, &slowest) || slowest > spidarcad::app::kSlowestTicks) {
        std::fprintf(stderr, "%s: --slowest: '%s' is not an integer in 0..%d\n", argv[0], value,
                     spidarcad::app::kSlowestTicks);
        return 2;
      }
    } else {
      std::fprintf(
          stderr,
          "%s: unknown argument '%s' (this program takes --ticks N, --warm-up N, "
          "--slowest N, --normal, --no-lock, --no-golden, --golden-ticks N, --repeat R and "
          "--help)\n",
          argv[0], argv[i]);
      return 2;
    }
  }
  // As the window's haptic runtime: the process's memory locked before the first tick.
  const spidarcad::haptics::MemoryLockResult lock = lock_memory
                                                        ? spidarcad::haptics::LockProcessMemory()
                                                        : spidarcad::haptics::MemoryLockResult{};
  std::vector<std::vector<spidarcad::app::SceneTickRow>> runs(static_cast<std::size_t>(repeat));
  for (auto& run : runs) {
    run = spidarcad::app::MeasureSceneTicks(options);
    if (golden)
      for (auto& r : spidarcad::app::MeasureGoldenRunTicks(options, golden_ticks))
        run.push_back(std::move(r));
  }
  const std::vector<spidarcad::app::SceneTickRow>& rows = runs.front();
  std::printf("HapticLoop::Step compute time, %ld ticks per scene, simulated device + hand\n",
              options.ticks);
  std::printf("measuring thread: %s; %s\n\n", rows.empty() ? "-" : rows.front().scheduling.c_str(),
              lock_memory ? lock.message.c_str() : "memory lock: not requested (--no-lock)");
  std::printf(
      "| scene | p50 µs | p99 µs | p99.9 µs | max µs | mean µs |\n|---|---|---|---|---|---|\n");
  for (const auto& r : rows) {
    std::printf("| %s | %.1f | %.1f | %.1f | %.1f | %.1f |\n", r.name.c_str(), r.p50, r.p99, r.p999,
                r.max, r.mean);
  }
  std::printf(
      "\nThe same ticks in thread CPU time (CLOCK_THREAD_CPUTIME_ID: preemption by other "
      "processes excluded), with the page faults (minor/major) and involuntary context switches "
      "the kernel counted on the thread during the timed ticks (getrusage(RUSAGE_THREAD))\n\n"
      "| scene | p50 µs | p99 µs | p99.9 µs | max µs | ticks > 200 µs | faults | ticks with a "
      "fault | involuntary switches |\n|---|---|---|---|---|---|---|---|---|\n");
  for (const auto& r : rows) {
    long over = 0, over_switched = 0, over_faulted = 0;
    for (std::size_t i = 0; i < r.cpu.size(); ++i) {
      if (r.cpu[i] <= 200.0) continue;
      ++over;
      if (i < r.counters.size()) {
        over_switched += r.counters[i].involuntary_switches > 0;
        over_faulted += r.counters[i].minor_faults + r.counters[i].major_faults > 0;
      }
    }
    std::printf(
        "| %s | %.1f | %.1f | %.1f | %.1f | %ld (%ld switched, %ld faulted) | %ld/%ld | "
        "%ld | %ld |\n",
        r.name.c_str(), r.cpu_p50, r.cpu_p99, r.cpu_p999, r.cpu_max, over, over_switched,
        over_faulted, r.minor_faults, r.major_faults, r.ticks_with_faults, r.involuntary_switches);
  }
  std::printf("\n");
  for (const auto& r : rows) {
    if (!r.note.empty()) std::printf("%s\n", r.note.c_str());
  }
  if (slowest > 0) {
    std::printf("\nThe %ld slowest ticks of each scene by thread CPU time\n\n", slowest);
    std::printf(
        "| scene | tick | CPU µs | wall µs | minor faults | major faults | voluntary switches | "
        "involuntary switches |\n|---|---|---|---|---|---|---|---|\n");
    for (const auto& r : rows) {
      for (long i = 0; i < slowest && i < static_cast<long>(r.slowest.size()); ++i) {
        const spidarcad::app::SlowTick& t = r.slowest[i];
        std::printf("| %s | %ld | %.1f | %.1f | %u | %u | %u | %u |\n", r.name.c_str(), t.index,
                    t.cpu, t.us, t.counters.minor_faults, t.counters.major_faults,
                    t.counters.voluntary_switches, t.counters.involuntary_switches);
      }
    }
    std::printf("\nThe first ticks with a page fault (index: minor/major faults, CPU µs)\n\n");
    for (const auto& r : rows) {
      std::printf("- %s:", r.name.c_str());
      int shown = 0;
      for (std::size_t i = 0; i < r.counters.size() && shown < 12; ++i) {
        const spidarcad::app::TickCounters& c = r.counters[i];
        if (c.minor_faults + c.major_faults == 0) continue;
        std::printf(" %zu: %u/%u, %.1f;", i, c.minor_faults, c.major_faults, r.cpu[i]);
        ++shown;
      }
      std::printf("%s\n", shown == 0 ? " none" : "");
    }
  }
  if (repeat > 1) PrintRepeatable(runs);
  return 0;
}
