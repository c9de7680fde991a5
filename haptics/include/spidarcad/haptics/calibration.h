// Calibration of the string-length sensing: estimating each string's encoder parameters
// (encoder.h: offset, gain, winding quadratic) from data the device can gather.
//
// Two methods:
//  1. FitLinesPerString, the paper's (Sec. 6): the grip is held in a jig at poses whose string
//     lengths are known; each string's reference lengths are fitted to a line in its counts by
//     linear least squares (offset and gain; optionally the quadratic term).
//  2. SelfCalibrate: no jig beyond the homing pose. The user waves the grip through many
//     unknown poses; since 8 strings over-determine the 7-DOF pose, each pose carries one
//     redundant length, and with enough poses the per-string parameters and all poses are
//     estimated jointly by Levenberg-Marquardt (7 unknowns per pose, eliminated pose by pose
//     with a Schur complement, plus 2 or 3 per string).
//
// Identifiability (SelfCalibrate). The frame size (a, b, c, d) fixes the length scale, so the
// gains are identifiable from unknown poses alone once the poses span the workspace (tested);
// the offsets are anchored by a known pose (SelfCalibrate requires one when it estimates
// offsets; without one they are at best weakly determined). With the homing pose, where the
// counters were zeroed, offset_i is the string's length at home, so the homing jig's error
// goes straight into the offsets; the winding quadratics are identifiable from poses far from home (where u² is
// large) and are estimated by default. Stretch is not identifiable from data taken at one
// constant tension: it is kept at its initial (nominal) value. Counting: each unknown pose
// adds 8 equations and 7 unknowns, so with P parameters in all and K_known known poses the
// data need K_unknown > P − 8 K_known; SelfCalibrate asks for at least
// P − 8 K_known + 2 × (parameters per string) unknown poses (22 for the defaults with the
// homing pose), recommends ten times that, checks the conditioning of the reduced problem and
// reports kDegenerate instead of returning garbage when the data do not determine the
// parameters (poses that do not move, too little spread).
//
// Solver: a common gain scale is first chosen on a grid (the one large error that can trap
// the joint solve), poses start from ForwardKinematics, then Levenberg-Marquardt with the
// per-pose 7×7 blocks eliminated (Schur complement); after convergence any pose whose own FK
// fits better is re-seeded and LM resumes (at most 5 rounds).
//
// Not real-time code: these run off the haptic thread and allocate.
// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "spidarcad/haptics/encoder.h"
#include "spidarcad/haptics/geometry.h"

