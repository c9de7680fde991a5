// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
// Tests of the runtime adapters (app/src/runtime): solids as distance fields, scenes as haptic
// force fields with their device-to-scene map, and `spidarcad run` on a scene file. Expected
// values are closed forms (a sphere's distance, a plate face's spring law k × depth, the fit's
// formula applied to known boxes), not the code's own output.
#include <cmath>
#include <fstream>
#include <memory>
#include <random>
#include <string>

#include <gtest/gtest.h>

#include "golden_compare.h"
#include "runtime/scene_haptics.h"
#include "runtime/solid_distance_field.h"
#include "spidarcad/haptics/force_field.h"
#include "spidarcad/haptics/proxy_field.h"
#include "spidarcad/modeling/implicit_evaluator.h"
#include "spidarcad/modeling/scene_io.h"
#include "spidarcad_runner.h"

namespace {

using spidarcad::app::BuildHapticScene;
using spidarcad::app::FitWorkspace;
using spidarcad::app::SceneHaptics;
using spidarcad::app::SceneHapticsOptions;
using spidarcad::app::SolidDistanceField;
using spidarcad::app::ToolModel;
namespace haptics = spidarcad::haptics;
namespace modeling = spidarcad::modeling;

std::string Source(const std::string& relative) {
  return std::string(SPIDARCAD_SOURCE_DIR) + "/" + relative;
}

modeling::Scene SphereScene() {
  return modeling::ParseScene(R"({"format": "spidarcad-scene", "version": 1, "solids": [
      {"name": "ball", "root": {"type": "translate", "translation": [0.01, -0.02, 0.03],
       "children": [{"type": "sphere", "radius": 0.05}]}}]})");
}

TEST(SolidDistanceField, EqualsTheSpheresClosedFormDistanceAndGradient) {
  const modeling::Scene scene = SphereScene();
  auto solid = std::make_shared<const modeling::CompiledSolid>(
      modeling::CompiledSolid::Compile(scene.solids[0].root));
  const SolidDistanceField field(solid);
  const Eigen::Vector3d c(0.01, -0.02, 0.03);
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> u(-0.12, 0.12);
  for (int i = 0; i < 200; ++i) {
    const Eigen::Vector3d p(u(rng), u(rng), u(rng));
    Eigen::Vector3d g;
    const double phi = field.Evaluate(p, &g);
    EXPECT_NEAR(phi, (p - c).norm() - 0.05, 1e-12);
    EXPECT_NEAR((g - (p - c).normalized()).norm(), 0.0, 1e-9);
    EXPECT_EQ(field.Evaluate(p, nullptr), phi);  // value without a gradient: same number
    Eigen::Vector3d g_solid;
    EXPECT_EQ(solid->ValueAndGradient(p, &g_solid), phi);
    EXPECT_EQ(g_solid, g);
  }
  EXPECT_THROW(SolidDistanceField(nullptr), std::invalid_argument);
}

// Steps a proxy from above the plate's top face straight down to `depth` (world m) below it.
haptics::ToolWrench PressPlate(haptics::HapticScene* scene, const Eigen::Vector3d& above_W,
                               double depth) {
  haptics::ToolKinematics tool;
  tool.p_WT = above_W;
  haptics::ToolWrench w = scene->Evaluate(tool);
  EXPECT_EQ(w.f_T_W.norm(), 0.0);  // free space: no force
  const double top = 0.01;
  const int steps = 50;
  for (int k = 1; k <= steps; ++k) {
    tool.time = 1e-3 * k;
    tool.p_WT.z() = above_W.z() + (top - depth - above_W.z()) * k / steps;
    w = scene->Evaluate(tool);
  }
  return w;
}

