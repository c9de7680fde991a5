// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
// CompiledSolid::Specialize and CellSpecializedSolid: the pruned tapes must give bit-identical
// values and gradients to the full tape at every point of their box (checked on random points,
// box corners and faces, for every solid of the shipped scenes and for hand-built trees), must
// actually prune where the geometry says they can, and must keep both operands of ties.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <cstring>
#include <memory>
#include <random>
#include <stdexcept>
#include <string>
#include <vector>

#include "spidarcad/modeling/cell_specialized_solid.h"
#include "spidarcad/modeling/implicit_evaluator.h"
#include "spidarcad/modeling/scene_io.h"
#include "spidarcad/modeling/surface_mesher.h"
#include "support/malloc_counter.h"

namespace spidarcad::modeling {
namespace {

std::uint64_t Bits(double v) {
  std::uint64_t b;
  std::memcpy(&b, &v, sizeof b);
  return b;
}

// Bitwise comparison of Value and ValueAndGradient of two tapes at p; returns false (after
// recording failures) on any difference.
bool SameAt(const CompiledSolid& full, const CompiledSolid& pruned, const Eigen::Vector3d& p,
            const std::string& where) {
  Eigen::Vector3d g_full, g_pruned;
  const double v_full = full.ValueAndGradient(p, &g_full);
  const double v_pruned = pruned.ValueAndGradient(p, &g_pruned);
  const double w_full = full.Value(p), w_pruned = pruned.Value(p);
  bool ok = Bits(v_full) == Bits(v_pruned) && Bits(w_full) == Bits(w_pruned);
  for (int k = 0; k < 3; ++k) ok = ok && Bits(g_full[k]) == Bits(g_pruned[k]);
  if (!ok) {
    ADD_FAILURE() << where << " at p = (" << p.x() << ", " << p.y() << ", " << p.z() << "): full "
                  << v_full << " / " << w_full << " grad " << g_full.transpose() << ", pruned "
                  << v_pruned << " / " << w_pruned << " grad " << g_pruned.transpose();
  }
  return ok;
}

// Points of a box: its 8 corners, its 6 face centres, random points on its faces and edges,
// and random points inside.
std::vector<Eigen::Vector3d> BoxPoints(const Eigen::AlignedBox3d& box, std::mt19937& rng,
                                       int inside) {
  std::vector<Eigen::Vector3d> points;
  const Eigen::Vector3d lo = box.min(), hi = box.max();
  for (int corner = 0; corner < 8; ++corner)
    points.push_back(box.corner(static_cast<Eigen::AlignedBox3d::CornerType>(corner)));
  std::uniform_real_distribution<double> u(0.0, 1.0);
  auto random_in = [&]() {
    const double fx = u(rng), fy = u(rng), fz = u(rng);
    const Eigen::Vector3d p(lo.x() + fx * (hi.x() - lo.x()), lo.y() + fy * (hi.y() - lo.y()),
                            lo.z() + fz * (hi.z() - lo.z()));
    return Eigen::Vector3d(p.cwiseMax(lo).cwiseMin(hi));
  };
  for (int axis = 0; axis < 3; ++axis) {
    for (int side = 0; side < 2; ++side) {
      Eigen::Vector3d c = box.center();
      c[axis] = side ? hi[axis] : lo[axis];
      points.push_back(c);
      for (int i = 0; i < 8; ++i) {
        Eigen::Vector3d p = random_in();
        p[axis] = side ? hi[axis] : lo[axis];
        points.push_back(p);
        p[(axis + 1) % 3] = u(rng) < 0.5 ? lo[(axis + 1) % 3] : hi[(axis + 1) % 3];  // on an edge
        points.push_back(p);
      }
    }
  }
  for (int i = 0; i < inside; ++i) points.push_back(random_in());
  return points;
}

struct PruneCount {
  long boxes = 0;
  long pruned = 0;  // boxes whose tape got shorter
};

// Specializes `full` on random boxes of several sizes inside `region` and compares on each
// box's points.
PruneCount CheckRandomBoxes(const CompiledSolid& full, const Eigen::AlignedBox3d& region,
                            const std::string& name, unsigned seed, int boxes_per_size = 60,
                            int inside = 60) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  PruneCount count;
  const double extent = (region.max() - region.min()).maxCoeff();
  for (double fraction : {0.005, 0.02, 0.05, 0.15, 0.4}) {
    const double size = fraction * extent;
    for (int b = 0; b < boxes_per_size; ++b) {
      Eigen::Vector3d lo;
      for (int k = 0; k < 3; ++k)
        lo[k] = region.min()[k] + u(rng) * (region.max()[k] - region.min()[k]);
      Eigen::Vector3d sizes(size * (0.3 + u(rng)), size * (0.3 + u(rng)), size * (0.3 + u(rng)));
      const Eigen::AlignedBox3d box(lo, lo + sizes);
      const CompiledSolid pruned = full.Specialize(box);
      EXPECT_LE(pruned.instruction_count(), full.instruction_count()) << name;
      ++count.boxes;
      if (pruned.instruction_count() < full.instruction_count()) ++count.pruned;
      int failures = 0;
      for (const Eigen::Vector3d& p : BoxPoints(box, rng, inside)) {
        if (!SameAt(full, pruned, p, name) && ++failures > 3) return count;
      }
    }
  }
  return count;
}

Eigen::AlignedBox3d RegionOf(const CompiledSolid& solid) {
  const Eigen::Vector3d h = Eigen::Vector3d::Constant(0.5);
  Eigen::AlignedBox3d b = FindBounds(solid, Eigen::AlignedBox3d(-h, h), 0.01);
  if (b.isEmpty()) b = Eigen::AlignedBox3d(-h, h);
  const Eigen::Vector3d m = Eigen::Vector3d::Constant(0.02);
  return Eigen::AlignedBox3d(b.min() - m, b.max() + m);
}

ImplicitNode At(const Eigen::Vector3d& t, ImplicitNode child) {
  return ImplicitNode(TranslateParams{t}, {std::move(child)});
}

TEST(TapeSpecialization, SceneSolidsAreBitIdenticalOnEveryBox) {
  long pruned_boxes = 0;
  unsigned seed = 1;
  for (const char* file : {"platform.json", "clay.json", "assembly.json"}) {
    const Scene scene = LoadScene(std::string(SPIDARCAD_SOURCE_DIR) + "/assets/scenes/" + file);
    ASSERT_FALSE(scene.solids.empty()) << file;
    for (const Solid& s : scene.solids) {
      const CompiledSolid full = CompiledSolid::Compile(s.root);
      const PruneCount c =
          CheckRandomBoxes(full, RegionOf(full), std::string(file) + " solid " + s.name, seed++);
      pruned_boxes += c.pruned;
    }
  }
  // The scenes hold unions and differences of separated parts: many boxes must prune.
  EXPECT_GT(pruned_boxes, 100);
}

TEST(TapeSpecialization, HandBuiltTreesAreBitIdenticalOnEveryBox) {
  const ImplicitNode sphere(SphereParams{0.02});
  const ImplicitNode box(BoxParams{Eigen::Vector3d(0.05, 0.03, 0.04)});
  const ImplicitNode cylinder(CylinderParams{0.006, 0.08});
  ExtrusionParams triangle;
  triangle.profile = {{0.0, 0.0}, {0.03, 0.0}, {0.0, 0.02}};
  triangle.height = 0.02;
  const ImplicitNode cone(ConeParams{0.015, 0.004, 0.03});
  std::vector<std::pair<std::string, ImplicitNode>> trees;
  trees.emplace_back(
      "union", ImplicitNode(UnionParams{},
                            {At({-0.04, 0, 0}, sphere), At({0.04, 0, 0}, box),
                             At({0, 0.05, 0}, cone), At({0, -0.05, 0}, ImplicitNode(triangle))}));
  trees.emplace_back("intersection",
                     ImplicitNode(IntersectionParams{},
                                  {box, At({0.01, 0, 0}, ImplicitNode(SphereParams{0.03}))}));
  trees.emplace_back("difference",
                     ImplicitNode(DifferenceParams{},
                                  {box, At({0.015, 0, 0}, cylinder), At({-0.015, 0, 0}, cylinder),
                                   ImplicitNode(RotateParams{{1, 0, 0}, 1.2}, {cylinder})}));
  trees.emplace_back(
      "smooth union",
      ImplicitNode(SmoothUnionParams{0.01}, {At({-0.03, 0, 0}, sphere), At({0.03, 0.01, 0}, sphere),
                                             At({0, 0.06, 0}, box)}));
  trees.emplace_back("smooth intersection",
                     ImplicitNode(SmoothIntersectionParams{0.008},
                                  {box, At({0.02, 0, 0.01}, ImplicitNode(SphereParams{0.035}))}));
  trees.emplace_back("smooth difference",
                     ImplicitNode(SmoothDifferenceParams{0.004},
                                  {box, At({0.02, 0, 0}, cylinder), At({-0.02, 0.01, 0}, sphere)}));
  MirrorParams mirror;
  mirror.normal = Eigen::Vector3d(1, 0.2, 0);
  mirror.offset = 0.01;
  mirror.keep_original = true;
  trees.emplace_back(
      "transforms",
      ImplicitNode(
          UnionParams{},
          {ImplicitNode(mirror,
                        {At({0.03, 0, 0}, ImplicitNode(ScaleParams{{1.0, 0.5, 2.0}}, {sphere}))}),
           ImplicitNode(LinearArrayParams{{0.02, 0, 0.01}, 4},
                        {At({-0.05, 0.04, 0}, ImplicitNode(SphereParams{0.006}))}),
           ImplicitNode(PolarArrayParams{{0, 0, 1}, 6, 1.0471975511965976},
                        {At({0.05, 0, -0.04}, ImplicitNode(CylinderParams{0.004, 0.01}))})}));
  trees.emplace_back(
      "offset and shell",
      ImplicitNode(UnionParams{},
                   {ImplicitNode(OffsetParams{0.003}, {At({0.04, 0, 0}, box)}),
                    ImplicitNode(ShellParams{0.002}, {At({-0.05, 0, 0}, sphere)}),
                    ImplicitNode(SmoothDifferenceParams{0.0}, {At({0, 0.05, 0}, box), sphere})}));
  // A deep nest of smooth blends and differences.
  ImplicitNode nest = box;
  for (int i = 0; i < 6; ++i) {
    const Eigen::Vector3d t(0.01 * i - 0.03, 0.004 * i, -0.002 * i);
    nest = (i % 2)
               ? ImplicitNode(SmoothDifferenceParams{0.003},
                              {nest, At(t, ImplicitNode(SphereParams{0.008}))})
               : ImplicitNode(
                     SmoothUnionParams{0.005},
                     {nest, At(t + Eigen::Vector3d(0, 0.03, 0), ImplicitNode(SphereParams{0.01}))});
  }
  trees.emplace_back("nested blends", nest);
  unsigned seed = 100;
  for (const auto& [name, tree] : trees) {
    const CompiledSolid full = CompiledSolid::Compile(tree);
    const Eigen::AlignedBox3d region(Eigen::Vector3d::Constant(-0.1),
                                     Eigen::Vector3d::Constant(0.1));
    const PruneCount c = CheckRandomBoxes(full, region, name, seed++, 80, 40);
    if (name != "intersection") {
      EXPECT_GT(c.pruned, 0) << name;
    }
  }
}

TEST(TapeSpecialization, PrunesAFarOperandAndKeepsTies) {
  const ImplicitNode sphere(SphereParams{0.01});
  const CompiledSolid two = CompiledSolid::Compile(
      ImplicitNode(UnionParams{}, {At({-0.05, 0, 0}, sphere), At({0.05, 0, 0}, sphere)}));
  ASSERT_EQ(two.instruction_count(), 3);
  const Eigen::AlignedBox3d near_left(Eigen::Vector3d(-0.06, -0.01, -0.01),
                                      Eigen::Vector3d(-0.04, 0.01, 0.01));
  EXPECT_EQ(two.Specialize(near_left).instruction_count(), 1);
  // Midway between the spheres neither can be dropped.
  const Eigen::AlignedBox3d middle(Eigen::Vector3d(-0.005, -0.01, -0.01),
                                   Eigen::Vector3d(0.005, 0.01, 0.01));
  EXPECT_EQ(two.Specialize(middle).instruction_count(), 3);
  // Two identical operands tie everywhere: both stay.
  const CompiledSolid same = CompiledSolid::Compile(ImplicitNode(UnionParams{}, {sphere, sphere}));
  EXPECT_EQ(same.Specialize(Eigen::AlignedBox3d(Eigen::Vector3d::Constant(0.02),
                                                Eigen::Vector3d::Constant(0.03)))
                .instruction_count(),
            3);
  // A smooth union keeps both where the gap is below the radius, prunes where it is well above.
  const CompiledSolid blend = CompiledSolid::Compile(
      ImplicitNode(SmoothUnionParams{0.02}, {At({-0.05, 0, 0}, sphere), At({0.05, 0, 0}, sphere)}));
  const Eigen::AlignedBox3d small_left(Eigen::Vector3d(-0.052, -0.002, -0.002),
                                       Eigen::Vector3d(-0.048, 0.002, 0.002));
  EXPECT_EQ(blend.Specialize(small_left).instruction_count(), 1);  // gap ≈ 0.1 m > 0.02 m
  const Eigen::AlignedBox3d centre(Eigen::Vector3d(-0.002, -0.002, -0.002),
                                   Eigen::Vector3d(0.002, 0.002, 0.002));
  EXPECT_EQ(blend.Specialize(centre).instruction_count(), 3);
  // Inside the core of a hole the subtracted cylinder alone decides: the result is −cylinder.
  const CompiledSolid holed = CompiledSolid::Compile(
      ImplicitNode(DifferenceParams{}, {ImplicitNode(BoxParams{Eigen::Vector3d(0.2, 0.2, 0.2)}),
                                        ImplicitNode(CylinderParams{0.02, 0.3})}));
  const Eigen::AlignedBox3d core(Eigen::Vector3d(-0.002, -0.002, -0.01),
                                 Eigen::Vector3d(0.002, 0.002, 0.01));
  const CompiledSolid negated = holed.Specialize(core);
  EXPECT_EQ(negated.instruction_count(), 2);  // cylinder, negate
  std::mt19937 rng(7);
  for (const Eigen::Vector3d& p : BoxPoints(core, rng, 200)) SameAt(holed, negated, p, "hole core");
  // Specializing an empty solid or on an empty box changes nothing.
  EXPECT_EQ(CompiledSolid().Specialize(core).instruction_count(), 0);
  EXPECT_EQ(two.Specialize(Eigen::AlignedBox3d()).instruction_count(), 3);
}

// The assembly's torso, a rounded box less five cylinders: near one hole only the box and that
// hole's cylinder remain.
CompiledSolid Torso() {
  const Scene scene = LoadScene(std::string(SPIDARCAD_SOURCE_DIR) + "/assets/scenes/assembly.json");
  for (const Solid& s : scene.solids) {
    if (s.name == "body") return CompiledSolid::Compile(s.root);
  }
  ADD_FAILURE() << "assembly.json has no solid 'body'";
  return {};
}

TEST(TapeSpecialization, TorsoNearOneHoleKeepsTheBoxAndThatCylinder) {
  const CompiledSolid torso = Torso();
  ASSERT_EQ(torso.instruction_count(), 11);  // 6 primitives, 5 differences
  // A 4 mm cube in the bottom right hole (centre (0.012, 0, -0.03), radius 4.6 mm).
  const Eigen::AlignedBox3d hole(Eigen::Vector3d(0.010, -0.002, -0.030),
                                 Eigen::Vector3d(0.014, 0.002, -0.026));
  const CompiledSolid pruned = torso.Specialize(hole);
  EXPECT_LE(pruned.instruction_count(), 3);
  EXPECT_LE(pruned.primitive_count(), 2);
  std::mt19937 rng(11);
  for (const Eigen::Vector3d& p : BoxPoints(hole, rng, 500)) SameAt(torso, pruned, p, "torso hole");
}

TEST(CellSpecializedSolid, MatchesTheFullTapeEverywhere) {
  for (const char* file : {"platform.json", "clay.json", "assembly.json"}) {
    const Scene scene = LoadScene(std::string(SPIDARCAD_SOURCE_DIR) + "/assets/scenes/" + file);
    for (const Solid& s : scene.solids) {
      auto full = std::make_shared<const CompiledSolid>(CompiledSolid::Compile(s.root));
      const Eigen::AlignedBox3d region = RegionOf(*full);
      CellSpecializationSettings settings;
      settings.cell_size = 0.01;
      const CellSpecializedSolid cells(full, region, settings);
      const CellSpecializationStats& st = cells.stats();
      EXPECT_GT(st.cells, 0);
      EXPECT_LE(st.distinct_tapes, st.specialized_cells);
      EXPECT_LE(st.mean_instructions, st.full_instructions);
      std::mt19937 rng(3);
      std::uniform_real_distribution<double> u(-0.1, 1.1);  // a margin outside the grid too
      const std::string name = std::string(file) + " solid " + s.name;
      int failures = 0;
      for (int i = 0; i < 20000 && failures < 4; ++i) {
        Eigen::Vector3d p;
        for (int k = 0; k < 3; ++k)
          p[k] = region.min()[k] + u(rng) * (region.max()[k] - region.min()[k]);
        if (i % 4 == 0) {
          // On a cell face: a coordinate on a grid plane as the grid computes it.
          const int k = i % 3;
          const double h = st.cell_size;
          p[k] = region.min()[k] + h * std::floor((p[k] - region.min()[k]) / h);
        }
        failures += !SameAt(*full, cells.TapeAt(p), p, name);
        Eigen::Vector3d g1, g2;
        const double v1 = full->ValueAndGradient(p, &g1), v2 = cells.ValueAndGradient(p, &g2);
        EXPECT_EQ(Bits(v1), Bits(v2)) << name;
        EXPECT_EQ(Bits(full->Value(p)), Bits(cells.Value(p))) << name;
      }
    }
  }
}

TEST(CellSpecializedSolid, TorsoGridPrunesAndSharesTapes) {
  auto torso = std::make_shared<const CompiledSolid>(Torso());
  const Eigen::AlignedBox3d region(Eigen::Vector3d(-0.04, -0.03, -0.05),
                                   Eigen::Vector3d(0.04, 0.03, 0.05));
  CellSpecializationSettings settings;
  settings.cell_size = 0.005;
  const CellSpecializedSolid cells(torso, region, settings);
  const CellSpecializationStats& st = cells.stats();
  EXPECT_EQ(st.cells, 16 * 12 * 20);
  EXPECT_GT(st.specialized_cells, st.cells / 2);
  EXPECT_LT(st.distinct_tapes, st.specialized_cells / 4);
  EXPECT_LT(st.mean_instructions, 0.6 * st.full_instructions);
  EXPECT_LE(cells.TapeAt(Eigen::Vector3d(0.012, 0, -0.028)).instruction_count(), 3);
  // Outside the grid and at NaN: the full tape.
  EXPECT_EQ(&cells.TapeAt(Eigen::Vector3d(1, 0, 0)), &cells.solid());
  EXPECT_EQ(&cells.TapeAt(Eigen::Vector3d(NAN, 0, 0)), &cells.solid());
  // A coarse cap grows the cells.
  settings.max_cells = 100;
  const CellSpecializedSolid coarse(torso, region, settings);
  EXPECT_LE(coarse.stats().cells, 100);
  EXPECT_GT(coarse.stats().cell_size, 0.005);
}

TEST(CellSpecializedSolid, EvaluateDoesNotAllocate) {
  auto torso = std::make_shared<const CompiledSolid>(Torso());
  const CellSpecializedSolid cells(torso, Eigen::AlignedBox3d(Eigen::Vector3d::Constant(-0.05),
                                                              Eigen::Vector3d::Constant(0.05)));
  std::vector<Eigen::Vector3d> points;
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> u(-0.06, 0.06);
  for (int i = 0; i < 1000; ++i) points.emplace_back(u(rng), u(rng), u(rng));
  ASSERT_TRUE(test_support::MallocCounterActive());
  double sum = 0.0;
  {
    test_support::MallocCounter counter;
    Eigen::Vector3d g;
    for (const Eigen::Vector3d& p : points)
      sum += cells.ValueAndGradient(p, &g) + cells.Value(p) + g.x();
    EXPECT_EQ(counter.count(), 0);
  }
  EXPECT_TRUE(std::isfinite(sum));
}

TEST(CellSpecializedSolid, RejectsBadInput) {
  auto torso = std::make_shared<const CompiledSolid>(Torso());
  const Eigen::AlignedBox3d region(Eigen::Vector3d::Constant(-0.05),
                                   Eigen::Vector3d::Constant(0.05));
  auto message = [&](std::shared_ptr<const CompiledSolid> s, const Eigen::AlignedBox3d& r,
                     const CellSpecializationSettings& c) {
    try {
      CellSpecializedSolid cells(std::move(s), r, c);
    } catch (const std::invalid_argument& e) {
      return std::string(e.what());
    }
    return std::string("no error");
  };
  EXPECT_NE(message(nullptr, region, {}).find("null"), std::string::npos);
  EXPECT_NE(message(torso, Eigen::AlignedBox3d(), {}).find("region"), std::string::npos);
  CellSpecializationSettings bad;
  bad.cell_size = 0;
  EXPECT_NE(message(torso, region, bad).find("cell_size"), std::string::npos);
  bad.cell_size = NAN;
  EXPECT_NE(message(torso, region, bad).find("cell_size"), std::string::npos);
  bad = {};
  bad.max_cells = 0;
  EXPECT_NE(message(torso, region, bad).find("max_cells"), std::string::npos);
}

}  // namespace
}  // namespace spidarcad::modeling
