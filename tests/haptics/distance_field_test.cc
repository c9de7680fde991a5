// Tests of the simple distance fields: values against closed forms and brute-force distances,
// gradients against finite differences, rigid transforms, unions, bad input, no allocation.
// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#include "spidarcad/haptics/distance_field.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <cstring>
#include <limits>
#include <memory>
#include <random>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include "support/malloc_counter.h"

namespace spidarcad::haptics {
namespace {

// Distance from p to the surface of the box [−h, h] by brute force: the nearest of many
// sampled surface points (upper bound) refined by the clamp formula for outside points.
double BruteForceBoxDistance(const Eigen::Vector3d& h, const Eigen::Vector3d& p) {
  double best = std::numeric_limits<double>::infinity();
  const int n = 60;
  for (int axis = 0; axis < 3; ++axis) {
    const int u = (axis + 1) % 3, v = (axis + 2) % 3;
    for (int side = -1; side <= 1; side += 2) {
      for (int i = 0; i <= n; ++i) {
        for (int j = 0; j <= n; ++j) {
          Eigen::Vector3d q;
          q(axis) = side * h(axis);
          q(u) = -h(u) + 2 * h(u) * i / n;
          q(v) = -h(v) + 2 * h(v) * j / n;
          // Within the face cell, the exact nearest point on this face:
          Eigen::Vector3d c = p;
          c(axis) = side * h(axis);
          c(u) = std::clamp(p(u), -h(u), h(u));
          c(v) = std::clamp(p(v), -h(v), h(v));
          best = std::min(best, std::min((q - p).norm(), (c - p).norm()));
        }
      }
    }
  }
  const bool inside = (p.cwiseAbs().array() < h.array()).all();
  return inside ? -best : best;
}

Eigen::Vector3d FiniteDifferenceGradient(const DistanceField& f, const Eigen::Vector3d& p) {
  const double e = 1e-7;
  Eigen::Vector3d g;
  for (int i = 0; i < 3; ++i) {
    Eigen::Vector3d d = Eigen::Vector3d::Zero();
    d(i) = e;
    g(i) = (f.Evaluate(p + d, nullptr) - f.Evaluate(p - d, nullptr)) / (2 * e);
  }
  return g;
}

TEST(SphereDistanceField, MatchesTheClosedFormAndItsGradient) {
  const Eigen::Vector3d c(0.01, -0.02, 0.03);
  const SphereDistanceField sphere(c, 0.05);
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> u(-0.1, 0.1);
  for (int k = 0; k < 200; ++k) {
    const Eigen::Vector3d p(u(rng), u(rng), u(rng));
    Eigen::Vector3d g;
    const double v = sphere.Evaluate(p, &g);
    EXPECT_NEAR(v, std::sqrt((p - c).squaredNorm()) - 0.05, 1e-15);
    EXPECT_LT((g - FiniteDifferenceGradient(sphere, p)).norm(), 1e-6);
  }
}

TEST(BoxDistanceField, MatchesABruteForceDistanceInsideAndOutside) {
  const Eigen::Vector3d h(0.03, 0.02, 0.01);
  const BoxDistanceField box(h);
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> u(-0.05, 0.05);
  for (int k = 0; k < 60; ++k) {
    const Eigen::Vector3d p(u(rng), u(rng), u(rng));
    EXPECT_NEAR(box.Evaluate(p, nullptr), BruteForceBoxDistance(h, p), 1e-12) << p.transpose();
  }
}

TEST(BoxDistanceField, GradientMatchesFiniteDifferencesAwayFromCreases) {
  const BoxDistanceField box(Eigen::Vector3d(0.03, 0.02, 0.01));
  const Eigen::Vector3d points[] = {{0.05, 0.0, 0.0},   {0.05, 0.04, 0.0}, {0.05, 0.04, -0.03},
                                    {0.0, 0.0, 0.005},  {0.025, 0.0, 0.0}, {-0.01, -0.018, 0.0},
                                    {0.0, -0.03, -0.02}};
  for (const auto& p : points) {
    Eigen::Vector3d g;
    box.Evaluate(p, &g);
    EXPECT_LT((g - FiniteDifferenceGradient(box, p)).norm(), 1e-6) << p.transpose();
  }
}

TEST(HalfSpaceDistanceField, IsTheSignedDistanceToThePlane) {
  const HalfSpaceDistanceField half(Eigen::Vector3d(0, 0, 0.01), Eigen::Vector3d(0, 0, 3.0));
  Eigen::Vector3d g;
  EXPECT_DOUBLE_EQ(half.Evaluate(Eigen::Vector3d(0.2, -0.3, 0.004), &g), -0.006);
  EXPECT_EQ(g, Eigen::Vector3d::UnitZ());
}

TEST(TransformedDistanceField, PreservesDistancesUnderARigidMotion) {
  auto box = std::make_shared<BoxDistanceField>(Eigen::Vector3d(0.03, 0.02, 0.01));
  Eigen::Isometry3d X_WB = Eigen::Isometry3d::Identity();
  X_WB.linear() = Eigen::AngleAxisd(0.7, Eigen::Vector3d(1, 2, 3).normalized()).toRotationMatrix();
  X_WB.translation() = Eigen::Vector3d(0.1, -0.2, 0.05);
  const TransformedDistanceField placed(box, X_WB);
  // 4 mm outside the +x face, 2 mm inside the −z face: distances and normals in W.
  Eigen::Vector3d g;
  EXPECT_NEAR(placed.Evaluate(X_WB * Eigen::Vector3d(0.034, 0.001, 0.0), &g), 0.004, 1e-15);
  EXPECT_LT((g - X_WB.linear().col(0)).norm(), 1e-12);
  EXPECT_NEAR(placed.Evaluate(X_WB * Eigen::Vector3d(0.0, 0.0, -0.008), &g), -0.002, 1e-15);
  EXPECT_LT((g + X_WB.linear().col(2)).norm(), 1e-12);
  // A transformed sphere is the sphere at the moved centre.
  auto sphere = std::make_shared<SphereDistanceField>(Eigen::Vector3d::Zero(), 0.02);
  const TransformedDistanceField moved(sphere, X_WB);
  const SphereDistanceField reference(X_WB.translation(), 0.02);
  const Eigen::Vector3d p(0.13, -0.18, 0.07);
  EXPECT_NEAR(moved.Evaluate(p, nullptr), reference.Evaluate(p, nullptr), 1e-15);
}

TEST(UnionDistanceField, IsTheMinimumOfItsChildren) {
  auto a = std::make_shared<SphereDistanceField>(Eigen::Vector3d(-0.02, 0, 0), 0.015);
  auto b = std::make_shared<SphereDistanceField>(Eigen::Vector3d(0.02, 0, 0), 0.01);
  const UnionDistanceField both({a, b});
  Eigen::Vector3d g;
  EXPECT_NEAR(both.Evaluate(Eigen::Vector3d(0.04, 0, 0), &g), 0.01, 1e-15);
  EXPECT_LT((g - Eigen::Vector3d::UnitX()).norm(), 1e-15);
  EXPECT_NEAR(both.Evaluate(Eigen::Vector3d(-0.04, 0, 0), &g), 0.005, 1e-15);
  EXPECT_LT((g + Eigen::Vector3d::UnitX()).norm(), 1e-15);
}

TEST(DistanceFields, RejectBadParametersNamingThem) {
  EXPECT_THROW(SphereDistanceField(Eigen::Vector3d::Zero(), 0.0), std::invalid_argument);
  EXPECT_THROW(BoxDistanceField(Eigen::Vector3d(0.1, -0.1, 0.1)), std::invalid_argument);
  EXPECT_THROW(HalfSpaceDistanceField(Eigen::Vector3d::Zero(), Eigen::Vector3d::Zero()),
               std::invalid_argument);
  EXPECT_THROW(UnionDistanceField({}), std::invalid_argument);
  Eigen::Isometry3d scaled = Eigen::Isometry3d::Identity();
  scaled.linear() *= 2.0;
  EXPECT_THROW(
      TransformedDistanceField(std::make_shared<BoxDistanceField>(Eigen::Vector3d::Ones()), scaled),
      std::invalid_argument);
  try {
    SphereDistanceField(Eigen::Vector3d::Zero(), -1.0);
    FAIL();
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("radius"), std::string::npos) << e.what();
  }
}

std::uint64_t Bits(double v) {
  std::uint64_t b;
  std::memcpy(&b, &v, sizeof b);
  return b;
}

// A field that only knows Evaluate: its EvaluateBatch is the default, point by point.
class PointByPoint final : public DistanceField {
 public:
  explicit PointByPoint(std::shared_ptr<const DistanceField> f) : f_(std::move(f)) {}
  double Evaluate(const Eigen::Vector3d& p, Eigen::Vector3d* g) const noexcept override {
    return f_->Evaluate(p, g);
  }

