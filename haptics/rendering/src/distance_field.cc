// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#include "spidarcad/haptics/distance_field.h"

#include <algorithm>
#include <cmath>
#include <sstream>
#include <stdexcept>
#include <string>

namespace spidarcad::haptics {

namespace {
[[noreturn]] void Bad(const char* where, const std::string& what) {
  throw std::invalid_argument(std::string(where) + ": " + what);
}
std::string Str(const Eigen::Vector3d& v) {
  std::ostringstream s;
  s << "(" << v.x() << ", " << v.y() << ", " << v.z() << ")";
  return s.str();
}
}  // namespace

void DistanceField::EvaluateBatch(const double* x, const double* y, const double* z, int n,
                                  double* phi, double* gx, double* gy, double* gz) const noexcept {
  Eigen::Vector3d g;
  for (int i = 0; i < n; ++i) {
    const Eigen::Vector3d p(x[i], y[i], z[i]);
    if (gx == nullptr) {
      phi[i] = Evaluate(p, nullptr);
      continue;
    }
    phi[i] = Evaluate(p, &g);
    gx[i] = g.x();
    gy[i] = g.y();
    gz[i] = g.z();
  }
}

SphereDistanceField::SphereDistanceField(const Eigen::Vector3d& center_W, double radius)
    : center_W_(center_W), radius_(radius) {
  if (!center_W.allFinite())
    Bad("SphereDistanceField", "centre " + Str(center_W) + " is not finite");
  if (!(radius > 0 && std::isfinite(radius))) {
    Bad("SphereDistanceField", "radius = " + std::to_string(radius) + " must be finite and > 0");
  }
}

double SphereDistanceField::Evaluate(const Eigen::Vector3d& p_W,
                                     Eigen::Vector3d* gradient_W) const noexcept {
  const Eigen::Vector3d r = p_W - center_W_;
  const double n = r.norm();
  if (gradient_W != nullptr)
    *gradient_W = n > 0 ? Eigen::Vector3d(r / n) : Eigen::Vector3d::UnitZ();
  return n - radius_;
}

BoxDistanceField::BoxDistanceField(const Eigen::Vector3d& half_sides) : half_sides_(half_sides) {
  if (!(half_sides.allFinite() && (half_sides.array() > 0).all())) {
    Bad("BoxDistanceField", "half_sides " + Str(half_sides) + " must be finite and > 0");
  }
}

double BoxDistanceField::Evaluate(const Eigen::Vector3d& p_W,
                                  Eigen::Vector3d* gradient_W) const noexcept {
  // q: per-axis distance outside the slab (negative inside).
  const Eigen::Vector3d a = p_W.cwiseAbs();
  const Eigen::Vector3d q = a - half_sides_;
  const Eigen::Vector3d outside = q.cwiseMax(0.0);
  const double out_norm = outside.norm();
  if (out_norm > 0) {
    if (gradient_W != nullptr) {
      for (int i = 0; i < 3; ++i) (*gradient_W)(i) = std::copysign(outside(i) / out_norm, p_W(i));
    }
    return out_norm;
  }
  // Inside (or on the surface): the nearest face.
  int axis = 0;
  q.maxCoeff(&axis);
  if (gradient_W != nullptr) {
    gradient_W->setZero();
    (*gradient_W)(axis) = p_W(axis) >= 0 ? 1.0 : -1.0;
  }
  return q(axis);
}

HalfSpaceDistanceField::HalfSpaceDistanceField(const Eigen::Vector3d& p_WP,
                                               const Eigen::Vector3d& n_W)
    : p_WP_(p_WP) {
  const double n = n_W.norm();
  if (!(n > 0 && std::isfinite(n)))
    Bad("HalfSpaceDistanceField", "normal " + Str(n_W) + " is zero or not finite");
  if (!p_WP.allFinite()) Bad("HalfSpaceDistanceField", "point " + Str(p_WP) + " is not finite");
  n_W_ = n_W / n;
}

double HalfSpaceDistanceField::Evaluate(const Eigen::Vector3d& p_W,
                                        Eigen::Vector3d* gradient_W) const noexcept {
  if (gradient_W != nullptr) *gradient_W = n_W_;
  return n_W_.dot(p_W - p_WP_);
}

UnionDistanceField::UnionDistanceField(std::vector<std::shared_ptr<const DistanceField>> children)
    : children_(std::move(children)) {
  if (children_.empty()) Bad("UnionDistanceField", "needs at least one child");
  for (std::size_t i = 0; i < children_.size(); ++i) {
    if (children_[i] == nullptr)
      Bad("UnionDistanceField", "child " + std::to_string(i) + " is null");
  }
}

double UnionDistanceField::Evaluate(const Eigen::Vector3d& p_W,
                                    Eigen::Vector3d* gradient_W) const noexcept {
  double best = children_[0]->Evaluate(p_W, gradient_W);
  Eigen::Vector3d g;
  for (std::size_t i = 1; i < children_.size(); ++i) {
    const double v = children_[i]->Evaluate(p_W, gradient_W != nullptr ? &g : nullptr);
    if (v < best) {
      best = v;
      if (gradient_W != nullptr) *gradient_W = g;
    }
  }
  return best;
}

TransformedDistanceField::TransformedDistanceField(std::shared_ptr<const DistanceField> body,
                                                   const Eigen::Isometry3d& X_WB)
    : body_(std::move(body)), X_WB_(X_WB) {
  if (body_ == nullptr) Bad("TransformedDistanceField", "body field is null");
  const Eigen::Matrix3d R = X_WB.linear();
  if (!X_WB.matrix().allFinite() ||
      (R.transpose() * R - Eigen::Matrix3d::Identity()).norm() > 1e-9 || R.determinant() < 0) {
    Bad("TransformedDistanceField", "X_WB is not a rigid transform");
  }
  X_BW_ = X_WB_.inverse(Eigen::Isometry);
}

double TransformedDistanceField::Evaluate(const Eigen::Vector3d& p_W,
                                          Eigen::Vector3d* gradient_W) const noexcept {
  const Eigen::Vector3d p_B = X_BW_ * p_W;
  if (gradient_W == nullptr) return body_->Evaluate(p_B, nullptr);
  Eigen::Vector3d g_B;
  const double v = body_->Evaluate(p_B, &g_B);
  *gradient_W = X_WB_.linear() * g_B;
  return v;
}

void UnionDistanceField::EvaluateBatch(const double* x, const double* y, const double* z, int n,
                                       double* phi, double* gx, double* gy,
                                       double* gz) const noexcept {
  // As Evaluate: the first child's value and gradient, replaced by a later child's where that
  // one is strictly smaller. Chunks of kChunk points keep the scratch on the stack.
  constexpr int kChunk = 64;
  double v[kChunk], vx[kChunk], vy[kChunk], vz[kChunk];
  const bool gradient = gx != nullptr;
  for (int begin = 0; begin < n; begin += kChunk) {
    const int count = std::min(kChunk, n - begin);
    double* out_x = gradient ? gx + begin : nullptr;
    double* out_y = gradient ? gy + begin : nullptr;
    double* out_z = gradient ? gz + begin : nullptr;
    children_[0]->EvaluateBatch(x + begin, y + begin, z + begin, count, phi + begin, out_x, out_y,
                                out_z);
    for (std::size_t c = 1; c < children_.size(); ++c) {
      children_[c]->EvaluateBatch(x + begin, y + begin, z + begin, count, v,
                                  gradient ? vx : nullptr, vy, vz);
      for (int i = 0; i < count; ++i) {
        if (!(v[i] < phi[begin + i])) continue;
        phi[begin + i] = v[i];
        if (gradient) {
          out_x[i] = vx[i];
          out_y[i] = vy[i];
          out_z[i] = vz[i];
        }
      }
    }
  }
}

void TransformedDistanceField::EvaluateBatch(const double* x, const double* y, const double* z,
                                             int n, double* phi, double* gx, double* gy,
                                             double* gz) const noexcept {
  constexpr int kChunk = 64;
  double bx[kChunk], by[kChunk], bz[kChunk], hx[kChunk], hy[kChunk], hz[kChunk];
  const bool gradient = gx != nullptr;
  for (int begin = 0; begin < n; begin += kChunk) {
    const int count = std::min(kChunk, n - begin);
    for (int i = 0; i < count; ++i) {
      const Eigen::Vector3d p_B = X_BW_ * Eigen::Vector3d(x[begin + i], y[begin + i], z[begin + i]);
      bx[i] = p_B.x();
      by[i] = p_B.y();
      bz[i] = p_B.z();
    }
    body_->EvaluateBatch(bx, by, bz, count, phi + begin, gradient ? hx : nullptr, hy, hz);
    if (!gradient) continue;
    for (int i = 0; i < count; ++i) {
      const Eigen::Vector3d g_W = X_WB_.linear() * Eigen::Vector3d(hx[i], hy[i], hz[i]);
      gx[begin + i] = g_W.x();
      gy[begin + i] = g_W.y();
      gz[begin + i] = g_W.z();
    }
  }
}

}  // namespace spidarcad::haptics
