// Tests of `spidarcad workspace`, run as a separate process: CSV columns and content, the
// no-display path, the PNG under a display, and bad options.
// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#include <gtest/gtest.h>

#include <cmath>
#include <cstdlib>
#include <fstream>
#include <map>
#include <sstream>
#include <string>
#include <vector>

#include "spidarcad_runner.h"

namespace {

using spidarcad::test_support::CommandRun;
using spidarcad::test_support::ReadWholeFile;
using spidarcad::test_support::RunSpidarcad;
using spidarcad::test_support::TestOutputPath;

std::vector<std::string> Split(const std::string& line) {
  std::vector<std::string> fields;
  std::stringstream ss(line);
  std::string f;
  while (std::getline(ss, f, ',')) fields.push_back(f);
  return fields;
}

TEST(WorkspaceCommand, WritesDocumentedCsvAndExplainsHowToGetThePngWithoutDisplay) {
  const std::string csv = TestOutputPath("ws_nodisplay.csv");
  const std::string png = TestOutputPath("ws_nodisplay.png");
  std::remove(csv.c_str());
  std::remove(png.c_str());
  const CommandRun run = RunSpidarcad(
      "workspace --step 0.02 --angle-step 15 --out-csv '" + csv + "' --out-png '" + png + "'", "",
      "nodisplay", "env -u DISPLAY");
  EXPECT_EQ(run.status, 0) << run.err;
  EXPECT_NE(run.err.find("xvfb-run"), std::string::npos) << run.err;
  EXPECT_FALSE(std::ifstream(png).good());
  EXPECT_NE(run.out.find("Paper (Sec. 6)"), std::string::npos) << run.out;
  EXPECT_NE(run.out.find("moving -x"), std::string::npos) << run.out;

  std::ifstream in(csv);
  std::string header;
  ASSERT_TRUE(std::getline(in, header));
  EXPECT_EQ(header,
            "sweep,axis,sign,distance_m,angle_deg,force_N,force_min_N,moment_pos_Nm,"
            "moment_neg_Nm,grasp_close_Nm,grasp_open_Nm");
  std::map<std::string, int> counts;
  std::map<std::string, double> centre_force, last_force;
  std::string line;
  while (std::getline(in, line)) {
    const std::vector<std::string> f = Split(line);
    ASSERT_EQ(f.size(), 11u) << line;
    ++counts[f[0]];
    const std::string key = f[1] + f[2];
    if (f[0] == "translate") {
      const double distance = std::stod(f[3]), force = std::stod(f[5]);
      EXPECT_GE(force, 0.0);
      EXPECT_LT(distance, 0.24);
      if (distance == 0) centre_force[key] = force;
      last_force[key] = force;
    } else {
      EXPECT_EQ(f[5], "nan");
      EXPECT_LE(std::stod(f[4]), 90.0);
    }
    for (size_t k = 6; k < 11; ++k) EXPECT_GE(std::stod(f[k]), 0.0) << line;
  }
  EXPECT_GT(counts["translate"], 40);
  EXPECT_EQ(counts["rotate"], 6 * 7);
  ASSERT_EQ(centre_force.size(), 6u);
  // At the centre the device is mirror-symmetric in x: +x and −x deliver the same force; the
  // force toward each face falls far below its centre value by the end of the sweep.
  EXPECT_NEAR(centre_force["x1"], centre_force["x-1"], 1e-9);
  for (const auto& [key, full] : centre_force) {
    EXPECT_GT(full, 1.0) << key;
    EXPECT_LT(last_force[key], 0.5 * full) << key;
  }
}

TEST(WorkspaceCommand, WritesAReadablePngUnderADisplay) {
  const char* display = std::getenv("DISPLAY");
  if (display == nullptr || display[0] == '\0') {
    GTEST_SKIP() << "no X display; run under xvfb-run -a -s \"-screen 0 1280x1024x24\"";
  }
  const std::string csv = TestOutputPath("ws_display.csv");
  const std::string png = TestOutputPath("ws_display.png");
  std::remove(png.c_str());
  const CommandRun run = RunSpidarcad(
      "workspace --step 0.02 --angle-step 10 --out-csv '" + csv + "' --out-png '" + png + "'", "",
      "display");
  ASSERT_EQ(run.status, 0) << run.err;
  const std::string bytes = ReadWholeFile(png);
  ASSERT_GT(bytes.size(), 10000u);
  EXPECT_EQ(bytes.substr(1, 3), "PNG");
}

TEST(WorkspaceCommand, RejectsBadOptionsWithStatus2) {
  for (const std::string& args :
       {std::string("workspace --step 0 --out-png ''"),
        std::string("workspace --tmin 9 --out-png ''"),
        std::string("workspace --frame 0.1,0.1 --out-png ''"),
        std::string("workspace --pole 0.3 --out-png ''"),
        std::string("workspace --out-csv /nonexistent/dir/ws.csv --out-png ''")}) {
    const CommandRun run = RunSpidarcad(args, "", "bad");
    EXPECT_EQ(run.status, 2) << args << "\n" << run.err;
    EXPECT_FALSE(run.err.empty()) << args;
  }
}

}  // namespace
