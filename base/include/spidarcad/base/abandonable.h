// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
// Running a library call that cannot be interrupted (TetGen's tetrahedralize, CHOLMOD's
// factorisation) so that a cancelled job need not wait for it: the call runs on a thread of its
// own; the caller waits, polling its cancel flag, and on cancellation returns at once, leaving
// the thread to finish in the background (detached) and drop its result. The abandoned call keeps
// its CPU time and memory until it ends by itself: cancellation frees the caller, not the
// machine.
#pragma once

#include <atomic>
#include <chrono>
#include <condition_variable>
#include <exception>
#include <functional>
#include <memory>
#include <mutex>
#include <optional>
#include <thread>
#include <type_traits>
#include <utility>

namespace spidarcad {

// Runs work() and returns its result, or std::nullopt as soon as *cancel is seen raised (polled
// every `poll`) before work() has returned; an exception thrown by work() is rethrown here
// (unless abandoned). Without a cancel flag work() runs on the calling thread. `work` must own
// everything it touches (capture by value or by shared_ptr, never references to the caller's
// frame): after an abandon it goes on running after RunAbandonable has returned. `while_waiting`
// (when set) runs on the calling thread at each poll, e.g. to pass on progress that work() left
// in an atomic. Threads: call from a worker thread (the helper thread inherits its scheduling
// policy).
template <typename Work>
std::optional<std::invoke_result_t<Work&>> RunAbandonable(
    Work work, const std::atomic<bool>* cancel,
    std::chrono::milliseconds poll = std::chrono::milliseconds(5),
    const std::function<void()>& while_waiting = {}) {
  using Result = std::invoke_result_t<Work&>;
  if (cancel == nullptr) return std::optional<Result>(work());
  if (cancel->load(std::memory_order_relaxed)) return std::nullopt;
  struct Shared {
    std::mutex mutex;
    std::condition_variable done_cv;
    bool done = false;
    std::optional<Result> result;
    std::exception_ptr error;
  };
  auto shared = std::make_shared<Shared>();
  std::thread thread([shared, work = std::move(work)]() mutable {
    std::optional<Result> result;
    std::exception_ptr error;
    try {
      result.emplace(work());
    } catch (...) {
      error = std::current_exception();
    }
    std::lock_guard<std::mutex> lock(shared->mutex);
    shared->result = std::move(result);
    shared->error = error;
    shared->done = true;
    shared->done_cv.notify_all();
  });
  std::unique_lock<std::mutex> lock(shared->mutex);
  while (!shared->done) {
    if (cancel->load(std::memory_order_relaxed)) {
      lock.unlock();
      thread.detach();  // `shared` keeps the state alive until the thread ends
      return std::nullopt;
    }
    shared->done_cv.wait_for(lock, poll);
    if (while_waiting) {
      lock.unlock();
      while_waiting();
      lock.lock();
    }
  }
  lock.unlock();
  thread.join();
  if (shared->error) std::rethrow_exception(shared->error);
  return std::move(shared->result);
}

}  // namespace spidarcad
