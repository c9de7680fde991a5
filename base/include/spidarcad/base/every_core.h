// Work shared out over the machine's cores, the calling thread among them.
// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#pragma once

#include <algorithm>
#include <cstddef>
#include <system_error>
#include <thread>
#include <vector>

namespace spidarcad::base {

// Runs `work` on min(tasks, cores) threads, this one among them (fewer when no thread can be
// started), and returns once every one has returned. `work` takes its tasks itself (say from an
// atomic counter) and must not throw; nothing is run for no tasks.
template <class Work>
void RunOnEveryCore(std::size_t tasks, Work&& work) {
  if (tasks == 0) return;
  const std::size_t helpers =
      std::min<std::size_t>(tasks, std::max(1u, std::thread::hardware_concurrency())) - 1;
  std::vector<std::thread> threads;
  for (std::size_t t = 0; t < helpers; ++t) {
    try {
      threads.emplace_back(work);
    } catch (const std::system_error&) {
      break;  // fewer threads: this one does the rest
    }
  }
  work();
  for (std::thread& t : threads) t.join();
}

}  // namespace spidarcad::base
