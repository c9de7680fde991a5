// Runs the built `spidarcad calibrate` and checks its table, its file and its errors.
// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <sys/wait.h>

#include <cstdio>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <regex>
#include <sstream>
#include <string>

#include "spidarcad/haptics/simulated_device.h"
#include "spidarcad_runner.h"

namespace {

using spidarcad::test_support::CommandRun;
using spidarcad::test_support::RunSpidarcad;

using testing::HasSubstr;

std::string OutputPath(const std::string& name) {
  return std::string(SPIDARCAD_TEST_OUTPUT_DIR) + "/calibrate_" + name;
}

TEST(CalibrateCommand, HelpTeachesMethodsAndOptions) {
  const CommandRun run = RunSpidarcad("calibrate --help");
  EXPECT_EQ(run.status, 0);
  for (const char* word : {"--simulated", "--seed", "--poses", "--method", "--out", "--load",
                           "self-calibration", "6.24", "Examples"}) {
    EXPECT_THAT(run.all(), HasSubstr(word));
  }
}

TEST(CalibrateCommand, PrintsBeforeAfterTableAndWritesARecoveredCalibration) {
  const std::string out = OutputPath("seed3.json");
  std::filesystem::remove(out);
  const CommandRun run =
      RunSpidarcad("calibrate --simulated --seed 3 --poses 60 --eval-poses 80 --out " + out);
  ASSERT_EQ(run.status, 0) << run.all();
  EXPECT_THAT(run.all(), HasSubstr("uncalibrated"));
  EXPECT_THAT(run.all(), HasSubstr("line fit"));
  EXPECT_THAT(run.all(), HasSubstr("self-calibration"));
  EXPECT_THAT(run.all(), HasSubstr("0.80 +- 0.4"));
  // The file holds the self-calibration; its gains match the simulator's hidden truth for
  // the same seed (an independent reference: the test builds the device itself).
  std::ifstream in(out);
  ASSERT_TRUE(in.good());
  const nlohmann::json j = nlohmann::json::parse(in);
  EXPECT_EQ(j["format"], "spidarcad-calibration");
  EXPECT_EQ(j["method"], "self");
  spidarcad::haptics::SimulatedDeviceConfig config;
  config.seed = 3;
  const spidarcad::haptics::SimulatedSpidarG device(config);
  ASSERT_EQ(j["strings"].size(), 8u);
  for (int i = 0; i < 8; ++i) {
    EXPECT_NEAR(j["strings"][i]["gain"].get<double>(), device.true_encoder().strings[i].gain, 1e-3)
        << "string " << i + 1;
    EXPECT_NEAR(j["strings"][i]["offset"].get<double>(), device.true_encoder().strings[i].offset,
                1e-3)
        << "string " << i + 1;
  }
  // Loading it back evaluates it as another row.
  const CommandRun load = RunSpidarcad(
      "calibrate --simulated --seed 3 --method line --poses 30 "
      "--eval-poses 40 --load " +
      out);
  EXPECT_EQ(load.status, 0) << load.all();
  EXPECT_THAT(load.all(), HasSubstr("loaded calibrate_seed3.json"));
}

TEST(CalibrateCommand, TooFewPosesFailsWithTheReason) {
  const CommandRun run =
      RunSpidarcad("calibrate --simulated --method self --poses 5 --eval-poses 10");
  EXPECT_EQ(run.status, 1) << run.all();
  EXPECT_THAT(run.all(), HasSubstr("too_few_samples"));
  EXPECT_THAT(run.all(), HasSubstr("unknown poses"));
}

TEST(CalibrateCommand, BadInputExitsWithStatus2) {
  EXPECT_EQ(RunSpidarcad("calibrate").status, 2);
  EXPECT_THAT(RunSpidarcad("calibrate").all(), HasSubstr("--simulated"));
  EXPECT_THAT(RunSpidarcad("calibrate").all(), HasSubstr("--device board-sim|usb"));
  EXPECT_EQ(RunSpidarcad("calibrate --simulated --method magic").status, 2);
  EXPECT_EQ(RunSpidarcad("calibrate --simulated --poses 0").status, 2);
  // A count that would allocate gigabytes is refused up front, naming the option and the range.
  const CommandRun huge = RunSpidarcad("calibrate --simulated --poses 2000000000");
  EXPECT_EQ(huge.status, 2);
  EXPECT_THAT(huge.all(), HasSubstr("--poses: must be in [1, 100000]"));
  EXPECT_EQ(RunSpidarcad("calibrate --simulated --eval-poses 2000000000").status, 2);
  EXPECT_EQ(RunSpidarcad("calibrate --device bluetooth").status, 2);
  EXPECT_THAT(RunSpidarcad("calibrate --device bluetooth").all(), HasSubstr("board-sim or usb"));
  EXPECT_EQ(RunSpidarcad("calibrate --simulated --device usb").status, 2);
  const CommandRun frame = RunSpidarcad("calibrate --simulated --frame 0.2,0.2,0.2 --pole 0.3");
  EXPECT_EQ(frame.status, 2);
  EXPECT_THAT(frame.all(), HasSubstr("--frame/--pole"));
}

// A valid version-1 file for the simulated device of seed 3 (docs/calibration-format.md), with
// string 3's gain replaced by `gain3` (JSON text).
std::string FileText(const std::string& gain3) {
  std::ostringstream f;
  f << R"({"format": "spidarcad-calibration", "version": 1,
           "device": {"kind": "simulated", "seed": 3,
                      "frame": {"a": 0.24, "b": 0.24, "c": 0.24}, "pole": 0.04},
           "date": "2026-12-02T01:00:00Z", "method": "line",
           "encoder": {"counts_per_rev": 2000, "pulley_radius": 0.008},
           "fit": {"samples": 30, "iterations": 0, "condition": 12.5, "rms_residual": 1e-5,
                   "string_rms_residual": [1e-5, 1e-5, 1e-5, 1e-5, 1e-5, 1e-5, 1e-5, 1e-5]},
           "strings": [)";
  for (int i = 0; i < 8; ++i) {
    f << (i ? "," : "") << R"({"offset": 0.39, "gain": )" << (i == 2 ? gain3 : "1.0")
      << R"(, "quadratic": 0, "stretch": 0})";
  }
  f << "]}";
  return f.str();
}

TEST(CalibrateCommand, BadCalibrationFileNamesFileAndField) {
  const std::string path = OutputPath("bad.json");
  std::ofstream(path) << FileText("\"x\"");
  const CommandRun run = RunSpidarcad("calibrate --simulated --seed 3 --load " + path);
  EXPECT_EQ(run.status, 2) << run.all();
  EXPECT_THAT(run.all(), HasSubstr(path));
  EXPECT_THAT(run.all(), HasSubstr("strings[2].gain"));

  const std::string missing = OutputPath("missing.json");
  {
    std::ofstream f(missing);
    f << R"({"format": "spidarcad-calibration", "version": 1, "encoder": {"counts_per_rev": 2000}})";
  }
  const CommandRun run2 = RunSpidarcad("calibrate --simulated --load " + missing);
  EXPECT_EQ(run2.status, 2);
  EXPECT_THAT(run2.all(), HasSubstr("'device' is missing"));

  const CommandRun run3 =
      RunSpidarcad("calibrate --simulated --load " + OutputPath("nonexistent.json"));
  EXPECT_EQ(run3.status, 2);
  EXPECT_THAT(run3.all(), HasSubstr("cannot open"));
}

TEST(CalibrateCommand, LoadRefusesAFileFromAnotherDeviceOrFrameWithTheReason) {
  const std::string path = OutputPath("seed3_line.json");
  std::ofstream(path) << FileText("1.0");
  const CommandRun seed =
      RunSpidarcad("calibrate --simulated --seed 4 --eval-poses 5 --load " + path);
  EXPECT_EQ(seed.status, 2) << seed.all();
  EXPECT_THAT(seed.all(), HasSubstr("seed 3"));
  EXPECT_THAT(seed.all(), HasSubstr("seed 4"));
  const CommandRun frame = RunSpidarcad(
      "calibrate --simulated --seed 3 --frame 0.3,0.3,0.3 --eval-poses 5 --load " + path);
  EXPECT_EQ(frame.status, 2) << frame.all();
  EXPECT_THAT(frame.all(), HasSubstr("--frame 0.3,0.3,0.3"));
}

TEST(CalibrateCommand, JsonTableGivesPoseErrorsPerMethod) {
  const CommandRun run = RunSpidarcad("calibrate --simulated --seed 2 --json --eval-poses 100");
  ASSERT_EQ(run.status, 0) << run.all();
  nlohmann::json j;
  ASSERT_NO_THROW(j = nlohmann::json::parse(run.out)) << run.out;
  for (const char* method : {"uncalibrated", "line", "self", "true_parameters"}) {
    ASSERT_TRUE(j.contains(method)) << method;
    const nlohmann::json& m = j[method];
    EXPECT_EQ(m["status"], "ok") << method;
    for (const char* quantity : {"position_mm", "rotation_deg"}) {
      const double mean = m[quantity]["mean"].get<double>();
      const double max = m[quantity]["max"].get<double>();
      EXPECT_GE(mean, 0.0) << method << " " << quantity;
      EXPECT_LE(mean, max) << method << " " << quantity;
    }
    EXPECT_EQ(m["fk_failures"], 0) << method;
  }
  // The uncalibrated device is millimetres off (the paper's 6 % gain error); self-calibration
  // reaches issue 15's 0.2 mm, within a few times the floor of the true parameters, and beats
  // the line fit (which cannot see stretch).
  EXPECT_GT(j["uncalibrated"]["position_mm"]["max"].get<double>(), 5.0);
  EXPECT_LE(j["self"]["position_mm"]["max"].get<double>(), 0.2);
  EXPECT_LT(j["self"]["position_mm"]["max"].get<double>(),
            j["line"]["position_mm"]["max"].get<double>());
  EXPECT_LT(j["true_parameters"]["position_mm"]["max"].get<double>(),
            j["self"]["position_mm"]["max"].get<double>() + 0.05);
  EXPECT_LT(j["self"]["rotation_deg"]["max"].get<double>(), 1.0);
  // The notes went to stderr: stdout is JSON alone.
  EXPECT_THAT(run.err, HasSubstr("self: self-calibration"));
}

TEST(CalibrateCommand, OutWritesTheDocumentedFileWithIdentityAndDate) {
  const std::string out = OutputPath("identity.json");
  std::filesystem::remove(out);
  const CommandRun run = RunSpidarcad(
      "calibrate --simulated --seed 5 --method self --eval-poses 10 --frame 0.25,0.24,0.23 "
      "--pole 0.035 --json --out " +
      out);
  ASSERT_EQ(run.status, 0) << run.all();
  const nlohmann::json j = nlohmann::json::parse(std::ifstream(out));
  EXPECT_EQ(j["format"], "spidarcad-calibration");
  EXPECT_EQ(j["version"], 1);
  EXPECT_EQ(j["device"]["kind"], "simulated");
  EXPECT_EQ(j["device"]["seed"], 5);
  EXPECT_EQ(j["device"]["frame"]["a"], 0.25);
  EXPECT_EQ(j["device"]["frame"]["c"], 0.23);
  EXPECT_EQ(j["device"]["pole"], 0.035);
  EXPECT_EQ(j["method"], "self");
  EXPECT_TRUE(
      std::regex_match(j["date"].get<std::string>(),
                       std::regex(R"([0-9]{4}-[0-9]{2}-[0-9]{2}T[0-9]{2}:[0-9]{2}:[0-9]{2}Z)")));
  EXPECT_EQ(j["fit"]["samples"], 101);  // 100 waved poses and the homing one
  EXPECT_LT(j["fit"]["rms_residual"].get<double>(), 5e-5);
  // Stretch estimated: it matches the simulator's hidden truth for that seed and frame.
  spidarcad::haptics::SimulatedDeviceConfig config;
  config.seed = 5;
  config.geometry = {0.25, 0.24, 0.23, 0.035};
  config.home_pose = spidarcad::haptics::GripPose::Rest(0.035);
  const spidarcad::haptics::SimulatedSpidarG device(config);
  for (int i = 0; i < 8; ++i) {
    EXPECT_NEAR(j["strings"][i]["stretch"].get<double>(), device.true_encoder().strings[i].stretch,
                8e-5)
        << "string " << i + 1;
    EXPECT_NEAR(j["strings"][i]["gain"].get<double>(), device.true_encoder().strings[i].gain, 1e-3)
        << "string " << i + 1;
  }
  // And it loads back on the same device and frame.
  const CommandRun load = RunSpidarcad(
      "calibrate --simulated --seed 5 --method line --poses 30 --eval-poses 20 "
      "--frame 0.25,0.24,0.23 --pole 0.035 --load " +
      out);
  EXPECT_EQ(load.status, 0) << load.all();
}

}  // namespace
