// Counts heap allocations, so a test can prove that real-time code (everything a 1 kHz haptic
// tick calls) allocates nothing. The test executable's malloc, calloc, realloc and the aligned
// allocators (posix_memalign, aligned_alloc, memalign, valloc) interpose the C library's;
// operator new goes through malloc or the aligned ones. Under AddressSanitizer the sanitizer's
// allocation hook counts instead (every kind alike).
// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#pragma once

namespace spidarcad::test_support {

// Counts allocations made while alive. Not reentrant: one at a time.
class MallocCounter {
 public:
  enum class Threads {
    kAll,         // from any thread of the process
    kThisThread,  // only those made on the thread that constructed the counter: for a tick
                  // called on the test's thread while other threads (a column or patch worker,
                  // libusb's event thread) allocate as they may
  };
  explicit MallocCounter(Threads threads = Threads::kAll);
  ~MallocCounter();
  MallocCounter(const MallocCounter&) = delete;
  MallocCounter& operator=(const MallocCounter&) = delete;
  // Allocations since construction.
  long count() const;
};

// True when this process's malloc is the counting one (checked with a probe allocation);
// false if another interposer (a sanitizer, a replacement in the test file) took precedence.
bool MallocCounterActive();

}  // namespace spidarcad::test_support
