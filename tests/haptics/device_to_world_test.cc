// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#include "spidarcad/haptics/device_to_world.h"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <random>

namespace spidarcad::haptics {
namespace {

Eigen::Vector3d RandomVector(std::mt19937* rng, double scale) {
  std::uniform_real_distribution<double> u(-scale, scale);
  return Eigen::Vector3d(u(*rng), u(*rng), u(*rng));
}

TEST(DeviceToWorld, MapsPointsByScaleAndOffsetAndBack) {
  const DeviceToWorld x{2.5, Eigen::Vector3d(0.1, -0.2, 0.3)};
  // A device point 4 cm along y lands 10 cm along y from the device origin's image.
  EXPECT_LT((x.PointToWorld(Eigen::Vector3d(0, 0.04, 0)) - Eigen::Vector3d(0.1, -0.1, 0.3)).norm(),
            1e-15);
  EXPECT_LT((x.PointToWorld(Eigen::Vector3d::Zero()) - x.p_WDo).norm(), 1e-15);
  std::mt19937 rng(3);
  for (int i = 0; i < 100; ++i) {
    const Eigen::Vector3d p_D = RandomVector(&rng, 0.2);
    const Eigen::Vector3d p_W = x.PointToWorld(p_D);
    for (int a = 0; a < 3; ++a) EXPECT_DOUBLE_EQ(p_W(a), 2.5 * p_D(a) + x.p_WDo(a));
    EXPECT_LT((x.PointToDevice(p_W) - p_D).norm(), 1e-15);
    // Differences of points are vectors: they scale and do not shift.
    const Eigen::Vector3d q_D = RandomVector(&rng, 0.2);
    EXPECT_LT((x.PointToWorld(q_D) - p_W - x.VectorToWorld(q_D - p_D)).norm(), 1e-15);
    EXPECT_LT((x.VectorToDevice(x.VectorToWorld(q_D)) - q_D).norm(), 1e-16);
  }
}

TEST(DeviceToWorld, DefaultIsTheIdentity) {
  const DeviceToWorld x;
  const Eigen::Vector3d p(0.01, 0.02, -0.03);
  EXPECT_EQ(x.PointToWorld(p), p);
  EXPECT_EQ(x.PointToDevice(p), p);
  EXPECT_EQ(x.ForceToDevice(p), p);
  EXPECT_TRUE(x.IsValid());
}

TEST(DeviceToWorld, BoxToDeviceHoldsThePreimagesOfTheBoxCorners) {
  const DeviceToWorld x{4.0, Eigen::Vector3d(1.0, 0.0, -1.0)};
  const Eigen::AlignedBox3d box_W(Eigen::Vector3d(0.6, -0.4, -1.2), Eigen::Vector3d(1.4, 0.4, 0));
  const Eigen::AlignedBox3d box_D = x.BoxToDevice(box_W);
  EXPECT_LT((box_D.min() - Eigen::Vector3d(-0.1, -0.1, -0.05)).norm(), 1e-15);
  EXPECT_LT((box_D.max() - Eigen::Vector3d(0.1, 0.1, 0.25)).norm(), 1e-15);
  EXPECT_TRUE(x.BoxToDevice(Eigen::AlignedBox3d()).isEmpty());
}

// f_D = s·f_W is the force conjugate to the map: for a world potential U(p_W) (a spring), the
// device force −∂U(X_WD p_D)/∂p_D found by central differences in D equals ForceToDevice of the
// world force −∂U/∂p_W, and f_D·v_D + m_D·ω_D = f_W·v_W + m_W·ω_W for any motion.
TEST(DeviceToWorld, ForceMapIsPowerConjugateToTheVelocityMap) {
  const DeviceToWorld x{3.7, Eigen::Vector3d(-0.2, 0.5, 0.05)};
  const double k = 800.0;  // N/m in W
  const Eigen::Vector3d anchor_W(0.1, 0.4, 0.2);
  auto energy = [&](const Eigen::Vector3d& p_W) {
    return 0.5 * k * (p_W - anchor_W).squaredNorm();
  };
  std::mt19937 rng(12);
  for (int i = 0; i < 50; ++i) {
    const Eigen::Vector3d p_D = RandomVector(&rng, 0.1);
    const Eigen::Vector3d p_W = x.PointToWorld(p_D);
    const Eigen::Vector3d f_W = -k * (p_W - anchor_W);
    const Eigen::Vector3d f_D = x.ForceToDevice(f_W);
    const double step = 1e-6;  // m in D
    for (int a = 0; a < 3; ++a) {
      const Eigen::Vector3d e = step * Eigen::Vector3d::Unit(a);
      const double f_fd =
          -(energy(x.PointToWorld(p_D + e)) - energy(x.PointToWorld(p_D - e))) / (2 * step);
      EXPECT_NEAR(f_D(a), f_fd, 1e-6 * (1 + std::abs(f_fd))) << i << " axis " << a;
    }
    const Eigen::Vector3d v_D = RandomVector(&rng, 0.5), w = RandomVector(&rng, 3.0);
    const Eigen::Vector3d m_W = RandomVector(&rng, 0.2);
    const double power_W = f_W.dot(x.VectorToWorld(v_D)) + m_W.dot(w);  // ω_W = ω_D
    const double power_D = f_D.dot(v_D) + x.MomentToDevice(m_W).dot(w);
    EXPECT_NEAR(power_D, power_W, 1e-12 * (1 + std::abs(power_W))) << i;
  }
}

TEST(DeviceToWorld, IsValidOnlyForAFinitePositiveScaleAndAFiniteOrigin) {
  EXPECT_TRUE((DeviceToWorld{0.5, Eigen::Vector3d(1, 2, 3)}.IsValid()));
  EXPECT_FALSE((DeviceToWorld{0.0, Eigen::Vector3d::Zero()}.IsValid()));
  EXPECT_FALSE((DeviceToWorld{-1.0, Eigen::Vector3d::Zero()}.IsValid()));
  EXPECT_FALSE(
      (DeviceToWorld{std::numeric_limits<double>::infinity(), Eigen::Vector3d::Zero()}.IsValid()));
  EXPECT_FALSE((DeviceToWorld{NAN, Eigen::Vector3d::Zero()}.IsValid()));
  EXPECT_FALSE((DeviceToWorld{1.0, Eigen::Vector3d(0, NAN, 0)}.IsValid()));
}

}  // namespace
}  // namespace spidarcad::haptics
