// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
// Jobs (ARCHITECTURE.md, "Document, commands, jobs"): a long operation (mesh this, tetrahedralize
// that, precompute this FE model) runs on its own worker thread with a progress fraction and a
// cancel flag. Its work function returns a *finisher*, a closure that the main thread runs when
// it polls the queue (typically: push the result into the Document as an undoable command). A
// job that throws or is cancelled runs no finisher, so the Document is left as it was; its error
// text is kept for the UI.
//
// Threads: JobQueue and the Job accessors belong to the main thread, except JobContext, which the
// worker uses. Workers are plain std::threads created from the main thread (never from the
// SCHED_FIFO haptic thread, whose policy they would inherit).
#pragma once

#include <atomic>
#include <functional>
#include <list>
#include <memory>
#include <mutex>
#include <string>
#include <thread>

namespace spidarcad::app {

// What a job's work function gets: progress reporting and the cancel flag. Thread safe.
class JobContext {
 public:
  // Fraction done, clamped to [0, 1]; non-finite values are ignored.
  void SetProgress(double fraction) noexcept;
  // Text of the current phase ("surface", "tetrahedra", ...), shown beside the progress bar.
  void SetPhase(const std::string& phase);
  // True once cancellation was requested; long loops should poll it and stop.
  bool cancelled() const noexcept { return cancel_.load(std::memory_order_relaxed); }
  // The flag itself, for settings structs that take `const std::atomic<bool>* cancel`.
  const std::atomic<bool>* cancel_flag() const noexcept { return &cancel_; }
  // A progress callback for settings structs (`std::function<void(double)> progress`) that maps
  // their [0, 1] onto [begin, end] of this job, so several phases fill one bar.
  std::function<void(double)> ProgressRange(double begin, double end);

 private:
  friend class Job;
  std::atomic<bool> cancel_{false};
  std::atomic<double> progress_{0.0};
  mutable std::mutex phase_mutex_;
  std::string phase_;
};

// One background operation. Created by JobQueue::Start.
class Job {
 public:
  // Runs on the main thread after success.
  using Finisher = std::function<void()>;
  // Runs on the worker; throws to fail (the message becomes error()).
  using Work = std::function<Finisher(JobContext&)>;
  enum class State { kRunning, kSucceeded, kFailed, kCancelled };

  // Starts the worker thread at once.
  Job(std::string title, Work work);
  // Requests cancellation and joins the worker.
  ~Job();
  Job(const Job&) = delete;
  Job& operator=(const Job&) = delete;

  // Title given at Start ("Mesh platform", ...).
  const std::string& title() const { return title_; }
  // Fraction done in [0, 1].
  double progress() const noexcept { return context_.progress_.load(std::memory_order_relaxed); }
  // Current phase text.
  std::string phase() const;
  // Asks the worker to stop; the job ends as kCancelled (its finisher never runs).
  void Cancel() noexcept { context_.cancel_.store(true, std::memory_order_relaxed); }
  // True once Cancel was called.
  bool cancel_requested() const noexcept { return context_.cancelled(); }
  // kRunning until the worker has returned.
  State state() const noexcept { return state_.load(std::memory_order_acquire); }
  // Error text when state() is kFailed (what() of the exception), else empty.
  const std::string& error() const { return error_; }
  // Blocks until the worker has returned.
  void Wait();

 private:
  friend class JobQueue;
  std::string title_;
  JobContext context_;
  std::atomic<State> state_{State::kRunning};
  std::string error_;      // written by the worker before state_ is released
  Finisher finisher_;      // likewise
  bool finished_ = false;  // main thread: finisher run / outcome reported
  std::thread thread_;
};

// The main thread's list of jobs. Poll() once per frame.
class JobQueue {
 public:
  // Called on the main thread for each job that ended without success (failed or cancelled).
  using FailureHandler = std::function<void(const Job&)>;

  JobQueue() = default;
  // Cancels and joins every job still running.
  ~JobQueue();

  // Starts a job and returns it (owned by the queue; valid until Prune removes it).
  Job& Start(std::string title, Job::Work work);
  // Runs the finishers of jobs that succeeded since the last call (in start order) and reports
  // the others through `on_failure`. Returns the number of jobs that ended in this call. A
  // finisher that throws turns its job into kFailed with that message.
  int Poll(const FailureHandler& on_failure = {});
  // Drops jobs that have ended and been polled.
  void Prune();
  // Jobs in start order (running ones and ended ones not yet pruned).
  const std::list<std::unique_ptr<Job>>& jobs() const { return jobs_; }
  // True while any job is running.
  bool busy() const;
  // True while any job is running or has ended without Poll having taken its outcome yet (a
  // succeeded job's finisher not run): what a caller waiting for the jobs' results to land in
  // the document needs, since busy() turns false as soon as the worker ends, before the
  // finisher runs on the next Poll.
  bool pending() const;
  // Requests cancellation of every running job.
  void CancelAll();

 private:
  std::list<std::unique_ptr<Job>> jobs_;
};

}  // namespace spidarcad::app
