// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#include "spidarcad/haptics/loop_runner.h"

#include <pthread.h>
#include <sched.h>
#include <time.h>

#include <cerrno>
#include <cmath>
#include <stdexcept>
#include <string>

namespace spidarcad::haptics {

namespace {

double Seconds(const timespec& t) { return static_cast<double>(t.tv_sec) + 1e-9 * t.tv_nsec; }

void AddNanoseconds(timespec* t, std::int64_t ns) {
  std::int64_t total = static_cast<std::int64_t>(t->tv_nsec) + ns;
  t->tv_sec += total / 1000000000;
  total %= 1000000000;
  if (total < 0) {
    total += 1000000000;
    t->tv_sec -= 1;
  }
  t->tv_nsec = static_cast<long>(total);
}

timespec Now() {
  timespec t;
  clock_gettime(CLOCK_MONOTONIC, &t);
  return t;
}

}  // namespace

LatencyHistogram::LatencyHistogram(double bin_width, int num_bins)
    : bin_width_(bin_width), num_bins_(num_bins) {
  if (!(bin_width > 0 && std::isfinite(bin_width)) || num_bins < 1) {
    throw std::invalid_argument("LatencyHistogram: bin width " + std::to_string(bin_width) +
                                " s and bin count " + std::to_string(num_bins) +
                                " must be positive");
  }
  bins_ = std::make_unique<std::atomic<std::uint64_t>[]>(num_bins + 1);
  Clear();
}

void LatencyHistogram::Add(double seconds) noexcept {
  if (std::isnan(seconds)) return;
  if (seconds < 0) seconds = 0;
  const double index = seconds / bin_width_;
  const int bin = index >= num_bins_ ? num_bins_ : static_cast<int>(index);
  bins_[bin].fetch_add(1, std::memory_order_relaxed);
  count_.fetch_add(1, std::memory_order_relaxed);
  // One writer thread: plain load/store is enough for max and sum.
  if (seconds > max_.load(std::memory_order_relaxed))
    max_.store(seconds, std::memory_order_relaxed);
  sum_.store(sum_.load(std::memory_order_relaxed) + seconds, std::memory_order_relaxed);
}

void LatencyHistogram::Clear() noexcept {
  for (int i = 0; i <= num_bins_; ++i) bins_[i].store(0, std::memory_order_relaxed);
  count_.store(0, std::memory_order_relaxed);
  max_.store(0.0, std::memory_order_relaxed);
  sum_.store(0.0, std::memory_order_relaxed);
}

double LatencyHistogram::mean() const noexcept {
  const std::uint64_t n = count();
  return n == 0 ? 0.0 : sum_.load(std::memory_order_relaxed) / static_cast<double>(n);
}

double LatencyHistogram::Percentile(double p) const noexcept {
  std::uint64_t total = 0;
  for (int i = 0; i <= num_bins_; ++i) total += bins_[i].load(std::memory_order_relaxed);
  if (total == 0) return 0.0;
  p = std::min(1.0, std::max(0.0, p));
  // Smallest bin whose cumulative count reaches ceil(p · total) (at least 1).
  const auto rank = std::max<std::uint64_t>(
      1, static_cast<std::uint64_t>(std::ceil(p * static_cast<double>(total))));
  std::uint64_t cumulative = 0;
  for (int i = 0; i < num_bins_; ++i) {
    cumulative += bins_[i].load(std::memory_order_relaxed);
    if (cumulative >= rank) return std::min(max(), (i + 1) * bin_width_);
  }
  return max();
}

const char* RealtimeStatusName(RealtimeStatus status) {
  switch (status) {
    case RealtimeStatus::kNotStarted:
      return "not_started";
    case RealtimeStatus::kFifo:
      return "fifo";
    case RealtimeStatus::kNoPermission:
      return "no_permission";
    case RealtimeStatus::kNotRequested:
      return "not_requested";
    case RealtimeStatus::kFailed:
      return "failed";
  }
  return "unknown";
}

LoopRunner::LoopRunner(const RunnerSettings& settings) : settings_(settings) {
  if (!(settings.period > 0 && settings.period <= 1.0)) {
    throw std::invalid_argument("RunnerSettings.period = " + std::to_string(settings.period) +
                                " s: must be in (0, 1]");
  }
  if (settings.priority < 1 || settings.priority > 99) {
    throw std::invalid_argument("RunnerSettings.priority = " + std::to_string(settings.priority) +
                                ": must be in 1..99");
  }
  if (settings.skip_after_periods < 1) {
    throw std::invalid_argument("RunnerSettings.skip_after_periods must be >= 1");
  }
}

LoopRunner::~LoopRunner() { Stop(); }

void LoopRunner::Start(TickFunction tick) {
  if (running()) throw std::logic_error("LoopRunner::Start: already running");
  if (thread_.joinable()) thread_.join();
  tick_ = std::move(tick);
  lateness_.Clear();
  jitter_.Clear();
  compute_.Clear();
  ticks_.store(0);
  overruns_.store(0);
  prefaulted_pages_.store(0);
  stop_.store(false);
  realtime_status_.store(RealtimeStatus::kNotStarted);
  running_.store(true, std::memory_order_release);
  // Created from the caller's (normal) thread; the new thread raises its own priority, so no
  // other thread ever inherits SCHED_FIFO from it.
  thread_ = std::thread([this] { Run(); });
  while (realtime_status_.load(std::memory_order_acquire) == RealtimeStatus::kNotStarted) {
    std::this_thread::yield();
  }
}

void LoopRunner::Stop() {
  stop_.store(true, std::memory_order_release);
  if (thread_.joinable()) thread_.join();
  running_.store(false, std::memory_order_release);
}

void LoopRunner::Run() {
  RealtimeStatus status = RealtimeStatus::kNotRequested;
  if (settings_.try_realtime) {
    sched_param param{};
    param.sched_priority = settings_.priority;
    const int err = pthread_setschedparam(pthread_self(), SCHED_FIFO, &param);
    status = err == 0 ? RealtimeStatus::kFifo
                      : (err == EPERM ? RealtimeStatus::kNoPermission : RealtimeStatus::kFailed);
  }
  // Before the first tick: the stack pages the tick's call chain will use are present.
  prefaulted_pages_.store(PrefaultStack(settings_.prefault_stack_bytes), std::memory_order_release);
  realtime_status_.store(status, std::memory_order_release);

  const auto period_ns = static_cast<std::int64_t>(std::llround(settings_.period * 1e9));
  timespec next = Now();
  double previous_wake = Seconds(next);
  std::uint64_t tick = 0;
  while (!stop_.load(std::memory_order_acquire)) {
    AddNanoseconds(&next, period_ns);
    while (clock_nanosleep(CLOCK_MONOTONIC, TIMER_ABSTIME, &next, nullptr) == EINTR) {
    }
    const timespec wake = Now();
    const double wake_s = Seconds(wake);
    const double lateness = wake_s - Seconds(next);
    TickTiming timing;
    timing.tick = tick++;
    timing.period = settings_.period;
    timing.elapsed = wake_s - previous_wake;
    timing.lateness = lateness;
    tick_(timing);
    const double done = Seconds(Now());
    compute_.Add(done - wake_s);
    lateness_.Add(lateness);
    jitter_.Add(std::abs(timing.elapsed - settings_.period));
    previous_wake = wake_s;
    ticks_.fetch_add(1, std::memory_order_relaxed);
    // Far behind schedule: skip the missed slots instead of running them back to back.
    if (done - Seconds(next) > settings_.skip_after_periods * settings_.period) {
      overruns_.fetch_add(1, std::memory_order_relaxed);
      const auto behind = static_cast<std::int64_t>((done - Seconds(next)) / settings_.period);
      AddNanoseconds(&next, behind * period_ns);
    }
  }
}

}  // namespace spidarcad::haptics
