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
//     with a Schur complement, plus 2 to 4 per string).
//
// Identifiability (SelfCalibrate). The frame size (a, b, c, d) fixes the length scale, so the
// gains are identifiable from unknown poses alone once the poses span the workspace (tested).
// So are the offsets: a constant length error moves the strings' lengths in a way no pose
// change reproduces across the workspace (string directions differ from pose to pose), so a
// known pose (the homing pose, where the counters were zeroed) only anchors them. The homing
// jig reproduces its pose to a fraction of a millimetre, and holding that pose exactly puts the
// jig's error into every offset (0.2–0.6 mm of pose error on the simulated device); by default
// the known poses are therefore estimated too, pulled toward the known pose with a tolerance
// (known_position_sd, known_rotation_sd) that the data overrule. The winding quadratics are
// identifiable from poses far from home (where u² is large). Stretch (strain per newton) is
// identifiable only when the tensions vary between samples: at one tension h = L (1 + s τ) is
// a rescaled L, indistinguishable from gain and offset. Unmodelled stretch was the dominant
// error of self-calibration from samples at one pretension (0.5–0.8 mm of pose error at
// 0.2–3 N on the simulated device, ten times the floor); so a calibration session varies the
// tensions (CalibrationTensions) and SelfCalibrate estimates stretch whenever every string's
// tension spans min_tension_spread, keeping the initial stretch otherwise. Counting: each
// unknown pose adds 8 equations and 7 unknowns, so with P parameters in all and K_known known
// poses the data need K_unknown > P − 8 K_known; SelfCalibrate asks for at least
// P − 8 K_known + 2 × (parameters per string) unknown poses (22 for offset, gain and quadratic
// with the homing pose, 32 with stretch), recommends ten times that, checks the conditioning of
// the reduced problem and reports kDegenerate instead of returning garbage when the data do not
// determine the parameters (poses that do not move, too little spread).
//
// Solver: a common gain scale is first chosen on a grid (the one large error that can trap
// the joint solve), poses start from ForwardKinematics, then Levenberg-Marquardt with the
// per-pose 7×7 blocks eliminated (Schur complement); after convergence any pose whose own FK
// fits better is re-seeded and LM resumes (at most 5 rounds). Known poses with a tolerance
// are pose blocks like the unknown ones, with a prior residual (known ⊖ estimated, weighted by
// length_sd / tolerance) added to the cost.
//
// Not real-time code: these run off the haptic thread and allocate.
// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "spidarcad/haptics/device.h"
#include "spidarcad/haptics/encoder.h"
#include "spidarcad/haptics/geometry.h"

