// Tests of the implicit node tree: validation errors name node and field; every primitive's
// value is checked against an independent closed form or a brute-force distance to densely
// sampled surface points.
// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#include "spidarcad/modeling/implicit_node.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <cmath>
#include <functional>
#include <random>
#include <string>
#include <vector>

namespace spidarcad::modeling {
namespace {

using ::testing::HasSubstr;

Eigen::Vector3d RandomPoint(std::mt19937& rng, double half) {
  std::uniform_real_distribution<double> u(-half, half);
  return {u(rng), u(rng), u(rng)};
}

// Exact signed distance of an axis-aligned box of half-extents h at the origin, written as
// "distance to the clamped point" outside and "nearest face" inside.
double BoxDistance(const Eigen::Vector3d& p, const Eigen::Vector3d& h) {
  const Eigen::Vector3d clamped = p.cwiseMax(-h).cwiseMin(h);
  if ((p - clamped).norm() > 0) return (p - clamped).norm();
  return -(h - p.cwiseAbs()).minCoeff();
}

// Distance from p to the nearest of points.
double NearestDistance(const Eigen::Vector3d& p, const std::vector<Eigen::Vector3d>& points) {
  double best = INFINITY;
  for (const Eigen::Vector3d& s : points) best = std::min(best, (p - s).squaredNorm());
  return std::sqrt(best);
}

TEST(ImplicitNodePrimitive, SphereMatchesClosedForm) {
  const ImplicitNode sphere(SphereParams{0.07});
  std::mt19937 rng(1);
  for (int i = 0; i < 200; ++i) {
    const Eigen::Vector3d p = RandomPoint(rng, 0.2);
    EXPECT_NEAR(EvaluateTree(sphere, p), p.norm() - 0.07, 1e-15);
  }
}

TEST(ImplicitNodePrimitive, BoxMatchesClosedForm) {
  const Eigen::Vector3d size(0.3, 0.2, 0.01);
  const ImplicitNode box(BoxParams{size});
  std::mt19937 rng(2);
  for (int i = 0; i < 500; ++i) {
    const Eigen::Vector3d p = RandomPoint(rng, 0.25);
    EXPECT_NEAR(EvaluateTree(box, p), BoxDistance(p, size / 2), 1e-15);
  }
}

TEST(ImplicitNodePrimitive, RoundedBoxIsInnerBoxDilated) {
  // A rounded box is the Minkowski sum of a smaller box and a ball (convex): d = d_inner - r.
  const Eigen::Vector3d size(0.1, 0.06, 0.04);
  const double r = 0.01;
  const ImplicitNode rounded(RoundedBoxParams{size, r});
  std::mt19937 rng(3);
  for (int i = 0; i < 500; ++i) {
    const Eigen::Vector3d p = RandomPoint(rng, 0.1);
    EXPECT_NEAR(EvaluateTree(rounded, p),
                BoxDistance(p, size / 2 - Eigen::Vector3d::Constant(r)) - r, 1e-15);
  }
}

TEST(ImplicitNodePrimitive, CylinderMatchesCaseAnalysis) {
  const double r = 0.04, h = 0.1;
  const ImplicitNode cylinder(CylinderParams{r, h});
  std::mt19937 rng(4);
  for (int i = 0; i < 500; ++i) {
    const Eigen::Vector3d p = RandomPoint(rng, 0.1);
    const double rho = std::hypot(p.x(), p.y());
    double expected;
    if (rho <= r && std::abs(p.z()) <= h / 2) {
      expected = -std::min(r - rho, h / 2 - std::abs(p.z()));
    } else {
      expected = std::hypot(std::max(rho - r, 0.0), std::max(std::abs(p.z()) - h / 2, 0.0));
    }
    EXPECT_NEAR(EvaluateTree(cylinder, p), expected, 1e-15);
  }
}

TEST(ImplicitNodePrimitive, CapsuleMatchesSampledSegment) {
  CapsuleParams params;
  params.a = Eigen::Vector3d(-0.03, 0.01, 0.0);
  params.b = Eigen::Vector3d(0.05, -0.02, 0.04);
  params.radius = 0.015;
  const ImplicitNode capsule(params);
  std::vector<Eigen::Vector3d> axis;
  const int n = 20000;
  for (int i = 0; i <= n; ++i) axis.push_back(params.a + (params.b - params.a) * (double(i) / n));
  const double spacing = (params.b - params.a).norm() / n;
  std::mt19937 rng(5);
  for (int i = 0; i < 200; ++i) {
    const Eigen::Vector3d p = RandomPoint(rng, 0.1);
    EXPECT_NEAR(EvaluateTree(capsule, p), NearestDistance(p, axis) - params.radius, spacing);
  }
}

TEST(ImplicitNodePrimitive, TorusMatchesSampledCentreCircle) {
  const double big_r = 0.05, small_r = 0.012;
  const ImplicitNode torus(TorusParams{big_r, small_r});
  std::vector<Eigen::Vector3d> circle;
  const int n = 40000;
  for (int i = 0; i < n; ++i) {
    const double t = 2 * M_PI * i / n;
    circle.emplace_back(big_r * std::cos(t), big_r * std::sin(t), 0.0);
  }
  const double spacing = 2 * M_PI * big_r / n;
  std::mt19937 rng(6);
  for (int i = 0; i < 200; ++i) {
    const Eigen::Vector3d p = RandomPoint(rng, 0.08);
    EXPECT_NEAR(EvaluateTree(torus, p), NearestDistance(p, circle) - small_r, spacing);
  }
}

TEST(ImplicitNodePrimitive, HalfSpaceIsSignedPlaneDistance) {
  HalfSpaceParams params;
  params.normal = Eigen::Vector3d(1, 2, -2);  // length 3, normalised by the node
  params.offset = 0.02;
  const ImplicitNode plane(params);
  std::mt19937 rng(7);
  for (int i = 0; i < 100; ++i) {
    const Eigen::Vector3d p = RandomPoint(rng, 0.2);
    EXPECT_NEAR(EvaluateTree(plane, p), (p.x() + 2 * p.y() - 2 * p.z()) / 3.0 - 0.02, 1e-15);
  }
}

// Profile of a solid of revolution sampled in the (ρ, z) half-plane; the sign comes from an
// independent inside test.
TEST(ImplicitNodePrimitive, ConeMatchesSampledProfile) {
  for (const auto& [rb, rt] :
       {std::pair{0.05, 0.0}, std::pair{0.02, 0.045}, std::pair{0.03, 0.03}}) {
    const double h = 0.08;
    const ImplicitNode cone(ConeParams{rb, rt, h});
    std::vector<Eigen::Vector3d> profile;  // (ρ, z, 0)
    const int n = 20000;
    for (int i = 0; i <= n; ++i) {
      const double t = double(i) / n;
      profile.emplace_back(rb * t, -h / 2, 0);                      // bottom disk
      profile.emplace_back(rt * t, h / 2, 0);                       // top disk
      profile.emplace_back(rb + (rt - rb) * t, -h / 2 + h * t, 0);  // slanted side
    }
    const double spacing = std::hypot(h, rt - rb) / n + 0.05 / n;
    std::mt19937 rng(8);
    for (int i = 0; i < 200; ++i) {
      const Eigen::Vector3d p = RandomPoint(rng, 0.08);
      const double rho = std::hypot(p.x(), p.y());
      const bool inside = std::abs(p.z()) < h / 2 && rho < rb + (rt - rb) * (p.z() + h / 2) / h;
      const double unsigned_distance = NearestDistance(Eigen::Vector3d(rho, p.z(), 0), profile);
      EXPECT_NEAR(EvaluateTree(cone, p), inside ? -unsigned_distance : unsigned_distance, spacing)
          << "rb " << rb << " rt " << rt << " at " << p.transpose();
    }
  }
}

// Winding number by summed angles (a second point-in-polygon algorithm).
bool InsideByWinding(const std::vector<Eigen::Vector2d>& poly, const Eigen::Vector2d& p) {
  double total = 0;
  for (size_t i = 0; i < poly.size(); ++i) {
    const Eigen::Vector2d a = poly[i] - p, b = poly[(i + 1) % poly.size()] - p;
    total += std::atan2(a.x() * b.y() - a.y() * b.x(), a.dot(b));
  }
  return std::abs(total) > M_PI;
}

TEST(ImplicitNodePrimitive, ExtrusionMatchesSampledProfileAndCaps) {
  // A non-convex L-shaped profile, clockwise.
  ExtrusionParams params;
  params.profile = {{0, 0}, {0, 0.06}, {0.02, 0.06}, {0.02, 0.02}, {0.05, 0.02}, {0.05, 0}};
  params.height = 0.03;
  const ImplicitNode extrusion(params);
  std::vector<Eigen::Vector3d> boundary;
  const int n = 5000;
  for (size_t e = 0; e < params.profile.size(); ++e) {
    const Eigen::Vector2d a = params.profile[e],
                          b = params.profile[(e + 1) % params.profile.size()];
    for (int i = 0; i < n; ++i) {
      const Eigen::Vector2d q = a + (b - a) * (double(i) / n);
      boundary.emplace_back(q.x(), q.y(), 0);
    }
  }
  const double spacing = 0.06 / n;
  std::mt19937 rng(9);
  std::uniform_real_distribution<double> u(-0.03, 0.09);
  std::uniform_real_distribution<double> uz(-0.06, 0.06);
  for (int i = 0; i < 300; ++i) {
    const Eigen::Vector3d p(u(rng), u(rng), uz(rng));
    const bool inside_2d = InsideByWinding(params.profile, p.head<2>());
    const double d2 =
        (inside_2d ? -1 : 1) * NearestDistance(Eigen::Vector3d(p.x(), p.y(), 0), boundary);
    const double dz = std::abs(p.z()) - params.height / 2;
    double expected;
    if (d2 < 0 && dz < 0) {
      expected = std::max(d2, dz);  // inside: nearest of side wall and cap
    } else {
      expected = std::hypot(std::max(d2, 0.0), std::max(dz, 0.0));
    }
    EXPECT_NEAR(EvaluateTree(extrusion, p), expected, 2 * spacing) << p.transpose();
  }
}

TEST(ImplicitNodeTree, TransformsMoveThePrimitive) {
  // translate(rotate(scale(box))) evaluated at points given in the box's frame.
  ImplicitNode box(BoxParams{Eigen::Vector3d(0.1, 0.04, 0.02)});
  ImplicitNode scaled(ScaleParams{Eigen::Vector3d::Constant(2.0)}, {box});
  RotateParams rotate;
  rotate.axis = Eigen::Vector3d(0, 0, 1);
  rotate.angle = M_PI / 2;
  ImplicitNode rotated(rotate, {scaled});
  ImplicitNode moved(TranslateParams{Eigen::Vector3d(1, 2, 3)}, {rotated});
  std::mt19937 rng(10);
  for (int i = 0; i < 100; ++i) {
    const Eigen::Vector3d q =
        RandomPoint(rng, 0.3);  // in the scaled box frame (size 0.2, 0.08, 0.04)
    const Eigen::Vector3d p = Eigen::Vector3d(1, 2, 3) + Eigen::Vector3d(-q.y(), q.x(), q.z());
    EXPECT_NEAR(EvaluateTree(moved, p), BoxDistance(q, Eigen::Vector3d(0.1, 0.04, 0.02)), 1e-14);
  }
}

TEST(ImplicitNodeTree, CountsNodes) {
  ImplicitNode tree(UnionParams{},
                    {ImplicitNode(SphereParams{0.1}),
                     ImplicitNode(TranslateParams{}, {ImplicitNode(SphereParams{0.1})})});
  EXPECT_EQ(CountNodes(tree), 4);
  EXPECT_STREQ(NodeTypeName(tree.params), "union");
  EXPECT_TRUE(IsPrimitive(tree.children[0].params));
  EXPECT_FALSE(IsPrimitive(tree.params));
}

// Runs ValidateTree and returns the ModelError it throws (fails the test when none).
ModelError ValidationError(const ImplicitNode& root, const std::string& root_path = "") {
  try {
    ValidateTree(root, root_path);
  } catch (const ModelError& e) {
    return e;
  }
  ADD_FAILURE() << "no ModelError";
  return ModelError("", "", "");
}

TEST(ImplicitNodeValidation, NegativeRadiusNamesNodeAndField) {
  ImplicitNode bad(SphereParams{-0.1}, {}, "ball");
  bad.name = "Ball joint";
  ImplicitNode root(UnionParams{},
                    {ImplicitNode(BoxParams{}), ImplicitNode(TranslateParams{}, {bad})}, "root");
  const ModelError e = ValidationError(root, "/solids/0/root");
  EXPECT_EQ(e.path(), "/solids/0/root/children/1/children/0");
  EXPECT_EQ(e.field(), "radius");
  EXPECT_THAT(e.what(), HasSubstr("'ball'"));
  EXPECT_THAT(e.what(), HasSubstr("Ball joint"));
  EXPECT_THAT(e.what(), HasSubstr("sphere"));
  EXPECT_THAT(e.what(), HasSubstr("/solids/0/root/children/1/children/0"));
  EXPECT_THAT(e.what(), HasSubstr("'radius'"));
  EXPECT_THAT(e.what(), HasSubstr("-0.1"));
}

TEST(ImplicitNodeValidation, RejectsEachBadField) {
  struct Case {
    NodeParams params;
    std::vector<ImplicitNode> children;
    std::string field;
  };
  const ImplicitNode leaf(SphereParams{0.1});
  ExtrusionParams bow_tie;  // self-intersecting
  bow_tie.profile = {{0, 0}, {1, 1}, {1, 0}, {0, 1}};
  ExtrusionParams two_points;
  two_points.profile = {{0, 0}, {1, 1}};
  ExtrusionParams flat_height;
  flat_height.profile = {{0, 0}, {1, 0}, {0, 1}};
  flat_height.height = 0;
  ConeParams both_zero{0, 0, 0.1};
  MirrorParams zero_normal;
  zero_normal.normal = Eigen::Vector3d::Zero();
  LinearArrayParams no_copies;
  no_copies.count = 0;
  PolarArrayParams nan_angle;
  nan_angle.step_angle = NAN;
  const std::vector<Case> cases = {
      {BoxParams{Eigen::Vector3d(0.1, -0.1, 0.1)}, {}, "size"},
      {RoundedBoxParams{Eigen::Vector3d(0.1, 0.1, 0.04), 0.03}, {}, "radius"},
      {CylinderParams{0.1, 0.0}, {}, "height"},
      {CapsuleParams{Eigen::Vector3d(NAN, 0, 0), Eigen::Vector3d::Zero(), 0.1}, {}, "a"},
      {both_zero, {}, "radius_bottom"},
      {ConeParams{0.1, -0.01, 0.1}, {}, "radius_top"},
      {TorusParams{0.05, 0.06}, {}, "minor_radius"},
      {HalfSpaceParams{Eigen::Vector3d::Zero(), 0.0}, {}, "normal"},
      {bow_tie, {}, "profile"},
      {two_points, {}, "profile"},
      {flat_height, {}, "height"},
      {SmoothUnionParams{-0.01}, {leaf, leaf}, "radius"},
      {OffsetParams{INFINITY}, {leaf}, "distance"},
      {ShellParams{0.0}, {leaf}, "thickness"},
      {ScaleParams{Eigen::Vector3d(1, 0, 1)}, {leaf}, "factors"},
      {RotateParams{Eigen::Vector3d::Zero(), 1.0}, {leaf}, "axis"},
      {zero_normal, {leaf}, "normal"},
      {no_copies, {leaf}, "count"},
      {nan_angle, {leaf}, "step_angle"},
      {SphereParams{0.1}, {leaf}, "children"},
      {UnionParams{}, {}, "children"},
      {DifferenceParams{}, {leaf}, "children"},
  };
  for (const Case& c : cases) {
    const ImplicitNode node(c.params, c.children, "n1");
    const ModelError e = ValidationError(node);
    EXPECT_EQ(e.field(), c.field) << NodeTypeName(c.params) << ": " << e.what();
    EXPECT_THAT(e.what(), HasSubstr("'n1'")) << e.what();
    EXPECT_THAT(e.what(), HasSubstr(NodeTypeName(c.params)));
  }
}

TEST(ImplicitNodeValidation, RejectsRepeatedId) {
  const ImplicitNode root(UnionParams{}, {ImplicitNode(SphereParams{0.1}, {}, "x"),
                                          ImplicitNode(BoxParams{}, {}, "x")});
  const ModelError e = ValidationError(root);
  EXPECT_EQ(e.field(), "id");
  EXPECT_EQ(e.path(), "/children/1");
}

// A chain of `levels` nodes: levels - 1 translate nodes, each the only child of the one above,
// around a sphere (built bottom-up, without recursion).
ImplicitNode TranslateChain(int levels) {
  ImplicitNode node(SphereParams{0.01});
  for (int i = 1; i < levels; ++i) {
    std::vector<ImplicitNode> children;
    children.push_back(std::move(node));
    node = ImplicitNode(TranslateParams{Eigen::Vector3d(1e-4, 0, 0)}, std::move(children));
  }
  return node;
}

std::string RepeatedChildPath(int times) {
  std::string path;
  for (int i = 0; i < times; ++i) path += "/children/0";
  return path;
}

TEST(ImplicitNodeValidation, TenThousandNestedTranslatesAreRefusedAtLevel257) {
  const ImplicitNode chain = TranslateChain(10000);
  EXPECT_EQ(CountNodes(chain), 10000);
  const ModelError e = ValidationError(chain, "/solids/0/root");
  // The first node past the limit: level kMaxTreeDepth + 1, i.e. 256 steps below the root.
  EXPECT_EQ(e.path(), "/solids/0/root" + RepeatedChildPath(kMaxTreeDepth));
  EXPECT_EQ(e.field(), "children");
  EXPECT_THAT(e.what(), HasSubstr("deeper than 256 levels"));
  EXPECT_THAT(e.what(), HasSubstr("flatten"));
}

TEST(ImplicitNodeValidation, TreeOfExactlyTheDepthLimitIsAccepted) {
  const ImplicitNode chain = TranslateChain(kMaxTreeDepth);
  EXPECT_NO_THROW(ValidateTree(chain));
  // The reference evaluator walks it: the sphere moved by 255 × 0.1 mm along x.
  const double shift = (kMaxTreeDepth - 1) * 1e-4;
  EXPECT_NEAR(EvaluateTree(chain, Eigen::Vector3d(shift, 0, 0)), -0.01, 1e-12);
  EXPECT_THROW(ValidateTree(TranslateChain(kMaxTreeDepth + 1)), ModelError);
}

TEST(ImplicitNodeValidation, TreeOverTheNodeLimitIsRefusedNamingTheFirstNodePastIt) {
  std::vector<ImplicitNode> spheres(kMaxTreeNodes, ImplicitNode(SphereParams{0.01}));
  const ImplicitNode too_many(UnionParams{}, std::move(spheres));  // kMaxTreeNodes + 1 nodes
  const ModelError e = ValidationError(too_many, "/solids/2/root");
  // The root is node 1, child i is node i + 2: node kMaxTreeNodes + 1 is child kMaxTreeNodes - 1.
  EXPECT_EQ(e.path(), "/solids/2/root/children/" + std::to_string(kMaxTreeNodes - 1));
  EXPECT_THAT(e.what(), HasSubstr("more than 500000 nodes"));
}

TEST(ImplicitNodeValidation, AcceptsValidTree) {
  ExtrusionParams triangle;
  triangle.profile = {{0, 0}, {0.1, 0}, {0, 0.1}};
  const ImplicitNode root(DifferenceParams{},
                          {ImplicitNode(triangle), ImplicitNode(SphereParams{0.01})});
  EXPECT_NO_THROW(ValidateTree(root));
}

}  // namespace
}  // namespace spidarcad::modeling
