// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#include "spidarcad/fem/blas_kernels.h"

#include <cpuid.h>
#include <strings.h>
#include <unistd.h>

#include <cstdint>
#include <cstring>
#include <mutex>
#include <string>

extern "C" {
char* openblas_get_corename(void);
char* openblas_get_config(void);
int openblas_get_num_threads(void);
void openblas_set_num_threads(int);

// The symbol fem's link options name (--undefined), so that every program linked with
// spidarcad::fem takes this file, and with it the getenv below, from the static library.
extern const int spidarcad_fem_blas_kernels;
const int spidarcad_fem_blas_kernels = 1;
}

namespace spidarcad::fem {
namespace {

constexpr char kCoreTypeName[] = "OPENBLAS_CORETYPE";

// The environment's value of `name`, as glibc's getenv finds it (the first "name=" entry of
// environ); nullptr for an empty name or none. `name` is not null.
char* EnvironmentValue(const char* name) {
  if (name[0] == '\0' || environ == nullptr) return nullptr;
  const std::size_t n = std::strlen(name);
  for (char** e = environ; *e != nullptr; ++e)
    if (std::strncmp(*e, name, n) == 0 && (*e)[n] == '=') return *e + n + 1;
  return nullptr;
}

// XCR0: the register states the operating system saves (needs OSXSAVE).
std::uint64_t SavedStates() {
  std::uint32_t lo = 0, hi = 0;
  __asm__ volatile("xgetbv" : "=a"(lo), "=d"(hi) : "c"(0));
  return (static_cast<std::uint64_t>(hi) << 32) | lo;
}

}  // namespace

const char* CpuBlasCoreType() {
  unsigned a = 0, b = 0, c = 0, d = 0;
  if (__get_cpuid(1, &a, &b, &c, &d) == 0) return nullptr;
  const bool osxsave = (c >> 27 & 1) != 0, avx = (c >> 28 & 1) != 0, fma = (c >> 12 & 1) != 0;
  if (!osxsave || !avx) return nullptr;
  const std::uint64_t xcr0 = SavedStates();
  const bool ymm_saved = (xcr0 & 0x6) == 0x6;    // SSE and AVX state
  const bool zmm_saved = (xcr0 & 0xe6) == 0xe6;  // and opmask, ZMM0–15 high, ZMM16–31
  if (!ymm_saved || __get_cpuid_count(7, 0, &a, &b, &c, &d) == 0) return nullptr;
  const bool avx2 = (b >> 5 & 1) != 0;
  constexpr unsigned kAvx512 =
      1u << 16 | 1u << 17 | 1u << 28 | 1u << 30 | 1u << 31;  // F DQ CD BW VL
  if (zmm_saved && (b & kAvx512) == kAvx512) return "SkylakeX";
  if (avx2 && fma) return "Haswell";
  return nullptr;
}

std::string BlasKernelDescription() {
  std::string config = openblas_get_config();  // "OpenBLAS 0.3.21 NO_LAPACKE DYNAMIC_ARCH ..."
  const std::size_t second_space = config.find(' ', config.find(' ') + 1);
  std::string line = config.substr(0, second_space) + ", " + openblas_get_corename() + " kernels";
  if (const char* user = EnvironmentValue(kCoreTypeName)) {
    line += std::string(" (") + kCoreTypeName + "=" + user + ")";
  } else if (const char* cpu = CpuBlasCoreType();
             cpu != nullptr && strcasecmp(openblas_get_corename(), cpu) == 0) {
    line += " (chosen by spidarcad from the CPU's features; ";
    line += kCoreTypeName;
    line += " overrides)";
  } else {
    line += " (chosen by OpenBLAS)";
  }
  return line;
}

namespace {
std::mutex single_threaded_mutex;
int single_threaded_users = 0;
int threads_before = 1;
}  // namespace

SingleThreadedBlas::SingleThreadedBlas() {
  const std::lock_guard<std::mutex> lock(single_threaded_mutex);
  if (single_threaded_users++ == 0) {
    threads_before = openblas_get_num_threads();
    openblas_set_num_threads(1);
  }
}

SingleThreadedBlas::~SingleThreadedBlas() {
  const std::lock_guard<std::mutex> lock(single_threaded_mutex);
  if (--single_threaded_users == 0) openblas_set_num_threads(threads_before);
}

}  // namespace spidarcad::fem

// The program's getenv: libc's answer for every name, and for OPENBLAS_CORETYPE when the
// environment has none, the core type of the CPU's features (see blas_kernels.h). OpenBLAS asks
// for it in its constructor, before main; symbols of the program come before libc's.
extern "C" char* getenv(const char* name) noexcept {
  if (char* value = spidarcad::fem::EnvironmentValue(name)) return value;
  if (std::strcmp(name, spidarcad::fem::kCoreTypeName) == 0)  // name: never null (libc's contract)
    return const_cast<char*>(spidarcad::fem::CpuBlasCoreType());
  return nullptr;
}
