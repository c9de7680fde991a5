// Haptic tick time per scene kind: HapticLoop::Step on the simulated SPIDAR-G gripped by the
// simulated hand, as in `spidarcad run`, for every kind of scene the window shows (empty, demo,
// implicit proxy, six-DOF shell, FE contact, sculpt, assembly). Used by `spidarcad report`
// (section "tick") and by bench/app_scene_tick_bench; every golden run of the regression test
// is a row too (MeasureGoldenRunTicks).
// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#pragma once

#include <cstdint>
#include <functional>
#include <string>
#include <vector>

namespace spidarcad::app {

// What the kernel counted on the measuring thread during one tick: getrusage(RUSAGE_THREAD)
// read just before and just after HapticLoop::Step (outside the timed region).
struct TickCounters {
  std::uint32_t minor_faults = 0;          // page faults served without I/O (first touch, ...)
  std::uint32_t major_faults = 0;          // page faults that waited for I/O
  std::uint32_t voluntary_switches = 0;    // the thread blocked (a lock, a syscall that sleeps)
  std::uint32_t involuntary_switches = 0;  // the thread was preempted
};

// One of the slowest ticks of a scene.
struct SlowTick {
  long index = 0;          // tick index in the run (0 = first timed tick)
  double us = 0, cpu = 0;  // wall clock and thread CPU time, µs
  TickCounters counters;
};

// Tick-time figures of one scene (µs), with the samples.
struct SceneTickRow {
  std::string name;
  double p50 = 0, p99 = 0, p999 = 0, max = 0, mean = 0;        // wall clock (steady clock)
  double cpu_p50 = 0, cpu_p99 = 0, cpu_p999 = 0, cpu_max = 0;  // thread CPU time
  // Summed over the ticks: page faults, involuntary context switches, ticks with a fault.
  long minor_faults = 0, major_faults = 0, involuntary_switches = 0, ticks_with_faults = 0;
  std::vector<SlowTick> slowest;  // the kSlowestTicks slowest ticks by thread CPU, slowest first
  std::string note;               // scene-specific figures (FE: contact nodes reached, ...)
  std::string scheduling;         // of the measuring thread: "SCHED_FIFO 80", "normal ..."
  std::vector<double> us, cpu;    // the samples, per tick (wall clock, thread CPU), µs
  std::vector<TickCounters> counters;  // per tick
  // The run's tick index of each sample, for rows over a subset of the ticks; empty: sample i
  // is tick i.
  std::vector<long> index;
  // The run's tick index of sample i.
  long TickOf(std::size_t i) const { return i < index.size() ? index[i] : static_cast<long>(i); }
};

// Number of ticks SceneTickRow::slowest keeps.
inline constexpr int kSlowestTicks = 8;

// How the ticks are measured.
struct SceneTickOptions {
  long ticks = 20000;  // timed ticks per scene (>= 1; the trajectories repeat)
  // Untimed ticks run before the timed ones, on the same loop, device and hand, so that every
  // buffer the tick touches has been touched once (first-touch page faults, lazily grown
  // caches). 0 for none.
  long warm_up_ticks = 0;
  // Measure on a thread of its own at SCHED_FIFO priority 80, as LoopRunner runs the window's
  // haptic thread (normal scheduling when the OS refuses; SceneTickRow::scheduling says which).
  // The ticks run back to back, so the thread holds one core for the run. Both ways the
  // measuring thread touches its stack first (PrefaultStack).
  bool realtime = false;
};

// Runs every scene kind for `ticks` ticks (>= 1; the trajectories repeat) and returns one row
// per scene, plus rows over the FE ticks with 16 contact nodes and the assembly ticks carrying
// a part. `progress(fraction)` is called after each scene.
std::vector<SceneTickRow> MeasureSceneTicks(long ticks,
                                            const std::function<void(double)>& progress = {});
std::vector<SceneTickRow> MeasureSceneTicks(const SceneTickOptions& options,
                                            const std::function<void(double)>& progress = {});

// One row per golden run (cli/golden_runs.h: the list the regression test reads), named
// "golden NAME": the run built from the golden's own options exactly as `spidarcad run` builds
// it (ScriptedRun; assets from AssetPath), every tick it runs stepped, and each tick's
// HapticLoop::Step timed (wall clock, thread CPU, faults and switches) on the measuring thread of
// options.realtime; the set-up (FE models and columns, sculpt meshes, calibration) and the CSV
// rows are not timed. `max_ticks` > 0 stops each run after that many ticks (tests); 0: all of
// them (options.ticks and warm_up_ticks are not used). The note gives the ticks and the set-up
// time. `progress(fraction)` after each run. Throws what ScriptedRun throws.
std::vector<SceneTickRow> MeasureGoldenRunTicks(const SceneTickOptions& options, long max_ticks = 0,
                                                const std::function<void(double)>& progress = {});

// Summarises per-tick samples (µs; `us`, `cpu` and `counters` of the same non-zero length) into
// a row: percentiles, maxima, fault and switch totals, the slowest ticks by thread CPU time.
// `tick_index[i]`, when given, is the run's index of sample i (rows over a subset of the ticks);
// without it sample i is tick i.
SceneTickRow SummarizeTicks(const std::string& name, const std::vector<double>& us,
                            const std::vector<double>& cpu,
                            const std::vector<TickCounters>& counters,
                            const std::vector<long>& tick_index = {});

// The same scene measured in several runs, tick by tick: the simulated tick is deterministic
// (seeded device errors, scripted hand), so tick i does the same work in every run, and time
// that the machine charged to one run's tick (an interrupt, the hypervisor: a different tick in
// each run) is gone from the least of its times. Returns a row named after the first run's,
// whose per-tick wall and CPU times are the least over the runs of each tick present in all of
// them (matched by index, SceneTickRow::index), summarised as SummarizeTicks does (its counters
// are zero: they belong to single runs). A tick slow in every run is slow here: that is the
// code's. Throws std::invalid_argument when `runs` is empty, holds a null row, or the runs
// share no tick.
SceneTickRow RepeatableTicks(const std::vector<const SceneTickRow*>& runs);

// One repeatable row and the rows of the single runs it was made from.
struct RepeatableRow {
  SceneTickRow row;
  std::vector<const SceneTickRow*> runs;
};
// RepeatableTicks of every row of the first run whose name every run has and whose runs share a
// tick, in the first run's order. The runs must outlive the result.
std::vector<RepeatableRow> RepeatableRows(
    const std::vector<const std::vector<SceneTickRow>*>& runs);

}  // namespace spidarcad::app
