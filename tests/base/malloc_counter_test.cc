// Tests of the allocation counter of the no-allocation tests (tests/support/malloc_counter.h):
// it must see every kind of allocation on the measuring thread (or those tests prove nothing),
// and in kThisThread mode it must not see other threads' allocations, while still catching a
// deliberate allocation on the measuring thread (the case of a tick that allocates).
// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#include "support/malloc_counter.h"

#include <gtest/gtest.h>

#include <atomic>
#include <cstdlib>
#include <memory>
#include <thread>
#include <vector>

namespace spidarcad::test_support {
namespace {

// Keeps a pointer from being optimised away (an allocation the compiler could elide).
void Keep(void* p) { asm volatile("" : : "g"(p) : "memory"); }

// Allocations counted while `allocate` runs on this thread.
template <typename Allocate>
long Counted(MallocCounter::Threads threads, const Allocate& allocate) {
  long count = 0;
  {
    MallocCounter counter(threads);
    allocate();
    count = counter.count();
  }
  return count;
}

TEST(MallocCounter, SeesEveryKindOfAllocationOnTheMeasuringThread) {
  ASSERT_TRUE(MallocCounterActive());
  for (const MallocCounter::Threads threads :
       {MallocCounter::Threads::kAll, MallocCounter::Threads::kThisThread}) {
    EXPECT_GE(Counted(threads,
                      [] {
                        void* p = std::malloc(24);
                        Keep(p);
                        std::free(p);
                      }),
              1);
    EXPECT_GE(Counted(threads,
                      [] {
                        void* p = std::calloc(3, 8);
                        Keep(p);
                        std::free(p);
                      }),
              1);
    void* grown = std::malloc(8);
    EXPECT_GE(Counted(threads,
                      [&grown] {
                        grown = std::realloc(grown, 1 << 16);
                        Keep(grown);
                      }),
              1);
    std::free(grown);
    EXPECT_GE(Counted(threads,
                      [] {
                        void* p = std::aligned_alloc(64, 128);
                        Keep(p);
                        std::free(p);
                      }),
              1);
    EXPECT_GE(Counted(threads,
                      [] {
                        void* p = nullptr;
                        if (posix_memalign(&p, 64, 128) == 0) Keep(p);
                        std::free(p);
                      }),
              1);
    EXPECT_GE(Counted(threads, [] { Keep(std::make_unique<std::vector<double>>(100).get()); }), 1);
    struct alignas(64) Wide {
      double x[8];
    };
    EXPECT_GE(Counted(threads, [] { Keep(std::make_unique<Wide>().get()); }), 1);
    EXPECT_EQ(Counted(threads, [] {}), 0);
  }
}

// Another thread allocates while the counter runs on this one: kAll counts it, kThisThread does
// not; a deliberate allocation on this thread is caught either way. The other thread exists
// before the counter starts (making a thread allocates) and is driven through atomics only.
TEST(MallocCounter, ThisThreadModeIgnoresOtherThreadsAndStillCatchesItsOwn) {
  ASSERT_TRUE(MallocCounterActive());
  std::atomic<int> go{0}, done{0};
  std::thread other([&] {
    for (int round = 1; round <= 4; ++round) {
      while (go.load() < round) std::this_thread::yield();
      for (int k = 0; k < 10; ++k) Keep(std::make_unique<std::vector<double>>(100).get());
      done.store(round);
    }
  });
  // Runs one round of the other thread's allocations (and `own` here) under a counter.
  const auto round = [&](int r, MallocCounter::Threads threads, bool own) {
    long count = 0;
    {
      MallocCounter counter(threads);
      go.store(r);
      while (done.load() < r) std::this_thread::yield();
      if (own) Keep(std::make_unique<std::vector<double>>(100).get());
      count = counter.count();
    }
    return count;
  };
  EXPECT_GE(round(1, MallocCounter::Threads::kAll, false), 10);
  EXPECT_EQ(round(2, MallocCounter::Threads::kThisThread, false), 0);
  EXPECT_GE(round(3, MallocCounter::Threads::kThisThread, true), 1);
  EXPECT_GE(round(4, MallocCounter::Threads::kAll, true), 11);
  other.join();
}

}  // namespace
}  // namespace spidarcad::test_support
