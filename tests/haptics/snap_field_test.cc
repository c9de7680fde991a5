// Tests of the snap field: the pull points at the nearest vertex with the closed-form
// magnitude, is zero beyond the capture radius and fades continuously (C¹) to it, vertices
// win over edges over faces, the total force is continuous along sweeps across layer
// boundaries, bounded polygons pull toward their nearest point, and Evaluate allocates nothing.
// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#include "spidarcad/haptics/snap_field.h"

#include <gtest/gtest.h>

#include <cmath>
#include <stdexcept>

#include "support/malloc_counter.h"

namespace spidarcad::haptics {
namespace {

ToolKinematics At(const Eigen::Vector3d& p) {
  ToolKinematics t;
  t.p_WT = p;
  return t;
}

// The profile written out independently: F_max · tanh(4d/r) · (1 − smoothstep over [r/2, r]).
double ExpectedPull(double d, double r, double f_max) {
  if (d >= r) return 0.0;
  const double u = std::clamp(2.0 * d / r - 1.0, 0.0, 1.0);
  return f_max * std::tanh(4.0 * d / r) * (1.0 - u * u * (3.0 - 2.0 * u));
}

TEST(SnapField, PullsTowardTheNearestVertexWithTheProfileMagnitude) {
  SnapFeatures features;
  features.vertices_W = {Eigen::Vector3d(0, 0, 0), Eigen::Vector3d(0.05, 0, 0),
                         Eigen::Vector3d(0, 0.05, 0)};
  SnapSettings s;
  SnapField field(features, s);
  for (const Eigen::Vector3d& offset :
       {Eigen::Vector3d(0.003, 0.002, -0.001), Eigen::Vector3d(-0.005, 0.004, 0.0),
        Eigen::Vector3d(0.0005, 0.0, 0.0)}) {
    const Eigen::Vector3d tool = features.vertices_W[1] + offset;
    const ToolWrench w = field.Evaluate(At(tool));
    const Eigen::Vector3d expected =
        -offset.normalized() * ExpectedPull(offset.norm(), s.vertex_radius, s.max_force);
    EXPECT_LT((w.f_T_W - expected).norm(), 1e-12) << offset.transpose();
    EXPECT_EQ(field.snapped().kind, SnapKind::kVertex);
    EXPECT_EQ(field.snapped().index, 1);
    EXPECT_LE(w.f_T_W.norm(), s.max_force);
  }
}

TEST(SnapField, IsZeroBeyondTheCaptureRadiusAndFadesContinuouslyToIt) {
  SnapFeatures features;
  features.vertices_W = {Eigen::Vector3d(0.01, 0.02, 0.03)};
  SnapSettings s;
  SnapField field(features, s);
  const Eigen::Vector3d dir = Eigen::Vector3d(1, -2, 0.5).normalized();
  const double r = s.vertex_radius;
  EXPECT_EQ(field.Evaluate(At(features.vertices_W[0] + 1.01 * r * dir)).f_T_W.norm(), 0.0);
  EXPECT_EQ(field.snapped().kind, SnapKind::kNone);
  EXPECT_EQ(field.snapped().index, -1);
  // Just inside: the force and its slope vanish at r (C¹): |F(r − ε)| = O(ε²).
  double previous = 0.0;
  for (const double eps : {1e-2, 1e-3, 1e-4}) {
    const double f =
        field.Evaluate(At(features.vertices_W[0] + (1.0 - eps) * r * dir)).f_T_W.norm();
    EXPECT_LT(f, 12.0 * s.max_force * eps * eps) << eps;  // 1 − S(1 − 2ε) ≈ 12ε²
    if (previous > 0) {
      EXPECT_LT(f, previous * 0.02);
    }
    previous = f;
  }
  EXPECT_EQ(field.snapped().kind, SnapKind::kVertex);
}

TEST(SnapField, PrefersVerticesOverEdgesOverFaces) {
  // A square face in z = 0 with its edges and corners.
  const Eigen::Vector3d c[4] = {{0, 0, 0}, {0.04, 0, 0}, {0.04, 0.04, 0}, {0, 0.04, 0}};
  SnapFeatures features;
  SnapFace face;
  for (const auto& v : c) {
    features.vertices_W.push_back(v);
    face.polygon_W.push_back(v);
  }
  for (int i = 0; i < 4; ++i) features.edges_W.emplace_back(c[i], c[(i + 1) % 4]);
  features.faces_W.push_back(face);
  SnapSettings s;
  SnapField field(features, s);
  // 3 mm from corner 0 but right on edge 0 (y = 0): the vertex wins, and inside half its
  // radius the force points exactly at it.
  ToolWrench w = field.Evaluate(At({0.003, 0.0, 0.0}));
  EXPECT_EQ(field.snapped().kind, SnapKind::kVertex);
  EXPECT_EQ(field.snapped().index, 0);
  EXPECT_LT((w.f_T_W.normalized() + Eigen::Vector3d::UnitX()).norm(), 1e-12);
  // Mid-edge, 2 mm above the face: the edge is snapped (nearest edge 0).
  field.Evaluate(At({0.02, 0.001, 0.002}));
  EXPECT_EQ(field.snapped().kind, SnapKind::kEdge);
  EXPECT_EQ(field.snapped().index, 0);
  // Over the middle of the face, 2 mm up: the face, pulled straight down by F(2 mm).
  w = field.Evaluate(At({0.02, 0.02, 0.002}));
  EXPECT_EQ(field.snapped().kind, SnapKind::kFace);
  EXPECT_EQ(field.snapped().index, 0);
  EXPECT_LT(
      (w.f_T_W - Eigen::Vector3d(0, 0, -ExpectedPull(0.002, s.face_radius, s.max_force))).norm(),
      1e-12);
}

TEST(SnapField, TotalForceIsContinuousAcrossLayerBoundaries) {
  const Eigen::Vector3d c[4] = {{0, 0, 0}, {0.04, 0, 0}, {0.04, 0.04, 0}, {0, 0.04, 0}};
  SnapFeatures features;
  SnapFace face;
  for (const auto& v : c) {
    features.vertices_W.push_back(v);
    face.polygon_W.push_back(v);
  }
  for (int i = 0; i < 4; ++i) features.edges_W.emplace_back(c[i], c[(i + 1) % 4]);
  features.faces_W.push_back(face);
  SnapSettings s;
  SnapField field(features, s);
  // Sweeps in 10 µm steps from outside the corner over the face and off its far side, at
  // heights crossing every capture radius. Largest slope of any layer: F_max·4/r_face ≈ 1.3 N/mm
  // plus the weights' slopes: a step of 10 µm may change the force by well under 0.05 N.
  for (const double height : {0.0005, 0.002, 0.0045}) {
    Eigen::Vector3d previous = field.Evaluate(At({-0.01, -0.004, height})).f_T_W;
    double worst = 0.0;
    for (int k = 1; k <= 6000; ++k) {
      const Eigen::Vector3d p(-0.01 + 1e-5 * k, -0.004 + 0.8e-5 * k, height);
      const Eigen::Vector3d f = field.Evaluate(At(p)).f_T_W;
      worst = std::max(worst, (f - previous).norm());
      previous = f;
      ASSERT_LE(f.norm(), 3.0 * s.max_force);
    }
    EXPECT_LT(worst, 0.05) << "height " << height;
  }
}

TEST(SnapField, BoundedPolygonPullsTowardItsNearestPointAndPlanesTowardTheirProjection) {
  SnapFeatures features;
  SnapFace triangle;
  triangle.polygon_W = {{0, 0, 0.01}, {0.03, 0, 0.01}, {0, 0.03, 0.01}};
  features.faces_W.push_back(triangle);
  SnapFace plane;
  plane.point_W = Eigen::Vector3d(0, 0, -0.05);
  plane.normal_W = Eigen::Vector3d(0, 0, -2);
  features.faces_W.push_back(plane);
  SnapSettings s;
  SnapField field(features, s);
  // Beyond the hypotenuse x + y = 0.03, 1 mm above: the nearest point is on the hypotenuse.
  const Eigen::Vector3d p(0.0165, 0.0155, 0.011);
  const Eigen::Vector3d nearest(0.0155, 0.0145, 0.01);  // foot on x + y = 0.03
  EXPECT_LT((field.ClosestOnFace(0, p) - nearest).norm(), 1e-15);
  const ToolWrench w = field.Evaluate(At(p));
  const Eigen::Vector3d delta = nearest - p;
  EXPECT_LT((w.f_T_W - delta.normalized() * ExpectedPull(delta.norm(), s.face_radius, s.max_force))
                .norm(),
            1e-12);
  EXPECT_LT(
      (field.ClosestOnFace(1, Eigen::Vector3d(1, 2, -0.048)) - Eigen::Vector3d(1, 2, -0.05)).norm(),
      1e-15);
  field.Evaluate(At({1, 2, -0.048}));
  EXPECT_EQ(field.snapped().kind, SnapKind::kFace);
  EXPECT_EQ(field.snapped().index, 1);
}

TEST(SnapField, RejectsBadFeaturesNamingThem) {
  SnapFeatures degenerate;
  degenerate.edges_W.emplace_back(Eigen::Vector3d::Zero(), Eigen::Vector3d::Zero());
  try {
    SnapField field(degenerate);
    FAIL();
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("edge 0"), std::string::npos) << e.what();
  }
  SnapFeatures warped;
  SnapFace face;
  face.polygon_W = {{0, 0, 0}, {1, 0, 0}, {1, 1, 0.1}, {0, 1, 0}};
  warped.faces_W.push_back(face);
  EXPECT_THROW(SnapField{warped}, std::invalid_argument);
  SnapSettings s;
  s.vertex_radius = 0;
  EXPECT_THROW(SnapField(SnapFeatures{}, s), std::invalid_argument);
}

TEST(SnapField, EvaluateAllocatesNothing) {
  ASSERT_TRUE(test_support::MallocCounterActive());
  SnapFeatures features;
  for (int i = 0; i < 40; ++i) features.vertices_W.emplace_back(0.01 * i, 0, 0);
  for (int i = 0; i < 40; ++i)
    features.edges_W.emplace_back(Eigen::Vector3d(0.01 * i, 0, 0),
                                  Eigen::Vector3d(0.01 * i, 0.01, 0));
  SnapFace face;
  face.polygon_W = {{0, 0, 0}, {0.4, 0, 0}, {0.4, 0.01, 0}, {0, 0.01, 0}};
  features.faces_W.push_back(face);
  SnapField field(features);
  double sum = 0;
  long allocations = 0;
  {
    test_support::MallocCounter counter;
    for (int k = 0; k < 2000; ++k) {
      sum += field.Evaluate(At({2e-4 * k, 0.004, 0.002})).f_T_W.norm();
      sum += field.snapped().index;
    }
    allocations = counter.count();
  }
  EXPECT_EQ(allocations, 0);
  EXPECT_GT(sum, 0);
}

}  // namespace
}  // namespace spidarcad::haptics