 private:
  std::shared_ptr<const DistanceField> f_;
};

// EvaluateBatch of `field` against Evaluate point by point, bit for bit, with and without
// gradients, over n = 0..3 points and all of `points` (more than one chunk of the unions).
void ExpectBatchBitIdentical(const DistanceField& field, const std::vector<Eigen::Vector3d>& points,
                             const std::string& name) {
  const int n = static_cast<int>(points.size());
  std::vector<double> x(n), y(n), z(n), phi(n), psi(n), gx(n), gy(n), gz(n);
  for (int i = 0; i < n; ++i) {
    x[i] = points[i].x();
    y[i] = points[i].y();
    z[i] = points[i].z();
  }
  for (int count : {0, 1, 3, n}) {
    field.EvaluateBatch(x.data(), y.data(), z.data(), count, phi.data(), nullptr, nullptr, nullptr);
    field.EvaluateBatch(x.data(), y.data(), z.data(), count, psi.data(), gx.data(), gy.data(),
                        gz.data());
    int failures = 0;
    for (int i = 0; i < count && failures < 3; ++i) {
      Eigen::Vector3d g;
      const double value = field.Evaluate(points[i], nullptr);
      const double with_gradient = field.Evaluate(points[i], &g);
      const bool same = Bits(phi[i]) == Bits(value) && Bits(psi[i]) == Bits(with_gradient) &&
                        Bits(gx[i]) == Bits(g.x()) && Bits(gy[i]) == Bits(g.y()) &&
                        Bits(gz[i]) == Bits(g.z());
      if (!same) {
        ++failures;
        ADD_FAILURE() << name << ", point " << i << " of " << count << ": Evaluate " << value
                      << " / " << with_gradient << " (" << g.transpose() << "), batch " << phi[i]
                      << " / " << psi[i] << " (" << gx[i] << " " << gy[i] << " " << gz[i] << ")";
      }
    }
  }
}

TEST(DistanceFields, EvaluateBatchIsBitIdenticalToEvaluate) {
  auto box = std::make_shared<BoxDistanceField>(Eigen::Vector3d(0.03, 0.02, 0.01));
  auto sphere = std::make_shared<SphereDistanceField>(Eigen::Vector3d(0.02, 0, 0), 0.02);
  Eigen::Isometry3d X_WB = Eigen::Isometry3d::Identity();
  X_WB.linear() = Eigen::AngleAxisd(0.7, Eigen::Vector3d(1, 2, 3).normalized()).toRotationMatrix();
  X_WB.translation() = Eigen::Vector3d(0.01, -0.02, 0.005);
  auto placed = std::make_shared<TransformedDistanceField>(box, X_WB);
  auto floor =
      std::make_shared<HalfSpaceDistanceField>(Eigen::Vector3d::Zero(), Eigen::Vector3d::UnitZ());
  // A union of the overriding fields, and one whose first child is point by point; ties (a
  // sphere twice) keep the first child's gradient.
  const UnionDistanceField all({placed, sphere, floor, sphere});
  const UnionDistanceField mixed({std::make_shared<PointByPoint>(placed), box});
  const TransformedDistanceField moved_union(
      std::make_shared<UnionDistanceField>(
          std::vector<std::shared_ptr<const DistanceField>>{sphere, placed}),
      X_WB.inverse());
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> u(-0.06, 0.06);
  std::vector<Eigen::Vector3d> points;
  for (int i = 0; i < 150; ++i) points.emplace_back(u(rng), u(rng), u(rng));
  points.emplace_back(0.02, 0.0, 0.0);  // the sphere's centre
  points.emplace_back(std::numeric_limits<double>::quiet_NaN(), 0.0, 0.0);
  ExpectBatchBitIdentical(all, points, "union");
  ExpectBatchBitIdentical(mixed, points, "union with a point-by-point child");
  ExpectBatchBitIdentical(moved_union, points, "transformed union");
  ExpectBatchBitIdentical(*placed, points, "transformed box");
  ExpectBatchBitIdentical(*sphere, points, "sphere (default batch)");
}

TEST(DistanceFields, EvaluateAllocatesNothing) {
  ASSERT_TRUE(test_support::MallocCounterActive());
  auto box = std::make_shared<BoxDistanceField>(Eigen::Vector3d(0.03, 0.02, 0.01));
  auto sphere = std::make_shared<SphereDistanceField>(Eigen::Vector3d(0.05, 0, 0), 0.02);
  auto placed = std::make_shared<TransformedDistanceField>(
      box, Eigen::Isometry3d(Eigen::Translation3d(0, 0, 0.01)));
  const UnionDistanceField all({placed, sphere,
                                std::make_shared<HalfSpaceDistanceField>(
                                    Eigen::Vector3d::Zero(), Eigen::Vector3d::UnitZ())});
  double sum = 0;
  long allocations = 0;
  {
    test_support::MallocCounter counter;
    Eigen::Vector3d g;
    for (int k = 0; k < 1000; ++k)
      sum += all.Evaluate(Eigen::Vector3d(1e-4 * k, 0.01, 0.0), &g) + g.x();
    double x[100], y[100], z[100], phi[100], gx[100], gy[100], gz[100];
    for (int k = 0; k < 100; ++k) {
      x[k] = 1e-3 * k;
      y[k] = 0.01;
      z[k] = -1e-4 * k;
    }
    all.EvaluateBatch(x, y, z, 100, phi, gx, gy, gz);
    sum += phi[99] + gx[99];
    all.EvaluateBatch(x, y, z, 100, phi, nullptr, nullptr, nullptr);
    sum += phi[50];
    allocations = counter.count();
  }
  EXPECT_EQ(allocations, 0);
  EXPECT_TRUE(std::isfinite(sum));
}

}  // namespace
}  // namespace spidarcad::haptics
