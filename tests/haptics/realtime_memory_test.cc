// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
// The real-time thread's memory set-up (realtime_memory.h): the lock's decision and its fallback
// with the system calls replaced (no test locks this process's memory), and the stack prefault
// checked by the page faults the kernel counts on a thread whose stack is fresh memory.
#include "spidarcad/haptics/realtime_memory.h"

#include <alloca.h>
#include <gtest/gtest.h>
#include <pthread.h>
#include <sys/mman.h>
#include <sys/resource.h>

#include <cerrno>
#include <cstring>
#include <string>

#include "spidarcad/haptics/loop_runner.h"

namespace spidarcad::haptics {
namespace {

int g_lock_calls = 0;
int g_lock_flags = 0;

int FakeLockRefused(int flags) {
  ++g_lock_calls;
  g_lock_flags = flags;
  errno = EPERM;
  return -1;
}
int FakeLockNoMemory(int flags) {
  ++g_lock_calls;
  g_lock_flags = flags;
  errno = ENOMEM;
  return -1;
}
int FakeLockOk(int flags) {
  ++g_lock_calls;
  g_lock_flags = flags;
  return 0;
}
bool Unlimited() { return true; }
bool Limited() { return false; }

TEST(LockProcessMemory, LocksCurrentAndFuturePagesWhenPermitted) {
  g_lock_calls = 0;
  MemoryLockCalls calls;
  calls.lock_all = &FakeLockOk;
  calls.may_lock_unlimited = &Unlimited;
  const MemoryLockResult r = LockProcessMemory(calls);
  EXPECT_EQ(r.status, MemoryLockStatus::kLocked);
  EXPECT_EQ(g_lock_calls, 1);
  EXPECT_EQ(g_lock_flags, MCL_CURRENT | MCL_FUTURE);
  EXPECT_EQ(r.error, 0);
  EXPECT_STREQ(MemoryLockStatusName(r.status), "locked");
}

TEST(LockProcessMemory, FallsBackWithOneLineWhenMlockallIsRefused) {
  for (auto fake : {&FakeLockRefused, &FakeLockNoMemory}) {
    g_lock_calls = 0;
    MemoryLockCalls calls;
    calls.lock_all = fake;
    calls.may_lock_unlimited = &Unlimited;
    const MemoryLockResult r = LockProcessMemory(calls);
    EXPECT_EQ(r.status, MemoryLockStatus::kRefused);
    EXPECT_EQ(g_lock_calls, 1);
    const int expected = fake == &FakeLockRefused ? EPERM : ENOMEM;
    EXPECT_EQ(r.error, expected);
    EXPECT_NE(r.message.find("refused"), std::string::npos) << r.message;
    EXPECT_NE(r.message.find(std::strerror(expected)), std::string::npos) << r.message;
    EXPECT_EQ(r.message.find('\n'), std::string::npos) << "one line: " << r.message;
    EXPECT_STREQ(MemoryLockStatusName(r.status), "refused");
  }
}

TEST(LockProcessMemory, DoesNotLockUnderAFiniteLimitWithoutTheCapability) {
  // MCL_FUTURE under a finite RLIMIT_MEMLOCK would make later allocations fail: not tried.
  g_lock_calls = 0;
  MemoryLockCalls calls;
  calls.lock_all = &FakeLockOk;
  calls.may_lock_unlimited = &Limited;
  const MemoryLockResult r = LockProcessMemory(calls);
  EXPECT_EQ(r.status, MemoryLockStatus::kLimited);
  EXPECT_EQ(g_lock_calls, 0);
  EXPECT_NE(r.message.find("RLIMIT_MEMLOCK"), std::string::npos) << r.message;
  EXPECT_EQ(r.message.find('\n'), std::string::npos);
  EXPECT_STREQ(MemoryLockStatusName(r.status), "limited");
  EXPECT_STREQ(MemoryLockStatusName(MemoryLockStatus::kNotRequested), "not_requested");
}

long ThreadMinorFaults() {
  rusage ru{};
  getrusage(RUSAGE_THREAD, &ru);
  return ru.ru_minflt;
}

// Uses `bytes` of stack below its frame, one write per page; returns the minor page faults the
// kernel counted on this thread meanwhile.
__attribute__((noinline)) long FaultsOfDeepFrame(std::size_t bytes) {
  const long before = ThreadMinorFaults();
  volatile char* block = static_cast<char*>(alloca(bytes));
  for (std::size_t i = 0; i < bytes; i += 4096) block[i] = 1;
  return ThreadMinorFaults() - before;
}

struct DeepFrameProbe {
  std::size_t prefault = 0;  // bytes PrefaultStack touches first (0: not called)
  std::size_t pages = 0;     // what PrefaultStack returned
  long faults = -1;          // minor faults of a 128 KiB deep frame afterwards
};

void* RunProbe(void* arg) {
  auto* probe = static_cast<DeepFrameProbe*>(arg);
  if (probe->prefault > 0) probe->pages = PrefaultStack(probe->prefault);
  probe->faults = FaultsOfDeepFrame(128 * 1024);
  return nullptr;
}

// Runs the probe on a thread whose 1 MiB stack is freshly mapped (never touched, unlike the
// stacks glibc caches for new threads).
DeepFrameProbe ProbeOnFreshStack(std::size_t prefault) {
  DeepFrameProbe probe;
  probe.prefault = prefault;
  const std::size_t size = 1 << 20;
  void* stack = mmap(nullptr, size, PROT_READ | PROT_WRITE, MAP_PRIVATE | MAP_ANONYMOUS, -1, 0);
  EXPECT_NE(stack, MAP_FAILED);
  if (stack == MAP_FAILED) return probe;
  madvise(stack, size, MADV_NOHUGEPAGE);  // one fault per 4 KiB page, whatever THP's setting
  pthread_attr_t attr;
  pthread_attr_init(&attr);
  pthread_attr_setstack(&attr, stack, size);
  pthread_t thread;
  EXPECT_EQ(pthread_create(&thread, &attr, &RunProbe, &probe), 0);
  pthread_join(thread, nullptr);
  pthread_attr_destroy(&attr);
  munmap(stack, size);
  return probe;
}

TEST(PrefaultStack, TheDeepestFrameFindsItsStackPagesPresent) {
  // Without the prefault a 128 KiB frame first-touches its 32 pages; after touching 256 KiB
  // it touches none for the first time.
  const DeepFrameProbe cold = ProbeOnFreshStack(0);
  EXPECT_GE(cold.faults, 16) << "the probe should fault on a fresh stack";
  const DeepFrameProbe warm = ProbeOnFreshStack(256 * 1024);
  EXPECT_EQ(warm.pages, 64u);
  EXPECT_LE(warm.faults, 1) << "pages present after PrefaultStack";
  EXPECT_EQ(PrefaultStack(0), 0u);
}

TEST(LoopRunner, PrefaultsItsStackBeforeTheFirstTick) {
  RunnerSettings settings;
  settings.try_realtime = false;
  LoopRunner runner(settings);
  EXPECT_EQ(runner.prefaulted_stack_pages(), 0u);
  runner.Start([](const TickTiming&) {});
  EXPECT_EQ(runner.prefaulted_stack_pages(), kPrefaultStackBytes / 4096);
  runner.Stop();
  settings.prefault_stack_bytes = 0;
  LoopRunner bare(settings);
  bare.Start([](const TickTiming&) {});
  EXPECT_EQ(bare.prefaulted_stack_pages(), 0u);
  bare.Stop();
}

}  // namespace
}  // namespace spidarcad::haptics
