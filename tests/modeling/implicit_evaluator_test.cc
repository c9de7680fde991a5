// Tests of the compiled evaluator (tape) against independent computations: the tree-walking
// reference evaluator, central finite differences, sampled values inside interval bounds,
// Lipschitz and exact-distance properties, and an allocation counter.
// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#include "spidarcad/modeling/implicit_evaluator.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <atomic>
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <limits>
#include <new>
#include <random>
#include <string>
#include <vector>

// Counts every operator new in this test executable (the evaluator must not allocate).
// GCC cannot see that the replaced new and delete below pair malloc with free.
#pragma GCC diagnostic ignored "-Wmismatched-new-delete"
namespace {
std::atomic<long> g_allocations{0};
}  // namespace
void* operator new(std::size_t n) {
  g_allocations.fetch_add(1, std::memory_order_relaxed);
  if (void* p = std::malloc(n ? n : 1)) return p;
  throw std::bad_alloc();
}
// Every unaligned form is replaced: under AddressSanitizer a form left out is the sanitizer's
// own, and its blocks freed by the delete below are reported as alloc-dealloc mismatches.
void* operator new[](std::size_t n) { return operator new(n); }
void* operator new(std::size_t n, const std::nothrow_t&) noexcept {
  try {
    return operator new(n);
  } catch (const std::bad_alloc&) {
    return nullptr;
  }
}
void* operator new[](std::size_t n, const std::nothrow_t& tag) noexcept {
  return operator new(n, tag);
}
void operator delete(void* p) noexcept { std::free(p); }
void operator delete(void* p, std::size_t) noexcept { std::free(p); }
void operator delete[](void* p) noexcept { std::free(p); }
void operator delete[](void* p, std::size_t) noexcept { std::free(p); }
void operator delete(void* p, const std::nothrow_t&) noexcept { std::free(p); }
void operator delete[](void* p, const std::nothrow_t&) noexcept { std::free(p); }

