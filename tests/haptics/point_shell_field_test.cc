// Tests of the six-DOF point-shell field: the contact wrench of a box resting flat on a plane
// (zero torque, force in closed form), an off-centre touch (torque = r × f), the torque felt
// through the virtual coupling at equilibrium (penalty only, and held by the depth limit),
// stability and energy with the simulated hand pushing a box tool into a 10 kN/m wall, the
// shell generators, the size bound, no allocation in Evaluate; free-space noise on the
// simulated device's quantised readings (bounded from the encoder quantum), contact
// stiffness with and without the soft zone (closed form), and 4 cm / 10 cm grip jumps at a
// 2 mm plate (no tunnelling; through the haptic loop, the wrench limit holds).
// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#include "spidarcad/haptics/point_shell_field.h"

#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <memory>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include "spidarcad/haptics/haptic_loop.h"
#include "spidarcad/haptics/kinematics.h"
#include "spidarcad/haptics/simulated_device.h"
#include "spidarcad/haptics/simulated_hand.h"
#include "support/malloc_counter.h"

namespace spidarcad::haptics {
namespace {

std::shared_ptr<DistanceField> Floor() {
  return std::make_shared<HalfSpaceDistanceField>(Eigen::Vector3d::Zero(),
                                                  Eigen::Vector3d::UnitZ());
}

Eigen::Isometry3d Pose(const Eigen::Vector3d& p,
                       const Eigen::Matrix3d& R = Eigen::Matrix3d::Identity()) {
  Eigen::Isometry3d X = Eigen::Isometry3d::Identity();
  X.linear() = R;
  X.translation() = p;
  return X;
}

TEST(PointShell, GeneratorsPutPointsOnTheSurfaceWithInwardNormals) {
  const PointShell sphere = PointShell::Sphere(0.02, 500);
  ASSERT_EQ(sphere.size(), 500);
  Eigen::Vector3d mean = Eigen::Vector3d::Zero();
  for (int i = 0; i < sphere.size(); ++i) {
    EXPECT_NEAR(sphere.points_T[i].norm(), 0.02, 1e-15);
    EXPECT_LT((sphere.normals_T[i] + sphere.points_T[i] / 0.02).norm(), 1e-12);
    mean += sphere.points_T[i];
  }
  EXPECT_LT(mean.norm() / 500, 1e-3 * 0.02);  // evenly spread
  const PointShell box = PointShell::Box(Eigen::Vector3d(0.02, 0.01, 0.005), 0.005);
  EXPECT_EQ(box.size(), 2 * (4 * 2 + 2 * 8 + 8 * 4));  // per axis: faces' cell grids
  const BoxDistanceField surface(Eigen::Vector3d(0.02, 0.01, 0.005));
  Eigen::Vector3d g;
  for (int i = 0; i < box.size(); ++i) {
    EXPECT_NEAR(surface.Evaluate(box.points_T[i], &g), 0.0, 1e-15);
    EXPECT_LT((box.normals_T[i] + g).norm(), 1e-12);
  }
  const PointShell grip = PointShell::CrossGrip(0.04, 0.005, 9, 8);
  EXPECT_EQ(grip.size(), 2 * (9 * 8 + 2));
  EXPECT_NEAR(grip.Radius(), 0.045, 1e-15);
  EXPECT_THROW(PointShell::FromPoints({Eigen::Vector3d::Zero()}, {}), std::invalid_argument);
  EXPECT_THROW(PointShell::FromPoints({Eigen::Vector3d::Zero()}, {Eigen::Vector3d::Zero()}),
               std::invalid_argument);
}

TEST(PointShellField, BoxRestingFlatOnAPlaneGivesZeroTorque) {
  PointShellSettings s;
  const Eigen::Vector3d h(0.02, 0.015, 0.01);
  const PointShellField field(Floor(), PointShell::Box(h, 0.005), s);
  const double depth = 0.0008;
  const ShellContact c = field.ContactAt(Pose(Eigen::Vector3d(0.3, -0.1, h.z() - depth)));
  const int bottom = 8 * 6;  // cells of the 40 × 30 mm bottom face
  EXPECT_EQ(c.contacts, bottom);
  // Averaged over the contacts beyond N_ref: N_ref · k_p · depth, straight up.
  EXPECT_LT((c.force_W - Eigen::Vector3d(0, 0, s.reference_contacts * s.contact_stiffness * depth))
                .norm(),
            1e-12);
  EXPECT_LT(c.torque_W.norm(), 1e-15);
}

TEST(PointShellField, OffCentreTouchGivesTorqueRCrossF) {
  PointShellSettings s;
  const Eigen::Vector3d r_T(0.03, 0.01, -0.02);
  const PointShellField field(Floor(), PointShell::FromPoints({r_T}, {Eigen::Vector3d::UnitZ()}),
                              s);
  const Eigen::Matrix3d R = Eigen::AngleAxisd(0.1, Eigen::Vector3d::UnitX()).toRotationMatrix();
  const Eigen::Vector3d r = R * r_T;
  const double depth = 0.002;
  const ShellContact c = field.ContactAt(Pose(Eigen::Vector3d(0.0, 0.0, -r.z() - depth), R));
  const Eigen::Vector3d f(0, 0, s.contact_stiffness * depth);
  EXPECT_EQ(c.contacts, 1);
  EXPECT_LT((c.force_W - f).norm(), 1e-12);
  EXPECT_LT((c.torque_W - r.cross(f)).norm(), 1e-14);
}

TEST(PointShellField, UserFeelsTheOffCentreTorqueThroughTheCoupling) {
  PointShellSettings s;
  s.max_penetration = 0.01;  // the penalty law alone holds the point (1.2 mm deep)
  const Eigen::Vector3d r_T(0.03, 0.01, -0.02);
  PointShellField field(Floor(), PointShell::FromPoints({r_T}, {Eigen::Vector3d::UnitZ()}), s);
  ToolKinematics tool;
  tool.p_WT = Eigen::Vector3d(0, 0, 0.017);  // the point 3 mm inside the floor
  ToolWrench w;
  for (int k = 0; k < 3000; ++k) {
    tool.time = 1e-3 * k;
    w = field.Evaluate(tool);
  }
  // At rest: what the user feels is the contact wrench on the virtual tool.
  EXPECT_LT(field.v_WV().norm() + field.w_WV().norm(), 1e-6);
  const Eigen::Vector3d contact = field.p_WV() + field.q_WV() * r_T;
  ASSERT_LT(contact.z(), 0.0);
  const Eigen::Vector3d f(0, 0, -s.contact_stiffness * contact.z());
  EXPECT_LT((w.f_T_W - f).norm(), 1e-4 * f.norm()) << w.f_T_W.transpose();
  const Eigen::Vector3d m = (contact - tool.p_WT).cross(w.f_T_W);
  EXPECT_GT(m.norm(), 0.02);  // ~0.03 N·m: a torque clearly felt
  EXPECT_LT((w.m_T_W - m).norm(), 0.02 * m.norm())
      << w.m_T_W.transpose() << " vs " << m.transpose();
}

// Potential of a coupling spring of stiffness k with a soft zone of radius δ and ratio ε at
// stretch r: the integral of ε k r (r ≤ δ), then of k r − (1 − ε) k δ.
double SoftZonePotential(double k, double zone, double eps, double r) {
  if (r <= zone) return 0.5 * eps * k * r * r;
  return 0.5 * eps * k * zone * zone + 0.5 * k * (r * r - zone * zone) -
         (1.0 - eps) * k * zone * (r - zone);
}

// Energy of the hand + grip + virtual tool + contact system (the hand's target is fixed, so
// nothing but the hand's initial spring energy ever enters).
double SystemEnergy(const SimulatedHand& hand, const TrajectorySample& target,
                    const PointShellField& field, const Eigen::Vector3d& p_WT,
                    const Eigen::Quaterniond& q_WT) {
  const HandSettings& hs = hand.settings();
  const PointShellSettings& s = field.settings();
  double e =
      hand.KineticEnergy() + 0.5 * hs.stiffness * (target.p_DT - hand.position()).squaredNorm();
  const double hand_angle = Eigen::AngleAxisd(target.q_DT * hand.rotation().conjugate()).angle();
  e += 0.5 * hs.rot_stiffness * hand_angle * hand_angle;
  const Eigen::Matrix3d R_V = field.q_WV().toRotationMatrix();
  e += 0.5 * s.mass * field.v_WV().squaredNorm() +
       0.5 * field.w_WV().dot(R_V * s.inertia.asDiagonal() * R_V.transpose() * field.w_WV());
  e += SoftZonePotential(s.coupling_stiffness, s.coupling_soft_zone, s.soft_zone_ratio,
                         (p_WT - field.p_WV()).norm());
  const double coupling_angle = Eigen::AngleAxisd(q_WT * field.q_WV().conjugate()).angle();
  e += SoftZonePotential(s.rot_coupling_stiffness, s.rot_coupling_soft_zone, s.soft_zone_ratio,
                         coupling_angle);
  double sum_sq = 0;
  int n = 0;
  for (const auto& r_T : field.shell().points_T) {
    const double z = (field.p_WV() + R_V * r_T).z();
    if (z < 0) {
      sum_sq += z * z;
      ++n;
    }
  }
  const double scale = std::min(1.0, s.reference_contacts / std::max(1.0, double(n)));
  return e + 0.5 * scale * s.contact_stiffness * sum_sq;
}

TEST(PointShellField, SimulatedHandPushingIntoAStiffWallSettlesWithoutGainingEnergy) {
  // Wall: N_ref · k_p = 10 kN/m. The hand (300 N/m, 20 N·s/m) aims 2 cm below the floor with a
  // 3 cm box tool, slightly tilted so one edge lands first.
  PointShellSettings s;
  s.contact_stiffness = 1000.0;
  s.reference_contacts = 10;
  PointShellField field(Floor(), PointShell::Box(Eigen::Vector3d::Constant(0.015), 0.005), s);
  TrajectorySample start;
  start.p_DT = Eigen::Vector3d(0, 0, 0.03);
  start.q_DT = Eigen::Quaterniond(Eigen::AngleAxisd(0.05, Eigen::Vector3d::UnitX()));
  TrajectorySample target = start;
  target.p_DT = Eigen::Vector3d(0, 0, -0.02);
  SimulatedHand hand(HandSettings{}, start, 0.04);
  Eigen::Matrix<double, 7, 1> wrench = Eigen::Matrix<double, 7, 1>::Zero();
  // At rest, the virtual tool on the grip (as the first Evaluate puts it), out of contact: only
  // the hand's spring holds energy.
  const double e0 = 0.5 * hand.settings().stiffness * (target.p_DT - start.p_DT).squaredNorm();
  double e_max = e0;
  double z_min_early = 1, z_max_early = -1, z_min_late = 1, z_max_late = -1;
  int ticks_in_contact = 0;
  for (int k = 0; k < 3000; ++k) {
    ToolKinematics tool;
    tool.time = 1e-3 * k;
    tool.p_WT = hand.position();
    tool.R_WT = hand.rotation().toRotationMatrix();
    tool.v_WT = hand.velocity();
    tool.w_WT = hand.angular_velocity();
    tool.grasp = hand.grasp();
    const ToolWrench w = field.Evaluate(tool);
    ASSERT_TRUE(w.f_T_W.allFinite() && w.m_T_W.allFinite()) << k;
    wrench.head<3>() = w.f_T_W;
    wrench.segment<3>(3) = w.m_T_W;
    hand.Step(target, wrench, 1e-3);
    ticks_in_contact += field.contacts() > 0;
    e_max = std::max(e_max, SystemEnergy(hand, target, field, hand.position(), hand.rotation()));
    const double z = hand.position().z();
    if (k >= 1000 && k < 1500)
      z_min_early = std::min(z_min_early, z), z_max_early = std::max(z_max_early, z);
    if (k >= 2500) z_min_late = std::min(z_min_late, z), z_max_late = std::max(z_max_late, z);
  }
  EXPECT_GT(ticks_in_contact, 2500);
  EXPECT_LE(e_max, e0 * 1.01) << "energy rose from " << e0 << " to " << e_max << " J";
  EXPECT_LE(z_max_late - z_min_late, z_max_early - z_min_early + 1e-9);  // no growing oscillation
  EXPECT_LT(z_max_late - z_min_late, 1e-5);
  // Settled resting on the wall: the felt force balances the hand's spring, the virtual tool
  // sits on the wall (10 kN/m) and the grip below it by the coupling's stretch (1 kN/m).
  const double hand_force = hand.settings().stiffness * (hand.position().z() - target.p_DT.z());
  EXPECT_NEAR(wrench(2), hand_force, 0.01 * hand_force);
  const double wall = s.reference_contacts * s.contact_stiffness;
  EXPECT_NEAR(field.p_WV().z(), 0.015 - hand_force / wall, 1e-3);  // ± the tilt
  EXPECT_NEAR(hand.position().z(), field.p_WV().z() - hand_force / s.coupling_stiffness, 1e-4);
}

TEST(PointShellField, RejectsShellsBeyondTheBoundAndBadSettings) {
  PointShellSettings s;
  s.max_points = 100;
  EXPECT_THROW(PointShellField(Floor(), PointShell::Sphere(0.01, 101), s), std::invalid_argument);
  EXPECT_NO_THROW(PointShellField(Floor(), PointShell::Sphere(0.01, 100), s));
  EXPECT_THROW(PointShellField(nullptr, PointShell::Sphere(0.01, 10)), std::invalid_argument);
  PointShellSettings bad;
  bad.mass = 0;
  EXPECT_THROW(PointShellField(Floor(), PointShell::Sphere(0.01, 10), bad), std::invalid_argument);
}

TEST(PointShellField, EvaluateAllocatesNothing) {
  ASSERT_TRUE(test_support::MallocCounterActive());
  auto box = std::make_shared<TransformedDistanceField>(
      std::make_shared<BoxDistanceField>(Eigen::Vector3d(0.05, 0.05, 0.01)),
      Eigen::Isometry3d(Eigen::Translation3d(0, 0, -0.01)));
  PointShellField field(box, PointShell::Box(Eigen::Vector3d::Constant(0.015), 0.003));
  int contact = 0;
  long allocations = 0;
  {
    test_support::MallocCounter counter;
    for (int k = 0; k < 1000; ++k) {
      ToolKinematics tool;
      tool.time = 1e-3 * k;
      tool.p_WT =
          Eigen::Vector3d(0.01 * std::sin(3 * tool.time), 0, 0.02 - 0.01 * std::sin(5 * tool.time));
      tool.R_WT =
          Eigen::AngleAxisd(0.2 * std::sin(tool.time), Eigen::Vector3d::UnitY()).toRotationMatrix();
      field.Evaluate(tool);
      contact += field.contacts() > 0;
      (void)field.LatestState();
    }
    allocations = counter.count();
  }
  EXPECT_EQ(allocations, 0);
  EXPECT_GT(contact, 100);
}

// A distance field that counts its point evaluations (EvaluateBatch's default goes through
// Evaluate, so batches are counted point by point).
class Counted final : public DistanceField {
 public:
  explicit Counted(std::shared_ptr<const DistanceField> f) : f_(std::move(f)) {}
  double Evaluate(const Eigen::Vector3d& p, Eigen::Vector3d* g) const noexcept override {
    ++count;
    return f_->Evaluate(p, g);
  }
  mutable long count = 0;

