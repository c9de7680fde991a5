// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
// A lock-free single-producer single-consumer triple buffer: the haptic thread publishes a
// value every tick, the app reads the latest one whenever it wants. Neither side ever waits or
// allocates; the reader sees whole values only (never a value being written), and always the
// most recently published one (older ones are skipped).
#pragma once

#include <atomic>
#include <cstdint>
#include <type_traits>

namespace spidarcad::haptics {

// Three slots: the writer owns one (back), the reader owns one (front), the third (middle) is
// exchanged atomically. The middle index carries a "fresh" bit set by the writer and cleared
// by the reader. T must be copy-assignable without allocation (fixed-size types) for the
// real-time guarantee to hold.
template <class T>
class TripleBuffer {
 public:
  // All three slots start as `initial`.
  explicit TripleBuffer(const T& initial = T{}) {
    for (auto& slot : slots_) slot.value = initial;
  }
  TripleBuffer(const TripleBuffer&) = delete;
  TripleBuffer& operator=(const TripleBuffer&) = delete;

  // Writer side (one thread): the slot to fill, then Publish().
  T& WriteSlot() noexcept { return slots_[back_].value; }
  // Writer side: makes the filled slot the latest value.
  void Publish() noexcept {
    back_ = middle_.exchange(static_cast<std::uint8_t>(back_ | kFresh), std::memory_order_acq_rel) &
            kIndexMask;
  }
  // Writer side: copies `value` into the write slot and publishes it.
  void Write(const T& value) noexcept {
    WriteSlot() = value;
    Publish();
  }

  // Reader side (one thread): takes the latest published value if there is a new one. Returns
  // true when a new value arrived since the last call.
  bool Update() noexcept {
    if ((middle_.load(std::memory_order_relaxed) & kFresh) == 0) return false;
    front_ = middle_.exchange(front_, std::memory_order_acq_rel) & kIndexMask;
    return true;
  }
  // Reader side: the value taken by the last Update() (stable until the next Update()).
  const T& Read() const noexcept { return slots_[front_].value; }
  // Reader side: Update() then Read().
  const T& Latest() noexcept {
    Update();
    return Read();
  }

 private:
  static constexpr std::uint8_t kIndexMask = 0x3;
  static constexpr std::uint8_t kFresh = 0x4;
  struct alignas(64) Slot {
    T value;
  };
  Slot slots_[3];
  alignas(64) std::atomic<std::uint8_t> middle_{1};
  alignas(64) std::uint8_t back_ = 0;   // writer's slot
  alignas(64) std::uint8_t front_ = 2;  // reader's slot
};

}  // namespace spidarcad::haptics
