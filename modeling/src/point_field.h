// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
// Internal to modeling/: the point evaluations of the surface mesher and the sharpening pass.
// A solid whose tape is long enough for pruning to pay is evaluated through per-cell pruned
// tapes (CellSpecializedSolid), whose values and gradients are bit-identical to the full tape's,
// so the meshes do not change; a short tape (a sphere: one instruction) is evaluated as it is.
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <algorithm>
#include <memory>

#include "spidarcad/modeling/cell_specialized_solid.h"
#include "spidarcad/modeling/implicit_evaluator.h"

namespace spidarcad::modeling::internal {

class PointField {
 public:
  // Tapes of at most kMinPrunedInstructions instructions are evaluated as they are (nothing to
  // gain), and so are tapes of more than kMaxPrunedInstructions (a union of thousands of
  // primitives): specializing every cell of those would cost more than it saves and could not
  // be cancelled. The grid has at most kMaxCells cells.
  static constexpr int kMinPrunedInstructions = 8;
  static constexpr int kMaxPrunedInstructions = 256;
  static constexpr int kMaxCells = 1 << 15;

  // region: where most queries fall (m; queries outside use the full tape). cell: the mesh's
  // grid cell (m); the pruned tapes' cells are kCellsPerTapeCell of them across (a 1 cm cell
  // over the platform's bounds: 12,672 cells, 1.7 of its 17 instructions on average, built in
  // 6 ms).
  PointField(const CompiledSolid& solid, const Eigen::AlignedBox3d& region, double cell)
      : solid_(solid) {
    if (solid.instruction_count() <= kMinPrunedInstructions ||
        solid.instruction_count() > kMaxPrunedInstructions || region.isEmpty() ||
        !region.min().allFinite() || !region.max().allFinite() || !(cell > 0.0))
      return;
    CellSpecializationSettings settings;
    settings.cell_size = std::max(kCellsPerTapeCell * cell, region.sizes().maxCoeff() / 256.0);
    settings.max_cells = kMaxCells;
    cells_ = std::make_unique<CellSpecializedSolid>(std::make_shared<const CompiledSolid>(solid),
                                                    region, settings);
  }

  double Value(const Eigen::Vector3d& p) const noexcept {
    return cells_ != nullptr ? cells_->Value(p) : solid_.Value(p);
  }
  double ValueAndGradient(const Eigen::Vector3d& p, Eigen::Vector3d* gradient) const noexcept {
    return cells_ != nullptr ? cells_->ValueAndGradient(p, gradient)
                             : solid_.ValueAndGradient(p, gradient);
  }

 private:
  static constexpr double kCellsPerTapeCell = 4.0;
  const CompiledSolid& solid_;
  std::unique_ptr<CellSpecializedSolid> cells_;  // null: the full tape
};

}  // namespace spidarcad::modeling::internal
