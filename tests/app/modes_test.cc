// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
// Tests of the window's modes without a window (gui/modes.h): the squeeze detector on synthetic
// grasp histories, the solid the tool touches (against the solids' closed forms), and the
// modelling mode's selection by touch (Enter or a squeeze) with the snapped feature of a snap
// scene, checked against the box's own corner.
#include "gui/modes.h"

#include <gtest/gtest.h>
#include <vtkActor.h>
#include <vtkMapper.h>
#include <vtkPolyData.h>

#include <Eigen/Geometry>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <numbers>
#include <string>
#include <vector>

#include "doc/job.h"
#include "gui/tree_panel.h"
#include "gui/workbench_panels.h"
#include "scene/grip_control.h"
#include "scene/scene_model.h"

namespace spidarcad::app {
namespace {

constexpr double kDeg = std::numbers::pi / 180.0;

// Feeds θ(t) sampled every `dt` s from t0 to t1; returns how many squeezes fired.
template <typename Grasp>
int Squeezes(SqueezeDetector* d, Grasp grasp, double t0, double t1, double dt = 1.0 / 60.0) {
  int fired = 0;
  for (double t = t0; t <= t1 + 1e-12; t += dt) fired += d->Update(t, grasp(t)) ? 1 : 0;
  return fired;
}

// A triangle pulse: from θ0 down by `depth` over `close` s, back up over `open` s.
auto Pulse(double start, double close, double open, double depth) {
  return [=](double t) {
    const double theta0 = 90.0 * kDeg;
    if (t < start || t > start + close + open) return theta0;
    if (t < start + close) return theta0 - depth * (t - start) / close;
    return theta0 - depth + depth * (t - start - close) / open;
  };
}

TEST(SqueezeDetector, FiresOnceForAQuickDeepSqueezeAndNotForSlowOrShallowOnes) {
  SqueezeDetector quick;
  EXPECT_EQ(Squeezes(&quick, Pulse(0.2, 0.15, 0.15, 20 * kDeg), 0.0, 2.0), 1);
  SqueezeDetector slow;  // 0.3 s closing + 0.3 s opening: longer than 0.4 s
  EXPECT_EQ(Squeezes(&slow, Pulse(0.2, 0.3, 0.3, 20 * kDeg), 0.0, 2.0), 0);
  SqueezeDetector shallow;  // 8°: less than 10°
  EXPECT_EQ(Squeezes(&shallow, Pulse(0.2, 0.1, 0.1, 8 * kDeg), 0.0, 2.0), 0);
  SqueezeDetector closing_only;  // closes and stays closed (a grasp, not a squeeze)
  EXPECT_EQ(Squeezes(
                &closing_only,
                [](double t) { return (90.0 - 30.0 * std::min(t, 0.2) / 0.2) * kDeg; }, 0.0, 2.0),
            0);
  SqueezeDetector twice;
  const auto a = Pulse(0.2, 0.1, 0.1, 15 * kDeg), b = Pulse(1.0, 0.1, 0.1, 15 * kDeg);
  EXPECT_EQ(Squeezes(
                &twice, [&](double t) { return std::min(a(t), b(t)); }, 0.0, 2.0),
            2);
}

// The built-in demo scene in device coordinates (X_WD = identity).
struct DemoScene {
  SceneModel model;
  DemoScene() {
    const DeviceToWorld identity;
    model.Load(kDemoSceneName, GripControl(haptics::SpidarGeometry{}).limits(), &identity);
  }
  int Index(const std::string& name) const {
    for (int i = 0; i < static_cast<int>(model.objects().size()); ++i) {
      if (model.objects()[i].name == name) return i;
    }
    return -1;
  }
};

TEST(TouchedObject, FindsTheSolidUnderTheToolWithinTheMarginAndNoneFarAway) {
  DemoScene d;
  const int knob = d.Index("knob");
  ASSERT_GE(knob, 0);
  // The knob: a sphere of radius 35 mm at (80, 30, −85) mm (DemoSceneJson).
  const Eigen::Vector3d centre(0.08, 0.03, -0.085);
  const double r = 0.035;
  EXPECT_EQ(TouchedObject(d.model, {centre}, 0.004), knob);
  const Eigen::Vector3d out(0.0, 0.0, 1.0);
  EXPECT_EQ(TouchedObject(d.model, {centre + (r + 0.003) * out}, 0.004), knob);  // 3 mm off
  EXPECT_EQ(TouchedObject(d.model, {centre + (r + 0.006) * out}, 0.004), -1);    // 6 mm off
  // Several points: the nearest solid over all of them.
  EXPECT_EQ(TouchedObject(d.model, {Eigen::Vector3d(0.3, 0.3, 0.3), centre}, 0.004), knob);
  EXPECT_EQ(TouchedObject(d.model, {Eigen::Vector3d(0.3, 0.3, 0.3)}, 0.004), -1);
}

// A 40 mm cube centred at the origin with snap forces, in device coordinates.
std::string WriteSnapBox() {
  const std::string path = std::string(SPIDARCAD_TEST_OUTPUT_DIR) + "/modes_snap_box.json";
  std::ofstream(path) << R"({"format": "spidarcad-scene", "version": 1,
    "snap": {"max_force": 0.8, "vertex_radius": 0.01, "edge_radius": 0.006, "face_radius": 0.004},
    "solids": [{"name": "cube", "root": {"type": "box", "size": [0.04, 0.04, 0.04]}},
               {"name": "ball", "root": {"type": "translate", "translation": [0.12, 0, 0],
                "children": [{"type": "sphere", "radius": 0.02}]}}]})";
  return path;
}

