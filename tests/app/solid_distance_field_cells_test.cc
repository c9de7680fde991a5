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
#include <utility>
#include <vector>

#include "scene/assembly_scene.h"
#include "scene/scene_haptics.h"
#include "scene/solid_distance_field.h"
#include "spidarcad/haptics/point_shell_field.h"
#include "spidarcad/modeling/cell_specialized_solid.h"
#include "spidarcad/modeling/implicit_evaluator.h"
#include "spidarcad/modeling/scene_io.h"
#include "support/malloc_counter.h"

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
    const modeling::CellSpecializationStats& st = with->cells()->stats();
    RecordProperty("build_seconds_" + a->part(part).name, std::to_string(st.build_seconds));
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

// A field that only knows Evaluate: its EvaluateBatch is DistanceField's default, one point
// after the other (the scalar path).
class PointByPoint final : public haptics::DistanceField {
 public:
  explicit PointByPoint(std::shared_ptr<const haptics::DistanceField> f) : f_(std::move(f)) {}
  double Evaluate(const Eigen::Vector3d& p, Eigen::Vector3d* g) const noexcept override {
    return f_->Evaluate(p, g);
  }

 private:
  std::shared_ptr<const haptics::DistanceField> f_;
};

// The solids of a shipped scene as SolidDistanceFields over their pruned tapes (`cell` m).
std::vector<std::shared_ptr<const SolidDistanceField>> SceneFields(const char* file, double cell) {
  const modeling::Scene scene =
      modeling::LoadScene(std::string(SPIDARCAD_SOURCE_DIR) + "/assets/scenes/" + file);
  std::vector<std::shared_ptr<const SolidDistanceField>> fields;
  for (const modeling::Solid& s : scene.solids) {
    auto solid =
        std::make_shared<const modeling::CompiledSolid>(modeling::CompiledSolid::Compile(s.root));
    bool unbounded = false;
    const Eigen::AlignedBox3d box = SolidBounds(*solid, &unbounded);
    const Eigen::Vector3d margin = Eigen::Vector3d::Constant(0.02);
    modeling::CellSpecializationSettings settings;
    settings.cell_size = cell;
    fields.push_back(std::make_shared<const SolidDistanceField>(
        solid, std::make_shared<const modeling::CellSpecializedSolid>(
                   solid, Eigen::AlignedBox3d(box.min() - margin, box.max() + margin), settings)));
  }
  return fields;
}

TEST(SolidDistanceFieldCells, EvaluateBatchIsBitIdenticalToEvaluate) {
  std::mt19937 rng(12);
  for (const char* file : {"platform.json", "assembly.json"}) {
    for (const auto& fast : SceneFields(file, 0.005)) {
      const SolidDistanceField full(fast->cells()->shared_solid());
      bool unbounded = false;
      const Eigen::AlignedBox3d box = SolidBounds(fast->solid(), &unbounded);
      // Points over the solid's box and 3 cm around it (outside the grid too).
      std::uniform_real_distribution<double> u(-0.2, 1.2);
      const int n = 3001;
      std::vector<double> x(n), y(n), z(n), phi(n), psi(n), gx(n), gy(n), gz(n);
      for (int i = 0; i < n; ++i) {
        x[i] = box.min().x() + u(rng) * box.sizes().x();
        y[i] = box.min().y() + u(rng) * box.sizes().y();
        z[i] = box.min().z() + u(rng) * box.sizes().z();
      }
      for (const SolidDistanceField* field : {&full, fast.get()}) {
        const std::string name =
            std::string(file) + (field == &full ? ", full tape" : ", pruned tapes");
        field->EvaluateBatch(x.data(), y.data(), z.data(), n, phi.data(), nullptr, nullptr,
                             nullptr);
        field->EvaluateBatch(x.data(), y.data(), z.data(), n, psi.data(), gx.data(), gy.data(),
                             gz.data());
        for (int i = 0; i < n; ++i) {
          const Eigen::Vector3d p(x[i], y[i], z[i]);
          Eigen::Vector3d g;
          ASSERT_EQ(Bits(phi[i]), Bits(field->Evaluate(p, nullptr))) << name << " point " << i;
          ASSERT_EQ(Bits(psi[i]), Bits(field->Evaluate(p, &g))) << name << " point " << i;
          ASSERT_EQ(Bits(gx[i]), Bits(g.x())) << name << " point " << i;
          ASSERT_EQ(Bits(gy[i]), Bits(g.y())) << name << " point " << i;
          ASSERT_EQ(Bits(gz[i]), Bits(g.z())) << name << " point " << i;
        }
      }
    }
  }
}

