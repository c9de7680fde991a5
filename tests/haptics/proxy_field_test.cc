// Tests of the god-object proxy field: the proxy stays on the surface while the tool is
// inside, the force is k × depth along the normal (closed forms for a plane and a sphere),
// Coulomb friction sticks below μs and slides on the μd cone, concave corners of a union hold
// the proxy on both faces, a 2 mm plate is not tunnelled at 2 m/s, and Evaluate allocates
// nothing.
// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#include "spidarcad/haptics/proxy_field.h"

#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <random>
#include <stdexcept>
#include <string>
#include <vector>

#include "spidarcad/haptics/haptic_loop.h"
#include "spidarcad/haptics/kinematics.h"
#include "spidarcad/haptics/simulated_device.h"
#include "spidarcad/haptics/simulated_hand.h"
#include "support/malloc_counter.h"

namespace spidarcad::haptics {
namespace {

ToolKinematics At(const Eigen::Vector3d& p, double time,
                  const Eigen::Vector3d& v = Eigen::Vector3d::Zero()) {
  ToolKinematics t;
  t.p_WT = p;
  t.time = time;
  t.v_WT = v;
  return t;
}

std::shared_ptr<DistanceField> Floor() {
  return std::make_shared<HalfSpaceDistanceField>(Eigen::Vector3d::Zero(),
                                                  Eigen::Vector3d::UnitZ());
}

TEST(ProxyField, ForceIsStiffnessTimesDepthAlongThePlaneNormal) {
  ProxySettings s;
  s.damping = 0.0;
  ProxyField field(Floor(), s);
  EXPECT_EQ(field.Evaluate(At({0.01, 0.02, 0.01}, 0.0)).f_T_W.norm(), 0.0);
  const Eigen::Vector3d tool(0.013, 0.018, -0.003);
  const ToolWrench w = field.Evaluate(At(tool, 1e-3));
  EXPECT_TRUE(field.in_contact());
  EXPECT_LT((w.f_T_W - Eigen::Vector3d(0, 0, s.stiffness * 0.003)).norm(), 1e-9)
      << w.f_T_W.transpose();
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
                                std::sin(0.8 * (t - 0.1)) * std::sin(1.3 * t),
                                std::cos(0.8 * (t - 0.1)));
      p = (radius - depth) * dir.normalized();
    }
    field.Evaluate(At(p, t));
    if (reference.Evaluate(p, nullptr) < 0) {
      ASSERT_TRUE(field.in_contact()) << k;
      ++ticks_in_contact;
      worst_surface =
          std::max(worst_surface, std::abs(reference.Evaluate(field.proxy_W(), nullptr)));
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
  for (int k = 0; k < 20; ++k)
    w = field.Evaluate(At({0.003 + 0.0005 * k, 0.0, -depth}, 3e-3 + 1e-3 * k));
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
  auto wall =
      std::make_shared<HalfSpaceDistanceField>(Eigen::Vector3d::Zero(), Eigen::Vector3d::UnitX());
  auto corner = std::make_shared<UnionDistanceField>(
      std::vector<std::shared_ptr<const DistanceField>>{Floor(), wall});
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
  EXPECT_LT((field.proxy_W() - Eigen::Vector3d(0, 0.002, 0)).norm(), 1e-9)
      << field.proxy_W().transpose();
  EXPECT_LT((w.f_T_W - s.stiffness * Eigen::Vector3d(0.003, 0.0, 0.004)).norm(), 1e-6);
}

TEST(ProxyField, FollowsTheToolsProjectionWhileSlidingOnATiltedPlane) {
  // A tilted plane (its normal not along an axis, so projected points sit on it only to a
  // rounding error, either side); the tool slides 1-3 mm inside it at about 0.5 m/s. Every
  // tick the frictionless proxy is the tool's projection onto the plane (closed form).
  const Eigen::Vector3d n = Eigen::Vector3d(0.3, -0.5, 0.8).normalized();
  const Eigen::Vector3d origin(0.01, 0.02, -0.03);
  ProxySettings s;
  s.damping = 0.0;
  ProxyField field(std::make_shared<HalfSpaceDistanceField>(origin, n), s);
  const Eigen::Vector3d e1 = n.unitOrthogonal(), e2 = n.cross(e1);
  double worst = 0.0;
  field.Evaluate(At(origin + 0.002 * n, 0.0));
  for (int k = 1; k <= 400; ++k) {
    const double t = 1e-3 * k;
    const double depth = 0.002 + 0.001 * std::sin(11 * t);
    const Eigen::Vector3d tool =
        origin + 0.03 * std::sin(17 * t) * e1 + 0.02 * std::cos(13 * t) * e2 - depth * n;
    field.Evaluate(At(tool, t));
    ASSERT_TRUE(field.in_contact()) << k;
    const Eigen::Vector3d expected = tool - n.dot(tool - origin) * n;
    worst = std::max(worst, (field.proxy_W() - expected).norm());
  }
  EXPECT_LT(worst, 1e-9);
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
    const double spring =
        field.in_contact() ? 0.5 * s.stiffness * (field.proxy_W() - hand.position()).squaredNorm()
                           : 0.0;
    const double e = hand.KineticEnergy() +
                     0.5 * k_hand * (target.p_DT - hand.position()).squaredNorm() + spring;
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
                  EncoderCalibration::Nominal(
                      device.info().encoder,
                      InverseKinematics(device.info().geometry, device.info().home_pose)),
                  settings);
  auto scene = std::make_unique<HapticScene>();
  scene->Add(std::make_unique<ProxyField>(std::make_shared<HalfSpaceDistanceField>(
      Eigen::Vector3d(0, 0, -0.03), Eigen::Vector3d::UnitZ())));
  loop.Publish(std::move(scene));
  auto tick = [&](const Eigen::Vector3d& p0) {
    device.SetTruePose(
        GripPose::FromFrame(p0, Eigen::Matrix3d::Identity(), M_PI / 2, device.info().geometry.d));
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
      const Eigen::Vector3d p(0.04 * std::sin(2 * t), 0.02 * std::cos(3 * t),
                              0.018 * std::cos(7 * t));
      field.Evaluate(At(p, t));
      contact += field.in_contact();
      (void)field.LatestState();
    }
    allocations = counter.count();
  }
  EXPECT_EQ(allocations, 0);
  EXPECT_GT(contact, 200);
}

