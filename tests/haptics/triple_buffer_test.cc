// Tests of the lock-free triple buffer: latest-value semantics on one thread, and whole,
// in-order values under a concurrent writer and reader (seeded payloads).
// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#include "spidarcad/haptics/triple_buffer.h"

#include <gtest/gtest.h>

#include <array>
#include <atomic>
#include <cstdint>
#include <thread>

namespace spidarcad::haptics {
namespace {

// splitmix64: the payload of message `seq`, word `i`, from a seed (independent of the buffer).
std::uint64_t Mix(std::uint64_t x) {
  x += 0x9e3779b97f4a7c15ULL;
  x = (x ^ (x >> 30)) * 0xbf58476d1ce4e5b9ULL;
  x = (x ^ (x >> 27)) * 0x94d049bb133111ebULL;
  return x ^ (x >> 31);
}

struct Message {
  std::uint64_t seq = 0;
  std::array<std::uint64_t, 15> words{};
};

Message Make(std::uint64_t seed, std::uint64_t seq) {
  Message m;
  m.seq = seq;
  for (std::size_t i = 0; i < m.words.size(); ++i) m.words[i] = Mix(seed ^ (seq * 31 + i));
  return m;
}

TEST(TripleBuffer, ReaderSeesTheLatestValueOnly) {
  TripleBuffer<int> buffer(-1);
  EXPECT_FALSE(buffer.Update());
  EXPECT_EQ(buffer.Read(), -1);
  buffer.Write(1);
  buffer.Write(2);
  buffer.Write(3);
  EXPECT_TRUE(buffer.Update());
  EXPECT_EQ(buffer.Read(), 3);
  EXPECT_FALSE(buffer.Update());  // nothing new
  EXPECT_EQ(buffer.Read(), 3);
  buffer.Write(4);
  EXPECT_EQ(buffer.Latest(), 4);
  buffer.WriteSlot() = 5;  // not yet published
  EXPECT_FALSE(buffer.Update());
  EXPECT_EQ(buffer.Read(), 4);
  buffer.Publish();
  EXPECT_EQ(buffer.Latest(), 5);
}

TEST(TripleBuffer, ConcurrentReaderSeesWholeIncreasingValues) {
  constexpr std::uint64_t kSeed = 20261122;
  constexpr std::uint64_t kCount = 300000;
  TripleBuffer<Message> buffer(Make(kSeed, 0));
  // The writer races the reader within blocks of kBlock writes; at the end of each block it waits
  // until the reader has seen a value of the previous block, so the two overlap however the
  // threads are scheduled (on a loaded machine the writer could otherwise finish first).
  constexpr std::uint64_t kBlock = 1000;
  std::atomic<bool> done{false};
  std::atomic<std::uint64_t> seen{0};
  std::thread writer([&] {
    for (std::uint64_t seq = 1; seq <= kCount; ++seq) {
      buffer.Write(Make(kSeed, seq));
      if (seq % kBlock == 0) {
        while (seen.load() + kBlock < seq) std::this_thread::yield();
      }
    }
    done = true;
  });
  std::uint64_t last = 0, reads = 0, torn = 0, backwards = 0, fresh = 0;
  while (true) {
    const bool finished = done.load();
    if (buffer.Update()) ++fresh;
    const Message& m = buffer.Read();
    ++reads;
    if (m.seq < last) ++backwards;
    if (!(m.words == Make(kSeed, m.seq).words)) ++torn;
    last = m.seq;
    seen.store(m.seq);
    if (finished) break;
  }
  writer.join();
  buffer.Update();
  EXPECT_EQ(buffer.Read().seq, kCount);
  EXPECT_EQ(torn, 0u);
  EXPECT_EQ(backwards, 0u);
  // Each wait needs a value at least one block old; one fresh value serves at most two waits.
  EXPECT_GE(fresh, kCount / kBlock / 2);
  EXPECT_GT(reads, 1u);
}

}  // namespace
}  // namespace spidarcad::haptics
