// Isotropic linear elastic materials and their assignment to mesh regions.
// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#pragma once

#include <Eigen/Core>
#include <map>

namespace spidarcad::fem {

using Matrix6d = Eigen::Matrix<double, 6, 6>;

// How an element integrates the volumetric (λ) part of the strain energy
// W = μ ε:ε + (λ/2) (tr ε)².
enum class Formulation {
  // Plain displacement elements: (λ/2) (tr ε)² integrated pointwise like the rest. Locks as
  // ν → 1/2 (λ/μ → ∞), linear tetrahedra badly, quadratic ones mildly.
  kDisplacement,
  // Mean dilatation, 10-node elements only: the λ term acts on the element mean of tr ε,
  // (λ/2) V_e (θ̄_e)² with θ̄_e = (1/V_e) ∫ div u dV. This is the P2–P0 mixed element
  // (piecewise-constant pressure p = λ θ̄_e, condensed per element): the stiffness stays
  // symmetric positive definite and displacement-only, and does not lock as ν → 1/2.
  kMeanDilatation,
};

// Isotropic linear elastic material: Young's modulus E [Pa] and Poisson's ratio ν [-].
struct Material {
  double youngs_modulus = 1.0e9;
  double poisson_ratio = 0.3;
  // Element formulation of the volumetric term (kMeanDilatation needs 10-node elements).
  Formulation formulation = Formulation::kDisplacement;

  // Throws std::invalid_argument naming the field and its value unless E > 0 (finite) and
  // -1 < ν < 0.5.
  void Validate() const;
  // Lamé's first parameter λ = Eν / ((1 + ν)(1 − 2ν)), in Pa.
  double Lambda() const;
  // Shear modulus μ = G = E / (2(1 + ν)), in Pa.
  double Mu() const;
  // Elasticity matrix D (6 by 6) mapping engineering strain (εxx, εyy, εzz, γyz, γxz, γxy),
  // with γ = 2ε, to stress (σxx, σyy, σzz, σyz, σxz, σxy) in Pa.
  Matrix6d ElasticityMatrix() const;
};

// Materials by region label. Every region used by a mesh must have an entry.
class MaterialTable {
 public:
  // Table with one material for every region.
  explicit MaterialTable(const Material& default_material);
  // Empty table (every region must then be set explicitly).
  MaterialTable() = default;

  // Sets the material of region `label`; throws std::invalid_argument (naming the region and
  // field) when the material is invalid.
  void Set(int label, const Material& material);
  // Material of region `label`; throws std::invalid_argument when the region has none.
  const Material& Get(int label) const;

 private:
  bool has_default_ = false;
  Material default_;
  std::map<int, Material> by_region_;
};

}  // namespace spidarcad::fem
