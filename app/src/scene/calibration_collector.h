// A self-calibration session taken one device reading at a time, shared by `spidarcad calibrate
// --device` (cli/calibrate_session.cc) and the window's calibration wizard: while the user waves
// the grip and the motors hold varied tensions (CalibrationTensionSchedule), each reading is
// offered; the collector keeps the useful ones (haptics::CalibrationPoseCollector), says how
// many it has and which octants of the workspace still need some, and once enough are kept fits
// the self-calibration and returns the before/after table and the calibration file.
// Frame D, SI units (m, rad, N, s). Not real-time code: the haptic thread only produces the
// readings (scene/haptic_runtime.h); Offer and Fit run on the main thread or a Job.
// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#pragma once

#include <array>
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "scene/calibration_file.h"
#include "spidarcad/haptics/calibration.h"
#include "spidarcad/haptics/calibration_session.h"
#include "spidarcad/haptics/device.h"
#include "spidarcad/haptics/simulated_device.h"

namespace spidarcad::app {

// The tensions of a session: each vector (8 strings, N) is held this long, s, ...
inline constexpr double kCalibrationHoldSeconds = 0.1;
// ... drawn uniformly per string in [lo, min(hi, the device's tension_max)], N.
inline constexpr double kCalibrationTensionLo = 0.3;
inline constexpr double kCalibrationTensionHi = 3.0;

// `holds` tension vectors of a session on `info` (haptics::CalibrationTensions over the range
// above), deterministic in `seed`.
std::vector<haptics::Vector8d> CalibrationTensionSchedule(const haptics::DeviceInfo& info,
                                                          int holds, std::uint64_t seed);

// How well a calibration explains the session's readings by itself: the forward-kinematics
// residual (RMS over strings of the redundant string's disagreement), per sample, m.
struct CalibrationFkResidual {
  double rms = 0.0;  // RMS over the samples FK could place
  double max = 0.0;
  int failures = 0;  // samples FK could not place
};

// The residual of `calibration` over `samples` (FK from scratch on each, 50 iterations,
// accepting up to 5 cm so that a poor calibration's residual is measured, not refused).
CalibrationFkResidual FkResidualOn(const haptics::SpidarGeometry& geometry,
                                   const haptics::EncoderCalibration& calibration,
                                   const std::vector<haptics::UnknownPoseSample>& samples);

// One row of the before/after table.
struct CalibrationTableRow {
  std::string key;   // "uncalibrated", "self", "true_parameters" (the JSON keys of calibrate)
  std::string name;  // "uncalibrated (nominal)", "self-calibration", "true parameters (floor)"
  CalibrationFkResidual residual;  // over the session's poses
  // Simulated devices only: pose error against the simulator's hidden truth on 200 other poses
  // (0.2-3 N): position_error_mean/max (m), rotation_error_mean/max (rad).
  std::optional<haptics::AccuracyReport> accuracy;
};

// What Fit needs besides the readings.
struct CalibrationFitOptions {
  // The homing pretension of the device, N (every string): the simulated device's
  // config().homing_tension; a real board is assumed to home as the simulated one.
  double homing_tension = haptics::SimulatedDeviceConfig().homing_tension;
  // Simulated devices: the device with the hidden truth the calibrations are evaluated on
  // (EvaluateAccuracy moves it: not one a running haptic thread steps); null for a real board.
  haptics::SimulatedSpidarG* truth = nullptr;
  std::uint64_t eval_seed = 1;  // the 200 evaluation poses and their tensions
  int eval_poses = 200;
};

// The outcome of Fit.
struct CalibrationOutcome {
  bool ok = false;
  // Why not: "self-calibration: too_few_samples: ..." (haptics::CalibrationStatusName and the
  // solver's message).
  std::string error;
  std::string message;                    // the solver's summary (ok or not)
  std::vector<CalibrationTableRow> rows;  // uncalibrated, self, and (truth) true parameters
  CalibrationFile file;                   // the self-calibration with its device and date
  int poses = 0;                          // useful poses fitted
};

// The session's bookkeeping (see the file comment). The device's identity goes into the file.
class CalibrationCollector {
 public:
  // Judges the readings of the device `info` (identity `device`) with its nominal calibration
  // and FK acceptance kNominalFkMaxResidual; `poses` useful poses are wanted, at least
  // max(1, poses / 16) in every octant. Throws std::invalid_argument for poses < 1.
  CalibrationCollector(const CalibrationDevice& device, const haptics::DeviceInfo& info, int poses);

  // Offers one reading taken while the motors held `tension` (N, 8) for `held` s. True when kept.
  bool Offer(const haptics::EncoderReading& reading, const haptics::Vector8d& tension, double held);

  int collected() const { return collector_.collected(); }
  int target() const { return collector_.target(); }
  int per_octant() const { return collector_.per_octant(); }
  // Poses kept per octant (index: haptics::Octant(p0); bit 0 x >= 0, bit 1 y >= 0, bit 2 z >= 0).
  const std::array<int, 8>& octant_counts() const { return collector_.octant_counts(); }
  // The octants with fewer than per_octant() poses, in index order.
  std::vector<int> NeededOctants() const;
  // True once target() poses were kept and every octant has per_octant() of them.
  bool Done() const { return collector_.Done(); }
  // "40/100 useful poses; more needed in octants +x+y+z (2/6), ...".
  std::string Progress() const { return collector_.Progress(); }
  // Why readings were not kept.
  const haptics::PoseCollectorCounts& counts() const { return collector_.counts(); }
  // The kept samples, in order.
  const std::vector<haptics::UnknownPoseSample>& samples() const { return collector_.samples(); }
  const CalibrationDevice& device() const { return device_; }
  const haptics::DeviceInfo& info() const { return info_; }
  // The nominal calibration the readings are judged with (the "uncalibrated" row).
  const haptics::EncoderCalibration& nominal() const { return nominal_; }

  // Fits the self-calibration to the kept samples and the homing sample (whatever their number:
  // too few give ok = false with the solver's reason) and makes the table and the file (dated
  // now). Never throws for bad data. Takes up to a few seconds (truth evaluation included).
  CalibrationOutcome Fit(const CalibrationFitOptions& options) const;

 private:
  CalibrationDevice device_;
  haptics::DeviceInfo info_;
  haptics::EncoderCalibration nominal_;
  haptics::CalibrationPoseCollector collector_;
};

}  // namespace spidarcad::app