namespace spidarcad::haptics {

class SimulatedSpidarG;

// A sample taken with the grip at a known pose (a jig, or the homing pose).
struct KnownPoseSample {
  GripPose pose;                        // pose in D; the reference lengths are IK(pose)
  EncoderCounts counts{};               // encoder counters
  Vector8d tension = Vector8d::Zero();  // tensions while sampling, N
};

// A sample taken with the grip at an unknown pose (the user waving the grip).
struct UnknownPoseSample {
  EncoderCounts counts{};
  Vector8d tension = Vector8d::Zero();
};

// How a calibration ended.
enum class CalibrationStatus : std::uint8_t {
  kOk = 0,         // parameters estimated
  kInvalidInput,   // non-finite numbers or a bad initial calibration
  kTooFewSamples,  // fewer samples than the parameters need (see message)
  kDegenerate,     // the samples do not determine the parameters (no spread, repeated poses)
  kNotConverged,   // the iteration budget ran out
};

// One word for a status ("ok", "invalid_input", ...).
const char* CalibrationStatusName(CalibrationStatus status);

// Result of a calibration. When status != kOk, `calibration` is the initial one unchanged.
struct CalibrationResult {
  CalibrationStatus status = CalibrationStatus::kInvalidInput;
  EncoderCalibration calibration;  // estimated parameters
  std::string message;             // why, when status != kOk; a summary otherwise
  double rms_residual = 0.0;       // RMS of (model length − measured length) over all data, m
  Vector8d string_rms_residual = Vector8d::Zero();  // the same per string, m
  int iterations = 0;                               // LM iterations (0 for the line fit)
  double condition = 0.0;       // condition number of the scaled parameter information
  std::vector<GripPose> poses;  // SelfCalibrate: estimated unknown poses, in input order
};

// Settings of FitLinesPerString.
struct LineFitSettings {
  bool fit_quadratic = false;  // also fit the winding quadratic (3 parameters per string)
  double min_span = 0.02;      // m; each string's nominal paid-out lengths must span this
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
  bool estimate_offset = true;            // estimate offsets (needs known samples to anchor them)
  bool estimate_quadratic = true;         // estimate winding quadratics (needs poses far from home)
  int max_iterations = 100;               // LM iterations
  double tolerance = 1e-12;               // stop when the relative cost decrease is below this
  double max_condition = 1e9;             // above this the data are reported kDegenerate
  double initial_fk_max_residual = 0.05;  // m; FK acceptance for the starting poses
  // Estimate each string's stretch (compliance) too, when every string's tension spans at
  // least min_tension_spread over the samples; otherwise it is kept from `initial` and the
  // message says so. At one tension stretch cannot be told from gain and offset.
  bool estimate_stretch = true;
  double min_tension_spread = 1.0;  // N
  // Tolerance of the known poses (a jig reproduces the homing pose only to so much): 0 holds
  // them exactly; > 0 estimates their poses too, pulled toward the known ones with these
  // standard deviations (m per axis, rad per axis and for the grasp). Both 0 or both > 0.
  double known_position_sd = 1e-3;
  double known_rotation_sd = 0.01;
  // Standard deviation of one length reading (noise and quantisation), m: weighs the known
  // poses' tolerance against the lengths.
  double length_sd = 1.2e-5;
};

// Self-calibration from `unknown` samples (poses unknown) anchored by `known` samples (at least
// the homing pose). Starts from `initial` (typically the nominal calibration), estimates the
// per-string offset, gain, quadratic and (with varying tensions) stretch, and every pose.
CalibrationResult SelfCalibrate(const SpidarGeometry& geometry, const EncoderCalibration& initial,
                                const std::vector<KnownPoseSample>& known,
                                const std::vector<UnknownPoseSample>& unknown,
                                const SelfCalibrationSettings& settings = {});

// Accuracy of a calibration on poses with known truth.
struct AccuracyReport {
  int num_poses = 0;
  int fk_failures = 0;             // poses where ForwardKinematics returned no pose
  double length_error_mean = 0.0;  // mean of |l_est − l_true| / l_true over strings, poses
  double length_error_sd = 0.0;    // its standard deviation (fractions, not per cent)
  double length_error_max = 0.0;
  double length_abs_error_rms = 0.0;  // RMS of l_est − l_true, m
  double position_error_mean = 0.0;   // |p0_est − p0_true|, m
  double position_error_max = 0.0;
  double rotation_error_mean = 0.0;  // angle between R_est and R_true, rad
  double rotation_error_max = 0.0;
  double grasp_error_max = 0.0;  // |θ_est − θ_true|, rad
};

// Random poses for calibration and evaluation, deterministic in `seed`: centre uniform in the
// cube |x|,|y|,|z| <= half_side (m), rotation by an angle uniform in [0, max_rotation] (rad)
// about a random axis, grasp uniform in [π/2 − grasp_range, π/2 + grasp_range]; poses with an
// attachment point closer than 1 cm to a frame face are redrawn.
std::vector<GripPose> RandomGripPoses(const SpidarGeometry& geometry, int count, double half_side,
                                      double max_rotation, double grasp_range, std::uint64_t seed);

// The sample every device gives without a jig session: counters zero at its homing pose
// (info.home_pose, reproduced by the homing jig only to its tolerance), under the homing
// pretension `homing_tension` (N, every string).
KnownPoseSample HomingSample(const DeviceInfo& info, double homing_tension);

// Moves the simulated grip through `poses` under constant `tension` (N, all strings), letting
// the motors settle, and records the readings as known-pose samples (the jig's poses).
std::vector<KnownPoseSample> GatherKnownSamples(SimulatedSpidarG* device,
                                                const std::vector<GripPose>& poses, double tension);
// The same, forgetting the poses (the user waving the grip).
std::vector<UnknownPoseSample> GatherUnknownSamples(SimulatedSpidarG* device,
                                                    const std::vector<GripPose>& poses,
                                                    double tension);
// The same with the tensions (N, one vector per pose) the motors hold at each pose. Throws
// std::invalid_argument when the counts of poses and tensions differ.
std::vector<UnknownPoseSample> GatherUnknownSamples(SimulatedSpidarG* device,
                                                    const std::vector<GripPose>& poses,
                                                    const std::vector<Vector8d>& tensions);

// Tensions for a calibration session, deterministic in `seed`: `count` vectors whose entries
// are uniform in [lo, hi] (N), independently per string, so that stretch can be estimated.
std::vector<Vector8d> CalibrationTensions(int count, double lo, double hi, std::uint64_t seed);

// Length and pose accuracy of `calibration` on the simulated device: at each pose, with string
// tensions drawn uniformly in [tension_lo, tension_hi] (seeded), compares the calibrated lengths
// with the true ones and the ForwardKinematics pose with the true pose.
AccuracyReport EvaluateAccuracy(SimulatedSpidarG* device, const EncoderCalibration& calibration,
                                const std::vector<GripPose>& poses, double tension_lo,
                                double tension_hi, std::uint64_t seed);

}  // namespace spidarcad::haptics
