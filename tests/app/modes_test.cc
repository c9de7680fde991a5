// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
// Tests of the window's modes without a window (gui/modes.h; the squeeze detector's tests are in
// touch_session_test.cc): the solid the tool touches (against the solids' closed forms), and the
// modelling mode's selection by touch (Enter or a squeeze) with the snapped feature of a snap
// scene, checked against the box's own corner; modelling by touch: a primitive placed by a
// squeeze or by P (one command, its pose the ghost's, aligned to the cube's face as worked out by
// hand, its size the grasp's before the squeeze), and a node grabbed, moved and turned, let go as
// one undo step whose undo and redo restore the document exactly.
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

// A triangle pulse: from θ0 down by `depth` over `close` s, back up over `open` s.
auto Pulse(double start, double close, double open, double depth) {
  return [=](double t) {
    const double theta0 = 90.0 * kDeg;
    if (t < start || t > start + close + open) return theta0;
    if (t < start + close) return theta0 - depth * (t - start) / close;
    return theta0 - depth + depth * (t - start - close) / open;
  };
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

haptics::ToolState ToolAt(const Eigen::Vector3d& p, double grasp, double time,
                          const Eigen::Matrix3d& R = Eigen::Matrix3d::Identity()) {
  haptics::ToolState tool;
  tool.time = time;
  tool.tool_W.p_WT = p;
  tool.tool_W.R_WT = R;
  tool.tool_W.time = time;
  tool.tool_W.grasp = grasp;
  tool.pose_D = haptics::GripPose::FromFrame(p, R, grasp, haptics::SpidarGeometry{}.d);
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

// The modelling mode on the snap box, with the tree and the workbench (no window).
struct TouchFixture {
  SceneModel model;
  TreeController tree{&model};
  WorkbenchState workbench;
  DemoFieldSettings springs;
  ModelMode mode{nullptr, &springs, 0.04};
  ModeContext context;
  TouchFixture() {
    const DeviceToWorld identity;
    model.Load(WriteSnapBox(), Eigen::Vector3d::Constant(0.19), &identity);
    tree.Select(model.objects()[0].id);
    mode.Enter();
    context.model = &model;
    context.tree = &tree;
    context.workbench = &workbench;
  }
};

TEST(ModelMode, ASqueezeWhilePlacingAddsTheGhostAsOneSolidRestingOnTheFaceBelow) {
  TouchFixture f;
  Document& doc = f.model.document();
  f.mode.SetPlacing(PlaceKind::kBox);
  const double c = PlaceSize(90 * kDeg, 0.04, 1.0);  // the grasp at rest: 62.8 mm
  // 2 mm above resting on the cube's top face (z = 20 mm), tilted 8° about y.
  const Eigen::Vector3d p(0.005, -0.003, 0.02 + c / 2 + 0.002);
  const Eigen::Matrix3d R =
      Eigen::AngleAxisd(8 * kDeg, Eigen::Vector3d::UnitY()).toRotationMatrix();
  const auto grasp = Pulse(1.0, 0.15, 0.15, 20 * kDeg);
  for (double t = 0.0; t < 0.9; t += 1.0 / 60.0)
    f.mode.Update(ToolAt(p, grasp(t), t, R), f.context);
  EXPECT_NEAR(f.mode.ghost_size(), c, 1e-15);
  EXPECT_EQ(f.mode.ghost().kind, AlignKind::kFace);
  EXPECT_EQ(doc.history().undo_size(), 0u) << "nothing placed before the squeeze";
  // The face is outlined (a closed square: 5 points).
  vtkPolyData* shown = vtkPolyData::SafeDownCast(f.mode.highlight()->GetMapper()->GetInput());
  ASSERT_NE(shown, nullptr);
  EXPECT_EQ(shown->GetNumberOfPoints(), 5);
  EXPECT_TRUE(f.mode.highlight()->GetVisibility());
  // Felt: the scene gains the snap field, whose face (lifted by c/2) pulls the grip down by
  // F_max·tanh(d/d_s) at d = 2 mm (d_s = 6 mm / 4; SnapField's profile, full weight there).
  f.springs.enabled = false;
  EXPECT_TRUE(f.mode.TakeSceneChanged());
  const auto scene = f.mode.BuildScene(f.context);
  haptics::ToolKinematics at;
  at.p_WT = p;
  at.R_WT = R;
  const haptics::ToolWrench pull = scene->Evaluate(at);
  EXPECT_NEAR(pull.f_T_W.z(), -0.8 * std::tanh(0.002 / 0.0015), 1e-9);
  EXPECT_NEAR(pull.f_T_W.head<2>().norm(), 0.0, 1e-9);
  for (double t = 0.9; t < 1.6; t += 1.0 / 60.0)
    f.mode.Update(ToolAt(p, grasp(t), t, R), f.context);
  ASSERT_EQ(doc.history().undo_size(), 1u);
  EXPECT_EQ(doc.history().UndoDescription(), "Add solid box");
  const DocObject* box = doc.FindByName("box");
  ASSERT_NE(box, nullptr);
  EXPECT_EQ(f.tree.selection()->object, box->id) << "the new solid is selected";
  const modeling::ImplicitNode& root = std::get<SolidData>(box->data).root;
  // Squared to the face, resting on it: centre c/2 above z = 20 mm; the size is the grasp's
  // before the squeeze (90°), not the squeezed one.
  const NodePose pose = PoseOfNode(root);
  EXPECT_LT((pose.X_AN.translation() - Eigen::Vector3d(0.005, -0.003, 0.02 + c / 2)).norm(), 1e-12);
  EXPECT_LT((pose.X_AN.linear() - Eigen::Matrix3d::Identity()).norm(), 1e-12);
  const auto& size = std::get<modeling::BoxParams>(root.children.front().children.front().params);
  EXPECT_LT((size.size - Eigen::Vector3d::Constant(c)).norm(), 1e-15);
  EXPECT_NE(f.mode.touch_message().find("aligned to face"), std::string::npos)
      << f.mode.touch_message();
}

TEST(ModelMode, PWhilePlacingAddsTheGhostAtTheGripPoseSizedByTheGraspNow) {
  TouchFixture f;
  Document& doc = f.model.document();
  f.mode.SetPlacing(PlaceKind::kCylinder);
  // In the air, far from every feature: no alignment, the grip's own pose.
  const Eigen::Vector3d p(-0.06, 0.07, 0.05);
  const Eigen::Matrix3d R =
      Eigen::AngleAxisd(0.6, Eigen::Vector3d(1, -2, 0.5).normalized()).toRotationMatrix();
  f.mode.Update(ToolAt(p, 120 * kDeg, 0.0, R), f.context);
  EXPECT_NEAR(f.mode.ghost_size(), PlaceSize(120 * kDeg, 0.04, 1.0), 1e-15);
  EXPECT_TRUE(f.mode.ghost_actor()->GetVisibility());
  f.mode.Update(ToolAt(p, 40 * kDeg, 0.02, R), f.context);  // the size follows the grasp
  const double c = PlaceSize(40 * kDeg, 0.04, 1.0);
  EXPECT_NEAR(f.mode.ghost_size(), c, 1e-15);
  f.context.place_key = true;
  f.mode.Update(ToolAt(p, 40 * kDeg, 0.04, R), f.context);
  f.context.place_key = false;
  ASSERT_EQ(doc.history().undo_size(), 1u);
  const modeling::ImplicitNode& root = std::get<SolidData>(doc.FindByName("cylinder")->data).root;
  const NodePose pose = PoseOfNode(root);
  EXPECT_LT((pose.X_AN.translation() - p).norm(), 1e-12);
  EXPECT_LT((pose.X_AN.linear() - R).norm(), 1e-12);
  const auto& cyl =
      std::get<modeling::CylinderParams>(root.children.front().children.front().params);
  EXPECT_NEAR(cyl.radius, c / 2, 1e-15);
  EXPECT_NEAR(cyl.height, c, 1e-15);
  // Disarmed: the ghost goes, P does nothing.
  f.mode.SetPlacing(std::nullopt);
  f.context.place_key = true;
  f.mode.Update(ToolAt(p, 40 * kDeg, 0.06, R), f.context);
  EXPECT_EQ(doc.history().undo_size(), 1u);
  EXPECT_FALSE(f.mode.ghost_actor()->GetVisibility());
}

TEST(ModelMode, AGrabMovedAndTurnedIsOneUndoStepThatUndoAndRedoRestoreExactly) {
  TouchFixture f;
  Document& doc = f.model.document();
  const ObjectId ball = f.model.objects()[1].id;
  f.tree.Select(ball);  // translate(0.12, 0, 0){sphere 20 mm}
  const nlohmann::json before = doc.ToJson(true);
  const std::uint64_t revision = doc.revision();
  // On the ball's top, then the grasp closes past 60°: grabbed.
  const Eigen::Vector3d top(0.12, 0.0, 0.0195);
  double t = 0.0;
  for (double g = 90; g >= 50; g -= 5, t += 1.0 / 60.0)
    f.mode.Update(ToolAt(top, g * kDeg, t), f.context);
  ASSERT_TRUE(f.mode.grabbing()) << f.mode.touch_message();
  // Moved 30 mm along y and 10 mm up while turning 30° about z, in 30 frames, held closed.
  const Eigen::Vector3d move(0.0, 0.03, 0.01);
  const double turn = 30 * kDeg;
  for (int k = 1; k <= 30; ++k, t += 1.0 / 60.0) {
    const double s = k / 30.0;
    f.mode.Update(ToolAt(top + s * move, 50 * kDeg, t,
                         Eigen::AngleAxisd(s * turn, Eigen::Vector3d::UnitZ()).toRotationMatrix()),
                  f.context);
  }
  EXPECT_EQ(doc.revision(), revision) << "the document changes only when the grab ends";
  // The node keeps its pose relative to the grip: X_WN = X_WT · X_WT0⁻¹ · X_WN0.
  Eigen::Isometry3d expected = Eigen::Isometry3d::Identity();
  expected.translation() = top + move;
  expected.linear() = Eigen::AngleAxisd(turn, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  expected = expected * Eigen::Translation3d(-top) * Eigen::Translation3d(0.12, 0, 0);
  EXPECT_EQ(f.mode.ghost().kind, AlignKind::kNone);
  EXPECT_LT((f.mode.ghost().X_WN.matrix() - expected.matrix()).norm(), 1e-12);
  // The grasp opens: let go, one command.
  for (double g = 55; g <= 90; g += 5, t += 1.0 / 60.0)
    f.mode.Update(ToolAt(top + move, g * kDeg, t,
                         Eigen::AngleAxisd(turn, Eigen::Vector3d::UnitZ()).toRotationMatrix()),
                  f.context);
  EXPECT_FALSE(f.mode.grabbing());
  ASSERT_EQ(doc.history().undo_size(), 1u);
  EXPECT_EQ(doc.history().UndoDescription(), "Move ball by touch");
  const NodePose pose = PoseOfNode(doc.Node(ball, {}));
  EXPECT_LT((pose.X_AN.matrix() - expected.matrix()).norm(), 1e-12);
  EXPECT_EQ(pose.depth, 2);
  const nlohmann::json after = doc.ToJson(true);
  ASSERT_TRUE(doc.Undo());
  EXPECT_EQ(doc.ToJson(true), before);
  ASSERT_TRUE(doc.Redo());
  EXPECT_EQ(doc.ToJson(true), after);
  // G grabs and lets go without moving: nothing changes.
  f.context.grab_key = true;
  f.mode.Update(ToolAt(top + move, 90 * kDeg, t), f.context);
  EXPECT_TRUE(f.mode.grabbing());
  f.mode.Update(ToolAt(top + move, 90 * kDeg, t + 0.02), f.context);
  f.context.grab_key = false;
  EXPECT_FALSE(f.mode.grabbing());
  EXPECT_EQ(doc.history().undo_size(), 1u);
}

TEST(ModelMode, ANodeUnderAScaleIsNotGrabbedAndUndoWaitsWhileANodeIsGrabbed) {
  TouchFixture f;
  Document& doc = f.model.document();
  const ObjectId ball = f.model.objects()[1].id;
  // translate{scale{sphere}}: the sphere is under a non-uniform scale.
  doc.Execute(edit::WrapNode(ball, {0}, modeling::ScaleParams{Eigen::Vector3d(1, 2, 1)}));
  f.model.Refresh();
  f.tree.Select(ball, {0, 0});
  f.context.grab_key = true;
  f.mode.Update(ToolAt(Eigen::Vector3d(0.12, 0, 0.05), 90 * kDeg, 0.0), f.context);
  EXPECT_FALSE(f.mode.grabbing());
  EXPECT_NE(f.mode.touch_message().find("scale or mirror"), std::string::npos)
      << f.mode.touch_message();
  // The whole ball can be grabbed; undo waits until it is let go.
  f.tree.Select(ball);
  f.tree.set_history_hold([&] { return f.mode.HistoryHold(); });
  f.mode.Update(ToolAt(Eigen::Vector3d(0.12, 0, 0.05), 90 * kDeg, 0.02), f.context);
  ASSERT_TRUE(f.mode.grabbing()) << f.mode.touch_message();
  EXPECT_FALSE(f.tree.Undo());
  EXPECT_NE(f.tree.error().find("let go of 'ball' first"), std::string::npos) << f.tree.error();
  EXPECT_EQ(doc.history().undo_size(), 1u);
  f.mode.Update(ToolAt(Eigen::Vector3d(0.12, 0, 0.05), 90 * kDeg, 0.04), f.context);
  f.context.grab_key = false;
  EXPECT_FALSE(f.mode.grabbing());
  EXPECT_EQ(f.mode.HistoryHold(), "");
  EXPECT_TRUE(f.tree.Undo()) << f.tree.error();
}

TEST(ModelMode, ClosingTheGraspAwayFromTheSelectedSolidGrabsNothing) {
  TouchFixture f;
  f.tree.Select(f.model.objects()[1].id);  // the ball; the grip is on the cube
  const Eigen::Vector3d on_cube(0.0, 0.0, 0.0195);
  double t = 0.0;
  for (double g = 90; g >= 50; g -= 5, t += 1.0 / 60.0)
    f.mode.Update(ToolAt(on_cube, g * kDeg, t), f.context);
  EXPECT_FALSE(f.mode.grabbing());
}

}  // namespace
}  // namespace spidarcad::app
