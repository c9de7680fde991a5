// The sensor-to-force chain that the 1 kHz haptic tick runs, end to end on the simulated
// SPIDAR-G: device read -> encoder lengths -> forward kinematics -> wrench matrix -> tension
// solve -> device write. Checks that the whole chain allocates nothing and that the force the
// device puts on the grip is the one asked for (a spring toward the centre, computed here from
// the true pose: an independent reference).
// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <cmath>

#include "spidarcad/haptics/encoder.h"
#include "spidarcad/haptics/kinematics.h"
#include "spidarcad/haptics/simulated_device.h"
#include "spidarcad/haptics/tension.h"
#include "support/malloc_counter.h"

namespace spidarcad::haptics {
namespace {

// A hand moving the grip along a circle and twisting it, at tick k of 1 ms.
GripPose HandPose(const SpidarGeometry& g, int k) {
  const double t = 1e-3 * k;
  const Eigen::Vector3d p0(0.05 * std::cos(2.0 * t), 0.05 * std::sin(2.0 * t), 0.02 * std::sin(t));
  const Eigen::Matrix3d R =
      Eigen::AngleAxisd(0.3 * std::sin(1.5 * t), Eigen::Vector3d(0.3, 0.5, 0.8).normalized())
          .toRotationMatrix();
  return GripPose::FromFrame(p0, R, M_PI / 2 + 0.2 * std::sin(t), g.d);
}

struct Chain {
  explicit Chain(const SimulatedDeviceConfig& config)
      : device(config),
        encoder(EncoderCalibration::Nominal(
            device.info().encoder,
            InverseKinematics(device.info().geometry, device.info().home_pose))),
        fk(device.info().geometry,
           [] {
             FkSettings s;
             s.max_residual = 5e-3;  // an uncalibrated device: several mm of length error
             return s;
           }()),
        solver(TensionSettings::ForPoleLength(device.info().geometry.d)) {}

  // One tick: returns false when FK refused the reading (zero force is then commanded).
  bool Tick(const GripPose& hand, double k_spring, Vector7d* asked) {
    device.SetTruePose(hand);
    device.Step(1e-3);
    EncoderReading reading;
    device.Read(&reading);
    const Vector8d lengths = encoder.Lengths(reading.counts, device.commanded_tensions());
    const FkResult pose = fk.Solve(lengths);
    if (pose.status != FkStatus::kOk) {
      device.WriteTensions(Vector8d::Constant(solver.settings().tau_min));
      return false;
    }
    asked->setZero();
    asked->head<3>() = -k_spring * pose.pose.p0;
    const Matrix78d A = WrenchMatrix(device.info().geometry, pose.pose);
    const TensionResult tensions = solver.Solve(A, *asked);
    device.WriteTensions(tensions.tau);
    return true;
  }

  SimulatedSpidarG device;
  EncoderCalibration encoder;
  ForwardKinematics fk;
  TensionSolver solver;
};

TEST(RealtimeChain, AllocatesNothingPerTick) {
  ASSERT_TRUE(test_support::MallocCounterActive()) << "the counting malloc is not in use";
  Chain chain{SimulatedDeviceConfig{}};
  const SpidarGeometry& g = chain.device.info().geometry;
  Vector7d asked;
  chain.Tick(HandPose(g, 0), 100.0, &asked);  // first tick outside the count
  long ok = 0;
  long allocations = 0;
  {
    test_support::MallocCounter counter;
    for (int k = 1; k <= 2000; ++k) ok += chain.Tick(HandPose(g, k), 100.0, &asked);
    allocations = counter.count();
  }
  EXPECT_EQ(allocations, 0);
  EXPECT_EQ(ok, 2000);
}

TEST(RealtimeChain, DisplaysTheSpringForceOnTheTrueGripWhenTheDeviceIsIdeal) {
  Chain chain{SimulatedDeviceConfig::Ideal()};
  const SpidarGeometry& g = chain.device.info().geometry;
  const double k_spring = 50.0;
  Vector7d asked;
  double worst = 0.0;
  for (int k = 0; k < 500; ++k) {
    const GripPose hand = HandPose(g, k);
    ASSERT_TRUE(chain.Tick(hand, k_spring, &asked)) << "tick " << k;
    // Let the motors settle on the commanded tensions, then compare the force on the grip
    // with the spring evaluated at the TRUE pose.
    for (int settle = 0; settle < 20; ++settle) chain.device.Step(1e-3);
    const Eigen::Vector3d expected = -k_spring * hand.p0;
    const Eigen::Vector3d felt = chain.device.TrueWrench().head<3>();
    worst = std::max(worst, (felt - expected).norm());
  }
  // 1 % of the largest spring force (50 N/m × 5.4 cm = 2.7 N) plus the solver's S2 bias.
  EXPECT_LT(worst, 0.03);
}

}  // namespace
}  // namespace spidarcad::haptics
