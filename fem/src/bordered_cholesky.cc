// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#include "spidarcad/fem/bordered_cholesky.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>

namespace spidarcad::fem {

BorderedCholesky::BorderedCholesky(int max_blocks) : max_blocks_(max_blocks) {
  if (max_blocks < 1) {
    throw std::invalid_argument("BorderedCholesky: max_blocks must be >= 1, got " +
                                std::to_string(max_blocks));
  }
  l_ = FactorMatrix::Zero(3 * max_blocks, 3 * max_blocks);
}

bool BorderedCholesky::AppendBlock(const Eigen::Matrix3d& diagonal) {
  if (k_ >= max_blocks_) return false;
  const int n3 = 3 * k_;
  // Border: Y = B L⁻ᵀ, row by row (L y_jᵀ = b_jᵀ), in place over B; in increasing column c.
  for (int j = 0; j < 3; ++j) {
    double* row = &l_(n3 + j, 0);
    for (int c = 0; c < n3; ++c) {
      const double* row_c = &l_(c, 0);
      double sum = row[c];
      for (int m = 0; m < c; ++m) sum -= row[m] * row_c[m];
      row[c] = sum / row_c[c];
    }
  }
  // Diagonal block: Cholesky of D − Y Yᵀ (3 by 3).
  const double scale = diagonal.diagonal().cwiseAbs().maxCoeff();
  for (int a = 0; a < 3; ++a) {
    for (int j = 0; j <= a; ++j) {
      double s = diagonal(a, j);
      const double* ra = &l_(n3 + a, 0);
      const double* rj = &l_(n3 + j, 0);
      for (int m = 0; m < n3 + j; ++m) s -= ra[m] * rj[m];
      if (a == j) {
        if (!(s > 1e-12 * scale)) return false;
        l_(n3 + a, n3 + a) = std::sqrt(s);
      } else {
        l_(n3 + a, n3 + j) = s / l_(n3 + j, n3 + j);
      }
    }
  }
  ++k_;
  return true;
}

void BorderedCholesky::RemoveBlock(int s) {
  if (s < 0 || s >= k_) return;
  const int n3 = 3 * k_;
  const int p = 3 * s;
  // Trailing block L33 (rows/cols p+3 .. n3−1) absorbs L32 L32ᵀ by three successive rank-one
  // (Givens-type) updates, applied together column by column. The update vectors are columns
  // p, p+1, p+2 of L itself (rows p+3 .. n3−1), which are discarded when the gap is closed.
  // Each column's inner loop has no carried dependency (unlike a row-by-row sweep).
  for (int m = p + 3; m < n3; ++m) {
    for (int j = 0; j < 3; ++j) {
      const double xm = l_(m, p + j);
      const double lmm = l_(m, m);
      const double r = std::sqrt(lmm * lmm + xm * xm);
      const double c_inv = lmm / r, sn = xm / lmm, c = r / lmm;
      l_(m, m) = r;
      for (int i = m + 1; i < n3; ++i) {
        double* row = &l_(i, 0);
        const double lim = (row[m] + sn * row[p + j]) * c_inv;
        row[m] = lim;
        row[p + j] = c * row[p + j] - sn * lim;
      }
    }
  }
  // Close the gap: rows and columns after the removed block move up and left by three.
  for (int r = p + 3; r < n3; ++r) {
    for (int col = 0; col < p; ++col) l_(r - 3, col) = l_(r, col);
    for (int col = p + 3; col <= r; ++col) l_(r - 3, col - 3) = l_(r, col);
  }
  --k_;
}

void BorderedCholesky::Truncate(int blocks) { k_ = std::clamp(blocks, 0, k_); }

void BorderedCholesky::Solve(double* x) const {
  const int n3 = 3 * k_;
  // L y = b.
  for (int i = 0; i < n3; ++i) {
    const double* row = &l_(i, 0);
    double sum = x[i];
    for (int m = 0; m < i; ++m) sum -= row[m] * x[m];
    x[i] = sum / row[i];
  }
  // Lᵀ x = y, column-oriented so that it reads rows of L.
  for (int i = n3 - 1; i >= 0; --i) {
    const double xi = x[i] / l_(i, i);
    x[i] = xi;
    const double* row = &l_(i, 0);
    for (int m = 0; m < i; ++m) x[m] -= row[m] * xi;
  }
}

}  // namespace spidarcad::fem
