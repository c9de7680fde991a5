// Report section: calibration, pose error against the number of calibration poses, for the
// paper's line fit (known jig poses) and self-calibration (unknown poses), over several seeds.
// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#include <algorithm>
#include <chrono>
#include <cmath>
#include <string>
#include <vector>

#include "cli/report_sections.h"
#include "spidarcad/haptics/calibration.h"
#include "spidarcad/haptics/kinematics.h"
#include "spidarcad/haptics/simulated_device.h"

namespace spidarcad::app {

void ReportCalibration(ReportContext& ctx) {
  const std::vector<int> seeds = ctx.Pick(std::vector<int>{1, 2, 3}, {1, 2, 3, 4, 5});
  const std::vector<int> line_counts =
      ctx.Pick(std::vector<int>{5, 10, 30, 100}, {4, 5, 10, 20, 50, 100, 200});
  const std::vector<int> self_counts =
      ctx.Pick(std::vector<int>{30, 60, 120}, {25, 30, 50, 100, 200, 400});
  const int eval_poses = ctx.Pick(60, 200);
  struct Row {
    std::string method;
    int poses, seed;
    double seconds = NAN, pos_mean = NAN, rot_mean = NAN, length_mean = NAN;
    std::string status;
  };
  std::vector<Row> rows;
  const double total = seeds.size() * (1 + line_counts.size() + self_counts.size());
  int done = 0;
  for (int seed : seeds) {
    haptics::SimulatedDeviceConfig config;
    config.seed = static_cast<unsigned>(seed);
    haptics::SimulatedSpidarG device(config);
    const haptics::SpidarGeometry& g = device.info().geometry;
    const haptics::EncoderCalibration nominal = haptics::EncoderCalibration::Nominal(
        device.info().encoder, haptics::InverseKinematics(g, device.info().home_pose));
    const auto evaluation = haptics::RandomGripPoses(g, eval_poses, 0.15, 0.5, 0.3, 1000 + seed);
    auto evaluate = [&](Row* row, const haptics::CalibrationResult& result) {
      row->status = haptics::CalibrationStatusName(result.status);
      if (result.status != haptics::CalibrationStatus::kOk) return;
      const haptics::AccuracyReport a =
          haptics::EvaluateAccuracy(&device, result.calibration, evaluation, 0.3, 3.0, 7 + seed);
      row->pos_mean = a.position_error_mean;
      row->rot_mean = a.rotation_error_mean;
      row->length_mean = a.length_error_mean;
    };
    {  // The nominal calibration, for reference.
      Row row;
      row.method = "nominal (no calibration)";
      row.poses = 0;
      row.seed = seed;
      haptics::CalibrationResult nominal_result;
      nominal_result.status = haptics::CalibrationStatus::kOk;
      nominal_result.calibration = nominal;
      evaluate(&row, nominal_result);
      row.seconds = 0;
      rows.push_back(row);
      ctx.Progress(++done / total);
    }
    for (int n : line_counts) {
      const auto poses = haptics::RandomGripPoses(g, n, 0.15, 0.5, 0.3, 100 * seed + n);
      const auto jig = haptics::GatherKnownSamples(&device, poses, 0.5);
      Row row;
      row.method = "line fit (known poses)";
      row.poses = n;
      row.seed = seed;
      haptics::CalibrationResult result;
      row.seconds = MedianSeconds(3, [&] { result = haptics::FitLinesPerString(g, nominal, jig); });
      evaluate(&row, result);
      rows.push_back(row);
      ctx.Progress(++done / total);
    }
    for (int n : self_counts) {
      const auto poses = haptics::RandomGripPoses(g, n, 0.15, 0.5, 0.3, 200 * seed + n);
      const auto home = haptics::GatherKnownSamples(&device, {device.info().home_pose}, 0.5);
      const auto wave = haptics::GatherUnknownSamples(&device, poses, 0.5);
      Row row;
      row.method = "self-calibration (unknown poses)";
      row.poses = n;
      row.seed = seed;
      haptics::CalibrationResult result;
      row.seconds =
          MedianSeconds(1, [&] { result = haptics::SelfCalibrate(g, nominal, home, wave); });
      evaluate(&row, result);
      rows.push_back(row);
      ctx.Progress(++done / total);
    }
  }
  ctx.md() << "Calibration of the simulated SPIDAR-G (each seed draws its own true encoder "
              "parameters: offsets, gains, winding). The line fit is the paper's method: "
              "the grip held at known jig poses, a line per string; self-calibration needs only "
              "the homing pose and unknown poses waved by the user. Poses uniform in a 30 cm "
              "cube, rotations to 0.5 rad; samples at 0.5 N. Error: ForwardKinematics with the "
              "estimated calibration on "
           << eval_poses << " other poses under tensions 0.3–3 N, against the true poses (mean).\n";
  std::vector<std::vector<std::string>> table, csv;
  for (const std::string& method :
       {std::string("nominal (no calibration)"), std::string("line fit (known poses)"),
        std::string("self-calibration (unknown poses)")}) {
    std::vector<int> counts;
    for (const Row& r : rows) {
      if (r.method == method && std::find(counts.begin(), counts.end(), r.poses) == counts.end())
        counts.push_back(r.poses);
    }
    for (int n : counts) {
      std::vector<double> pos, rot, sec;
      int ok = 0, all = 0;
      for (const Row& r : rows) {
        if (r.method != method || r.poses != n) continue;
        ++all;
        sec.push_back(r.seconds);
        if (r.status == "ok") {
          ++ok;
          pos.push_back(r.pos_mean);
          rot.push_back(r.rot_mean);
        }
      }
      table.push_back(
          {method, std::to_string(n), Sig(Median(sec), 2),
           pos.empty() ? "n/a" : Sig(1e3 * Median(pos), 3),
           pos.empty() ? "n/a" : Sig(1e3 * *std::max_element(pos.begin(), pos.end()), 3),
           rot.empty() ? "n/a" : Sig(Median(rot) * 180 / M_PI, 3),
           std::to_string(ok) + "/" + std::to_string(all)});
    }
  }
  for (const Row& r : rows) {
    csv.push_back({"\"" + r.method + "\"", std::to_string(r.poses), std::to_string(r.seed),
                   r.status, Sig(r.seconds, 6), Sig(r.pos_mean, 6), Sig(r.rot_mean, 6),
                   Sig(r.length_mean, 6)});
  }
  ctx.Table({"method", "poses", "time s (median)", "position error mm (median over seeds)",
             "worst seed mm", "rotation error ° (median)", "succeeded"},
            table);
  ctx.Csv("calibration",
          {"method", "poses", "seed", "status", "seconds", "pos_err_mean_m", "rot_err_mean_rad",
           "length_err_mean"},
          csv);
  Chart chart{"Calibration: pose error against calibration poses",
              "calibration poses",
              "mean position error [m]",
              true,
              true,
              {}};
  Chart time{"Calibration: time against pose error",
             "calibration time [s]",
             "mean position error [m]",
             true,
             true,
             {}};
  int colour = 0;
  for (const std::string& method :
       {std::string("line fit (known poses)"), std::string("self-calibration (unknown poses)")}) {
    ChartSeries t{method, {}, {}, colour, false, false, colour};
    for (size_t k = 0; k < seeds.size(); ++k) {
      ChartSeries s{method + ", seed " + std::to_string(seeds[k]), {}, {}, colour, true, k > 0, 0};
      for (const Row& r : rows) {
        if (r.method != method || r.seed != seeds[k] || r.status != "ok") continue;
        s.x.push_back(r.poses);
        s.y.push_back(r.pos_mean);
        t.x.push_back(r.seconds);
        t.y.push_back(r.pos_mean);
      }
      chart.series.push_back(s);
    }
    time.series.push_back(t);
    ++colour;
  }
  std::vector<double> nominal_pos;
  for (const Row& r : rows) {
    if (r.method == "nominal (no calibration)") nominal_pos.push_back(r.pos_mean);
  }
  chart.series.push_back(
      {"nominal (no calibration)",
       {1.0, static_cast<double>(std::max(line_counts.back(), self_counts.back()))},
       {Median(nominal_pos), Median(nominal_pos)},
       6,
       true,
       true,
       0});
  ctx.Figure("calibration_error_vs_poses", {chart, time},
             "One curve per method and seed (dashed: further seeds); black dashed: the nominal "
             "calibration.");
  auto median_at = [&](const std::string& method, int n) {
    std::vector<double> v;
    for (const Row& r : rows) {
      if (r.method == method && r.poses == n && r.status == "ok") v.push_back(r.pos_mean);
    }
    return Median(v);
  };
  ctx.Headline("mean position error " + Sig(1e3 * Median(nominal_pos), 2) + " mm nominal → " +
               Sig(1e3 * median_at("line fit (known poses)", line_counts.back()), 2) +
               " mm line fit (" + std::to_string(line_counts.back()) + " jig poses), " +
               Sig(1e3 * median_at("self-calibration (unknown poses)", self_counts.back()), 2) +
               " mm self-calibration (" + std::to_string(self_counts.back()) + " unknown poses)");
  ctx.Summary(std::to_string(line_counts.back()) + " jig poses or " +
                  std::to_string(self_counts.back()) + " unknown poses",
              Sig(1e3 * median_at("line fit (known poses)", line_counts.back()), 2) +
                  " mm (line fit), " +
                  Sig(1e3 * median_at("self-calibration (unknown poses)", self_counts.back()), 2) +
                  " mm (self-calibration) mean position error");
}

}  // namespace spidarcad::app
