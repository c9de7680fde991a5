// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
// Tests of the runtime adapters (app/src/runtime): solids as distance fields, scenes as haptic
// force fields with their device-to-scene map, and `spidarcad run` on a scene file. Expected
// values are closed forms (a sphere's distance, a plate face's spring law k × depth, the fit's
// formula applied to known boxes), not the code's own output.
#include "scene/scene_haptics.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <fstream>
#include <memory>
#include <random>
#include <string>

#include "golden_compare.h"
#include "scene/snap_features.h"
#include "scene/solid_distance_field.h"
#include "spidarcad/haptics/force_field.h"
#include "spidarcad/haptics/proxy_field.h"
#include "spidarcad/haptics/snap_field.h"
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
    const haptics::ToolWrench w =
        PressPlate(fresh.scene.get(), Eigen::Vector3d(0.15, 0.05, 0.03), depth);
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
  const haptics::ToolWrench w =
      PressPlate(built.scene.get(), Eigen::Vector3d(0.15, 0.05, 0.03), depth_W);
  // Felt: k × grip depth = 1200 × (0.003 / 2.5) N.
  EXPECT_NEAR(w.f_T_W.z(), 1200.0 * depth_W / 2.5, 1e-5);
}

TEST(FitWorkspace, MapsTheScenesBoxIntoTheDeviceCubeCentredAndFillingTheFraction) {
  const Eigen::AlignedBox3d box(Eigen::Vector3d(-0.05, -0.3, -0.3), Eigen::Vector3d(0.3, 0.3, 0.2));
  const auto map = FitWorkspace(box, 0.1, 0.8);
  EXPECT_NEAR(map.X_WD.world_scale, 0.6 / 0.16, 1e-12);
  EXPECT_TRUE(map.X_WD.p_WDo.isApprox(Eigen::Vector3d(0.125, 0.0, -0.05)));
  // Every corner maps into the cube, and the largest side spans exactly 0.16 m of grip motion.
  for (int i = 0; i < 8; ++i) {
    const Eigen::Vector3d corner = box.corner(static_cast<Eigen::AlignedBox3d::CornerType>(i));
    const Eigen::Vector3d p_D = (corner - map.X_WD.p_WDo) / map.X_WD.world_scale;
    EXPECT_LE(p_D.cwiseAbs().maxCoeff(), 0.08 + 1e-12);
  }
  EXPECT_NEAR((box.max().y() - box.min().y()) / map.X_WD.world_scale, 0.16, 1e-12);
  // A 4 cm part is magnified: s < 1.
  const auto small = FitWorkspace(
      Eigen::AlignedBox3d(Eigen::Vector3d::Constant(0.0), Eigen::Vector3d::Constant(0.04)), 0.1,
      0.8);
  EXPECT_NEAR(small.X_WD.world_scale, 0.25, 1e-12);
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
  EXPECT_NEAR(fitted.map.X_WD.world_scale, b.sizes().maxCoeff() / 0.16, 1e-12);
  haptics::LoopSettings settings;
  fitted.ApplyTo(&settings);
  EXPECT_EQ(settings.X_WD.world_scale, fitted.map.X_WD.world_scale);
  EXPECT_EQ(settings.X_WD.p_WDo, fitted.map.X_WD.p_WDo);

  SceneHapticsOptions given;
  given.world_scale = 1.5;
  SceneHaptics half = BuildHapticScene(scene, given);
  EXPECT_EQ(half.map.X_WD.world_scale, 1.5);
  EXPECT_FALSE(half.map.scale_fitted);
  EXPECT_TRUE(half.map.origin_fitted);
  EXPECT_EQ(half.map.X_WD.p_WDo, fitted.map.X_WD.p_WDo);

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
          Source("assets/trajectories/press.csv") +
          "' --world-scale 1 --world-origin 0.1,0,0.04 --out '" + out + "'",
      "", "scene_press");
  ASSERT_EQ(run.status, 0) << run.err;
  EXPECT_NE(run.out.find("fields: proxy 'platform', proxy 'wall'"), std::string::npos) << run.out;
  EXPECT_NE(run.out.find("X_WD: p_W = 1 p_D + (0.1, 0, 0.04) m"), std::string::npos) << run.out;
  const auto table = spidarcad::test_support::ReadCsvTable(out);
  for (const char* c : {"t",  "x",  "y",  "z",  "qw", "qx", "qy",   "qz",   "grasp",   "fx",
                        "fy", "fz", "mx", "my", "mz", "g",  "tau1", "tau8", "tick_us", "fk_z"}) {
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
  r = spidarcad::test_support::RunSpidarcad("run '" + Source("assets/scenes/clay.json") +
                                                "' --tool hammer --trajectory '" + traj +
                                                "' --out '" + out + "'",
                                            "", "bad_tool");
  EXPECT_EQ(r.status, 2);
  EXPECT_NE(r.err.find("--tool: 'hammer'"), std::string::npos) << r.err;
}

}  // namespace

