// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
// The clay's distance grid (scene/clay_grid.h) against closed forms: near a fine icosphere it is
// the sphere's distance |p − c| − r within the facets' sagitta and the interpolation error, its
// gradient the radial direction; far inside it holds −band and far outside at least +band (the
// sign sweep); a local update after a bump equals recomputing every node of the same grid, and
// recomputes only a small part of it; a mesh that leaves the box is rebuilt whole.
#include "scene/clay_grid.h"

#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <vector>

#include "spidarcad/modeling/sculpt.h"

namespace spidarcad::app {
namespace {

struct Mesh {
  std::vector<Eigen::Vector3d> positions;
  std::vector<Eigen::Vector3i> triangles;
};

Mesh Sphere(double radius, int subdivisions) {
  const modeling::TriangleMesh m = modeling::IcosphereMesh(radius, subdivisions);
  Mesh out;
  for (Eigen::Index v = 0; v < m.vertices.cols(); ++v) out.positions.push_back(m.vertices.col(v));
  for (Eigen::Index t = 0; t < m.triangles.cols(); ++t) out.triangles.push_back(m.triangles.col(t));
  return out;
}

// The largest distance between the icosphere's facets and the sphere (the sagitta of its longest
// edge e: r − sqrt(r² − e²/3) bounds the depth of a facet's centre below the sphere).
double Sagitta(const Mesh& m, double radius) {
  double e = 0.0;
  for (const Eigen::Vector3i& t : m.triangles)
    for (int k = 0; k < 3; ++k)
      e = std::max(e, (m.positions[t[(k + 1) % 3]] - m.positions[t[k]]).norm());
  return radius - std::sqrt(radius * radius - e * e / 3.0);
}

TEST(ClayDistanceGrid, IsTheSphereDistanceNearAFineIcosphere) {
  const double r = 0.02;
  const Mesh m = Sphere(r, 5);
  ClayGridSettings settings;
  settings.cell = 0.001;
  const auto grid = ClayDistanceGrid::Build(m.positions, m.triangles, settings);
  const double band = grid->band();
  EXPECT_DOUBLE_EQ(band, 3.0 * settings.cell);
  // Trilinear interpolation of |p| − r: error below h²/r (curvature 1/r over a cell), where no
  // corner of the point's cell is clamped to ±band (|φ| < band − √3 h).
  const double tolerance = Sagitta(m, r) + settings.cell * settings.cell / r;
  const double accurate = band - std::sqrt(3.0) * settings.cell;
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> unit(-1.0, 1.0);
  std::uniform_real_distribution<double> offset(-accurate, accurate);
  double worst = 0.0, worst_angle = 0.0;
  for (int i = 0; i < 2000; ++i) {
    Eigen::Vector3d dir(unit(rng), unit(rng), unit(rng));
    if (dir.norm() < 1e-3) continue;
    dir.normalize();
    const Eigen::Vector3d p = (r + offset(rng)) * dir;
    Eigen::Vector3d gradient;
    const double phi = grid->Evaluate(p, &gradient);
    worst = std::max(worst, std::abs(phi - (p.norm() - r)));
    worst_angle =
        std::max(worst_angle, std::acos(std::clamp(gradient.normalized().dot(dir), -1.0, 1.0)));
  }
  EXPECT_LT(worst, tolerance) << "sagitta " << Sagitta(m, r);
  EXPECT_LT(worst_angle, 0.1);  // rad: the gradient is radial
}

TEST(ClayDistanceGrid, HoldsMinusBandDeepInsideAndAtLeastBandFarOutside) {
  const double r = 0.02;
  const Mesh m = Sphere(r, 3);
  ClayGridSettings settings;
  settings.cell = 0.001;
  const auto grid = ClayDistanceGrid::Build(m.positions, m.triangles, settings);
  const double band = grid->band();
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> unit(-1.0, 1.0);
  int inside = 0, outside = 0;
  for (int i = 0; i < 3000; ++i) {
    const Eigen::Vector3d p(0.03 * unit(rng), 0.03 * unit(rng), 0.03 * unit(rng));
    const double exact = p.norm() - r;
    const double phi = grid->Evaluate(p, nullptr);
    if (exact < -band - 2.0 * grid->cell()) {
      EXPECT_NEAR(phi, -band, 1e-9) << p.transpose();  // stored as float
      ++inside;
    } else if (exact > band + 2.0 * grid->cell()) {
      EXPECT_GE(phi, band - 1e-7) << p.transpose();
      EXPECT_LE(phi, exact + 1e-7) << p.transpose();  // a lower bound of the distance
      ++outside;
    }
  }
  EXPECT_GT(inside, 100);
  EXPECT_GT(outside, 1000);
  // Far outside the box: band + the distance to the box, growing with the distance.
  const Eigen::Vector3d far(1.0, 0.0, 0.0);
  Eigen::Vector3d gradient;
  const double phi = grid->Evaluate(far, &gradient);
  EXPECT_GT(phi, band + 0.9);
  EXPECT_LE(phi, far.norm() - r);
  EXPECT_NEAR(gradient.x(), 1.0, 1e-12);
}

// The vertex with the largest z.
Eigen::Vector3d Top(const Mesh& m) {
  Eigen::Vector3d top = m.positions.front();
  for (const Eigen::Vector3d& p : m.positions)
    if (p.z() > top.z()) top = p;
  return top;
}

// A bump: vertices within 15 mm of the top pushed out along z by up to 5 mm.
Mesh Bumped(const Mesh& m, Eigen::AlignedBox3d* changed) {
  Mesh out = m;
  const Eigen::Vector3d top = Top(m);
  for (Eigen::Vector3d& p : out.positions) {
    const double d = (p - top).norm();
    if (d >= 0.015) continue;
    changed->extend(p);
    const double w = 1.0 - (d / 0.015) * (d / 0.015);
    p.z() += 0.005 * w * w;
    changed->extend(p);
  }
  return out;
}

TEST(ClayDistanceGrid, LocalUpdateEqualsRecomputingEveryNodeAndIsSmall) {
  const Mesh m = Sphere(0.02, 4);
  ClayGridSettings settings;
  settings.cell = 0.001;
  const auto before = ClayDistanceGrid::Build(m.positions, m.triangles, settings);
  Eigen::AlignedBox3d changed;
  const Mesh bumped = Bumped(m, &changed);
  ASSERT_FALSE(changed.isEmpty());
  const auto local = ClayDistanceGrid::Update(*before, bumped.positions, bumped.triangles, changed);
  Eigen::AlignedBox3d everything(Eigen::Vector3d::Constant(-1.0), Eigen::Vector3d::Constant(1.0));
  const auto whole =
      ClayDistanceGrid::Update(*before, bumped.positions, bumped.triangles, everything);
  ASSERT_EQ(local->size(), whole->size());
  ASSERT_EQ(whole->recomputed_nodes(), whole->node_count());
  long differ = 0, moved = 0;
  for (int k = 0; k < local->size()[2]; ++k)
    for (int j = 0; j < local->size()[1]; ++j)
      for (int i = 0; i < local->size()[0]; ++i) {
        differ += local->Node(i, j, k) != whole->Node(i, j, k);
        moved += before->Node(i, j, k) != whole->Node(i, j, k);
      }
  EXPECT_EQ(differ, 0);
  EXPECT_GT(moved, 100);  // the bump changed the field
  EXPECT_LT(local->recomputed_nodes(), local->node_count() / 4)
      << local->recomputed_nodes() << " of " << local->node_count();
  // The bump's top is on the new surface; a point 2.5 mm above the old top, outside before,
  // is inside the bump.
  const Eigen::Vector3d top = Top(m);
  EXPECT_NEAR(local->Evaluate(top + Eigen::Vector3d(0, 0, 0.005), nullptr), 0.0, 1e-4);
  EXPECT_NEAR(before->Evaluate(top + Eigen::Vector3d(0, 0, 0.0025), nullptr), 0.0025, 1e-4);
  EXPECT_LT(local->Evaluate(top + Eigen::Vector3d(0, 0, 0.0025), nullptr), 0.0);
}

TEST(ClayDistanceGrid, AMeshThatLeavesTheBoxIsRebuiltWhole) {
  const Mesh m = Sphere(0.02, 3);
  const auto before = ClayDistanceGrid::Build(m.positions, m.triangles);
  Mesh moved = m;
  Eigen::AlignedBox3d changed;
  for (Eigen::Vector3d& p : moved.positions) {
    changed.extend(p);
    p.x() += 0.1;
    changed.extend(p);
  }
  const auto after = ClayDistanceGrid::Update(*before, moved.positions, moved.triangles, changed);
  EXPECT_EQ(after->recomputed_nodes(), after->node_count());
  EXPECT_NEAR(after->Evaluate(Eigen::Vector3d(0.1, 0, 0), nullptr), -after->band(), 1e-9);
  EXPECT_GT(after->Evaluate(Eigen::Vector3d(0, 0, 0), nullptr), 0.0);
}

TEST(ClayDistanceGrid, RejectsABadMesh) {
  std::vector<Eigen::Vector3d> p = {Eigen::Vector3d::Zero()};
  std::vector<Eigen::Vector3i> t = {Eigen::Vector3i(0, 1, 2)};
  EXPECT_THROW(ClayDistanceGrid::Build(p, t), std::invalid_argument);
  EXPECT_THROW(ClayDistanceGrid::Build({}, {}), std::invalid_argument);
}

}  // namespace
}  // namespace spidarcad::app
