// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#include "support/malloc_counter.h"

#include <atomic>
#include <cerrno>
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
extern "C" void* __libc_calloc(std::size_t n, std::size_t size);
extern "C" void* __libc_realloc(void* ptr, std::size_t size);
extern "C" void* __libc_memalign(std::size_t alignment, std::size_t size);
extern "C" void* __libc_valloc(std::size_t size);
#endif

namespace {
std::atomic<long> g_malloc_count{0};
std::atomic<bool> g_counting{false};
std::atomic<bool> g_this_thread_only{false};
thread_local bool t_measuring = false;  // the thread that constructed a kThisThread counter

// Whether an allocation made now on this thread counts.
inline bool Counts() {
  return g_counting.load(std::memory_order_relaxed) &&
         (!g_this_thread_only.load(std::memory_order_relaxed) || t_measuring);
}
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
  if (!Counts() || t_tracing) return;
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
// tells whether this one is in use. Every function that can hand out a new block counts: a
// realloc counts whether or not it moves the block (it may), not when it frees (size 0).
namespace {
inline void Count() {
  if (Counts()) g_malloc_count.fetch_add(1, std::memory_order_relaxed);
}
inline bool PowerOfTwo(std::size_t n) { return n != 0 && (n & (n - 1)) == 0; }
}  // namespace
extern "C" __attribute__((weak)) void* malloc(std::size_t size) {
  Count();
  return __libc_malloc(size);
}
extern "C" __attribute__((weak)) void* calloc(std::size_t n, std::size_t size) {
  Count();
  return __libc_calloc(n, size);
}
extern "C" __attribute__((weak)) void* realloc(void* ptr, std::size_t size) {
  if (size != 0 || ptr == nullptr) Count();
  return __libc_realloc(ptr, size);
}
extern "C" __attribute__((weak)) void* memalign(std::size_t alignment, std::size_t size) {
  Count();
  return __libc_memalign(alignment, size);
}
extern "C" __attribute__((weak)) void* aligned_alloc(std::size_t alignment, std::size_t size) {
  Count();
  return __libc_memalign(alignment, size);
}
extern "C" __attribute__((weak)) int posix_memalign(void** out, std::size_t alignment,
                                                    std::size_t size) {
  if (!PowerOfTwo(alignment) || alignment % sizeof(void*) != 0) return EINVAL;
  Count();
  void* p = __libc_memalign(alignment, size);
  if (p == nullptr) return ENOMEM;
  *out = p;
  return 0;
}
extern "C" __attribute__((weak)) void* valloc(std::size_t size) {
  Count();
  return __libc_valloc(size);
}
#endif

namespace spidarcad::test_support {

MallocCounter::MallocCounter(Threads threads) {
  g_malloc_count.store(0);
  t_measuring = true;
  g_this_thread_only.store(threads == Threads::kThisThread);
  g_counting.store(true);
}

MallocCounter::~MallocCounter() {
  g_counting.store(false);
  g_this_thread_only.store(false);
  t_measuring = false;
}

long MallocCounter::count() const { return g_malloc_count.load(); }

bool MallocCounterActive() {
  MallocCounter counter;
  auto* probe = new std::vector<double>(100);
  delete probe;
  return counter.count() > 0;
}

}  // namespace spidarcad::test_support
