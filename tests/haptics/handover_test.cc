// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#include "spidarcad/haptics/handover.h"

#include <gtest/gtest.h>

#include <atomic>
#include <memory>
#include <thread>

namespace spidarcad::haptics {
namespace {

// Counts its live instances, so a test sees who freed what.
struct Counted {
  explicit Counted(int v, int* live) : value(v), live_count(live) { ++*live_count; }
  ~Counted() { --*live_count; }
  Counted(const Counted&) = delete;
  Counted& operator=(const Counted&) = delete;
  int value;
  int* live_count;
};

TEST(Handover, ReaderGetsNullBeforeTheFirstOffer) {
  Handover<Counted> handover;
  EXPECT_EQ(handover.Acquire(), nullptr);
  EXPECT_EQ(handover.active(), nullptr);
  EXPECT_FALSE(handover.Collect());
}

TEST(Handover, AnOfferTheReaderNeverTookIsReplacedAndFreedByTheApp) {
  int live = 0;
  {
    Handover<Counted> handover;
    handover.Offer(std::make_unique<Counted>(1, &live));
    handover.Offer(std::make_unique<Counted>(2, &live));
    EXPECT_EQ(live, 1);  // the unseen first one is gone
    Counted* taken = handover.Acquire();
    ASSERT_NE(taken, nullptr);
    EXPECT_EQ(taken->value, 2);
  }
  EXPECT_EQ(live, 0);  // the destructor frees what is left
}

TEST(Handover, TheReaderRetiresWithoutFreeingAndTheAppFreesOnCollect) {
  int live = 0;
  Handover<Counted> handover;
  handover.Offer(std::make_unique<Counted>(1, &live));
  EXPECT_EQ(handover.Acquire()->value, 1);
  EXPECT_EQ(handover.Acquire()->value, 1);  // nothing new: the same one
  handover.Offer(std::make_unique<Counted>(2, &live));
  EXPECT_EQ(handover.Acquire()->value, 2);  // 1 retired, not freed by the reader
  EXPECT_EQ(live, 2);
  EXPECT_TRUE(handover.Collect());  // the app frees 1
  EXPECT_EQ(live, 1);
  EXPECT_FALSE(handover.Collect());
  // An offer frees what was retired before it becomes pending.
  handover.Offer(std::make_unique<Counted>(3, &live));
  EXPECT_EQ(handover.Acquire()->value, 3);              // 2 retired
  handover.Offer(std::make_unique<Counted>(4, &live));  // frees 2
  EXPECT_EQ(live, 2);                                   // 3 active, 4 pending
  EXPECT_EQ(handover.active()->value, 3);
}

// One app thread offers numbered objects while a reader thread acquires: the reader sees the
// numbers in increasing order and never a freed object (ASan would report a use after free),
// and in the end only the active object is left alive.
TEST(Handover, ConcurrentOffersReachTheReaderInOrder) {
  std::atomic<int> live{0};
  struct Numbered {
    Numbered(int v, std::atomic<int>* l) : value(v), live_count(l) { ++*live_count; }
    ~Numbered() { --*live_count; }
    int value;
    std::atomic<int>* live_count;
  };
  constexpr int kOffers = 20000;
  {
    Handover<Numbered> handover;
    std::atomic<int> last_seen{-1};
    std::atomic<bool> in_order{true};
    std::thread reader([&] {
      while (last_seen.load() != kOffers - 1) {
        const Numbered* n = handover.Acquire();
        if (n == nullptr) continue;
        if (n->value < last_seen.load()) in_order.store(false);
        last_seen.store(n->value);
      }
    });
    for (int i = 0; i < kOffers; ++i) handover.Offer(std::make_unique<Numbered>(i, &live));
    // The reader takes the last offer once the app has freed what it retired.
    while (last_seen.load() != kOffers - 1) {
      handover.Collect();
      std::this_thread::yield();
    }
    reader.join();
    EXPECT_TRUE(in_order.load());
    handover.Collect();
    EXPECT_EQ(live.load(), 1);  // only the active one
  }
  EXPECT_EQ(live.load(), 0);
}

}  // namespace
}  // namespace spidarcad::haptics