namespace spidarcad::modeling {
namespace {

constexpr int kNumNodeTypes = static_cast<int>(std::variant_size_v<NodeParams>);

double Uniform(std::mt19937& rng, double lo, double hi) {
  return std::uniform_real_distribution<double>(lo, hi)(rng);
}

Eigen::Vector3d RandomVector(std::mt19937& rng, double half) {
  return {Uniform(rng, -half, half), Uniform(rng, -half, half), Uniform(rng, -half, half)};
}

Eigen::Vector3d RandomDirection(std::mt19937& rng) {
  Eigen::Vector3d v;
  do {
    v = RandomVector(rng, 1.0);
  } while (v.norm() < 0.1 || v.norm() > 1.0);
  return v.normalized();
}

// A node of the given type (variant index) with random valid parameters; children as given.
NodeParams RandomParams(int type, std::mt19937& rng) {
  auto len = [&](double lo = 0.02, double hi = 0.08) { return Uniform(rng, lo, hi); };
  switch (type) {
    case 0:
      return SphereParams{len()};
    case 1:
      return BoxParams{Eigen::Vector3d(len(), len(), len())};
    case 2: {
      const Eigen::Vector3d size(len(), len(), len());
      return RoundedBoxParams{size, Uniform(rng, 0.0, 0.5 * size.minCoeff())};
    }
    case 3:
      return CylinderParams{len(0.01, 0.05), len()};
    case 4:
      return CapsuleParams{RandomVector(rng, 0.04), RandomVector(rng, 0.04), len(0.01, 0.03)};
    case 5:
      return ConeParams{len(0.0, 0.05), len(0.01, 0.05), len()};
    case 6: {
      const double big = len(0.03, 0.06);
      return TorusParams{big, Uniform(rng, 0.005, big)};
    }
    case 7:
      return HalfSpaceParams{RandomDirection(rng), Uniform(rng, -0.03, 0.03)};
    case 8: {
      // A random star-shaped (hence simple) polygon around the origin.
      ExtrusionParams p;
      const int n = 3 + static_cast<int>(rng() % 6);
      for (int i = 0; i < n; ++i) {
        const double a = 2 * M_PI * (i + Uniform(rng, 0.0, 0.8)) / n;
        const double r = len(0.02, 0.06);
        p.profile.emplace_back(r * std::cos(a), r * std::sin(a));
      }
      p.height = len();
      return p;
    }
    case 9:
      return UnionParams{};
    case 10:
      return IntersectionParams{};
    case 11:
      return DifferenceParams{};
    case 12:
      return SmoothUnionParams{len(0.0, 0.03)};
    case 13:
      return SmoothIntersectionParams{len(0.0, 0.03)};
    case 14:
      return SmoothDifferenceParams{len(0.0, 0.03)};
    case 15:
      return OffsetParams{Uniform(rng, -0.01, 0.02)};
    case 16:
      return ShellParams{len(0.002, 0.01)};
    case 17:
      return TranslateParams{RandomVector(rng, 0.05)};
    case 18:
      return RotateParams{RandomDirection(rng), Uniform(rng, -M_PI, M_PI)};
    case 19: {
      if (rng() % 2) return ScaleParams{Eigen::Vector3d::Constant(Uniform(rng, 0.5, 2.0))};
      return ScaleParams{
          Eigen::Vector3d(Uniform(rng, 0.5, 2.0), Uniform(rng, 0.5, 2.0), Uniform(rng, 0.5, 2.0))};
    }
    case 20: {
      MirrorParams p;
      p.normal = RandomDirection(rng);
      p.offset = Uniform(rng, -0.02, 0.02);
      p.keep_original = rng() % 2;
      return p;
    }
    case 21: {
      LinearArrayParams p;
      p.step = RandomVector(rng, 0.05);
      p.count = 1 + static_cast<int>(rng() % 3);
      return p;
    }
    default: {
      PolarArrayParams p;
      p.axis = RandomDirection(rng);
      p.count = 1 + static_cast<int>(rng() % 4);
      p.step_angle = 2 * M_PI / p.count;
      p.axis = RandomDirection(rng);
      return p;
    }
  }
}

// A primitive placed at a random offset, so that siblings overlap partly.
ImplicitNode RandomLeaf(std::mt19937& rng) {
  // Half-spaces are rare: they make every tree unbounded.
  int type = static_cast<int>(rng() % 9);
  if (type == 7 && rng() % 3) type = 0;
  return ImplicitNode(TranslateParams{RandomVector(rng, 0.03)},
                      {ImplicitNode(RandomParams(type, rng))});
}

// A node of `type` whose children are random leaves.
ImplicitNode ExampleOf(int type, std::mt19937& rng) {
  ImplicitNode node(RandomParams(type, rng));
  if (IsPrimitive(node.params)) return node;
  const int children = 2 + static_cast<int>(rng() % 2);
  for (int i = 0; i < children; ++i) node.children.push_back(RandomLeaf(rng));
  return node;
}

ImplicitNode RandomTree(std::mt19937& rng, int depth) {
  if (depth == 0 || rng() % 4 == 0) return RandomLeaf(rng);
  ImplicitNode node(RandomParams(9 + static_cast<int>(rng() % (kNumNodeTypes - 9)), rng));
  const int children = 1 + static_cast<int>(rng() % 3) +
                       (std::holds_alternative<DifferenceParams>(node.params) ||
                        std::holds_alternative<SmoothDifferenceParams>(node.params));
  for (int i = 0; i < children; ++i) node.children.push_back(RandomTree(rng, depth - 1));
  return node;
}

TEST(CompiledSolid, MatchesTreeWalkOnRandomTrees) {
  std::mt19937 rng(11);
  for (int t = 0; t < 200; ++t) {
    const ImplicitNode tree = RandomTree(rng, 4);
    const CompiledSolid solid = CompiledSolid::Compile(tree);
    for (int i = 0; i < 50; ++i) {
      const Eigen::Vector3d p = RandomVector(rng, 0.12);
      Eigen::Vector3d g;
      const double expected = EvaluateTree(tree, p);
      ASSERT_NEAR(solid.Value(p), expected, 1e-12 * (1 + std::abs(expected))) << "tree " << t;
      ASSERT_NEAR(solid.ValueAndGradient(p, &g), expected, 1e-12 * (1 + std::abs(expected)))
          << "tree " << t;
    }
  }
}

TEST(CompiledSolid, MatchesTreeWalkForEveryNodeType) {
  std::mt19937 rng(12);
  for (int type = 0; type < kNumNodeTypes; ++type) {
    for (int t = 0; t < 10; ++t) {
      const ImplicitNode tree = ExampleOf(type, rng);
      const CompiledSolid solid = CompiledSolid::Compile(tree);
      for (int i = 0; i < 50; ++i) {
        const Eigen::Vector3d p = RandomVector(rng, 0.1);
        const double expected = EvaluateTree(tree, p);
        ASSERT_NEAR(solid.Value(p), expected, 1e-12 * (1 + std::abs(expected)))
            << NodeTypeName(tree.params);
      }
    }
  }
}

// Gradient of the compiled solid vs central differences of the reference evaluator. Points at
// a kink (where the one-sided differences disagree) are skipped and counted.
TEST(CompiledSolid, GradientMatchesFiniteDifferencesForEveryNodeType) {
  std::mt19937 rng(13);
  const double h = 1e-6;
  for (int type = 0; type < kNumNodeTypes; ++type) {
    int checked = 0, skipped = 0;
    for (int t = 0; t < 10; ++t) {
      const ImplicitNode tree = ExampleOf(type, rng);
      const CompiledSolid solid = CompiledSolid::Compile(tree);
      for (int i = 0; i < 40; ++i) {
        const Eigen::Vector3d p = RandomVector(rng, 0.1);
        Eigen::Vector3d gradient;
        solid.ValueAndGradient(p, &gradient);
        Eigen::Vector3d central, forward, backward;
        const double f0 = EvaluateTree(tree, p);
        for (int k = 0; k < 3; ++k) {
          const Eigen::Vector3d e = Eigen::Vector3d::Unit(k) * h;
          const double fp = EvaluateTree(tree, p + e), fm = EvaluateTree(tree, p - e);
          central[k] = (fp - fm) / (2 * h);
          forward[k] = (fp - f0) / h;
          backward[k] = (f0 - fm) / h;
        }
        if ((forward - backward).norm() > 1e-3) {
          ++skipped;
          continue;
        }
        ++checked;
        ASSERT_LT((gradient - central).norm(), 1e-5)
            << NodeTypeName(tree.params) << " at " << p.transpose() << ": " << gradient.transpose()
            << " vs " << central.transpose();
      }
    }
    EXPECT_LT(skipped, checked / 10) << NodeTypeName(RandomParams(type, rng)) << ": too many kinks";
  }
}

// On an extrusion's side walls the gradient is the wall's outward normal, also at points that
// lie on the wall to rounding: those on the profile's edges and those Newton's steps put there
// from either side (as the surface sharpening projects its samples). The distance to the profile
// was the length of the offset to the nearest point of an edge, signed by a crossing test: on
// the wall both lose their direction, and the gradient came out zero or pointing inwards (on the
// platform's gusset, 2026-12-06, nine tenths of such points). Checked on the gusset's profile
// and on an L-shaped one (both clockwise) and on the two reversed (counter-clockwise), 200
// points per edge and side.
TEST(CompiledSolid, ExtrusionGradientOnItsWallsIsTheOutwardNormal) {
  std::vector<std::vector<Eigen::Vector2d>> profiles = {
      {{0.005, 0.002}, {0.2, 0.002}, {0.005, -0.14}},
      {{0, 0}, {0, 0.06}, {0.02, 0.06}, {0.02, 0.02}, {0.05, 0.02}, {0.05, 0}}};
  for (int k = 0; k < 2; ++k) profiles.emplace_back(profiles[k].rbegin(), profiles[k].rend());
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> u(0.02, 0.98), uz(-0.004, 0.004);
  for (const auto& profile : profiles) {
    ExtrusionParams params;
    params.profile = profile;
    params.height = 0.01;
    const CompiledSolid solid = CompiledSolid::Compile(ImplicitNode(params));
    double area2 = 0.0;  // twice the signed area: > 0 counter-clockwise
    for (size_t e = 0; e < profile.size(); ++e) {
      const Eigen::Vector2d a = profile[e], b = profile[(e + 1) % profile.size()];
      area2 += a.x() * b.y() - b.x() * a.y();
    }
    int bad = 0, total = 0;
    std::string first;
    for (size_t e = 0; e < profile.size(); ++e) {
      const Eigen::Vector2d a = profile[e], b = profile[(e + 1) % profile.size()];
      const Eigen::Vector2d t = (b - a).normalized();
      const Eigen::Vector2d out2 =
          area2 > 0 ? Eigen::Vector2d(t.y(), -t.x()) : Eigen::Vector2d(-t.y(), t.x());
      const Eigen::Vector3d out(out2.x(), out2.y(), 0.0);
      for (int i = 0; i < 200; ++i) {
        const Eigen::Vector2d q = a + (b - a) * u(rng);
        Eigen::Vector3d p(q.x(), q.y(), uz(rng));
        if (i % 2 == 1) {
          // From 0.1 mm off the wall (outside or inside), Newton's steps onto it.
          p += out * (i % 4 == 1 ? 1e-4 : -1e-4);
          for (int k = 0; k < 4; ++k) {
            Eigen::Vector3d g;
            const double f = solid.ValueAndGradient(p, &g);
            if (!(g.squaredNorm() > 0.0)) break;
            p -= g * (f / g.squaredNorm());
          }
        }
        Eigen::Vector3d g;
        solid.ValueAndGradient(p, &g);
        ++total;
        if (!(g.dot(out) > 0.999 * g.norm() && g.norm() > 0.5)) {
          if (bad++ == 0)
            first = "edge " + std::to_string(e) + " at " + std::to_string(p.x()) + " " +
                    std::to_string(p.y()) + ": gradient " + std::to_string(g.x()) + " " +
                    std::to_string(g.y()) + " " + std::to_string(g.z());
        }
      }
    }
    EXPECT_EQ(bad, 0) << bad << " of " << total << " points; first: " << first;
  }
}

// The same on a cone frustum's caps and side (its distance is taken in the (ρ, z) half-plane the
// same way): points on the caps to rounding had a zero gradient.
TEST(CompiledSolid, ConeGradientOnItsSurfaceIsTheOutwardNormal) {
  const double rb = 0.03, rt = 0.01, hh = 0.04;
  ConeParams params;
  params.radius_bottom = rb;
  params.radius_top = rt;
  params.height = 2 * hh;
  const CompiledSolid solid = CompiledSolid::Compile(ImplicitNode(params));
  std::mt19937 rng(6);
  std::uniform_real_distribution<double> u(0.02, 0.98), phi(0.0, 2 * M_PI);
  const double slope = (rb - rt) / (2 * hh);
  const Eigen::Vector2d side_normal = Eigen::Vector2d(1.0, slope).normalized();  // (ρ, z)
  int bad = 0, total = 0;
  std::string first;
  for (int face = 0; face < 3; ++face) {
    for (int i = 0; i < 200; ++i) {
      const double a = phi(rng), t = u(rng);
      const Eigen::Vector3d radial(std::cos(a), std::sin(a), 0.0);
      Eigen::Vector3d p, out;
      if (face == 0) {  // bottom cap
        p = radial * (t * rb) + Eigen::Vector3d(0, 0, -hh);
        out = Eigen::Vector3d(0, 0, -1);
      } else if (face == 1) {  // top cap
        p = radial * (t * rt) + Eigen::Vector3d(0, 0, hh);
        out = Eigen::Vector3d(0, 0, 1);
      } else {  // side
        const double z = -hh + 2 * hh * t;
        p = radial * (rb + (rt - rb) * t) + Eigen::Vector3d(0, 0, z);
        out = radial * side_normal.x() + Eigen::Vector3d(0, 0, side_normal.y());
      }
      Eigen::Vector3d g;
      solid.ValueAndGradient(p, &g);
      ++total;
      if (!(g.dot(out) > 0.999 * g.norm() && g.norm() > 0.5) && bad++ == 0)
        first = "face " + std::to_string(face) + ": gradient " + std::to_string(g.x()) + " " +
                std::to_string(g.y()) + " " + std::to_string(g.z());
    }
  }
  EXPECT_EQ(bad, 0) << bad << " of " << total << " points; first: " << first;
}

// Every value sampled in a box lies in Bounds(box); Classify agrees with the samples.
TEST(CompiledSolid, IntervalBoundsContainSampledValues) {
  std::mt19937 rng(14);
  int inside = 0, outside = 0;
  for (int t = 0; t < 150; ++t) {
    const ImplicitNode tree = (t < kNumNodeTypes) ? ExampleOf(t, rng) : RandomTree(rng, 4);
    const CompiledSolid solid = CompiledSolid::Compile(tree);
    for (int b = 0; b < 20; ++b) {
      const Eigen::Vector3d centre = RandomVector(rng, 0.12);
      const Eigen::Vector3d half(std::exp(Uniform(rng, std::log(1e-4), std::log(0.1))),
                                 std::exp(Uniform(rng, std::log(1e-4), std::log(0.1))),
                                 std::exp(Uniform(rng, std::log(1e-4), std::log(0.1))));
      const Eigen::AlignedBox3d box(centre - half, centre + half);
      const Interval bounds = solid.Bounds(box);
      const BoxClass cls = solid.Classify(box);
      inside += cls == BoxClass::kInside;
      outside += cls == BoxClass::kOutside;
      ASSERT_LE(bounds.lo, bounds.hi);
      for (int s = 0; s < 40; ++s) {
        Eigen::Vector3d p;
        if (s < 8) {
          p = box.corner(static_cast<Eigen::AlignedBox3d::CornerType>(s));
        } else {
          for (int k = 0; k < 3; ++k) p[k] = Uniform(rng, box.min()[k], box.max()[k]);
        }
        const double v = EvaluateTree(tree, p);
        ASSERT_TRUE(bounds.Contains(v)) << "tree " << t << " value " << v << " outside ["
                                        << bounds.lo << ", " << bounds.hi << "]";
        if (cls == BoxClass::kInside) {
          ASSERT_LT(v, 0.0);
        }
        if (cls == BoxClass::kOutside) {
          ASSERT_GT(v, 0.0);
        }
      }
    }
  }
  // The bounds are useful, not merely valid: many boxes are decided.
  EXPECT_GT(inside, 50);
  EXPECT_GT(outside, 500);
}

TEST(CompiledSolid, ClassifiesBoxesAroundASphere) {
  const CompiledSolid solid = CompiledSolid::Compile(ImplicitNode(SphereParams{0.1}));
  const Eigen::Vector3d small = Eigen::Vector3d::Constant(0.01);
  EXPECT_EQ(solid.Classify(Eigen::AlignedBox3d(-small, small)), BoxClass::kInside);
  const Eigen::Vector3d far(0.2, 0.0, 0.0);
  EXPECT_EQ(solid.Classify(Eigen::AlignedBox3d(far - small, far + small)), BoxClass::kOutside);
  const Eigen::Vector3d on(0.1, 0.0, 0.0);
  EXPECT_EQ(solid.Classify(Eigen::AlignedBox3d(on - small, on + small)), BoxClass::kAmbiguous);
  // Interval arithmetic alone is tight for a sphere: the bound over a box touching the sphere.
  const Interval b = solid.Bounds(
      Eigen::AlignedBox3d(Eigen::Vector3d(0.15, -0.01, -0.01), Eigen::Vector3d(0.17, 0.01, 0.01)));
  EXPECT_NEAR(b.lo, 0.05, 1e-12);
  EXPECT_NEAR(b.hi, std::sqrt(0.17 * 0.17 + 2e-4) - 0.1, 1e-12);
}

// Every node keeps a Lipschitz-1 bound: |f(p) - f(q)| <= |p - q| and |∇f| <= 1.
TEST(CompiledSolid, RandomTreesAreLipschitzOne) {
  std::mt19937 rng(15);
  for (int t = 0; t < 200; ++t) {
    const ImplicitNode tree = RandomTree(rng, 4);
    const CompiledSolid solid = CompiledSolid::Compile(tree);
    for (int i = 0; i < 50; ++i) {
      const Eigen::Vector3d p = RandomVector(rng, 0.12), q = RandomVector(rng, 0.12);
      ASSERT_LE(std::abs(solid.Value(p) - solid.Value(q)), (p - q).norm() * (1 + 1e-9) + 1e-15)
          << "tree " << t;
      Eigen::Vector3d g;
      solid.ValueAndGradient(p, &g);
      ASSERT_LE(g.norm(), 1 + 1e-9) << "tree " << t;
    }
  }
}

// Primitives under rigid motions, mirrors and uniform scales stay exact distances: the gradient
// has unit length and the closest-point projection p - f ∇f lands on the surface.
TEST(CompiledSolid, RigidTransformsOfPrimitivesAreExactDistances) {
  std::mt19937 rng(16);
  for (int type = 0; type < 9; ++type) {
    for (int t = 0; t < 10; ++t) {
      ImplicitNode node(RandomParams(type, rng));
      MirrorParams mirror;
      mirror.normal = RandomDirection(rng);
      mirror.offset = 0.01;
      node = ImplicitNode(mirror, {node});
      node = ImplicitNode(RotateParams{RandomDirection(rng), Uniform(rng, -3, 3)}, {node});
      node = ImplicitNode(ScaleParams{Eigen::Vector3d::Constant(Uniform(rng, 0.5, 2))}, {node});
      node = ImplicitNode(TranslateParams{RandomVector(rng, 0.02)}, {node});
      const CompiledSolid solid = CompiledSolid::Compile(node);
      int checked = 0;
      for (int i = 0; i < 100 && checked < 20; ++i) {
        const Eigen::Vector3d p = RandomVector(rng, 0.15);
        Eigen::Vector3d g;
        const double f = solid.ValueAndGradient(p, &g);
        if (g.norm() == 0) continue;  // a point on the medial axis
        ++checked;
        EXPECT_NEAR(g.norm(), 1.0, 1e-9) << NodeTypeName(RandomParams(type, rng));
        EXPECT_NEAR(solid.Value(p - f * g), 0.0, 1e-9)
            << NodeTypeName(RandomParams(type, rng)) << " f " << f;
      }
      EXPECT_GT(checked, 10);
    }
  }
}

TEST(CompiledSolid, NonUniformScaleUsesSmallestFactor) {
  ImplicitNode node(ScaleParams{Eigen::Vector3d(2, 1, 0.5)}, {ImplicitNode(SphereParams{0.1})});
  const CompiledSolid solid = CompiledSolid::Compile(node);
  // Ellipsoid with semi-axes 0.2, 0.1, 0.05: at (0.3, 0, 0) the true distance is 0.1; the bound
  // is 0.5 * (0.15 - 0.1) = 0.025 <= 0.1.
  EXPECT_NEAR(solid.Value(Eigen::Vector3d(0.3, 0, 0)), 0.025, 1e-15);
  EXPECT_NEAR(solid.Value(Eigen::Vector3d(0, 0, 0.05)), 0.0, 1e-15);
}

TEST(CompiledSolid, UnrollsArrays) {
  LinearArrayParams line;
  line.step = Eigen::Vector3d(0.1, 0, 0);
  line.count = 5;
  PolarArrayParams ring;
  ring.count = 6;
  ring.step_angle = M_PI / 3;
  const ImplicitNode tree(ring, {ImplicitNode(line, {ImplicitNode(SphereParams{0.01})})});
  const CompiledSolid solid = CompiledSolid::Compile(tree);
  EXPECT_EQ(solid.primitive_count(), 30);
  // The copy i = 3 of the line, rotated by 2 steps (120°).
  const Eigen::Vector3d p(0.3 * std::cos(2 * M_PI / 3), 0.3 * std::sin(2 * M_PI / 3), 0);
  EXPECT_NEAR(solid.Value(p), -0.01, 1e-12);
}

TEST(CompiledSolid, RejectsTreeDeeperThanTheStack) {
  ImplicitNode chain(SphereParams{0.1});
  for (int i = 0; i < CompiledSolid::kMaxStackDepth + 5; ++i) {
    chain = ImplicitNode(UnionParams{}, {ImplicitNode(SphereParams{0.1}), chain});
  }
  EXPECT_THROW(CompiledSolid::Compile(chain), ModelError);
}

TEST(CompiledSolid, CompileValidates) {
  try {
    CompiledSolid::Compile(ImplicitNode(UnionParams{}, {ImplicitNode(SphereParams{-1}, {}, "bad")}),
                           "/solids/3/root");
    FAIL() << "no ModelError";
  } catch (const ModelError& e) {
    EXPECT_EQ(e.path(), "/solids/3/root/children/0");
    EXPECT_EQ(e.field(), "radius");
  }
}

TEST(CompiledSolid, EmptySolidIsOutsideEverywhere) {
  const CompiledSolid empty;
  Eigen::Vector3d g(1, 2, 3);
  EXPECT_EQ(empty.Value(Eigen::Vector3d::Zero()), INFINITY);
  EXPECT_EQ(empty.ValueAndGradient(Eigen::Vector3d::Zero(), &g), INFINITY);
  EXPECT_EQ(g, Eigen::Vector3d::Zero());
  EXPECT_EQ(empty.Classify(Eigen::AlignedBox3d(Eigen::Vector3d::Zero(), Eigen::Vector3d::Ones())),
            BoxClass::kOutside);
}

TEST(CompiledSolid, BatchMatchesSinglePoints) {
  std::mt19937 rng(17);
  const ImplicitNode tree = RandomTree(rng, 4);
  const CompiledSolid solid = CompiledSolid::Compile(tree);
  Eigen::Matrix3Xd points(3, 100);
  for (int i = 0; i < 100; ++i) points.col(i) = RandomVector(rng, 0.1);
  Eigen::VectorXd values(100), values2(100);
  Eigen::Matrix3Xd gradients(3, 100);
  solid.Values(points, values);
  solid.ValuesAndGradients(points, values2, gradients);
  for (int i = 0; i < 100; ++i) {
    EXPECT_EQ(values[i], solid.Value(points.col(i)));
    EXPECT_NEAR(values[i], EvaluateTree(tree, points.col(i)), 1e-12);
    EXPECT_EQ(values2[i], values[i]);
    Eigen::Vector3d g;
    solid.ValueAndGradient(points.col(i), &g);
    EXPECT_EQ(gradients.col(i), g);
  }
}

std::uint64_t Bits(double v) {
  std::uint64_t b;
  std::memcpy(&b, &v, sizeof b);
  return b;
}

// Points that exercise the evaluator's selections: random ones, the origin and the axes
// (centres of primitives: Sqrt's kink, Abs at ±0), signed zeros, points on the planes
// between siblings (ties of Min/Max), and non-finite coordinates.
std::vector<Eigen::Vector3d> LanePoints(std::mt19937& rng, int random) {
  std::vector<Eigen::Vector3d> points;
  for (int i = 0; i < random; ++i) points.push_back(RandomVector(rng, 0.1));
  points.emplace_back(0.0, 0.0, 0.0);
  points.emplace_back(-0.0, 0.0, -0.0);
  points.emplace_back(0.0, 0.02, 0.0);
  points.emplace_back(0.03, 0.0, -0.0);
  points.emplace_back(0.0, 0.0, -0.05);
  for (int i = 0; i < 16; ++i) {
    Eigen::Vector3d p = RandomVector(rng, 0.06);
    p[i % 3] = (i % 2) ? 0.0 : -0.0;
    points.push_back(p);
  }
  const double nan = std::numeric_limits<double>::quiet_NaN();
  const double inf = std::numeric_limits<double>::infinity();
  points.emplace_back(nan, 0.0, 0.0);
  points.emplace_back(0.01, nan, nan);
  points.emplace_back(inf, 0.0, 0.0);
  points.emplace_back(-inf, inf, 0.0);
  points.emplace_back(1e300, -1e300, 1e-300);
  return points;
}

// Values and ValuesAndGradients (several points per pass of the tape) of `solid` against Value
// and ValueAndGradient point by point, bit for bit, over `points` in batches of every length from
// 1 to 9 and all at once. Returns the number of mismatching points (each also a test failure, at
// most three reported).
int CompareLanes(const CompiledSolid& solid, const std::vector<Eigen::Vector3d>& points,
                 const std::string& name) {
  const int n = static_cast<int>(points.size());
  Eigen::Matrix3Xd p(3, n), g(3, n);
  Eigen::VectorXd v(n), w(n);
  for (int i = 0; i < n; ++i) p.col(i) = points[i];
  int mismatches = 0;
  auto check = [&](int begin, int count) {
    solid.Values(p.middleCols(begin, count), v.segment(begin, count));
    solid.ValuesAndGradients(p.middleCols(begin, count), w.segment(begin, count),
                             g.middleCols(begin, count));
    for (int i = begin; i < begin + count; ++i) {
      Eigen::Vector3d single_g;
      const double value = solid.Value(points[i]);
      const double dual = solid.ValueAndGradient(points[i], &single_g);
      bool same = Bits(v[i]) == Bits(value) && Bits(w[i]) == Bits(dual);
      for (int k = 0; k < 3; ++k) same = same && Bits(g(k, i)) == Bits(single_g[k]);
      if (!same && ++mismatches <= 3) {
        ADD_FAILURE() << name << " at p = (" << points[i].transpose() << "): single " << value
                      << " / " << dual << " grad " << single_g.transpose() << ", batch " << v[i]
                      << " / " << w[i] << " grad " << g.col(i).transpose();
      }
    }
  };
  check(0, n);
  int begin = 0;
  for (int count = 1; begin + count <= n && count <= 9; ++count) {
    check(begin, count);
    begin += count;
  }
  return mismatches;
}

TEST(CompiledSolid, BatchIsBitIdenticalToSinglePointsForEveryNodeType) {
  std::mt19937 rng(41);
  long compared = 0;
  for (int type = 0; type < kNumNodeTypes; ++type) {
    for (int example = 0; example < 6; ++example) {
      const CompiledSolid solid = CompiledSolid::Compile(ExampleOf(type, rng));
      const std::vector<Eigen::Vector3d> points = LanePoints(rng, 300);
      EXPECT_EQ(CompareLanes(solid, points, "node type " + std::to_string(type)), 0);
      compared += static_cast<long>(points.size());
    }
  }
  EXPECT_GT(compared, kNumNodeTypes * 6 * 300);
}

TEST(CompiledSolid, BatchIsBitIdenticalOnRandomAndPrunedTrees) {
  std::mt19937 rng(42);
  for (int t = 0; t < 40; ++t) {
    const CompiledSolid solid = CompiledSolid::Compile(RandomTree(rng, 4));
    const std::vector<Eigen::Vector3d> points = LanePoints(rng, 400);
    EXPECT_EQ(CompareLanes(solid, points, "random tree " + std::to_string(t)), 0);
  }
  // Pruned tapes bring the negation that only Specialize emits: a box less a cylinder, inside
  // the hole's core, is −cylinder.
  const CompiledSolid holed = CompiledSolid::Compile(
      ImplicitNode(DifferenceParams{}, {ImplicitNode(BoxParams{Eigen::Vector3d(0.2, 0.2, 0.2)}),
                                        ImplicitNode(CylinderParams{0.02, 0.3})}));
  const CompiledSolid core = holed.Specialize(Eigen::AlignedBox3d(
      Eigen::Vector3d(-0.002, -0.002, -0.01), Eigen::Vector3d(0.002, 0.002, 0.01)));
  ASSERT_EQ(core.instruction_count(), 2);
  EXPECT_EQ(CompareLanes(core, LanePoints(rng, 200), "hole core"), 0);
  // The empty solid: +∞ and a zero gradient in every lane.
  EXPECT_EQ(CompareLanes(CompiledSolid(), LanePoints(rng, 10), "empty"), 0);
}

// One per instruction plus one per profile point of every extrusion; Specialize keeps it an
// upper bound (a pruned tape costs no more).
TEST(CompiledSolid, EvaluationCostCountsInstructionsAndProfilePoints) {
  ExtrusionParams e;
  e.profile = {{0, 0}, {0.1, 0}, {0.1, 0.1}, {0.05, 0.15}, {0, 0.1}};
  std::vector<ImplicitNode> children = {ImplicitNode(e), ImplicitNode(SphereParams{0.05})};
  children.emplace_back(TranslateParams{Eigen::Vector3d(1, 0, 0)},
                        std::vector<ImplicitNode>{ImplicitNode(SphereParams{0.05})});
  const CompiledSolid solid = CompiledSolid::Compile(ImplicitNode(UnionParams{}, children));
  ASSERT_EQ(solid.instruction_count(), 5);  // three primitives, two min
  EXPECT_EQ(solid.EvaluationCost(), 5.0 + 5.0);
  EXPECT_EQ(CompiledSolid::Compile(ImplicitNode(SphereParams{0.1})).EvaluationCost(), 1.0);
  // Near the far sphere only: the extrusion is pruned away, and its cost with it.
  const CompiledSolid far = solid.Specialize(
      Eigen::AlignedBox3d(Eigen::Vector3d(0.99, -0.01, -0.01), Eigen::Vector3d(1.01, 0.01, 0.01)));
  EXPECT_EQ(far.instruction_count(), 1);
  EXPECT_EQ(far.EvaluationCost(), 1.0);
}

TEST(CompiledSolid, EvaluationAllocatesNothing) {
  std::mt19937 rng(18);
  ImplicitNode tree = RandomTree(rng, 5);
  const CompiledSolid solid = CompiledSolid::Compile(tree);
  Eigen::Matrix3Xd points(3, 64);
  for (int i = 0; i < 64; ++i) points.col(i) = RandomVector(rng, 0.1);
  Eigen::VectorXd values(64);
  Eigen::Matrix3Xd gradients(3, 64);
  const long before = g_allocations.load();
  double sink = 0;
  for (int i = 0; i < 1000; ++i) {
    const Eigen::Vector3d p = points.col(i % 64);
    Eigen::Vector3d g;
    sink += solid.Value(p) + solid.ValueAndGradient(p, &g) + g.x();
    const Eigen::AlignedBox3d box(p, p + Eigen::Vector3d::Constant(0.01));
    sink += solid.Bounds(box).lo + static_cast<int>(solid.Classify(box));
  }
  solid.Values(points, values);
  solid.ValuesAndGradients(points, values, gradients);
  // Batches of a length that is not a multiple of the lanes, on sub-blocks (Eigen::Ref).
  solid.Values(points.leftCols(63), values.head(63));
  solid.ValuesAndGradients(points.middleCols(1, 62), values.head(62), gradients.leftCols(62));
  EXPECT_EQ(g_allocations.load() - before, 0);
  EXPECT_TRUE(std::isfinite(sink));
  // The counter itself works.
  const long mark = g_allocations.load();
  auto* probe = new std::vector<int>(10);
  delete probe;
  EXPECT_GT(g_allocations.load(), mark);
}

}  // namespace
}  // namespace spidarcad::modeling
