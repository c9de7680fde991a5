// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
// The tick table (cli/report_tick.h): a row's percentiles, maxima, fault totals and slowest ticks
// against a brute-force reading of the samples, and `spidarcad report --only tick` carrying the
// thread-CPU p99.9 and max columns into its table, CSV and summary. No timed assertion: only the
// columns' presence and their order relations are checked on the measured run.
#include "cli/report_tick.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <numeric>
#include <random>
#include <stdexcept>
#include <string>
#include <vector>

#include "cli/golden_runs.h"
#include "spidarcad_runner.h"

namespace spidarcad::app {
namespace {

using test_support::CommandRun;
using test_support::ReadWholeFile;
using test_support::RunSpidarcad;
using test_support::TestOutputPath;

TEST(ReportTick, RowCarriesCpuP999MaxFaultsAndTheSlowestTicksOfItsSamples) {
  // CPU samples 1..1000 µs in a shuffled order, wall clock = 2 × CPU; a fault on every 100th
  // tick, a switch on every 250th.
  const int n = 1000;
  std::vector<double> cpu(n), us(n);
  std::iota(cpu.begin(), cpu.end(), 1.0);
  std::mt19937 rng(7);
  std::shuffle(cpu.begin(), cpu.end(), rng);
  std::vector<TickCounters> counters(n);
  for (int i = 0; i < n; ++i) {
    us[i] = 2.0 * cpu[i];
    if (i % 100 == 0) counters[i].minor_faults = 3;
    if (i % 500 == 0) counters[i].major_faults = 1;
    if (i % 250 == 0) counters[i].involuntary_switches = 1;
  }
  const SceneTickRow row = SummarizeTicks("synthetic", us, cpu, counters);
  // Nearest rank: the 999th smallest of 1..1000 is 999; the 990th is 990.
  EXPECT_EQ(row.cpu_p999, 999.0);
  EXPECT_EQ(row.cpu_p99, 990.0);
  EXPECT_EQ(row.cpu_max, 1000.0);
  EXPECT_EQ(row.max, 2000.0);
  EXPECT_EQ(row.minor_faults, 30);
  EXPECT_EQ(row.major_faults, 2);
  EXPECT_EQ(row.ticks_with_faults, 10);
  EXPECT_EQ(row.involuntary_switches, 4);
  ASSERT_EQ(row.slowest.size(), static_cast<std::size_t>(kSlowestTicks));
  for (int j = 0; j < kSlowestTicks; ++j) {
    const SlowTick& t = row.slowest[j];
    EXPECT_EQ(t.cpu, 1000.0 - j);  // slowest first
    ASSERT_GE(t.index, 0);
    ASSERT_LT(t.index, n);
    EXPECT_EQ(cpu[t.index], t.cpu);
    EXPECT_EQ(t.us, us[t.index]);
    EXPECT_EQ(t.counters.minor_faults, counters[t.index].minor_faults);
  }

  // A subset row names the run's tick indices, not the subset's.
  std::vector<double> sub_cpu{5.0, 9.0, 7.0}, sub_us{6.0, 10.0, 8.0};
  std::vector<TickCounters> sub_counters(3);
  sub_counters[1].minor_faults = 2;
  const SceneTickRow sub =
      SummarizeTicks("subset", sub_us, sub_cpu, sub_counters, std::vector<long>{40, 41, 77});
  ASSERT_EQ(sub.slowest.size(), 3u);
  EXPECT_EQ(sub.slowest[0].index, 41);
  EXPECT_EQ(sub.slowest[0].counters.minor_faults, 2u);
  EXPECT_EQ(sub.slowest[1].index, 77);
  EXPECT_EQ(sub.slowest[2].index, 40);
  EXPECT_EQ(sub.ticks_with_faults, 1);
}

// Three runs of 1000 ticks at 10 µs each (wall 12 µs), with tick 300 slow in every run (the
// code's: 150, 170, 160 µs) and one run-only outlier each (ticks 5, 600, 999: the machine's).
// The repeatable row keeps the least time of each tick, so its maximum is tick 300's 150 µs,
// and its slowest ticks name it; a subset row is matched by tick index, keeping the ticks in
// every run.
TEST(ReportTick, RepeatableTicksKeepEachTicksLeastTimeOverTheRuns) {
  const int n = 1000;
  std::vector<SceneTickRow> runs(3);
  const long outlier[3] = {5, 600, 999};
  const double slow[3] = {150.0, 170.0, 160.0};
  for (int r = 0; r < 3; ++r) {
    std::vector<double> cpu(n, 10.0), us(n, 12.0);
    cpu[300] = slow[r];
    us[300] = slow[r] + 1.0;
    cpu[outlier[r]] = 2500.0;
    us[outlier[r]] = 2600.0;
    runs[r] = SummarizeTicks("scene", us, cpu, std::vector<TickCounters>(n));
    EXPECT_EQ(runs[r].cpu_max, 2500.0);
  }
  const SceneTickRow rep = RepeatableTicks({&runs[0], &runs[1], &runs[2]});
  EXPECT_EQ(rep.name, "scene");
  ASSERT_EQ(rep.cpu.size(), static_cast<std::size_t>(n));
  EXPECT_EQ(rep.cpu_max, 150.0);
  EXPECT_EQ(rep.max, 151.0);
  EXPECT_EQ(rep.cpu_p50, 10.0);
  EXPECT_EQ(rep.cpu[5], 10.0);
  EXPECT_EQ(rep.cpu[600], 10.0);
  ASSERT_FALSE(rep.slowest.empty());
  EXPECT_EQ(rep.slowest[0].index, 300);
  EXPECT_EQ(rep.slowest[0].cpu, 150.0);
  // One run alone is its own repeatable row.
  EXPECT_EQ(RepeatableTicks({&runs[1]}).cpu_max, 2500.0);
  // RepeatableRows: by name over whole runs; a row missing from one run is left out.
  std::vector<SceneTickRow> run_a{runs[0]}, run_b{runs[1]}, run_c{runs[2]};
  run_a.push_back(SummarizeTicks("only in a", {1.0}, {1.0}, std::vector<TickCounters>(1)));
  const std::vector<RepeatableRow> rows = RepeatableRows({&run_a, &run_b, &run_c});
  ASSERT_EQ(rows.size(), 1u);
  EXPECT_EQ(rows[0].row.cpu_max, 150.0);
  ASSERT_EQ(rows[0].runs.size(), 3u);
  EXPECT_EQ(rows[0].runs[2], &run_c[0]);
  EXPECT_EQ(rows[0].runs[1]->TickOf(7), 7);

  // Subsets: ticks {10, 20, 30} and {20, 30, 40}; only 20 and 30 are in both.
  const SceneTickRow a =
      SummarizeTicks("subset", {1.0, 2.0, 3.0}, {1.0, 2.0, 3.0}, std::vector<TickCounters>(3),
                     std::vector<long>{10, 20, 30});
  const SceneTickRow b =
      SummarizeTicks("subset", {5.0, 1.5, 9.0}, {5.0, 1.5, 9.0}, std::vector<TickCounters>(3),
                     std::vector<long>{20, 30, 40});
  const SceneTickRow ab = RepeatableTicks({&a, &b});
  EXPECT_EQ(ab.index, (std::vector<long>{20, 30}));
  EXPECT_EQ(ab.cpu, (std::vector<double>{2.0, 1.5}));
  EXPECT_EQ(ab.cpu_max, 2.0);
  EXPECT_EQ(ab.slowest[0].index, 20);

  const SceneTickRow c =
      SummarizeTicks("subset", {1.0}, {1.0}, std::vector<TickCounters>(1), std::vector<long>{99});
  EXPECT_THROW(RepeatableTicks({&a, &c}), std::invalid_argument);
  EXPECT_THROW(RepeatableTicks({}), std::invalid_argument);
  EXPECT_THROW(RepeatableTicks({&a, nullptr}), std::invalid_argument);
}

// Fields of a CSV line; a field in double quotes may hold commas.
std::vector<std::string> SplitQuoted(const std::string& line) {
  std::vector<std::string> fields(1);
  bool quoted = false;
  for (char c : line) {
    if (c == '"') {
      quoted = !quoted;
    } else if (c == ',' && !quoted) {
      fields.emplace_back();
    } else {
      fields.back() += c;
    }
  }
  return fields;
}

TEST(ReportTick, TickSectionReportsThreadCpuP999AndMaxPerScene) {
  const std::string dir = TestOutputPath("report_tick");
  std::filesystem::remove_all(dir);
  const std::string cache = TestOutputPath("report_tick_fe_cache");
  const CommandRun run = RunSpidarcad("report --out '" + dir + "' --quick --only tick --no-plots",
                                      "", "tick", "env SPIDARCAD_CACHE_DIR='" + cache + "'");
  ASSERT_EQ(run.status, 0) << run.all();
  const std::string md = ReadWholeFile(dir + "/report.md");
  EXPECT_NE(md.find("| CPU p50 µs | CPU p99 µs | CPU p99.9 µs | CPU max µs |"), std::string::npos)
      << md;
  std::ifstream in(dir + "/tick.csv");
  std::string line;
  ASSERT_TRUE(std::getline(in, line));
  const std::vector<std::string> header = SplitQuoted(line);
  auto column = [&](const std::string& name) {
    const auto it = std::find(header.begin(), header.end(), name);
    return it == header.end() ? -1 : static_cast<int>(it - header.begin());
  };
  const int p99 = column("cpu_p99_us"), p999 = column("cpu_p999_us"), max = column("cpu_max_us");
  const int faults = column("ticks_with_faults");
  ASSERT_GE(p99, 0) << line;
  ASSERT_GE(p999, 0) << line;
  ASSERT_GE(max, 0) << line;
  ASSERT_GE(faults, 0) << line;
  int rows = 0;
  std::vector<std::string> names;
  while (std::getline(in, line)) {
    const std::vector<std::string> f = SplitQuoted(line);
    names.push_back(f[0]);
    ASSERT_EQ(f.size(), header.size()) << line;
    EXPECT_LE(std::stod(f[p99]), std::stod(f[p999])) << line;
    EXPECT_LE(std::stod(f[p999]), std::stod(f[max])) << line;
    EXPECT_GE(std::stol(f[faults]), 0) << line;
    ++rows;
  }
  // 8 scenes, plus the 2004-point shell, the FE k = 16 and the assembly carrying rows, then one
  // row per golden run of the regression test (the one list of cli/golden_runs.h), in its order,
  // named after it.
  const std::vector<GoldenRun>& golden = GoldenRuns();
  ASSERT_EQ(rows, 11 + static_cast<int>(golden.size()));
  EXPECT_EQ(names[4], "six-DOF shell tool (platform.json, 2004 points, twist)");
  for (std::size_t i = 0; i < golden.size(); ++i)
    EXPECT_EQ(names[11 + i], "golden " + golden[i].name);
  EXPECT_NE(md.find("| golden platform_fe_press |"), std::string::npos) << md;
  const std::string summary = ReadWholeFile(dir + "/summary.md");
  EXPECT_NE(summary.find("worst p99.9"), std::string::npos) << summary;
  EXPECT_NE(summary.find("worst max"), std::string::npos) << summary;
  EXPECT_NE(summary.find("repeatable over 3 runs: worst p99.9"), std::string::npos) << summary;
  // The summary table's headline carries the repeatable figures beside the single run's.
  EXPECT_NE(md.find("of the 1000 µs tick; repeatable over 3 runs: worst p99.9"), std::string::npos)
      << md;

  // The repeatable table: one row per scene kind that every run has; each tick's least time
  // cannot exceed any run's maximum, and its p99.9 cannot exceed its maximum.
  EXPECT_NE(md.find("Repeatable tick time"), std::string::npos) << md;
  std::ifstream rep(dir + "/tick_repeatable.csv");
  ASSERT_TRUE(std::getline(rep, line));
  EXPECT_EQ(line,
            "scene,ticks,cpu_p50_us,cpu_p999_us,cpu_max_us,slowest_tick,single_run_cpu_max_us");
  int rep_rows = 0;
  while (std::getline(rep, line)) {
    const std::vector<std::string> f = SplitQuoted(line);
    ASSERT_EQ(f.size(), 7u) << line;
    EXPECT_EQ(f[0], names[rep_rows]) << line;
    EXPECT_GT(std::stol(f[1]), 0) << line;
    const double rep_max = std::stod(f[4]);
    EXPECT_LE(std::stod(f[3]), rep_max) << line;
    int runs_listed = 0;
    for (std::size_t at = 0; at != std::string::npos;) {
      const std::size_t comma = f[6].find(',', at);
      EXPECT_LE(rep_max, std::stod(f[6].substr(at, comma - at))) << line;
      ++runs_listed;
      at = comma == std::string::npos ? comma : comma + 1;
    }
    EXPECT_EQ(runs_listed, 3) << line;
    ++rep_rows;
  }
  // Every scene kind's row: the FE k = 16 and carrying rows are subsets whose ticks may differ
  // between runs, but they share most of them.
  EXPECT_EQ(rep_rows, 11);
}

}  // namespace
}  // namespace spidarcad::app