// ---------------------------------------------------------------------------------------------
// Hard cases: 5 m/s into a 0.5 mm wall and into concave corners.

std::string Format(const char* format, double value) {
  char buffer[128];
  std::snprintf(buffer, sizeof(buffer), format, value);
  return buffer;
}

// Distance of f from the cone {Σ λ_i n_i, λ ≥ 0} of up to three unit normals, relative to |f|
// (0 when f is in the cone): the best non-negative combination over every subset, by normal
// equations (independent of the proxy's own QP).
double ConeDistance(const Eigen::Vector3d& f, const std::vector<Eigen::Vector3d>& normals) {
  const int n = static_cast<int>(normals.size());
  double best = f.norm();
  for (int mask = 1; mask < (1 << n); ++mask) {
    Eigen::Matrix3Xd N(3, 0);
    for (int i = 0; i < n; ++i) {
      if (mask & (1 << i)) {
        N.conservativeResize(3, N.cols() + 1);
        N.col(N.cols() - 1) = normals[i];
      }
    }
    const Eigen::VectorXd lambda = (N.transpose() * N).ldlt().solve(N.transpose() * f);
    if ((lambda.array() < -1e-12).any()) continue;
    best = std::min(best, (N * lambda - f).norm());
  }
  return f.norm() > 0 ? best / f.norm() : 0.0;
}

