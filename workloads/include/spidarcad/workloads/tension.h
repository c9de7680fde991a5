// Tension-distribution workloads: wrench requests at grip poses, cold (independent random
// poses) and warm (a smooth 1 kHz hand motion). Shared by bench/tension_bench.cc and the
// report's tension section. Uses spidarcad::haptics.
// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#pragma once

#include <Eigen/Geometry>
#include <cmath>
#include <random>
#include <vector>

#include "spidarcad/haptics/geometry.h"
#include "spidarcad/haptics/tension.h"

namespace spidarcad::workloads {

// One request: the wrench matrix A (7×8, the pose's string directions) and the commanded
// generalized wrench q (force N, moment N·m, grasp N·m) in D.
struct TensionRequest {
  haptics::Matrix78d A;
  haptics::Vector7d q;
};

// A rotation about a random axis by an angle uniform in [−max_angle, max_angle] rad.
inline Eigen::Matrix3d RandomRotation(std::mt19937* rng, double max_angle) {
  std::normal_distribution<double> normal(0.0, 1.0);
  std::uniform_real_distribution<double> angle(-max_angle, max_angle);
  const Eigen::Vector3d axis(normal(*rng), normal(*rng), normal(*rng));
  return Eigen::AngleAxisd(angle(*rng), axis.normalized()).toRotationMatrix();
}

// Independent random poses within 8 cm of the centre (cold-start workload). `scale` 1 gives
// displayable requests (force up to 2 N per axis, moments up to 0.03 N·m), 50 saturating ones.
inline std::vector<TensionRequest> RandomTensionRequests(const haptics::SpidarGeometry& g,
                                                         int count, double scale, unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> pos(-0.08, 0.08), grasp(1.0, 2.1), u(-1, 1);
  std::vector<TensionRequest> out;
  for (int k = 0; k < count; ++k) {
    const haptics::GripPose pose = haptics::GripPose::FromFrame(
        Eigen::Vector3d(pos(rng), pos(rng), pos(rng)), RandomRotation(&rng, 0.5), grasp(rng), g.d);
    haptics::Vector7d q;
    q << 2 * u(rng), 2 * u(rng), 2 * u(rng), 0.03 * u(rng), 0.03 * u(rng), 0.03 * u(rng),
        0.03 * u(rng);
    out.push_back({haptics::WrenchMatrix(g, pose), scale * q});
  }
  return out;
}

// A smooth 1 kHz hand motion with a varying wrench (warm-start workload): consecutive requests
// are 1 ms of motion apart.
inline std::vector<TensionRequest> TrajectoryTensionRequests(const haptics::SpidarGeometry& g,
                                                             int count, double scale) {
  std::vector<TensionRequest> out;
  for (int k = 0; k < count; ++k) {
    const double t = 1e-3 * k;
    const Eigen::Matrix3d R =
        Eigen::AngleAxisd(0.4 * std::sin(t), Eigen::Vector3d(1, 2, 3).normalized())
            .toRotationMatrix();
    const haptics::GripPose pose = haptics::GripPose::FromFrame(
        Eigen::Vector3d(0.08 * std::sin(t), 0.05 * std::cos(2 * t), 0.06 * std::sin(3 * t)), R,
        1.5 + 0.3 * std::sin(t), g.d);
    haptics::Vector7d q;
    q << 3 * std::sin(5 * t), 2 * std::cos(7 * t), -2 + 2 * std::sin(3 * t), 0.03 * std::sin(4 * t),
        0.02, -0.03 * std::cos(6 * t), 0.03 * std::sin(8 * t);
    out.push_back({haptics::WrenchMatrix(g, pose), scale * q});
  }
  return out;
}

}  // namespace spidarcad::workloads