namespace {

using spidarcad::app::CountSnapFeatures;
using spidarcad::app::ExtractSnapFeatures;

modeling::Scene Parse(const std::string& solids, const std::string& extra = "") {
  return modeling::ParseScene(R"({"format": "spidarcad-scene", "version": 1, )" + extra +
                              R"("solids": )" + solids + "}");
}

// True when `set` holds a point within 1e-9 m of p.
bool Holds(const std::vector<Eigen::Vector3d>& set, const Eigen::Vector3d& p) {
  return std::any_of(set.begin(), set.end(),
                     [&](const Eigen::Vector3d& q) { return (p - q).norm() < 1e-9; });
}

TEST(SnapFeatures, RotatedMovedBoxHasItsEightCornersTwelveEdgesAndSixFaces) {
  // A 40 x 20 x 10 mm box turned 30° about z and moved to (0.1, 0.05, -0.02): corners by hand.
  const modeling::Scene scene = Parse(R"([{"name": "b", "root": {"type": "translate",
      "translation": [0.1, 0.05, -0.02], "children": [{"type": "rotate", "axis": [0, 0, 1],
      "angle": 0.5235987755982988, "children": [{"type": "box", "size": [0.04, 0.02, 0.01]}]}]}}])");
  const haptics::SnapFeatures f = ExtractSnapFeatures(scene);
  ASSERT_EQ(f.vertices_W.size(), 8u);
  ASSERT_EQ(f.edges_W.size(), 12u);
  ASSERT_EQ(f.faces_W.size(), 6u);
  const double c = std::cos(M_PI / 6), s = std::sin(M_PI / 6);
  for (int i = 0; i < 8; ++i) {
    const double x = (i & 1 ? 0.02 : -0.02), y = (i & 2 ? 0.01 : -0.01),
                 z = (i & 4 ? 0.005 : -0.005);
    const Eigen::Vector3d corner(0.1 + c * x - s * y, 0.05 + s * x + c * y, -0.02 + z);
    EXPECT_TRUE(Holds(f.vertices_W, corner)) << "corner " << corner.transpose();
  }
  // Edges: four of each length, both ends at corners.
  int lengths[3] = {0, 0, 0};
  for (const auto& [a, b] : f.edges_W) {
    EXPECT_TRUE(Holds(f.vertices_W, a) && Holds(f.vertices_W, b));
    const double l = (b - a).norm();
    for (int k = 0; k < 3; ++k)
      lengths[k] += std::abs(l - std::array<double, 3>{0.04, 0.02, 0.01}[k]) < 1e-12;
  }
  EXPECT_EQ(lengths[0], 4);
  EXPECT_EQ(lengths[1], 4);
  EXPECT_EQ(lengths[2], 4);
  // Faces: rectangles of corners; their areas are the box's, two of each.
  double area_sum = 0;
  for (const haptics::SnapFace& face : f.faces_W) {
    ASSERT_EQ(face.polygon_W.size(), 4u);
    for (const Eigen::Vector3d& p : face.polygon_W) EXPECT_TRUE(Holds(f.vertices_W, p));
    area_sum +=
        (face.polygon_W[1] - face.polygon_W[0]).cross(face.polygon_W[3] - face.polygon_W[0]).norm();
  }
  EXPECT_NEAR(area_sum, 2 * (0.04 * 0.02 + 0.04 * 0.01 + 0.02 * 0.01), 1e-15);
}

