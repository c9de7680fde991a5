// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
// The BLAS kernels under CHOLMOD's supernodal factorisations and solves (OpenBLAS).
//
// Debian 12's OpenBLAS (0.3.21, built with the kernels of every x86-64 core: DYNAMIC_ARCH)
// picks its kernels from the CPU's family and model numbers, and a model newer than its table
// gets its oldest kernels (Prescott: SSE3), AVX-512 or not. On an Intel Xeon of family 6,
// model 207, its dgemm ran 4.8 times slower than with its SkylakeX kernels, and a slab solve
// of a 130k-tet part took 1.25 times as long (docs/design/2026-12-07-blas-kernels.md).
//
// OpenBLAS reads OPENBLAS_CORETYPE once, as it is loaded, before any code of the program runs.
// A program linked with spidarcad::fem therefore answers that one name itself: its getenv
// (blas_kernels.cc, which the link always includes) returns the environment's value as libc
// does, and only when the environment has no OPENBLAS_CORETYPE does it return
// CpuBlasCoreType(). A user's own OPENBLAS_CORETYPE is always what OpenBLAS gets; child
// processes of the program (the FE worker) choose the same way.
#pragma once

#include <string>

namespace spidarcad::fem {

// The OpenBLAS core type for this CPU's own features, read with CPUID and XGETBV (the
// operating system must save the registers): "SkylakeX" with AVX-512 F, CD, DQ, BW and VL;
// else "Haswell" with AVX2 and FMA; else nullptr (OpenBLAS chooses). Those are the kernels
// OpenBLAS gives the CPUs it knows with the same features (Skylake-SP to Sapphire Rapids;
// Haswell on, Zen 1–3). Reentrant; no allocation.
const char* CpuBlasCoreType();

// One line naming the BLAS kernels in use and what chose them, e.g. "OpenBLAS 0.3.21,
// SkylakeX kernels (chosen by spidarcad from the CPU's features; OPENBLAS_CORETYPE overrides)"
// or "OpenBLAS 0.3.21, Haswell kernels (OPENBLAS_CORETYPE=Haswell)".
std::string BlasKernelDescription();

// While an object of this class lives, OpenBLAS runs each call on its caller's thread
// (openblas_set_num_threads(1)); the count it had comes back when the last such object in the
// process ends. For work that runs BLAS-heavy tasks on threads of its own, one per core: OpenBLAS's
// own threads then neither wait for each other's callers nor spin (sched_yield, up to 0.1 s after
// each call) on a core another task needs. Calls made meanwhile on other threads run
// single-threaded too. Thread-safe; nests.
class SingleThreadedBlas {
 public:
  SingleThreadedBlas();
  ~SingleThreadedBlas();
  SingleThreadedBlas(const SingleThreadedBlas&) = delete;
  SingleThreadedBlas& operator=(const SingleThreadedBlas&) = delete;
};

}  // namespace spidarcad::fem
