// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#include "support/malloc_counter.h"

#include <atomic>
#include <cstddef>
#include <cstdio>
#include <cstdlib>
#include <vector>

#if defined(__SANITIZE_ADDRESS__)
#define SPIDARCAD_ASAN 1
#elif defined(__has_feature)
#if __has_feature(address_sanitizer)
#define SPIDARCAD_ASAN 1
#endif
#endif

#ifdef SPIDARCAD_ASAN
// Declared here rather than through <sanitizer/allocator_interface.h>, which clang ships and
// GCC 12 does not; both runtimes (libasan, libclang_rt.asan) define the function.
extern "C" int __sanitizer_install_malloc_and_free_hooks(
    void (*malloc_hook)(const volatile void* ptr, std::size_t size),
    void (*free_hook)(const volatile void* ptr));
extern "C" void __sanitizer_print_stack_trace();
#else
extern "C" void* __libc_malloc(std::size_t size);
#endif

namespace {
std::atomic<long> g_malloc_count{0};
std::atomic<bool> g_counting{false};
}  // namespace

#ifdef SPIDARCAD_ASAN
// Under AddressSanitizer (scripts/sanitize.sh) the sanitizer owns malloc: an interposer would
// hand it blocks it did not allocate. Its allocation hook counts instead (malloc and new alike).
// The runtime installs a pair only when both hooks are given (a null free hook installs
// nothing), hence the empty one.
namespace {
// SPIDARCAD_MALLOC_COUNTER_TRACE=1 prints the size and the stack of every counted allocation
// (stderr), to find where a counted one comes from; tracing itself is not counted.
const bool g_trace = std::getenv("SPIDARCAD_MALLOC_COUNTER_TRACE") != nullptr;
thread_local bool t_tracing = false;
void CountAllocation(const volatile void* /*ptr*/, std::size_t size) {
  if (!g_counting.load(std::memory_order_relaxed) || t_tracing) return;
  g_malloc_count.fetch_add(1, std::memory_order_relaxed);
  if (g_trace) {
    t_tracing = true;
    std::fprintf(stderr, "MallocCounter: counted an allocation of %zu bytes at\n", size);
    __sanitizer_print_stack_trace();
    t_tracing = false;
  }
}
void IgnoreFree(const volatile void* /*ptr*/) {}
const int g_hook_installed = __sanitizer_install_malloc_and_free_hooks(CountAllocation, IgnoreFree);
}  // namespace
#else
// Weak, so that a test executable with its own interposer still links; MallocCounterActive
// tells whether this one is in use.
extern "C" __attribute__((weak)) void* malloc(std::size_t size) {
  if (g_counting.load(std::memory_order_relaxed)) {
    g_malloc_count.fetch_add(1, std::memory_order_relaxed);
  }
  return __libc_malloc(size);
}
#endif

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
