// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
// RunAbandonable (base/abandonable.h): the result or the exception of the work when it ends
// first; nothing, at once, when the cancel flag is raised first, the work going on to its end on
// its own thread.
#include "spidarcad/base/abandonable.h"

#include <gtest/gtest.h>

#include <atomic>
#include <chrono>
#include <memory>
#include <optional>
#include <stdexcept>
#include <thread>

namespace spidarcad {
namespace {

TEST(RunAbandonable, ReturnsTheResultOnTheCallingThreadWithoutAFlag) {
  const std::thread::id caller = std::this_thread::get_id();
  std::thread::id ran;
  const std::optional<int> r = RunAbandonable(
      [&ran] {
        ran = std::this_thread::get_id();
        return 42;
      },
      nullptr);
  ASSERT_TRUE(r.has_value());
  EXPECT_EQ(*r, 42);
  EXPECT_EQ(ran, caller);
}

TEST(RunAbandonable, ReturnsTheResultOrRethrowsWhenTheWorkEndsFirst) {
  std::atomic<bool> cancel{false};
  const std::optional<std::unique_ptr<int>> r =
      RunAbandonable([] { return std::make_unique<int>(7); }, &cancel);
  ASSERT_TRUE(r.has_value());
  EXPECT_EQ(**r, 7);
  EXPECT_THROW(RunAbandonable([]() -> int { throw std::runtime_error("work failed"); }, &cancel),
               std::runtime_error);
}

TEST(RunAbandonable, ReturnsNothingWithoutRunningWhenAlreadyCancelled) {
  std::atomic<bool> cancel{true};
  auto ran = std::make_shared<std::atomic<bool>>(false);
  EXPECT_FALSE(RunAbandonable(
                   [ran] {
                     *ran = true;
                     return 1;
                   },
                   &cancel)
                   .has_value());
  EXPECT_FALSE(*ran);
}

TEST(RunAbandonable, AbandonsTheWorkWhenCancelledAndTheWorkEndsOnItsOwn) {
  std::atomic<bool> cancel{false};
  // The work waits for `release`; it owns its state through shared_ptrs.
  auto release = std::make_shared<std::atomic<bool>>(false);
  auto started = std::make_shared<std::atomic<bool>>(false);
  auto finished = std::make_shared<std::atomic<bool>>(false);
  std::thread canceller([&] {
    while (!*started) std::this_thread::yield();
    cancel = true;
  });
  const std::optional<int> r = RunAbandonable(
      [release, started, finished] {
        *started = true;
        while (!*release) std::this_thread::sleep_for(std::chrono::milliseconds(1));
        *finished = true;
        return 3;
      },
      &cancel, std::chrono::milliseconds(1));
  canceller.join();
  EXPECT_FALSE(r.has_value());
  EXPECT_FALSE(*finished) << "returned before the work ended";
  *release = true;
  for (int i = 0; i < 10000 && !*finished; ++i)
    std::this_thread::sleep_for(std::chrono::milliseconds(1));
  EXPECT_TRUE(*finished) << "the abandoned work ran to its end";
}

}  // namespace
}  // namespace spidarcad
