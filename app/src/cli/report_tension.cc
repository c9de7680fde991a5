// Report section: tension distribution, time against the gap to the optimum and the share of
// the commanded wrench displayed. The optimum comes from a brute-force enumeration of every
// active set (3^8 candidates), independent of the solver's active-set iteration.
// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#include <Eigen/Cholesky>
#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <random>
#include <string>
#include <vector>

#include "cli/report_sections.h"
#include "spidarcad/haptics/tension.h"
#include "spidarcad/workloads/tension.h"

namespace spidarcad::app {

namespace {

using haptics::GripPose;
using haptics::SpidarGeometry;
using haptics::TensionSettings;
using haptics::Vector7d;
using haptics::Vector8d;

using Request = workloads::TensionRequest;

Eigen::Matrix<double, 7, 1> Weights(const TensionSettings& s) {
  Eigen::Matrix<double, 7, 1> w;
  w << 1, 1, 1, s.s0, s.s0, s.s0, s.s1;
  return w;
}

// J(τ) = |f − Fτ|² + S0 |m − Mτ|² + S1 (g − Gτ)² + S2 |τ|².
double Objective(const Request& r, const Vector8d& tau, const TensionSettings& s) {
  const Vector7d e = r.q - r.A * tau;
  return e.cwiseProduct(e).dot(Weights(s)) + s.s2 * tau.squaredNorm();
}

// The exact optimum by enumeration: for every assignment of each tension to free, τ_min or
// τ_max, the minimiser over the free ones with the others fixed; the least J among those
// within the bounds is the optimum (the true optimum's own assignment is among them).
double BruteForceOptimum(const Request& r, const TensionSettings& s) {
  const Eigen::Matrix<double, 7, 1> w = Weights(s);
  const Eigen::Matrix<double, 8, 8> H =
      r.A.transpose() * w.asDiagonal() * r.A + s.s2 * Eigen::Matrix<double, 8, 8>::Identity();
  const Vector8d b = r.A.transpose() * w.asDiagonal() * r.q;
  double best = INFINITY;
  int code[8] = {0};
  for (int pattern = 0; pattern < 6561; ++pattern) {
    int p = pattern;
    for (int i = 0; i < 8; ++i) {
      code[i] = p % 3;  // 0 free, 1 at τ_min, 2 at τ_max
      p /= 3;
    }
    Vector8d fixed = Vector8d::Zero();
    for (int i = 0; i < 8; ++i) {
      if (code[i] == 1) fixed(i) = s.tau_min;
      if (code[i] == 2) fixed(i) = s.tau_max;
    }
    Eigen::Matrix<double, 8, 8> M = H;
    Vector8d rhs = b - H * fixed;
    for (int i = 0; i < 8; ++i) {
      if (code[i] == 0) continue;
      M.row(i).setZero();
      M.col(i).setZero();
      M(i, i) = 1;
      rhs(i) = 0;
    }
    const Vector8d free = M.llt().solve(rhs);
    Vector8d tau = fixed;
    bool inside = true;
    for (int i = 0; i < 8; ++i) {
      if (code[i] != 0) continue;
      tau(i) = free(i);
      if (tau(i) < s.tau_min - 1e-9 || tau(i) > s.tau_max + 1e-9) inside = false;
    }
    if (!inside) continue;
    best = std::min(best, Objective(r, tau, s));
  }
  return best;
}

struct Row {
  std::string name;
  bool warm = false, saturated = false;
  double us = NAN;                               // median per solve, µs
  double gap_mean = NAN, gap_max = NAN;          // (J − J*) / J*
  double share_force = NAN, share_moment = NAN;  // mean achieved·q/|q|²
  double saturated_fraction = NAN;
  double iterations = NAN;  // mean active-set changes
};

}  // namespace

void ReportTensions(ReportContext& ctx) {
  const SpidarGeometry g;
  const TensionSettings settings = TensionSettings::ForPoleLength(g.d);
  const int n_random = ctx.Pick(150, 600);
  const int n_path = ctx.Pick(1000, 5000);
  const int checked = ctx.Pick(150, 600);  // requests checked against the brute force
  const int repeats = ctx.Pick(5, 15);
  struct Workload {
    std::string name;
    std::vector<Request> requests;
    bool warm, saturated;
  };
  std::vector<Workload> workloads;
  workloads.push_back({"random poses, feasible, cold",
                       workloads::RandomTensionRequests(g, n_random, 1.0, 1), false, false});
  workloads.push_back({"random poses, saturated (×50), cold",
                       workloads::RandomTensionRequests(g, n_random, 50.0, 2), false, true});
  for (bool saturated : {false, true}) {
    const auto path = workloads::TrajectoryTensionRequests(g, n_path, saturated ? 20.0 : 1.0);
    for (bool warm : {false, true}) {
      workloads.push_back({std::string("1 kHz path, ") +
                               (saturated ? "saturated (×20), " : "feasible, ") +
                               (warm ? "warm" : "cold"),
                           path, warm, saturated});
    }
  }
  std::vector<Row> rows;
  for (size_t w = 0; w < workloads.size(); ++w) {
    const Workload& work = workloads[w];
    Row row;
    row.name = work.name;
    row.warm = work.warm;
    row.saturated = work.saturated;
    haptics::TensionSolver solver(settings);
    const int n = static_cast<int>(work.requests.size());
    std::vector<haptics::TensionResult> results(n);
    const double s = MedianSeconds(repeats, [&] {
      solver.Reset();
      for (int k = 0; k < n; ++k) {
        if (!work.warm) solver.Reset();
        results[k] = solver.Solve(work.requests[k].A, work.requests[k].q);
      }
    });
    row.us = 1e6 * s / n;
    double force = 0, moment = 0, sat = 0, iters = 0;
    for (int k = 0; k < n; ++k) {
      const Request& r = work.requests[k];
      const haptics::TensionResult& res = results[k];
      force += res.achieved.head<3>().dot(r.q.head<3>()) / r.q.head<3>().squaredNorm();
      moment += res.achieved.segment<3>(3).dot(r.q.segment<3>(3)) / r.q.segment<3>(3).squaredNorm();
      sat += res.status == haptics::TensionStatus::kSaturated;
      iters += res.iterations;
    }
    row.share_force = force / n;
    row.share_moment = moment / n;
    row.saturated_fraction = sat / n;
    row.iterations = iters / n;
    // The gap on an evenly spread subset (every request of the random sets).
    const int stride = std::max(1, n / checked);
    double gap_sum = 0;
    int gap_n = 0;
    row.gap_max = 0;
    for (int k = 0; k < n; k += stride) {
      const double best = BruteForceOptimum(work.requests[k], settings);
      const double gap =
          std::max(0.0, (Objective(work.requests[k], results[k].tau, settings) - best) / best);
      gap_sum += gap;
      row.gap_max = std::max(row.gap_max, gap);
      ++gap_n;
    }
    row.gap_mean = gap_sum / gap_n;
    rows.push_back(row);
    ctx.Progress((w + 1.0) / workloads.size());
  }

  ctx.md() << "The tension distribution (TensionSolver: exact active-set solution of the bounded "
              "least-squares problem, S0 = S1 = 1/d², S2 = 1e-3, tensions in ["
           << settings.tau_min << ", " << settings.tau_max
           << "] N) on random poses within 8 cm of the centre (force up to 2 N per axis, "
              "moments up to 0.03 N·m; ×50 saturates the strings) and along a 1 kHz hand path "
              "(×20 saturates), solved cold (active set forgotten before each solve) and warm. "
              "The gap is (J − J*) / J* against the optimum J* found by enumerating all 3^8 "
              "active sets; the share displayed is the mean of achieved·q / |q|² for the force "
              "and the moment. Times are medians over "
           << repeats << " passes, per solve.\n";
  std::vector<std::vector<std::string>> table, csv;
  for (const Row& r : rows) {
    table.push_back({r.name, Sig(r.us), Sig(r.gap_mean, 2), Sig(r.gap_max, 2),
                     Fixed(100 * r.share_force, 1), Fixed(100 * r.share_moment, 1),
                     Fixed(100 * r.saturated_fraction, 0), Fixed(r.iterations, 2)});
    csv.push_back({r.name.rfind("random", 0) == 0 ? "random_poses" : "1khz_path",
                   r.warm ? "warm" : "cold", r.saturated ? "saturated" : "feasible", Sig(r.us, 6),
                   Sig(r.gap_mean, 6), Sig(r.gap_max, 6), Sig(r.share_force, 6),
                   Sig(r.share_moment, 6), Sig(r.saturated_fraction, 6)});
  }
  ctx.Table({"workload", "µs per solve", "gap mean", "gap max", "force displayed %",
             "moment displayed %", "saturated %", "active-set changes"},
            table);
  ctx.Csv("tensions",
          {"workload", "start", "request", "us_per_solve", "gap_mean", "gap_max", "share_force",
           "share_moment", "saturated_fraction"},
          csv);
  constexpr double kFloor = 1e-16;
  Chart gap{"Tensions: time against gap to the optimum",
            "time per solve [us]",
            "mean relative gap (J-J*)/J* (floor 1e-16)",
            true,
            true,
            {}};
  Chart share{"Tensions: time against share displayed",
              "time per solve [us]",
              "force displayed [%]",
              true,
              false,
              {}};
  for (size_t k = 0; k < rows.size(); ++k) {
    const Row& r = rows[k];
    const int colour = (r.warm ? 1 : 0) + (r.saturated ? 2 : 0);
    const int marker = r.name.rfind("random", 0) == 0 ? 0 : 1;
    gap.series.push_back(
        {r.name, {r.us}, {std::max(kFloor, r.gap_mean)}, colour, false, false, marker});
    share.series.push_back({r.name, {r.us}, {100 * r.share_force}, colour, false, false, marker});
  }
  ctx.Figure("tensions_time_vs_gap", {gap, share},
             "Colour: cold/warm × feasible/saturated; marker: circle random poses, square the "
             "1 kHz path.");
  double worst_gap = 0;
  for (const Row& r : rows) worst_gap = std::max(worst_gap, r.gap_max);
  ctx.Headline("warm " + Sig(rows[3].us, 2) + " µs, cold " + Sig(rows[2].us, 2) +
               " µs per solve on the 1 kHz path; gap to the brute-force optimum ≤ " +
               Sig(worst_gap, 2) + "; saturated ×50: " + Fixed(100 * rows[1].share_force, 0) +
               " % of the force displayed");
  ctx.Summary("warm " + Sig(rows[3].us, 2) + " µs, cold " + Sig(rows[2].us, 2) + " µs per solve",
              "gap to the optimum ≤ " + Sig(worst_gap, 2));
}

}  // namespace spidarcad::app
