// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
// Scripted grip trajectories for headless runs: what the simulated hand tries to follow.
//
// CSV format, one sample per line: `t,x,y,z,qw,qx,qy,qz,grasp`
//   t          time, s, strictly increasing
//   x,y,z      grip centre p0 in the device frame D, m
//   qw..qz     unit quaternion of the grip frame's rotation R_DT (normalised on load; a norm
//              off by more than 1e-3 is an error)
//   grasp      angle between the poles, rad, in (0, π) (π/2 at rest)
// Blank lines and lines whose first non-blank character is '#' are skipped. Errors name the
// file, the line and the field.
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <iosfwd>
#include <string>
#include <vector>

namespace spidarcad::haptics {

// One sample of a trajectory (device frame D).
struct TrajectorySample {
  double t = 0.0;                                            // s
  Eigen::Vector3d p_DT = Eigen::Vector3d::Zero();            // grip centre, m
  Eigen::Quaterniond q_DT = Eigen::Quaterniond::Identity();  // grip rotation
  double grasp = 1.5707963267948966;                         // rad
};

// A time-ordered list of samples with interpolation.
class Trajectory {
 public:
  // Parses CSV from `in`; `source` names it in errors. Throws std::invalid_argument with
  // "source:line: field 'name': message" on bad input, or "source: no samples".
  static Trajectory Parse(std::istream& in, const std::string& source);
  // Reads a CSV file. Throws std::invalid_argument (also when the file cannot be opened).
  static Trajectory Load(const std::string& path);
  // Writes the CSV format (with a header comment), shortest round-trip numbers.
  void Write(std::ostream& out) const;
  // Appends a sample; its time must exceed the last one (throws std::invalid_argument).
  void Add(const TrajectorySample& sample);
  // The state at time t: linear interpolation of position and grasp, slerp of rotation;
  // held constant before the first and after the last sample. Requires at least one sample.
  TrajectorySample Sample(double t) const noexcept;
  const std::vector<TrajectorySample>& samples() const noexcept { return samples_; }
  bool empty() const noexcept { return samples_.empty(); }
  double start_time() const noexcept { return samples_.empty() ? 0.0 : samples_.front().t; }
  double end_time() const noexcept { return samples_.empty() ? 0.0 : samples_.back().t; }

 private:
  std::vector<TrajectorySample> samples_;
};

// Generators. All sample at `rate` Hz, start at t = 0, keep the grip at rest orientation
// (identity) and grasp π/2 unless they vary it, and throw std::invalid_argument on
// non-positive durations or rates.

// Moves from `start` to `surface` (over 40 % of `duration`), presses `depth` m further along
// −normal (20 %), holds (10 %), and returns to `start` (30 %). Smooth (cosine) blends.
Trajectory ApproachPressRelease(const Eigen::Vector3d& start, const Eigen::Vector3d& surface,
                                const Eigen::Vector3d& normal, double depth, double duration,
                                double rate);
// `turns` turns of a circle of `radius` m about `center` in the plane normal to `axis`,
// starting at center + radius·u (u ⟂ axis), eased in and out.
Trajectory Circle(const Eigen::Vector3d& center, double radius, const Eigen::Vector3d& axis,
                  double turns, double duration, double rate);
// Rotates the grip about `axis` (through its centre `center`) as amplitude·sin(2π
// t/duration·cycles).
Trajectory Twist(const Eigen::Vector3d& center, const Eigen::Vector3d& axis, double amplitude,
                 double cycles, double duration, double rate);
// Closes the grasp from π/2 to `grasp_min` and opens it again, `cycles` times.
Trajectory Squeeze(const Eigen::Vector3d& center, double grasp_min, double cycles, double duration,
                   double rate);

}  // namespace spidarcad::haptics