TEST(BuildHapticScene, ProxyOnThePlatformPlatePushesOutAlongTheNormalWithStiffnessTimesDepth) {
  const modeling::Scene scene = modeling::LoadScene(Source("assets/scenes/platform.json"));
  SceneHapticsOptions options;
  options.world_scale = 1.0;
  options.p_WDo = Eigen::Vector3d::Zero();
  SceneHaptics built = BuildHapticScene(scene, options);
  ASSERT_EQ(built.fields.size(), 2u);
  EXPECT_EQ(built.fields[0].solid, "platform");
  EXPECT_EQ(built.fields[1].solid, "wall");
  // The plate's top face z = 0.01 m, away from its edges, holes and the gusset.
  for (double depth : {0.0005, 0.002, 0.004}) {
    SceneHaptics fresh = BuildHapticScene(scene, options);
    const haptics::ToolWrench w = PressPlate(fresh.scene.get(), Eigen::Vector3d(0.15, 0.05, 0.03), depth);
    EXPECT_NEAR(w.f_T_W.z(), 1500.0 * depth, 1e-6 * 1500.0) << "depth " << depth;
    EXPECT_NEAR(w.f_T_W.head<2>().norm(), 0.0, 1e-9);
  }
}

TEST(BuildHapticScene, StiffnessIsWhatTheGripFeelsWhateverTheWorldScale) {
  const modeling::Scene scene = modeling::LoadScene(Source("assets/scenes/platform.json"));
  SceneHapticsOptions options;
  options.world_scale = 2.5;  // a grip displacement δ is a world displacement 2.5 δ
  options.p_WDo = Eigen::Vector3d::Zero();
  options.stiffness = 1200.0;
  SceneHaptics built = BuildHapticScene(scene, options);
  const double depth_W = 0.003;
  const haptics::ToolWrench w = PressPlate(built.scene.get(), Eigen::Vector3d(0.15, 0.05, 0.03), depth_W);
  // Felt: k × grip depth = 1200 × (0.003 / 2.5) N.
  EXPECT_NEAR(w.f_T_W.z(), 1200.0 * depth_W / 2.5, 1e-5);
}

TEST(FitWorkspace, MapsTheScenesBoxIntoTheDeviceCubeCentredAndFillingTheFraction) {
  const Eigen::AlignedBox3d box(Eigen::Vector3d(-0.05, -0.3, -0.3), Eigen::Vector3d(0.3, 0.3, 0.2));
  const auto map = FitWorkspace(box, 0.1, 0.8);
  EXPECT_NEAR(map.world_scale, 0.6 / 0.16, 1e-12);
  EXPECT_TRUE(map.p_WDo.isApprox(Eigen::Vector3d(0.125, 0.0, -0.05)));
  // Every corner maps into the cube, and the largest side spans exactly 0.16 m of grip motion.
  for (int i = 0; i < 8; ++i) {
    const Eigen::Vector3d corner = box.corner(static_cast<Eigen::AlignedBox3d::CornerType>(i));
    const Eigen::Vector3d p_D = (corner - map.p_WDo) / map.world_scale;
    EXPECT_LE(p_D.cwiseAbs().maxCoeff(), 0.08 + 1e-12);
  }
  EXPECT_NEAR((box.max().y() - box.min().y()) / map.world_scale, 0.16, 1e-12);
  // A 4 cm part is magnified: s < 1.
  const auto small = FitWorkspace(Eigen::AlignedBox3d(Eigen::Vector3d::Constant(0.0), Eigen::Vector3d::Constant(0.04)), 0.1, 0.8);
  EXPECT_NEAR(small.world_scale, 0.25, 1e-12);
  EXPECT_THROW(FitWorkspace(Eigen::AlignedBox3d(), 0.1, 0.8), std::invalid_argument);
}

