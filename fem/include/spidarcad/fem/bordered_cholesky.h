// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
// The Cholesky factor of the contact block, grown and shrunk one contact node (three rows and
// columns: x, y, z) at a time. The one kernel of ContactSolver (condensation.h) and
// CachedContactSolver (column_cache.h).
//
// Shapes: A is the condensed contact block G_cc, n by n with n = 3k for k contact nodes
// (k <= max_blocks, a few dozen in the tick: 16 in the FE touch field, tested to 64), symmetric
// positive definite, in m/N. A = L Lᵀ with L lower triangular, stored row-major in a
// 3·max_blocks square matrix (rows contiguous for both triangular sweeps; only the lower
// triangle of the top-left n by n block is meaningful).
//
// Appending block k (border B = A(new, old), 3 by n; diagonal block D = A(new, new), 3 by 3):
//     [ A  Bᵀ ]   [ L  0 ] [ Lᵀ  Yᵀ ]
//     [ B  D  ] = [ Y  M ] [ 0   Mᵀ ],   Y = B L⁻ᵀ (3 by n, forward substitution on each row),
//                                        M Mᵀ = D − Y Yᵀ (3 by 3 Cholesky): O(n²) work.
// The block is refused when a pivot of D − Y Yᵀ is not above 1e-12 · max_i |D_ii| (the new node
// adds nothing the old ones do not already span, to within rounding).
// Removing block s: the rows and columns of s go and the trailing part absorbs Y_s Y_sᵀ by three
// rank-one (Givens-type) updates, O(n²). Truncate keeps a leading principal block, whose factor
// is the leading block of L.
//
// Everything but the constructor is real-time safe: no allocation, lock or exception.
#pragma once

#include <Eigen/Core>

namespace spidarcad::fem {

// A = L Lᵀ grown and shrunk by blocks of three rows (see the file comment).
class BorderedCholesky {
 public:
  // Row-major dense storage of L.
  using FactorMatrix = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;

  // Room for up to max_blocks blocks (>= 1; allocates 9·max_blocks² doubles). Starts empty.
  // Throws std::invalid_argument for max_blocks < 1.
  explicit BorderedCholesky(int max_blocks);

  // Number of blocks k in the factor.
  int num_blocks() const { return k_; }
  // Size n = 3k of A.
  int size() const { return 3 * k_; }
  // Largest number of blocks.
  int max_blocks() const { return max_blocks_; }

  // Row j (0, 1, 2) of the border of the next block: write B(j, 0 .. n−1) = A(n + j, 0 .. n−1)
  // here, then call AppendBlock. Valid while k < max_blocks.
  double* BorderRow(int j) { return &l_(3 * k_ + j, 0); }
  // Appends the block whose border was written through BorderRow and whose diagonal block is
  // `diagonal` (3 by 3; only its lower triangle is read, so pass it symmetric). Returns false
  // (k unchanged, the factor of the first k blocks intact) when D − Y Yᵀ is not positive
  // definite or k == max_blocks.
  bool AppendBlock(const Eigen::Matrix3d& diagonal);
  // Removes block s (0 <= s < k); later blocks move down by one. Out of range: no-op.
  void RemoveBlock(int s);
  // Keeps the first `blocks` blocks (0 <= blocks <= k; clamped).
  void Truncate(int blocks);
  // Solves A x = b in place: x holds b (n entries) on entry and x on return. k = 0: no-op.
  void Solve(double* x) const;

  // The factor: the lower triangle of its top-left n by n block is L.
  const FactorMatrix& factor() const { return l_; }

 private:
  int max_blocks_;
  int k_ = 0;
  FactorMatrix l_;  // 3·max_blocks square, lower triangle used
};

}  // namespace spidarcad::fem
