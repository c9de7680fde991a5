// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
// Memory set-up for a real-time thread, done once before its first tick so that no tick waits
// for the kernel: lock the process's pages in RAM (mlockall), touch the thread's stack, and
// let the caller run untimed warm-up ticks (HapticLoop::Step over its own buffers).
//
// Locking: mlockall(MCL_CURRENT | MCL_FUTURE) keeps every mapped page resident (no page fault
// after reclaim or swap, every page of a later allocation faulted in by the allocation, not by
// its first use inside a tick). It is asked for only when the process may lock without a limit
// (CAP_IPC_LOCK, or RLIMIT_MEMLOCK unlimited): an ordinary user under the usual 8 MiB limit
// could lock its current pages, but MCL_FUTURE would then make every later allocation past the
// limit fail (ENOMEM, std::bad_alloc). Otherwise the memory stays unlocked and the status says
// why; the caller logs MemoryLockResult::message once, outside any tick.
#pragma once

#include <cstddef>
#include <string>

namespace spidarcad::haptics {

// What LockProcessMemory did.
enum class MemoryLockStatus {
  kNotRequested,  // not asked for
  kLocked,        // mlockall(MCL_CURRENT | MCL_FUTURE) succeeded
  kLimited,       // not tried: no CAP_IPC_LOCK and RLIMIT_MEMLOCK is finite (see above)
  kRefused,       // mlockall failed (EPERM, ENOMEM, ...): memory not locked
};
// One word per status ("not_requested", "locked", "limited", "refused").
const char* MemoryLockStatusName(MemoryLockStatus status);

// The outcome of LockProcessMemory: the status and one line for the log (what happened, and
// for kLimited / kRefused what to do about it).
struct MemoryLockResult {
  MemoryLockStatus status = MemoryLockStatus::kNotRequested;
  int error = 0;  // errno of a refused mlockall
  std::string message;
};

// The system calls LockProcessMemory makes; tests replace them. Null members are the real
// calls: mlockall(2), and "may lock without a limit" = CAP_IPC_LOCK in the effective set or
// RLIMIT_MEMLOCK = RLIM_INFINITY.
struct MemoryLockCalls {
  int (*lock_all)(int flags) = nullptr;  // returns 0, or −1 with errno set
  bool (*may_lock_unlimited)() = nullptr;
};

// Locks the process's current and future pages (see the file comment). Never throws, never
// aborts. Process-wide: call it from the main thread before starting the real-time thread.
MemoryLockResult LockProcessMemory(const MemoryLockCalls& calls = {});

// Undoes a kLocked LockProcessMemory (munlockall). Process-wide.
void UnlockProcessMemory() noexcept;

// Default amount of stack PrefaultStack touches, bytes: well above the deepest tick's frames
// (the haptic loop with the heaviest field).
inline constexpr std::size_t kPrefaultStackBytes = 256 * 1024;

// Touches `bytes` of the calling thread's stack below the caller's frame (one write per 4 KiB
// page), so that the tick's deepest call chain finds its stack pages present. Call it on the
// real-time thread before the first tick. Returns the number of pages touched.
std::size_t PrefaultStack(std::size_t bytes = kPrefaultStackBytes) noexcept;

}  // namespace spidarcad::haptics
