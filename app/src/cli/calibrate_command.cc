// `spidarcad calibrate`: calibrates the string-length sensing of a SPIDAR-G.
//   --simulated          a study on the simulated SPIDAR-G, whose hidden truth is known: the
//                        paper's line fit and self-calibration, a before/after table (text or
//                        --json), optionally the calibration file (--out).
//   --device board-sim|usb  a self-calibration session on a connected board (calibrate_session.cc).
// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <iostream>
#include <memory>
#include <nlohmann/json.hpp>
#include <numbers>
#include <optional>
#include <string>
#include <vector>

#include "cli/calibrate_session.h"
#include "cli/cli_common.h"
#include "cli/commands.h"
#include "scene/calibration_file.h"
#include "spidarcad/haptics/calibration.h"
#include "spidarcad/haptics/kinematics.h"
#include "spidarcad/haptics/simulated_device.h"

namespace spidarcad::app {

namespace {

using haptics::AccuracyReport;
using haptics::CalibrationResult;
using haptics::CalibrationStatus;
using haptics::EncoderCalibration;
using haptics::SimulatedSpidarG;

constexpr double kRadToDeg = 180.0 / std::numbers::pi;

constexpr const char* kCalibrateHelp =
    "Calibrates the string-length sensing (per-string encoder offset, gain, winding\n"
    "nonlinearity and string stretch; see haptics/device/include/spidarcad/haptics/encoder.h) and\n"
    "shows how much it improves the measured string lengths and the grip pose.\n"
    "\n"
    "Two uses:\n"
    "  --simulated            a study on the simulated SPIDAR-G, whose hidden imperfections are\n"
    "                         known: the paper's line fit and self-calibration side by side.\n"
    "  --device board-sim|usb a self-calibration session on a connected board: wave the grip\n"
    "                         through the workspace until the progress line says enough poses\n"
    "                         were collected in every octant (board-sim: a simulated hand\n"
    "                         waves it). Then the before/after table and --out FILE.\n"
    "\n"
    "The simulated SPIDAR-G's imperfections are modelled on the paper's device: length-per-\n"
    "count error 6.24 +- 1.54 % per string, winding nonlinearity, string stretch under\n"
    "tension, a homing jig error, noise and quantisation to 0.0251 mm counts. --seed draws a\n"
    "different device; --frame A,B,C --pole D another size (the paper's Sec. 8).\n"
    "\n"
    "Methods (--simulated):\n"
    "  line  the paper's: the grip is held in a jig at --poses known poses; each string's\n"
    "        reference lengths are fitted to a line in its counts (offset, gain).\n"
    "  self  self-calibration: the user waves the grip through --poses unknown poses while\n"
    "        the motors vary each string's tension (0.3-3 N); the 8th string's redundancy\n"
    "        (8 strings, 7 DOF) lets Levenberg-Marquardt estimate every pose and each\n"
    "        string's offset, gain, winding quadratic and stretch, anchored by the homing\n"
    "        pose only (held to a 1 mm / 0.6 deg tolerance: the jig is not exact). Needs 32\n"
    "        poses at least, 100 or more spread over the workspace for accuracy.\n"
    "  both  runs both (default).\n"
    "\n"
    "Evaluation (--simulated): --eval-poses poses drawn in a cube of 5/6 of the frame (the\n"
    "40 cm cube of the 48 cm frame; rotations up to 30 deg, grasp 90 +- 17 deg, string\n"
    "tensions 0.2-3 N). Columns:\n"
    "  gain err %     |gain - true gain| / true gain per string, mean +- sd (before\n"
    "                 calibration this is the paper's 6.24 +- 1.54 %)\n"
    "  length err %   |l - l_true| / l_true over strings and poses, mean +- sd\n"
    "  len rms mm     RMS of l - l_true\n"
    "  pos mm, rot deg  grip position / rotation error of forward kinematics, mean and max\n"
    "The 'true parameters' row uses the simulator's hidden truth (its stretch included): what\n"
    "remains there is noise and quantisation. The line fit's jig poses are all held at one\n"
    "pretension, which cannot reveal string stretch (it keeps the nominal stretch, 0): most\n"
    "of its error is stretch under the evaluation's varying tensions.\n"
    "--json prints the table as JSON instead: {\"uncalibrated\"|\"line\"|\"self\"|\"loaded\"|\n"
    "\"true_parameters\": {\"status\", \"position_mm\": {\"mean\", \"max\"}, \"rotation_deg\":\n"
    "{\"mean\", \"max\"}, \"length_rms_mm\", \"fk_failures\", ...}}.\n"
    "\n"
    "--out writes the calibration file (self if it succeeded, else line): JSON with the\n"
    "device's identity (kind, seed or serial, frame and pole), the date, the method, the\n"
    "per-string parameters and the fit residuals; docs/calibration-format.md. `spidarcad run\n"
    "--calibration FILE` reads it. --load evaluates a saved file on the same simulated device\n"
    "(a file made on another device or frame is refused with the reason). Exit status: 0 when\n"
    "every requested calibration succeeded, 1 when one failed (the reason is printed), 2 for\n"
    "bad input.\n"
    "\n"
    "Examples:\n"
    "  spidarcad calibrate --simulated\n"
    "  spidarcad calibrate --simulated --seed 3 --json\n"
    "  spidarcad calibrate --simulated --seed 7 --poses 40 --method self --out cal.json\n"
    "  spidarcad calibrate --simulated --seed 7 --method line --load cal.json\n"
    "  spidarcad calibrate --device board-sim --seed 7 --out cal.json\n"
    "  spidarcad calibrate --device usb --out board.json";

struct CalibrateOptions {
  bool simulated = false;
  std::string device;  // "" (use --simulated), board-sim, usb
  std::uint64_t seed = 1;
  int poses = -1;  // -1: 100 (--simulated) or 200 (--device)
  int eval_poses = 200;
  std::string method = "both";
  std::string out;
  std::string load;
  bool json = false;
  double timeout = 0.0;  // --device: give up after this long, s (0: the default)
  haptics::SpidarGeometry geometry;
};

std::string Format(const char* fmt, double a, double b) {
  char buffer[64];
  std::snprintf(buffer, sizeof(buffer), fmt, a, b);
  return buffer;
}

// Mean and sd of the relative gain error of `cal` against the device's hidden truth, in %.
std::pair<double, double> GainError(const EncoderCalibration& cal, const SimulatedSpidarG& dev) {
  double sum = 0, sum_sq = 0;
  for (int i = 0; i < haptics::kNumStrings; ++i) {
    const double truth = dev.true_encoder().strings[i].gain;
    const double e = 100.0 * std::abs(cal.strings[i].gain - truth) / truth;
    sum += e;
    sum_sq += e * e;
  }
  const double mean = sum / haptics::kNumStrings;
  return {mean, std::sqrt(std::max(0.0, sum_sq / haptics::kNumStrings - mean * mean))};
}

// One row of the before/after table.
struct Row {
  std::string key;      // JSON key: uncalibrated, line, self, loaded, true_parameters
  std::string name;     // table label
  std::string status;   // "ok", a CalibrationStatusName, or "-" (not a calibration)
  std::string message;  // why, when it failed
  std::optional<AccuracyReport> accuracy;          // absent when the calibration failed
  std::pair<double, double> gain_error{0.0, 0.0};  // %, mean and sd (simulated truth)
};

void PrintTable(const std::vector<Row>& rows) {
  std::printf("%-26s %-15s %-14s %-14s %8s %16s %16s %5s\n", "method", "status", "gain err %",
              "length err %", "len rms", "pos mm", "rot deg", "fk");
  std::printf("%-26s %-15s %-14s %-14s %8s %16s %16s %5s\n", "", "", "(mean +- sd)", "(mean +- sd)",
              "mm", "(mean / max)", "(mean / max)", "fail");
  for (const Row& row : rows) {
    if (!row.accuracy) {
      std::printf("%-26s %-15s %-14s %-14s %8s %16s %16s %5s\n", row.name.c_str(),
                  row.status.c_str(), "-", "-", "-", "-", "-", "-");
      continue;
    }
    const AccuracyReport& r = *row.accuracy;
    std::printf(
        "%-26s %-15s %-14s %-14s %8.3f %16s %16s %5d\n", row.name.c_str(), row.status.c_str(),
        Format("%.2f +- %.2f", row.gain_error.first, row.gain_error.second).c_str(),
        Format("%.2f +- %.2f", 100 * r.length_error_mean, 100 * r.length_error_sd).c_str(),
        1e3 * r.length_abs_error_rms,
        Format("%.2f / %.2f", 1e3 * r.position_error_mean, 1e3 * r.position_error_max).c_str(),
        Format("%.2f / %.2f", kRadToDeg * r.rotation_error_mean, kRadToDeg * r.rotation_error_max)
            .c_str(),
        r.fk_failures);
  }
}

nlohmann::json TableJson(const std::vector<Row>& rows) {
  nlohmann::json j = nlohmann::json::object();
  for (const Row& row : rows) {
    nlohmann::json entry;
    entry["status"] = row.status == "-" ? "ok" : row.status;
    if (!row.accuracy) {
      entry["message"] = row.message;
      j[row.key] = entry;
      continue;
    }
    const AccuracyReport& r = *row.accuracy;
    entry["position_mm"] = {{"mean", 1e3 * r.position_error_mean},
                            {"max", 1e3 * r.position_error_max}};
    entry["rotation_deg"] = {{"mean", kRadToDeg * r.rotation_error_mean},
                             {"max", kRadToDeg * r.rotation_error_max}};
    entry["length_rms_mm"] = 1e3 * r.length_abs_error_rms;
    entry["length_error_percent"] = {{"mean", 100 * r.length_error_mean},
                                     {"sd", 100 * r.length_error_sd}};
    entry["gain_error_percent"] = {{"mean", row.gain_error.first}, {"sd", row.gain_error.second}};
    entry["fk_failures"] = r.fk_failures;
    entry["poses"] = r.num_poses;
    j[row.key] = entry;
  }
  return j;
}

void CheckCounts(const CalibrateOptions& options) {
  // A calibration uses tens to hundreds of poses; 100,000 bounds the memory and time it may take.
  constexpr int kMaxPoses = 100000;
  if (options.poses != -1 && (options.poses < 1 || options.poses > kMaxPoses)) {
    throw InputError("--poses: must be in [1, " + std::to_string(kMaxPoses) + "], got " +
                     std::to_string(options.poses) +
                     " (100 to 300 poses reach the floor; see --help)");
  }
  if (options.eval_poses < 1 || options.eval_poses > kMaxPoses) {
    throw InputError("--eval-poses: must be in [1, " + std::to_string(kMaxPoses) + "], got " +
                     std::to_string(options.eval_poses));
  }
}

// --simulated: line fit and self-calibration on the simulated SPIDAR-G, judged against its
// hidden truth.
void RunSimulatedStudy(const CalibrateOptions& given) {
  CheckCounts(given);
  CalibrateOptions options = given;
  if (options.poses == -1) options.poses = 100;
  ValidateGeometry(options.geometry);
  haptics::SimulatedDeviceConfig config;
  config.seed = options.seed;
  config.geometry = options.geometry;
  config.home_pose = haptics::GripPose::Rest(options.geometry.d);
  CalibrationDevice identity;
  identity.kind = "simulated";
  identity.seed = options.seed;
  identity.geometry = options.geometry;
  identity.encoder = config.encoder;
  // Read the file to evaluate first, so that a bad or foreign file fails before any work.
  std::optional<CalibrationFile> loaded;
  if (!options.load.empty()) {
    loaded = LoadCalibrationFile(options.load);
    const std::string why = CalibrationMismatch(*loaded, identity);
    if (!why.empty()) throw InputError("--load: " + options.load + " does not fit: " + why);
  }

  SimulatedSpidarG device(config);
  const haptics::SpidarGeometry& geometry = device.info().geometry;
  const double pretension = config.homing_tension;
  const EncoderCalibration nominal = EncoderCalibration::Nominal(
      device.info().encoder, haptics::InverseKinematics(geometry, device.info().home_pose));

  // The 40 cm cube of the paper's 48 cm frame, scaled with the frame.
  const double half_cube = std::min({geometry.a, geometry.b, geometry.c}) * (0.2 / 0.24);
  constexpr double kMaxRotation = 30.0 / kRadToDeg;
  constexpr double kGraspRange = 0.3;
  constexpr double kTensionLo = 0.2, kTensionHi = 3.0;
  constexpr double kWaveTensionLo = 0.3, kWaveTensionHi = 3.0;  // self: tensions while waving
  const auto eval_poses = haptics::RandomGripPoses(
      geometry, options.eval_poses, half_cube, kMaxRotation, kGraspRange, options.seed * 7919 + 1);
  const auto calibration_poses = haptics::RandomGripPoses(
      geometry, options.poses, half_cube, kMaxRotation, kGraspRange, options.seed * 104729 + 2);

  std::vector<Row> rows;
  const auto evaluate = [&](const EncoderCalibration& cal) {
    return haptics::EvaluateAccuracy(&device, cal, eval_poses, kTensionLo, kTensionHi, 1);
  };
  rows.push_back({"uncalibrated", "uncalibrated (nominal)", "-", "", evaluate(nominal),
                  GainError(nominal, device)});

  std::vector<std::string> failures;
  const bool run_line = options.method == "line" || options.method == "both";
  const bool run_self = options.method == "self" || options.method == "both";
  CalibrationResult line, self;
  const CalibrationResult* best = nullptr;
  std::string best_method;
  int best_samples = 0;
  const auto report = [&](const std::string& key, const std::string& name,
                          const CalibrationResult& r) {
    Row row{key, name, haptics::CalibrationStatusName(r.status), r.message, std::nullopt, {}};
    if (r.status != CalibrationStatus::kOk) {
      failures.push_back(name + ": " + row.status + ": " + r.message);
    } else {
      row.accuracy = evaluate(r.calibration);
      row.gain_error = GainError(r.calibration, device);
    }
    rows.push_back(row);
    return r.status == CalibrationStatus::kOk;
  };
  if (run_line) {
    const auto jig = haptics::GatherKnownSamples(&device, calibration_poses, pretension);
    line = haptics::FitLinesPerString(geometry, nominal, jig);
    if (report("line", "line fit (paper, jig)", line)) {
      best = &line;
      best_method = "line";
      best_samples = static_cast<int>(jig.size());
    }
  }
  if (run_self) {
    // As on a real device: the homing sample (counters zero at the jig's pose, reproduced only
    // to the jig's tolerance) and the waved poses, with the tensions varied per string so
    // that stretch is estimated too.
    const std::vector<haptics::KnownPoseSample> home = {
        haptics::HomingSample(device.info(), config.homing_tension)};
    const auto wave = haptics::GatherUnknownSamples(
        &device, calibration_poses,
        haptics::CalibrationTensions(options.poses, kWaveTensionLo, kWaveTensionHi, options.seed));
    self = haptics::SelfCalibrate(geometry, nominal, home, wave);
    if (report("self", "self-calibration", self)) {
      best = &self;
      best_method = "self";
      best_samples = static_cast<int>(wave.size() + home.size());
    }
  }
  if (loaded) {
    rows.push_back({"loaded", "loaded " + std::filesystem::path(options.load).filename().string(),
                    "-", "", evaluate(loaded->calibration),
                    GainError(loaded->calibration, device)});
  }
  rows.push_back({"true_parameters", "true parameters (floor)", "-", "",
                  evaluate(device.true_encoder()), GainError(device.true_encoder(), device)});

  // Output: the table on stdout (text or JSON), notes on stdout (text) or stderr (JSON).
  std::FILE* notes = options.json ? stderr : stdout;
  if (options.json) {
    std::printf("%s\n", TableJson(rows).dump(2).c_str());
  } else {
    std::printf(
        "Simulated SPIDAR-G (seed %llu): frame %.0f x %.0f x %.0f cm, pole %.1f cm, 0.0251 mm "
        "per count.\nCalibration: %d poses. Evaluation: %d poses in a %.0f cm cube, rotation <= "
        "30 deg, grasp\n90 +- 17 deg, tensions 0.2-3 N.\n\n",
        static_cast<unsigned long long>(options.seed), 200 * geometry.a, 200 * geometry.b,
        200 * geometry.c, 100 * geometry.d, options.poses, options.eval_poses, 200 * half_cube);
    PrintTable(rows);
    std::printf(
        "\nPaper (Sec. 6): length error 6.24 +- 1.54 %% before, 0.80 +- 0.4 %% after the line "
        "fit;\nposition error under 4 mm in a 40 cm cube.\n");
  }
  if (run_line && line.status == CalibrationStatus::kOk) {
    std::fprintf(notes, "line: %s\n", line.message.c_str());
  }
  if (run_self && self.status == CalibrationStatus::kOk) {
    std::fprintf(notes, "self: %s\n", self.message.c_str());
  }
  if (!options.out.empty()) {
    if (best != nullptr) {
      CalibrationFile file;
      file.device = identity;
      file.date = NowIso8601Utc();
      file.method = best_method;
      file.calibration = best->calibration;
      file.fit = FitOf(*best, best_samples);
      SaveCalibrationFile(file, options.out);
      std::fprintf(notes, "wrote %s (%s)\n", options.out.c_str(), best_method.c_str());
    } else {
      failures.push_back("--out: no calibration succeeded, '" + options.out + "' not written");
    }
  }
  std::fflush(stdout);
  for (const std::string& f : failures) std::cerr << "spidarcad calibrate: " << f << "\n";
  if (!failures.empty()) throw CommandExit{1};
}

void RunCalibrate(const CalibrateOptions& options) {
  if (!options.device.empty() && options.device != "simulated") {
    if (options.simulated) {
      throw InputError("--simulated and --device " + options.device +
                       ": choose one (--simulated is the study on the simulated SPIDAR-G)");
    }
    if (options.device != "board-sim" && options.device != "usb") {
      throw InputError("--device: '" + options.device +
                       "' is not a device; use board-sim or usb (or --simulated)");
    }
    CalibrationSessionOptions session;
    session.device = options.device;
    session.seed = options.seed;
    session.geometry = options.geometry;
    CheckCounts(options);
    session.poses = options.poses == -1 ? 200 : options.poses;
    session.out = options.out;
    session.json = options.json;
    session.max_seconds = options.timeout;
    RunCalibrationSession(session);
    return;
  }
  if (!options.simulated && options.device.empty()) {
    throw InputError(
        "calibrate: say which device: --simulated (a study on the simulated SPIDAR-G) or "
        "--device board-sim|usb (a self-calibration session on a board)");
  }
  RunSimulatedStudy(options);
}

}  // namespace

void RegisterCalibrateCommand(CLI::App& app) {
  auto options = std::make_shared<CalibrateOptions>();
  CLI::App* cmd = app.add_subcommand(
      "calibrate", "Calibrate string-length sensing: before/after table and calibration file");
  cmd->footer(kCalibrateHelp);
  cmd->add_flag("--simulated", options->simulated,
                "Study on the simulated SPIDAR-G: line fit and self-calibration against its "
                "hidden truth");
  cmd->add_option("--device", options->device,
                  "Self-calibration session on a board: board-sim (the board simulator, a "
                  "simulated hand waves the grip) or usb (a real board, you wave it)");
  cmd->add_option("--seed", options->seed,
                  "Seed of the simulated device's imperfections and noise (default 1)");
  cmd->add_option("--poses", options->poses,
                  "Calibration poses: --simulated: the number used (default 100); --device: "
                  "the useful poses to collect (default 200)");
  cmd->add_option("--eval-poses", options->eval_poses,
                  "Number of evaluation poses (--simulated; default 200)");
  cmd->add_option("--method", options->method, "line, self or both (--simulated; default both)")
      ->check(CLI::IsMember({"line", "self", "both"}));
  cmd->add_option("--out", options->out,
                  "Write the calibration file (JSON, docs/calibration-format.md)");
  cmd->add_option("--load", options->load,
                  "Evaluate the calibration file on the same simulated device (--simulated)");
  cmd->add_flag("--json", options->json,
                "Print the before/after table as JSON (position error in mm, rotation error in "
                "deg, mean and max, per method)");
  cmd->add_option("--timeout", options->timeout,
                  "--device: give up after this many seconds without enough poses (default 180 "
                  "of simulated time for board-sim, 300 for usb)");
  AddGeometryOptions(*cmd, &options->geometry);
  cmd->callback([options]() { RunCalibrate(*options); });
}

}  // namespace spidarcad::app
