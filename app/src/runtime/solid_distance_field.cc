// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#include "runtime/solid_distance_field.h"

#include <stdexcept>
#include <utility>

namespace spidarcad::app {

SolidDistanceField::SolidDistanceField(std::shared_ptr<const modeling::CompiledSolid> solid)
    : solid_(std::move(solid)) {
  if (solid_ == nullptr) throw std::invalid_argument("SolidDistanceField: the solid is null");
}

double SolidDistanceField::Evaluate(const Eigen::Vector3d& p_W,
                                    Eigen::Vector3d* gradient_W) const noexcept {
  if (gradient_W == nullptr) return solid_->Value(p_W);
  return solid_->ValueAndGradient(p_W, gradient_W);
}

}  // namespace spidarcad::app
