// Tests of SculptMesh's self-intersection check (modeling/src/sculpt_intersection.cc): its
// decisions against a brute-force check of every moved triangle against every triangle of the
// mesh, with a second segment-triangle test (signs of orientation determinants instead of
// Möller–Trumbore), on random strokes of every tool with fixed seeds, many of which fold the
// surface through itself.
// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <array>
#include <numbers>
#include <random>
#include <string>
#include <vector>

#include "spidarcad/modeling/sculpt.h"

namespace spidarcad::modeling {
namespace {

// Six times the signed volume of tetrahedron (a, b, c, d): positive when d is on the side of
// triangle abc its normal (b - a) × (c - a) points to.
double Orient(const Eigen::Vector3d& a, const Eigen::Vector3d& b, const Eigen::Vector3d& c,
              const Eigen::Vector3d& d) {
  return (b - a).cross(c - a).dot(d - a);
}

// Segment pq meets triangle abc (closed): p and q on opposite sides of the plane (or on it) and
// the line pq passing inside the triangle's three edges (all three orientations of one sign).
bool SegmentMeetsTriangle(const Eigen::Vector3d& p, const Eigen::Vector3d& q,
                          const Eigen::Vector3d& a, const Eigen::Vector3d& b,
                          const Eigen::Vector3d& c) {
  const double sp = Orient(a, b, c, p), sq = Orient(a, b, c, q);
  if ((sp > 0.0 && sq > 0.0) || (sp < 0.0 && sq < 0.0)) return false;
  if (sp == 0.0 && sq == 0.0) return false;  // in the plane: not counted (as the check)
  const double e0 = Orient(p, q, a, b), e1 = Orient(p, q, b, c), e2 = Orient(p, q, c, a);
  return (e0 >= 0.0 && e1 >= 0.0 && e2 >= 0.0) || (e0 <= 0.0 && e1 <= 0.0 && e2 <= 0.0);
}

// The rule of sculpt.h's check, pair by pair: triangles without a shared vertex cross when an
// edge of one meets the other; with one shared vertex, when the edge opposite it in one meets
// the other; with a shared edge, when they are folded flat (normals within 2.6° of opposite).
bool PairCrosses(const std::vector<Eigen::Vector3d>& x, const Eigen::Vector3i& s,
                 const Eigen::Vector3i& t) {
  std::vector<int> shared_s, shared_t;
  for (int k = 0; k < 3; ++k) {
    for (int l = 0; l < 3; ++l) {
      if (s[k] == t[l]) {
        shared_s.push_back(k);
        shared_t.push_back(l);
      }
    }
  }
  const auto edge_meets = [&](const Eigen::Vector3i& e, int k, const Eigen::Vector3i& f) {
    return SegmentMeetsTriangle(x[e[k]], x[e[(k + 1) % 3]], x[f[0]], x[f[1]], x[f[2]]);
  };
  switch (shared_s.size()) {
    case 0:
      for (int k = 0; k < 3; ++k) {
        if (edge_meets(s, k, t) || edge_meets(t, k, s)) return true;
      }
      return false;
    case 1:
      return edge_meets(s, (shared_s[0] + 1) % 3, t) || edge_meets(t, (shared_t[0] + 1) % 3, s);
    case 2: {
      const Eigen::Vector3d ns = (x[s[1]] - x[s[0]]).cross(x[s[2]] - x[s[0]]);
      const Eigen::Vector3d nt = (x[t[1]] - x[t[0]]).cross(x[t[2]] - x[t[0]]);
      return ns.normalized().dot(nt.normalized()) < -0.999;
    }
    default:
      return false;
  }
}

// Every triangle with a moved corner against every other triangle of the mesh.
bool BruteForceIntersects(const SculptMesh& mesh) {
  std::vector<char> moved_vertex(mesh.vertex_count(), 0);
  for (int v : mesh.stroke_vertices()) moved_vertex[v] = 1;
  const std::vector<Eigen::Vector3i>& triangles = mesh.triangles();
  const std::vector<Eigen::Vector3d>& x = mesh.positions();
  const int count = mesh.triangle_count();
  std::vector<char> moved(count, 0);
  for (int t = 0; t < count; ++t) {
    moved[t] = moved_vertex[triangles[t][0]] || moved_vertex[triangles[t][1]] ||
               moved_vertex[triangles[t][2]];
  }
  for (int s = 0; s < count; ++s) {
    if (!moved[s]) continue;
    for (int t = 0; t < count; ++t) {
      if (t == s || (moved[t] && t < s)) continue;  // each pair once
      if (PairCrosses(x, triangles[s], triangles[t])) return true;
    }
  }
  return false;
}

// A lens 10 cm across and 16 mm thick (a squashed icosphere): strokes fold it easily.
TriangleMesh Lens(int subdivisions) {
  TriangleMesh mesh = IcosphereMesh(0.05, subdivisions);
  mesh.vertices.row(2) *= 0.16;
  return mesh;
}

TEST(SculptIntersection, DecisionsMatchBruteForceOnRandomStrokes) {
  std::mt19937 rng(20261202);
  std::uniform_real_distribution<double> unit(-1.0, 1.0);
  const TriangleMesh lens = Lens(3);
  int crossing = 0, clear = 0;
  for (int stroke = 0; stroke < 60; ++stroke) {
    SculptMesh mesh(lens, 0.005);
    SculptToolSettings settings;
    settings.tool = static_cast<SculptTool>(stroke % 5);
    settings.radius = 0.01 + 0.03 * (0.5 + 0.5 * unit(rng));
    settings.grasp_controls_strength = false;
    settings.conserve_volume = stroke % 3 == 0;
    settings.prevent_self_intersection = false;  // the stroke goes all the way
    const int centre = std::uniform_int_distribution<int>(0, mesh.vertex_count() - 1)(rng);
    Eigen::Isometry3d X0 = Eigen::Isometry3d::Identity();
    X0.linear() =
        Eigen::Quaterniond::FromTwoVectors(Eigen::Vector3d::UnitZ(), mesh.normals()[centre])
            .toRotationMatrix();
    X0.translation() = mesh.positions()[centre];
    mesh.BeginStroke(settings, X0, 0.0);
    const Eigen::Vector3d drag = 0.04 * Eigen::Vector3d(unit(rng), unit(rng), unit(rng));
    const Eigen::Vector3d axis = Eigen::Vector3d(unit(rng), unit(rng), unit(rng)).normalized();
    const double angle = 2.5 * unit(rng);
    for (int step = 1; step <= 4; ++step) {
      const double amount = step / 4.0;
      Eigen::Isometry3d X = X0;
      X.translation() += amount * drag;
      X.linear() = Eigen::AngleAxisd(amount * angle, axis) * X0.linear();
      mesh.UpdateStroke(X, 0.0);
      const bool expected = BruteForceIntersects(mesh);
      EXPECT_EQ(mesh.MovedRegionIntersects(), expected)
          << "stroke " << stroke << " (" << SculptToolName(settings.tool) << ", radius "
          << settings.radius << " m) step " << step;
      (expected ? crossing : clear) += 1;
    }
    mesh.CancelStroke();
  }
  // Both answers occur often, so that neither a check that always says yes nor one that always
  // says no could pass.
  EXPECT_GE(crossing, 40);
  EXPECT_GE(clear, 40);
}

TEST(SculptIntersection, MatchesBruteForceAlongABisectedStrokeAndIsFalseWithoutAStroke) {
  // The grab through the lens of HardSculpt: the checked stroke stops at the share the
  // bisection finds; the brute force agrees just below it and disagrees with a stop 1/256 later.
  const TriangleMesh lens = Lens(4);
  SculptMesh mesh(lens, 0.005);
  EXPECT_FALSE(mesh.MovedRegionIntersects());
  SculptToolSettings settings;
  settings.radius = 0.03;
  settings.grasp_controls_strength = false;
  const Eigen::Vector3d top(0, 0, 0.008), drag(0, 0, -0.03);
  Eigen::Isometry3d X = Eigen::Isometry3d::Identity();
  X.translation() = top;
  mesh.BeginStroke(settings, X, 0.0);
  X.translation() = top + drag;
  mesh.UpdateStroke(X, 0.0);
  const double limit = mesh.stroke_stats().limit;
  ASSERT_GT(limit, 0.5);
  ASSERT_LT(limit, 1.0);
  EXPECT_FALSE(mesh.MovedRegionIntersects());
  EXPECT_FALSE(BruteForceIntersects(mesh));
  mesh.CancelStroke();
  // The same stroke unchecked, with the grasp setting the share (limit + 1/256).
  settings.prevent_self_intersection = false;
  settings.grasp_controls_strength = true;
  const double share = limit + 1.0 / 256;
  const double theta =
      std::numbers::pi / 2 - share * (std::numbers::pi / 2 - settings.grasp_closed_angle);
  X.translation() = top;
  mesh.BeginStroke(settings, X, theta);
  X.translation() = top + drag;
  mesh.UpdateStroke(X, theta);
  EXPECT_TRUE(BruteForceIntersects(mesh));
  EXPECT_TRUE(mesh.MovedRegionIntersects());
  mesh.CancelStroke();
  EXPECT_FALSE(mesh.MovedRegionIntersects());
}

}  // namespace
}  // namespace spidarcad::modeling
