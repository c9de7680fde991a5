// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#include "spidarcad/fem/material.h"

#include <gtest/gtest.h>

#include <Eigen/LU>
#include <limits>
#include <stdexcept>
#include <string>

namespace spidarcad::fem {
namespace {

std::string ErrorOf(const Material& m) {
  try {
    m.Validate();
  } catch (const std::invalid_argument& e) {
    return e.what();
  }
  return "";
}

TEST(Material, ValidateNamesFieldAndValueWhenOutOfRange) {
  EXPECT_EQ(ErrorOf({2.0e11, 0.3}), "");
  EXPECT_EQ(ErrorOf({1.0, -0.99}), "");
  const std::string e0 = ErrorOf({0.0, 0.3});
  EXPECT_NE(e0.find("youngs_modulus"), std::string::npos) << e0;
  const std::string e1 = ErrorOf({-5.0, 0.3});
  EXPECT_NE(e1.find("-5"), std::string::npos) << e1;
  const std::string e2 = ErrorOf({1e9, 0.5});
  EXPECT_NE(e2.find("poisson_ratio"), std::string::npos) << e2;
  EXPECT_NE(e2.find("0.5"), std::string::npos) << e2;
  EXPECT_NE(ErrorOf({1e9, -1.0}).find("-1"), std::string::npos);
  EXPECT_NE(ErrorOf({std::numeric_limits<double>::quiet_NaN(), 0.3}), "");
  EXPECT_NE(ErrorOf({1e9, std::numeric_limits<double>::infinity()}), "");
}

TEST(Material, ComplianceGivesYoungsModulusAndPoissonRatioWhenInverted) {
  const Material m{7.0e10, 0.33};
  const Matrix6d c = m.ElasticityMatrix().inverse();
  // Uniaxial stress σxx: εxx = σ/E, εyy = −νσ/E; shear γ = τ/G.
  EXPECT_NEAR(c(0, 0) * m.youngs_modulus, 1.0, 1e-12);
  EXPECT_NEAR(-c(1, 0) / c(0, 0), 0.33, 1e-12);
  EXPECT_NEAR(c(3, 3) * m.youngs_modulus / (2.0 * 1.33), 1.0, 1e-12);
  EXPECT_NEAR(m.Lambda() + 2.0 * m.Mu() / 3.0, m.youngs_modulus / (3.0 * (1.0 - 2.0 * 0.33)), 1.0);
}

TEST(MaterialTable, ThrowsNamingRegionWhenMissingOrInvalid) {
  MaterialTable table;
  table.Set(3, {1e9, 0.2});
  EXPECT_DOUBLE_EQ(table.Get(3).youngs_modulus, 1e9);
  try {
    table.Get(4);
    FAIL();
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("region 4"), std::string::npos) << e.what();
  }
  try {
    table.Set(5, {1e9, 0.7});
    FAIL();
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("region 5"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("poisson_ratio"), std::string::npos) << e.what();
  }
  MaterialTable with_default(Material{2e9, 0.1});
  EXPECT_DOUBLE_EQ(with_default.Get(42).youngs_modulus, 2e9);
  EXPECT_THROW(MaterialTable(Material{-1.0, 0.1}), std::invalid_argument);
}

}  // namespace
}  // namespace spidarcad::fem
