// Tests of the assembly scene: assets/scenes/assembly.json loads into an AssemblyField, each
// peg fits its hole with clearance (measured on the compiled solids by bisection, and no shell
// point of a seated part inside the body), and a scripted grip (approach the right arm, close,
// carry it to the body, insert, open) ends with the arm seated. The same parts as a Document's
// rigid parts (AdoptScenePartsAsRigidParts) build the same field; the geometry cache compiles
// only the trees that changed.
// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#include "scene/assembly_scene.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <memory>
#include <string>
#include <variant>
#include <vector>

#include "doc/command.h"
#include "doc/document.h"
#include "spidarcad/modeling/implicit_evaluator.h"
#include "spidarcad/modeling/scene_io.h"
#include "support/malloc_counter.h"

namespace spidarcad::app {
namespace {

const std::string kScene = std::string(SPIDARCAD_SOURCE_DIR) + "/assets/scenes/assembly.json";
constexpr double kPi = 3.14159265358979323846;

const modeling::Solid& FindSolid(const modeling::Scene& scene, const std::string& name) {
  for (const modeling::Solid& s : scene.solids) {
    if (s.name == name) return s;
  }
  throw std::runtime_error("no solid " + name);
}

// Smallest r in [lo, hi] where inside(r) turns true (inside(lo) false, inside(hi) true), by
// bisection.
template <class F>
double Crossing(const F& inside, double lo, double hi) {
  EXPECT_FALSE(inside(lo));
  EXPECT_TRUE(inside(hi));
  for (int i = 0; i < 50; ++i) {
    const double mid = 0.5 * (lo + hi);
    (inside(mid) ? hi : lo) = mid;
  }
  return 0.5 * (lo + hi);
}

TEST(AssemblyScene, EachPegFitsItsHoleWithClearance) {
  const modeling::Scene scene = modeling::LoadScene(kScene);
  const auto field = BuildAssemblyField(scene);
  ASSERT_EQ(field->size(), 6);
  int checked = 0;
  for (int i = 0; i < field->size(); ++i) {
    const modeling::ScenePart& sp = scene.parts[i];
    if (sp.seats.empty()) continue;
    const modeling::ScenePart& body = scene.parts[field->part(i).seats[0].other];
    const auto peg = modeling::CompiledSolid::Compile(FindSolid(scene, sp.solid).root);
    const auto hole = modeling::CompiledSolid::Compile(FindSolid(scene, body.solid).root);
    const Eigen::Isometry3d X_OS = field->part(i).seats[0].X_OS;
    double peg_max = 0, hole_min = 1;
    for (int k = 0; k < 16; ++k) {
      const double a = 2 * kPi * k / 16;
      // Half way down the peg (peg along −z of P from the origin, 8 mm long).
      auto at = [&](double r) { return Eigen::Vector3d(r * std::cos(a), r * std::sin(a), -0.004); };
      const double r_peg = Crossing([&](double r) { return peg.Value(at(r)) > 0; }, 0.0, 0.008);
      const double r_hole =
          Crossing([&](double r) { return hole.Value(X_OS * at(r)) < 0; }, 0.0, 0.008);
      peg_max = std::max(peg_max, r_peg);
      hole_min = std::min(hole_min, r_hole);
    }
    EXPECT_NEAR(peg_max, 0.004, 1e-6) << sp.name;
    EXPECT_NEAR(hole_min, 0.0046, 1e-6) << sp.name;
    EXPECT_LT(peg_max, hole_min) << sp.name;
    // Seated, no surface point of the part is inside the body.
    const haptics::PointShell& shell = field->part(i).shell_P;
    ASSERT_GT(shell.size(), 100) << sp.name;
    double min_phi = 1;
    for (const Eigen::Vector3d& r : shell.points_T) {
      min_phi = std::min(min_phi, hole.Value(X_OS * r));
    }
    EXPECT_GT(min_phi, 2e-4) << sp.name;
    ++checked;
  }
  EXPECT_EQ(checked, 5);
}

TEST(AssemblyScene, PartsStartApartAndWithinTheWorkspace) {
  const modeling::Scene scene = modeling::LoadScene(kScene);
  const auto field = BuildAssemblyField(scene);
  // No part's surface is inside another part at the start, and every seated surface point lies
  // within a 0.15 m cube.
  Eigen::AlignedBox3d seated_box;
  for (int i = 0; i < field->size(); ++i) {
    for (const Eigen::Vector3d& r : field->part(i).shell_P.points_T) {
      const Eigen::Vector3d p_W = field->X_WP(i) * r;
      for (int j = 0; j < field->size(); ++j) {
        if (j == i) continue;
        const Eigen::Vector3d p_Pj = field->X_WP(j).inverse() * p_W;
        EXPECT_GT(field->part(j).field_P->Evaluate(p_Pj, nullptr), 0.0)
            << field->part(i).name << " in " << field->part(j).name;
      }
      if (!field->part(i).seats.empty()) {
        const auto& seat = field->part(i).seats[0];
        seated_box.extend(field->X_WP(seat.other) * seat.X_OS * r);
      }
    }
  }
  EXPECT_LT(seated_box.sizes().maxCoeff(), 0.15);
}

TEST(AssemblyScene, ScriptedRunSeatsTheRightArm) {
  const modeling::Scene scene = modeling::LoadScene(kScene);
  const auto field = BuildAssemblyField(scene);
  const int arm = 2;
  ASSERT_EQ(field->part(arm).name, "right_arm");
  // The grip's plane (T's xy) is the world's yz plane, so the arm's 12 mm square section lies
  // between the poles: x_T → y_W, y_T → z_W, z_T → x_W.
  haptics::ToolKinematics tool;
  tool.R_WT << 0, 0, 1, 1, 0, 0, 0, 1, 0;
  const Eigen::Vector3d b_W = tool.R_WT * Eigen::Vector3d(1, 1, 0).normalized();
  const Eigen::Vector3d centre_P(0, 0, 0.0175);  // middle of the arm's bulk
  auto grip_for = [&](const Eigen::Isometry3d& X_WP) {
    return Eigen::Vector3d(X_WP * centre_P - 0.02 * b_W);
  };
  auto tick = [&] {
    tool.time += 1e-3;
    return field->Evaluate(tool);
  };
  auto move_to = [&](const Eigen::Vector3d& p, int ticks) {
    const Eigen::Vector3d start = tool.p_WT;
    for (int k = 1; k <= ticks; ++k) {
      const Eigen::Vector3d next = start + (p - start) * (double(k) / ticks);
      tool.v_WT = (next - tool.p_WT) / 1e-3;
      tool.p_WT = next;
      tick();
    }
    tool.v_WT.setZero();
    for (int k = 0; k < 200; ++k) tick();
  };
  // Approach.
  const Eigen::Isometry3d start = field->X_WP(arm);
  tool.p_WT = grip_for(start);
  tick();
  EXPECT_EQ(field->carried(), -1);
  // Close the grasp.
  double min_g = 0;
  while (field->carried() < 0 && tool.grasp > 0.3) {
    tool.grasp -= 1e-3;
    tool.grasp_rate = -1.0;
    min_g = std::min(min_g, tick().g);
  }
  tool.grasp_rate = 0;
  ASSERT_EQ(field->carried(), arm);
  EXPECT_LT(min_g, 0.0);
  // Carry: lift, over to the body's right side, in front of the hole, then insert along −x.
  const Eigen::Isometry3d seat =
      field->X_WP(field->part(arm).seats[0].other) * field->part(arm).seats[0].X_OS;
  Eigen::Isometry3d waypoint = seat;
  waypoint.translation() += Eigen::Vector3d(0.025, 0.06, 0);
  move_to(grip_for(waypoint), 600);
  waypoint.translation().y() = seat.translation().y();
  move_to(grip_for(waypoint), 600);
  EXPECT_EQ(field->contacts(), 0);
  Eigen::Isometry3d inserted = seat;
  inserted.translation().x() += 0.001;  // 1 mm short of the seat
  move_to(grip_for(inserted), 600);
  ASSERT_EQ(field->carried(), arm);
  EXPECT_LT((field->X_WP(arm).translation() - inserted.translation()).norm(), 1e-3);
  // Open.
  while (tool.grasp < kPi / 2) {
    tool.grasp = std::min(kPi / 2, tool.grasp + 2e-3);
    tick();
  }
  EXPECT_EQ(field->carried(), -1);
  EXPECT_TRUE(field->seated(arm));
  EXPECT_EQ(field->X_WP(arm).matrix(), seat.matrix());
  // The grip leaves; the arm stays.
  move_to(tool.p_WT + Eigen::Vector3d(0.03, 0.04, 0.0), 200);
  EXPECT_TRUE(field->seated(arm));
  EXPECT_EQ(field->X_WP(arm).matrix(), seat.matrix());
  const haptics::AssemblyState& state = field->LatestState();
  EXPECT_TRUE(state.seated[arm]);
  EXPECT_EQ(state.carried, -1);
  for (int i = 0; i < field->size(); ++i) {
    if (i != arm) {
      EXPECT_FALSE(state.seated[i]);
      EXPECT_EQ(field->X_WP(i).matrix(), field->part(i).X_WP.matrix()) << field->part(i).name;
    }
  }
}

// The carried part's candidate search and the tool's shell evaluate the parts' cell-specialised
// tapes several points at a time (DistanceField::EvaluateBatch). Against the same field
// evaluating one point at a time (AssemblySettings::batch_evaluation off), an approach, a
// grasp of the right arm, a carry into its hole with the peg pressed on the hole's wall, a
// release and the tool pushed into the body give the same wrench, poses, contacts and candidates
// every tick, bit for bit; the batched field's ticks allocate nothing.
TEST(AssemblyScene, BatchedEvaluationEqualsThePointByPointFieldBitForBit) {
  const modeling::Scene scene = modeling::LoadScene(kScene);
  std::unique_ptr<haptics::AssemblyField> fields[2];
  for (const bool batch : {true, false}) {
    AssemblySceneSettings settings;
    settings.field.batch_evaluation = batch;
    fields[batch ? 0 : 1] = BuildAssemblyField(scene, settings);
  }
  const int arm = 2;
  ASSERT_EQ(fields[0]->part(arm).name, "right_arm");
  // The grip as in ScriptedRunSeatsTheRightArm.
  haptics::ToolKinematics tool;
  tool.R_WT << 0, 0, 1, 1, 0, 0, 0, 1, 0;
  const Eigen::Vector3d b_W = tool.R_WT * Eigen::Vector3d(1, 1, 0).normalized();
  const Eigen::Vector3d centre_P(0, 0, 0.0175);
  auto grip_for = [&](const Eigen::Isometry3d& X_WP) {
    return Eigen::Vector3d(X_WP * centre_P - 0.02 * b_W);
  };
  int carried_ticks = 0, touching = 0, tool_touching = 0;
  long candidates = 0, allocations = 0;
  ASSERT_TRUE(test_support::MallocCounterActive());
  auto tick = [&] {
    tool.time += 1e-3;
    haptics::ToolWrench a;
    {
      test_support::MallocCounter counter;  // the batched tick allocates nothing
      a = fields[0]->Evaluate(tool);
      allocations += counter.count();
    }
    const haptics::ToolWrench b = fields[1]->Evaluate(tool);
    ASSERT_EQ(a.f_T_W, b.f_T_W) << "t = " << tool.time;
    ASSERT_EQ(a.m_T_W, b.m_T_W) << "t = " << tool.time;
    ASSERT_EQ(a.g, b.g) << "t = " << tool.time;
    ASSERT_EQ(fields[0]->carried(), fields[1]->carried());
    ASSERT_EQ(fields[0]->contacts(), fields[1]->contacts());
    ASSERT_EQ(fields[0]->candidates(), fields[1]->candidates());
    for (int i = 0; i < fields[0]->size(); ++i)
      ASSERT_EQ(fields[0]->X_WP(i).matrix(), fields[1]->X_WP(i).matrix()) << "part " << i;
    carried_ticks += fields[0]->carried() >= 0;
    touching += fields[0]->carried() >= 0 && fields[0]->contacts() > 0;
    tool_touching += fields[0]->carried() < 0 && fields[0]->contacts() > 0;
    candidates += fields[0]->candidates();
  };
  auto move_to = [&](const Eigen::Vector3d& p, int ticks) {
    const Eigen::Vector3d start = tool.p_WT;
    for (int k = 1; k <= ticks && !HasFatalFailure(); ++k) {
      const Eigen::Vector3d next = start + (p - start) * (double(k) / ticks);
      tool.v_WT = (next - tool.p_WT) / 1e-3;
      tool.p_WT = next;
      tick();
    }
    tool.v_WT.setZero();
  };
  tool.p_WT = grip_for(fields[0]->X_WP(arm));
  tick();
  while (fields[0]->carried() < 0 && tool.grasp > 0.3 && !HasFatalFailure()) {
    tool.grasp -= 1e-3;
    tool.grasp_rate = -1.0;
    tick();
  }
  tool.grasp_rate = 0;
  ASSERT_EQ(fields[0]->carried(), arm);
  // In front of the hole, then in along −x, 2 mm off its axis: the peg presses on the wall.
  const haptics::AssemblySeat& seat_of = fields[0]->part(arm).seats[0];
  const Eigen::Isometry3d seat = fields[0]->X_WP(seat_of.other) * seat_of.X_OS;
  Eigen::Isometry3d waypoint = seat;
  waypoint.translation() += Eigen::Vector3d(0.025, 0.06, 0);
  move_to(grip_for(waypoint), 400);
  waypoint.translation().y() = seat.translation().y();
  move_to(grip_for(waypoint), 400);
  Eigen::Isometry3d pressed = seat;
  pressed.translation() += Eigen::Vector3d(0.004, 0.002, 0.001);
  move_to(grip_for(pressed), 600);
  for (int k = 0; k < 300 && !HasFatalFailure(); ++k) {
    tool.p_WT.y() += 0.0004 * std::sin(0.05 * k);
    tick();
  }
  while (tool.grasp < kPi / 2 && !HasFatalFailure()) {
    tool.grasp = std::min(kPi / 2, tool.grasp + 2e-3);
    tick();
  }
  // The open grip's tool sphere pushed into the body beside the arm.
  const Eigen::Vector3d body_W = fields[0]->X_WP(seat_of.other).translation();
  move_to(body_W + Eigen::Vector3d(0, -0.01, 0.03), 400);
  move_to(body_W + Eigen::Vector3d(0, -0.01, 0.0), 400);
  std::printf("carried %d ticks, %d with contacts, %ld candidates in all; tool in contact %d\n",
              carried_ticks, touching, candidates, tool_touching);
  EXPECT_GT(carried_ticks, 1000);
  EXPECT_GT(touching, 50);  // the peg did press on the hole's wall
  EXPECT_GT(candidates, 10000);
  EXPECT_GT(tool_touching, 50);  // the tool's own shell pressed on the body
  EXPECT_EQ(allocations, 0);
}

// The version 1 robot as rigid parts: one rigid_part per part with its solid's tree, its pose
// and seats; no solid left (every solid is a part's); clean, no history, same file. The field of
// the rigid parts is the field of the scene: names, fixed flags, poses and seats bit for bit, and
// the same distance at probe points.
TEST(AssemblyScene, SceneModelPartsBecomeRigidPartsThatBuildTheSameField) {
  const modeling::Scene scene = modeling::LoadScene(kScene);
  Document doc;
  doc.Load(kScene);
  ASSERT_EQ(doc.parts().size(), 6u);
  ASSERT_TRUE(AdoptScenePartsAsRigidParts(&doc));
  EXPECT_TRUE(doc.parts().empty());
  EXPECT_EQ(doc.file_path(), kScene);
  EXPECT_FALSE(doc.dirty());
  EXPECT_FALSE(doc.history().CanUndo());
  EXPECT_FALSE(AdoptScenePartsAsRigidParts(&doc)) << "a second call has nothing to do";
  ASSERT_EQ(doc.objects().size(), 6u);
  for (size_t i = 0; i < doc.objects().size(); ++i) {
    const DocObject& o = doc.objects()[i];
    const modeling::ScenePart& sp = scene.parts[i];
    EXPECT_EQ(o.name, sp.name);
    const auto* r = std::get_if<RigidPartData>(&o.data);
    ASSERT_NE(r, nullptr) << o.name;
    EXPECT_EQ(modeling::NodeToJson(r->root), modeling::NodeToJson(FindSolid(scene, sp.solid).root));
    EXPECT_EQ(r->fixed, sp.fixed);
    ASSERT_EQ(r->seats.size(), sp.seats.size());
  }
  std::vector<ObjectId> ids;
  const std::vector<AssemblyPartInput> inputs = RigidPartInputs(doc, &ids);
  ASSERT_EQ(ids.size(), 6u);
  EXPECT_EQ(ids[2], doc.objects()[2].id);
  const auto from_scene = BuildAssemblyField(scene);
  const auto from_doc = BuildAssemblyField(inputs, AssemblySceneSettings{}, nullptr);
  ASSERT_EQ(from_doc->size(), from_scene->size());
  for (int i = 0; i < from_doc->size(); ++i) {
    const haptics::AssemblyPart& a = from_doc->part(i);
    const haptics::AssemblyPart& b = from_scene->part(i);
    EXPECT_EQ(a.name, b.name);
    EXPECT_EQ(a.fixed, b.fixed);
    EXPECT_EQ(a.X_WP.matrix(), b.X_WP.matrix()) << a.name;
    EXPECT_EQ(a.shell_P.size(), b.shell_P.size()) << a.name;
    ASSERT_EQ(a.seats.size(), b.seats.size());
    for (size_t k = 0; k < a.seats.size(); ++k) {
      EXPECT_EQ(a.seats[k].other, b.seats[k].other);
      EXPECT_EQ(a.seats[k].X_OS.matrix(), b.seats[k].X_OS.matrix());
    }
    for (const Eigen::Vector3d& p :
         {Eigen::Vector3d(0.006, 0.0, -0.004), Eigen::Vector3d(0.0, 0.01, 0.02),
          Eigen::Vector3d(-0.02, 0.003, 0.001)}) {
      EXPECT_EQ(a.field_P->Evaluate(p, nullptr), b.field_P->Evaluate(p, nullptr)) << a.name;
    }
  }
}

// A document saved with a part in its seat (the workbench's cap on its base): the field starts
// with it seated, so `spidarcad run`'s summary counts it as the window's assembly mode and
// `spidarcad info` do (it said "0 of 1" before 2026-12-07).
TEST(AssemblyScene, APartSavedInItsSeatIsSeatedInTheSummary) {
  Document doc;
  doc.Load(std::string(SPIDARCAD_SOURCE_DIR) + "/assets/scenes/workbench.json");
  const auto field =
      BuildAssemblyField(RigidPartInputs(doc, nullptr), AssemblySceneSettings{}, nullptr);
  ASSERT_EQ(field->size(), 2);
  EXPECT_EQ(FormatAssemblySummary(*field, field->LatestState()),
            "assembly: 1 of 1 parts seated (cap), carried: none\n");
}

// Two parts of one solid get separate trees; the copy's node ids get the part's name so that
// ids stay unique in the document. Other solids stay, in order, ahead of the parts.
TEST(AssemblyScene, SharedSolidsCopyTheirTreeWithUniqueNodeIds) {
  const std::filesystem::path path =
      std::filesystem::path(SPIDARCAD_TEST_OUTPUT_DIR) / "adopt_shared_solid.json";
  {
    std::ofstream out(path);
    out << R"({"format": "spidarcad-scene", "version": 1, "units": "m", "solids": [
      {"name": "peg", "root": {"type": "sphere", "id": "ball", "radius": 0.01}},
      {"name": "table", "root": {"type": "box", "size": [0.1, 0.1, 0.01]}}],
      "parts": [{"name": "a", "solid": "peg", "position": [0.05, 0, 0]},
                {"name": "b", "solid": "peg", "position": [-0.05, 0, 0]}]})";
  }
  Document doc;
  doc.Load(path.string());
  ASSERT_TRUE(AdoptScenePartsAsRigidParts(&doc));
  ASSERT_EQ(doc.objects().size(), 3u);
  EXPECT_EQ(doc.objects()[0].name, "table");
  EXPECT_TRUE(std::holds_alternative<SolidData>(doc.objects()[0].data));
  EXPECT_EQ(std::get<RigidPartData>(doc.objects()[1].data).root.id, "ball");
  EXPECT_EQ(std::get<RigidPartData>(doc.objects()[2].data).root.id, "ball_b");
  EXPECT_EQ(std::get<RigidPartData>(doc.objects()[2].data).X_WP.translation(),
            Eigen::Vector3d(-0.05, 0, 0));
  EXPECT_FALSE(doc.dirty());
}

