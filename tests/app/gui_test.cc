// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
// Tests of the window's pieces that need no display (colour map, picking and drag math, the
// demo field, the haptic runtime on a virtual clock and on its thread, the scene model with its
// mesh jobs and export, option parsing), and screenshot tests of the window itself that run the
// spidarcad binary with --screenshot when an X display is available (CI: xvfb-run).
#include "gui/gui.h"

#include <gtest/gtest.h>
#include <sys/wait.h>
#include <vtkImageData.h>
#include <vtkNew.h>
#include <vtkPNGReader.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <numbers>
#include <set>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include "doc/command.h"
#include "doc/job.h"
#include "gui/colour_map.h"
#include "gui/panels.h"
#include "gui/window_layout.h"
#include "scene/device_session.h"
#include "scene/fe_setup.h"
#include "scene/grip_control.h"
#include "scene/haptic_runtime.h"
#include "scene/scene_fields.h"
#include "scene/scene_model.h"
#include "spidarcad/haptics/kinematics.h"
#include "spidarcad/haptics/tension.h"
#include "spidarcad/modeling/scene_io.h"
#include "spidarcad/modeling/tet_mesh.h"
#include "spidarcad/modeling/triangle_mesh_io.h"
#include "support/command_runner.h"
#include "support/malloc_counter.h"
#include "window_test_support.h"

