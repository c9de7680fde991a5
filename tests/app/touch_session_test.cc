// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
// Tests of modelling by touch without a window (scene/touch_session.h): the squeeze detector on
// synthetic grasp histories; a TouchSession placing a sphere on a cube's top face as model mode
// and `spidarcad run --place` drive it, frame by frame: the ghost's alignment and size against
// the cube's geometry worked out by hand, the felt pull against SnapField's closed form
// F_max·tanh(d/d_s) toward the lifted face, zero far from it, one command per squeeze placing the
// ghost as it was when the squeeze began; and the run's slot field, which forwards to the
// session's felt field without allocating.
#include "scene/touch_session.h"

#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <cmath>
#include <numbers>
#include <variant>

#include "doc/command.h"
#include "doc/document.h"
#include "spidarcad/haptics/snap_field.h"
#include "spidarcad/modeling/implicit_node.h"
#include "support/malloc_counter.h"

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
auto Pulse(double start, double close, double open, double depth, double theta0 = 90.0 * kDeg) {
  return [=](double t) {
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

// The tool state of a grip at p (W = D), grip frame unturned, grasp θ, at time t.
haptics::ToolState ToolAt(const Eigen::Vector3d& p, double grasp, double time) {
  haptics::ToolState tool;
  tool.time = time;
  tool.pose_D = haptics::GripPose::FromFrame(p, Eigen::Matrix3d::Identity(), grasp, 0.04);
  tool.tool_W.time = time;
  tool.tool_W.p_WT = p;
  tool.tool_W.grasp = grasp;
  return tool;
}

// A document holding a 40 mm cube centred at the origin (top face z = 20 mm).
void AddCube(Document* doc) {
  doc->Execute(edit::AddSolid(
      "cube", modeling::ImplicitNode(modeling::BoxParams{Eigen::Vector3d::Constant(0.04)})));
}

// The session's felt wrench at p.
haptics::ToolWrench Felt(const TouchSession& session, const Eigen::Vector3d& p) {
  TouchSnapSlotField slot(&session);
  haptics::ToolKinematics at;
  at.p_WT = p;
  return slot.Evaluate(at);
}

TEST(TouchSession, ASqueezePlacesTheGhostRestingOnTheFaceAndItsPullIsSnapFieldsClosedForm) {
  Document doc;
  AddCube(&doc);
  TouchSession session(0.04);
  session.SetWorldScale(1.0);
  EXPECT_FALSE(session.SetPlacing(PlaceKind::kSphere));
  // The grasp at 50°: the sphere is c = d·θ across and rests with its centre c/2 above the top.
  const double theta = 50 * kDeg;
  const double c = 0.04 * theta;
  const double rest_z = 0.02 + c / 2;
  // Far above: the ghost is the grip's own pose, aligned to nothing; the felt field exists (the
  // lifted face) but pulls with zero force beyond its 6 mm capture.
  const Eigen::Vector3d far(0.004, -0.003, rest_z + 0.02);
  SqueezeDetector squeeze;
  double t = 0.0;
  const TouchSession::PlaceFrame first =
      session.UpdatePlacing(ToolAt(far, theta, t), &doc, 0, false, 0.0, false);
  EXPECT_FALSE(first.placed);
  EXPECT_TRUE(first.felt_changed);
  EXPECT_EQ(session.ghost().kind, AlignKind::kNone);
  EXPECT_NEAR(session.ghost_size(), c, 1e-15);
  EXPECT_LT((session.ghost().X_WN.translation() - far).norm(), 1e-15);
  ASSERT_NE(session.felt_snap(), nullptr);
  EXPECT_EQ(Felt(session, far).f_T_W.norm(), 0.0);
  // 1.2 mm above the resting height, inside the capture: aligned to the top face (the box's
  // face 'z+' among its six), and the pull is F_max·tanh(d/d_s)·w(d), d = 1.2 mm, d_s = 6/4 mm,
  // w = 1 below half the capture, straight down.
  const Eigen::Vector3d near(0.004, -0.003, rest_z + 0.0012);
  t += 0.016;
  const TouchSession::PlaceFrame second =
      session.UpdatePlacing(ToolAt(near, theta, t), &doc, 0, false, 0.0, false);
  EXPECT_FALSE(second.felt_changed) << "same features, same rest height: the same field";
  EXPECT_EQ(session.ghost().kind, AlignKind::kFace);
  EXPECT_LT((session.ghost().X_WN.translation() - Eigen::Vector3d(0.004, -0.003, rest_z)).norm(),
            1e-12);
  const haptics::ToolWrench pull = Felt(session, near);
  EXPECT_NEAR(pull.f_T_W.z(), -0.8 * std::tanh(0.0012 / 0.0015), 1e-12);
  EXPECT_NEAR(pull.f_T_W.head<2>().norm(), 0.0, 1e-12);
  EXPECT_LE(pull.f_T_W.norm(), 0.8);
  EXPECT_NEAR(pull.f_T_W.norm(), haptics::SnapField::Pull(0.0012, 0.006, 0.8), 1e-12);
  // Held there, then a 20° squeeze from 50° in 0.3 s at 62.5 frames/s: one command placing the
  // ghost as it was when the squeeze began (50°: size c), centred on the face's rest.
  const auto grasp = Pulse(1.0, 0.15, 0.15, 20 * kDeg, theta);
  int placed = 0;
  for (t = 0.032; t < 2.0; t += 0.016) {
    const bool squeezed = squeeze.Update(t, grasp(t));
    const TouchSession::PlaceFrame frame = session.UpdatePlacing(
        ToolAt(near, grasp(t), t), &doc, 0, squeezed, squeeze.last_start(), false);
    placed += frame.placed ? 1 : 0;
    if (frame.placed) {
      EXPECT_NE(frame.placed_id, 0u);
      EXPECT_EQ(frame.placed_id, session.placed_id());
    }
  }
  ASSERT_EQ(placed, 1);
  EXPECT_EQ(session.placed_count(), 1);
  ASSERT_EQ(doc.history().undo_size(), 2u);  // the cube, then the sphere
  EXPECT_EQ(doc.history().UndoDescription(), "Add solid sphere");
  const DocObject* sphere = doc.FindByName("sphere");
  ASSERT_NE(sphere, nullptr);
  const modeling::ImplicitNode& root = std::get<SolidData>(sphere->data).root;
  const NodePose pose = PoseOfNode(root);
  EXPECT_LT((pose.X_AN.translation() - Eigen::Vector3d(0.004, -0.003, rest_z)).norm(), 1e-12);
  EXPECT_LT((pose.X_AN.linear() - Eigen::Matrix3d::Identity()).norm(), 1e-12);
  const double radius =
      std::get<modeling::SphereParams>(root.children.front().children.front().params).radius;
  EXPECT_NEAR(2.0 * radius, c, 1e-15);
  EXPECT_NE(session.message().find("placed 'sphere' (34.9 mm), aligned to face"), std::string::npos)
      << session.message();
  // Disarmed: the felt field goes (the scene changes), and the slot field feels nothing.
  EXPECT_TRUE(session.SetPlacing(std::nullopt));
  EXPECT_EQ(session.felt_snap(), nullptr);
  EXPECT_EQ(Felt(session, near).f_T_W.norm(), 0.0);
}

// The felt field follows the grasp's size only once it has held within 2 % for 0.1 s (so a
// squeeze never moves the lifted faces), and the features follow the document.
TEST(TouchSession, TheFeltFieldFollowsASteadyGraspAndTheFeaturesTheDocument) {
  Document doc;
  AddCube(&doc);
  TouchSession session(0.04);
  session.SetPlacing(PlaceKind::kBox);
  const Eigen::Vector3d p(0.0, 0.0, 0.09);  // 70 mm above the top: no face in reach
  auto frame = [&](double grasp_deg, double t, bool place_key = false) {
    return session.UpdatePlacing(ToolAt(p, grasp_deg * kDeg, t), &doc, 0, false, 0, place_key);
  };
  EXPECT_TRUE(frame(90, 0.0).felt_changed);
  EXPECT_NEAR(session.felt_rest_height(), PlaceSize(90 * kDeg, 0.04, 1.0) / 2, 1e-15);
  // Within 2 %: kept.
  EXPECT_FALSE(frame(89.5, 0.016).felt_changed);
  // 80°: the ghost follows at once, the felt faces once 80° has held for 0.1 s (the 89.5°
  // sample at 0.016 s is then older than 0.1 s: from t = 0.128 s).
  double t = 0.032;
  int changes = 0;
  for (; t < 0.3; t += 0.016) {
    const bool changed = frame(80, t).felt_changed;
    EXPECT_NEAR(session.ghost_size(), PlaceSize(80 * kDeg, 0.04, 1.0), 1e-15);
    if (changed) {
      ++changes;
      EXPECT_GT(t, 0.016 + TouchSession::kSteadyTime) << "moved before the grasp held";
    }
  }
  EXPECT_EQ(changes, 1);
  EXPECT_NEAR(session.felt_rest_height(), PlaceSize(80 * kDeg, 0.04, 1.0) / 2, 1e-15);
  // 12 edges and 6 faces of the cube; a second cube far away doubles them (the revision moved),
  // and the felt field is rebuilt at its height.
  EXPECT_EQ(session.features().features.faces_W.size(), 6u);
  doc.Execute(edit::AddSolid(
      "far cube",
      modeling::ImplicitNode(
          modeling::TranslateParams{Eigen::Vector3d(0.2, 0, 0)},
          {modeling::ImplicitNode(modeling::BoxParams{Eigen::Vector3d::Constant(0.04)})})));
  EXPECT_TRUE(frame(80, t).felt_changed);
  EXPECT_EQ(session.features().features.faces_W.size(), 12u);
  // P (place_key) places the ghost as it is now: a box of the grasp's size, unaligned here.
  EXPECT_TRUE(frame(80, t + 0.016, true).placed);
  const DocObject* box = doc.FindByName("box");
  ASSERT_NE(box, nullptr);
  EXPECT_LT((PoseOfNode(std::get<SolidData>(box->data).root).X_AN.translation() - p).norm(), 1e-15);
  // Not placing: nothing happens, nothing is placed, no felt field.
  EXPECT_TRUE(session.SetPlacing(std::nullopt));
  EXPECT_EQ(session.felt_rest_height(), 0.0);
  EXPECT_FALSE(
      session.UpdatePlacing(ToolAt(p, 80 * kDeg, t + 0.032), &doc, 0, true, 0, true).placed);
  EXPECT_EQ(session.placed_count(), 1);
}

// Near a corner the ghost's centre goes onto the vertex, and the felt pull is the vertex's alone:
// within half the vertex radius (s·5 mm / 2) SnapField's layering gives the vertex full weight,
// so the force is F_max·tanh(d/d_s) toward the corner, d_s = 5 mm / 4.
TEST(TouchSession, NearACornerTheGhostTakesTheVertexAndThePullPointsAtIt) {
  Document doc;
  AddCube(&doc);
  TouchSession session(0.04);
  session.SetPlacing(PlaceKind::kSphere);
  const Eigen::Vector3d corner(0.02, 0.02, 0.02);
  const Eigen::Vector3d out = Eigen::Vector3d(1, 1, 1).normalized();
  const Eigen::Vector3d p = corner + 0.002 * out;
  session.UpdatePlacing(ToolAt(p, 30 * kDeg, 0.0), &doc, 0, false, 0, false);
  ASSERT_EQ(session.ghost().kind, AlignKind::kVertex) << session.ghost().Text();
  EXPECT_EQ(AlignKindNumber(session.ghost().kind), 4);
  EXPECT_LT((session.ghost().X_WN.translation() - corner).norm(), 1e-12);
  const haptics::ToolWrench pull = Felt(session, p);
  const double expected = 0.8 * std::tanh(0.002 / 0.00125);
  EXPECT_NEAR(pull.f_T_W.norm(), expected, 1e-12);
  EXPECT_LT((pull.f_T_W + expected * out).norm(), 1e-12);
  // Placed there: the sphere is centred on the corner.
  EXPECT_TRUE(session.Place(&doc));
  const NodePose pose = PoseOfNode(std::get<SolidData>(doc.FindByName("sphere")->data).root);
  EXPECT_LT((pose.X_AN.translation() - corner).norm(), 1e-12);
}

TEST(TouchSnapSlotField, EvaluateAllocatesNothing) {
  ASSERT_TRUE(test_support::MallocCounterActive());
  Document doc;
  AddCube(&doc);
  TouchSession session(0.04);
  session.SetPlacing(PlaceKind::kSphere);
  const double c = 0.04 * 50 * kDeg;
  session.UpdatePlacing(ToolAt(Eigen::Vector3d(0, 0, 0.03), 50 * kDeg, 0.0), &doc, 0, false, 0,
                        false);
  ASSERT_NE(session.felt_snap(), nullptr);
  TouchSnapSlotField slot(&session);
  double sum = 0.0;
  long allocations = 0;
  {
    test_support::MallocCounter counter;
    for (int i = 0; i < 1000; ++i) {
      haptics::ToolKinematics at;
      at.p_WT = Eigen::Vector3d(0.001, -0.002, 0.02 + c / 2 + 1e-5 * i);
      sum += slot.Evaluate(at).f_T_W.z();
    }
    allocations = counter.count();
  }
  EXPECT_EQ(allocations, 0);
  EXPECT_LT(sum, 0.0);  // it pulled: real work
}

}  // namespace
}  // namespace spidarcad::app