TEST(BuildHapticScene, FitsThePlatformsKnownBoxUnlessTheOptionsGiveTheMap) {
  const modeling::Scene scene = modeling::LoadScene(Source("assets/scenes/platform.json"));
  SceneHaptics fitted = BuildHapticScene(scene, SceneHapticsOptions{});
  // The wall (x −0.05..0, y ±0.3, z −0.3..0.2) and plate (x to 0.3) bound the scene; FindBounds
  // overestimates by at most about a cell (side / 64 < 1 cm).
  const Eigen::AlignedBox3d& b = fitted.map.bounds_W;
  const Eigen::Vector3d lo(-0.05, -0.3, -0.3), hi(0.3, 0.3, 0.2);
  EXPECT_TRUE((b.min().array() <= lo.array() + 1e-9).all() && (b.min() - lo).norm() < 0.02);
  EXPECT_TRUE((b.max().array() >= hi.array() - 1e-9).all() && (b.max() - hi).norm() < 0.02);
  EXPECT_TRUE(fitted.map.scale_fitted && fitted.map.origin_fitted);
  EXPECT_NEAR(fitted.map.world_scale, b.sizes().maxCoeff() / 0.16, 1e-12);
  haptics::LoopSettings settings;
  fitted.ApplyTo(&settings);
  EXPECT_EQ(settings.world_scale, fitted.map.world_scale);
  EXPECT_EQ(settings.p_WDo, fitted.map.p_WDo);

  SceneHapticsOptions given;
  given.world_scale = 1.5;
  SceneHaptics half = BuildHapticScene(scene, given);
  EXPECT_EQ(half.map.world_scale, 1.5);
  EXPECT_FALSE(half.map.scale_fitted);
  EXPECT_TRUE(half.map.origin_fitted);
  EXPECT_EQ(half.map.p_WDo, fitted.map.p_WDo);

  SceneHapticsOptions bad;
  bad.stiffness = -1;
  EXPECT_THROW(BuildHapticScene(scene, bad), std::invalid_argument);
}

TEST(BuildHapticScene, ShellToolPressedIntoThePlateIsPushedUpAndFeelsNoForceInFreeSpace) {
  const modeling::Scene scene = modeling::LoadScene(Source("assets/scenes/platform.json"));
  SceneHapticsOptions options;
  options.tool = ToolModel::kShell;
  options.world_scale = 1.0;
  options.p_WDo = Eigen::Vector3d::Zero();
  SceneHaptics built = BuildHapticScene(scene, options);
  ASSERT_EQ(built.fields.size(), 1u);
  EXPECT_EQ(built.fields[0].kind, "point_shell");
  haptics::ToolKinematics tool;
  tool.p_WT = Eigen::Vector3d(0.15, 0.0, 0.05);  // 4 cm above the plate: poles at z = 0.05 ± 6 mm
  haptics::ToolWrench w;
  for (int k = 0; k < 200; ++k) {
    tool.time = 1e-3 * k;
    w = built.scene->Evaluate(tool);
  }
  EXPECT_LT(w.f_T_W.norm(), 1e-9);
  // Grip centre 3 mm below the top face + radius: the capsules sink 3 mm into the plate; the
  // virtual tool stops on the face and the coupling pushes the grip up, without moment (the
  // cross is symmetric about its centre).
  // Lowered at 10 cm/s (a hand's pace; a jump would fling V through the 1 cm plate).
  const double z_end = 0.01 + 0.006 - 0.003;
  for (int k = 200; k < 1200; ++k) {
    tool.time = 1e-3 * k;
    tool.p_WT.z() = std::max(z_end, 0.05 - 1e-4 * (k - 200));
    tool.v_WT.z() = tool.p_WT.z() > z_end ? -0.1 : 0.0;
    w = built.scene->Evaluate(tool);
  }
  EXPECT_GT(w.f_T_W.z(), 0.5);
  EXPECT_LT(w.f_T_W.head<2>().norm(), 0.05 * w.f_T_W.z());
  EXPECT_LT(w.m_T_W.norm(), 1e-3);
}

