// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#include "spidarcad/modeling/cell_specialized_solid.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <stdexcept>
#include <string>
#include <unordered_map>
#include <utility>

namespace spidarcad::modeling {

namespace {

// Cells per block edge: cells are specialized from their block's tape (already pruned for the
// larger box), which is exact (bit-identity composes) and cheaper than starting from the full
// tape every time.
constexpr int kBlock = 4;

std::string Describe(const Eigen::AlignedBox3d& box) {
  auto v = [](const Eigen::Vector3d& p) {
    return "(" + std::to_string(p.x()) + ", " + std::to_string(p.y()) + ", " +
           std::to_string(p.z()) + ")";
  };
  return "[" + v(box.min()) + ", " + v(box.max()) + "]";
}

}  // namespace

CellSpecializedSolid::CellSpecializedSolid(std::shared_ptr<const CompiledSolid> solid,
                                           const Eigen::AlignedBox3d& region,
                                           const CellSpecializationSettings& settings)
    : solid_(std::move(solid)) {
  const auto start = std::chrono::steady_clock::now();
  if (solid_ == nullptr) throw std::invalid_argument("CellSpecializedSolid: the solid is null");
  if (region.isEmpty() || !region.min().allFinite() || !region.max().allFinite()) {
    throw std::invalid_argument("CellSpecializedSolid: the region " + Describe(region) +
                                " is empty or not finite");
  }
  if (!(settings.cell_size > 0) || !std::isfinite(settings.cell_size)) {
    throw std::invalid_argument("CellSpecializedSolid: cell_size = " +
                                std::to_string(settings.cell_size) + " must be finite and > 0");
  }
  if (settings.max_cells <= 0) {
    throw std::invalid_argument(
        "CellSpecializedSolid: max_cells = " + std::to_string(settings.max_cells) + " must be > 0");
  }
  const Eigen::Vector3d extent = region.max() - region.min();
  double h = settings.cell_size;
  auto count = [&](double size) {
    return Eigen::Vector3d((extent / size).array().ceil().max(1.0));
  };
  while (count(h).prod() > settings.max_cells) h *= 1.25;
  const Eigen::Vector3d n = count(h);
  nx_ = static_cast<int>(n.x());
  ny_ = static_cast<int>(n.y());
  nz_ = static_cast<int>(n.z());
  origin_ = region.min();
  inverse_cell_ = 1.0 / h;
  const long cells = static_cast<long>(nx_) * ny_ * nz_;
  cell_tape_.assign(static_cast<std::size_t>(cells), 0);

  // A cell's box is padded so that a point the lookup assigns to the cell (after rounding in
  // (p − origin)/h) lies inside the box the tape was specialized for.
  const double pad = 1e-6 * h + 1e-12;
  auto box_of = [&](int x0, int y0, int z0, int x1, int y1, int z1) {
    const Eigen::Vector3d lo =
        origin_ + h * Eigen::Vector3d(x0, y0, z0) - Eigen::Vector3d::Constant(pad);
    const Eigen::Vector3d hi =
        origin_ + h * Eigen::Vector3d(x1, y1, z1) + Eigen::Vector3d::Constant(pad);
    return Eigen::AlignedBox3d(lo, hi);
  };
  std::unordered_multimap<std::uint64_t, std::uint32_t> index;
  const int full = solid_->instruction_count();
  double instruction_sum = 0;
  for (int bz = 0; bz < nz_; bz += kBlock) {
    for (int by = 0; by < ny_; by += kBlock) {
      for (int bx = 0; bx < nx_; bx += kBlock) {
        const int ex = std::min(bx + kBlock, nx_), ey = std::min(by + kBlock, ny_),
                  ez = std::min(bz + kBlock, nz_);
        const CompiledSolid block = solid_->Specialize(box_of(bx, by, bz, ex, ey, ez));
        for (int z = bz; z < ez; ++z) {
          for (int y = by; y < ey; ++y) {
            for (int x = bx; x < ex; ++x) {
              CompiledSolid tape = block.Specialize(box_of(x, y, z, x + 1, y + 1, z + 1));
              const int count_here = tape.instruction_count();
              instruction_sum += std::min(count_here, full);
              if (count_here >= full) continue;  // nothing pruned: the full tape
              ++stats_.specialized_cells;
              const std::uint64_t key = tape.TapeHash();
              std::uint32_t k = 0;
              for (auto [it, end] = index.equal_range(key); it != end; ++it) {
                if (tapes_[it->second - 1].SameTape(tape)) {
                  k = it->second;
                  break;
                }
              }
              if (k == 0) {
                tapes_.push_back(std::move(tape));
                k = static_cast<std::uint32_t>(tapes_.size());
                index.emplace(key, k);
              }
              cell_tape_[(static_cast<std::size_t>(z) * ny_ + y) * nx_ + x] = k;
            }
          }
        }
      }
    }
  }
  stats_.cells = static_cast<int>(cells);
  stats_.distinct_tapes = static_cast<int>(tapes_.size());
  stats_.mean_instructions = instruction_sum / static_cast<double>(cells);
  stats_.full_instructions = full;
  stats_.cell_size = h;
  stats_.build_seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

const CompiledSolid& CellSpecializedSolid::TapeAt(const Eigen::Vector3d& p) const noexcept {
  const double fx = (p.x() - origin_.x()) * inverse_cell_;
  const double fy = (p.y() - origin_.y()) * inverse_cell_;
  const double fz = (p.z() - origin_.z()) * inverse_cell_;
  // Negated comparisons also send NaN to the full tape.
  if (!(fx >= 0.0 && fx < nx_ && fy >= 0.0 && fy < ny_ && fz >= 0.0 && fz < nz_)) return *solid_;
  const std::size_t cell = (static_cast<std::size_t>(fz) * static_cast<std::size_t>(ny_) +
                            static_cast<std::size_t>(fy)) *
                               static_cast<std::size_t>(nx_) +
                           static_cast<std::size_t>(fx);
  const std::uint32_t k = cell_tape_[cell];
  return k == 0 ? *solid_ : tapes_[k - 1];
}

void CellSpecializedSolid::ValueBatch(const double* x, const double* y, const double* z, int n,
                                      double* value) const noexcept {
  Batch(x, y, z, n, value, nullptr, nullptr, nullptr);
}

void CellSpecializedSolid::ValueAndGradientBatch(const double* x, const double* y, const double* z,
                                                 int n, double* value, double* gx, double* gy,
                                                 double* gz) const noexcept {
  Batch(x, y, z, n, value, gx, gy, gz);
}

void CellSpecializedSolid::Batch(const double* x, const double* y, const double* z, int n,
                                 double* value, double* gx, double* gy, double* gz) const noexcept {
  // Chunks of kChunk points; in each, the points of one tape are gathered into the columns of a
  // 3 × m matrix, evaluated together (CompiledSolid::Values / ValuesAndGradients, SIMD across
  // points) and scattered back, tape after tape in order of first appearance.
  constexpr int kChunk = 64;
  const CompiledSolid* tape[kChunk];
  bool done[kChunk];
  int index[kChunk];
  double gathered[3 * kChunk], values[kChunk], gradients[3 * kChunk];
  for (int begin = 0; begin < n; begin += kChunk) {
    const int count = std::min(kChunk, n - begin);
    for (int i = 0; i < count; ++i) {
      const int p = begin + i;
      tape[i] = &TapeAt(Eigen::Vector3d(x[p], y[p], z[p]));
      done[i] = false;
    }
    for (int i = 0; i < count; ++i) {
      if (done[i]) continue;
      const CompiledSolid* t = tape[i];
      int m = 0;
      for (int j = i; j < count; ++j) {
        if (done[j] || tape[j] != t) continue;
        done[j] = true;
        index[m] = begin + j;
        gathered[3 * m] = x[begin + j];
        gathered[3 * m + 1] = y[begin + j];
        gathered[3 * m + 2] = z[begin + j];
        ++m;
      }
      const Eigen::Map<const Eigen::Matrix3Xd> points(gathered, 3, m);
      Eigen::Map<Eigen::VectorXd> v(values, m);
      if (gx == nullptr) {
        t->Values(points, v);
        for (int k = 0; k < m; ++k) value[index[k]] = values[k];
      } else {
        Eigen::Map<Eigen::Matrix3Xd> g(gradients, 3, m);
        t->ValuesAndGradients(points, v, g);
        for (int k = 0; k < m; ++k) {
          value[index[k]] = values[k];
          gx[index[k]] = gradients[3 * k];
          gy[index[k]] = gradients[3 * k + 1];
          gz[index[k]] = gradients[3 * k + 2];
        }
      }
    }
  }
}

}  // namespace spidarcad::modeling
