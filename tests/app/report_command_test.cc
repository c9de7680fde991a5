// Tests of `spidarcad report`, run as a separate process: the files, the stamp, figures checked
// against independent expectations (FK on exact lengths, the tension optimum), the tables-only
// path without a display, and bad --only names.
// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <filesystem>
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

// Splits a CSV line (fields without commas, quotes kept).
std::vector<std::string> Split(const std::string& line) {
  std::vector<std::string> fields;
  std::stringstream in(line);
  std::string field;
  while (std::getline(in, field, ',')) fields.push_back(field);
  return fields;
}

// Rows of a CSV file keyed by its first `key_columns` columns joined with '|'.
std::map<std::string, std::vector<std::string>> ReadCsv(const std::string& path, int key_columns,
                                                        std::vector<std::string>* header) {
  std::ifstream in(path);
  std::string line;
  std::map<std::string, std::vector<std::string>> rows;
  if (!std::getline(in, line)) return rows;
  *header = Split(line);
  while (std::getline(in, line)) {
    const std::vector<std::string> f = Split(line);
    if (static_cast<int>(f.size()) < key_columns) continue;
    std::string key = f[0];
    for (int i = 1; i < key_columns; ++i) key += "|" + f[i];
    rows[key] = f;
  }
  return rows;
}

// Column index of `name` in `header` (-1 when missing).
int Column(const std::vector<std::string>& header, const std::string& name) {
  for (size_t i = 0; i < header.size(); ++i) {
    if (header[i] == name) return static_cast<int>(i);
  }
  return -1;
}

std::string FreshDir(const std::string& name) {
  const std::string dir = TestOutputPath(name);
  std::filesystem::remove_all(dir);
  return dir;
}

TEST(ReportCommand, WritesStampedReportWhoseFkAndTensionFiguresMatchIndependentReferences) {
  const std::string dir = FreshDir("report_fk_tensions");
  const CommandRun run =
      RunSpidarcad("report --out '" + dir + "' --quick --only fk,tensions", "", "fk_tensions");
  ASSERT_EQ(run.status, 0) << run.err;
  // Progress on stderr, one line per section at least.
  EXPECT_NE(run.err.find("[ 1/2] fk"), std::string::npos) << run.err;
  EXPECT_NE(run.err.find("[ 2/2] tensions"), std::string::npos) << run.err;

  const std::string md = ReadWholeFile(dir + "/report.md");
  ASSERT_FALSE(md.empty());
  for (const char* key :
       {"| commit |", "| build type |", "| CPU |", "| cores |", "| BLAS | OpenBLAS ", "| date |",
        "| mode | --quick |", "## Summary", "## Forward kinematics", "## Tension distribution"}) {
    EXPECT_NE(md.find(key), std::string::npos) << key;
  }
  EXPECT_EQ(md.find("## Workspace"), std::string::npos);  // not asked for
  EXPECT_EQ(md.find("| commit |  |"), std::string::npos);
  EXPECT_EQ(md.find("failed"), std::string::npos);

  // FK: on exact lengths the closed form and the refinement recover the true pose to rounding;
  // 0.8 % noise per string costs millimetres (the paper's calibrated accuracy).
  std::vector<std::string> header;
  const auto fk = ReadCsv(dir + "/fk.csv", 2, &header);
  const int pos_max = Column(header, "pos_err_max_m");
  const int solved = Column(header, "solved_fraction");
  ASSERT_GE(pos_max, 0);
  ASSERT_GE(solved, 0);
  ASSERT_TRUE(fk.count("closed form|exact"));
  ASSERT_TRUE(fk.count("refined (cold)|exact"));
  ASSERT_TRUE(fk.count("refined (cold)|0.8 % per string"));
  EXPECT_LT(std::stod(fk.at("closed form|exact")[pos_max]), 1e-9);
  EXPECT_LT(std::stod(fk.at("refined (cold)|exact")[pos_max]), 1e-9);
  EXPECT_EQ(std::stod(fk.at("closed form|exact")[solved]), 1.0);
  EXPECT_GT(std::stod(fk.at("refined (cold)|0.8 % per string")[pos_max]), 1e-4);

  // Tensions: the solver is exact, so its gap to the brute-force optimum is at rounding level;
  // feasible requests are displayed in full, saturating ones only in part.
  const auto tensions = ReadCsv(dir + "/tensions.csv", 3, &header);
  const int gap_max = Column(header, "gap_max");
  const int share = Column(header, "share_force");
  ASSERT_GE(gap_max, 0);
  ASSERT_GE(share, 0);
  ASSERT_TRUE(tensions.count("random_poses|cold|feasible"));
  ASSERT_TRUE(tensions.count("random_poses|cold|saturated"));
  int checked = 0;
  for (const auto& [key, row] : tensions) {
    EXPECT_LT(std::stod(row[gap_max]), 1e-6) << key;
    ++checked;
  }
  EXPECT_EQ(checked, 6);
  EXPECT_GT(std::stod(tensions.at("random_poses|cold|feasible")[share]), 0.95);
  EXPECT_LT(std::stod(tensions.at("random_poses|cold|saturated")[share]), 0.5);

  // A chart when there was a display (directly or through xvfb-run).
  if (md.find("skipped (no X display)") == std::string::npos) {
    const std::string png = ReadWholeFile(dir + "/fk_time_vs_error.png");
    ASSERT_GT(png.size(), 1000u);
    EXPECT_EQ(png.substr(1, 3), "PNG");
  }
}

