// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
// A compiled solid with one pruned tape per cell of a uniform grid (CompiledSolid::Specialize):
// a point query looks up its cell and runs that cell's shorter tape, with results bit-identical
// to the full tape's. Near one feature of a CSG part (one hole of a box less five cylinders) the
// tape shrinks to the few primitives that can matter there.
//
// Real-time safety: Value and ValueAndGradient are noexcept, const, allocation- and lock-free
// (several threads may evaluate one instance). Construction allocates and takes time (it
// specializes every cell): build it off the haptic thread.
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <cstdint>
#include <memory>
#include <vector>

#include "spidarcad/modeling/implicit_evaluator.h"

namespace spidarcad::modeling {

// Grid of a CellSpecializedSolid. SI units.
struct CellSpecializationSettings {
  double cell_size =
      0.005;  // edge of a cubic cell, m (> 0); grown if the grid would exceed max_cells
  int max_cells = 1 << 18;  // cap on the number of cells (> 0)
};

// Build figures of a CellSpecializedSolid.
struct CellSpecializationStats {
  int cells = 0;                 // cells in the grid
  int specialized_cells = 0;     // cells whose tape is shorter than the full one
  int distinct_tapes = 0;        // distinct pruned tapes stored (identical ones are shared)
  double mean_instructions = 0;  // instructions per cell, averaged over all cells
  int full_instructions = 0;     // instructions of the full tape
  double cell_size = 0;          // the cell edge used, m
  double build_seconds = 0;      // wall time of the construction, s
};

// A CompiledSolid (frame W) with a grid of specialized tapes over a region of W. Points
// outside the grid, and cells whose tape could not be pruned, use the full tape.
class CellSpecializedSolid {
 public:
  // Specializes `solid` on every cell of a grid covering region_W (m, frame W). Throws
  // std::invalid_argument for a null solid, an empty or non-finite region or bad settings.
  CellSpecializedSolid(std::shared_ptr<const CompiledSolid> solid,
                       const Eigen::AlignedBox3d& region_W,
                       const CellSpecializationSettings& settings = {});

  // Value at p_W (m), bit-identical to solid().Value(p_W).
  double Value(const Eigen::Vector3d& p_W) const noexcept { return TapeAt(p_W).Value(p_W); }
  // Value and gradient (W), bit-identical to solid().ValueAndGradient(p_W, gradient_W).
  double ValueAndGradient(const Eigen::Vector3d& p_W, Eigen::Vector3d* gradient_W) const noexcept {
    return TapeAt(p_W).ValueAndGradient(p_W, gradient_W);
  }
  // The tape used at p_W (the full one outside the grid or for NaN coordinates).
  const CompiledSolid& TapeAt(const Eigen::Vector3d& p_W) const noexcept;
  // Batch evaluation, structure of arrays (m, frame W): the n points (x[i], y[i], z[i]) are
  // grouped by the tape of their cell and each group runs through that tape several points at
  // a time (CompiledSolid::Values, SIMD across points). value[i] is bit-identical to
  // Value(p_i). Any n >= 0; no array may overlap an output. Real-time safe (fixed scratch on
  // the stack).
  void ValueBatch(const double* x, const double* y, const double* z, int n,
                  double* value) const noexcept;
  // The same with gradients (W), each bit-identical to ValueAndGradient(p_i).
  void ValueAndGradientBatch(const double* x, const double* y, const double* z, int n,
                             double* value, double* gx, double* gy, double* gz) const noexcept;

  // The full solid.
  const CompiledSolid& solid() const noexcept { return *solid_; }
  const std::shared_ptr<const CompiledSolid>& shared_solid() const noexcept { return solid_; }
  // Build figures.
  const CellSpecializationStats& stats() const noexcept { return stats_; }

 private:
  // Both batch functions (gx null: values only).
  void Batch(const double* x, const double* y, const double* z, int n, double* value, double* gx,
             double* gy, double* gz) const noexcept;

  std::shared_ptr<const CompiledSolid> solid_;
  std::vector<CompiledSolid> tapes_;  // distinct pruned tapes; tape index k > 0 is tapes_[k - 1]
  std::vector<std::uint32_t> cell_tape_;  // per cell (x fastest): 0 the full tape, else k
  Eigen::Vector3d origin_ = Eigen::Vector3d::Zero();  // min corner of the grid, m
  double inverse_cell_ = 0.0;                         // 1 / cell size, 1/m
  int nx_ = 0, ny_ = 0, nz_ = 0;
  CellSpecializationStats stats_;
};

}  // namespace spidarcad::modeling
