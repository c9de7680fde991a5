// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
// Clay width under the grasp (scene/clay_width.h, and SculptSession/SculptToolField in
// scene/sculpt_field.h): on a ball of clay on the grip's bisector the squeeze is GraspField's
// closed form Q = k (r − L sin θ/2) L cos θ/2 (depth r − L sin θ/2); the grasp torque is never
// positive, zero with the fingers open and with one finger in the clay, continuous as the
// fingers close onto the clay (centred or not); the tick allocates nothing; the grid channel
// hands a rebuilt grid over and frees the old one on the app side; a squeeze begins a stroke
// whose strength follows the squeeze (and holds its largest value when the fingers ease off),
// and ends when they let go; after a stroke the field renders the rebuilt clay (at once, or
// through the asynchronous build).
#include "scene/clay_width.h"

#include <gtest/gtest.h>

#include <cmath>
#include <memory>
#include <numbers>
#include <random>
#include <vector>

#include "scene/clay_grid.h"
#include "scene/sculpt_field.h"
#include "spidarcad/haptics/geometry.h"
#include "spidarcad/modeling/sculpt.h"
#include "support/malloc_counter.h"

namespace spidarcad::app {
namespace {

constexpr double kDeg = std::numbers::pi / 180.0;
constexpr double kR = 0.02;  // the ball of clay, radius m, centred at the origin
constexpr double kL = 0.03;  // grip centre to ball centre, m

std::shared_ptr<const ClayDistanceGrid> Ball(
    double radius, double cell, int subdivisions = 5,
    const Eigen::Vector3d& centre = Eigen::Vector3d::Zero()) {
  const modeling::TriangleMesh m = modeling::IcosphereMesh(radius, subdivisions);
  std::vector<Eigen::Vector3d> p;
  std::vector<Eigen::Vector3i> t;
  for (Eigen::Index v = 0; v < m.vertices.cols(); ++v) p.push_back(m.vertices.col(v) + centre);
  for (Eigen::Index f = 0; f < m.triangles.cols(); ++f) t.push_back(m.triangles.col(f));
  ClayGridSettings settings;
  settings.cell = cell;
  settings.slack = 0.0;
  return ClayDistanceGrid::Build(p, t, settings);
}

// The grip frame whose bisector b and pole-plane axis a (unit, orthogonal) are b_W and a_W:
// x = (b + a)/√2, y = (b − a)/√2, z = a × b (ARCHITECTURE.md).
Eigen::Matrix3d GripFrame(const Eigen::Vector3d& b_W, const Eigen::Vector3d& a_W) {
  Eigen::Matrix3d R;
  R.col(0) = (b_W + a_W) / std::sqrt(2.0);
  R.col(1) = (b_W - a_W) / std::sqrt(2.0);
  R.col(2) = a_W.cross(b_W);
  return R;
}

// The grip at (0, 0, L) with its bisector pointing down at the ball, poles in the x-z plane.
haptics::ToolKinematics Pinch(double grasp_deg, double height = kL) {
  haptics::ToolKinematics tool;
  tool.p_WT = Eigen::Vector3d(0, 0, height);
  tool.R_WT = GripFrame(-Eigen::Vector3d::UnitZ(), Eigen::Vector3d::UnitX());
  tool.grasp = grasp_deg * kDeg;
  return tool;
}

ClayWidthSettings Settings() {
  ClayWidthSettings s;
  s.grasp.pole_length = 0.04;
  return s;
}

TEST(ClayWidth, GripFrameIsARotationWithTheBisectorWhereAsked) {
  const Eigen::Matrix3d R = Pinch(90.0).R_WT;
  EXPECT_LT((R.transpose() * R - Eigen::Matrix3d::Identity()).norm(), 1e-12);
  EXPECT_NEAR(R.determinant(), 1.0, 1e-12);
  const haptics::PoleDirections poles = haptics::GripPoleDirections(80.0 * kDeg);
  const Eigen::Vector3d bisector = (R * (poles.u_T[0] + poles.u_T[1])).normalized();
  EXPECT_LT((bisector - Eigen::Vector3d(0, 0, -1)).norm(), 1e-12);
}

TEST(ClayWidth, SqueezeOfABallOnTheBisectorIsGraspFieldsClosedForm) {
  const auto ball = Ball(kR, 0.0005);
  const ClayWidthSettings s = Settings();
  const double k = s.grasp.stiffness;
  const double theta_star = 2.0 * std::asin(kR / kL);
  for (double deg : {80.0, 81.0, 82.0, 83.0}) {
    const double theta = deg * kDeg;
    ASSERT_LT(theta, theta_star);
    const ClaySqueeze q = ComputeClaySqueeze(*ball, Eigen::Isometry3d::Identity(), Pinch(deg), s);
    const double depth = kR - kL * std::sin(theta / 2);
    const double Q = k * depth * kL * std::cos(theta / 2);
    EXPECT_TRUE(q.pole[0].pushing && q.pole[1].pushing) << deg;
    EXPECT_NEAR(q.squeeze, depth, 1e-5) << deg;
    EXPECT_NEAR(q.pole[0].depth, q.pole[1].depth, 1e-5) << deg;
    EXPECT_NEAR(q.g, -2.0 * Q, 0.03 * 2.0 * Q + 2e-3) << deg;
    // The pinch: the two contacts lie on the ball, symmetric about the bisector.
    EXPECT_NEAR((q.contact_W[0] + q.contact_W[1]).x(), 0.0, 1e-4) << deg;
  }
}

TEST(ClayWidth, GraspTorqueIsNeverPositive) {
  const auto ball = Ball(kR, 0.001, 4);
  const ClayWidthSettings s = Settings();
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> unit(-1.0, 1.0);
  int squeezing = 0;
  for (int i = 0; i < 4000; ++i) {
    // Random grips whose bisector points near the ball, from 25-35 mm away, half of them
    // closed onto it.
    haptics::ToolKinematics tool;
    tool.R_WT = Eigen::Quaterniond(unit(rng), unit(rng), unit(rng), unit(rng))
                    .normalized()
                    .toRotationMatrix();
    const Eigen::Vector3d b_W = tool.R_WT * Eigen::Vector3d(1, 1, 0).normalized();
    tool.p_WT = -(0.03 + 0.005 * unit(rng)) * b_W +
                0.004 * Eigen::Vector3d(unit(rng), unit(rng), unit(rng));
    tool.grasp = 1.35 + 0.25 * unit(rng);
    tool.grasp_rate = 5.0 * unit(rng);
    const ClaySqueeze q = ComputeClaySqueeze(*ball, Eigen::Isometry3d::Identity(), tool, s);
    ASSERT_LE(q.g, 0.0) << i;
    ASSERT_TRUE(std::isfinite(q.g));
    squeezing += q.g < 0.0;
  }
  EXPECT_GT(squeezing, 100);  // the random grips did squeeze the clay often
}

TEST(ClayWidth, ZeroWithTheFingersOpen) {
  const auto ball = Ball(kR, 0.0005);
  const ClayWidthSettings s = Settings();
  for (double deg : {84.0, 86.0, 90.0, 100.0}) {  // above θ* = 83.6°
    haptics::ToolKinematics tool = Pinch(deg);
    tool.grasp_rate = -2.0;  // closing: no damping either out of contact
    const ClaySqueeze q = ComputeClaySqueeze(*ball, Eigen::Isometry3d::Identity(), tool, s);
    EXPECT_EQ(q.g, 0.0) << deg;
    EXPECT_EQ(q.squeeze, 0.0) << deg;
  }
  EXPECT_EQ(SqueezeStrength(0.0, 1e-3), 0.0);
}

TEST(ClayWidth, ZeroWithOneFingerInTheClay) {
  const double grasp = 70.0 * kDeg;
  haptics::ToolKinematics tool = Pinch(70.0);
  const haptics::PoleDirections poles = haptics::GripPoleDirections(grasp);
  const Eigen::Vector3d u1 = tool.R_WT * poles.u_T[0];
  const Eigen::Vector3d u2 = tool.R_WT * poles.u_T[1];
  // A small ball that pole 1 enters 0.5 mm deep at 30 mm along it, on the side of pole 2 (so
  // closing drives pole 1 deeper) but clear of pole 2.
  const double r = 0.006;
  const Eigen::Vector3d toward = (u2 - u1 * u1.dot(u2)).normalized();
  const Eigen::Vector3d centre = tool.p_WT + 0.03 * u1 + (r - 0.0005) * toward;
  const auto ball = Ball(r, 0.0005, 4, centre);
  const ClaySqueeze q = ComputeClaySqueeze(*ball, Eigen::Isometry3d::Identity(), tool, Settings());
  EXPECT_NEAR(q.pole[0].depth, 0.0005, 5e-5);
  EXPECT_TRUE(q.pole[0].pushing);
  EXPECT_EQ(q.pole[1].depth, 0.0);
  EXPECT_EQ(q.squeeze, 0.0);
  EXPECT_EQ(q.g, 0.0);
}

// Largest change of g between two grasp angles 0.005° apart, closing from 89° to 80.5°.
double LargestStep(const ClayDistanceGrid& ball, double* first_g) {
  const ClayWidthSettings s = Settings();
  double previous = 0.0, largest = 0.0;
  *first_g = 0.0;
  for (int i = 0; i <= 1700; ++i) {
    const double deg = 89.0 - 0.005 * i;
    const double g = ComputeClaySqueeze(ball, Eigen::Isometry3d::Identity(), Pinch(deg), s).g;
    if (*first_g == 0.0 && g != 0.0) *first_g = g;
    if (i > 0) largest = std::max(largest, std::abs(g - previous));
    previous = g;
  }
  return largest;
}

TEST(ClayWidth, ContinuousAsTheFingersCloseOntoTheClay) {
  // Angular stiffness k L² cos²(θ*/2) ≈ 5.3 N·m/rad on g: 4.6e-4 N·m per 0.005° step.
  double first = 0.0;
  const double centred = LargestStep(*Ball(kR, 0.0005), &first);
  EXPECT_LT(centred, 2e-3);
  EXPECT_LT(std::abs(first), 2e-3);
  // Off centre by 1 mm along the poles' plane: one finger sinks into the clay first (about
  // 0.7 mm before the other touches); the second's touch adds no step (GraspField's sum would
  // jump by k δ1 (−a1) ≈ 0.1 N·m on g there).
  const auto shifted = Ball(kR, 0.0005, 5, Eigen::Vector3d(0.001, 0, 0.0));
  const double off = LargestStep(*shifted, &first);
  EXPECT_LT(off, 3e-3);
  EXPECT_LT(std::abs(first), 3e-3);
}

std::unique_ptr<SculptSession> BallSession(double pole_length = 0.04) {
  auto session = std::make_unique<SculptSession>();
  session->settings().tool.radius = 0.02;
  session->settings().clay_width.grasp.pole_length = pole_length;
  session->settings().clay_width.grid.cell = 0.001;
  session->SetMesh(modeling::IcosphereMesh(kR, 4), 0.005);
  return session;
}

TEST(ClayWidth, SculptToolFieldAllocatesNothingWhileSqueezing) {
  ASSERT_TRUE(test_support::MallocCounterActive());
  auto session = BallSession();
  auto field = session->MakeField();
  field->Evaluate(Pinch(80.0));  // takes the grid
  double sum = 0.0;
  long allocations = 0;
  {
    test_support::MallocCounter counter;
    for (int i = 0; i < 1000; ++i) {
      haptics::ToolKinematics tool = Pinch(80.0 + 0.003 * i);
      tool.grasp_rate = -0.5;
      sum += field->Evaluate(tool).g;
    }
    allocations = counter.count();
  }
  EXPECT_EQ(allocations, 0);
  EXPECT_LT(sum, 0.0);  // it squeezed: real work
}

TEST(ClayGridChannel, HandsTheNewestGridOverAndFreesTheOldOnTheAppSide) {
  ClayGridChannel channel;
  EXPECT_EQ(channel.Acquire(), nullptr);
  std::weak_ptr<const ClayDistanceGrid> first, unseen;
  {
    auto a = Ball(kR, 0.002, 2);
    first = a;
    channel.Offer(std::move(a));
  }
  const ClayDistanceGrid* taken = channel.Acquire();
  ASSERT_NE(taken, nullptr);
  EXPECT_EQ(taken, first.lock().get());
  {
    auto b = Ball(kR, 0.002, 2);
    unseen = b;
    channel.Offer(std::move(b));
  }
  auto c = Ball(kR, 0.002, 2);
  const ClayDistanceGrid* third = c.get();
  channel.Offer(std::move(c));
  EXPECT_TRUE(unseen.expired());  // replaced before the haptic side took it: freed by Offer
  EXPECT_EQ(channel.Acquire(), third);
  EXPECT_FALSE(first.expired());  // retired by the haptic side, not freed there
  EXPECT_TRUE(channel.Collect());
  EXPECT_TRUE(first.expired());
  EXPECT_EQ(channel.Acquire(), third);
  EXPECT_FALSE(channel.Collect());
}

TEST(SculptSession, ASqueezeBeginsAStrokeWhoseStrengthFollowsTheSqueeze) {
  auto owner = BallSession();
  SculptSession& session = *owner;
  const double full = session.settings().clay_width.full_squeeze_depth;
  EXPECT_EQ(session.Step(Pinch(86.0), false), SculptFrameEvent::kIdle);  // open: no contact
  EXPECT_EQ(session.squeeze().squeeze, 0.0);
  // 81°: the fingers are in the clay δ = r − L sin θ/2 (0.51 mm) deep, above 70°: a squeeze.
  ASSERT_EQ(session.Step(Pinch(81.0), false), SculptFrameEvent::kBegan);
  EXPECT_TRUE(session.squeeze_stroke());
  const double d81 = kR - kL * std::sin(40.5 * kDeg);
  EXPECT_NEAR(session.stroke_strength(), d81 / full, 0.05);
  // Harder: 80° (0.72 mm) grabs more strongly.
  EXPECT_EQ(session.Step(Pinch(80.0), false), SculptFrameEvent::kUpdated);
  const double d80 = kR - kL * std::sin(40.0 * kDeg);
  EXPECT_NEAR(session.stroke_strength(), d80 / full, 0.05);
  EXPECT_GT(session.stroke_strength(), d81 / full + 0.1);
  // Easing off keeps the clay where the firmest squeeze put it.
  const double held = session.stroke_strength();
  EXPECT_EQ(session.Step(Pinch(82.5), false), SculptFrameEvent::kUpdated);
  EXPECT_EQ(session.stroke_strength(), held);
  // ... while the felt stroke force follows the squeeze now.
  auto field = session.MakeField();
  haptics::ToolKinematics pulled = Pinch(82.5, kL + 0.005);
  const haptics::ToolWrench w = field->Evaluate(pulled);
  Eigen::Isometry3d X_WT = Eigen::Isometry3d::Identity();
  X_WT.linear() = pulled.R_WT;
  X_WT.translation() = pulled.p_WT;
  const ClaySqueeze q =
      ComputeClaySqueeze(*session.clay_grid(), ClayPlacement(session.published_model(), X_WT),
                         pulled, session.settings().clay_width);
  const double s_now = SqueezeStrength(q.squeeze, full);
  EXPECT_GT(s_now, 0.0);
  EXPECT_LT(s_now, held);
  EXPECT_NEAR(w.f_T_W.z(), -session.settings().tool.stiffness * s_now * 0.005, 1e-9);
  // Open: the fingers leave the clay and the stroke ends.
  EXPECT_EQ(session.Step(Pinch(88.0), false), SculptFrameEvent::kEnded);
  EXPECT_FALSE(session.stroke_active());
}

TEST(SculptSession, AfterAStrokeTheFieldFeelsTheRebuiltClay) {
  for (bool async : {false, true}) {
    auto owner = BallSession();
    SculptSession& session = *owner;
    session.set_async_grids(async);
    session.SetMesh(modeling::IcosphereMesh(kR, 4), 0.005);
    session.FinishGridBuild();
    const std::shared_ptr<const ClayDistanceGrid> before = session.clay_grid();
    ASSERT_NE(before, nullptr);
    auto field = session.MakeField();
    const auto* sculpt_field = dynamic_cast<const SculptToolField*>(field.get());
    ASSERT_NE(sculpt_field, nullptr);
    field->Evaluate(Pinch(90.0));
    // An angle stroke at the top vertex, pulled 8 mm up at full strength.
    Eigen::Vector3d top = session.mesh()->positions().front();
    for (const Eigen::Vector3d& p : session.mesh()->positions())
      if (p.z() > top.z()) top = p;
    haptics::ToolKinematics tool;
    tool.p_WT = top;
    tool.grasp = 30.0 * kDeg;
    ASSERT_EQ(session.Step(tool, false), SculptFrameEvent::kBegan);
    EXPECT_FALSE(session.squeeze_stroke());
    tool.p_WT.z() += 0.008;
    session.Step(tool, false);
    tool.grasp = 90.0 * kDeg;
    ASSERT_EQ(session.Step(tool, false), SculptFrameEvent::kEnded);
    session.FinishGridBuild();
    const std::shared_ptr<const ClayDistanceGrid> after = session.clay_grid();
    ASSERT_NE(after, nullptr);
    EXPECT_NE(after, before) << async;
    EXPECT_LT(after->recomputed_nodes(), after->node_count()) << async;  // a local update
    // The pulled top is on the new surface.
    EXPECT_NEAR(after->Evaluate(top + Eigen::Vector3d(0, 0, 0.008), nullptr), 0.0, 1e-4);
    // The field takes the new grid at its next tick (the app then frees the old one's slot)
    // and feels the pulled clay: the pinch's contacts lie within the stroke's radius.
    const ClayWidthSettings& s = session.settings().clay_width;
    field->Evaluate(Pinch(80.0));
    EXPECT_TRUE(session.clay_channel()->Collect()) << async;
    const ClaySqueeze now =
        ComputeClaySqueeze(*after, Eigen::Isometry3d::Identity(), Pinch(80.0), s);
    const ClaySqueeze old =
        ComputeClaySqueeze(*before, Eigen::Isometry3d::Identity(), Pinch(80.0), s);
    EXPECT_EQ(sculpt_field->last_squeeze().squeeze, now.squeeze) << async;
    EXPECT_EQ(sculpt_field->last_squeeze().g, now.g) << async;
    EXPECT_GT(std::abs(now.squeeze - old.squeeze), 2e-5) << async;
  }
}

}  // namespace
}  // namespace spidarcad::app