TEST(SnapFeatures, KeepsOnlyFeaturesOnTheSurfaceAndEachOnce) {
  // A 20 mm cube with a 10 mm cube cut out of its (+,+,+) corner: the cube keeps 7 corners (the
  // cut one is gone), the cutter gives its one corner inside the cube (5, 5, 5) mm; of the
  // cutter's edges, the three from that corner are half inside, half out: dropped.
  const modeling::Scene notch = Parse(R"([{"name": "n", "root": {"type": "difference", "children": [
      {"type": "box", "size": [0.02, 0.02, 0.02]},
      {"type": "translate", "translation": [0.01, 0.01, 0.01],
       "children": [{"type": "box", "size": [0.01, 0.01, 0.01]}]}]}}])");
  const haptics::SnapFeatures f = ExtractSnapFeatures(notch);
  ASSERT_EQ(f.vertices_W.size(), 8u);
  EXPECT_FALSE(Holds(f.vertices_W, Eigen::Vector3d(0.01, 0.01, 0.01)));
  EXPECT_TRUE(Holds(f.vertices_W, Eigen::Vector3d(0.005, 0.005, 0.005)));
  EXPECT_TRUE(Holds(f.vertices_W, Eigen::Vector3d(-0.01, -0.01, -0.01)));
  // Cube edges not touching the notch: the 12 minus the 3 through the cut corner.
  EXPECT_EQ(f.edges_W.size(), 9u);
  // Faces: the cube's three faces away from the notch. The three it cuts lose a quarter: their
  // test point 90 % of the way to the cut corner, (10, 9, 9) mm and alike, is in the air. The
  // cutter's faces reach outside the cube.
  EXPECT_EQ(f.faces_W.size(), 3u);
  for (const haptics::SnapFace& face : f.faces_W) {
    Eigen::Vector3d centroid = Eigen::Vector3d::Zero();
    for (const Eigen::Vector3d& p : face.polygon_W) centroid += p / 4.0;
    EXPECT_NEAR(centroid.minCoeff(), -0.01, 1e-12) << "a face away from the notch is at -10 mm";
  }
  // A box straddling a keep_original mirror plane maps onto itself: each feature once.
  const modeling::Scene mirrored = Parse(R"([{"name": "m", "root": {"type": "mirror",
      "normal": [1, 0, 0], "keep_original": true,
      "children": [{"type": "box", "size": [0.02, 0.01, 0.01]}]}}])");
  const spidarcad::app::SnapFeatureCounts counts = CountSnapFeatures(ExtractSnapFeatures(mirrored));
  EXPECT_EQ(counts.ToString(), "8 vertices, 12 edges, 6 faces");
  // Spheres have no features.
  EXPECT_EQ(CountSnapFeatures(ExtractSnapFeatures(SphereScene())).ToString(),
            "0 vertices, 0 edges, 0 faces");
}

TEST(BuildHapticScene, SnapSceneAddsASnapFieldPullingTowardTheCornerWithTheDocumentedProfile) {
  const std::string box = R"([{"name": "b", "root": {"type": "box", "size": [0.04, 0.04, 0.04]}}])";
  SceneHapticsOptions options;
  options.world_scale = 1.0;
  options.p_WDo = Eigen::Vector3d::Zero();
  // Without "snap": the proxy only.
  EXPECT_EQ(BuildHapticScene(Parse(box), options).fields.size(), 1u);
  SceneHaptics built = BuildHapticScene(
      Parse(
          box,
          R"("snap": {"max_force": 0.8, "vertex_radius": 0.01, "edge_radius": 0.006, "face_radius": 0.004}, )"),
      options);
  ASSERT_EQ(built.fields.size(), 2u);
  EXPECT_EQ(built.fields[1].kind, "snap");
  EXPECT_EQ(built.fields[1].solid, "8 vertices, 12 edges, 6 faces");
  // Outside the box, 3 mm from the corner (0.02, 0.02, 0.02) along the diagonal: only the vertex
  // pulls (within half its radius), toward the corner, 0.8 N · tanh(4d/r) · w(d),
  // w = 1 (d < r/2). The proxy is out of contact.
  const Eigen::Vector3d corner(0.02, 0.02, 0.02);
  const Eigen::Vector3d u = Eigen::Vector3d::Ones().normalized();
  for (double d : {0.001, 0.003, 0.0045}) {
    haptics::ToolKinematics tool;
    tool.p_WT = corner + d * u;
    const haptics::ToolWrench w = built.scene->Evaluate(tool);
    const double expected = 0.8 * std::tanh(4.0 * d / 0.01);
    EXPECT_NEAR(w.f_T_W.norm(), expected, 1e-9) << "d " << d;
    EXPECT_NEAR(w.f_T_W.normalized().dot(-u), 1.0, 1e-9) << "d " << d;
  }
}

