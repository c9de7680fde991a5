// Collecting self-calibration samples from a running device (SelfCalibrate, calibration.h):
// while the user waves the grip through the workspace and the motors vary the string tensions,
// CalibrationPoseCollector keeps the readings that add information (settled tensions, taut
// strings, a pose forward kinematics can place and that is not near one already kept) and
// says how many are still needed and in which octants of the workspace. WavingTrajectory is a
// hand motion that does this, for a simulated hand.
// Frame D, SI units (m, rad, N, s). Not real-time code in general: Offer allocates nothing
// until more than 4 × target samples were kept (capacity is reserved), Progress allocates.
// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#pragma once

#include <array>
#include <cstdint>
#include <string>
#include <vector>

#include "spidarcad/haptics/calibration.h"
#include "spidarcad/haptics/device.h"
#include "spidarcad/haptics/encoder.h"
#include "spidarcad/haptics/geometry.h"
#include "spidarcad/haptics/kinematics.h"
#include "spidarcad/haptics/trajectory.h"

namespace spidarcad::haptics {

// Octant of a grip centre about the frame centre: bit 0 set for x >= 0, bit 1 for y >= 0,
// bit 2 for z >= 0.
int Octant(const Eigen::Vector3d& p0);
// Its name, e.g. "+x-y+z".
std::string OctantName(int octant);

// What makes a reading useful.
struct PoseCollectorSettings {
  int target = 100;               // useful poses wanted
  int per_octant = 0;             // at least this many in every octant; 0: max(1, target / 16)
  double min_distance = 0.02;     // m: a new pose's centre this far from every kept one, or
  double min_angle = 0.17;        // rad: rotated or grasped this much more (about 10°)
  double settle_time = 0.02;      // s: tensions held this long (10 motor time constants)
  double fk_max_residual = 5e-3;  // m: FK acceptance with the initial (nominal) calibration
};

// Why readings were not kept (counts since construction).
struct PoseCollectorCounts {
  long offered = 0;
  long kept = 0;
  long not_ok = 0;     // device status not ok, or a stale reading (same sequence)
  long slack = 0;      // a string flagged slack
  long unsettled = 0;  // tensions changed less than settle_time ago
  long no_pose = 0;    // forward kinematics found no pose
  long too_close = 0;  // near a pose already kept
};

// Keeps the useful readings of a self-calibration session.
class CalibrationPoseCollector {
 public:
  // `initial`: the calibration the poses are judged with (typically the nominal one).
  // Throws std::invalid_argument naming the setting when one is out of range.
  CalibrationPoseCollector(const SpidarGeometry& geometry, const EncoderCalibration& initial,
                           const PoseCollectorSettings& settings = {});

  // Offers one reading taken while the motors held `tension` (N) for `held` s. True when kept.
  bool Offer(const EncoderReading& reading, const Vector8d& tension, double held);

  int collected() const { return static_cast<int>(samples_.size()); }
  int target() const { return settings_.target; }
  int per_octant() const { return per_octant_; }
  // Poses kept per octant (index: Octant()).
  const std::array<int, 8>& octant_counts() const { return octant_counts_; }
  // True once target poses were kept and every octant has per_octant of them.
  bool Done() const;
  // "40/100 useful poses; more needed in octants +x+y+z (2/6), -x+y-z (4/6)", or
  // "100/100 useful poses; every octant covered".
  std::string Progress() const;
  const PoseCollectorCounts& counts() const { return counts_; }
  // The kept samples (counts and tensions), in order.
  const std::vector<UnknownPoseSample>& samples() const { return samples_; }
  // Their poses by forward kinematics with the initial calibration.
  const std::vector<GripPose>& poses() const { return poses_; }

 private:
  SpidarGeometry geometry_;
  EncoderCalibration initial_;
  PoseCollectorSettings settings_;
  int per_octant_ = 1;
  ForwardKinematics fk_;
  std::uint32_t last_sequence_ = 0;
  bool has_sequence_ = false;
  std::array<int, 8> octant_counts_{};
  PoseCollectorCounts counts_;
  std::vector<UnknownPoseSample> samples_;
  std::vector<GripPose> poses_;
};

// A hand waving the grip through the workspace for `duration` s (samples every 50 ms),
// deterministic in `seed`: the centre follows a Lissajous figure over ±(half-side − d − 3 cm)
// on each axis (every octant, corners included), the grip turns up to 0.3 rad about each axis
// and the grasp swings ±0.3 rad about π/2, all with incommensurate periods of 4–10 s; it eases
// in from the rest pose at the centre over the first 2 s.
Trajectory WavingTrajectory(const SpidarGeometry& geometry, double duration, std::uint64_t seed);

}  // namespace spidarcad::haptics