// Once failed (1 of 120 crossings, phase 25 at 30°, lagged a tick: force 3.4 N off the normal;
// phase 12 at 60° stalled 4e-12 m from the tool, the tiny force all tangential): the proxy,
// projected onto the top face, sits on it only to a rounding error, and the sweep along the
// face toward the goal (itself on the face to a rounding error) counted φ < 0 as the solid, met
// it at once and stalled. Now the sweep passes points with φ >= −surface_tolerance (the surface)
// and whether the tool is inside is decided by the sign of φ at the tool alone: the earlier
// attempt that only counted the tolerance band as free also let the proxy settle on a tool
// 8.5e-19 m inside the 2 mm plate as if free (ProxyField.DoesNotTunnelThroughATwo... lost
// contact there).
TEST(HardProxy, DoesNotTunnelThroughAHalfMillimetreWallAtFiveMetresPerSecond) {
  // A 0.5 mm wall (z in [−0.25, 0.25] mm), the tool crossing it at 5 m/s: 5 mm per 1 ms tick,
  // ten times the wall's thickness, so most ticks jump from above it to below it. 40 phases of
  // the crossing (every 0.125 mm) and slants from straight down to 60° off the normal.
  const double half = 0.00025;
  auto wall = std::make_shared<BoxDistanceField>(Eigen::Vector3d(0.2, 0.2, half));
  double lowest = 1.0;     // lowest proxy height above the top face, m
  double worst_force = 0;  // largest |f − k (top − z_t) e_z|, N
  double worst_cone = 0;   // largest relative distance of f from the normal
  int ticks_below = 0;
  for (int phase = 0; phase < 40; ++phase) {
    for (const double slant_deg : {0.0, 30.0, 60.0}) {
      ProxySettings s;
      s.damping = 0.0;
      ProxyField field(wall, s);
      const double slant = slant_deg * M_PI / 180;
      const Eigen::Vector3d velocity =
          5.0 * Eigen::Vector3d(std::sin(slant) * 0.8, std::sin(slant) * 0.6, -std::cos(slant));
      const Eigen::Vector3d start(-0.02, 0.01, 0.012 + 0.000125 * phase * std::cos(slant));
      for (int k = 0; k < 10; ++k) {
        const Eigen::Vector3d tool = start + velocity * (1e-3 * k);
        const ToolWrench w = field.Evaluate(At(tool, 1e-3 * k, velocity));
        lowest = std::min(lowest, field.proxy_W().z() - half);
        if (tool.z() < half) {
          ASSERT_TRUE(field.in_contact()) << phase << " " << slant_deg << " " << k;
          ++ticks_below;
          // The spring reaches from below the wall to its top face, straight up.
          const Eigen::Vector3d expected(0, 0, s.stiffness * (half - tool.z()));
          worst_force = std::max(worst_force, (w.f_T_W - expected).norm());
          worst_cone = std::max(worst_cone, ConeDistance(w.f_T_W, {Eigen::Vector3d::UnitZ()}));
        } else {
          worst_force = std::max(worst_force, w.f_T_W.norm());
        }
      }
    }
  }
  RecordProperty("figure", Format("lowest proxy %.3g m relative to the top face; ", lowest) +
                               Format("force error %.3g N over ", worst_force) +
                               std::to_string(ticks_below) + " ticks below the top face");
  RecordProperty("bar",
                 "proxy never below the top face (>= -1e-9 m); force = k*depth along +z "
                 "within 1e-6 N");
  EXPECT_GE(lowest, -1e-9);
  EXPECT_LT(worst_force, 1e-6);
  EXPECT_LT(worst_cone, 1e-9);
  EXPECT_GT(ticks_below, 600);
}

// A concave corner: the union of n half-spaces through the origin (solid where any n_i·x < 0).
struct Corner {
  std::vector<Eigen::Vector3d> normals;
  std::shared_ptr<DistanceField> field;
};

Corner MakeCorner(const std::vector<Eigen::Vector3d>& normals) {
  Corner corner;
  std::vector<std::shared_ptr<const DistanceField>> parts;
  for (const Eigen::Vector3d& n : normals) {
    corner.normals.push_back(n.normalized());
    parts.push_back(
        std::make_shared<HalfSpaceDistanceField>(Eigen::Vector3d::Zero(), n.normalized()));
  }
  corner.field = std::make_shared<UnionDistanceField>(parts);
  return corner;
}