 private:
  std::shared_ptr<const DistanceField> f_;
};

std::uint64_t Bits(double v) {
  std::uint64_t b;
  std::memcpy(&b, &v, sizeof b);
  return b;
}

// The narrow phase culled by motion bounds against every point tested each tick: the same
// wrench, virtual tool and contact count, bit for bit, on every tick of slow presses, fast
// twists, a grip that leaves and comes back, and a 4 cm jump; and the culled field evaluates
// fewer points (counted through the environment).
TEST(PointShellField, CullingByMotionBoundsGivesTheExhaustiveResultsBitForBit) {
  // A floor with a box on it (a union: edges and corners), counting its evaluations.
  auto scene =
      std::make_shared<UnionDistanceField>(std::vector<std::shared_ptr<const DistanceField>>{
          Floor(), std::make_shared<TransformedDistanceField>(
                       std::make_shared<BoxDistanceField>(Eigen::Vector3d(0.02, 0.02, 0.01)),
                       Eigen::Isometry3d(Eigen::Translation3d(0.03, 0, 0.01)))});
  auto culled_env = std::make_shared<Counted>(scene);
  auto full_env = std::make_shared<Counted>(scene);
  PointShellSettings exhaustive;
  exhaustive.cull_by_motion = false;
  const PointShell shell = PointShell::CrossGrip(0.04, 0.006, 12, 8);
  PointShellField culled(culled_env, shell), full(full_env, shell, exhaustive);
  int mismatches = 0, touching = 0;
  for (int k = 0; k < 4000; ++k) {
    ToolKinematics tool;
    tool.time = 1e-3 * k;
    const double t = tool.time;
    // Slow presses first, then fast twists (up to about 0.6 m/s and 10 rad/s), a lift of 10 cm
    // and back, and a 4 cm jump of the grip at tick 3000.
    const double fast = k < 2000 ? 1.0 : 6.0;
    tool.p_WT = Eigen::Vector3d(0.02 * std::sin(fast * t), 0.015 * std::cos(0.7 * fast * t),
                                0.012 - 0.006 * std::sin(2.0 * fast * t));
    if (k >= 2500 && k < 2700) tool.p_WT.z() += 0.1;
    if (k >= 3000) tool.p_WT.x() += 0.04;
    tool.R_WT = (Eigen::AngleAxisd(0.8 * std::sin(fast * t), Eigen::Vector3d::UnitZ()) *
                 Eigen::AngleAxisd(0.3 * std::sin(1.3 * fast * t), Eigen::Vector3d::UnitX()))
                    .toRotationMatrix();
    tool.v_WT = Eigen::Vector3d(0.02 * fast * std::cos(fast * t), 0, 0);
    tool.w_WT = Eigen::Vector3d(0, 0, 0.8 * fast * std::cos(fast * t));
    const ToolWrench a = culled.Evaluate(tool), b = full.Evaluate(tool);
    touching += culled.contacts() > 0;
    bool same = culled.contacts() == full.contacts();
    for (int i = 0; i < 3; ++i) {
      same = same && Bits(a.f_T_W[i]) == Bits(b.f_T_W[i]) && Bits(a.m_T_W[i]) == Bits(b.m_T_W[i]) &&
             Bits(culled.p_WV()[i]) == Bits(full.p_WV()[i]) &&
             Bits(culled.w_WV()[i]) == Bits(full.w_WV()[i]);
    }
    mismatches += !same;
  }
  EXPECT_EQ(mismatches, 0);
  EXPECT_GT(touching, 1000);
  EXPECT_LT(culled_env->count, full_env->count);
  RecordProperty("evaluations_culled", std::to_string(culled_env->count));
  RecordProperty("evaluations_exhaustive", std::to_string(full_env->count));
  std::printf("evaluations: culled %ld, exhaustive %ld\n", culled_env->count, full_env->count);
}

// The first tick near a part has no motion bound for any point (they are all −∞ after a
// reset): the shell's sphere clusters bound its far side at once, so a 2000-point ball that
// appears 1 mm above the floor evaluates well under half its points on that tick (clusters
// included), and the field still matches the exhaustive one bit for bit as it presses on.
TEST(PointShellField, FirstTickNearAPartBoundsTheFarSideByClusters) {
  auto culled_env = std::make_shared<Counted>(Floor());
  auto full_env = std::make_shared<Counted>(Floor());
  PointShellSettings exhaustive;
  exhaustive.cull_by_motion = false;
  const PointShell shell = PointShell::Sphere(0.03, 2000);
  PointShellField culled(culled_env, shell), full(full_env, shell, exhaustive);
  int mismatches = 0, touching = 0;
  for (int k = 0; k < 400; ++k) {
    ToolKinematics tool;
    tool.time = 1e-3 * k;
    // 1 mm above the floor at first, then 2 mm into it over the 400 ticks, turning slowly.
    tool.p_WT = Eigen::Vector3d(0.0, 0.0, 0.031 - 0.003 * k / 400.0);
    tool.R_WT = Eigen::AngleAxisd(0.5 * tool.time, Eigen::Vector3d::UnitX()).toRotationMatrix();
    tool.v_WT = Eigen::Vector3d(0, 0, -0.0075);
    tool.w_WT = Eigen::Vector3d(0.5, 0, 0);
    const long before = culled_env->count;
    const ToolWrench a = culled.Evaluate(tool), b = full.Evaluate(tool);
    if (k == 0) {
      EXPECT_LT(culled_env->count - before, shell.size() / 2);
      RecordProperty("first_tick_evaluations", std::to_string(culled_env->count - before));
    }
    touching += culled.contacts() > 0;
    bool same = culled.contacts() == full.contacts();
    for (int i = 0; i < 3; ++i) {
      same = same && Bits(a.f_T_W[i]) == Bits(b.f_T_W[i]) && Bits(a.m_T_W[i]) == Bits(b.m_T_W[i]) &&
             Bits(culled.p_WV()[i]) == Bits(full.p_WV()[i]);
    }
    mismatches += !same;
  }
  EXPECT_EQ(mismatches, 0);
  EXPECT_GT(touching, 100);
}

TEST(PointShellField, PointPressedPastTheDepthLimitIsHeldAndTheWrenchActsThroughIt) {
  // The same single point as above, but with the default depth limit (0.6 mm): the penalty
  // (1000 N/m) alone would let it sink 1.2 mm; the limit holds it, so the felt force exceeds
  // the penalty force, and at rest it is still a force along the normal through the contact.
  PointShellSettings s;
  const Eigen::Vector3d r_T(0.03, 0.01, -0.02);
  PointShellField field(Floor(), PointShell::FromPoints({r_T}, {Eigen::Vector3d::UnitZ()}), s);
  ToolKinematics tool;
  tool.p_WT = Eigen::Vector3d(0.0, 0.0, 0.023);  // the point 3 mm above the floor
  for (int k = 0; k < 100; ++k) {                // settle on the grip in free space
    tool.time = 1e-3 * k;
    field.Evaluate(tool);
  }
  tool.p_WT.z() = 0.017;  // then 3 mm inside, over a few ticks
  ToolWrench w;
  double deepest = 0;
  for (int k = 100; k < 3000; ++k) {
    tool.time = 1e-3 * k;
    w = field.Evaluate(tool);
    deepest = std::min(deepest, (field.p_WV() + field.q_WV() * r_T).z());
  }
  EXPECT_GE(deepest, -s.max_penetration - 1e-6);
  EXPECT_LT(field.v_WV().norm() + field.w_WV().norm(), 1e-6);
  const Eigen::Vector3d contact = field.p_WV() + field.q_WV() * r_T;
  EXPECT_GT(w.f_T_W.z(), 1.2 * s.contact_stiffness * -contact.z());  // more than the penalty
  EXPECT_LT(w.f_T_W.head<2>().norm(), 1e-6 * w.f_T_W.norm());        // along the normal
  const Eigen::Vector3d m = (contact - tool.p_WT).cross(w.f_T_W);
  EXPECT_LT((w.m_T_W - m).norm(), 0.02 * m.norm())
      << w.m_T_W.transpose() << " vs " << m.transpose();
}

// A flat 3 cm box tool (36 points on its bottom face, 10 kN/m wall) held with its grip `depth`
// below the resting height; returns the felt force along +z at rest.
double RestingForce(const PointShellSettings& s, double depth) {
  PointShellField field(Floor(), PointShell::Box(Eigen::Vector3d::Constant(0.015), 0.005), s);
  ToolKinematics tool;
  tool.p_WT = Eigen::Vector3d(0.01, -0.02, 0.015 - depth);
  ToolWrench w;
  for (int k = 0; k < 1500; ++k) {
    tool.time = 1e-3 * k;
    w = field.Evaluate(tool);
  }
  EXPECT_LT(field.v_WV().norm(), 1e-6);
  return w.f_T_W.z();
}

TEST(PointShellField, SoftZoneKeepsTheContactStiffness) {
  PointShellSettings before;  // the coupling without soft zone or depth limit
  before.coupling_soft_zone = 0;
  before.rot_coupling_soft_zone = 0;
  before.max_penetration = 1.0;
  const PointShellSettings after;  // defaults
  const double d1 = 1e-3, d2 = 3e-3;
  const double k_before = (RestingForce(before, d2) - RestingForce(before, d1)) / (d2 - d1);
  const double f1 = RestingForce(after, d1), f2 = RestingForce(after, d2);
  const double k_after = (f2 - f1) / (d2 - d1);
  // Coupling and wall in series: 1 / (1/k_c + 1/(N_ref k_p)) = 909 N/m.
  const double wall = after.reference_contacts * after.contact_stiffness;
  const double series = 1.0 / (1.0 / after.coupling_stiffness + 1.0 / wall);
  EXPECT_NEAR(k_before, series, 0.01 * series);
  EXPECT_NEAR(k_after, k_before, 0.02 * k_before);
  // Closed form with the zone: k_c (r − (1 − ε) δ) = wall · penetration, r + penetration = depth.
  const double offset =
      (1.0 - after.soft_zone_ratio) * after.coupling_stiffness * after.coupling_soft_zone;
  const double expected =
      (after.coupling_stiffness * d2 - offset) / (1.0 + after.coupling_stiffness / wall);
  EXPECT_NEAR(f2, expected, 1e-3 * expected);
}

// The simulated device (quantised, noisy, uncalibrated encoders) with the grip held still at a
// tilted pose; returns the largest felt force over ticks [1000, 4000) of a shell field whose
// environment is 0.5 m away, evaluated on the loop's tool state.
double FreeSpaceForceOnTheSimulatedDevice(const PointShellSettings& s, double* quantum) {
  SimulatedSpidarG device(SimulatedDeviceConfig{});
  LoopSettings loop_settings;
  loop_settings.fk.max_residual = 5e-3;  // uncalibrated
  HapticLoop loop(device.info(),
                  EncoderCalibration::Nominal(
                      device.info().encoder,
                      InverseKinematics(device.info().geometry, device.info().home_pose)),
                  loop_settings);
  auto far_floor = std::make_shared<HalfSpaceDistanceField>(Eigen::Vector3d(0, 0, -0.5),
                                                            Eigen::Vector3d::UnitZ());
  PointShellField field(far_floor, PointShell::CrossGrip(0.04, 0.005, 9, 8), s);
  const GripPose still = GripPose::FromFrame(
      Eigen::Vector3d(0.01, -0.02, 0.015),
      Eigen::AngleAxisd(0.2, Eigen::Vector3d(1, 2, 3).normalized()).toRotationMatrix(), M_PI / 2,
      0.04);
  double largest = 0;
  for (int k = 0; k < 4000; ++k) {
    device.SetTruePose(still);
    device.Step(1e-3);
    TickInputs in;
    device.Read(&in.reading);
    const TickOutputs out = loop.Step(in, 1e-3);
    device.WriteTensions(out.tau);
    const ToolWrench w = field.Evaluate(out.tool_W);
    EXPECT_EQ(field.contacts(), 0);
    if (k >= 1000) largest = std::max(largest, w.f_T_W.norm());
  }
  *quantum = device.info().encoder.MetresPerCount();
  return largest;
}

TEST(PointShellField, StillGripInFreeSpaceFeelsAlmostNothingOnQuantisedReadings) {
  // Held still, p_WT jitters within about 2 encoder quanta q (0.025 mm each) and the loop's
  // velocity estimate (a difference quotient through a low-pass) within 2q/dt. Inside the soft
  // zone (δ = 2q) the coupling acts at ε of its strength, so
  //   |F| ≤ ε (k_c · 2q + b_c · 2q/dt) = 0.1 (0.050 + 0.151) N ≈ 0.02 N.
  // Without the zone the same jitter gives ~0.09 N peaks (0.03 N rms).
  const PointShellSettings s;
  double q = 0;
  const double with_zone = FreeSpaceForceOnTheSimulatedDevice(s, &q);
  const double bound =
      s.soft_zone_ratio * (s.coupling_stiffness * 2 * q + s.coupling_damping * 2 * q / 1e-3);
  EXPECT_NEAR(s.coupling_soft_zone, 2 * q, 0.02 * q);  // the default zone is 2 quanta
  EXPECT_LT(with_zone, bound);
  PointShellSettings no_zone = s;
  no_zone.coupling_soft_zone = 0;
  no_zone.rot_coupling_soft_zone = 0;
  const double without_zone = FreeSpaceForceOnTheSimulatedDevice(no_zone, &q);
  EXPECT_GT(without_zone, 3 * bound);  // the chatter the zone removes
}

// A 2 mm plate (|z| < 1 mm, 20 cm wide) under a 3 cm box tool whose grip starts 5 mm above it
// and jumps `jump` down in one tick, then stays. The grip velocity follows the haptic loop's
// estimate (difference quotient through the 100 Hz low-pass). Returns the deepest any point
// went into the plate (m, ≥ 0) and, via `far_side`, whether V's centre ever got below the plate.
double JumpAtAPlate(double jump, bool* far_side, double* largest_force) {
  auto plate = std::make_shared<BoxDistanceField>(Eigen::Vector3d(0.1, 0.1, 0.001));
  const PointShellSettings s;
  PointShellField field(plate, PointShell::Box(Eigen::Vector3d::Constant(0.015), 0.005), s);
  ToolKinematics tool;
  tool.p_WT = Eigen::Vector3d(0.0, 0.0, 0.001 + 0.015 + 0.005);
  const double alpha = 1e-3 / (1e-3 + 1.0 / (2 * M_PI * 100.0));
  Eigen::Vector3d previous = tool.p_WT;
  double deepest = 0;
  *far_side = false;
  *largest_force = 0;
  for (int k = 0; k < 1000; ++k) {
    tool.time = 1e-3 * k;
    if (k == 100) tool.p_WT.z() -= jump;
    tool.v_WT += alpha * ((tool.p_WT - previous) / 1e-3 - tool.v_WT);
    previous = tool.p_WT;
    const ToolWrench w = field.Evaluate(tool);
    EXPECT_TRUE(w.f_T_W.allFinite());
    *largest_force = std::max(*largest_force, w.f_T_W.norm());
    const Eigen::Matrix3d R = field.q_WV().toRotationMatrix();
    for (const Eigen::Vector3d& r_T : field.shell().points_T) {
      deepest = std::max(deepest, -plate->Evaluate(field.p_WV() + R * r_T, nullptr));
    }
    *far_side |= field.p_WV().z() < 0;
  }
  return deepest;
}

TEST(PointShellField, GripJumpingPastAThinPlateLeavesTheToolOnTheNearSide) {
  const PointShellSettings s;
  for (const double jump : {0.04, 0.10}) {
    bool far_side = true;
    double largest_force = 0;
    const double deepest = JumpAtAPlate(jump, &far_side, &largest_force);
    EXPECT_FALSE(far_side) << jump;
    // No point ever past the depth limit plus one trusted step (0.8 mm < half the plate).
    EXPECT_LT(deepest, s.max_penetration + s.min_step) << jump;
    // The felt force is the coupling's stretch (at most the jump plus the 5 mm gap) and its
    // damping on the loop's velocity estimate (≤ α · jump/dt ≈ 0.39 · jump/dt).
    EXPECT_LT(largest_force,
              s.coupling_stiffness * (jump + 0.005) + s.coupling_damping * 0.39 * jump / 1e-3)
        << jump;
  }
}

// A field wrapper so the test keeps access to the shell field the loop owns.
class Borrowed final : public ForceField {
 public:
  explicit Borrowed(ForceField* field) : field_(field) {}
  ToolWrench Evaluate(const ToolKinematics& tool) noexcept override {
    return field_->Evaluate(tool);
  }
  const char* name() const noexcept override { return "borrowed"; }