TEST(ReportCommand, WithoutDisplayOrXvfbWritesTablesOnlyAndSaysSo) {
  const std::string dir = FreshDir("report_tables_only");
  // SPIDARCAD_REPORT_UNDER_XVFB stops the re-execution under xvfb-run, as when it is missing.
  const CommandRun run =
      RunSpidarcad("report --out '" + dir + "' --quick --only fk", "", "tables_only",
                   "env -u DISPLAY SPIDARCAD_REPORT_UNDER_XVFB=1");
  ASSERT_EQ(run.status, 0) << run.err;
  EXPECT_NE(run.err.find("tables only"), std::string::npos) << run.err;
  const std::string md = ReadWholeFile(dir + "/report.md");
  EXPECT_NE(md.find("charts were not drawn"), std::string::npos);
  EXPECT_NE(md.find("| closed form | exact |"), std::string::npos);
  EXPECT_FALSE(std::filesystem::exists(dir + "/fk_time_vs_error.png"));
}

TEST(ReportCommand, MarkdownElsewhereLinksEveryChartAndCsvInOutDirRelativeToIt) {
  const std::string root = FreshDir("report_markdown");
  const std::string data = root + "/docs/report", markdown = root + "/docs/performance.md";
  const CommandRun run = RunSpidarcad(
      "report --out '" + data + "' --markdown '" + markdown + "' --quick --only fk", "", "md");
  ASSERT_EQ(run.status, 0) << run.err;
  EXPECT_FALSE(std::filesystem::exists(data + "/report.md"));
  const std::string md = ReadWholeFile(markdown);
  EXPECT_NE(md.find("--markdown " + markdown), std::string::npos) << md.substr(0, 400);
  // Every link that is not an anchor names a file that exists, relative to the markdown's folder.
  int png = 0, csv = 0;
  for (size_t at = md.find("]("); at != std::string::npos; at = md.find("](", at + 2)) {
    const size_t end = md.find(')', at);
    ASSERT_NE(end, std::string::npos);
    const std::string target = md.substr(at + 2, end - at - 2);
    if (target.empty() || target[0] == '#') continue;
    EXPECT_EQ(target.rfind("report/", 0), 0u) << target;
    EXPECT_TRUE(std::filesystem::exists(root + "/docs/" + target)) << target;
    png += target.ends_with(".png");
    csv += target.ends_with(".csv");
  }
  EXPECT_GT(png, 0);
  EXPECT_GT(csv, 0);
}

