// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
// Distance fields: how the haptic force fields see the scene's geometry without depending on
// modeling/ (ARCHITECTURE.md). The app adapts its solids (modeling::CompiledSolid) to this
// interface; the simple implementations here (sphere, box, half-space, a union, a rigid
// transform) serve tests, benchmarks and simple scenes.
//
// Convention: φ(p) is the signed distance from p to the surface, or a lower bound of its
// magnitude with the right sign: φ < 0 inside the solid, φ > 0 outside, m. "Lower bound" means
// |φ(p)| ≤ true distance, so a sphere of radius |φ(p)| around p never crosses the surface
// (sphere tracing relies on it). The gradient dφ/dp (W) may be unnormalised; its direction
// points out of the solid.
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <memory>
#include <vector>

namespace spidarcad::haptics {

// A signed distance (or bounded) field in some frame, called here W. Evaluate is real-time
// safe in every implementation: no allocation, locks, I/O or exceptions; const and therefore
// callable from several fields at once on the haptic thread.
class DistanceField {
 public:
  virtual ~DistanceField() = default;
  // φ(p_W) [m]; writes dφ/dp (W, outward, possibly unnormalised) to *gradient_W when it is not
  // null.
  virtual double Evaluate(const Eigen::Vector3d& p_W,
                          Eigen::Vector3d* gradient_W) const noexcept = 0;
  // φ at n points given as arrays (structure of arrays, m, W): phi[i] = Evaluate(p_i, g_i) with
  // p_i = (x[i], y[i], z[i]) and, when gx is not null, g_i written to (gx[i], gy[i], gz[i]);
  // when gx is null the gradient is not asked for (gy and gz are ignored). The results are
  // bit-identical to n calls of Evaluate. This default makes those calls; fields that evaluate
  // several points at once (SIMD across points) override it. Any n >= 0; no array may overlap
  // an output. Real-time safe like Evaluate.
  virtual void EvaluateBatch(const double* x, const double* y, const double* z, int n, double* phi,
                             double* gx, double* gy, double* gz) const noexcept;
};

// A solid ball: φ = |p − c| − r (exact). At the centre the gradient is +z (any unit vector).
class SphereDistanceField final : public DistanceField {
 public:
  // Centre c_W [m], radius r > 0 [m]. Throws std::invalid_argument naming the bad value.
  SphereDistanceField(const Eigen::Vector3d& center_W, double radius);
  double Evaluate(const Eigen::Vector3d& p_W, Eigen::Vector3d* gradient_W) const noexcept override;

 private:
  Eigen::Vector3d center_W_;
  double radius_;
};

// An axis-aligned box centred at the origin of its frame with half sides h (exact SDF:
// rounded outside, the distance to the nearest face inside). Place it with
// TransformedDistanceField.
class BoxDistanceField final : public DistanceField {
 public:
  // Half sides h [m], each > 0. Throws std::invalid_argument naming the bad value.
  explicit BoxDistanceField(const Eigen::Vector3d& half_sides);
  double Evaluate(const Eigen::Vector3d& p_W, Eigen::Vector3d* gradient_W) const noexcept override;
  const Eigen::Vector3d& half_sides() const noexcept { return half_sides_; }

 private:
  Eigen::Vector3d half_sides_;
};

// The half-space n·(p − p_P) < 0 is solid: φ = n·(p − p_P) with n normalised (exact).
class HalfSpaceDistanceField final : public DistanceField {
 public:
  // A point on the plane p_WP [m], outward normal n_W (normalised here). Throws
  // std::invalid_argument on a zero or non-finite normal.
  HalfSpaceDistanceField(const Eigen::Vector3d& p_WP, const Eigen::Vector3d& n_W);
  double Evaluate(const Eigen::Vector3d& p_W, Eigen::Vector3d* gradient_W) const noexcept override;

 private:
  Eigen::Vector3d p_WP_;
  Eigen::Vector3d n_W_;
};

// The union of several solids: φ = min_i φ_i (a lower bound of the distance outside, exact
// distance to the union's surface only where one child dominates; concave edges where children
// meet). The gradient is the minimising child's.
class UnionDistanceField final : public DistanceField {
 public:
  // At least one child, none null. Throws std::invalid_argument otherwise.
  explicit UnionDistanceField(std::vector<std::shared_ptr<const DistanceField>> children);
  double Evaluate(const Eigen::Vector3d& p_W, Eigen::Vector3d* gradient_W) const noexcept override;
  // Each child's EvaluateBatch, then the same selection as Evaluate point by point.
  void EvaluateBatch(const double* x, const double* y, const double* z, int n, double* phi,
                     double* gx, double* gy, double* gz) const noexcept override;

 private:
  std::vector<std::shared_ptr<const DistanceField>> children_;
};

// A body-frame field placed in W by the rigid transform X_WB: φ_W(p_W) = φ_B(X_WB⁻¹ p_W),
// gradient rotated back into W. Distances are preserved (rigid motion).
class TransformedDistanceField final : public DistanceField {
 public:
  // `body` (not null) evaluated in B; X_WB a rigid transform (rotation part orthonormal).
  // Throws std::invalid_argument on a null body or a non-rigid X_WB.
  TransformedDistanceField(std::shared_ptr<const DistanceField> body,
                           const Eigen::Isometry3d& X_WB);
  double Evaluate(const Eigen::Vector3d& p_W, Eigen::Vector3d* gradient_W) const noexcept override;
  // The points mapped into B as Evaluate maps them, the body's EvaluateBatch, the gradients
  // rotated back.
  void EvaluateBatch(const double* x, const double* y, const double* z, int n, double* phi,
                     double* gx, double* gy, double* gz) const noexcept override;
  const Eigen::Isometry3d& X_WB() const noexcept { return X_WB_; }

 private:
  std::shared_ptr<const DistanceField> body_;
  Eigen::Isometry3d X_WB_;
  Eigen::Isometry3d X_BW_;
};

}  // namespace spidarcad::haptics
