// Runs the built `spidarcad calibrate` and checks its table, its file and its errors.
// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#include <sys/wait.h>

#include <cstdio>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <nlohmann/json.hpp>

#include "spidarcad_runner.h"

#include "spidarcad/haptics/simulated_device.h"

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
  const CommandRun run = RunSpidarcad("calibrate --simulated --seed 3 --poses 60 --eval-poses 80 --out " + out);
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
    EXPECT_NEAR(j["strings"][i]["gain"].get<double>(), device.true_encoder().strings[i].gain,
                1e-3)
        << "string " << i + 1;
    EXPECT_NEAR(j["strings"][i]["offset"].get<double>(), device.true_encoder().strings[i].offset,
                1e-3)
        << "string " << i + 1;
  }
  // Loading it back evaluates it as another row.
  const CommandRun load = RunSpidarcad("calibrate --simulated --seed 3 --method line --poses 30 "
                                "--eval-poses 40 --load " + out);
  EXPECT_EQ(load.status, 0) << load.all();
  EXPECT_THAT(load.all(), HasSubstr("loaded calibrate_seed3.json"));
}

TEST(CalibrateCommand, TooFewPosesFailsWithTheReason) {
  const CommandRun run = RunSpidarcad("calibrate --simulated --method self --poses 5 --eval-poses 10");
  EXPECT_EQ(run.status, 1) << run.all();
  EXPECT_THAT(run.all(), HasSubstr("too_few_samples"));
  EXPECT_THAT(run.all(), HasSubstr("unknown poses"));
}

TEST(CalibrateCommand, BadInputExitsWithStatus2) {
  EXPECT_EQ(RunSpidarcad("calibrate").status, 2);
  EXPECT_THAT(RunSpidarcad("calibrate").all(), HasSubstr("--simulated"));
  EXPECT_EQ(RunSpidarcad("calibrate --simulated --method magic").status, 2);
  EXPECT_EQ(RunSpidarcad("calibrate --simulated --poses 0").status, 2);
}

TEST(CalibrateCommand, BadCalibrationFileNamesFileAndField) {
  const std::string path = OutputPath("bad.json");
  {
    std::ofstream f(path);
    f << R"({"format": "spidarcad-calibration", "version": 1,
             "encoder": {"counts_per_rev": 2000, "pulley_radius": 0.008},
             "strings": [)";
    for (int i = 0; i < 8; ++i) {
      f << (i ? "," : "") << R"({"offset": 0.39, "gain": )" << (i == 2 ? "\"x\"" : "1.0")
        << R"(, "quadratic": 0, "stretch": 0})";
    }
    f << "]}";
  }
  const CommandRun run = RunSpidarcad("calibrate --simulated --load " + path);
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
  EXPECT_THAT(run2.all(), HasSubstr("encoder.pulley_radius"));

  const CommandRun run3 = RunSpidarcad("calibrate --simulated --load " + OutputPath("nonexistent.json"));
  EXPECT_EQ(run3.status, 2);
  EXPECT_THAT(run3.all(), HasSubstr("cannot open"));
}

}  // namespace
