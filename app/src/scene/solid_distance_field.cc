// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#include "scene/solid_distance_field.h"

#include <algorithm>
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

void SolidDistanceField::EvaluateBatch(const double* x, const double* y, const double* z, int n,
                                       double* phi, double* gx, double* gy,
                                       double* gz) const noexcept {
  if (cells_ != nullptr) {
    if (gx == nullptr) {
      cells_->ValueBatch(x, y, z, n, phi);
    } else {
      cells_->ValueAndGradientBatch(x, y, z, n, phi, gx, gy, gz);
    }
    return;
  }
  // The full tape's batch functions take the points as the columns of a 3 × m matrix: chunks
  // of kChunk points through scratch on the stack.
  constexpr int kChunk = 64;
  double points[3 * kChunk], gradients[3 * kChunk];
  for (int begin = 0; begin < n; begin += kChunk) {
    const int count = std::min(kChunk, n - begin);
    for (int i = 0; i < count; ++i) {
      points[3 * i] = x[begin + i];
      points[3 * i + 1] = y[begin + i];
      points[3 * i + 2] = z[begin + i];
    }
    const Eigen::Map<const Eigen::Matrix3Xd> p(points, 3, count);
    Eigen::Map<Eigen::VectorXd> values(phi + begin, count);
    if (gx == nullptr) {
      solid_->Values(p, values);
      continue;
    }
    Eigen::Map<Eigen::Matrix3Xd> g(gradients, 3, count);
    solid_->ValuesAndGradients(p, values, g);
    for (int i = 0; i < count; ++i) {
      gx[begin + i] = gradients[3 * i];
      gy[begin + i] = gradients[3 * i + 1];
      gz[begin + i] = gradients[3 * i + 2];
    }
  }
}

}  // namespace spidarcad::app