// A rebuild after a pose change finds every tree in the cache; after an edit of one tree (the
// head's peg radius) only that tree is compiled again, and the field holds the new shape: its
// distance beside the peg is the edited solid's own and moved by the edit (0.5 mm).
TEST(AssemblyScene, GeometryCacheCompilesOnlyChangedTrees) {
  Document doc;
  doc.Load(kScene);
  ASSERT_TRUE(AdoptScenePartsAsRigidParts(&doc));
  AssemblyGeometryCache cache;
  BuildAssemblyField(RigidPartInputs(doc, nullptr), AssemblySceneSettings{}, &cache);
  EXPECT_EQ(cache.compiled_last(), 4) << "body, head, arm, leg";
  EXPECT_EQ(cache.size(), 4);
  const ObjectId head = doc.objects()[1].id;
  Eigen::Isometry3d X = std::get<RigidPartData>(doc.Get(head).data).X_WP;
  X.translation() += Eigen::Vector3d(0.01, 0, 0);
  doc.Execute(edit::SetRigidPose(head, X));
  auto moved = BuildAssemblyField(RigidPartInputs(doc, nullptr), AssemblySceneSettings{}, &cache);
  EXPECT_EQ(cache.compiled_last(), 0);
  EXPECT_EQ(moved->part(1).X_WP.matrix(), X.matrix());
  const Eigen::Vector3d p_P(0.006, 0.0, -0.004);  // 2 mm beside the 4 mm peg, mid-height
  const double before = moved->part(1).field_P->Evaluate(p_P, nullptr);
  EXPECT_NEAR(before, 0.002, 1e-12);
  doc.Execute(edit::SetNodeField(head, {1, 0}, "radius", 0.0035));
  auto edited = BuildAssemblyField(RigidPartInputs(doc, nullptr), AssemblySceneSettings{}, &cache);
  EXPECT_EQ(cache.compiled_last(), 1);
  EXPECT_EQ(cache.size(), 4);
  const double after = edited->part(1).field_P->Evaluate(p_P, nullptr);
  const auto own =
      modeling::CompiledSolid::Compile(std::get<RigidPartData>(doc.Get(head).data).root);
  EXPECT_NEAR(after, own.Value(p_P), 1e-12);
  EXPECT_NEAR(after - before, 0.0005, 1e-12);
  // The other parts' geometry is shared with the earlier build.
  EXPECT_EQ(edited->part(2).field_P, moved->part(2).field_P);
}

TEST(AssemblyScene, SceneWithoutPartsIsRejected) {
  modeling::Scene scene = modeling::LoadScene(kScene);
  scene.parts.clear();
  EXPECT_THROW(BuildAssemblyField(scene), std::invalid_argument);
}

}  // namespace
}  // namespace spidarcad::app