// The edit section (quick: P1 at 6 mm, the two local edits) follows each edit through the slab
// route and checks the felt patch's compliance against a monolithic solve of the new mesh: both
// within 1e-9; the load holes (beside the patch, in the last slab) re-mesh one slab and refactor
// one plane of S, the bolt holes (the first slab) one slab and one plane: the interface factor,
// completed from both ends beforehand, keeps the planes beyond it.
TEST(ReportCommand, EditSectionFollowsEachEditThroughTheSlabsToTheMonolithicForce) {
  const std::string dir = FreshDir("report_edit");
  const CommandRun run =
      RunSpidarcad("report --out '" + dir + "' --quick --only edit --no-plots", "", "edit");
  ASSERT_EQ(run.status, 0) << run.all();
  std::vector<std::string> header;
  const auto rows = ReadCsv(dir + "/edit.csv", 5, &header);
  const int remeshed = Column(header, "slabs_remeshed"),
            planes = Column(header, "planes_refactored");
  const int error = Column(header, "relative_difference"), time = Column(header, "edit_to_force_s");
  ASSERT_GE(std::min({remeshed, planes, error, time}), 0);
  // Both surfaces (marching tetrahedra, lattice), the two local edits each.
  ASSERT_EQ(rows.size(), 4u);
  for (const std::string surface : {"tetrahedra", "lattice"}) {
    const auto load = rows.find("1|6|4|" + surface + "|load holes r 4 -> 4.5 mm");
    const auto bolt = rows.find("1|6|4|" + surface + "|bolt holes r 5.5 -> 6 mm");
    ASSERT_NE(load, rows.end()) << surface;
    ASSERT_NE(bolt, rows.end()) << surface;
    EXPECT_EQ(load->second[remeshed], "1") << surface;
    EXPECT_EQ(load->second[planes], "1") << surface;
    EXPECT_EQ(bolt->second[remeshed], "1") << surface;
    EXPECT_EQ(bolt->second[planes], "1") << surface;  // the interface factor twisted there
  }
  for (const auto& [key, f] : rows) {
    EXPECT_LT(std::stod(f[error]), 1e-9) << key;
    EXPECT_GT(std::stod(f[time]), 0.0) << key;
  }
  EXPECT_NE(ReadWholeFile(dir + "/report.md").find("Edit to felt force"), std::string::npos);
}

// The hard-case section runs every Hard<Thing> case of the build's test executables: each one
// passes and records its measured figure and its pass line (the convention of
// tests/CMakeLists.txt), and the table lists each of the four executables' cases.
TEST(ReportCommand, HardSectionListsEveryHardCaseWithItsFigureAndPassLine) {
  const std::string dir = FreshDir("report_hard");
  const CommandRun run =
      RunSpidarcad("report --out '" + dir + "' --quick --only hard --no-plots", "", "hard");
  ASSERT_EQ(run.status, 0) << run.all();
  std::ifstream in(dir + "/hard_cases.csv");
  std::string line;
  ASSERT_TRUE(std::getline(in, line));
  EXPECT_EQ(line, "case,figure,bar,verdict,seconds");
  int rows = 0;
  std::map<std::string, int> suites;
  while (std::getline(in, line)) {
    const std::vector<std::string> f = Split(line);
    ASSERT_EQ(f.size(), 5u) << line;
    EXPECT_EQ(f[0].rfind("Hard", 0), 0u) << line;
    EXPECT_FALSE(f[1].empty()) << f[0] << " records no figure";
    EXPECT_FALSE(f[2].empty()) << f[0] << " records no pass line";
    EXPECT_EQ(f[3], "pass") << line;
    ++suites[f[0].substr(0, f[0].find('.'))];
    ++rows;
  }
  EXPECT_GE(rows, 30);
  EXPECT_GT(suites.count("HardFk"), 0u);              // haptics_tests
  EXPECT_GT(suites.count("HardSculpt"), 0u);          // modeling_tests
  EXPECT_GT(suites.count("HardIncompressible"), 0u);  // fem_tests
  EXPECT_GT(suites.count("HardVtu"), 0u);             // app_tests
  const std::string summary = ReadWholeFile(dir + "/summary.md");
  EXPECT_NE(summary.find("| Hard cases | " + std::to_string(rows) + " cases in "),
            std::string::npos)
      << summary;
  EXPECT_NE(summary.find("every case within its pass line"), std::string::npos) << summary;
}

