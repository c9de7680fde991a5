// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#include "scene/solid_distance_field.h"

#include <stdexcept>
#include <utility>

namespace spidarcad::app {

SolidDistanceField::SolidDistanceField(std::shared_ptr<const modeling::CompiledSolid> solid)
    : solid_(std::move(solid)) {
  if (solid_ == nullptr) throw std::invalid_argument("SolidDistanceField: the solid is null");
}

SolidDistanceField::SolidDistanceField(std::shared_ptr<const modeling::CompiledSolid> solid,
                                       std::shared_ptr<const modeling::CellSpecializedSolid> cells)
    : solid_(std::move(solid)), cells_(std::move(cells)) {
  if (solid_ == nullptr) throw std::invalid_argument("SolidDistanceField: the solid is null");
  if (cells_ != nullptr && cells_->shared_solid() != solid_) {
    throw std::invalid_argument("SolidDistanceField: the specialized cells wrap a different solid");
  }
}

double SolidDistanceField::Evaluate(const Eigen::Vector3d& p_W,
                                    Eigen::Vector3d* gradient_W) const noexcept {
  if (cells_ != nullptr) {
    if (gradient_W == nullptr) return cells_->Value(p_W);
    return cells_->ValueAndGradient(p_W, gradient_W);
  }
  if (gradient_W == nullptr) return solid_->Value(p_W);
  return solid_->ValueAndGradient(p_W, gradient_W);
}

}  // namespace spidarcad::app
