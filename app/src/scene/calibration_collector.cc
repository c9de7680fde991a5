// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#include "scene/calibration_collector.h"

#include <algorithm>
#include <cmath>
#include <exception>
#include <numbers>
#include <stdexcept>

#include "scene/device_rig.h"
#include "spidarcad/haptics/kinematics.h"

namespace spidarcad::app {

namespace {

haptics::PoseCollectorSettings CollectorSettings(int poses) {
  if (poses < 1) {
    throw std::invalid_argument("CalibrationCollector: poses must be at least 1, got " +
                                std::to_string(poses));
  }
  haptics::PoseCollectorSettings settings;
  settings.target = poses;
  settings.fk_max_residual = kNominalFkMaxResidual;
  return settings;
}

}  // namespace

std::vector<haptics::Vector8d> CalibrationTensionSchedule(const haptics::DeviceInfo& info,
                                                          int holds, std::uint64_t seed) {
  return haptics::CalibrationTensions(holds, kCalibrationTensionLo,
                                      std::min(kCalibrationTensionHi, info.tension_max), seed);
}

CalibrationFkResidual FkResidualOn(const haptics::SpidarGeometry& geometry,
                                   const haptics::EncoderCalibration& calibration,
                                   const std::vector<haptics::UnknownPoseSample>& samples) {
  haptics::FkSettings settings;
  settings.max_iterations = 50;
  settings.max_residual = 0.05;  // accept a poor calibration: its residual is what we measure
  settings.warm_start = false;
  haptics::ForwardKinematics fk(geometry, settings);
  CalibrationFkResidual out;
  double sum_sq = 0.0;
  int n = 0;
  for (const auto& s : samples) {
    const haptics::FkResult r = fk.Solve(calibration.Lengths(s.counts, s.tension));
    if (r.status != haptics::FkStatus::kOk) {
      ++out.failures;
      continue;
    }
    sum_sq += r.residual * r.residual;
    out.max = std::max(out.max, r.residual);
    ++n;
  }
  out.rms = n > 0 ? std::sqrt(sum_sq / n) : 0.0;
  return out;
}

CalibrationCollector::CalibrationCollector(const CalibrationDevice& device,
                                           const haptics::DeviceInfo& info, int poses)
    : device_(device),
      info_(info),
      nominal_(NominalCalibration(info)),
      collector_(info.geometry, nominal_, CollectorSettings(poses)) {}

bool CalibrationCollector::Offer(const haptics::EncoderReading& reading,
                                 const haptics::Vector8d& tension, double held) {
  return collector_.Offer(reading, tension, held);
}

std::vector<int> CalibrationCollector::NeededOctants() const {
  std::vector<int> out;
  for (int o = 0; o < 8; ++o) {
    if (octant_counts()[o] < per_octant()) out.push_back(o);
  }
  return out;
}

CalibrationOutcome CalibrationCollector::Fit(const CalibrationFitOptions& options) const {
  CalibrationOutcome out;
  out.poses = collected();
  const std::vector<haptics::KnownPoseSample> home = {
      haptics::HomingSample(info_, options.homing_tension)};
  haptics::CalibrationResult self;
  try {
    self = haptics::SelfCalibrate(info_.geometry, nominal_, home, samples());
  } catch (const std::exception& e) {  // a bad setting (none of ours); said, not thrown
    out.error = std::string("self-calibration: ") + e.what();
    return out;
  }
  out.message = self.message;
  if (self.status != haptics::CalibrationStatus::kOk) {
    out.error = std::string("self-calibration: ") + haptics::CalibrationStatusName(self.status) +
                ": " + self.message;
    return out;
  }
  out.rows.push_back({"uncalibrated", "uncalibrated (nominal)",
                      FkResidualOn(info_.geometry, nominal_, samples()), std::nullopt});
  out.rows.push_back({"self", "self-calibration",
                      FkResidualOn(info_.geometry, self.calibration, samples()), std::nullopt});
  if (haptics::SimulatedSpidarG* truth = options.truth; truth != nullptr) {
    // Against the simulator's hidden truth, on poses the session never saw.
    const haptics::SpidarGeometry& g = info_.geometry;
    const auto eval =
        haptics::RandomGripPoses(g, options.eval_poses, std::min({g.a, g.b, g.c}) * (0.2 / 0.24),
                                 30.0 / (180.0 / std::numbers::pi), 0.3, options.eval_seed);
    const auto evaluate = [&](const haptics::EncoderCalibration& calibration) {
      return haptics::EvaluateAccuracy(truth, calibration, eval, 0.2, 3.0, 1);
    };
    out.rows[0].accuracy = evaluate(nominal_);
    out.rows[1].accuracy = evaluate(self.calibration);
    out.rows.push_back({"true_parameters", "true parameters (floor)",
                        FkResidualOn(info_.geometry, truth->true_encoder(), samples()),
                        evaluate(truth->true_encoder())});
  }
  out.file.device = device_;
  out.file.date = NowIso8601Utc();
  out.file.method = "self";
  out.file.calibration = self.calibration;
  out.file.fit = FitOf(self, static_cast<int>(samples().size() + home.size()));
  out.ok = true;
  return out;
}

}  // namespace spidarcad::app
