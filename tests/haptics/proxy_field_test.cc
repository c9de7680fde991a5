// Tests of the god-object proxy field: the proxy stays on the surface while the tool is
// inside, the force is k × depth along the normal (closed forms for a plane and a sphere),
// Coulomb friction sticks below μs and slides on the μd cone, concave corners of a union hold
// the proxy on both faces, a 2 mm plate is not tunnelled at 2 m/s, and Evaluate allocates
// nothing.
// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#include "spidarcad/haptics/proxy_field.h"

#include <cmath>
#include <stdexcept>

#include <Eigen/Geometry>
#include <gtest/gtest.h>

#include "spidarcad/haptics/haptic_loop.h"
#include "spidarcad/haptics/kinematics.h"
#include "spidarcad/haptics/simulated_device.h"
#include "spidarcad/haptics/simulated_hand.h"
#include "support/malloc_counter.h"

namespace spidarcad::haptics {
namespace {

ToolKinematics At(const Eigen::Vector3d& p, double time, const Eigen::Vector3d& v = Eigen::Vector3d::Zero()) {
  ToolKinematics t;
  t.p_WT = p;
  t.time = time;
  t.v_WT = v;
  return t;
}

std::shared_ptr<DistanceField> Floor() {
  return std::make_shared<HalfSpaceDistanceField>(Eigen::Vector3d::Zero(), Eigen::Vector3d::UnitZ());
}

TEST(ProxyField, ForceIsStiffnessTimesDepthAlongThePlaneNormal) {
  ProxySettings s;
  s.damping = 0.0;
  ProxyField field(Floor(), s);
  EXPECT_EQ(field.Evaluate(At({0.01, 0.02, 0.01}, 0.0)).f_T_W.norm(), 0.0);
  const Eigen::Vector3d tool(0.013, 0.018, -0.003);
  const ToolWrench w = field.Evaluate(At(tool, 1e-3));
  EXPECT_TRUE(field.in_contact());
  EXPECT_LT((w.f_T_W - Eigen::Vector3d(0, 0, s.stiffness * 0.003)).norm(), 1e-9) << w.f_T_W.transpose();
  EXPECT_LT((field.proxy_W() - Eigen::Vector3d(0.013, 0.018, 0.0)).norm(), 1e-12);
  EXPECT_EQ(w.m_T_W.norm(), 0.0);
}

TEST(ProxyField, StaysOnTheSphereWhileTheToolMovesInsideAndPushesAlongTheNormal) {
  const double radius = 0.05;
  ProxySettings s;
  s.damping = 0.0;
  ProxyField field(std::make_shared<SphereDistanceField>(Eigen::Vector3d::Zero(), radius), s);
  const SphereDistanceField reference(Eigen::Vector3d::Zero(), radius);
  // In from above, then a wandering path 2-8 mm inside the surface for 2 s.
  int ticks_in_contact = 0;
  double worst_surface = 0.0;
  for (int k = 0; k <= 2000; ++k) {
    const double t = 1e-3 * k;
    Eigen::Vector3d p;
    if (k < 100) {
      p = Eigen::Vector3d(0, 0, 0.07 - 0.0003 * k);  // reaches 4 mm inside at k = 100
    } else {
      const double depth = 0.005 + 0.003 * std::sin(5 * t);
      const Eigen::Vector3d dir(std::sin(0.8 * (t - 0.1)) * std::cos(1.3 * t),
                                std::sin(0.8 * (t - 0.1)) * std::sin(1.3 * t), std::cos(0.8 * (t - 0.1)));
      p = (radius - depth) * dir.normalized();
    }
    field.Evaluate(At(p, t));
    if (reference.Evaluate(p, nullptr) < 0) {
      ASSERT_TRUE(field.in_contact()) << k;
      ++ticks_in_contact;
      worst_surface = std::max(worst_surface, std::abs(reference.Evaluate(field.proxy_W(), nullptr)));
    }
  }
  EXPECT_GT(ticks_in_contact, 1900);
  EXPECT_LT(worst_surface, 1e-6);
  // Held still 6 mm inside: the proxy converges onto the ray and f = k·depth·n.
  const Eigen::Vector3d dir = Eigen::Vector3d(0.3, -0.5, 0.8).normalized();
  const Eigen::Vector3d tool = (radius - 0.006) * dir;
  ToolWrench w;
  for (int k = 0; k < 200; ++k) w = field.Evaluate(At(tool, 2.001 + 1e-3 * k));
  EXPECT_LT((w.f_T_W - s.stiffness * 0.006 * dir).norm(), 1e-6) << w.f_T_W.transpose();
}

TEST(ProxyField, FrictionHoldsBelowStaticAndSlidesOnTheDynamicCone) {
  ProxySettings s;
  s.damping = 0.0;
  s.static_friction = 0.5;
  s.dynamic_friction = 0.3;
  ProxyField field(Floor(), s);
  const double depth = 0.004;
  field.Evaluate(At({0.0, 0.0, 0.002}, 0.0));
  field.Evaluate(At({0.0, 0.0, -depth}, 1e-3));  // enters straight down: proxy at the origin
  ASSERT_LT(field.proxy_W().norm(), 1e-12);
  // 1.5 mm sideways < μs·depth = 2 mm: sticks, tangential force k·1.5 mm.
  ToolWrench w = field.Evaluate(At({0.0015, 0.0, -depth}, 2e-3));
  EXPECT_LT(field.proxy_W().norm(), 1e-12);
  EXPECT_NEAR(w.f_T_W.x(), -s.stiffness * 0.0015, 1e-9);
  EXPECT_NEAR(w.f_T_W.z(), s.stiffness * depth, 1e-9);
  // 3 mm > 2 mm: slides; the proxy lags by μd·depth = 1.2 mm, force μd·k·depth sideways.
  for (int k = 0; k < 20; ++k) w = field.Evaluate(At({0.003 + 0.0005 * k, 0.0, -depth}, 3e-3 + 1e-3 * k));
  EXPECT_TRUE(field.sliding());
  EXPECT_NEAR(field.proxy_W().x(), 0.003 + 0.0005 * 19 - 0.3 * depth, 1e-12);
  EXPECT_NEAR(w.f_T_W.x(), -0.3 * s.stiffness * depth, 1e-9);
  EXPECT_NEAR(w.f_T_W.z(), s.stiffness * depth, 1e-9);
  // Stop: it sticks again (the tangential force stays on the dynamic cone, the proxy stays).
  const Eigen::Vector3d held = field.proxy_W();
  for (int k = 0; k < 5; ++k) field.Evaluate(At({0.0125, 0.0, -depth}, 0.03 + 1e-3 * k));
  EXPECT_FALSE(field.sliding());
  EXPECT_LT((field.proxy_W() - held).norm(), 1e-12);
}

TEST(ProxyField, HoldsTheProxyInAConcaveCornerOfAUnion) {
  // Floor z < 0 united with a wall x < 0: a concave edge along y.
  auto wall = std::make_shared<HalfSpaceDistanceField>(Eigen::Vector3d::Zero(), Eigen::Vector3d::UnitX());
  auto corner = std::make_shared<UnionDistanceField>(std::vector<std::shared_ptr<const DistanceField>>{Floor(), wall});
  ProxySettings s;
  s.damping = 0.0;
  ProxyField field(corner, s);
  const Eigen::Vector3d start(0.01, 0.002, 0.01), end(-0.003, 0.002, -0.004);
  ToolWrench w;
  for (int k = 0; k <= 20; ++k) {
    w = field.Evaluate(At(start + (end - start) * (k / 20.0), 1e-3 * k));
    ASSERT_GE(field.proxy_W().x(), -1e-9) << k;
    ASSERT_GE(field.proxy_W().z(), -1e-9) << k;
  }
  EXPECT_LT((field.proxy_W() - Eigen::Vector3d(0, 0.002, 0)).norm(), 1e-9) << field.proxy_W().transpose();
  EXPECT_LT((w.f_T_W - s.stiffness * Eigen::Vector3d(0.003, 0.0, 0.004)).norm(), 1e-6);
}

TEST(ProxyField, DoesNotTunnelThroughATwoMillimetrePlateAtTwoMetresPerSecond) {
  // A 2 mm plate (z in [−1, 1] mm), the tool crossing it at 2 m/s (2 mm per 1 ms tick), at
  // several phases and slants; the proxy must stay on top and the force keep pushing up.
  auto plate = std::make_shared<BoxDistanceField>(Eigen::Vector3d(0.05, 0.05, 0.001));
  for (int phase = 0; phase < 8; ++phase) {
    for (const double slant : {0.0, 0.5}) {
      ProxySettings s;
      s.damping = 0.0;
      ProxyField field(plate, s);
      const Eigen::Vector3d velocity = 2.0 * Eigen::Vector3d(slant, 0.3 * slant, -1.0).normalized();
      const Eigen::Vector3d start(-0.01, -0.003, 0.01 + 0.00025 * phase);
      for (int k = 0; k < 12; ++k) {
        const Eigen::Vector3d tool = start + velocity * (1e-3 * k);
        const ToolWrench w = field.Evaluate(At(tool, 1e-3 * k, velocity));
        ASSERT_GE(field.proxy_W().z(), 0.001 - 1e-6) << "phase " << phase << " tick " << k;
        if (tool.z() < 0.001) {
          ASSERT_TRUE(field.in_contact());
          // Below the top face: the spring reaches up to the top face, through the plate.
          ASSERT_NEAR(w.f_T_W.z(), s.stiffness * (0.001 - tool.z()), 1e-6) << phase << " " << k;
        }
      }
    }
  }
}

TEST(ProxyField, LeavesTheSurfaceWhenTheToolWithdrawsAndDampsOnlyInContact) {
  ProxySettings s;
  s.damping = 3.0;
  ProxyField field(Floor(), s);
  field.Evaluate(At({0, 0, 0.001}, 0.0, {0, 0, -0.1}));
  ToolWrench w = field.Evaluate(At({0, 0, -0.002}, 1e-3, {0, 0, -0.1}));
  EXPECT_NEAR(w.f_T_W.z(), s.stiffness * 0.002 + 3.0 * 0.1, 1e-9);  // pressing in: damped
  w = field.Evaluate(At({0, 0, -0.0001}, 2e-3, {0, 0, 1.0}));
  EXPECT_NEAR(w.f_T_W.z(), 0.0, 1e-12);  // fast withdrawal: the damper never pulls inward
  w = field.Evaluate(At({0, 0, 0.003}, 3e-3, {0, 0, 1.0}));
  EXPECT_FALSE(field.in_contact());
  EXPECT_EQ(w.f_T_W.norm(), 0.0);
  EXPECT_EQ(field.proxy_W(), Eigen::Vector3d(0, 0, 0.003));
}

TEST(ProxyField, TipOffsetGivesTheMomentAboutTheToolOrigin) {
  ProxySettings s;
  s.damping = 0.0;
  s.tip_T = Eigen::Vector3d(0, 0, -0.05);
  ProxyField field(Floor(), s);
  ToolKinematics tool = At({0.0, 0.0, 0.06}, 0.0);
  tool.R_WT = Eigen::AngleAxisd(0.3, Eigen::Vector3d::UnitY()).toRotationMatrix();
  field.Evaluate(tool);
  tool.p_WT.z() = 0.04;
  tool.time = 1e-3;
  const ToolWrench w = field.Evaluate(tool);
  const Eigen::Vector3d r = tool.R_WT * s.tip_T;
  const double depth = -(tool.p_WT + r).z();
  ASSERT_GT(depth, 0);
  EXPECT_NEAR(w.f_T_W.z(), s.stiffness * depth, 1e-9);
  EXPECT_LT((w.m_T_W - r.cross(Eigen::Vector3d(0, 0, s.stiffness * depth))).norm(), 1e-9);
}

TEST(ProxyField, GivesNoForceWhenTheToolStartsInside) {
  ProxyField field(Floor());
  EXPECT_EQ(field.Evaluate(At({0, 0, -0.01}, 0.0)).f_T_W.norm(), 0.0);
  EXPECT_EQ(field.Evaluate(At({0, 0, -0.005}, 1e-3)).f_T_W.norm(), 0.0);
  field.Evaluate(At({0, 0, 0.001}, 2e-3));
  EXPECT_GT(field.Evaluate(At({0, 0, -0.002}, 3e-3)).f_T_W.z(), 1.0);
}

TEST(ProxyField, SimulatedHandPushingIntoA10kNPerMetreWallSettlesWithoutGainingEnergy) {
  // The hand (300 N/m, 20 N·s/m, 0.3 kg) aims 2 cm into a 10 kN/m floor; the field is sampled
  // once per 1 ms tick and held (as the loop does). With the target fixed, the energy of hand,
  // grip and proxy spring can only fall from the hand spring's initial 0.24 J.
  ProxySettings s;
  s.stiffness = 1e4;
  s.damping = 1.0;
  ProxyField field(Floor(), s);
  TrajectorySample start;
  start.p_DT = Eigen::Vector3d(0.001, 0.002, 0.02);
  TrajectorySample target = start;
  target.p_DT.z() = -0.02;
  SimulatedHand hand(HandSettings{}, start, 0.04);
  const double k_hand = hand.settings().stiffness;
  const double e0 = 0.5 * k_hand * 0.04 * 0.04;
  double e_max = 0.0, early = 0.0, late = 0.0;
  Eigen::Matrix<double, 7, 1> wrench = Eigen::Matrix<double, 7, 1>::Zero();
  for (int k = 0; k < 3000; ++k) {
    ToolKinematics tool = At(hand.position(), 1e-3 * k, hand.velocity());
    tool.R_WT = hand.rotation().toRotationMatrix();
    wrench.head<3>() = field.Evaluate(tool).f_T_W;
    hand.Step(target, wrench, 1e-3);
    const double spring = field.in_contact() ? 0.5 * s.stiffness * (field.proxy_W() - hand.position()).squaredNorm() : 0.0;
    const double e = hand.KineticEnergy() + 0.5 * k_hand * (target.p_DT - hand.position()).squaredNorm() + spring;
    e_max = std::max(e_max, e);
    const double z_rest = -k_hand * 0.02 / (k_hand + s.stiffness);  // closed-form rest depth
    if (k >= 1000 && k < 1500) early = std::max(early, std::abs(hand.position().z() - z_rest));
    if (k >= 2500) late = std::max(late, std::abs(hand.position().z() - z_rest));
  }
  EXPECT_LE(e_max, e0 * 1.01) << "energy rose from " << e0 << " to " << e_max << " J";
  EXPECT_LE(late, early + 1e-9);
  EXPECT_LT(late, 1e-6);
  EXPECT_TRUE(field.in_contact());
}

TEST(ProxyField, RendersThroughTheHapticLoopOnTheSimulatedDeviceWithoutAllocating) {
  ASSERT_TRUE(test_support::MallocCounterActive());
  SimulatedSpidarG device(SimulatedDeviceConfig::Ideal());
  LoopSettings settings;
  settings.fk.max_residual = 5e-3;
  settings.ramp_time = 0.0;
  HapticLoop loop(device.info(),
                  EncoderCalibration::Nominal(device.info().encoder,
                                              InverseKinematics(device.info().geometry, device.info().home_pose)),
                  settings);
  auto scene = std::make_unique<HapticScene>();
  scene->Add(std::make_unique<ProxyField>(std::make_shared<HalfSpaceDistanceField>(
      Eigen::Vector3d(0, 0, -0.03), Eigen::Vector3d::UnitZ())));
  loop.Publish(std::move(scene));
  auto tick = [&](const Eigen::Vector3d& p0) {
    device.SetTruePose(GripPose::FromFrame(p0, Eigen::Matrix3d::Identity(), M_PI / 2, device.info().geometry.d));
    device.Step(1e-3);
    TickInputs in;
    device.Read(&in.reading);
    const TickOutputs out = loop.Step(in, 1e-3);
    device.WriteTensions(out.tau);
    return out;
  };
  for (int k = 0; k < 50; ++k) tick(Eigen::Vector3d(0.01, 0.0, -0.02));
  TickOutputs out;
  for (int k = 0; k < 100; ++k) out = tick(Eigen::Vector3d(0.01, 0.0, -0.034));  // 4 mm in
  EXPECT_FALSE(IsZeroForceEvent(out.events));
  EXPECT_NEAR(out.wrench_D(2), 1500.0 * 0.004, 0.05);  // ± encoder quantisation
  EXPECT_LT(out.wrench_D.head<2>().norm(), 0.05);
  long allocations = 0;
  int pushed = 0;
  {
    test_support::MallocCounter counter;
    for (int k = 0; k < 1000; ++k) {
      const double t = 1e-3 * k;
      out = tick(Eigen::Vector3d(0.02 * std::sin(2 * t), 0.01, -0.028 - 0.004 * std::sin(7 * t)));
      pushed += out.wrench_D(2) > 0.5;
    }
    allocations = counter.count();
  }
  EXPECT_EQ(allocations, 0);
  EXPECT_GT(pushed, 200);
}

TEST(ProxyField, RejectsBadSettings) {
  ProxySettings s;
  s.static_friction = 0.2;
  s.dynamic_friction = 0.3;
  EXPECT_THROW(ProxyField(Floor(), s), std::invalid_argument);
  EXPECT_THROW(ProxyField(nullptr), std::invalid_argument);
  ProxySettings k;
  k.stiffness = -1;
  EXPECT_THROW(ProxyField(Floor(), k), std::invalid_argument);
}

TEST(ProxyField, EvaluateAllocatesNothing) {
  ASSERT_TRUE(test_support::MallocCounterActive());
  auto box = std::make_shared<TransformedDistanceField>(
      std::make_shared<BoxDistanceField>(Eigen::Vector3d(0.03, 0.03, 0.01)),
      Eigen::Isometry3d(Eigen::AngleAxisd(0.2, Eigen::Vector3d::UnitX())));
  ProxySettings s;
  s.static_friction = 0.4;
  s.dynamic_friction = 0.3;
  ProxyField field(box, s);
  int contact = 0;
  long allocations = 0;
  {
    test_support::MallocCounter counter;
    for (int k = 0; k < 2000; ++k) {
      const double t = 1e-3 * k;
      const Eigen::Vector3d p(0.04 * std::sin(2 * t), 0.02 * std::cos(3 * t), 0.018 * std::cos(7 * t));
      field.Evaluate(At(p, t));
      contact += field.in_contact();
      (void)field.LatestState();
    }
    allocations = counter.count();
  }
  EXPECT_EQ(allocations, 0);
  EXPECT_GT(contact, 200);
}

}  // namespace
}  // namespace spidarcad::haptics
