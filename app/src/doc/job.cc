// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#include "doc/job.h"

#include <algorithm>
#include <cmath>
#include <exception>
#include <utility>

namespace spidarcad::app {

void JobContext::SetProgress(double fraction) noexcept {
  if (!std::isfinite(fraction)) return;
  progress_.store(std::clamp(fraction, 0.0, 1.0), std::memory_order_relaxed);
}

void JobContext::SetPhase(const std::string& phase) {
  std::lock_guard<std::mutex> lock(phase_mutex_);
  phase_ = phase;
}

std::function<void(double)> JobContext::ProgressRange(double begin, double end) {
  return [this, begin, end](double fraction) {
    if (!std::isfinite(fraction)) return;
    SetProgress(begin + (end - begin) * std::clamp(fraction, 0.0, 1.0));
  };
}

Job::Job(std::string title, Work work) : title_(std::move(title)) {
  thread_ = std::thread([this, work = std::move(work)]() {
    State outcome = State::kSucceeded;
    try {
      finisher_ = work(context_);
      if (context_.cancelled()) outcome = State::kCancelled;
    } catch (const std::exception& e) {
      error_ = e.what();
      outcome = context_.cancelled() ? State::kCancelled : State::kFailed;
    } catch (...) {
      error_ = "unknown error";
      outcome = context_.cancelled() ? State::kCancelled : State::kFailed;
    }
    if (outcome == State::kSucceeded) context_.SetProgress(1.0);
    if (outcome != State::kSucceeded) finisher_ = nullptr;
    state_.store(outcome, std::memory_order_release);
  });
}

Job::~Job() {
  Cancel();
  if (thread_.joinable()) thread_.join();
}

std::string Job::phase() const {
  std::lock_guard<std::mutex> lock(context_.phase_mutex_);
  return context_.phase_;
}

void Job::Wait() {
  if (thread_.joinable()) thread_.join();
}

JobQueue::~JobQueue() {
  CancelAll();
  jobs_.clear();  // each Job joins its worker
}

Job& JobQueue::Start(std::string title, Job::Work work) {
  jobs_.push_back(std::make_unique<Job>(std::move(title), std::move(work)));
  return *jobs_.back();
}

int JobQueue::Poll(const FailureHandler& on_failure) {
  int ended = 0;
  for (auto& job : jobs_) {
    if (job->finished_ || job->state() == Job::State::kRunning) continue;
    job->Wait();  // the worker has stored its outcome; join so the thread is reclaimed
    job->finished_ = true;
    ++ended;
    if (job->state() == Job::State::kSucceeded) {
      try {
        if (job->finisher_) job->finisher_();
      } catch (const std::exception& e) {
        job->error_ = e.what();
        job->state_.store(Job::State::kFailed, std::memory_order_release);
      }
      job->finisher_ = nullptr;
    }
    if (job->state() != Job::State::kSucceeded && on_failure) on_failure(*job);
  }
  return ended;
}

void JobQueue::Prune() {
  jobs_.remove_if([](const std::unique_ptr<Job>& job) { return job->finished_; });
}

bool JobQueue::busy() const {
  return std::any_of(jobs_.begin(), jobs_.end(), [](const std::unique_ptr<Job>& job) {
    return job->state() == Job::State::kRunning;
  });
}

bool JobQueue::pending() const {
  return std::any_of(jobs_.begin(), jobs_.end(),
                     [](const std::unique_ptr<Job>& job) { return !job->finished_; });
}

void JobQueue::CancelAll() {
  for (auto& job : jobs_) job->Cancel();
}

}  // namespace spidarcad::app
