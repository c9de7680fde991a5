// Tests of the real-time runner and its latency histogram. No timing assertions: the runner is
// checked for what it does (ticks in order on its own thread, scheduling as reported,
// statistics consistent with the samples), not how fast.
// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#include "spidarcad/haptics/loop_runner.h"

#include <gtest/gtest.h>
#include <pthread.h>
#include <sched.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <random>
#include <thread>
#include <vector>

namespace spidarcad::haptics {
namespace {

TEST(LatencyHistogram, PercentilesMatchSortedSamplesWithinOneBin) {
  std::mt19937_64 rng(42);
  std::lognormal_distribution<double> dist(std::log(20e-6), 0.5);
  LatencyHistogram h(1e-7, 10000);  // 0.1 µs bins up to 1 ms
  std::vector<double> samples;
  for (int i = 0; i < 20000; ++i) {
    const double x = dist(rng);
    samples.push_back(x);
    h.Add(x);
  }
  samples.push_back(5e-3);  // into the overflow bin
  h.Add(5e-3);
  std::sort(samples.begin(), samples.end());
  EXPECT_EQ(h.count(), samples.size());
  EXPECT_EQ(h.max(), samples.back());
  for (double p : {0.5, 0.9, 0.99, 0.999}) {
    const auto rank = static_cast<std::size_t>(std::ceil(p * samples.size()));
    const double exact = samples[rank - 1];
    EXPECT_GE(h.Percentile(p), exact) << p;
    EXPECT_LE(h.Percentile(p), exact + 1e-7) << p;
  }
  EXPECT_EQ(h.Percentile(1.0), 5e-3);
  double sum = 0;
  for (double x : samples) sum += x;
  EXPECT_NEAR(h.mean(), sum / samples.size(), 1e-12);
  h.Clear();
  EXPECT_EQ(h.count(), 0u);
  EXPECT_EQ(h.Percentile(0.5), 0.0);
}

TEST(LoopRunner, TicksInOrderOnItsOwnThreadWithTheReportedScheduling) {
  RunnerSettings settings;
  settings.period = 1e-3;
  LoopRunner runner(settings);
  std::vector<std::uint64_t> seen(100000);
  std::atomic<std::uint64_t> count{0};
  std::atomic<int> policy{-1};
  std::atomic<bool> same_thread{false};
  const auto main_id = std::this_thread::get_id();
  runner.Start([&](const TickTiming& timing) {
    const std::uint64_t n = count.load(std::memory_order_relaxed);
    if (n < seen.size()) seen[n] = timing.tick;
    if (n == 0) {
      sched_param param;
      int p = -1;
      pthread_getschedparam(pthread_self(), &p, &param);
      policy = p;
      same_thread = std::this_thread::get_id() == main_id;
    }
    count.store(n + 1, std::memory_order_release);
  });
  const RealtimeStatus status = runner.realtime_status();
  EXPECT_NE(status, RealtimeStatus::kNotStarted);
  // Wait (generously) for 50 ticks; no assertion on the time it takes.
  for (int i = 0; i < 20000 && count.load() < 50; ++i) {
    std::this_thread::sleep_for(std::chrono::milliseconds(1));
  }
  runner.Stop();
  EXPECT_FALSE(runner.running());
  const std::uint64_t n = count.load();
  ASSERT_GE(n, 50u);
  EXPECT_EQ(runner.ticks(), n);
  for (std::uint64_t i = 0; i < n; ++i) ASSERT_EQ(seen[i], i);
  EXPECT_FALSE(same_thread.load());
  EXPECT_EQ(policy.load() == SCHED_FIFO, status == RealtimeStatus::kFifo);
  EXPECT_EQ(runner.compute().count(), n);
  EXPECT_EQ(runner.lateness().count(), n);
  EXPECT_LE(runner.compute().Percentile(0.5), runner.compute().Percentile(0.99));
  EXPECT_LE(runner.compute().Percentile(0.999), runner.compute().max());
  // A stopped runner can start again with fresh statistics.
  runner.Start([](const TickTiming&) {});
  runner.Stop();
  EXPECT_LT(runner.ticks(), n + 1000);
}

TEST(LoopRunner, FallsBackCleanlyWhenRealtimeIsNotRequested) {
  RunnerSettings settings;
  settings.try_realtime = false;
  LoopRunner runner(settings);
  std::atomic<int> ticks{0};
  runner.Start([&](const TickTiming&) { ticks.fetch_add(1); });
  EXPECT_EQ(runner.realtime_status(), RealtimeStatus::kNotRequested);
  for (int i = 0; i < 20000 && ticks.load() < 5; ++i) {
    std::this_thread::sleep_for(std::chrono::milliseconds(1));
  }
  runner.Stop();
  EXPECT_GE(ticks.load(), 5);
}

TEST(LoopRunner, RejectsBadSettings) {
  RunnerSettings s;
  s.period = 0;
  EXPECT_THROW(LoopRunner{s}, std::invalid_argument);
  s = RunnerSettings{};
  s.priority = 100;
  EXPECT_THROW(LoopRunner{s}, std::invalid_argument);
}

}  // namespace
}  // namespace spidarcad::haptics
