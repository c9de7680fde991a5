// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
// The BLAS kernels: OpenBLAS, loaded before any of the program's code runs, uses the kernels of
// the CPU's own features (checked with libgcc's CPU detection, a second reading of CPUID), and
// the program's getenv answers every other name as the environment holds it.
#include "spidarcad/fem/blas_kernels.h"

#include <dlfcn.h>
#include <gtest/gtest.h>
#include <unistd.h>

#include <cstdlib>
#include <cstring>
#include <string>
#include <thread>

extern "C" char* openblas_get_corename(void);
extern "C" int openblas_get_num_threads(void);
extern "C" void openblas_set_num_threads(int);

namespace spidarcad::fem {
namespace {

// Whether the environment the test started with names OPENBLAS_CORETYPE (read from environ,
// not through getenv).
bool UserSetCoreType() {
  for (char** e = environ; e != nullptr && *e != nullptr; ++e)
    if (std::strncmp(*e, "OPENBLAS_CORETYPE=", 18) == 0) return true;
  return false;
}

// The core type the CPU's features call for, by libgcc's detection.
const char* ExpectedCoreType() {
  __builtin_cpu_init();
  if (__builtin_cpu_supports("avx512f") && __builtin_cpu_supports("avx512cd") &&
      __builtin_cpu_supports("avx512dq") && __builtin_cpu_supports("avx512bw") &&
      __builtin_cpu_supports("avx512vl"))
    return "SkylakeX";
  if (__builtin_cpu_supports("avx2") && __builtin_cpu_supports("fma")) return "Haswell";
  return nullptr;
}

TEST(BlasKernels, OpenBlasUsesTheKernelsOfTheCpusFeatures) {
  if (UserSetCoreType()) GTEST_SKIP() << "OPENBLAS_CORETYPE is set: OpenBLAS uses the user's";
  const char* expected = ExpectedCoreType();
  if (expected == nullptr) GTEST_SKIP() << "a CPU without AVX2 and FMA: OpenBLAS chooses";
  EXPECT_STREQ(CpuBlasCoreType(), expected);
  // The dynamic linker binds getenv, for every library, to the program's own.
  EXPECT_EQ(dlsym(RTLD_DEFAULT, "getenv"), reinterpret_cast<void*>(&getenv));
  // What OpenBLAS took in its constructor, before main.
  EXPECT_STREQ(openblas_get_corename(), expected);
  const std::string line = BlasKernelDescription();
  EXPECT_EQ(line.rfind("OpenBLAS ", 0), 0u) << line;
  EXPECT_NE(line.find(std::string(expected) + " kernels (chosen by spidarcad"), std::string::npos)
      << line;
}

TEST(BlasKernels, GetenvAnswersEveryNameAsTheEnvironmentHoldsIt) {
  ASSERT_EQ(unsetenv("SPIDARCAD_BLAS_TEST"), 0);
  EXPECT_EQ(std::getenv("SPIDARCAD_BLAS_TEST"), nullptr);
  ASSERT_EQ(setenv("SPIDARCAD_BLAS_TEST", "a=b", 1), 0);
  ASSERT_NE(std::getenv("SPIDARCAD_BLAS_TEST"), nullptr);
  EXPECT_STREQ(std::getenv("SPIDARCAD_BLAS_TEST"), "a=b");
  EXPECT_EQ(std::getenv("SPIDARCAD_BLAS_TES"), nullptr);  // a prefix is not the name
  EXPECT_EQ(std::getenv("SPIDARCAD_BLAS_TEST_"), nullptr);
  EXPECT_EQ(std::getenv(""), nullptr);
  ASSERT_EQ(unsetenv("SPIDARCAD_BLAS_TEST"), 0);
  EXPECT_EQ(std::getenv("SPIDARCAD_BLAS_TEST"), nullptr);

  // A user's OPENBLAS_CORETYPE is what getenv gives, and the description names it; without
  // one, getenv gives the CPU's core type.
  const char* before = std::getenv("OPENBLAS_CORETYPE");
  const std::string saved = before != nullptr ? before : "";
  const bool was_set = UserSetCoreType();
  ASSERT_EQ(setenv("OPENBLAS_CORETYPE", "Sandybridge", 1), 0);
  EXPECT_STREQ(std::getenv("OPENBLAS_CORETYPE"), "Sandybridge");
  EXPECT_NE(BlasKernelDescription().find("(OPENBLAS_CORETYPE=Sandybridge)"), std::string::npos)
      << BlasKernelDescription();
  ASSERT_EQ(unsetenv("OPENBLAS_CORETYPE"), 0);
  const char* derived = std::getenv("OPENBLAS_CORETYPE");
  if (CpuBlasCoreType() == nullptr) {
    EXPECT_EQ(derived, nullptr);
  } else {
    EXPECT_STREQ(derived, CpuBlasCoreType());
  }
  if (was_set) {
    ASSERT_EQ(setenv("OPENBLAS_CORETYPE", saved.c_str(), 1), 0);
  }
}

// While any SingleThreadedBlas lives (nested, or on several threads at once), OpenBLAS runs one
// thread; the count it had before comes back when the last one ends.
TEST(SingleThreadedBlas, OneThreadWhileAnyLivesThenTheCountItHad) {
  const int before = openblas_get_num_threads();
  openblas_set_num_threads(2);
  {
    const SingleThreadedBlas outer;
    EXPECT_EQ(openblas_get_num_threads(), 1);
    {
      const SingleThreadedBlas inner;
      EXPECT_EQ(openblas_get_num_threads(), 1);
    }
    EXPECT_EQ(openblas_get_num_threads(), 1);
    std::thread other([] {
      const SingleThreadedBlas on_another_thread;
      EXPECT_EQ(openblas_get_num_threads(), 1);
    });
    other.join();
    EXPECT_EQ(openblas_get_num_threads(), 1);
  }
  EXPECT_EQ(openblas_get_num_threads(), 2);
  openblas_set_num_threads(before);
}

}  // namespace
}  // namespace spidarcad::fem
