// Calibration files: round trip, every field validated with the file and field named, atomic
// writes, and which device a file fits.
// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#include "scene/calibration_file.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <regex>
#include <string>

#include "cli/cli_common.h"
#include "support/scoped_env.h"

namespace spidarcad::app {
namespace {

using testing::HasSubstr;

std::string OutputPath(const std::string& name) {
  return std::string(SPIDARCAD_TEST_OUTPUT_DIR) + "/calibration_file_" + name;
}

CalibrationFile Example() {
  CalibrationFile file;
  file.device.kind = "simulated";
  file.device.seed = 3;
  file.date = "2026-12-02T01:45:03Z";
  file.method = "self";
  for (int i = 0; i < haptics::kNumStrings; ++i) {
    file.calibration.strings[i] = {0.30 + 0.01 * i, 1.06 + 0.001 * i, 0.02 * i - 0.05, 4e-4};
    file.fit.string_rms_residual[i] = 1e-5 * (i + 1);
  }
  file.fit.samples = 101;
  file.fit.iterations = 9;
  file.fit.condition = 640.5;
  file.fit.rms_residual = 1.3e-5;
  return file;
}

// Writes `j` to a file and returns the loader's error message ("" when it loads).
std::string LoadError(const nlohmann::json& j, const std::string& name) {
  const std::string path = OutputPath(name);
  std::ofstream(path) << j.dump(1);
  try {
    LoadCalibrationFile(path);
  } catch (const InputError& e) {
    return e.what();
  }
  return "";
}

TEST(CalibrationFile, RoundTripsEveryFieldExactly) {
  const CalibrationFile file = Example();
  const std::string path = OutputPath("round_trip.json");
  SaveCalibrationFile(file, path);
  const CalibrationFile back = LoadCalibrationFile(path);
  EXPECT_EQ(back.device.kind, "simulated");
  EXPECT_EQ(back.device.seed, 3u);
  EXPECT_EQ(back.device.geometry.a, 0.24);
  EXPECT_EQ(back.device.geometry.d, 0.04);
  EXPECT_EQ(back.date, file.date);
  EXPECT_EQ(back.method, "self");
  EXPECT_EQ(back.calibration.spec.counts_per_rev, 2000);
  for (int i = 0; i < haptics::kNumStrings; ++i) {
    EXPECT_EQ(back.calibration.strings[i].offset, file.calibration.strings[i].offset);
    EXPECT_EQ(back.calibration.strings[i].gain, file.calibration.strings[i].gain);
    EXPECT_EQ(back.calibration.strings[i].quadratic, file.calibration.strings[i].quadratic);
    EXPECT_EQ(back.calibration.strings[i].stretch, file.calibration.strings[i].stretch);
    EXPECT_EQ(back.fit.string_rms_residual[i], file.fit.string_rms_residual[i]);
  }
  EXPECT_EQ(back.fit.samples, 101);
  EXPECT_EQ(back.fit.condition, 640.5);
  // The text is the documented layout (docs/calibration-format.md).
  const nlohmann::json j = nlohmann::json::parse(std::ifstream(path));
  EXPECT_EQ(j["format"], "spidarcad-calibration");
  EXPECT_EQ(j["version"], 1);
  EXPECT_EQ(j["device"]["frame"]["b"], 0.24);
  EXPECT_EQ(j["device"]["pole"], 0.04);
  EXPECT_FALSE(j["device"].contains("serial"));
}

TEST(CalibrationFile, UsbFilesCarryTheSerialInsteadOfTheSeed) {
  CalibrationFile file = Example();
  file.device.kind = "usb";
  file.device.serial = "SPG-0042";
  const std::string path = OutputPath("usb.json");
  SaveCalibrationFile(file, path);
  const nlohmann::json j = nlohmann::json::parse(std::ifstream(path));
  EXPECT_EQ(j["device"]["serial"], "SPG-0042");
  EXPECT_FALSE(j["device"].contains("seed"));
  EXPECT_EQ(LoadCalibrationFile(path).device.serial, "SPG-0042");
}

TEST(CalibrationFile, NowIsIso8601Utc) {
  EXPECT_TRUE(std::regex_match(
      NowIso8601Utc(),
      std::regex(R"(20[0-9]{2}-[01][0-9]-[0-3][0-9]T[0-2][0-9]:[0-5][0-9]:[0-6][0-9]Z)")));
}

TEST(CalibrationFile, EveryMissingFieldIsNamedWithTheFile) {
  const std::string path = OutputPath("complete.json");
  SaveCalibrationFile(Example(), path);
  const nlohmann::json good = nlohmann::json::parse(std::ifstream(path));
  const std::vector<nlohmann::json::json_pointer> fields = {
      nlohmann::json::json_pointer("/format"),
      nlohmann::json::json_pointer("/version"),
      nlohmann::json::json_pointer("/device"),
      nlohmann::json::json_pointer("/device/kind"),
      nlohmann::json::json_pointer("/device/seed"),
      nlohmann::json::json_pointer("/device/frame"),
      nlohmann::json::json_pointer("/device/frame/c"),
      nlohmann::json::json_pointer("/device/pole"),
      nlohmann::json::json_pointer("/date"),
      nlohmann::json::json_pointer("/method"),
      nlohmann::json::json_pointer("/encoder/counts_per_rev"),
      nlohmann::json::json_pointer("/encoder/pulley_radius"),
      nlohmann::json::json_pointer("/strings"),
      nlohmann::json::json_pointer("/strings/5/stretch"),
      nlohmann::json::json_pointer("/fit"),
      nlohmann::json::json_pointer("/fit/samples"),
      nlohmann::json::json_pointer("/fit/rms_residual"),
      nlohmann::json::json_pointer("/fit/string_rms_residual"),
  };
  for (const auto& pointer : fields) {
    nlohmann::json j = good;
    j[pointer.parent_pointer()].erase(pointer.back());
    // The field as the message spells it: device.frame.c, strings[5].stretch.
    std::string name = pointer.to_string().substr(1);
    name = std::regex_replace(name, std::regex("/([0-9]+)"), "[$1]");
    std::replace(name.begin(), name.end(), '/', '.');
    const std::string error = LoadError(j, "missing.json");
    EXPECT_THAT(error, HasSubstr(OutputPath("missing.json"))) << name;
    EXPECT_THAT(error, HasSubstr("'" + name + "' is missing")) << name;
  }
}

TEST(CalibrationFile, WrongValuesAreNamedWithWhatWasExpected) {
  const std::string path = OutputPath("complete2.json");
  SaveCalibrationFile(Example(), path);
  const nlohmann::json good = nlohmann::json::parse(std::ifstream(path));
  struct Case {
    const char* pointer;
    nlohmann::json value;
    const char* expect;
  };
  const Case cases[] = {
      {"/format", "spidarcad-scene", "field 'format': expected \"spidarcad-calibration\""},
      {"/version", 2, "field 'version': only version 1"},
      {"/device/kind", "bluetooth", "field 'device.kind': expected \"simulated\""},
      {"/device/seed", -4, "field 'device.seed': expected an integer >= 0"},
      {"/device/frame/a", "wide", "field 'device.frame.a': expected a number, got \"wide\""},
      {"/device/pole", 0.5, "field 'device'"},  // the grip does not fit the frame
      {"/date", "yesterday", "field 'date': expected ISO 8601 UTC"},
      {"/date", "2026-13-02T01:45:03Z", "field 'date'"},
      {"/method", "guess", "field 'method': expected \"self\" or \"line\""},
      {"/encoder/counts_per_rev", 2000.5, "field 'encoder.counts_per_rev': expected an integer"},
      {"/encoder/pulley_radius", -0.008, "field 'encoder.pulley_radius': expected a positive"},
      {"/strings/2/gain", "x", "field 'strings[2].gain': expected a number, got \"x\""},
      {"/strings/7/gain", 0.0, "field 'strings[7].gain': expected a positive number"},
      {"/strings/1/stretch", -1e-4, "field 'strings[1].stretch': expected a number >= 0"},
      {"/strings", nlohmann::json::array({1, 2}), "field 'strings': expected an array of 8"},
      {"/fit/rms_residual", -1.0, "field 'fit.rms_residual'"},
      {"/fit/string_rms_residual/4", "big", "field 'fit.string_rms_residual[4]'"},
  };
  for (const Case& c : cases) {
    nlohmann::json j = good;
    j[nlohmann::json::json_pointer(c.pointer)] = c.value;
    const std::string error = LoadError(j, "wrong.json");
    EXPECT_THAT(error, HasSubstr(OutputPath("wrong.json"))) << c.pointer;
    EXPECT_THAT(error, HasSubstr(c.expect)) << c.pointer;
  }
  // Not JSON at all: the line and column of the problem, the end of the 11-byte text (column 12,
  // just after its last character, as every JSON reader reports an early end; scene_io's
  // ParseJsonText).
  const std::string broken = OutputPath("broken.json");
  std::ofstream(broken) << "{\"format\": ";
  try {
    LoadCalibrationFile(broken);
    ADD_FAILURE() << "no error";
  } catch (const InputError& e) {
    EXPECT_THAT(e.what(), HasSubstr(broken + ":1:12: JSON syntax error"));
  }
  EXPECT_THROW(LoadCalibrationFile(OutputPath("does_not_exist.json")), InputError);
}

TEST(CalibrationFile, SaveIsAtomicAndLeavesNothingBehindOnFailure) {
  const std::filesystem::path dir = OutputPath("atomic_dir");
  std::filesystem::remove_all(dir);
  std::filesystem::create_directories(dir);
  const std::string path = (dir / "cal.json").string();
  std::ofstream(path) << "old contents";
  SaveCalibrationFile(Example(), path);
  EXPECT_EQ(LoadCalibrationFile(path).fit.samples, 101);
  int entries = 0;
  for ([[maybe_unused]] const auto& e : std::filesystem::directory_iterator(dir)) ++entries;
  EXPECT_EQ(entries, 1);  // no temporary left
  // Into a directory that does not exist: an error naming the option and the file.
  const std::string nowhere = (dir / "missing" / "cal.json").string();
  try {
    SaveCalibrationFile(Example(), nowhere, "--out");
    ADD_FAILURE() << "no error";
  } catch (const InputError& e) {
    EXPECT_THAT(e.what(), HasSubstr("--out"));
    EXPECT_THAT(e.what(), HasSubstr(nowhere));
  }
  EXPECT_FALSE(std::filesystem::exists(nowhere));
}

TEST(CalibrationFile, MismatchNamesTheDeviceOrFrameThatDiffers) {
  const CalibrationFile file = Example();  // simulated, seed 3, 48 cm frame
  CalibrationDevice same = file.device;
  EXPECT_EQ(CalibrationMismatch(file, same), "");
  CalibrationDevice board_sim = same;
  board_sim.kind = "board-sim";  // the same simulated SPIDAR-G behind the board simulator
  EXPECT_EQ(CalibrationMismatch(file, board_sim), "");
  CalibrationDevice other_seed = same;
  other_seed.seed = 4;
  EXPECT_THAT(CalibrationMismatch(file, other_seed), HasSubstr("seed 3"));
  EXPECT_THAT(CalibrationMismatch(file, other_seed), HasSubstr("seed 4"));
  CalibrationDevice usb;
  usb.kind = "usb";
  usb.serial = "SPG-0042";
  EXPECT_THAT(CalibrationMismatch(file, usb), HasSubstr("USB board serial SPG-0042"));
  CalibrationDevice bigger = same;
  bigger.geometry.a = 0.30;
  EXPECT_THAT(CalibrationMismatch(file, bigger), HasSubstr("--frame 0.24,0.24,0.24 --pole 0.04"));
  EXPECT_THAT(CalibrationMismatch(file, bigger), HasSubstr("--frame 0.3,0.24,0.24"));
  CalibrationDevice other_encoder = same;
  other_encoder.encoder.counts_per_rev = 4000;
  EXPECT_THAT(CalibrationMismatch(file, other_encoder), HasSubstr("4000 counts/rev"));
  CalibrationFile usb_file = file;
  usb_file.device = usb;
  CalibrationDevice other_board = usb;
  other_board.serial = "SPG-0007";
  EXPECT_THAT(CalibrationMismatch(usb_file, other_board), HasSubstr("serial SPG-0007"));
  EXPECT_EQ(CalibrationMismatch(usb_file, usb), "");
}

// Points XDG_CONFIG_HOME at a fresh directory for the test's life (the memory lives there).
class ScopedConfigHome {
 public:
  explicit ScopedConfigHome(const std::string& name)
      : dir_(Fresh(OutputPath("xdg_" + name))), env_("XDG_CONFIG_HOME", dir_.c_str()) {}
  const std::string& dir() const { return dir_; }

