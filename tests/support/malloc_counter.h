// Counts heap allocations of the whole test process, so a test can prove that real-time code
// (everything a 1 kHz haptic tick calls) allocates nothing. The test executable's malloc
// interposes the C library's; operator new goes through it too.
// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#pragma once

namespace spidarcad::test_support {

// Counts mallocs made while alive (from any thread). Not reentrant: one at a time.
class MallocCounter {
 public:
  MallocCounter();
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
