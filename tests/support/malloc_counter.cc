// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#include "support/malloc_counter.h"

#include <atomic>
#include <cstddef>
#include <cstdlib>
#include <vector>

extern "C" void* __libc_malloc(std::size_t size);

namespace {
std::atomic<long> g_malloc_count{0};
std::atomic<bool> g_counting{false};
}  // namespace

// Weak, so that a test executable with its own interposer still links; MallocCounterActive
// tells whether this one is in use.
extern "C" __attribute__((weak)) void* malloc(std::size_t size) {
  if (g_counting.load(std::memory_order_relaxed)) {
    g_malloc_count.fetch_add(1, std::memory_order_relaxed);
  }
  return __libc_malloc(size);
}

namespace spidarcad::test_support {

MallocCounter::MallocCounter() {
  g_malloc_count.store(0);
  g_counting.store(true);
}

MallocCounter::~MallocCounter() { g_counting.store(false); }

long MallocCounter::count() const { return g_malloc_count.load(); }

bool MallocCounterActive() {
  MallocCounter counter;
  auto* probe = new std::vector<double>(100);
  delete probe;
  return counter.count() > 0;
}

}  // namespace spidarcad::test_support