 private:
  static std::string Fresh(const std::string& dir) {
    std::filesystem::remove_all(dir);
    return dir;
  }
  std::string dir_;
  test_support::ScopedEnv env_;
};

CalibrationDevice Board(const std::string& serial) {
  CalibrationDevice board;
  board.kind = "usb";
  board.serial = serial;
  return board;
}

TEST(DeviceMemory, RemembersOneFilePerBoardSerialUnderXdgConfigHome) {
  const ScopedConfigHome home("per_board");
  EXPECT_EQ(DeviceMemoryPath(), home.dir() + "/spidarcad/devices.json");
  EXPECT_EQ(RememberedCalibration(Board("SPG-0042")), "");  // nothing yet, no file
  std::string why;
  ASSERT_TRUE(RememberCalibration(Board("SPG-0042"), "/lab/a.json", &why)) << why;
  ASSERT_TRUE(RememberCalibration(Board("SPG-0007"), "/lab/b.json", &why)) << why;
  EXPECT_EQ(RememberedCalibration(Board("SPG-0042")), "/lab/a.json");
  EXPECT_EQ(RememberedCalibration(Board("SPG-0007")), "/lab/b.json");
  // A newer calibration of the same board replaces the older one; the other board keeps its own.
  ASSERT_TRUE(RememberCalibration(Board("SPG-0042"), "/lab/c.json", &why)) << why;
  EXPECT_EQ(RememberedCalibration(Board("SPG-0042")), "/lab/c.json");
  EXPECT_EQ(RememberedCalibration(Board("SPG-0007")), "/lab/b.json");
  EXPECT_EQ(RememberedCalibration(Board("SPG-0099")), "");
  // The file is what the header documents.
  std::ifstream in(DeviceMemoryPath());
  const nlohmann::json doc = nlohmann::json::parse(in);
  EXPECT_EQ(doc["format"], "spidarcad-devices");
  EXPECT_EQ(doc["version"], 1);
  EXPECT_EQ(doc["calibrations"]["usb:SPG-0007"], "/lab/b.json");
  EXPECT_FALSE(std::filesystem::exists(DeviceMemoryPath() + ".tmp"));
}

TEST(DeviceMemory, KeepsRelativePathsAbsoluteAndIgnoresSimulatedDevicesAndBadFiles) {
  const ScopedConfigHome home("relative");
  std::string why;
  ASSERT_TRUE(RememberCalibration(Board("SPG-1"), "cal/board.json", &why)) << why;
  EXPECT_EQ(RememberedCalibration(Board("SPG-1")),
            (std::filesystem::current_path() / "cal/board.json").string());
  // Simulated devices are recalibrated at every start: never remembered, never looked up.
  CalibrationDevice simulated;
  simulated.kind = "simulated";
  EXPECT_TRUE(RememberCalibration(simulated, "/lab/sim.json", &why));
  EXPECT_EQ(RememberedCalibration(simulated), "");
  // A board without a serial number cannot be told from another: not remembered.
  EXPECT_TRUE(RememberCalibration(Board(""), "/lab/none.json", &why));
  EXPECT_EQ(RememberedCalibration(Board("")), "");
  // A memory file that is not one counts as empty, and the next remember rewrites it.
  std::ofstream(DeviceMemoryPath()) << "{ not json";
  EXPECT_EQ(RememberedCalibration(Board("SPG-1")), "");
  ASSERT_TRUE(RememberCalibration(Board("SPG-1"), "/lab/again.json", &why)) << why;
  EXPECT_EQ(RememberedCalibration(Board("SPG-1")), "/lab/again.json");
}

TEST(DeviceMemory, FallsBackToHomeAndSaysWhyWhenNeitherIsSet) {
  const test_support::ScopedEnv no_xdg("XDG_CONFIG_HOME", nullptr);
  {
    const test_support::ScopedEnv home("HOME", "/nonexistent-home");
    EXPECT_EQ(DeviceMemoryPath(), "/nonexistent-home/.config/spidarcad/devices.json");
  }
  const test_support::ScopedEnv no_home("HOME", nullptr);
  EXPECT_EQ(DeviceMemoryPath(), "");
  std::string why;
  EXPECT_FALSE(RememberCalibration(Board("SPG-1"), "/lab/a.json", &why));
  EXPECT_THAT(why, HasSubstr("XDG_CONFIG_HOME"));
  EXPECT_EQ(RememberedCalibration(Board("SPG-1")), "");
}

}  // namespace
}  // namespace spidarcad::app
