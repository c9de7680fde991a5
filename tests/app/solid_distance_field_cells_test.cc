// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
// SolidDistanceField over per-cell pruned tapes (modeling::CellSpecializedSolid): the same
// numbers, bit for bit, as the field over the full tape, and the assembly scene's fields use it.
#include <gtest/gtest.h>

#include <cstdint>
#include <cstdio>
#include <cstring>
#include <memory>
#include <random>
#include <stdexcept>
#include <string>

#include "scene/assembly_scene.h"
#include "scene/solid_distance_field.h"
#include "spidarcad/modeling/cell_specialized_solid.h"
#include "spidarcad/modeling/implicit_evaluator.h"
#include "spidarcad/modeling/scene_io.h"

namespace spidarcad::app {
namespace {

std::uint64_t Bits(double v) {
  std::uint64_t b;
  std::memcpy(&b, &v, sizeof b);
  return b;
}

TEST(SolidDistanceFieldCells, BitIdenticalToTheFullTape) {
  const modeling::Scene scene =
      modeling::LoadScene(std::string(SPIDARCAD_SOURCE_DIR) + "/assets/scenes/assembly.json");
  for (const modeling::Solid& s : scene.solids) {
    auto solid =
        std::make_shared<const modeling::CompiledSolid>(modeling::CompiledSolid::Compile(s.root));
    const Eigen::AlignedBox3d region(Eigen::Vector3d::Constant(-0.05),
                                     Eigen::Vector3d::Constant(0.05));
    auto cells = std::make_shared<const modeling::CellSpecializedSolid>(solid, region);
    const SolidDistanceField full(solid), fast(solid, cells);
    std::mt19937 rng(9);
    std::uniform_real_distribution<double> u(-0.06, 0.06);
    for (int i = 0; i < 5000; ++i) {
      const Eigen::Vector3d p(u(rng), u(rng), u(rng));
      Eigen::Vector3d g1, g2;
      const double v1 = full.Evaluate(p, &g1), v2 = fast.Evaluate(p, &g2);
      ASSERT_EQ(Bits(v1), Bits(v2)) << s.name;
      for (int k = 0; k < 3; ++k) ASSERT_EQ(Bits(g1[k]), Bits(g2[k])) << s.name;
      ASSERT_EQ(Bits(full.Evaluate(p, nullptr)), Bits(fast.Evaluate(p, nullptr))) << s.name;
    }
    EXPECT_EQ(&fast.solid(), solid.get());
    // Cells of another solid are refused; null cells mean the full tape.
    auto other =
        std::make_shared<const modeling::CompiledSolid>(modeling::CompiledSolid::Compile(s.root));
    EXPECT_THROW(SolidDistanceField(other, cells), std::invalid_argument);
    EXPECT_THROW(SolidDistanceField(nullptr, cells), std::invalid_argument);
    EXPECT_NO_THROW(SolidDistanceField(other, nullptr));
  }
}

TEST(SolidDistanceFieldCells, AssemblyFieldsMatchWithAndWithoutCells) {
  const modeling::Scene scene =
      modeling::LoadScene(std::string(SPIDARCAD_SOURCE_DIR) + "/assets/scenes/assembly.json");
  AssemblySceneSettings on, off;
  off.specialization_cell = 0.0;
  const auto a = BuildAssemblyField(scene, on);
  const auto b = BuildAssemblyField(scene, off);
  ASSERT_EQ(a->size(), b->size());
  std::mt19937 rng(4);
  std::uniform_real_distribution<double> u(-0.08, 0.08);
  for (int part = 0; part < a->size(); ++part) {
    const auto* with = dynamic_cast<const SolidDistanceField*>(a->part(part).field_P.get());
    const auto* without = dynamic_cast<const SolidDistanceField*>(b->part(part).field_P.get());
    ASSERT_NE(with, nullptr);
    ASSERT_NE(without, nullptr);
    ASSERT_NE(with->cells(), nullptr) << a->part(part).name;
    EXPECT_EQ(without->cells(), nullptr);
    EXPECT_LT(with->cells()->stats().mean_instructions, with->cells()->stats().full_instructions)
        << a->part(part).name;
    EXPECT_LT(with->cells()->stats().build_seconds, 1.0);
    const modeling::CellSpecializationStats& st = with->cells()->stats();
    std::printf(
        "part %s: %d cells of %.1f mm, %d specialized, %d distinct tapes, %.2f of %d instructions, "
        "%.2f ms\n",
        a->part(part).name.c_str(), st.cells, st.cell_size * 1e3, st.specialized_cells,
        st.distinct_tapes, st.mean_instructions, st.full_instructions, st.build_seconds * 1e3);
    for (int i = 0; i < 2000; ++i) {
      const Eigen::Vector3d p(u(rng), u(rng), u(rng));
      Eigen::Vector3d g1, g2;
      ASSERT_EQ(Bits(a->part(part).field_P->Evaluate(p, &g1)),
                Bits(b->part(part).field_P->Evaluate(p, &g2)));
      for (int k = 0; k < 3; ++k) ASSERT_EQ(Bits(g1[k]), Bits(g2[k]));
    }
  }
}

}  // namespace
}  // namespace spidarcad::app
