// Tests of the simulated hand against closed forms (static equilibria, the damped oscillator)
// and, with the whole haptic loop and simulated device, resting against a stiff wall without a
// growing oscillation.
// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#include "spidarcad/haptics/simulated_hand.h"

#include <gtest/gtest.h>

#include <cmath>

#include "spidarcad/haptics/haptic_loop.h"
#include "spidarcad/haptics/kinematics.h"
#include "spidarcad/haptics/simulated_device.h"

namespace spidarcad::haptics {
namespace {

TEST(SimulatedHand, SettlesWhereTheHandSpringsBalanceTheDeviceWrench) {
  HandSettings s;
  TrajectorySample target;
  target.p_DT = {0.01, 0.02, -0.01};
  target.grasp = 1.4;
  SimulatedHand hand(s, target, 0.04);
  Vector7d w;
  w << 3.0, -1.5, 0.6, 0.02, -0.01, 0.005, 0.1;
  for (int k = 0; k < 5000; ++k) hand.Step(target, w, 1e-3);
  const Eigen::Vector3d expected_p = target.p_DT + w.head<3>() / s.stiffness;
  EXPECT_LT((hand.position() - expected_p).norm(), 1e-9);
  // Small rotation: angle ≈ |m| / k_r (exactly: k_r · angle · axis = m at equilibrium).
  const Eigen::AngleAxisd aa(hand.rotation() * target.q_DT.conjugate());
  EXPECT_LT((aa.angle() * aa.axis() - w.segment<3>(3) / s.rot_stiffness).norm(), 1e-9);
  // −g/2 is the generalised force on θ.
  EXPECT_NEAR(hand.grasp(), 1.4 - 0.5 * w(6) / s.grasp_stiffness, 1e-9);
  EXPECT_LT(hand.KineticEnergy(), 1e-12);
}

TEST(SimulatedHand, FreeResponseMatchesTheDampedOscillator) {
  HandSettings s;
  s.mass = 0.3;
  s.stiffness = 300.0;
  s.damping = 3.0;
  s.substeps = 8;
  TrajectorySample start;
  start.p_DT = {0.01, 0, 0};
  SimulatedHand hand(s, start, 0.04);
  TrajectorySample target;  // origin
  const double wn = std::sqrt(s.stiffness / s.mass);
  const double zeta = s.damping / (2 * std::sqrt(s.stiffness * s.mass));
  const double wd = wn * std::sqrt(1 - zeta * zeta);
  double worst = 0;
  for (int k = 1; k <= 400; ++k) {
    hand.Step(target, Vector7d::Zero(), 1e-3);
    const double t = 1e-3 * k;
    const double x = 0.01 * std::exp(-zeta * wn * t) *
                     (std::cos(wd * t) + zeta / std::sqrt(1 - zeta * zeta) * std::sin(wd * t));
    worst = std::max(worst, std::abs(hand.position().x() - x));
  }
  EXPECT_LT(worst, 2e-4);  // 2 % of the amplitude: the integrator's phase error at h = 125 µs
}

TEST(SimulatedHand, RestsAgainstAStiffWallWithoutGrowingOscillation) {
  SimulatedSpidarG device(SimulatedDeviceConfig::Ideal());
  LoopSettings settings;
  settings.ramp_time = 0.2;
  HapticLoop loop(device.info(),
                  EncoderCalibration::Nominal(
                      device.info().encoder,
                      InverseKinematics(device.info().geometry, device.info().home_pose)),
                  settings);
  const double k_wall = 3000.0;
  auto scene = std::make_unique<HapticScene>();
  scene->Add(std::make_unique<PlaneWallField>(Eigen::Vector3d(0, 0, -0.03),
                                              Eigen::Vector3d::UnitZ(), k_wall, 5.0));
  loop.Publish(std::move(scene));
  HandSettings hs;
  const Trajectory path =
      ApproachPressRelease({0, 0, 0.0}, {0, 0, -0.03}, {0, 0, 1}, 0.003, 2.0, 1000.0);
  TrajectorySample target = path.Sample(0);
  SimulatedHand hand(hs, target, device.info().geometry.d);
  double max_energy_late = 0, z_min = 1, z_max = -1;
  double energy_early_peak = 0;
  for (int k = 0; k < 3000; ++k) {
    const double t = 1e-3 * k;
    target = path.Sample(std::min(t, 1.3));  // stop at the hold, 3 mm inside
    hand.Step(target, device.TrueWrench(), 1e-3);
    device.SetTruePose(hand.pose());
    device.Step(1e-3);
    TickInputs in;
    device.Read(&in.reading);
    device.WriteTensions(loop.Step(in, 1e-3).tau);
    if (t > 1.0 && t < 1.6) energy_early_peak = std::max(energy_early_peak, hand.KineticEnergy());
    if (t > 2.5) {
      max_energy_late = std::max(max_energy_late, hand.KineticEnergy());
      z_min = std::min(z_min, hand.position().z());
      z_max = std::max(z_max, hand.position().z());
    }
  }
  // Closed-form equilibrium of the hand spring against the wall spring (series springs).
  const double z_target = -0.033;
  const double z_eq = (hs.stiffness * z_target + k_wall * -0.03) / (hs.stiffness + k_wall);
  EXPECT_NEAR(0.5 * (z_min + z_max), z_eq, 1e-4);
  EXPECT_LT(z_max - z_min, 5e-5);  // no sustained oscillation
  EXPECT_LT(max_energy_late, 1e-6);
  EXPECT_LE(max_energy_late, energy_early_peak + 1e-12);
}

}  // namespace
}  // namespace spidarcad::haptics
