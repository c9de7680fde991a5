// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#include "spidarcad/haptics/realtime_memory.h"

#include <alloca.h>
#include <linux/capability.h>
#include <sys/mman.h>
#include <sys/resource.h>
#include <sys/syscall.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstdint>
#include <cstring>

namespace spidarcad::haptics {

namespace {

constexpr std::size_t kPage = 4096;

int RealLockAll(int flags) { return mlockall(flags); }

// CAP_IPC_LOCK in the effective set (capget(2)), or RLIMIT_MEMLOCK unlimited.
bool RealMayLockUnlimited() {
  rlimit limit{};
  if (getrlimit(RLIMIT_MEMLOCK, &limit) == 0 && limit.rlim_cur == RLIM_INFINITY) return true;
  __user_cap_header_struct header{};
  header.version = _LINUX_CAPABILITY_VERSION_3;
  header.pid = 0;
  __user_cap_data_struct data[_LINUX_CAPABILITY_U32S_3] = {};
  if (syscall(SYS_capget, &header, data) != 0) return false;
  return (data[CAP_IPC_LOCK / 32].effective & (1u << (CAP_IPC_LOCK % 32))) != 0;
}

// The soft RLIMIT_MEMLOCK in KiB for messages; −1 when unlimited or unknown.
long MemlockLimitKiB() {
  rlimit limit{};
  if (getrlimit(RLIMIT_MEMLOCK, &limit) != 0 || limit.rlim_cur == RLIM_INFINITY) return -1;
  return static_cast<long>(limit.rlim_cur / 1024);
}

// Writes one byte per page of [p, p + bytes) through a volatile pointer (not optimised away).
void TouchPages(char* p, std::size_t bytes) noexcept {
  volatile char* v = p;
  for (std::size_t i = 0; i < bytes; i += kPage) v[i] = 0;
  if (bytes > 0) v[bytes - 1] = 0;
}

}  // namespace

const char* MemoryLockStatusName(MemoryLockStatus status) {
  switch (status) {
    case MemoryLockStatus::kNotRequested:
      return "not_requested";
    case MemoryLockStatus::kLocked:
      return "locked";
    case MemoryLockStatus::kLimited:
      return "limited";
    case MemoryLockStatus::kRefused:
      return "refused";
  }
  return "unknown";
}

MemoryLockResult LockProcessMemory(const MemoryLockCalls& calls) {
  int (*lock_all)(int) = calls.lock_all ? calls.lock_all : &RealLockAll;
  bool (*may_lock_unlimited)() =
      calls.may_lock_unlimited ? calls.may_lock_unlimited : &RealMayLockUnlimited;
  MemoryLockResult result;
  if (!may_lock_unlimited()) {
    result.status = MemoryLockStatus::kLimited;
    const long kib = MemlockLimitKiB();
    result.message =
        "memory lock: not locked (no CAP_IPC_LOCK and RLIMIT_MEMLOCK " +
        (kib >= 0 ? std::to_string(kib) + " KiB" : std::string("finite")) +
        "): a page fault can delay a haptic tick; grant CAP_IPC_LOCK or raise the limit "
        "(ulimit -l unlimited) to lock";
    return result;
  }
  errno = 0;
  if (lock_all(MCL_CURRENT | MCL_FUTURE) != 0) {
    result.error = errno;
    result.status = MemoryLockStatus::kRefused;
    result.message = std::string("memory lock: mlockall(MCL_CURRENT | MCL_FUTURE) refused (") +
                     std::strerror(result.error) +
                     "): running unlocked, a page fault can delay a haptic tick";
    return result;
  }
  result.status = MemoryLockStatus::kLocked;
  result.message = "memory lock: the process's pages are locked in RAM (mlockall)";
  return result;
}

void UnlockProcessMemory() noexcept { munlockall(); }

std::size_t PrefaultStack(std::size_t bytes) noexcept {
  // Bounded well below the smallest stack this runs on (8 MiB by default on Linux).
  bytes = std::min<std::size_t>(bytes, 4u << 20);
  if (bytes == 0) return 0;
  char* block = static_cast<char*>(alloca(bytes));
  TouchPages(block, bytes);
  return (bytes + kPage - 1) / kPage;
}

}  // namespace spidarcad::haptics