TEST(ReportCommand, UnknownOnlyNameExitsTwoListingTheValidNamesAndWritesNothing) {
  const std::string dir = FreshDir("report_bad_only");
  const CommandRun run =
      RunSpidarcad("report --out '" + dir + "' --quick --only fk,bogus", "", "bad_only");
  EXPECT_EQ(run.status, 2);
  EXPECT_NE(run.err.find("'bogus'"), std::string::npos) << run.err;
  for (const char* name : {"fk", "singular", "tensions", "calibration", "workspace", "implicit",
                           "surface", "tets", "fe", "tick", "sculpt"}) {
    EXPECT_NE(run.err.find(name), std::string::npos) << name;
  }
  EXPECT_FALSE(std::filesystem::exists(dir));
}

TEST(ReportCommand, SingularSectionFindsTheNamedSingularFamilyAndSummaryHasOneRowPerPart) {
  const std::string dir = FreshDir("report_singular");
  const CommandRun run = RunSpidarcad(
      "report --out '" + dir + "' --quick --only fk,singular --no-plots", "", "singular");
  ASSERT_EQ(run.status, 0) << run.err;
  const std::string md = ReadWholeFile(dir + "/report.md");
  EXPECT_NE(md.find("## FK conditioning and singular set"), std::string::npos);
  EXPECT_EQ(md.find("failed"), std::string::npos);
  // docs/kinematics.md: the centre on the z axis with the grip turned 90 degrees about z at a
  // 90-degree grasp is singular (each pole's cubic has a double root), and the rest pose at the
  // centre is well conditioned. The maps' grids hold those poses.
  std::vector<std::string> header;
  std::ifstream in(dir + "/fk_conditioning.csv");
  std::string line;
  ASSERT_TRUE(std::getline(in, line));
  header = Split(line);
  const int u = Column(header, "u"), v = Column(header, "v"),
            gain = Column(header, "error_gain_m_per_m"), status = Column(header, "fk_status");
  ASSERT_GE(u, 0);
  ASSERT_GE(v, 0);
  ASSERT_GE(gain, 0);
  ASSERT_GE(status, 0);
  int family = 0, rest = 0;
  while (std::getline(in, line)) {
    const std::vector<std::string> f = Split(line);
    const double fu = std::stod(f[u]), fv = std::stod(f[v]);
    // "inf" parses as infinity; points outside the frame ("n/a") are not read.
    if (f[0] == "fk_gain_z_yaw" && std::abs(std::abs(fv) - M_PI / 2) < 1e-5 && std::abs(fu) < 0.1) {
      const double g = std::stod(f[gain]);
      EXPECT_TRUE(!(g < 1e3)) << "z " << fu << " yaw " << fv << ": gain " << g;
      EXPECT_NE(f[status], "0") << "FK returned ok on the singular family at z " << fu;
      ++family;
    }
    if (f[0] == "fk_gain_xy" && std::abs(fu) < 1e-12 && std::abs(fv) < 1e-12) {
      EXPECT_LT(std::stod(f[gain]), 10.0);
      EXPECT_EQ(f[status], "0");
      ++rest;
    }
  }
  EXPECT_GT(family, 4);
  EXPECT_EQ(rest, 1);
  // summary.md: the stamp line and one row per part run, each with a speed and an error cell.
  const std::string summary = ReadWholeFile(dir + "/summary.md");
  EXPECT_NE(summary.find("| part | speed | error |"), std::string::npos) << summary;
  EXPECT_NE(summary.find("| Forward kinematics | warm "), std::string::npos) << summary;
  EXPECT_NE(summary.find("| FK conditioning and singular set | "), std::string::npos) << summary;
  EXPECT_NE(summary.find("--only fk,singular"), std::string::npos) << summary;
  EXPECT_EQ(summary.find("| — |"), std::string::npos) << summary;
}

}  // namespace