// The six-DOF shell against the platform's solids, ticked through the batch (the tapes' SIMD
// evaluation, pruned per cell) with the narrow phase culled by motion bounds, and point by point
// with every point tested each tick (the scalar path): the same wrench, virtual tool and
// contacts, bit for bit, on every tick of a press and twist into the plate; no allocation.
TEST(SolidDistanceFieldCells, ShellTicksThroughTheBatchMatchPointByPoint) {
  ASSERT_TRUE(test_support::MallocCounterActive());
  std::vector<std::shared_ptr<const haptics::DistanceField>> batched, scalar;
  for (const auto& f : SceneFields("platform.json", 0.01)) {
    batched.push_back(f);
    scalar.push_back(std::make_shared<PointByPoint>(f));
  }
  for (int points : {196, 2004}) {
    const int rings = points == 196 ? 12 : 50, around = points == 196 ? 8 : 20;
    haptics::PointShellField a(std::make_shared<haptics::UnionDistanceField>(batched),
                               haptics::PointShell::CrossGrip(0.04, 0.006, rings, around));
    haptics::PointShellSettings exhaustive;
    exhaustive.cull_by_motion = false;
    haptics::PointShellField b(std::make_shared<haptics::UnionDistanceField>(scalar),
                               haptics::PointShell::CrossGrip(0.04, 0.006, rings, around),
                               exhaustive);
    ASSERT_EQ(a.shell().size(), points);
    int touching = 0, mismatches = 0;
    long allocations = 0;
    {
      test_support::MallocCounter counter;
      for (int k = 0; k < 800; ++k) {
        haptics::ToolKinematics tool;
        tool.time = 1e-3 * k;
        // Over the plate's top (z = 0.01), down 8 mm into it and back, twisting and tilting.
        const double s = std::sin(M_PI * k / 800.0);
        tool.p_WT = Eigen::Vector3d(0.15 + 0.02 * s, 0.01 * s, 0.0175 - 0.008 * s);
        tool.R_WT = (Eigen::AngleAxisd(0.6 * s, Eigen::Vector3d::UnitZ()) *
                     Eigen::AngleAxisd(0.2 * s, Eigen::Vector3d::UnitX()))
                        .toRotationMatrix();
        tool.v_WT = Eigen::Vector3d(0.02, 0.01, -0.008) * (M_PI / 0.8) * std::cos(M_PI * k / 800.0);
        const haptics::ToolWrench wa = a.Evaluate(tool), wb = b.Evaluate(tool);
        touching += a.contacts() > 0;
        bool same = a.contacts() == b.contacts();
        for (int i = 0; i < 3; ++i) {
          same = same && Bits(wa.f_T_W[i]) == Bits(wb.f_T_W[i]) &&
                 Bits(wa.m_T_W[i]) == Bits(wb.m_T_W[i]) && Bits(a.p_WV()[i]) == Bits(b.p_WV()[i]);
        }
        for (int i = 0; i < 4; ++i)
          same = same && Bits(a.q_WV().coeffs()[i]) == Bits(b.q_WV().coeffs()[i]);
        mismatches += !same;
      }
      allocations = counter.count();
    }
    EXPECT_EQ(mismatches, 0) << points << " points";
    EXPECT_GT(touching, 300) << points << " points";
    EXPECT_EQ(allocations, 0) << points << " points";
  }
}

}  // namespace
}  // namespace spidarcad::app