// Once failed: on concave edges the proxy stalled up to 3.1 mm short of the closest free point,
// the spring then pulling along the edge (force 0.81 off the normals' cone): the same stalled
// sweep as above (a proxy on a slanted face a rounding error inside it could not slide). Fixed
// with the wall case above (the sweep passes the surface's tolerance band); the met face's plane
// (proxy_field.cc) holds the proxy in the edge.
TEST(HardProxy, HoldsTheProxyInConcaveCornersAtFiveMetresPerSecond) {
  // Concave corners of unions of half-spaces: a three-face box corner, a 60° V-groove and a
  // 45°-sloped corner of three faces. The tool rushes in at 5 m/s from several directions
  // and stops 3–8 mm inside. Every tick: the proxy stays in free space (n_i·x ≥ 0), and the
  // frictionless force lies in the cone of the normals of the faces the proxy touches.
  // At rest the proxy sits at the point of free space closest to the tool (a QP solved here
  // by brute force over the faces' subsets) and f = k (proxy − tool).
  const double beta = 30 * M_PI / 180;
  const std::vector<std::vector<Eigen::Vector3d>> corners = {
      {Eigen::Vector3d::UnitX(), Eigen::Vector3d::UnitY(), Eigen::Vector3d::UnitZ()},
      {Eigen::Vector3d(std::cos(beta), 0, std::sin(beta)),
       Eigen::Vector3d(-std::cos(beta), 0, std::sin(beta))},
      {Eigen::Vector3d(1, 0, 1), Eigen::Vector3d(0, 1, 1), Eigen::Vector3d(-1, -1, 1)}};
  double worst_outside = 0, worst_cone = 0, worst_rest = 0, largest_force = 0;
  int contact_ticks = 0;
  for (std::size_t c = 0; c < corners.size(); ++c) {
    const Corner corner = MakeCorner(corners[c]);
    Eigen::Vector3d inward = Eigen::Vector3d::Zero();  // into the free region
    for (const Eigen::Vector3d& n : corner.normals) inward += n;
    inward.normalize();
    std::mt19937 rng(static_cast<unsigned>(7 + c));
    std::uniform_real_distribution<double> uni(-1, 1), depth_dist(0.003, 0.008);
    for (int trial = 0; trial < 12; ++trial) {
      ProxySettings s;
      s.damping = 0.0;
      ProxyField field(corner.field, s);
      // Start 2 cm out in the free region, end inside near the corner.
      const Eigen::Vector3d start =
          0.02 * (inward + 0.3 * Eigen::Vector3d(uni(rng), uni(rng), uni(rng))).normalized();
      const Eigen::Vector3d end =
          -depth_dist(rng) * inward + 0.002 * Eigen::Vector3d(uni(rng), uni(rng), uni(rng));
      const Eigen::Vector3d velocity = 5.0 * (end - start).normalized();
      const int travel_ticks = static_cast<int>(std::ceil((end - start).norm() / 5e-3));
      ToolWrench w;
      for (int k = 0; k < travel_ticks + 50; ++k) {
        const bool moving = k < travel_ticks;
        const Eigen::Vector3d tool = moving ? Eigen::Vector3d(start + velocity * 1e-3 * k) : end;
        w = field.Evaluate(At(tool, 1e-3 * k, moving ? velocity : Eigen::Vector3d::Zero()));
        const Eigen::Vector3d& x = field.proxy_W();
        std::vector<Eigen::Vector3d> touching;
        for (const Eigen::Vector3d& n : corner.normals) {
          worst_outside = std::max(worst_outside, -n.dot(x));
          if (std::abs(n.dot(x)) < 1e-7) touching.push_back(n);
        }
        largest_force = std::max(largest_force, w.f_T_W.norm());
        if (field.in_contact() && w.f_T_W.norm() > 1e-9) {
          ++contact_ticks;
          worst_cone = std::max(worst_cone, ConeDistance(w.f_T_W, touching));
        }
      }
      // At rest: the closest free point to the tool, by brute force over subsets of faces.
      Eigen::Vector3d best = end;
      double best_distance = std::numeric_limits<double>::infinity();
      const int n = static_cast<int>(corner.normals.size());
      for (int mask = 0; mask < (1 << n); ++mask) {
        Eigen::Matrix3Xd N(3, 0);
        for (int i = 0; i < n; ++i) {
          if (mask & (1 << i)) {
            N.conservativeResize(3, N.cols() + 1);
            N.col(N.cols() - 1) = corner.normals[i];
          }
        }
        Eigen::Vector3d p = end;
        if (N.cols() > 0) {
          // Project onto the intersection of the chosen planes: p = end − N (NᵀN)⁻¹ Nᵀ end.
          p = end - N * (N.transpose() * N).ldlt().solve(N.transpose() * end);
        }
        bool feasible = true;
        for (const Eigen::Vector3d& m : corner.normals) feasible &= m.dot(p) >= -1e-12;
        if (feasible && (p - end).norm() < best_distance) {
          best_distance = (p - end).norm();
          best = p;
        }
      }
      worst_rest = std::max(worst_rest, (field.proxy_W() - best).norm());
      worst_rest =
          std::max(worst_rest, (w.f_T_W - s.stiffness * (best - end)).norm() / s.stiffness);
    }
  }
  RecordProperty("figure",
                 Format("proxy at most %.3g m inside a face; ", worst_outside) +
                     Format("force off the normals' cone by %.3g (relative); ", worst_cone) +
                     Format("rest proxy off the closest free point by %.3g m; ", worst_rest) +
                     Format("largest force %.3g N", largest_force));
  RecordProperty("bar",
                 "proxy inside no face by more than 1e-9 m; force in the normals' cone "
                 "within 1e-6; rest proxy and force within 1e-6 m of the QP solution");
  EXPECT_LT(worst_outside, 1e-9);
  EXPECT_LT(worst_cone, 1e-6);
  EXPECT_LT(worst_rest, 1e-6);
  EXPECT_GT(contact_ticks, 1000);
  // Force bounded by the spring to the deepest tool point (8 mm + 2·√3 mm of scatter).
  EXPECT_LT(largest_force, 1500.0 * 0.012);
}

}  // namespace
}  // namespace spidarcad::haptics
