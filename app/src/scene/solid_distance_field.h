// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
// The adapter from a compiled implicit solid (modeling::CompiledSolid) to the haptic force
// fields' view of geometry (haptics::DistanceField), so that haptics/ never includes modeling/.
//
// Sign and units (docs/scene-format.md, distance_field.h): φ < 0 inside, > 0 outside, in
// metres of the scene (world frame W); the gradient points out of the solid and has length
// <= 1. Scene values are exact distances or Lipschitz-1 lower bounds, which is what the proxy's
// sweep and the point shell need. Scene files are always in metres ("units": "m"), so no unit
// scaling happens here: the device-to-scene map X_WD (scale and offset) lives in the haptic loop
// (haptics::LoopSettings::world_scale, p_WDo), which hands the fields positions already in W.
#pragma once

#include <Eigen/Core>
#include <memory>

#include "spidarcad/haptics/distance_field.h"
#include "spidarcad/modeling/cell_specialized_solid.h"
#include "spidarcad/modeling/implicit_evaluator.h"

namespace spidarcad::app {

// A CompiledSolid seen as a haptics::DistanceField (in W). Evaluate is real-time safe: the
// evaluator is noexcept, allocation-free and const (several fields may share one solid).
class SolidDistanceField final : public haptics::DistanceField {
 public:
  // `solid` must not be null. Throws std::invalid_argument otherwise.
  explicit SolidDistanceField(std::shared_ptr<const modeling::CompiledSolid> solid);
  // The same, evaluated through the per-cell pruned tapes `cells` (bit-identical results, fewer
  // instructions near one feature); `cells` null: the full tape only. Throws
  // std::invalid_argument when `solid` is null or `cells` wraps another solid.
  SolidDistanceField(std::shared_ptr<const modeling::CompiledSolid> solid,
                     std::shared_ptr<const modeling::CellSpecializedSolid> cells);
  // φ(p_W) [m] and, when gradient_W is not null, dφ/dp (W, outward, |∇φ| <= 1).
  double Evaluate(const Eigen::Vector3d& p_W, Eigen::Vector3d* gradient_W) const noexcept override;
  // Several points at once through the tape's batch evaluation (SIMD across points; grouped by
  // cell when the pruned tapes are set), bit-identical to Evaluate point by point.
  void EvaluateBatch(const double* x, const double* y, const double* z, int n, double* phi,
                     double* gx, double* gy, double* gz) const noexcept override;
  // The wrapped solid.
  const modeling::CompiledSolid& solid() const noexcept { return *solid_; }
  // The per-cell pruned tapes, or null when the full tape is evaluated.
  const modeling::CellSpecializedSolid* cells() const noexcept { return cells_.get(); }

 private:
  std::shared_ptr<const modeling::CompiledSolid> solid_;
  std::shared_ptr<const modeling::CellSpecializedSolid> cells_;  // null: the full tape only
};

}  // namespace spidarcad::app
