// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#include "spidarcad/haptics/calibration_session.h"

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <numbers>
#include <sstream>
#include <stdexcept>

namespace spidarcad::haptics {

namespace {

FkSettings CollectorFk(const PoseCollectorSettings& settings) {
  FkSettings fk;
  fk.max_iterations = 50;
  fk.max_residual = settings.fk_max_residual;
  return fk;
}

void Check(bool ok, const char* field, double value, const char* what) {
  if (!ok) {
    throw std::invalid_argument(std::string("PoseCollectorSettings: field '") + field + "' " +
                                what + ", got " + std::to_string(value));
  }
}

}  // namespace

int Octant(const Eigen::Vector3d& p0) {
  return (p0.x() >= 0.0 ? 1 : 0) | (p0.y() >= 0.0 ? 2 : 0) | (p0.z() >= 0.0 ? 4 : 0);
}

std::string OctantName(int octant) {
  std::string name;
  name += (octant & 1) ? "+x" : "-x";
  name += (octant & 2) ? "+y" : "-y";
  name += (octant & 4) ? "+z" : "-z";
  return name;
}

CalibrationPoseCollector::CalibrationPoseCollector(const SpidarGeometry& geometry,
                                                   const EncoderCalibration& initial,
                                                   const PoseCollectorSettings& settings)
    : geometry_(geometry),
      initial_(initial),
      settings_(settings),
      fk_((geometry.Validate(), geometry), CollectorFk(settings)) {
  initial.Validate();
  Check(settings.target >= 1, "target", settings.target, "must be at least 1");
  Check(settings.per_octant >= 0, "per_octant", settings.per_octant, "must be >= 0");
  Check(settings.min_distance >= 0.0, "min_distance", settings.min_distance, "must be >= 0 (m)");
  Check(settings.min_angle >= 0.0, "min_angle", settings.min_angle, "must be >= 0 (rad)");
  Check(settings.settle_time >= 0.0, "settle_time", settings.settle_time, "must be >= 0 (s)");
  Check(settings.fk_max_residual > 0.0, "fk_max_residual", settings.fk_max_residual,
        "must be > 0 (m)");
  per_octant_ = settings.per_octant > 0 ? settings.per_octant : std::max(1, settings.target / 16);
  samples_.reserve(4 * static_cast<std::size_t>(settings.target));
  poses_.reserve(4 * static_cast<std::size_t>(settings.target));
}

bool CalibrationPoseCollector::Offer(const EncoderReading& reading, const Vector8d& tension,
                                     double held) {
  ++counts_.offered;
  if (reading.status != DeviceStatus::kOk ||
      (has_sequence_ && reading.sequence == last_sequence_) || !tension.allFinite()) {
    ++counts_.not_ok;
    return false;
  }
  has_sequence_ = true;
  last_sequence_ = reading.sequence;
  if (reading.slack_mask != 0) {
    ++counts_.slack;
    return false;
  }
  if (!(held >= settings_.settle_time)) {
    ++counts_.unsettled;
    return false;
  }
  const FkResult r = fk_.Solve(initial_.Lengths(reading.counts, tension));
  if (r.status != FkStatus::kOk) {
    ++counts_.no_pose;
    return false;
  }
  const Eigen::Matrix3d R = r.pose.Rotation();
  for (const GripPose& kept : poses_) {
    if ((kept.p0 - r.pose.p0).norm() < settings_.min_distance &&
        RotationAngleBetween(kept.Rotation(), R) < settings_.min_angle &&
        std::abs(kept.Grasp() - r.grasp) < settings_.min_angle) {
      ++counts_.too_close;
      return false;
    }
  }
  samples_.push_back({reading.counts, tension});
  poses_.push_back(r.pose);
  ++octant_counts_[Octant(r.pose.p0)];
  ++counts_.kept;
  return true;
}

bool CalibrationPoseCollector::Done() const {
  if (collected() < settings_.target) return false;
  for (int n : octant_counts_) {
    if (n < per_octant_) return false;
  }
  return true;
}

std::string CalibrationPoseCollector::Progress() const {
  std::ostringstream os;
  os << std::min(collected(), settings_.target) << "/" << settings_.target << " useful poses";
  std::string missing;
  for (int o = 0; o < 8; ++o) {
    if (octant_counts_[o] >= per_octant_) continue;
    missing += (missing.empty() ? "" : ", ") + OctantName(o) + " (" +
               std::to_string(octant_counts_[o]) + "/" + std::to_string(per_octant_) + ")";
  }
  if (missing.empty()) {
    os << "; every octant covered";
  } else {
    os << "; more needed in octants " << missing;
  }
  return os.str();
}

Trajectory WavingTrajectory(const SpidarGeometry& geometry, double duration, std::uint64_t seed) {
  geometry.Validate();
  // Phases from the seed (SplitMix64, as elsewhere in calibration).
  std::uint64_t state = seed ^ 0xC0FFEE123ULL;
  const auto next = [&state] {
    std::uint64_t z = (state += 0x9E3779B97F4A7C15ULL);
    z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ULL;
    z = (z ^ (z >> 27)) * 0x94D049BB133111EBULL;
    z ^= z >> 31;
    return 2.0 * std::numbers::pi * (static_cast<double>(z >> 11) * 0x1.0p-53);
  };
  double phase[7];
  for (double& p : phase) p = next();
  const double d = geometry.d;
  // The attachment points stay within |p0| + d of the centre: 3 cm from the faces at least
  // (the hand yields about a centimetre to the strings' pull).
  const double margin = 0.03;
  const Eigen::Vector3d amplitude =
      (Eigen::Vector3d(geometry.a, geometry.b, geometry.c).array() - d - margin).max(0.0);
  // Periods (s): centre 7.1, 9.7, 5.3; rotation 6.1, 8.3, 4.7; grasp 3.9.
  const double period[7] = {7.1, 9.7, 5.3, 6.1, 8.3, 4.7, 3.9};
  const double rotation_amplitude = 0.3;
  const double grasp_amplitude = 0.3;
  Trajectory trajectory;
  const int steps = std::max(1, static_cast<int>(std::ceil(duration / 0.05)));
  for (int k = 0; k <= steps; ++k) {
    const double t = duration * k / steps;
    // Ease in over the first 2 s from the rest pose at the centre.
    const double ease = std::min(1.0, t / 2.0);
    const auto wave = [&](int i) {
      return ease * std::sin(2.0 * std::numbers::pi * t / period[i] + phase[i]);
    };
    TrajectorySample s;
    s.t = t;
    s.p_DT =
        Eigen::Vector3d(amplitude.x() * wave(0), amplitude.y() * wave(1), amplitude.z() * wave(2));
    const Eigen::Vector3d w = rotation_amplitude * Eigen::Vector3d(wave(3), wave(4), wave(5));
    s.q_DT = w.norm() > 0.0 ? Eigen::Quaterniond(Eigen::AngleAxisd(w.norm(), w / w.norm()))
                            : Eigen::Quaterniond::Identity();
    s.grasp = std::numbers::pi / 2 + grasp_amplitude * wave(6);
    trajectory.Add(s);
  }
  return trajectory;
}

}  // namespace spidarcad::haptics
