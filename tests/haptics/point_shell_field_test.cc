// Tests of the six-DOF point-shell field: the contact wrench of a box resting flat on a plane
// (zero torque, force in closed form), an off-centre touch (torque = r × f), the torque felt
// through the virtual coupling at equilibrium, stability and energy with the simulated hand
// pushing a box tool into a 10 kN/m wall, the shell generators, the size bound, and no
// allocation in Evaluate.
// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#include "spidarcad/haptics/point_shell_field.h"

#include <cmath>
#include <stdexcept>

#include <Eigen/Geometry>
#include <gtest/gtest.h>

#include "spidarcad/haptics/simulated_hand.h"
#include "support/malloc_counter.h"

namespace spidarcad::haptics {
namespace {

std::shared_ptr<DistanceField> Floor() {
  return std::make_shared<HalfSpaceDistanceField>(Eigen::Vector3d::Zero(), Eigen::Vector3d::UnitZ());
}

Eigen::Isometry3d Pose(const Eigen::Vector3d& p, const Eigen::Matrix3d& R = Eigen::Matrix3d::Identity()) {
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
  EXPECT_LT((c.force_W - Eigen::Vector3d(0, 0, s.reference_contacts * s.contact_stiffness * depth)).norm(),
            1e-12);
  EXPECT_LT(c.torque_W.norm(), 1e-15);
}

TEST(PointShellField, OffCentreTouchGivesTorqueRCrossF) {
  PointShellSettings s;
  const Eigen::Vector3d r_T(0.03, 0.01, -0.02);
  const PointShellField field(Floor(), PointShell::FromPoints({r_T}, {Eigen::Vector3d::UnitZ()}), s);
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
  EXPECT_LT((w.m_T_W - m).norm(), 0.02 * m.norm()) << w.m_T_W.transpose() << " vs " << m.transpose();
}

// Energy of the hand + grip + virtual tool + contact system (the hand's target is fixed, so
// nothing but the hand's initial spring energy ever enters).
double SystemEnergy(const SimulatedHand& hand, const TrajectorySample& target, const PointShellField& field,
                    const Eigen::Vector3d& p_WT, const Eigen::Quaterniond& q_WT) {
  const HandSettings& hs = hand.settings();
  const PointShellSettings& s = field.settings();
  double e = hand.KineticEnergy() + 0.5 * hs.stiffness * (target.p_DT - hand.position()).squaredNorm();
  const double hand_angle = Eigen::AngleAxisd(target.q_DT * hand.rotation().conjugate()).angle();
  e += 0.5 * hs.rot_stiffness * hand_angle * hand_angle;
  const Eigen::Matrix3d R_V = field.q_WV().toRotationMatrix();
  e += 0.5 * s.mass * field.v_WV().squaredNorm() +
       0.5 * field.w_WV().dot(R_V * s.inertia.asDiagonal() * R_V.transpose() * field.w_WV());
  e += 0.5 * s.coupling_stiffness * (p_WT - field.p_WV()).squaredNorm();
  const double coupling_angle = Eigen::AngleAxisd(q_WT * field.q_WV().conjugate()).angle();
  e += 0.5 * s.rot_coupling_stiffness * coupling_angle * coupling_angle;
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
    if (k >= 1000 && k < 1500) z_min_early = std::min(z_min_early, z), z_max_early = std::max(z_max_early, z);
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
  auto box = std::make_shared<TransformedDistanceField>(std::make_shared<BoxDistanceField>(Eigen::Vector3d(0.05, 0.05, 0.01)),
                                                        Eigen::Isometry3d(Eigen::Translation3d(0, 0, -0.01)));
  PointShellField field(box, PointShell::Box(Eigen::Vector3d::Constant(0.015), 0.003));
  int contact = 0;
  long allocations = 0;
  {
    test_support::MallocCounter counter;
    for (int k = 0; k < 1000; ++k) {
      ToolKinematics tool;
      tool.time = 1e-3 * k;
      tool.p_WT = Eigen::Vector3d(0.01 * std::sin(3 * tool.time), 0, 0.02 - 0.01 * std::sin(5 * tool.time));
      tool.R_WT = Eigen::AngleAxisd(0.2 * std::sin(tool.time), Eigen::Vector3d::UnitY()).toRotationMatrix();
      field.Evaluate(tool);
      contact += field.contacts() > 0;
      (void)field.LatestState();
    }
    allocations = counter.count();
  }
  EXPECT_EQ(allocations, 0);
  EXPECT_GT(contact, 100);
}

}  // namespace
}  // namespace spidarcad::haptics