TEST(SnapFeatures, PrismCylinderAndPlaneGiveTheirFeaturesAndHugeArraysAreRefused) {
  // A right triangle (legs 30 and 20 mm) extruded 10 mm: 6 vertices, 9 edges, 3 sides + 2 caps.
  const modeling::Scene prism = Parse(R"([{"name": "p", "root": {"type": "extrusion",
      "profile": [[0, 0], [0.03, 0], [0, 0.02]], "height": 0.01}}])");
  const haptics::SnapFeatures f = ExtractSnapFeatures(prism);
  EXPECT_EQ(CountSnapFeatures(f).ToString(), "6 vertices, 9 edges, 5 faces");
  EXPECT_TRUE(Holds(f.vertices_W, Eigen::Vector3d(0.03, 0, 0.005)));
  EXPECT_TRUE(Holds(f.vertices_W, Eigen::Vector3d(0, 0.02, -0.005)));
  // A cylinder: its two rims as chords (every chord end on the circle r = 10 mm), two caps.
  const modeling::Scene post =
      Parse(R"([{"name": "c", "root": {"type": "cylinder", "radius": 0.01, "height": 0.02}}])");
  const haptics::SnapFeatures c = ExtractSnapFeatures(post);
  EXPECT_EQ(
      CountSnapFeatures(c).ToString(),
      "0 vertices, " + std::to_string(2 * spidarcad::app::kCylinderSegments) + " edges, 2 faces");
  for (const auto& [a, b] : c.edges_W) {
    EXPECT_NEAR(a.head<2>().norm(), 0.01, 1e-12);
    EXPECT_NEAR(std::abs(a.z()), 0.01, 1e-12);
    EXPECT_NEAR(b.z(), a.z(), 1e-12);
  }
  // A half-space turned by 90° about x: the plane y = -0.05 (normal (0, -1, 0) after the turn of
  // the normal (0, 0, 1)), as one unbounded face.
  const modeling::Scene ground =
      Parse(R"([{"name": "g", "root": {"type": "rotate", "axis": [1, 0, 0],
      "angle": 1.5707963267948966, "children": [{"type": "half_space", "normal": [0, 0, 1], "offset": 0.05}]}}])");
  const haptics::SnapFeatures g = ExtractSnapFeatures(ground);
  ASSERT_EQ(g.faces_W.size(), 1u);
  EXPECT_TRUE(g.faces_W[0].polygon_W.empty());
  EXPECT_NEAR(std::abs(g.faces_W[0].normal_W.y()), 1.0, 1e-12);
  EXPECT_NEAR(g.faces_W[0].point_W.y(), -0.05, 1e-12);
  // 300 separate boxes: 2400 corners alone, more than a tick can scan: refused, saying so.
  const modeling::Scene many =
      Parse(R"([{"name": "m", "root": {"type": "linear_array", "step": [0.01, 0, 0],
      "count": 300, "children": [{"type": "box", "size": [0.005, 0.005, 0.005]}]}}])");
  try {
    ExtractSnapFeatures(many);
    ADD_FAILURE() << "no error for 300 boxes";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(
        std::string(e.what()).find("7800 snap features (2400 vertices, 3600 edges, 1800 faces)"),
        std::string::npos)
        << e.what();
  }
}

}  // namespace
