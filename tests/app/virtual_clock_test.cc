// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
// The window on the virtual clock (`spidarcad SCENE --clock virtual --trajectory T --out W.csv`,
// gui/virtual_clock.h) against `spidarcad run SCENE --trajectory T --out R.csv` with the same
// options, both run as processes: the two CSVs are equal byte for byte in every column but
// tick_us (the wall-clock compute time of each tick, which no two runs share), for one document
// of each kind: a solid scene (the demo's floor and spring, pressed), an FE part (the platform's
// FE model pushed, the window in FE mode), a sculpt (the clay grabbed, the window in sculpt
// mode), an assembly (the right leg picked up; --calibrate) and modelling by touch (a sphere
// placed on a cube's face, --place sphere). The trajectories are the
// golden runs' cut short after the contact, the stroke or the grab, so each window renders a
// few hundred frames. Window tests: they need an X display (xvfb-run).
#include <gtest/gtest.h>

#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include "golden_compare.h"
#include "spidarcad_runner.h"

namespace {

using spidarcad::test_support::CsvLinesWithout;
using spidarcad::test_support::RunSpidarcad;
using spidarcad::test_support::TestOutputPath;

std::string Source(const std::string& relative) {
  return "'" + std::string(SPIDARCAD_SOURCE_DIR) + "/" + relative + "'";
}

// The samples of assets/trajectories/NAME.csv up to time `until` (s), into the test's output.
// The file is named by both, because ctest -j runs these tests in parallel processes: with one
// name per trajectory, the FE press test (1.3 s of press.csv) rewrote the demo test's 1.4 s
// prefix between that test's CLI run and its window run, which then wrote 100 rows fewer.
std::string TrajectoryPrefix(const std::string& name, double until) {
  std::ifstream in(std::string(SPIDARCAD_SOURCE_DIR) + "/assets/trajectories/" + name + ".csv");
  const std::string path = TestOutputPath(
      "vclock_" + name + "_" + std::to_string(std::lround(until * 1000.0)) + "ms_prefix.csv");
  std::ofstream out(path);
  std::string line;
  while (std::getline(in, line)) {
    if (!line.empty() && line[0] != '#' && line[0] != 't' && std::stod(line) > until + 1e-9) break;
    out << line << "\n";
  }
  return "'" + path + "'";
}

bool HaveDisplay() {
  const char* display = std::getenv("DISPLAY");
  return display != nullptr && display[0] != '\0';
}

// Runs `run ARGS` and the window with ARGS plus WINDOW_ARGS on the virtual clock; expects the
// same CSV but for tick_us, and returns the window's stdout.
std::string ExpectWindowMatchesRun(const std::string& tag, const std::string& args,
                                   const std::string& window_args = "") {
  const std::string run_csv = TestOutputPath("vclock_" + tag + "_run.csv");
  const std::string window_csv = TestOutputPath("vclock_" + tag + "_window.csv");
  std::filesystem::remove(window_csv);
  // Each its own empty FE column cache: both compute the columns along the path.
  const auto env = [&](const std::string& who) {
    const std::string cache = TestOutputPath("vclock_" + tag + "_" + who + "_cache");
    std::filesystem::remove_all(cache);
    return "env SPIDARCAD_CACHE_DIR='" + cache + "'";
  };
  const auto run =
      RunSpidarcad("run " + args + " --out '" + run_csv + "'", "", tag + "_run", env("run"));
  EXPECT_EQ(run.status, 0) << run.err;
  const auto window = RunSpidarcad(
      args + " --clock virtual --out '" + window_csv + "' --size " + "400x300 " + window_args, "",
      tag + "_window", env("window"));
  EXPECT_EQ(window.status, 0) << window.out << window.err;
  const std::vector<std::string> expected = CsvLinesWithout(run_csv, {"tick_us"});
  const std::vector<std::string> actual = CsvLinesWithout(window_csv, {"tick_us"});
  EXPECT_GT(expected.size(), 100u);
  EXPECT_EQ(actual.size(), expected.size());
  std::size_t first = 0;
  while (first < actual.size() && first < expected.size() && actual[first] == expected[first])
    ++first;
  EXPECT_EQ(first, expected.size())
      << "first differing line " << first + 1
      << ":\n  run:    " << (first < expected.size() ? expected[first] : "")
      << "\n  window: " << (first < actual.size() ? actual[first] : "");
  // The same set-up: the summaries name the same fields and X_WD.
  for (const char* key : {"fields:", "X_WD:"}) {
    const std::size_t at = run.out.find(key);
    if (at == std::string::npos) continue;
    const std::string line = run.out.substr(at, run.out.find('\n', at) - at);
    EXPECT_NE(window.out.find(line), std::string::npos) << line << "\n" << window.out;
  }
  EXPECT_NE(window.out.find("wrote " + window_csv), std::string::npos) << window.out;
  return window.out;
}

TEST(VirtualClockWindow, GivesRunsCsvForTheDemoPress) {
  if (!HaveDisplay()) GTEST_SKIP() << "no X display: run under xvfb-run";
  ExpectWindowMatchesRun("demo", "demo --trajectory " + TrajectoryPrefix("press", 1.4));
}

TEST(VirtualClockWindow, GivesRunsCsvForTheFePartInFeMode) {
  if (!HaveDisplay()) GTEST_SKIP() << "no X display: run under xvfb-run";
  const std::string out = ExpectWindowMatchesRun(
      "fe",
      Source("assets/scenes/platform_fe.json") + " --trajectory " + TrajectoryPrefix("press", 1.3) +
          " --world-scale 1 --world-origin 0.1,0,0.04",
      "--mode fe");
  EXPECT_NE(out.find("fields: fe_touch 'platform FE'"), std::string::npos) << out;
}

TEST(VirtualClockWindow, GivesRunsCsvForTheClaySculptInSculptMode) {
  if (!HaveDisplay()) GTEST_SKIP() << "no X display: run under xvfb-run";
  const std::string out = ExpectWindowMatchesRun(
      "sculpt",
      Source("assets/scenes/clay_sculpt.json") + " --trajectory " +
          TrajectoryPrefix("sculpt_grab", 1.8) +
          " --world-origin 0,-0.038,0.0739 --sculpt-radius 0.03 --sculpt-tool grab",
      "--mode sculpt");
  EXPECT_NE(out.find("sculpt 'clay': 1 stroke (grab"), std::string::npos) << out;
}

TEST(VirtualClockWindow, GivesRunsCsvForTheAssemblyPickUp) {
  if (!HaveDisplay()) GTEST_SKIP() << "no X display: run under xvfb-run";
  const std::string out = ExpectWindowMatchesRun(
      "assembly", Source("assets/scenes/assembly.json") + " --trajectory " +
                      TrajectoryPrefix("seat_right_leg", 5.25) + " --calibrate");
  EXPECT_NE(out.find("carried: right_leg"), std::string::npos) << out;
}

// Modelling by touch (--place sphere): the run's TouchSession places, on the window's document,
// and its felt snap pull is in the CSV of both; the window only shows the ghost. The golden
// touch_place_sphere's trajectory cut after the squeeze that places the sphere.
TEST(VirtualClockWindow, GivesRunsCsvForModellingByTouch) {
  if (!HaveDisplay()) GTEST_SKIP() << "no X display: run under xvfb-run";
  const std::string out =
      ExpectWindowMatchesRun("touch", Source("assets/scenes/touch_box.json") + " --trajectory " +
                                          TrajectoryPrefix("touch_place", 6.5) +
                                          " --world-scale 1 --world-origin 0,0,0 --place sphere");
  EXPECT_NE(out.find("fields: proxy 'cube', touch_snap (place sphere)"), std::string::npos) << out;
  EXPECT_NE(out.find("; 1 placed\n"), std::string::npos) << out;
}

// The emergency stop (--estop-frame, as Space) acts on the run's loop: zero force and the
// emergency_stop bit (4) from the frame it is pressed at (16 ticks a frame), none before.
TEST(VirtualClockWindow, EmergencyStopZeroesTheRunsForceFromItsFrame) {
  if (!HaveDisplay()) GTEST_SKIP() << "no X display: run under xvfb-run";
  const std::string csv = TestOutputPath("vclock_estop.csv");
  const auto window = RunSpidarcad("demo --clock virtual --size 400x300 --estop-frame 20 --out '" +
                                       csv + "' --trajectory " + TrajectoryPrefix("press", 0.8),
                                   "", "estop");
  ASSERT_EQ(window.status, 0) << window.out << window.err;
  const spidarcad::test_support::CsvTable table = spidarcad::test_support::ReadCsvTable(csv);
  const int events = table.Column("events"), fz = table.Column("fz");
  // Frame 20 is pressed before its ticks run: ticks 19 * 16 = 304 on are stopped.
  for (std::size_t k = 0; k < table.rows.size(); ++k) {
    const bool stopped = (static_cast<unsigned>(table.rows[k][events]) & (1u << 4)) != 0;
    EXPECT_EQ(stopped, k >= 304) << "tick " << k;
    if (stopped) {
      EXPECT_EQ(table.rows[k][fz], 0.0) << "tick " << k;
    }
  }
  EXPECT_NE(table.rows[303][fz], 0.0) << "the spring pulled before the stop";
}

TEST(VirtualClockWindow, NeedsATrajectoryAndAnOutputAndRefusesUsb) {
  if (!HaveDisplay()) GTEST_SKIP() << "no X display: run under xvfb-run";
  const auto no_out = RunSpidarcad(
      "demo --clock virtual --trajectory " + Source("assets/trajectories/press.csv"), "", "no_out");
  EXPECT_EQ(no_out.status, 2);
  EXPECT_NE(no_out.err.find("--clock virtual: needs --trajectory T.csv and --out R.csv"),
            std::string::npos)
      << no_out.err;
  const auto usb = RunSpidarcad("demo --clock virtual --device usb --out x.csv --trajectory " +
                                    Source("assets/trajectories/press.csv"),
                                "", "usb");
  EXPECT_EQ(usb.status, 2);
  EXPECT_NE(usb.err.find("not with --device usb"), std::string::npos) << usb.err;
  // A run option without the virtual clock is refused by the parser.
  const auto scale = RunSpidarcad("demo --world-scale 2 --frames 1", "", "scale");
  EXPECT_NE(scale.status, 0);
  EXPECT_NE(scale.all().find("--clock"), std::string::npos) << scale.all();
}

}  // namespace
