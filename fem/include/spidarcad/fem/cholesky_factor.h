// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
// The supernodal Cholesky factor L Lᵀ = P A Pᵀ of a sparse symmetric positive definite matrix A
// (CHOLMOD through Eigen's CholmodSupernodalLLT, on OpenBLAS), and its flat form: every field
// and array of the factor in one contiguous block of bytes, so that a factor computed in one
// process can be rebuilt in another of the same build and solves bit for bit as the original
// (app/scene/worker_process.h factorises in a child process that a window job's Cancel can
// kill). No process, file or socket code here: the caller moves the bytes.
//
// Flat form (host byte order, every field and array starting on an 8-byte boundary): a header
// of kFlatHeaderWords 64-bit words (magic and version, n, failed column, ok, nonzeros, peak
// bytes, and CHOLMOD's supernodal fields), then the int32 arrays Perm (n), ColCount (n), IPerm
// (n, when present), super, pi, px (nsuper + 1 each), s (ssize) and the doubles x (xsize), each
// padded to 8 bytes. A factor that is not ok() (not positive definite) has the header only.
#pragma once

#include <Eigen/Core>
#include <atomic>
#include <cstddef>
#include <memory>

#include "spidarcad/fem/stiffness.h"

namespace spidarcad::fem {

class CholeskyFactor {
 public:
  // Words of the flat form's header.
  static constexpr std::size_t kFlatHeaderWords = 18;

  // No factor yet: ok() is false, size() 0, failed_column() −1.
  CholeskyFactor();
  ~CholeskyFactor();
  CholeskyFactor(const CholeskyFactor&) = delete;
  CholeskyFactor& operator=(const CholeskyFactor&) = delete;

  // Factorises a (n by n, symmetric; only its lower triangle is read): CHOLMOD's symbolic
  // analysis (its default orderings) then the numeric supernodal factorisation. Returns ok().
  bool Compute(const SparseMatrixd& a);

  // True when the factor of a positive definite matrix is held.
  bool ok() const;
  // n, the size of the factored matrix (0 before Compute).
  int size() const;
  // Column of A (original order) at which the factorisation met a non-positive pivot, or −1.
  int failed_column() const;
  // Nonzeros of L (CHOLMOD's lnz).
  double nonzeros() const;
  // Peak memory of CHOLMOD during the factorisation, bytes, in the process that computed it
  // (the flat form carries it).
  double peak_bytes() const;

  // X = A⁻¹ B for B n by m (CHOLMOD's solve with this factor). Requires ok().
  Eigen::MatrixXd Solve(const Eigen::MatrixXd& b) const;

  // Bytes of the flat form.
  std::size_t FlatBytes() const;
  // Writes the flat form, FlatBytes() bytes, to `out`. Throws std::logic_error before Compute.
  void WriteFlat(char* out) const;
  // Rebuilds the factor that WriteFlat wrote for a matrix of size n: `data` holds `bytes` bytes
  // (any alignment). Checks the block before using it (its length against the counts, the
  // permutation, the supernodes' column ranges, pointers and row indices) and throws
  // std::invalid_argument saying what is wrong; std::bad_alloc when the factor does not fit in
  // memory. Copies the arrays in chunks of kFlatChunkBytes and polls `cancel` between them:
  // returns nullptr once it is raised.
  static std::unique_ptr<CholeskyFactor> ReadFlat(const char* data, std::size_t bytes, int n,
                                                  const std::atomic<bool>* cancel = nullptr);
  // Chunk of ReadFlat's copy, bytes.
  static constexpr std::size_t kFlatChunkBytes = std::size_t{16} << 20;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace spidarcad::fem
