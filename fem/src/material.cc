// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#include "spidarcad/fem/material.h"

#include <cmath>
#include <sstream>
#include <stdexcept>
#include <string>

namespace spidarcad::fem {

void Material::Validate() const {
  if (!std::isfinite(youngs_modulus) || !(youngs_modulus > 0.0)) {
    std::ostringstream s;
    s << "Material: youngs_modulus (E) must be finite and > 0 Pa, got " << youngs_modulus;
    throw std::invalid_argument(s.str());
  }
  if (!std::isfinite(poisson_ratio) || !(poisson_ratio > -1.0) || !(poisson_ratio < 0.5)) {
    std::ostringstream s;
    s << "Material: poisson_ratio (nu) must satisfy -1 < nu < 0.5, got " << poisson_ratio;
    throw std::invalid_argument(s.str());
  }
}

double Material::Lambda() const {
  const double e = youngs_modulus, nu = poisson_ratio;
  return e * nu / ((1.0 + nu) * (1.0 - 2.0 * nu));
}

double Material::Mu() const { return youngs_modulus / (2.0 * (1.0 + poisson_ratio)); }

Matrix6d Material::ElasticityMatrix() const {
  const double l = Lambda(), m = Mu();
  Matrix6d d = Matrix6d::Zero();
  d.topLeftCorner<3, 3>().setConstant(l);
  d.topLeftCorner<3, 3>().diagonal().array() += 2.0 * m;
  d.bottomRightCorner<3, 3>().diagonal().setConstant(m);
  return d;
}

MaterialTable::MaterialTable(const Material& default_material)
    : has_default_(true), default_(default_material) {
  default_.Validate();
}

void MaterialTable::Set(int label, const Material& material) {
  try {
    material.Validate();
  } catch (const std::invalid_argument& e) {
    throw std::invalid_argument("region " + std::to_string(label) + ": " + e.what());
  }
  by_region_[label] = material;
}

const Material& MaterialTable::Get(int label) const {
  auto it = by_region_.find(label);
  if (it != by_region_.end()) return it->second;
  if (has_default_) return default_;
  throw std::invalid_argument("MaterialTable: no material for region " + std::to_string(label));
}

}  // namespace spidarcad::fem