TEST(RunCommandScene, WritesTheColumnsAndForceOnlyInContactAlongThePlateNormal) {
  const std::string out = spidarcad::test_support::TestOutputPath("scene_run_platform_press.csv");
  const auto run = spidarcad::test_support::RunSpidarcad(
      "run '" + Source("assets/scenes/platform.json") + "' --trajectory '" +
          Source("assets/trajectories/press.csv") + "' --world-scale 1 --world-origin 0.1,0,0.04 --out '" +
          out + "'",
      "", "scene_press");
  ASSERT_EQ(run.status, 0) << run.err;
  EXPECT_NE(run.out.find("fields: proxy 'platform', proxy 'wall'"), std::string::npos) << run.out;
  EXPECT_NE(run.out.find("X_WD: p_W = 1 p_D + (0.1, 0, 0.04) m"), std::string::npos) << run.out;
  const auto table = spidarcad::test_support::ReadCsvTable(out);
  for (const char* c : {"t", "x", "y", "z", "qw", "qx", "qy", "qz", "grasp", "fx", "fy", "fz", "mx",
                        "my", "mz", "g", "tau1", "tau8", "tick_us", "fk_z"}) {
    ASSERT_GE(table.Column(c), 0) << c;
  }
  ASSERT_EQ(table.rows.size(), 3001u);
  const int fx = table.Column("fx"), fz = table.Column("fz"), fk_z = table.Column("fk_z");
  const int t = table.Column("t");
  int in_contact = 0, held = 0;
  for (const auto& row : table.rows) {
    // Depth below the top face z_W = 0.01, from the measured grip (what the loop used).
    const double depth = 0.01 - (row[fk_z] + 0.04);
    const double f = Eigen::Vector3d(row[fx], row[fx + 1], row[fz]).norm();
    if (depth < -1e-6) {
      ASSERT_EQ(f, 0.0) << "force above the plate at t " << row[t];
    }
    if (f > 0) {
      // Pushes out (the normal damping may cancel the spring, never pull in); friction within
      // μs = 0.3 of the spring's normal force k × depth (plus the tangential damping-free slack
      // of the encoder noise, 0.01 N).
      ++in_contact;
      EXPECT_GE(row[fz], 0.0);
      EXPECT_LT(std::hypot(row[fx], row[fx + 1]), 0.3 * 1500.0 * std::max(depth, 0.0) + 0.01)
          << "t " << row[t];
    }
    if (row[t] > 1.8 && row[t] < 2.1) {  // holding still at the bottom: k × depth
      EXPECT_NEAR(row[fz], 1500.0 * depth, 0.03) << "t " << row[t];
      ++held;
    }
  }
  EXPECT_GT(in_contact, 500);
  EXPECT_GT(held, 250);
}

TEST(RunCommandScene, BadSceneOrToolExitsTwoNamingTheFileOrOption) {
  const std::string out = spidarcad::test_support::TestOutputPath("scene_run_bad.csv");
  const std::string traj = Source("assets/trajectories/press.csv");
  auto r = spidarcad::test_support::RunSpidarcad(
      "run /nonexistent/scene.json --trajectory '" + traj + "' --out '" + out + "'", "", "missing");
  EXPECT_EQ(r.status, 2);
  EXPECT_NE(r.err.find("/nonexistent/scene.json"), std::string::npos) << r.err;
  const std::string bad = spidarcad::test_support::TestOutputPath("scene_bad_radius.json");
  std::ofstream(bad) << R"({"format": "spidarcad-scene", "version": 1, "solids": [
  {"name": "ball", "root": {"type": "sphere", "radius": -0.02}}]})";
  r = spidarcad::test_support::RunSpidarcad(
      "run '" + bad + "' --trajectory '" + traj + "' --out '" + out + "'", "", "bad_radius");
  EXPECT_EQ(r.status, 2);
  EXPECT_NE(r.err.find(bad), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("/solids/0/root/radius"), std::string::npos) << r.err;
  r = spidarcad::test_support::RunSpidarcad(
      "run '" + Source("assets/scenes/clay.json") + "' --tool hammer --trajectory '" + traj +
          "' --out '" + out + "'", "", "bad_tool");
  EXPECT_EQ(r.status, 2);
  EXPECT_NE(r.err.find("--tool: 'hammer'"), std::string::npos) << r.err;
}

}  // namespace