haptics::ToolState ToolAt(const Eigen::Vector3d& p, double grasp, double time) {
  haptics::ToolState tool;
  tool.time = time;
  tool.tool_W.p_WT = p;
  tool.tool_W.time = time;
  tool.tool_W.grasp = grasp;
  tool.pose_D = haptics::GripPose::FromFrame(p, Eigen::Matrix3d::Identity(), grasp,
                                             haptics::SpidarGeometry{}.d);
  return tool;
}

TEST(ModelMode, EnterSelectsTheTouchedSolidAndHighlightsTheSnappedCorner) {
  SceneModel model;
  const DeviceToWorld identity;
  model.Load(WriteSnapBox(), Eigen::Vector3d::Constant(0.19), &identity);
  TreeController tree(&model);
  tree.Select(model.objects()[1].id);  // the ball
  WorkbenchState workbench;
  DemoFieldSettings springs;
  ModelMode mode(nullptr, &springs, 0.04);
  mode.Enter();
  ModeContext context;
  context.model = &model;
  context.tree = &tree;
  context.workbench = &workbench;
  // 1 mm inside the corner (0.02, 0.02, 0.02), along the diagonal: the cube is touched, the
  // vertex snaps (within half its 10 mm radius).
  const Eigen::Vector3d corner(0.02, 0.02, 0.02);
  const Eigen::Vector3d p = corner - 0.001 * Eigen::Vector3d::Ones().normalized();
  mode.Update(ToolAt(p, 90 * kDeg, 1.0), context);
  EXPECT_EQ(tree.selection()->object, model.objects()[1].id) << "no key: nothing selected yet";
  ASSERT_EQ(mode.snapped().kind, haptics::SnapKind::kVertex);
  // The highlight shows exactly that corner.
  vtkPolyData* shown = vtkPolyData::SafeDownCast(mode.highlight()->GetMapper()->GetInput());
  ASSERT_NE(shown, nullptr);
  ASSERT_EQ(shown->GetNumberOfPoints(), 1);
  double q[3];
  shown->GetPoint(0, q);
  EXPECT_NEAR((Eigen::Vector3d(q[0], q[1], q[2]) - corner).norm(), 0.0, 1e-9);
  EXPECT_TRUE(mode.highlight()->GetVisibility());
  // Enter: the cube is selected, with its corner.
  context.select_key = true;
  mode.Update(ToolAt(p, 90 * kDeg, 1.02), context);
  context.select_key = false;
  ASSERT_TRUE(tree.selection().has_value());
  EXPECT_EQ(tree.selection()->object, model.objects()[0].id);
  EXPECT_EQ(workbench.selected, 0);
  EXPECT_EQ(mode.selected_feature().kind, haptics::SnapKind::kVertex);
  EXPECT_NE(mode.touch_message().find("'cube'"), std::string::npos) << mode.touch_message();
  // Leaving the mode hides the highlight.
  mode.Leave();
  EXPECT_FALSE(mode.highlight()->GetVisibility());
}

TEST(ModelMode, ASqueezeOfTheGraspSelectsTheTouchedSolidAndEnterFarFromAnySolidDoesNot) {
  SceneModel model;
  const DeviceToWorld identity;
  model.Load(WriteSnapBox(), Eigen::Vector3d::Constant(0.19), &identity);
  TreeController tree(&model);
  tree.Select(model.objects()[0].id);  // the cube
  WorkbenchState workbench;
  DemoFieldSettings springs;
  ModelMode mode(nullptr, &springs, 0.04);
  mode.Enter();
  ModeContext context;
  context.model = &model;
  context.tree = &tree;
  context.workbench = &workbench;
  // Enter in the air: nothing changes.
  context.select_key = true;
  mode.Update(ToolAt(Eigen::Vector3d(0.06, 0.1, 0.1), 90 * kDeg, 0.5), context);
  context.select_key = false;
  EXPECT_EQ(tree.selection()->object, model.objects()[0].id);
  EXPECT_NE(mode.touch_message().find("touches no solid"), std::string::npos);
  // On the ball's top (radius 20 mm at x = 120 mm), a 20° squeeze in 0.3 s at 60 frames/s.
  const Eigen::Vector3d top(0.12, 0.0, 0.0195);
  const auto grasp = Pulse(1.0, 0.15, 0.15, 20 * kDeg);
  for (double t = 0.9; t < 1.5; t += 1.0 / 60.0) mode.Update(ToolAt(top, grasp(t), t), context);
  EXPECT_EQ(tree.selection()->object, model.objects()[1].id);
  EXPECT_NE(mode.touch_message().find("squeeze"), std::string::npos) << mode.touch_message();
  EXPECT_EQ(mode.selected_feature().kind, haptics::SnapKind::kNone);  // a sphere has none
}

}  // namespace
}  // namespace spidarcad::app
