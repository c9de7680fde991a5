// Report section: the hard cases as a suite. Every GoogleTest case named Hard<Thing> (ctest label
// `hard`, tests/CMakeLists.txt) records its measured figure and its pass line as the test
// properties "figure" and "bar"; this section runs those cases in the build tree's test
// executables (build/tests/*_tests, found beside this program's build/app/) with GoogleTest's
// JSON output and tabulates name, figure, bar, verdict and time. Without the test executables (an
// installed spidarcad) it says how to build them.
// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "cli/report_sections.h"

namespace spidarcad::app {

namespace {

namespace fs = std::filesystem;

// The test executables of the build tree this program was built in, in module order: those
// found, and the names of those not built (their hard cases cannot be run).
struct TestExecutableList {
  std::vector<fs::path> found;
  std::vector<std::string> missing;
};

TestExecutableList TestExecutables() {
  std::error_code error;
  const fs::path self = fs::read_symlink("/proc/self/exe", error);
  if (error) return {};
  const fs::path tests = self.parent_path().parent_path() / "tests";
  TestExecutableList list;
  for (const char* name : {"haptics_tests", "modeling_tests", "fem_tests", "app_tests"}) {
    const fs::path p = tests / name;
    if (::access(p.c_str(), X_OK) == 0) {
      list.found.push_back(p);
    } else {
      list.missing.push_back(name);
    }
  }
  return list;
}

// Single-quotes `s` for the shell.
std::string Quote(const std::string& s) {
  std::string out = "'";
  for (char c : s) out += c == '\'' ? std::string("'\\''") : std::string(1, c);
  return out + "'";
}

struct HardCase {
  std::string name, figure, bar;
  bool passed = false;
  double seconds = 0.0;
};

// Runs the Hard* cases of `exe`, reading GoogleTest's JSON report written to `json`.
std::vector<HardCase> RunHardCases(const fs::path& exe, const fs::path& json) {
  std::error_code error;
  fs::remove(json, error);
  const std::string command =
      Quote(exe.string()) + " --gtest_filter='Hard*' --gtest_output=json:" + Quote(json.string()) +
      " > /dev/null 2>&1";
  const int status = std::system(command.c_str());
  (void)status;  // a failing case still writes the report; a crash leaves none (below)
  std::ifstream in(json);
  std::vector<HardCase> cases;
  if (!in) {
    cases.push_back(
        {exe.filename().string() + " (no report: the executable crashed)", "", "", false, 0.0});
    return cases;
  }
  const nlohmann::json report = nlohmann::json::parse(in, nullptr, false);
  fs::remove(json, error);
  if (report.is_discarded() || !report.contains("testsuites")) return cases;
  for (const auto& suite : report.at("testsuites")) {
    for (const auto& test : suite.value("testsuite", nlohmann::json::array())) {
      HardCase c;
      c.name = suite.value("name", "") + "." + test.value("name", "");
      c.figure = test.value("figure", "");
      c.bar = test.value("bar", "");
      c.passed = !test.contains("failures") && test.value("result", "") == "COMPLETED";
      const std::string time = test.value("time", "0s");
      c.seconds = std::atof(time.c_str());
      cases.push_back(c);
    }
  }
  return cases;
}

}  // namespace

void ReportHardCases(ReportContext& ctx) {
  const TestExecutableList list = TestExecutables();
  const std::vector<fs::path>& executables = list.found;
  if (executables.empty()) {
    ctx.md() << "The test executables were not found beside this program (an installed "
                "spidarcad has none). Run the report from a build tree after "
                "`cmake --build build --target haptics_tests modeling_tests fem_tests app_tests`, "
                "or run the hard cases alone with `ctest --test-dir build -L hard`.\n";
    ctx.Headline("skipped: no test executables beside this program");
    ctx.Summary("—", "skipped (no test executables)");
    return;
  }
  std::vector<HardCase> cases;
  for (size_t i = 0; i < executables.size(); ++i) {
    const fs::path json =
        fs::path(ctx.settings().out_dir) / ("hard_" + std::to_string(i) + ".json");
    const std::vector<HardCase> found = RunHardCases(executables[i], json);
    cases.insert(cases.end(), found.begin(), found.end());
    ctx.Progress(static_cast<double>(i + 1) / executables.size());
  }
  int passed = 0;
  double total = 0.0;
  std::vector<std::vector<std::string>> rows, csv;
  for (const HardCase& c : cases) {
    passed += c.passed;
    total += c.seconds;
    rows.push_back({"`" + c.name + "`", c.figure.empty() ? "—" : c.figure,
                    c.bar.empty() ? "—" : c.bar, c.passed ? "pass" : "**FAIL**",
                    Sig(c.seconds, 2)});
    auto field = [](std::string s) {
      for (char& ch : s)
        if (ch == ',' || ch == '\n') ch = ';';
      return s;
    };
    csv.push_back(
        {c.name, field(c.figure), field(c.bar), c.passed ? "pass" : "fail", Sig(c.seconds, 4)});
  }
  const int failed = static_cast<int>(cases.size()) - passed;
  ctx.md() << "Every test suite named `Hard<Thing>` is a hard numerical case: near-singular poses, "
              "frame edges, noisy and quantized sensors, ill-conditioned meshes, nearly "
              "incompressible material, infeasible forces, hostile files. Each case records the "
              "figure it measured and the line it must stay within; the table is their run in "
              "this build (`ctest -L hard` runs the same cases; their sources are the "
              "`tests/*/..._test.cc` files named after each suite's module).\n\n";
  // A partial build (say a sanitizer build of one module's tests) runs fewer cases: say which
  // executables were not there, so that a short table is not read as the whole set.
  std::string not_built, targets;
  for (const std::string& name : list.missing) {
    not_built += (not_built.empty() ? "" : ", ") + name;
    targets += " " + name;
  }
  if (!not_built.empty()) {
    ctx.md() << "Not built in this tree, so their hard cases are missing from the table: "
             << not_built << " (`cmake --build build --target" << targets << "` builds them).\n\n";
  }
  ctx.Table({"case", "measured", "pass line", "verdict", "time [s]"}, rows);
  ctx.Csv("hard_cases", {"case", "figure", "bar", "verdict", "seconds"}, csv);
  ctx.Headline(std::to_string(cases.size()) + " hard cases: " + std::to_string(passed) +
               " within their pass lines" +
               (failed > 0 ? ", **" + std::to_string(failed) + " outside**" : std::string()) +
               " (" + Sig(total, 2) + " s of test time)" +
               (not_built.empty() ? std::string() : "; not built: " + not_built));
  ctx.Summary(std::to_string(cases.size()) + " cases in " + Sig(total, 2) + " s",
              (failed == 0 ? "every case within its pass line"
                           : std::to_string(failed) + " cases outside their pass lines") +
                  (not_built.empty() ? std::string() : "; not built: " + not_built));
  if (failed > 0) throw std::runtime_error(std::to_string(failed) + " hard cases failed");
}

}  // namespace spidarcad::app
