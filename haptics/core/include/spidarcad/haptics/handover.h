// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
// The hand-over of immutable objects from the app to the haptic thread (ARCHITECTURE.md): the app
// builds an object and offers it; the haptic thread takes the newest one at the start of a tick
// and hands the one it used back; the app frees what was handed back. Three atomic raw pointers,
// not std::atomic<std::shared_ptr> (not lock-free in gcc 12's libstdc++):
//   pending  written by the app (Offer), taken by the haptic thread (Acquire);
//   active   owned by the haptic thread (the object in use);
//   retired  the previous active object, handed back by the haptic thread; the app deletes it in
//            Offer / Collect, so no destructor (free) ever runs on the haptic thread. The haptic
//            thread takes a pending object only while retired is empty, so it never has to free
//            anything itself; an object offered twice before the haptic thread took the first
//            replaces it (the app deletes the unseen one).
// One writer thread (the app) and one reader thread (the haptic thread). HapticLoop hands its
// scenes over this way, and the clay hands its distance grids to the grasp.
#pragma once

#include <atomic>
#include <memory>

namespace spidarcad::haptics {

template <class T>
class Handover {
 public:
  Handover() = default;
  // Frees all three (no thread may use the hand-over any more).
  ~Handover() {
    delete pending_.exchange(nullptr);
    delete retired_.exchange(nullptr);
    delete active_;
  }
  Handover(const Handover&) = delete;
  Handover& operator=(const Handover&) = delete;

  // App side: frees what the haptic thread retired, then makes `object` the pending one,
  // freeing a pending object that was never taken (a null `object` just withdraws that one:
  // to hand the reader "nothing", offer an object that says so).
  void Offer(std::unique_ptr<T> object) {
    Collect();
    delete pending_.exchange(object.release(), std::memory_order_acq_rel);
  }
  // App side: frees the object the haptic thread retired, if any; true when one was freed.
  bool Collect() {
    T* retired = retired_.exchange(nullptr, std::memory_order_acq_rel);
    delete retired;
    return retired != nullptr;
  }

  // Haptic thread: takes the pending object if there is one and the retired slot is empty
  // (retiring the active one), and returns the active object (null before the first offer).
  // Lock-free, allocation-free, frees nothing.
  T* Acquire() noexcept {
    // Only this thread stores a non-null retired pointer, so once seen empty it stays empty
    // until this thread fills it: the hand-back never overwrites an object the app has not
    // freed yet.
    if (retired_.load(std::memory_order_acquire) != nullptr) return active_;
    if (pending_.load(std::memory_order_relaxed) == nullptr) return active_;
    T* next = pending_.exchange(nullptr, std::memory_order_acq_rel);
    if (next == nullptr) return active_;
    retired_.store(active_, std::memory_order_release);
    active_ = next;
    return active_;
  }
  // Haptic thread: the active object, as the last Acquire left it.
  T* active() const noexcept { return active_; }

 private:
  std::atomic<T*> pending_{nullptr};
  std::atomic<T*> retired_{nullptr};
  T* active_ = nullptr;  // the haptic thread's
};

}  // namespace spidarcad::haptics