namespace spidarcad::haptics {

class SimulatedSpidarG;

// A sample taken with the grip at a known pose (a jig, or the homing pose).
struct KnownPoseSample {
  GripPose pose;                          // pose in D; the reference lengths are IK(pose)
  EncoderCounts counts{};                 // encoder counters
  Vector8d tension = Vector8d::Zero();    // tensions while sampling, N
};

// A sample taken with the grip at an unknown pose (the user waving the grip).
struct UnknownPoseSample {
  EncoderCounts counts{};
  Vector8d tension = Vector8d::Zero();
};

// How a calibration ended.
enum class CalibrationStatus : std::uint8_t {
  kOk = 0,           // parameters estimated
  kInvalidInput,     // non-finite numbers or a bad initial calibration
  kTooFewSamples,    // fewer samples than the parameters need (see message)
  kDegenerate,       // the samples do not determine the parameters (no spread, repeated poses)
  kNotConverged,     // the iteration budget ran out
};

// One word for a status ("ok", "invalid_input", ...).
const char* CalibrationStatusName(CalibrationStatus status);

// Result of a calibration. When status != kOk, `calibration` is the initial one unchanged.
struct CalibrationResult {
  CalibrationStatus status = CalibrationStatus::kInvalidInput;
  EncoderCalibration calibration;   // estimated parameters (stretch kept from the initial)
  std::string message;              // why, when status != kOk; a summary otherwise
  double rms_residual = 0.0;        // RMS of (model length − measured length) over all data, m
  int iterations = 0;               // LM iterations (0 for the line fit)
  double condition = 0.0;           // condition number of the scaled parameter information
  std::vector<GripPose> poses;      // SelfCalibrate: estimated unknown poses, in input order
};

// Settings of FitLinesPerString.
struct LineFitSettings {
  bool fit_quadratic = false;     // also fit the winding quadratic (3 parameters per string)
  double min_span = 0.02;         // m; each string's nominal paid-out lengths must span this
};

// The paper's method: per-string linear least squares of reference length (IK of the known
// pose, divided by the stretch factor of `initial`) against nominal paid-out length u = n·m.
// Needs >= 2 samples (3 with fit_quadratic) whose counts span min_span on every string.
CalibrationResult FitLinesPerString(const SpidarGeometry& geometry,
                                    const EncoderCalibration& initial,
                                    const std::vector<KnownPoseSample>& samples,
                                    const LineFitSettings& settings = {});

// Settings of SelfCalibrate.
struct SelfCalibrationSettings {
  bool estimate_offset = true;      // estimate offsets (needs known samples to anchor them)
  bool estimate_quadratic = true;   // estimate winding quadratics (needs poses far from home)
  int max_iterations = 100;         // LM iterations
  double tolerance = 1e-12;         // stop when the relative cost decrease is below this
  double max_condition = 1e9;       // above this the data are reported kDegenerate
  double initial_fk_max_residual = 0.05;  // m; FK acceptance for the starting poses
};

// Self-calibration from `unknown` samples (poses unknown) anchored by `known` samples (at least
// the homing pose). Starts from `initial` (typically the nominal calibration), estimates the
// per-string offset, gain (and quadratic) and every unknown pose.
CalibrationResult SelfCalibrate(const SpidarGeometry& geometry,
                                const EncoderCalibration& initial,
                                const std::vector<KnownPoseSample>& known,
                                const std::vector<UnknownPoseSample>& unknown,
                                const SelfCalibrationSettings& settings = {});

// Accuracy of a calibration on poses with known truth.
struct AccuracyReport {
  int num_poses = 0;
  int fk_failures = 0;                // poses where ForwardKinematics returned no pose
  double length_error_mean = 0.0;     // mean of |l_est − l_true| / l_true over strings, poses
  double length_error_sd = 0.0;       // its standard deviation (fractions, not per cent)
  double length_error_max = 0.0;
  double length_abs_error_rms = 0.0;  // RMS of l_est − l_true, m
  double position_error_mean = 0.0;   // |p0_est − p0_true|, m
  double position_error_max = 0.0;
  double rotation_error_mean = 0.0;   // angle between R_est and R_true, rad
  double rotation_error_max = 0.0;
  double grasp_error_max = 0.0;       // |θ_est − θ_true|, rad
};

// Random poses for calibration and evaluation, deterministic in `seed`: centre uniform in the
// cube |x|,|y|,|z| <= half_side (m), rotation by an angle uniform in [0, max_rotation] (rad)
// about a random axis, grasp uniform in [π/2 − grasp_range, π/2 + grasp_range]; poses with an
// attachment point closer than 1 cm to a frame face are redrawn.
std::vector<GripPose> RandomGripPoses(const SpidarGeometry& geometry, int count,
                                      double half_side, double max_rotation, double grasp_range,
                                      std::uint64_t seed);

// Moves the simulated grip through `poses` under constant `tension` (N, all strings), letting
// the motors settle, and records the readings as known-pose samples (the jig's poses).
std::vector<KnownPoseSample> GatherKnownSamples(SimulatedSpidarG* device,
                                                const std::vector<GripPose>& poses,
                                                double tension);
// The same, forgetting the poses (the user waving the grip).
std::vector<UnknownPoseSample> GatherUnknownSamples(SimulatedSpidarG* device,
                                                    const std::vector<GripPose>& poses,
                                                    double tension);

// Length and pose accuracy of `calibration` on the simulated device: at each pose, with string
// tensions drawn uniformly in [tension_lo, tension_hi] (seeded), compares the calibrated lengths
// with the true ones and the ForwardKinematics pose with the true pose.
AccuracyReport EvaluateAccuracy(SimulatedSpidarG* device, const EncoderCalibration& calibration,
                                const std::vector<GripPose>& poses, double tension_lo,
                                double tension_hi, std::uint64_t seed);

}  // namespace spidarcad::haptics