namespace spidarcad::app {
namespace {

using haptics::GripPose;
using haptics::SpidarGeometry;
using window_test::CountChromaticity;
using window_test::ReadPng;
using window_test::RunTicks;
using window_test::SpringScene;
constexpr double kPi = std::numbers::pi;

TEST(TensionColourMap, HitsItsStopsAndInterpolatesLinearlyBetween) {
  for (int k = 0; k < 4; ++k) {
    const Rgb c = TensionColourMap(k / 3.0);
    for (int j = 0; j < 3; ++j) EXPECT_NEAR(c[j], kTensionColourStops[k][j], 1e-12);
  }
  const Rgb mid = TensionColourMap(0.5 / 3.0);  // halfway between blue and teal
  for (int j = 0; j < 3; ++j) {
    EXPECT_NEAR(mid[j], 0.5 * (kTensionColourStops[0][j] + kTensionColourStops[1][j]), 1e-12);
  }
  // Clamped outside [0, 1]; grey for NaN or an empty range.
  EXPECT_EQ(TensionColourMap(-3.0), TensionColourMap(0.0));
  EXPECT_EQ(TensionColourMap(7.0), TensionColourMap(1.0));
  EXPECT_EQ(TensionColourMap(std::nan("")), (Rgb{0.5, 0.5, 0.5}));
  EXPECT_EQ(TensionColour(1.0, 2.0, 2.0), (Rgb{0.5, 0.5, 0.5}));
  // τ_min is blue, τ_max red.
  const Rgb lo = TensionColour(0.2, 0.2, 8.0), hi = TensionColour(8.0, 0.2, 8.0);
  EXPECT_GT(lo[2], 0.9);
  EXPECT_LT(lo[0], 0.2);
  EXPECT_GT(hi[0], 0.8);
  EXPECT_LT(hi[2], 0.2);
}

TEST(IntersectRayPlane, FindsTheClosedFormPointAndRejectsParallelOrBehind) {
  Ray ray{{0.1, -2.0, 0.3}, {0.2, 1.0, -0.1}};
  Eigen::Vector3d hit;
  // Plane y = 0.5: s = 2.5, hit = origin + 2.5 direction.
  ASSERT_TRUE(IntersectRayPlane(ray, {7, 0.5, -3}, {0, 2, 0}, &hit));
  EXPECT_NEAR((hit - Eigen::Vector3d(0.6, 0.5, 0.05)).norm(), 0.0, 1e-12);
  EXPECT_FALSE(IntersectRayPlane(ray, {0, 0, 0}, {1, -0.2, 0}, &hit));  // parallel
  EXPECT_FALSE(IntersectRayPlane(ray, {0, -3.0, 0}, {0, 1, 0}, &hit));  // behind the origin
}

TEST(IntersectRaySphere, ReturnsEntryDistanceMissesAndInside) {
  double s = -1;
  ASSERT_TRUE(IntersectRaySphere({{-1, 0, 0}, {3, 0, 0}}, {0, 0, 0}, 0.5, &s));
  EXPECT_NEAR(s, 0.5, 1e-12);
  // Off-axis: the ray y = 0.3 enters the unit sphere at x = −sqrt(1 − 0.09).
  ASSERT_TRUE(IntersectRaySphere({{-2, 0.3, 0}, {1, 0, 0}}, {0, 0, 0}, 1.0, &s));
  EXPECT_NEAR(s, 2.0 - std::sqrt(0.91), 1e-12);
  EXPECT_FALSE(IntersectRaySphere({{-1, 0.6, 0}, {1, 0, 0}}, {0, 0, 0}, 0.5, &s));
  EXPECT_FALSE(IntersectRaySphere({{1, 0, 0}, {1, 0, 0}}, {0, 0, 0}, 0.5, &s));  // behind
  ASSERT_TRUE(IntersectRaySphere({{0.1, 0, 0}, {0, 1, 0}}, {0, 0, 0}, 0.5, &s));
  EXPECT_EQ(s, 0.0);
}

TEST(RollPitchYaw, RecoversTheAnglesOfZyxComposition) {
  const double roll = 0.3, pitch = -0.7, yaw = 2.1;
  const Eigen::Matrix3d R = (Eigen::AngleAxisd(yaw, Eigen::Vector3d::UnitZ()) *
                             Eigen::AngleAxisd(pitch, Eigen::Vector3d::UnitY()) *
                             Eigen::AngleAxisd(roll, Eigen::Vector3d::UnitX()))
                                .toRotationMatrix();
  const Eigen::Vector3d rpy = RollPitchYaw(R);
  EXPECT_NEAR(rpy[0], roll, 1e-12);
  EXPECT_NEAR(rpy[1], pitch, 1e-12);
  EXPECT_NEAR(rpy[2], yaw, 1e-12);
}

TEST(GripControl, ResetGivesTheRestPose) {
  const SpidarGeometry g;
  GripControl grip(g);
  grip.SetPose({0.05, 0.02, -0.01}, Eigen::AngleAxisd(0.4, Eigen::Vector3d::UnitY()).matrix(), 1.0);
  grip.Reset();
  const GripPose rest = GripPose::Rest(g.d);
  const GripPose pose = grip.Pose();
  EXPECT_NEAR((pose.p0 - rest.p0).norm(), 0.0, 1e-15);
  EXPECT_NEAR((pose.p1 - rest.p1).norm(), 0.0, 1e-15);
  EXPECT_NEAR((pose.p2 - rest.p2).norm(), 0.0, 1e-15);
}

TEST(GripControl, TranslateKeepsTheGrabbedPointUnderTheRay) {
  const SpidarGeometry g;
  GripControl grip(g);
  grip.SetPose({0.01, 0.02, 0.03}, Eigen::Matrix3d::Identity(), kPi / 2);
  const Eigen::Vector3d eye(1.0, -1.5, 0.8);
  const Eigen::Vector3d normal = (Eigen::Vector3d(0.01, 0.02, 0.03) - eye).normalized();
  // Grab 1 cm right of the centre, then move the ray to a point 5 cm further in the plane.
  const Eigen::Vector3d right = normal.cross(Eigen::Vector3d::UnitZ()).normalized();
  const Eigen::Vector3d up = right.cross(normal);
  const Eigen::Vector3d grabbed = Eigen::Vector3d(0.01, 0.02, 0.03) + 0.01 * right;
  ASSERT_TRUE(grip.BeginTranslate({eye, grabbed - eye}, normal));
  const Eigen::Vector3d target = grabbed + 0.03 * right - 0.04 * up;
  grip.Translate({eye, 2.0 * (target - eye)});
  // The centre moved by exactly the in-plane displacement of the grabbed point.
  EXPECT_NEAR((grip.p0() - (Eigen::Vector3d(0.01, 0.02, 0.03) + 0.03 * right - 0.04 * up)).norm(),
              0.0, 1e-12);
  EXPECT_TRUE(grip.dragging());
  grip.EndTranslate();
  grip.Translate({eye, -eye});
  EXPECT_NEAR((grip.p0() - (Eigen::Vector3d(0.01, 0.02, 0.03) + 0.03 * right - 0.04 * up)).norm(),
              0.0, 1e-12);  // no drag: ignored
}

TEST(GripControl, ClampsPositionInsideTheFrameAndGraspToItsRange) {
  const SpidarGeometry g;
  GripControl grip(g);
  grip.SetPose({1.0, -1.0, 0.1}, Eigen::Matrix3d::Identity(), 3.0);
  const double limit = g.a - g.d - GripControl::kMargin;  // 0.19 m
  EXPECT_NEAR(grip.p0().x(), limit, 1e-15);
  EXPECT_NEAR(grip.p0().y(), -limit, 1e-15);
  EXPECT_NEAR(grip.p0().z(), 0.1, 1e-15);
  EXPECT_NEAR(grip.grasp(), 160.0 * kPi / 180.0, 1e-12);
  grip.AdjustGrasp(-10.0);
  EXPECT_NEAR(grip.grasp(), 20.0 * kPi / 180.0, 1e-12);
  grip.AdjustGrasp(5.0 * kPi / 180.0);
  EXPECT_NEAR(grip.grasp(), 25.0 * kPi / 180.0, 1e-12);
}

TEST(GripControl, RotateComposesOnTheLeftAndStaysOrthonormal) {
  const SpidarGeometry g;
  GripControl grip(g);
  grip.Rotate(Eigen::Vector3d(0, 0, 2.0), kPi / 2);  // axis need not be unit length
  Eigen::Matrix3d Rz;
  Rz << 0, -1, 0, 1, 0, 0, 0, 0, 1;
  EXPECT_NEAR((grip.R() - Rz).norm(), 0.0, 1e-12);
  for (int k = 0; k < 1000; ++k) grip.Rotate(Eigen::Vector3d(0.3, -0.5, 0.8), 0.0137);
  EXPECT_NEAR((grip.R().transpose() * grip.R() - Eigen::Matrix3d::Identity()).norm(), 0.0, 1e-12);
  EXPECT_NEAR(grip.R().determinant(), 1.0, 1e-12);
  // The pole vectors keep length d.
  EXPECT_NEAR(grip.Pose().p1.norm(), g.d, 1e-12);
  EXPECT_NEAR(grip.Pose().p2.norm(), g.d, 1e-12);
}

TEST(DemoSpringWrench, MatchesTheClosedFormSprings) {
  const SpidarGeometry g;
  DemoFieldSettings field;
  // Translation only: f = −k p0, no moment, no grasp torque.
  GripPose pose =
      GripPose::FromFrame({0.05, -0.02, 0.03}, Eigen::Matrix3d::Identity(), kPi / 2, g.d);
  haptics::Vector7d q = DemoSpringWrench(field, pose);
  EXPECT_NEAR(q[0], -5.0, 1e-12);
  EXPECT_NEAR(q[1], 2.0, 1e-12);
  EXPECT_NEAR(q[2], -3.0, 1e-12);
  EXPECT_NEAR(q.tail<4>().norm(), 0.0, 1e-12);
  // A turn of 0.3 rad about z: m = −k_r 0.3 z.
  pose =
      GripPose::FromFrame(Eigen::Vector3d::Zero(),
                          Eigen::AngleAxisd(0.3, Eigen::Vector3d::UnitZ()).matrix(), kPi / 2, g.d);
  q = DemoSpringWrench(field, pose);
  EXPECT_NEAR((q.segment<3>(3) - Eigen::Vector3d(0, 0, -0.3 * field.k_rotation)).norm(), 0.0,
              1e-12);
  // Grasp: −g/2 is the generalised force on θ, which must be −dU/dθ for
  // U = ½ k_g (θ − π/2)²; check it by central differences of U.
  const double theta = 1.9, h = 1e-6;
  pose = GripPose::FromFrame(Eigen::Vector3d::Zero(), Eigen::Matrix3d::Identity(), theta, g.d);
  q = DemoSpringWrench(field, pose);
  auto U = [&](double t) { return 0.5 * field.k_grasp * (t - kPi / 2) * (t - kPi / 2); };
  EXPECT_NEAR(-q[6] / 2.0, -(U(theta + h) - U(theta - h)) / (2 * h), 1e-8);
  EXPECT_GT(q[6], 0.0);  // opened beyond rest: the field squeezes (g > 0 closes)
  field.enabled = false;
  EXPECT_EQ(DemoSpringWrench(field, pose), haptics::Vector7d::Zero());
}

TEST(HapticRuntime, IdealDeviceMeasuresTheTargetAndCommandsTheClosedFormSpringWrench) {
  RuntimeSettings settings;
  settings.device = RuntimeDevice::kIdeal;
  const SpidarGeometry g;
  const GripPose target = GripPose::FromFrame(
      {0.06, -0.04, 0.05}, Eigen::AngleAxisd(0.2, Eigen::Vector3d(1, 2, 3).normalized()).matrix(),
      1.8, g.d);
  HapticRuntime runtime(settings, GripPose::Rest(g.d));
  DemoFieldSettings field;
  runtime.Publish(SpringScene(field));
  runtime.SetTarget(target);
  RunTicks(&runtime, 800);  // past the 0.5 s force ramp
  const RuntimeFrame& f = runtime.Latest();
  ASSERT_EQ(f.tool.fk_status, haptics::FkStatus::kOk);
  EXPECT_EQ(f.tool.ramp, 1.0);
  // The rigid hand puts the grip at the target; the encoders see it to within quantisation.
  EXPECT_NEAR((f.hand_pose.p0 - target.p0).norm(), 0.0, 1e-12);
  EXPECT_LT((f.tool.pose_D.p0 - target.p0).norm(), 1e-4);
  const haptics::Vector8d exact = haptics::InverseKinematics(g, target);
  EXPECT_LT((f.lengths - exact).cwiseAbs().maxCoeff(), 1e-4);
  // The commanded wrench is the closed-form spring wrench at the measured pose (no damping at
  // rest, no limit reached: |f| = 100 N/m · 8.8 cm).
  const haptics::Vector7d expected = DemoSpringWrench(field, f.tool.pose_D);
  EXPECT_LT((f.tool.wrench_D - expected).norm(), 0.02 * expected.norm())
      << f.tool.wrench_D.transpose() << " vs " << expected.transpose();
  // Displayed = A τ at the measured pose, tensions within the solver's bounds.
  const haptics::TensionSettings& ts = runtime.loop().settings().tension;
  EXPECT_LT((haptics::WrenchMatrix(g, f.tool.pose_D) * f.tool.tau - f.tool.displayed_D).norm(),
            1e-9);
  for (int i = 0; i < haptics::kNumStrings; ++i) {
    EXPECT_GE(f.tool.tau[i], ts.tau_min - 1e-9);
    EXPECT_LE(f.tool.tau[i], ts.tau_max + 1e-9);
  }
  EXPECT_EQ(runtime.ticks(), 800u);
}

TEST(HapticRuntime, SimulatedHandSettlesWhereItsSpringBalancesTheField) {
  // Hand spring k_h toward the target p_t, centring spring k toward 0: at rest
  // k_h (p_t − p) = k p, so p = k_h p_t / (k_h + k).
  RuntimeSettings settings;  // simulated device with encoder errors, calibrated; hand 300 N/m
  const SpidarGeometry g;
  HapticRuntime runtime(settings, GripPose::Rest(g.d));
  DemoFieldSettings field;
  field.k_translation = 150.0;
  field.k_rotation = 0.0;
  field.k_grasp = 0.0;
  runtime.Publish(SpringScene(field));
  const Eigen::Vector3d p_target(0.05, 0.03, -0.04);
  runtime.SetTarget(GripPose::FromFrame(p_target, Eigen::Matrix3d::Identity(), kPi / 2, g.d));
  RunTicks(&runtime, 3000);
  const RuntimeFrame& f = runtime.Latest();
  const double kh = settings.hand.stiffness, k = field.k_translation;
  const Eigen::Vector3d expected = kh * p_target / (kh + k);
  // Calibrated encoders measure to ~0.3 mm; the strings display the spring to a few per cent.
  EXPECT_LT((f.hand_pose.p0 - expected).norm(), 2e-3)
      << f.hand_pose.p0.transpose() << " vs " << expected.transpose();
  EXPECT_LT((f.tool.pose_D.p0 - f.hand_pose.p0).norm(), 1.5e-3);
  EXPECT_GT((f.hand_pose.p0 - p_target).norm(), 0.01);  // really pushed back by the device
  EXPECT_NE(runtime.description().find("line-fit"), std::string::npos) << runtime.description();
}

TEST(HapticRuntime, TicksAllocateNothingWithSolidsAndSprings) {
  ASSERT_TRUE(test_support::MallocCounterActive());
  SceneModel model;
  model.Load(kDemoSceneName, GripControl(SpidarGeometry{}).limits());
  RuntimeSettings settings;
  settings.loop.X_WD.world_scale = model.device_to_world().world_scale;
  settings.loop.X_WD.p_WDo = model.device_to_world().p_WDo;
  const SpidarGeometry g;
  HapticRuntime runtime(settings, GripPose::Rest(g.d));
  DemoFieldSettings field;
  runtime.Publish(model.BuildHapticScene(field));
  // Push the grip down into the bracket, so that the contact (proxy) fields work too.
  runtime.SetTarget(
      GripPose::FromFrame({-0.04, 0, -0.07}, Eigen::Matrix3d::Identity(), kPi / 2, g.d));
  RunTicks(&runtime, 300);
  long allocations = 0;
  {
    test_support::MallocCounter counter;
    RunTicks(&runtime, 1000);
    allocations = counter.count();
  }
  EXPECT_EQ(allocations, 0);
  // The solid pushes up (+z) on the grip centre inside the bracket.
  EXPECT_GT(runtime.Latest().tool.wrench_D.z(), 1.0);
}

// The six-DOF shell (ContinuousShellField) and the proxy (ContinuousProxyField) in contact, and
// the first ticks after a republish, when the fresh field warm-starts from the hand-off: no tick
// allocates.
TEST(HapticRuntime, TicksAllocateNothingInContactAndAcrossARepublishForEitherTool) {
  ASSERT_TRUE(test_support::MallocCounterActive());
  for (const ToolModel tool : {ToolModel::kShell, ToolModel::kProxy}) {
    SCOPED_TRACE(ToolModelName(tool));
    SceneModel model;
    model.Load(kDemoSceneName, GripControl(SpidarGeometry{}).limits());
    RuntimeSettings settings;
    settings.loop.X_WD.world_scale = model.device_to_world().world_scale;
    settings.loop.X_WD.p_WDo = model.device_to_world().p_WDo;
    const SpidarGeometry g;
    HapticRuntime runtime(settings, GripPose::Rest(g.d));
    DemoFieldSettings field;
    SceneHapticsOptions options;
    options.tool = tool;
    runtime.Publish(model.BuildHapticScene(field, options));
    runtime.SetTarget(
        GripPose::FromFrame({-0.04, 0, -0.07}, Eigen::Matrix3d::Identity(), kPi / 2, g.d));
    RunTicks(&runtime, 300);
    ASSERT_GT(runtime.Latest().tool.wrench_D.z(), 1.0);  // in contact
    // The same fields again (the old field goes on), then a stiffer setting (a fresh field,
    // warm-started from the hand-off), as slider moves do.
    for (const double stiffness_factor : {1.0, 1.2}) {
      options.stiffness *= stiffness_factor;
      runtime.Publish(model.BuildHapticScene(field, options));
      long allocations = 0;
      {
        test_support::MallocCounter counter;
        RunTicks(&runtime, 300);
        allocations = counter.count();
      }
      EXPECT_EQ(allocations, 0) << "stiffness x" << stiffness_factor;
      EXPECT_GT(runtime.Latest().tool.wrench_D.z(), 1.0);  // still in contact after the republish
    }
  }
}

TEST(HapticRuntime, EmergencyStopLatchesZeroForceAndRearmRampsBackLinearly) {
  RuntimeSettings settings;
  settings.device = RuntimeDevice::kIdeal;
  const SpidarGeometry g;
  HapticRuntime runtime(settings, GripPose::Rest(g.d));
  runtime.Publish(SpringScene(DemoFieldSettings{}));
  runtime.SetTarget(
      GripPose::FromFrame({0.05, 0.0, 0.0}, Eigen::Matrix3d::Identity(), kPi / 2, g.d));
  RunTicks(&runtime, 700);
  ASSERT_GT(runtime.Latest().tool.wrench_D.head<3>().norm(), 4.0);
  runtime.EmergencyStop();
  const haptics::TensionSettings& ts = runtime.loop().settings().tension;
  for (int k = 0; k < 200; ++k) {
    RunTicks(&runtime, 1);
    const RuntimeFrame& f = runtime.Latest();
    ASSERT_TRUE(f.tool.events & haptics::kEventEmergencyStop) << "tick " << k;
    ASSERT_EQ(f.tool.wrench_D, haptics::Vector7d::Zero()) << "tick " << k;
    ASSERT_LE(f.tool.tau.maxCoeff(), ts.tau_min + 1e-12) << "tick " << k;
  }
  EXPECT_TRUE(runtime.emergency_stopped());
  EXPECT_GE(runtime.loop().event_counts()[4], 200u);  // bit 4: emergency_stop
  runtime.Rearm();
  const double ramp_time = runtime.loop().settings().ramp_time;
  for (int n = 1; n <= 300; ++n) {
    RunTicks(&runtime, 1);
    ASSERT_NEAR(runtime.Latest().tool.ramp, std::min(1.0, n * 1e-3 / ramp_time), 1e-9) << n;
  }
  RunTicks(&runtime, 300);
  EXPECT_EQ(runtime.Latest().tool.ramp, 1.0);
  EXPECT_GT(runtime.Latest().tool.wrench_D.head<3>().norm(), 4.0);
}

TEST(HapticRuntime, RunsOnItsOwnThreadAndReportsOrderedStatistics) {
  RuntimeSettings settings;
  settings.device = RuntimeDevice::kIdeal;
  HapticRuntime runtime(settings, GripPose::Rest(SpidarGeometry{}.d));
  runtime.Publish(SpringScene(DemoFieldSettings{}));
  runtime.Start();
  std::this_thread::sleep_for(std::chrono::milliseconds(300));
  runtime.Stop();
  const LoopStats s = CollectLoopStats(runtime, runtime.Latest());
  EXPECT_GT(s.ticks, 0u);
  EXPECT_NE(s.realtime, haptics::RealtimeStatus::kNotStarted);
  for (const auto* v : {&s.step, &s.tick, &s.jitter}) {
    EXPECT_LE((*v)[0], (*v)[1]);
    EXPECT_LE((*v)[1], (*v)[2]);
    EXPECT_LE((*v)[2], (*v)[3] + 1e-7);  // percentiles are bin upper edges (0.1 µs)
  }
  EXPECT_GT(s.step[3], 0.0);
  EXPECT_GE(s.tick[3], s.step[3] - 1e-7);  // the tick contains the step
  const std::string text = FormatLoopSummary(s);
  EXPECT_NE(text.find("loop: " + std::to_string(s.ticks) + " ticks"), std::string::npos) << text;
  for (int i = 0; i < haptics::kNumSafetyEvents; ++i) {
    EXPECT_NE(text.find(haptics::SafetyEventName(i)), std::string::npos) << text;
  }
}

TEST(CentringSpringField, FeelsLikeTheDeviceFrameSpringsThroughXwd) {
  const SpidarGeometry g;
  DemoFieldSettings demo;
  const double s = 2.5;
  const Eigen::Vector3d o(0.3, -0.2, 1.0);
  CentringSpringField field(demo, {s, o});
  const Eigen::Matrix3d R = Eigen::AngleAxisd(0.3, Eigen::Vector3d(0, 1, 1).normalized()).matrix();
  const Eigen::Vector3d p_D(0.05, -0.02, 0.03);
  haptics::ToolKinematics tool;
  tool.p_WT = s * p_D + o;  // the loop's X_WD
  tool.R_WT = R;
  tool.grasp = 1.9;
  const haptics::ToolWrench w = field.Evaluate(tool);
  const haptics::Vector7d q = DemoSpringWrench(demo, GripPose::FromFrame(p_D, R, 1.9, g.d));
  EXPECT_LT((w.f_T_W - q.head<3>()).norm(), 1e-12);
  EXPECT_LT((w.m_T_W - q.segment<3>(3)).norm(), 1e-12);
  EXPECT_NEAR(w.g, q[6], 1e-12);
}

TEST(ChooseDeviceToWorld, KeepsSmallScenesAtScaleOneAndFitsLargeOnesInReach) {
  const Eigen::Vector3d travel(0.19, 0.19, 0.19);
  const Eigen::AlignedBox3d small(Eigen::Vector3d(-0.05, 0.0, 0.1),
                                  Eigen::Vector3d(0.05, 0.1, 0.15));
  DeviceToWorld x = ChooseDeviceToWorld(small, travel);
  EXPECT_EQ(x.world_scale, 1.0);
  EXPECT_LT((x.p_WDo - Eigen::Vector3d(0.0, 0.05, 0.15 + 0.06)).norm(), 1e-12);
  // A 4 m platform: every corner lands inside the travel, below the device centre.
  const Eigen::AlignedBox3d big(Eigen::Vector3d(0, -1, -0.5), Eigen::Vector3d(4, 1, 0.2));
  x = ChooseDeviceToWorld(big, travel);
  EXPECT_NEAR(x.world_scale, 4.0 / (1.6 * 0.19), 1e-12);
  for (int c = 0; c < 8; ++c) {
    const Eigen::Vector3d p_D =
        (big.corner(static_cast<Eigen::AlignedBox3d::CornerType>(c)) - x.p_WDo) / x.world_scale;
    EXPECT_LE(p_D.cwiseAbs().maxCoeff(), 0.19 + 1e-12) << p_D.transpose();
    EXPECT_LT(p_D.z(), 0.0);
  }
  EXPECT_EQ(ChooseDeviceToWorld(Eigen::AlignedBox3d(), travel).world_scale, 1.0);
}

// Waits for every job of `jobs` to end, then polls the queue.
void Drain(JobQueue* jobs) {
  for (const auto& job : jobs->jobs()) job->Wait();
  jobs->Poll();
}

TEST(SceneModel, LoadsTheDemoAndMeshesPreviewsThatMatchTheKnobSphere) {
  SceneModel model;
  model.Load(kDemoSceneName, Eigen::Vector3d::Constant(0.19));
  ASSERT_EQ(model.objects().size(), 2u);
  EXPECT_EQ(model.objects()[1].name, "knob");
  EXPECT_EQ(model.objects()[0].preview.triangles.cols(), 0);
  JobQueue jobs;
  model.StartPreviewJobs(&jobs, 24.0);
  Drain(&jobs);
  const SceneObject& knob = model.objects()[1];
  ASSERT_GT(knob.preview.triangles.cols(), 100);
  EXPECT_EQ(knob.revision, 1);
  const double r = 0.035, exact = 4.0 / 3.0 * kPi * r * r * r;
  EXPECT_NEAR(modeling::MeshVolume(knob.preview), exact, 0.03 * exact);
  // 'none' is empty; a bad file names itself and leaves the model as it was.
  EXPECT_THROW(model.Load("/nonexistent/scene.json", Eigen::Vector3d::Constant(0.19)),
               std::exception);
  EXPECT_EQ(model.objects().size(), 2u);
  try {
    model.Load("/nonexistent/scene.json", Eigen::Vector3d::Constant(0.19));
  } catch (const std::exception& e) {
    EXPECT_NE(std::string(e.what()).find("/nonexistent/scene.json"), std::string::npos) << e.what();
  }
  model.Load(kNoSceneName, Eigen::Vector3d::Constant(0.19));
  EXPECT_TRUE(model.objects().empty());
  EXPECT_EQ(model.BuildHapticScene(DemoFieldSettings{})->size(), 1);  // the springs only
}

// Model mode's Mesh action with a cell size (and otherwise default settings).
MeshSettings MeshCell(double cell) {
  MeshSettings s;
  s.cell_size = cell;
  return s;
}

// The mesh data of Document object `id`.
const MeshData& MeshOf(const Document& doc, ObjectId id) {
  return std::get<MeshData>(doc.Get(id).data);
}

// The Mesh action lands its result in the Document as one mesh object (one undo step); a failed
// or cancelled job changes nothing, neither the Document nor its history.
TEST(SceneModel, MeshJobsLandOnSuccessAndChangeNothingOnFailureOrCancel) {
  SceneModel model;
  model.Load(kDemoSceneName, Eigen::Vector3d::Constant(0.19));
  const Document& doc = model.document();
  const std::string loaded = doc.ToJson(true).dump();
  JobQueue jobs;
  // Failure: a grid far beyond 2^30 cells is refused by the mesher.
  Job& bad = model.StartMeshJob(&jobs, 1, MeshKind::kSurface, MeshCell(1e-6));
  Drain(&jobs);
  EXPECT_EQ(bad.state(), Job::State::kFailed);
  EXPECT_FALSE(bad.error().empty());
  EXPECT_EQ(doc.ToJson(true).dump(), loaded);
  EXPECT_EQ(doc.history().undo_size(), 0u);
  EXPECT_EQ(model.TakeLandedMesh(), 0u);
  jobs.Prune();
  // Cancel before the worker gets far: no result lands.
  Job& cancelled = model.StartMeshJob(&jobs, 0, MeshKind::kSurface, MeshCell(0.0005));
  cancelled.Cancel();
  Drain(&jobs);
  EXPECT_EQ(cancelled.state(), Job::State::kCancelled);
  EXPECT_EQ(doc.ToJson(true).dump(), loaded);
  EXPECT_EQ(doc.history().undo_size(), 0u);
  jobs.Prune();
  // Success: tetrahedra of the knob whose volume matches the sphere's.
  MeshSettings settings = MeshCell(0.005);
  settings.mesher = "tetgen";
  Job& good = model.StartMeshJob(&jobs, 1, MeshKind::kTetrahedra, settings);
  EXPECT_EQ(good.title(), "Tetrahedra of knob");
  Drain(&jobs);
  ASSERT_EQ(good.state(), Job::State::kSucceeded) << good.error();
  const ObjectId id = model.TakeLandedMesh();
  ASSERT_NE(id, 0u);
  EXPECT_EQ(model.TakeLandedMesh(), 0u) << "taken once";
  const DocObject& knob = *doc.FindByName("knob");
  EXPECT_EQ(doc.Get(id).name, "knob tets");
  const MeshData& m = MeshOf(doc, id);
  EXPECT_EQ(m.source, knob.id);
  EXPECT_EQ(m.source_revision, knob.revision);
  EXPECT_EQ(m.settings.cell_size, 0.005);
  EXPECT_EQ(m.settings.mesher, "tetgen");
  EXPECT_FALSE(doc.IsMeshOutOfDate(id));
  ASSERT_TRUE(m.volume && m.surface);
  ASSERT_GT(m.volume->tets.cols(), 50);
  const double r = 0.035, exact = 4.0 / 3.0 * kPi * r * r * r;
  EXPECT_NEAR(modeling::TotalVolume(*m.volume), exact, 0.05 * exact);
  EXPECT_NEAR(modeling::TotalVolume(*m.volume), modeling::MeshVolume(*m.surface), 1e-6 * exact);
  ASSERT_EQ(doc.history().undo_size(), 1u);
  EXPECT_EQ(doc.history().UndoDescription(), "Mesh knob (tetrahedra)");
  EXPECT_THROW(model.StartMeshJob(&jobs, 7, MeshKind::kSurface, MeshCell(0.01)), std::out_of_range);
  EXPECT_THROW(model.StartMeshJob(&jobs, 1, MeshKind::kSurface, MeshCell(0.0)),
               std::invalid_argument);
  MeshSettings bad_settings = MeshCell(0.005);
  bad_settings.mesher = "cgal";
  bad_settings.sharp_edges = true;
  EXPECT_THROW(model.StartMeshJob(&jobs, 1, MeshKind::kTetrahedra, bad_settings), DocumentError);
}

// Undo removes the mesh object, redo brings it back with the same id and content, and the saved
// document reopens with the same mesh (binary storage), up to date with its solid.
TEST(SceneModel, LandedMeshUndoesRedoesAndSurvivesSaveAndReopen) {
  SceneModel model;
  model.Load(kDemoSceneName, Eigen::Vector3d::Constant(0.19));
  Document& doc = model.document();
  const std::string loaded = doc.ToJson(true).dump();
  JobQueue jobs;
  MeshSettings settings = MeshCell(0.004);
  settings.sharp_edges = true;
  settings.mesher = "cgal";  // ignored by a surface: the grid surface has no tetrahedral mesher
  model.StartMeshJob(&jobs, 0, MeshKind::kSurface, settings);
  Drain(&jobs);
  const ObjectId id = model.TakeLandedMesh();
  ASSERT_NE(id, 0u);
  EXPECT_EQ(doc.Get(id).name, "bracket surface");
  EXPECT_EQ(doc.history().UndoDescription(), "Mesh bracket (surface)");
  const MeshData landed = MeshOf(doc, id);
  ASSERT_TRUE(landed.surface);
  EXPECT_FALSE(landed.volume) << "a surface only";
  EXPECT_TRUE(landed.settings.sharp_edges);
  EXPECT_EQ(landed.settings.mesher, "");
  EXPECT_TRUE(IsClosedSurface(*landed.surface));
  // The bracket: a 140 x 100 x 50 mm box with 6 mm rounded edges and corners (Steiner's formula:
  // the inner box grown by a ball of radius r) minus a 22 mm bore through its 50 mm height,
  // within 3 %.
  const double r = 0.006, x = 0.14 - 2 * r, y = 0.10 - 2 * r, z = 0.05 - 2 * r;
  const double box = x * y * z + 2 * (x * y + y * z + z * x) * r + kPi * (x + y + z) * r * r +
                     4.0 / 3.0 * kPi * r * r * r;
  const double exact = box - kPi * 0.022 * 0.022 * 0.05;
  EXPECT_NEAR(modeling::MeshVolume(*landed.surface), exact, 0.03 * exact);
  const std::string after = doc.ToJson(true).dump();
  ASSERT_TRUE(doc.Undo());
  EXPECT_EQ(doc.ToJson(true).dump(), loaded);
  EXPECT_EQ(doc.Find(id), nullptr);
  ASSERT_TRUE(doc.Redo());
  EXPECT_EQ(doc.ToJson(true).dump(), after) << "redo brings back the same id and content";
  // Save and reopen: the same surface bit for bit, settings and source, not stale.
  const std::string dir = std::string(SPIDARCAD_TEST_OUTPUT_DIR) + "/scene_model_mesh";
  std::filesystem::create_directories(dir);
  const std::string path = dir + "/meshed.json";
  model.Save(path);
  Document reread;
  reread.Load(path);
  const DocObject* mesh = reread.FindByName("bracket surface");
  ASSERT_NE(mesh, nullptr);
  const MeshData& back = std::get<MeshData>(mesh->data);
  ASSERT_TRUE(back.surface);
  EXPECT_FALSE(back.volume);
  EXPECT_EQ(back.surface->vertices, landed.surface->vertices);
  EXPECT_EQ(back.surface->triangles, landed.surface->triangles);
  EXPECT_EQ(back.source, reread.FindByName("bracket")->id);
  EXPECT_EQ(back.settings.cell_size, 0.004);
  EXPECT_TRUE(back.settings.sharp_edges);
  EXPECT_FALSE(reread.IsMeshOutOfDate(mesh->id));
}

// A solid edited or deleted while its mesh job runs: the job fails saying so and nothing lands.
TEST(SceneModel, MeshOfASolidThatChangedOrWentAwayWhileMeshingLandsNothing) {
  SceneModel model;
  model.Load(kDemoSceneName, Eigen::Vector3d::Constant(0.19));
  Document& doc = model.document();
  JobQueue jobs;
  const ObjectId knob = doc.FindByName("knob")->id;
  Job& job = model.StartMeshJob(&jobs, 1, MeshKind::kSurface, MeshCell(0.005));
  // The edit lands on the main thread before the job's finisher (Poll) runs.
  doc.Execute(edit::SetNodeField(knob, {0}, "radius", 0.04));
  const std::string edited = doc.ToJson(true).dump();
  Drain(&jobs);
  EXPECT_EQ(job.state(), Job::State::kFailed);
  EXPECT_NE(job.error().find("'knob' changed while it was meshed"), std::string::npos)
      << job.error();
  EXPECT_EQ(doc.ToJson(true).dump(), edited);
  EXPECT_EQ(doc.history().undo_size(), 1u) << "the edit only";
  EXPECT_EQ(model.TakeLandedMesh(), 0u);
  jobs.Prune();
  Job& gone = model.StartMeshJob(&jobs, 1, MeshKind::kTetrahedra, MeshCell(0.006));
  doc.Execute(edit::DeleteObject(knob));
  const std::string deleted = doc.ToJson(true).dump();
  Drain(&jobs);
  EXPECT_EQ(gone.state(), Job::State::kFailed);
  EXPECT_NE(gone.error().find("'knob' was deleted"), std::string::npos) << gone.error();
  EXPECT_EQ(doc.ToJson(true).dump(), deleted);
}

// Refresh meshes a stale mesh object again from its edited solid with the stored settings, as
// one undo step; undo makes it stale again; a cancelled refresh changes nothing.
TEST(SceneModel, RefreshRemeshesAStaleMeshFromItsSourceInOneUndoStep) {
  SceneModel model;
  model.Load(kDemoSceneName, Eigen::Vector3d::Constant(0.19));
  Document& doc = model.document();
  JobQueue jobs;
  model.StartMeshJob(&jobs, 1, MeshKind::kSurface, MeshCell(0.004));
  Drain(&jobs);
  jobs.Prune();
  const ObjectId id = model.TakeLandedMesh();
  ASSERT_NE(id, 0u);
  const auto old_surface = MeshOf(doc, id).surface;
  const ObjectId knob = doc.FindByName("knob")->id;
  EXPECT_THROW(model.StartRefreshJob(&jobs, knob), DocumentError) << "a solid has no source";
  doc.Execute(edit::SetNodeField(knob, {0}, "radius", 0.045));
  model.Refresh();
  ASSERT_TRUE(doc.IsMeshOutOfDate(id));
  const std::string stale = doc.ToJson(true).dump();
  const std::size_t steps = doc.history().undo_size();
  Job& cancelled = model.StartRefreshJob(&jobs, id);
  cancelled.Cancel();
  Drain(&jobs);
  EXPECT_EQ(cancelled.state(), Job::State::kCancelled);
  EXPECT_EQ(doc.ToJson(true).dump(), stale);
  jobs.Prune();
  Job& job = model.StartRefreshJob(&jobs, id);
  EXPECT_EQ(job.title(), "Refresh knob surface");
  Drain(&jobs);
  ASSERT_EQ(job.state(), Job::State::kSucceeded) << job.error();
  EXPECT_EQ(doc.history().undo_size(), steps + 1);
  EXPECT_FALSE(doc.IsMeshOutOfDate(id));
  const MeshData& m = MeshOf(doc, id);
  EXPECT_EQ(m.settings.cell_size, 0.004);
  EXPECT_FALSE(m.volume) << "still a surface only";
  const double r = 0.045, exact = 4.0 / 3.0 * kPi * r * r * r;
  EXPECT_NEAR(modeling::MeshVolume(*m.surface), exact, 0.03 * exact);
  EXPECT_EQ(model.TakeLandedMesh(), 0u) << "a refresh adds no object";
  ASSERT_TRUE(doc.Undo());
  EXPECT_TRUE(doc.IsMeshOutOfDate(id));
  EXPECT_EQ(MeshOf(doc, id).surface, old_surface);
  ASSERT_TRUE(doc.Undo());  // the edit: the old mesh is up to date again
  EXPECT_FALSE(doc.IsMeshOutOfDate(id));
}

// Export writes a mesh object's surface and tetrahedra in every format and explains bad paths.
TEST(Export, WritesFilesThatReadBackAndExplainsBadPaths) {
  SceneModel model;
  model.Load(kDemoSceneName, Eigen::Vector3d::Constant(0.19));
  JobQueue jobs;
  model.StartMeshJob(&jobs, 1, MeshKind::kTetrahedra, MeshCell(0.006));
  Drain(&jobs);
  const ObjectId id = model.TakeLandedMesh();
  ASSERT_NE(id, 0u);
  const MeshData& knob = MeshOf(model.document(), id);
  ASSERT_TRUE(knob.surface && knob.volume);
  ASSERT_GT(knob.volume->tets.cols(), 0);
  const modeling::TriangleMesh& surface = *knob.surface;
  const modeling::TetMesh& tets = *knob.volume;
  const std::string dir = std::string(SPIDARCAD_TEST_OUTPUT_DIR) + "/gui_export";
  std::filesystem::create_directories(dir);
  for (const char* ext : {".stl", ".obj", ".ply"}) {
    const std::string path = dir + "/knob" + ext;
    ASSERT_EQ(ExportSurface(surface, path), "") << path;
    const modeling::TriangleMesh back = modeling::ReadTriangleMesh(path);
    EXPECT_EQ(back.triangles.cols(), surface.triangles.cols()) << ext;
    EXPECT_NEAR(modeling::MeshVolume(back), modeling::MeshVolume(surface),
                1e-5 * modeling::MeshVolume(surface))
        << ext;
  }
  EXPECT_NE(ExportSurface(surface, dir + "/knob.xyz").find(".stl"), std::string::npos);
  EXPECT_FALSE(ExportSurface(surface, "/nonexistent/dir/knob.stl").empty());
  EXPECT_NE(ExportSurface(modeling::TriangleMesh{}, dir + "/x.stl").find("nothing"),
            std::string::npos);
  ASSERT_EQ(ExportTetrahedra(tets, dir + "/knob.vtu"), "");
  const std::string vtu = test_support::ReadWholeFile(dir + "/knob.vtu");
  EXPECT_NE(vtu.find("NumberOfCells=\"" + std::to_string(tets.tets.cols()) + "\""),
            std::string::npos);
  ASSERT_EQ(ExportTetrahedra(tets, dir + "/knob.node"), "");
  EXPECT_TRUE(std::filesystem::exists(dir + "/knob.ele"));
  EXPECT_NE(ExportTetrahedra(tets, dir + "/knob.stl").find(".vtu"), std::string::npos);
  EXPECT_NE(ExportTetrahedra(modeling::TetMesh{}, dir + "/x.vtu").find("nothing"),
            std::string::npos);
}

TEST(GuiOptions, ParsesSizeAndGripAndRejectsBadValues) {
  int w = 0, h = 0;
  ParseWindowSize("1024x640", &w, &h);
  EXPECT_EQ(w, 1024);
  EXPECT_EQ(h, 640);
  EXPECT_THROW(ParseWindowSize("1024", &w, &h), CLI::ValidationError);
  EXPECT_THROW(ParseWindowSize("100x100", &w, &h), CLI::ValidationError);
  EXPECT_THROW(ParseWindowSize("800x600junk", &w, &h), CLI::ValidationError);
  std::array<double, 7> grip = {0, 0, 0, 0, 0, 0, 90};
  ParseGripPose("10,-20,30", &grip);
  EXPECT_EQ(grip, (std::array<double, 7>{10, -20, 30, 0, 0, 0, 90}));
  ParseGripPose("1,2,3,4,5,6,100", &grip);
  EXPECT_EQ(grip, (std::array<double, 7>{1, 2, 3, 4, 5, 6, 100}));
  try {
    ParseGripPose("1,2,x", &grip);
    FAIL() << "no exception";
  } catch (const CLI::ValidationError& e) {
    EXPECT_NE(std::string(e.what()).find("z [mm]"), std::string::npos) << e.what();
  }
  EXPECT_THROW(ParseGripPose("1,2,3,4", &grip), CLI::ValidationError);
}

// --set, --recover / --no-recover, --autosave-interval and --show as the command line gives them.
TEST(GuiOptions, ParsesDocumentOptionsAndRejectsBadOnes) {
  const SetFieldEdit e = ParseSetField("base/0/1:size=[0.1, 0.2, 0.3]");
  EXPECT_EQ(e.node, "base/0/1");
  EXPECT_EQ(e.field, "size");
  EXPECT_EQ(e.value, "[0.1, 0.2, 0.3]");
  const SetFieldEdit colon = ParseSetField("a:b:radius=0.5");  // the last ':' before '='
  EXPECT_EQ(colon.node, "a:b");
  EXPECT_EQ(colon.field, "radius");
  for (const char* bad : {"knob", "knob=1", ":radius=1", "knob:=1", "knob:radius="}) {
    EXPECT_THROW(ParseSetField(bad), CLI::ValidationError) << bad;
  }
  auto parse = [](std::vector<std::string> args, GuiOptions* options) {
    CLI::App app;
    AddGuiOptions(app, options);
    std::reverse(args.begin(), args.end());
    app.parse(args);
  };
  GuiOptions o;
  parse({"scene.json", "--set", "knob:radius=0.04", "--set", "lid:height=0.01", "--recover",
         "--autosave-interval", "0.5", "--show", "open"},
        &o);
  EXPECT_EQ(o.scene, "scene.json");
  EXPECT_EQ(o.set_fields, (std::vector<std::string>{"knob:radius=0.04", "lid:height=0.01"}));
  EXPECT_EQ(o.recover, 1);
  EXPECT_EQ(o.autosave_interval, 0.5);
  EXPECT_EQ(o.show, "open");
  GuiOptions n;
  parse({"--no-recover", "--show", "calibrate"}, &n);
  EXPECT_EQ(n.recover, 0);
  EXPECT_EQ(n.show, "calibrate");  // the calibration wizard, collecting
  GuiOptions d;
  parse({}, &d);
  EXPECT_EQ(d.recover, -1);
  EXPECT_EQ(d.autosave_interval, 60.0);
  GuiOptions x;
  EXPECT_THROW(parse({"--recover", "--no-recover"}, &x), CLI::ParseError);
  EXPECT_THROW(parse({"--autosave-interval", "0"}, &x), CLI::ParseError);
  EXPECT_THROW(parse({"--set", "nofield"}, &x), CLI::ParseError);
  EXPECT_THROW(parse({"--show", "everything"}, &x), CLI::ParseError);
}

// Runs a shell command; returns its exit status (−1 when it did not exit normally).
int RunCommand(const std::string& command, std::string* output) {
  FILE* pipe = popen(command.c_str(), "r");
  if (pipe == nullptr) return -1;
  char buffer[512];
  while (std::fgets(buffer, sizeof(buffer), pipe) != nullptr) *output += buffer;
  const int status = pclose(pipe);
  return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
}

TEST(SpidarcadWindow, ExplainsHowToRunHeadlessWithoutADisplay) {
  std::string output;
  const int status =
      RunCommand(std::string("env -u DISPLAY '") + SPIDARCAD_EXE + "' 2>&1", &output);
  EXPECT_EQ(status, 1) << output;
  EXPECT_NE(output.find("xvfb-run"), std::string::npos) << output;
}

TEST(SpidarcadWindow, ScreenshotShowsTheDeviceStringsByTensionAndThePanel) {
  // Only the variable: connecting here and disconnecting would let Xvfb reset just as the
  // child connects.
  const char* display = std::getenv("DISPLAY");
  if (display == nullptr || display[0] == '\0') {
    GTEST_SKIP() << "no X display: run the tests under `xvfb-run -a -s \"-screen 0 "
                    "1280x1024x24\" ctest` to include the window smoke test";
  }
  const std::string png = std::string(SPIDARCAD_TEST_OUTPUT_DIR) + "/gui_screenshot.png";
  std::filesystem::remove(png);
  // A displaced grip on the ideal device (rigid hand) in the empty scene, where the centring
  // springs are on, so that the expected tensions are known once the force ramp is over.
  const double x = 70, y = -50, z = 40, grasp = 110;
  std::string output;
  const int status =
      RunCommand(std::string("'") + SPIDARCAD_EXE + "' none --screenshot '" + png +
                     "' --size 1100x720 --device ideal --grip 70,-50,40,0,0,0,110 2>&1",
                 &output);
  ASSERT_EQ(status, 0) << output;
  const vtkSmartPointer<vtkImageData> image = ReadPng(png);
  int dims[3];
  image->GetDimensions(dims);
  ASSERT_EQ(dims[0], 1100);
  ASSERT_EQ(dims[1], 720);
  ASSERT_GE(image->GetNumberOfScalarComponents(), 3);
  const int comps = image->GetNumberOfScalarComponents();
  const auto* px = static_cast<const unsigned char*>(image->GetScalarPointer());
  auto at = [&](int i, int j) {  // column i, row j (bottom up)
    const unsigned char* p = px + (static_cast<size_t>(j) * dims[0] + i) * comps;
    return std::array<int, 3>{p[0], p[1], p[2]};
  };

  // Expected tensions, computed here from the haptics library.
  const SpidarGeometry g;
  const haptics::TensionSettings ts = haptics::TensionSettings::ForPoleLength(g.d);
  const GripPose pose = GripPose::FromFrame(Eigen::Vector3d(x, y, z) * 1e-3,
                                            Eigen::Matrix3d::Identity(), grasp * kPi / 180, g.d);
  haptics::TensionSolver solver(ts);
  const haptics::TensionResult tension =
      solver.Solve(haptics::WrenchMatrix(g, pose), DemoSpringWrench(DemoFieldSettings{}, pose));
  int lo = 0, hi = 0;
  tension.tau.minCoeff(&lo);
  tension.tau.maxCoeff(&hi);
  ASSERT_GT(tension.tau[hi] - tension.tau[lo], 0.3 * (ts.tau_max - ts.tau_min))
      << "pose does not spread the tensions: " << tension.tau.transpose();

  // Pixels of the 3D view (right of the panel) whose chromaticity matches a string colour.
  const int panel = static_cast<int>(kPanelWidth) + 2;
  auto count_colour = [&](const Rgb& rgb) {
    const double s = rgb[0] + rgb[1] + rgb[2];
    int count = 0;
    for (int j = 0; j < dims[1]; ++j) {
      for (int i = panel; i < dims[0]; ++i) {
        const auto p = at(i, j);
        const double ps = p[0] + p[1] + p[2];
        if (ps < 60) continue;
        double err = 0;
        for (int k = 0; k < 3; ++k) err = std::max(err, std::abs(p[k] / ps - rgb[k] / s));
        if (err < 0.035) ++count;
      }
    }
    return count;
  };
  EXPECT_EQ(output.find("before the loop settled"), std::string::npos) << output;
  const Rgb low = TensionColour(tension.tau[lo], ts.tau_min, ts.tau_max);
  const Rgb high = TensionColour(tension.tau[hi], ts.tau_min, ts.tau_max);
  EXPECT_GT(count_colour(low), 40) << "least-tensioned string " << lo + 1 << " not seen";
  EXPECT_GT(count_colour(high), 40) << "most-tensioned string " << hi + 1 << " not seen";

  // A real picture: many distinct colours overall.
  std::set<int> colours;
  for (int j = 0; j < dims[1]; j += 2) {
    for (int i = 0; i < dims[0]; i += 2) {
      const auto p = at(i, j);
      colours.insert((p[0] << 16) | (p[1] << 8) | p[2]);
    }
  }
  EXPECT_GT(colours.size(), 1000u);

  // The panel is drawn: its region differs from the 3D background and contains text (dark
  // pixels) on its light window colour. The background is sampled at the viewport's left edge
  // (the docked layout puts the mode panel at the window's right edge), in the viewport row
  // nearest this row.
  const WindowLayout layout =
      ComputeLayout(static_cast<float>(dims[0]), static_cast<float>(dims[1]));
  const int view_x = static_cast<int>(layout.viewport.x) + 3;
  const int view_lowest = dims[1] - static_cast<int>(layout.viewport.bottom()) + 2;  // bottom up
  const int view_highest = dims[1] - static_cast<int>(layout.viewport.y) - 3;
  int dark = 0, differing = 0;
  for (int j = 0; j < dims[1]; ++j) {
    for (int i = 0; i < panel - 4; ++i) {
      const auto p = at(i, j);
      const auto bg = at(view_x, std::clamp(j, view_lowest, view_highest));  // the 3D background
      if (p[0] + p[1] + p[2] < 200) ++dark;
      if (std::abs(p[0] - bg[0]) + std::abs(p[1] - bg[1]) + std::abs(p[2] - bg[2]) > 20) {
        ++differing;
      }
    }
  }
  EXPECT_GT(dark, 2000);
  EXPECT_GT(differing, (panel - 4) * dims[1] / 2);
}

// Counts pixels of `image` in columns [i0, i1) and rows [j0, j1) (bottom up) whose chromaticity
// is within `tolerance` of `rgb`'s and that are not too dark.
TEST(SpidarcadWindow, DemoSceneDrawsItsSolidsAndTheEmergencyStopZeroesTheStrings) {
  const char* display = std::getenv("DISPLAY");
  if (display == nullptr || display[0] == '\0') {
    GTEST_SKIP() << "no X display: run under xvfb-run to include the window tests";
  }
  const std::string png = std::string(SPIDARCAD_TEST_OUTPUT_DIR) + "/gui_demo_estop.png";
  std::filesystem::remove(png);
  // The built-in demo scene; Space pressed at frame 2 (same path as the key).
  std::string output;
  const int status = RunCommand(std::string("'") + SPIDARCAD_EXE + "' demo --screenshot '" + png +
                                    "' --size 1100x720 --device ideal --estop-frame 2 2>&1",
                                &output);
  ASSERT_EQ(status, 0) << output;
  EXPECT_EQ(output.find("before the loop settled"), std::string::npos) << output;
  const vtkSmartPointer<vtkImageData> image = ReadPng(png);
  int dims[3];
  image->GetDimensions(dims);
  ASSERT_EQ(dims[0], 1100);
  ASSERT_EQ(dims[1], 720);
  const int panel = static_cast<int>(kPanelWidth) + 2;
  const int view_right = dims[0] - 350;  // left of the scene and loop overlays
  // The solids in their colours in the middle of the view (shading keeps chromaticity).
  const int sand =
      CountChromaticity(image, panel, view_right, 0, dims[1] - 60, SceneModel::kColours[0], 0.03);
  const int sage =
      CountChromaticity(image, panel, dims[0], 0, dims[1] - 60, SceneModel::kColours[1], 0.03);
  EXPECT_GT(sand, 3000) << "the bracket (sand) is not drawn";
  EXPECT_GT(sage, 500) << "the knob (sage) is not drawn";
  // The stop banner (205, 25, 25) near the top of the view.
  EXPECT_GT(
      CountChromaticity(image, panel, dims[0], dims[1] - 80, dims[1], {0.80, 0.10, 0.10}, 0.02),
      1500);
  // Zero force: every string at the minimum tension colour, none at the maximum.
  const SpidarGeometry g;
  const haptics::TensionSettings ts = haptics::TensionSettings::ForPoleLength(g.d);
  EXPECT_GT(CountChromaticity(image, panel, view_right, 0, dims[1] - 80,
                              TensionColour(ts.tau_min, ts.tau_min, ts.tau_max), 0.035),
            200);
  EXPECT_EQ(CountChromaticity(image, panel, view_right, 0, dims[1] - 80,
                              TensionColour(ts.tau_max, ts.tau_min, ts.tau_max), 0.02),
            0);
  // The loop statistics the panel shows, as the exit summary prints them.
  EXPECT_NE(output.find("emergency stop: latched"), std::string::npos) << output;
  const size_t at = output.find("loop: ");
  ASSERT_NE(at, std::string::npos) << output;
  EXPECT_GT(std::stol(output.substr(at + 6)), 100) << output;
  const size_t estop = output.find("emergency_stop=");
  ASSERT_NE(estop, std::string::npos) << output;
  EXPECT_GT(std::stol(output.substr(estop + 15)), 0) << output;
  EXPECT_NE(output.find("period jitter [us]: p50"), std::string::npos) << output;
}

// FE mode end to end in the window: `--mode fe` opens the platform scene, meshes and precomputes
// the platform in Jobs, publishes its field; the simulated hand aims the grip so that the tool
// sphere presses the plate top (X_WD of the platform scene: scale 4.57, device centre at
// z = 0.48 m in W; the target is 0.7 mm below the top in W, the hand rests about 5 mm above it).
// The screenshot waits until the field has run (FeMode::Settled); the exit summary must show
// contact, the plate's reaction and an upward commanded force (the FE part is the only field: it is
// felt, not only drawn), within 8 N.
TEST(SpidarcadWindow, FeModeFeelsThePlatformUnderTheGrip) {
  const char* display = std::getenv("DISPLAY");
  if (display == nullptr || display[0] == '\0') GTEST_SKIP() << "no X display";
  const std::string png = std::string(SPIDARCAD_TEST_OUTPUT_DIR) + "/gui_fe_mode.png";
  std::filesystem::remove_all(std::string(SPIDARCAD_TEST_OUTPUT_DIR) + "/fe_cache");
  std::string output;
  const int status =
      RunCommand(std::string("SPIDARCAD_CACHE_DIR='") + SPIDARCAD_TEST_OUTPUT_DIR + "/fe_cache' '" +
                     SPIDARCAD_EXE + "' --mode fe --grip 10,0,-103 --screenshot '" + png + "' 2>&1",
                 &output);
  ASSERT_EQ(status, 0) << output;
  EXPECT_EQ(output.find("before the loop settled"), std::string::npos) << output;
  EXPECT_NE(output.find("fe: ready"), std::string::npos) << output;
  const size_t contacts = output.find("; contacts ");
  ASSERT_NE(contacts, std::string::npos) << output;
  EXPECT_GT(std::stoi(output.substr(contacts + 11)), 0) << output;
  const size_t reaction = output.find("FE force on tool (");
  ASSERT_NE(reaction, std::string::npos) << output;
  std::istringstream fe(output.substr(reaction + 18));
  double rx = 0, ry = 0, rz = 0;
  char sep = 0;
  fe >> rx >> sep >> ry >> sep >> rz;
  EXPECT_GT(rz, 1000.0) << "the plate's reaction on the tool, N, unscaled\n" << output;
  const size_t force = output.find("commanded force D (");
  ASSERT_NE(force, std::string::npos) << output;
  std::istringstream in(output.substr(force + 19));
  double fx = 0, fy = 0, fz = 0;
  char comma = 0;
  in >> fx >> comma >> fy >> comma >> fz;
  EXPECT_GT(fz, 0.1) << output;
  EXPECT_LT(std::sqrt(fx * fx + fy * fy + fz * fz), 8.0 + 1e-9) << output;
}

TEST(SpidarcadWindow, RefusesABadSceneFileWithStatusTwo) {
  const char* display = std::getenv("DISPLAY");
  if (display == nullptr || display[0] == '\0') GTEST_SKIP() << "no X display";
  std::string output;
  const int status = RunCommand(
      std::string("'") + SPIDARCAD_EXE + "' /nonexistent/scene.json --frames 1 2>&1", &output);
  EXPECT_EQ(status, 2) << output;
  EXPECT_NE(output.find("/nonexistent/scene.json"), std::string::npos) << output;
}

TEST(SpidarcadWindow, RefusesATrajectoryItCouldNotPlayWithStatusTwo) {
  const char* display = std::getenv("DISPLAY");
  if (display == nullptr || display[0] == '\0') GTEST_SKIP() << "no X display";
  const std::string exe = std::string("'") + SPIDARCAD_EXE + "'";
  std::string output;
  // A device would be read without end.
  EXPECT_EQ(RunCommand(exe + " none --trajectory /dev/zero --frames 1 2>&1", &output), 2) << output;
  EXPECT_NE(output.find("'/dev/zero': not a regular file"), std::string::npos) << output;
  // Played in real time, a trajectory to t = 1e300 s would never end (--screenshot waits for it).
  const std::string long_csv = std::string(SPIDARCAD_TEST_OUTPUT_DIR) + "/gui_long_trajectory.csv";
  std::ofstream(long_csv) << "# t,x,y,z,qw,qx,qy,qz,grasp\n0,0,0,0,1,0,0,0,1.57\n"
                             "1e300,0,0,0,1,0,0,0,1.57\n";
  EXPECT_EQ(RunCommand(exe + " none --trajectory '" + long_csv + "' --frames 1 2>&1", &output), 2)
      << output;
  EXPECT_NE(output.find("t = 1e+300 s"), std::string::npos) << output;
  EXPECT_NE(output.find("spidarcad run"), std::string::npos) << output;
}

TEST(SpidarcadWindow, ReadsTheDeviceThroughACalibrationFileAndRefusesAForeignOne) {
  const char* display = std::getenv("DISPLAY");
  if (display == nullptr || display[0] == '\0') GTEST_SKIP() << "no X display";
  const std::string exe = std::string("'") + SPIDARCAD_EXE + "'";
  const std::string cal = std::string(SPIDARCAD_TEST_OUTPUT_DIR) + "/gui_calibration_seed2.json";
  std::string output;
  ASSERT_EQ(RunCommand(exe + " calibrate --simulated --seed 2 --out '" + cal + "' 2>&1", &output),
            0)
      << output;
  // Seed 2's own calibration: the window runs, and FK accepts every tick at rest.
  EXPECT_EQ(
      RunCommand(exe + " none --seed 2 --calibration '" + cal + "' --frames 20 2>&1", &output), 0)
      << output;
  EXPECT_NE(output.find("fk_refused=0 "), std::string::npos) << output;
  // The default device is seed 1: another device's file is refused, naming both seeds.
  EXPECT_EQ(RunCommand(exe + " none --calibration '" + cal + "' --frames 1 2>&1", &output), 2)
      << output;
  EXPECT_NE(output.find("does not fit"), std::string::npos) << output;
  EXPECT_NE(output.find("seed 2"), std::string::npos) << output;
  // So is a frame it was not made on, and a nonsensical frame.
  EXPECT_EQ(RunCommand(exe + " none --seed 2 --frame 0.3,0.24,0.24 --calibration '" + cal +
                           "' --frames 1 2>&1",
                       &output),
            2)
      << output;
  EXPECT_NE(output.find("--frame 0.3,0.24,0.24"), std::string::npos) << output;
  EXPECT_EQ(RunCommand(exe + " none --pole -1 --frames 1 2>&1", &output), 2) << output;
  EXPECT_NE(output.find("--frame/--pole"), std::string::npos) << output;
}

}  // namespace
}  // namespace spidarcad::app
