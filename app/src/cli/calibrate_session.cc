// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#include "cli/calibrate_session.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <iostream>
#include <nlohmann/json.hpp>
#include <numbers>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include "cli/cli_common.h"
#include "scene/calibration_collector.h"
#include "scene/calibration_file.h"
#include "scene/device_rig.h"
#include "spidarcad/haptics/calibration.h"
#include "spidarcad/haptics/calibration_session.h"
#include "spidarcad/haptics/kinematics.h"
#include "spidarcad/haptics/simulated_device.h"
#include "spidarcad/haptics/simulated_hand.h"
#include "spidarcad/haptics/trajectory.h"

namespace spidarcad::app {

namespace {

using haptics::Vector8d;

constexpr double kDt = 1e-3;  // s, one device sample
constexpr double kRadToDeg = 180.0 / std::numbers::pi;

std::string Pair(double a, double b, int digits) {
  char text[64];
  std::snprintf(text, sizeof(text), "%.*f / %.*f", digits, a, digits, b);
  return text;
}

void PrintSessionTable(const std::vector<CalibrationTableRow>& rows) {
  std::printf("%-26s %20s %18s %18s\n", "method", "fk residual mm", "pos mm", "rot deg");
  std::printf("%-26s %20s %18s %18s\n", "", "(rms / max)", "(mean / max)", "(mean / max)");
  for (const CalibrationTableRow& row : rows) {
    const std::string residual = Pair(1e3 * row.residual.rms, 1e3 * row.residual.max, 3);
    const std::string pos = row.accuracy ? Pair(1e3 * row.accuracy->position_error_mean,
                                                1e3 * row.accuracy->position_error_max, 3)
                                         : "-";
    const std::string rot = row.accuracy ? Pair(kRadToDeg * row.accuracy->rotation_error_mean,
                                                kRadToDeg * row.accuracy->rotation_error_max, 2)
                                         : "-";
    std::printf("%-26s %20s %18s %18s\n", row.name.c_str(), residual.c_str(), pos.c_str(),
                rot.c_str());
  }
}

nlohmann::json SessionJson(const std::vector<CalibrationTableRow>& rows) {
  nlohmann::json j = nlohmann::json::object();
  for (const CalibrationTableRow& row : rows) {
    nlohmann::json entry;
    entry["status"] = "ok";
    entry["fk_residual_mm"] = {{"rms", 1e3 * row.residual.rms}, {"max", 1e3 * row.residual.max}};
    if (row.accuracy) {
      entry["position_mm"] = {{"mean", 1e3 * row.accuracy->position_error_mean},
                              {"max", 1e3 * row.accuracy->position_error_max}};
      entry["rotation_deg"] = {{"mean", kRadToDeg * row.accuracy->rotation_error_mean},
                               {"max", kRadToDeg * row.accuracy->rotation_error_max}};
      entry["fk_failures"] = row.accuracy->fk_failures;
    }
    j[row.key] = entry;
  }
  return j;
}

}  // namespace

void RunCalibrationSession(const CalibrationSessionOptions& options) {
  ValidateGeometry(options.geometry);
  if (options.poses < 1) {
    throw InputError("--poses: must be at least 1, got " + std::to_string(options.poses));
  }
  if (!(options.max_seconds >= 0.0) || !std::isfinite(options.max_seconds)) {
    throw InputError("--timeout: must be a number of seconds >= 0 (0: the default)");
  }
  RigKind kind = RigKind::kBoardSim;
  if (!ParseRigKind(options.device, &kind) || kind == RigKind::kSimulated) {
    throw InputError("--device: '" + options.device + "': use board-sim or usb");
  }
  RigOptions rig_options;
  rig_options.device.seed = options.seed;
  rig_options.device.geometry = options.geometry;
  rig_options.device.home_pose = haptics::GripPose::Rest(options.geometry.d);
  rig_options.reconnect_off_tick = kind == RigKind::kUsb;
  std::unique_ptr<DeviceRig> rig;
  try {
    rig = MakeDeviceRig(kind, rig_options);
  } catch (const std::invalid_argument& e) {
    throw InputError(std::string("--device ") + options.device + ": " + e.what());
  }
  const haptics::DeviceInfo& info = rig->info();
  haptics::SimulatedSpidarG* physical = rig->physical();  // board-sim; null for a real board
  const double max_seconds =
      options.max_seconds > 0.0 ? options.max_seconds : (physical ? 180.0 : 300.0);

  // board-sim: a simulated hand waves the grip (it starts at the homing pose, the centre).
  haptics::Trajectory wave;
  std::optional<haptics::SimulatedHand> hand;
  if (physical != nullptr) {
    wave = haptics::WavingTrajectory(info.geometry, max_seconds, options.seed);
    hand.emplace(haptics::HandSettings{}, wave.Sample(0.0), info.geometry.d);
  }
  if (!rig->Start(hand ? hand->pose() : info.home_pose)) throw InputError(rig->StartFailure());
  const RigServiceThread service(rig.get());

  CalibrationDevice identity;
  identity.kind = options.device;
  identity.seed = physical != nullptr ? options.seed : 0;
  identity.serial = physical != nullptr ? std::string() : rig->Serial();
  identity.geometry = info.geometry;
  identity.encoder = info.encoder;

  CalibrationCollector collector(identity, info, options.poses);
  const int holds = static_cast<int>(std::ceil(max_seconds / kCalibrationHoldSeconds)) + 1;
  const std::vector<Vector8d> schedule = CalibrationTensionSchedule(info, holds, options.seed);
  const int ticks_per_hold = static_cast<int>(std::lround(kCalibrationHoldSeconds / kDt));

  std::fprintf(stderr,
               "calibrate: %s; wave the grip through the whole frame (every octant), turning "
               "and squeezing it; the strings pull 0.3-3 N, changing every 0.1 s.\n",
               rig->Describe().c_str());
  const auto wall_start = std::chrono::steady_clock::now();
  int reported = -1;
  long k = 0;
  double t = 0.0;
  auto next_report = wall_start;
  for (; t < max_seconds && !collector.Done(); ++k, t = k * kDt) {
    const Vector8d& tau = schedule[static_cast<std::size_t>(k / ticks_per_hold)];
    haptics::EncoderReading reading;
    if (physical != nullptr) {
      hand->Step(wave.Sample(t), physical->TrueWrench(), kDt);
      physical->SetTruePose(hand->pose());
    } else {
      std::this_thread::sleep_until(wall_start + std::chrono::microseconds(k * 1000));
    }
    rig->Read(kDt, &reading);
    const bool kept = collector.Offer(reading, tau, (k % ticks_per_hold) * kDt);
    rig->Write(tau);
    // Progress: every 10 poses (and the first), and every 5 s on a real board.
    const bool step = kept && (collector.collected() / 10 != reported / 10 || reported < 0);
    const bool timed = physical == nullptr && std::chrono::steady_clock::now() >= next_report;
    if (step || timed) {
      std::fprintf(stderr, "calibrate: %5.1f s: %s\n", t, collector.Progress().c_str());
      reported = collector.collected();
      next_report = std::chrono::steady_clock::now() + std::chrono::seconds(5);
    }
  }
  // Let go of the grip.
  rig->Write(Vector8d::Zero());
  std::fprintf(stderr, "calibrate: %5.1f s: %s\n", t, collector.Progress().c_str());
  const haptics::PoseCollectorCounts& counts = collector.counts();
  std::fprintf(stderr,
               "calibrate: %ld readings: %ld kept, %ld near a kept pose, %ld while tensions "
               "settled, %ld slack, %ld without a pose, %ld not ok\n",
               counts.offered, counts.kept, counts.too_close, counts.unsettled, counts.slack,
               counts.no_pose, counts.not_ok);
  if (!collector.Done()) {
    std::fflush(stdout);
    std::cerr << "spidarcad calibrate: stopped after " << max_seconds << " s with "
              << collector.Progress()
              << "; wave the grip further into those corners (or raise --timeout)\n";
    throw CommandExit{1};
  }

  // The homing pretension of the simulated board; a real board is assumed to home as it.
  CalibrationFitOptions fit;
  if (physical != nullptr) fit.homing_tension = physical->config().homing_tension;
  // board-sim: also against the simulator's hidden truth, on poses the session never saw.
  fit.truth = physical;
  fit.eval_seed = options.seed * 7919 + 1;
  const CalibrationOutcome outcome = collector.Fit(fit);
  if (!outcome.ok) {
    std::fflush(stdout);
    std::cerr << "spidarcad calibrate: " << outcome.error << "\n";
    throw CommandExit{1};
  }
  const std::vector<CalibrationTableRow>& rows = outcome.rows;
  std::FILE* notes = options.json ? stderr : stdout;
  if (options.json) {
    std::printf("%s\n", SessionJson(rows).dump(2).c_str());
  } else {
    std::printf("Self-calibration session on %s: %d useful poses in %.1f s.\n\n",
                identity.Describe().c_str(), collector.collected(), t);
    PrintSessionTable(rows);
    std::printf(
        "\nfk residual: how far the 8 measured lengths are from the best-fitting pose, over the\n"
        "session's poses (the redundant string's disagreement; what a device can tell by "
        "itself).\n");
    if (physical != nullptr) {
      std::printf(
          "pos, rot: error of the measured pose against the simulator's hidden truth on 200\n"
          "other poses (0.2-3 N).\n");
    }
  }
  std::fprintf(notes, "self: %s\n", outcome.message.c_str());
  if (!options.out.empty()) {
    SaveCalibrationFile(outcome.file, options.out);
    std::fprintf(notes, "wrote %s (self-calibration of the %s)\n", options.out.c_str(),
                 identity.Describe().c_str());
    // A real board's calibration is remembered: the window reads the board through it next
    // time (DeviceMemoryPath()).
    if (identity.kind == "usb") {
      std::string why;
      if (RememberCalibration(identity, options.out, &why)) {
        std::fprintf(notes, "remembered it for the %s in %s\n", identity.Describe().c_str(),
                     DeviceMemoryPath().c_str());
      } else {
        std::fprintf(notes, "could not remember it for the window (%s)\n", why.c_str());
      }
    }
  }
  std::fflush(stdout);
}

}  // namespace spidarcad::app
