// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#include "doc/job.h"

#include <gtest/gtest.h>

#include <atomic>
#include <chrono>
#include <stdexcept>
#include <string>
#include <thread>

namespace spidarcad::app {
namespace {

// Polls until every job has ended (bounded, so a hung worker fails the test instead of the run).
int PollUntilIdle(JobQueue* queue, const JobQueue::FailureHandler& on_failure = {}) {
  int ended = 0;
  for (int i = 0; i < 20000 && (queue->busy() || ended == 0); ++i) {
    ended += queue->Poll(on_failure);
    std::this_thread::sleep_for(std::chrono::milliseconds(1));
  }
  return ended + queue->Poll(on_failure);
}

TEST(JobQueue, RunsFinisherOnPollingThreadWhenWorkSucceeds) {
  JobQueue queue;
  int document = 0;  // stands in for the Document: only the finisher may change it
  const std::thread::id main_id = std::this_thread::get_id();
  std::thread::id work_id, finish_id;
  queue.Start("add", [&](JobContext& context) -> Job::Finisher {
    work_id = std::this_thread::get_id();
    context.SetPhase("adding");
    context.SetProgress(0.5);
    return [&] {
      finish_id = std::this_thread::get_id();
      document = 42;
    };
  });
  EXPECT_EQ(PollUntilIdle(&queue), 1);
  EXPECT_EQ(document, 42);
  EXPECT_NE(work_id, main_id);
  EXPECT_EQ(finish_id, main_id);
  const Job& job = *queue.jobs().front();
  EXPECT_EQ(job.state(), Job::State::kSucceeded);
  EXPECT_DOUBLE_EQ(job.progress(), 1.0);
  EXPECT_EQ(job.phase(), "adding");
  queue.Prune();
  EXPECT_TRUE(queue.jobs().empty());
}

// A job whose worker has ended is no longer busy, but its result has not landed until Poll has
// run its finisher: pending() says so, and turns false only after that Poll.
TEST(JobQueue, PendingUntilPollHasRunTheFinisherOfAnEndedJob) {
  JobQueue queue;
  int document = 0;
  const Job& job =
      queue.Start("land", [&](JobContext&) -> Job::Finisher { return [&] { document = 1; }; });
  for (int i = 0; i < 20000 && job.state() == Job::State::kRunning; ++i) {
    std::this_thread::sleep_for(std::chrono::milliseconds(1));
  }
  ASSERT_EQ(job.state(), Job::State::kSucceeded);
  EXPECT_FALSE(queue.busy());
  EXPECT_TRUE(queue.pending()) << "the finisher has not run";
  EXPECT_EQ(document, 0);
  EXPECT_EQ(queue.Poll(), 1);
  EXPECT_EQ(document, 1);
  EXPECT_FALSE(queue.pending());
  queue.Prune();
  EXPECT_FALSE(queue.pending());
}

TEST(JobQueue, LeavesDocumentAndReportsErrorWhenWorkThrows) {
  JobQueue queue;
  int document = 7;
  std::string reported;
  queue.Start("mesh", [&](JobContext&) -> Job::Finisher {
    throw std::runtime_error("surface is open at edge 12");
  });
  PollUntilIdle(&queue, [&](const Job& job) { reported = job.error(); });
  EXPECT_EQ(document, 7);
  EXPECT_EQ(reported, "surface is open at edge 12");
  EXPECT_EQ(queue.jobs().front()->state(), Job::State::kFailed);
}

TEST(JobQueue, EndsCancelledWithoutFinisherWhenCancelledMidWork) {
  JobQueue queue;
  int document = 0;
  std::atomic<bool> started{false};
  Job& job = queue.Start("precompute", [&](JobContext& context) -> Job::Finisher {
    started = true;
    while (!context.cancelled()) std::this_thread::sleep_for(std::chrono::milliseconds(1));
    return [&] { document = 1; };  // must not run: the job was cancelled
  });
  while (!started) std::this_thread::sleep_for(std::chrono::milliseconds(1));
  EXPECT_TRUE(queue.busy());
  job.Cancel();
  int failures = 0;
  PollUntilIdle(&queue, [&](const Job& ended) {
    ++failures;
    EXPECT_EQ(ended.state(), Job::State::kCancelled);
  });
  EXPECT_EQ(failures, 1);
  EXPECT_EQ(document, 0);
}

TEST(JobQueue, TurnsJobFailedWhenFinisherThrows) {
  JobQueue queue;
  queue.Start("apply", [](JobContext&) -> Job::Finisher {
    return [] { throw std::invalid_argument("node 'bracket' was deleted meanwhile"); };
  });
  std::string reported;
  PollUntilIdle(&queue, [&](const Job& job) { reported = job.error(); });
  EXPECT_EQ(queue.jobs().front()->state(), Job::State::kFailed);
  EXPECT_EQ(reported, "node 'bracket' was deleted meanwhile");
}

TEST(JobContext, MapsPhaseProgressOntoItsRangeAndClampsWhenOutOfRange) {
  JobQueue queue;
  std::atomic<bool> go{false};
  std::atomic<int> step{0};
  Job& job = queue.Start("two phases", [&](JobContext& context) -> Job::Finisher {
    auto second = context.ProgressRange(0.25, 0.75);
    second(0.5);
    step = 1;
    while (!go) std::this_thread::sleep_for(std::chrono::milliseconds(1));
    context.SetProgress(7.0);
    step = 2;
    while (!context.cancelled()) std::this_thread::sleep_for(std::chrono::milliseconds(1));
    return {};
  });
  while (step != 1) std::this_thread::sleep_for(std::chrono::milliseconds(1));
  EXPECT_DOUBLE_EQ(job.progress(), 0.5);
  go = true;
  while (step != 2) std::this_thread::sleep_for(std::chrono::milliseconds(1));
  EXPECT_DOUBLE_EQ(job.progress(), 1.0);
  job.Cancel();
  PollUntilIdle(&queue);
}

TEST(JobQueue, JoinsRunningWorkersWhenDestroyed) {
  std::atomic<bool> stopped{false};
  {
    JobQueue queue;
    queue.Start("endless", [&](JobContext& context) -> Job::Finisher {
      while (!context.cancelled()) std::this_thread::sleep_for(std::chrono::milliseconds(1));
      stopped = true;
      return {};
    });
  }
  EXPECT_TRUE(stopped);
}

}  // namespace
}  // namespace spidarcad::app
