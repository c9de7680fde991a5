// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
// The real-time runner: a std::thread that calls a tick function at a fixed rate (1 kHz by
// default) with absolute-time sleeps (clock_nanosleep(CLOCK_MONOTONIC, TIMER_ABSTIME)), so
// sleep errors do not accumulate. It asks for SCHED_FIFO from inside the new thread and falls
// back to normal scheduling when the OS refuses (EPERM without CAP_SYS_NICE or an rtprio
// limit); realtime_status() says which. Before the first tick it touches its stack
// (RunnerSettings::prefault_stack_bytes); locking the process's memory is the owner's call
// (LockProcessMemory, realtime_memory.h), made before Start. Period jitter, wake-up lateness and
// tick compute time go into preallocated histograms (no allocation while running).
//
// STACK-NOTES: threads created by a SCHED_FIFO thread inherit SCHED_FIFO. The tick function
// must therefore never create threads (nor allocate, lock, do I/O or throw).
#pragma once

#include <atomic>
#include <cstddef>
#include <cstdint>
#include <functional>
#include <memory>
#include <thread>

#include "spidarcad/haptics/realtime_memory.h"

namespace spidarcad::haptics {

// A histogram of durations with fixed-width bins, preallocated. Add is lock-free and
// allocation-free (relaxed atomics), so one thread may Add while another reads statistics.
class LatencyHistogram {
 public:
  // Bins of `bin_width` s from 0 to num_bins · bin_width; larger values land in an overflow
  // bin (max() still records them exactly). Throws std::invalid_argument on bad sizes.
  explicit LatencyHistogram(double bin_width = 1e-7, int num_bins = 100000);
  // Records one duration, s (negative values count as 0, NaN is ignored).
  void Add(double seconds) noexcept;
  // Forgets every sample.
  void Clear() noexcept;
  // Number of samples.
  std::uint64_t count() const noexcept { return count_.load(std::memory_order_relaxed); }
  // Largest sample, s (0 when empty).
  double max() const noexcept { return max_.load(std::memory_order_relaxed); }
  // Mean of the samples, s (0 when empty).
  double mean() const noexcept;
  // The p-quantile (p in [0, 1]) as the upper edge of the bin that holds it (so within one
  // bin width above the true value); max() when it falls in the overflow bin; 0 when empty.
  double Percentile(double p) const noexcept;
  double bin_width() const noexcept { return bin_width_; }

 private:
  double bin_width_;
  int num_bins_;
  std::unique_ptr<std::atomic<std::uint64_t>[]> bins_;  // num_bins_ + 1 (overflow last)
  std::atomic<std::uint64_t> count_{0};
  std::atomic<double> max_{0.0};
  std::atomic<double> sum_{0.0};
};

// Timing of one tick as the runner hands it to the tick function.
struct TickTiming {
  std::uint64_t tick = 0;  // index since Start
  double period = 1e-3;    // nominal period, s (use it as dt for deterministic behaviour)
  double elapsed = 0.0;    // actual time since the previous wake-up, s
  double lateness = 0.0;   // wake-up time minus scheduled time, s (>= 0 normally)
};

// How the runner thread is scheduled.
enum class RealtimeStatus : std::uint8_t {
  kNotStarted = 0,
  kFifo,          // SCHED_FIFO granted
  kNoPermission,  // SCHED_FIFO refused with EPERM: running with normal scheduling
  kNotRequested,  // RunnerSettings::try_realtime was false
  kFailed,        // SCHED_FIFO refused for another reason: normal scheduling
};
// One word for a status ("not_started", "fifo", "no_permission", "not_requested", "failed").
const char* RealtimeStatusName(RealtimeStatus status);

// Settings of the runner.
struct RunnerSettings {
  double period = 1e-3;  // s (1 kHz)
  bool try_realtime = true;
  int priority = 80;  // SCHED_FIFO priority, 1..99
  // When a wake-up is later than this many periods the missed slots are skipped (not caught
  // up in a burst) and counted in overruns().
  int skip_after_periods = 2;
  // Bytes of the runner thread's stack touched before its first tick (PrefaultStack,
  // realtime_memory.h), so that no tick first-touches a stack page; 0: none.
  std::size_t prefault_stack_bytes = kPrefaultStackBytes;
};

// Runs a tick function periodically on its own thread.
class LoopRunner {
 public:
  // The tick function. Called on the runner thread only; must be real-time safe.
  using TickFunction = std::function<void(const TickTiming&)>;
  // Throws std::invalid_argument for a period not in (0, 1] s or a priority outside 1..99.
  explicit LoopRunner(const RunnerSettings& settings = {});
  // Stops the thread if running.
  ~LoopRunner();
  LoopRunner(const LoopRunner&) = delete;
  LoopRunner& operator=(const LoopRunner&) = delete;

  // Starts the thread (statistics cleared). Returns once the thread has set its scheduling
  // (see realtime_status()). Throws std::logic_error if already running.
  void Start(TickFunction tick);
  // Asks the thread to stop and joins it. Safe to call when not running.
  void Stop();
  bool running() const noexcept { return running_.load(std::memory_order_acquire); }

  RealtimeStatus realtime_status() const noexcept {
    return realtime_status_.load(std::memory_order_acquire);
  }
  // Ticks run since Start.
  std::uint64_t ticks() const noexcept { return ticks_.load(std::memory_order_relaxed); }
  // Wake-ups later than skip_after_periods periods (slots skipped).
  std::uint64_t overruns() const noexcept { return overruns_.load(std::memory_order_relaxed); }
  // Wake-up lateness against the absolute schedule, s.
  const LatencyHistogram& lateness() const noexcept { return lateness_; }
  // Period jitter |actual period − nominal period|, s.
  const LatencyHistogram& jitter() const noexcept { return jitter_; }
  // Time spent in the tick function, s.
  const LatencyHistogram& compute() const noexcept { return compute_; }
  const RunnerSettings& settings() const noexcept { return settings_; }
  // Stack pages the thread touched before its first tick (PrefaultStack; 0 before Start).
  std::size_t prefaulted_stack_pages() const noexcept {
    return prefaulted_pages_.load(std::memory_order_acquire);
  }

 private:
  void Run();

  RunnerSettings settings_;
  TickFunction tick_;
  std::thread thread_;
  std::atomic<bool> stop_{false};
  std::atomic<bool> running_{false};
  std::atomic<RealtimeStatus> realtime_status_{RealtimeStatus::kNotStarted};
  std::atomic<std::uint64_t> ticks_{0};
  std::atomic<std::uint64_t> overruns_{0};
  std::atomic<std::size_t> prefaulted_pages_{0};
  LatencyHistogram lateness_;
  LatencyHistogram jitter_;
  LatencyHistogram compute_;
};

}  // namespace spidarcad::haptics