 private:
  ForceField* field_;
};

TEST(PointShellField, GripGlitchThroughTheLoopKeepsTheWrenchLimitAndTheNearSide) {
  // The simulated device and the haptic loop: the true grip teleports 4 cm down through a 2 mm
  // plate in one tick (a glitch) and stays; the loop's commanded force never exceeds its limit.
  SimulatedSpidarG device(SimulatedDeviceConfig{});
  LoopSettings loop_settings;
  loop_settings.fk.max_residual = 5e-3;
  loop_settings.ramp_time = 0.05;
  HapticLoop loop(device.info(),
                  EncoderCalibration::Nominal(
                      device.info().encoder,
                      InverseKinematics(device.info().geometry, device.info().home_pose)),
                  loop_settings);
  auto plate = std::make_shared<TransformedDistanceField>(
      std::make_shared<BoxDistanceField>(Eigen::Vector3d(0.1, 0.1, 0.001)),
      Eigen::Isometry3d(Eigen::Translation3d(0, 0, -0.03)));
  PointShellField field(plate, PointShell::CrossGrip(0.04, 0.005, 9, 8));
  auto scene = std::make_unique<HapticScene>();
  scene->Add(std::make_unique<Borrowed>(&field));
  loop.Publish(std::move(scene));
  // The grip's lowest points (pole ends ± radius) are 5 mm above the plate's top.
  const double above = -0.03 + 0.001 + 0.005 + 0.005;
  int limited = 0;
  for (int k = 0; k < 1500; ++k) {
    const double z = k < 500 ? above : above - 0.04;
    device.SetTruePose(
        GripPose::FromFrame(Eigen::Vector3d(0, 0, z), Eigen::Matrix3d::Identity(), M_PI / 2, 0.04));
    device.Step(1e-3);
    TickInputs in;
    device.Read(&in.reading);
    const TickOutputs out = loop.Step(in, 1e-3);
    device.WriteTensions(out.tau);
    ASSERT_LE(out.wrench_D.head<3>().norm(), loop_settings.max_force + 1e-9) << k;
    limited += (out.events & kEventWrenchLimited) != 0;
    EXPECT_GT(field.p_WV().z(), -0.03 + 0.001) << k;  // V's centre stays above the plate
  }
  EXPECT_GT(limited, 500);  // the coupling pulls hard (~35 N): the limit is what holds
}

// ---------------------------------------------------------------------------------------------
// Hard case: the six-DOF shell against a 10 kN/m wall with a stiff hand.

std::string Format(const char* format, double value) {
  char buffer[128];
  std::snprintf(buffer, sizeof(buffer), format, value);
  return buffer;
}

TEST(HardPointShell, StiffHandAgainstA10kNPerMetreWallStaysPassiveBoundedAndOutside) {
  // The wall: N_ref · k_p = 10 kN/m. The hand is ten times stiffer than the default (3 kN/m,
  // 10 N·m/rad wrist) and less damped relative to its stiffness (ζ ≈ 0.18): it drives a box tool
  // (tilted, so an edge lands first) and the cross grip (its pole ends land first) from 3 cm
  // above the floor to a target 2 cm below it, and holds. With the target fixed, nothing but the
  // hand's initial spring energy ever enters: the energy of hand, grip, virtual tool, coupling
  // and contact must never exceed it; no shell point may pass the depth limit plus one trusted
  // step; the felt force is bounded by what that energy allows the coupling.
  HandSettings stiff;
  stiff.stiffness = 3000.0;
  stiff.damping = 10.0;
  stiff.rot_stiffness = 10.0;
  stiff.rot_damping = 0.02;
  struct Case {
    const char* name;
    PointShell shell;
    Eigen::Quaterniond tilt;
    double bottom;  // lowest shell point below the tool origin at rest orientation, m
  };
  const Case cases[] = {
      {"box", PointShell::Box(Eigen::Vector3d::Constant(0.015), 0.005),
       Eigen::Quaterniond(Eigen::AngleAxisd(0.05, Eigen::Vector3d::UnitX())), 0.015},
      {"cross grip", PointShell::CrossGrip(0.04, 0.005, 9, 8),
       Eigen::Quaterniond(Eigen::AngleAxisd(0.3, Eigen::Vector3d(1, 1, 0).normalized())), 0.02}};
  double worst_ratio = 0, worst_depth = 0, worst_force_ratio = 0, worst_late_motion = 0;
  for (const Case& c : cases) {
    PointShellSettings s;
    s.contact_stiffness = 1000.0;
    s.reference_contacts = 10;
    PointShellField field(Floor(), c.shell, s);
    TrajectorySample start;
    start.p_DT = Eigen::Vector3d(0, 0, 0.03 + c.bottom);
    start.q_DT = c.tilt;
    TrajectorySample target = start;
    target.p_DT.z() = -0.02;
    SimulatedHand hand(stiff, start, 0.04);
    const double e0 = 0.5 * stiff.stiffness * (target.p_DT - start.p_DT).squaredNorm();
    // Energy bounds every stretch and speed: the coupling's force is at most
    // k_c·r + b_c·|v_T − v_V| with ½ k_c r² ≤ E, ½ m_hand v_T² ≤ E, ½ m_V v_V² ≤ E (the soft
    // zone only lowers the spring).
    const double force_bound =
        std::sqrt(2 * s.coupling_stiffness * e0) +
        s.coupling_damping * (std::sqrt(2 * e0 / stiff.mass) + std::sqrt(2 * e0 / s.mass));
    Eigen::Matrix<double, 7, 1> wrench = Eigen::Matrix<double, 7, 1>::Zero();
    double e_max = 0, deepest = 0, largest_force = 0;
    Eigen::Vector3d late_min = Eigen::Vector3d::Constant(1),
                    late_max = Eigen::Vector3d::Constant(-1);
    int contact_ticks = 0;
    for (int k = 0; k < 3000; ++k) {
      ToolKinematics tool;
      tool.time = 1e-3 * k;
      tool.p_WT = hand.position();
      tool.R_WT = hand.rotation().toRotationMatrix();
      tool.v_WT = hand.velocity();
      tool.w_WT = hand.angular_velocity();
      tool.grasp = hand.grasp();
      const ToolWrench w = field.Evaluate(tool);
      ASSERT_TRUE(w.f_T_W.allFinite() && w.m_T_W.allFinite()) << c.name << " " << k;
      wrench.head<3>() = w.f_T_W;
      wrench.segment<3>(3) = w.m_T_W;
      largest_force = std::max(largest_force, w.f_T_W.norm());
      hand.Step(target, wrench, 1e-3);
      contact_ticks += field.contacts() > 0;
      e_max = std::max(e_max, SystemEnergy(hand, target, field, hand.position(), hand.rotation()));
      const Eigen::Matrix3d R_V = field.q_WV().toRotationMatrix();
      for (const Eigen::Vector3d& r_T : field.shell().points_T) {
        deepest = std::max(deepest, -(field.p_WV() + R_V * r_T).z());
      }
      if (k >= 2500) {
        late_min = late_min.cwiseMin(hand.position());
        late_max = late_max.cwiseMax(hand.position());
      }
    }
    EXPECT_GT(contact_ticks, 2500) << c.name;
    EXPECT_LE(e_max, e0 * 1.01) << c.name << ": energy rose from " << e0 << " to " << e_max;
    EXPECT_LT(deepest, s.max_penetration + s.min_step) << c.name;
    EXPECT_LT(largest_force, force_bound) << c.name;
    // Settled: the hand's force is what the wall holds; no oscillation remains.
    EXPECT_LT((late_max - late_min).norm(), 1e-5) << c.name;
    worst_ratio = std::max(worst_ratio, e_max / e0);
    worst_depth = std::max(worst_depth, deepest);
    worst_force_ratio = std::max(worst_force_ratio, largest_force / force_bound);
    worst_late_motion = std::max(worst_late_motion, (late_max - late_min).norm());
  }
  RecordProperty("figure", Format("max energy / energy put in %.4f; ", worst_ratio) +
                               Format("deepest shell point %.3g m; ", worst_depth) +
                               Format("largest force / energy bound %.3f; ", worst_force_ratio) +
                               Format("motion in the last 0.5 s %.3g m", worst_late_motion));
  RecordProperty("bar",
                 "energy <= 1.01 x put in; depth < max_penetration + min_step (8e-4 m); "
                 "force < energy bound; settled motion < 1e-5 m");
}

}  // namespace
}  // namespace spidarcad::haptics
