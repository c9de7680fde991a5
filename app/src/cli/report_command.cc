// `spidarcad report --out DIR [--quick] [--only a,b]`: runs the performance sweeps in-process
// and writes DIR/report.md with PNG charts, CSV data and a stamp (commit, build type, CPU,
// cores, date).
// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <ctime>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <memory>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include "cli/cli_common.h"
#include "cli/commands.h"
#include "cli/plot.h"
#include "cli/report_common.h"
#include "cli/report_sections.h"
#include "spidarcad/fem/blas_kernels.h"
#include "spidarcad_git_stamp.h"  // SPIDARCAD_GIT_COMMIT, generated at build time
#ifndef SPIDARCAD_BUILD_TYPE
#define SPIDARCAD_BUILD_TYPE "unknown"
#endif

namespace spidarcad::app {

const std::vector<ReportSection>& ReportSections() {
  static const std::vector<ReportSection> sections = {
      {"fk", "Forward kinematics", ReportForwardKinematics},
      {"singular", "FK conditioning and singular set", ReportSingularSet},
      {"tensions", "Tension distribution", ReportTensions},
      {"calibration", "Calibration", ReportCalibration},
      {"workspace", "Workspace", ReportWorkspace},
      {"implicit", "Implicit evaluation", ReportImplicit},
      {"surface", "Surface meshing", ReportSurfaceMeshing},
      {"tets", "Tetrahedral meshing", ReportTetMeshing},
      {"fe", "Finite elements", ReportFe},
      {"edit", "Edit to felt force", ReportEditToForce},
      {"tick", "Haptic tick per scene", ReportTick},
      {"sculpt", "Sculpting", ReportSculpt},
      {"hard", "Hard cases", ReportHardCases},
  };
  return sections;
}

namespace {

constexpr const char* kReportHelp =
    "Runs the performance sweeps of every part of the system in this process (no benchmark\n"
    "output is parsed) and writes DIR/report.md: a stamp (commit, build type, CPU model, core\n"
    "count, UTC date), a summary table with one headline row per section (paste it into the\n"
    "README), then each section's tables and PNG charts (speed against error, log axes), and\n"
    "its data as CSV files beside it.\n"
    "\n"
    "Sections (names for --only): fk, singular, tensions, calibration, workspace, implicit,\n"
    "surface, tets, fe, edit, tick, sculpt, hard. `edit` times the first correct felt force after\n"
    "an edit of the platform (slab route) against a full recompute. `hard` runs every\n"
    "Hard<Thing> test case of the build tree's test executables (build/tests/*_tests) and\n"
    "tabulates each measured figure against its pass line; it is skipped, saying so, where they\n"
    "are not built.\n"
    "\n"
    "DIR/summary.md is the short table of headline figures (one row per part: speed and\n"
    "error, with units) that scripts/update-readme-figures.sh DIR copies into README.md.\n"
    "--markdown FILE writes the report itself to FILE instead (its chart and CSV links point\n"
    "into DIR): the project's docs/performance.md is made that way.\n"
    "\n"
    "Progress goes to stderr, one line per section. --quick runs smaller sweeps (a few\n"
    "minutes on a 2-core machine); the full report takes what it needs (tens of minutes).\n"
    "\n"
    "The charts need an X display. Without one the command runs itself again under\n"
    "`xvfb-run -a` when xvfb-run is installed; otherwise it writes the tables only and says so.\n"
    "Timings are medians over repeats of the steady clock; errors are measured against\n"
    "independent references (true poses, closed forms, exact distance functions, a brute-force\n"
    "optimum).\n"
    "\n"
    "Examples:\n"
    "  spidarcad report --out report --quick\n"
    "  spidarcad report --out docs/report --markdown docs/performance.md\n"
    "  spidarcad report --out /tmp/r --quick --only fk,tensions";

struct ReportOptions {
  std::string out_dir;
  std::string markdown;  // --markdown: the report's path ("": DIR/report.md)
  bool quick = false;
  std::string only;
  bool no_plots = false;
};

std::string Trim(const std::string& s) {
  const size_t a = s.find_first_not_of(" \t\n");
  if (a == std::string::npos) return "";
  return s.substr(a, s.find_last_not_of(" \t\n") - a + 1);
}

std::string CpuModel() {
  std::ifstream in("/proc/cpuinfo");
  std::string line;
  while (std::getline(in, line)) {
    if (line.rfind("model name", 0) == 0) {
      const size_t colon = line.find(':');
      if (colon != std::string::npos) return Trim(line.substr(colon + 1));
    }
  }
  return "unknown";
}

// The first three fields of /proc/loadavg: other work on the machine inflates wall-clock times.
std::string LoadAverage() {
  std::ifstream in("/proc/loadavg");
  std::string a, b, c;
  if (!(in >> a >> b >> c)) return "unknown";
  return a + ", " + b + ", " + c;
}

std::string UtcNow() {
  const std::time_t now = std::time(nullptr);
  std::tm tm{};
  gmtime_r(&now, &tm);
  char buffer[64];
  std::strftime(buffer, sizeof buffer, "%Y-%m-%d %H:%M UTC", &tm);
  return buffer;
}

// The stamp lines of the report (markdown table rows).
std::vector<std::pair<std::string, std::string>> Stamp(const ReportOptions& o) {
  // The commit of the checkout at the last build (cmake/git_stamp.cmake).
  return {{"commit", SPIDARCAD_GIT_COMMIT},
          {"build type", SPIDARCAD_BUILD_TYPE},
          {"CPU", CpuModel()},
          {"cores", std::to_string(std::thread::hardware_concurrency())},
          {"BLAS", fem::BlasKernelDescription()},
          {"load average at the start (1, 5, 15 min)", LoadAverage()},
          {"date", UtcNow()},
          {"mode", o.quick ? "--quick" : "full"}};
}

// Re-executes this process under xvfb-run (no return on success). False when impossible.
bool ReexecUnderXvfb() {
  if (std::getenv("SPIDARCAD_REPORT_UNDER_XVFB") != nullptr) return false;
  std::string xvfb;
  if (const char* path = std::getenv("PATH")) {
    std::stringstream dirs(path);
    std::string dir;
    while (std::getline(dirs, dir, ':')) {
      const std::string candidate = (dir.empty() ? "." : dir) + "/xvfb-run";
      if (access(candidate.c_str(), X_OK) == 0) {
        xvfb = candidate;
        break;
      }
    }
  }
  if (xvfb.empty()) return false;
  std::error_code error;
  const std::string self = std::filesystem::read_symlink("/proc/self/exe", error).string();
  if (error) return false;
  std::ifstream cmdline("/proc/self/cmdline", std::ios::binary);
  std::vector<std::string> args;
  std::string arg;
  while (std::getline(cmdline, arg, '\0')) args.push_back(arg);
  if (args.empty()) return false;
  std::vector<std::string> full = {xvfb, "-a", "-s", "-screen 0 1280x1024x24", self};
  full.insert(full.end(), args.begin() + 1, args.end());
  std::vector<char*> argv;
  for (std::string& a : full) argv.push_back(a.data());
  argv.push_back(nullptr);
  setenv("SPIDARCAD_REPORT_UNDER_XVFB", "1", 1);
  std::cerr << "spidarcad report: no X display; running again under " << xvfb << "\n";
  std::fflush(stdout);
  execv(xvfb.c_str(), argv.data());
  return false;  // exec failed
}

// Progress on stderr: "[ 3/10] tensions  [#####.....]  50 %  12 s" redrawn on a terminal,
// one line per section otherwise.
class ProgressBar {
 public:
  ProgressBar(int index, int count, const std::string& name)
      : index_(index),
        count_(count),
        name_(name),
        tty_(isatty(2) != 0),
        start_(std::chrono::steady_clock::now()) {
    if (!tty_) {
      std::fprintf(stderr, "[%2d/%d] %s ...\n", index_, count_, name_.c_str());
      std::fflush(stderr);
    }
    Update(0.0);
  }
  void Update(double fraction) {
    if (!tty_) return;
    const auto now = std::chrono::steady_clock::now();
    if (fraction < 1.0 && fraction > 0.0 && now - last_ < std::chrono::milliseconds(200)) return;
    last_ = now;
    constexpr int kWidth = 30;
    const int filled = static_cast<int>(std::lround(fraction * kWidth));
    std::fprintf(stderr, "\r[%2d/%d] %-12s [%s%s] %3d %%  %5.0f s", index_, count_, name_.c_str(),
                 std::string(filled, '#').c_str(), std::string(kWidth - filled, '.').c_str(),
                 static_cast<int>(std::lround(100 * fraction)), SecondsSince(start_));
    std::fflush(stderr);
  }
  void Done(const std::string& note) {
    Update(1.0);
    if (tty_) {
      std::fprintf(stderr, "  %s\n", note.c_str());
    } else {
      std::fprintf(stderr, "[%2d/%d] %s %s in %.0f s\n", index_, count_, name_.c_str(),
                   note.c_str(), SecondsSince(start_));
    }
    std::fflush(stderr);
  }

 private:
  int index_, count_;
  std::string name_;
  bool tty_;
  std::chrono::steady_clock::time_point start_, last_{};
};

std::vector<const ReportSection*> SelectSections(const std::string& only) {
  const std::vector<ReportSection>& all = ReportSections();
  std::vector<const ReportSection*> chosen;
  if (Trim(only).empty()) {
    for (const ReportSection& s : all) chosen.push_back(&s);
    return chosen;
  }
  std::string valid;
  for (const ReportSection& s : all) valid += (valid.empty() ? "" : ", ") + s.name;
  std::vector<std::string> names;
  std::stringstream in(only);
  std::string name;
  while (std::getline(in, name, ',')) {
    name = Trim(name);
    if (name.empty()) continue;
    const auto it = std::find_if(all.begin(), all.end(),
                                 [&](const ReportSection& s) { return s.name == name; });
    if (it == all.end()) {
      throw InputError("--only: unknown section '" + name + "'; valid names: " + valid);
    }
    names.push_back(name);
  }
  if (names.empty()) throw InputError("--only: no section named; valid names: " + valid);
  for (const ReportSection& s : all) {  // report order, each once
    if (std::find(names.begin(), names.end(), s.name) != names.end()) chosen.push_back(&s);
  }
  return chosen;
}

// One row of DIR/summary.md.
struct SummaryRow {
  std::string part, speed, error;
};

// Writes DIR/summary.md: a stamp line and the table of headline figures (the README's block
// The command that made the report, as the user would type it again.
std::string CommandLine(const ReportOptions& options) {
  std::string line = "spidarcad report --out " + options.out_dir;
  if (!options.markdown.empty()) line += " --markdown " + options.markdown;
  if (options.quick) line += " --quick";
  if (!Trim(options.only).empty()) line += " --only " + options.only;
  return line;
}

// The prefix that makes a file name in DIR a link from the report at `markdown` ("" when the
// report is DIR/report.md), e.g. "report/" for --out docs/report --markdown docs/performance.md.
std::string LinkPrefix(const ReportOptions& options) {
  if (options.markdown.empty()) return "";
  namespace fs = std::filesystem;
  const fs::path from = fs::weakly_canonical(fs::absolute(options.markdown)).parent_path();
  const fs::path to = fs::weakly_canonical(fs::absolute(options.out_dir));
  const std::string rel = to.lexically_relative(from).generic_string();
  if (rel.empty() || rel == ".") return "";
  return rel + "/";
}

// between the report-summary markers; scripts/update-readme-figures.sh copies it there). No
// links: the file is read from DIR and from the README's directory alike.
void WriteSummary(const ReportOptions& options,
                  const std::vector<std::pair<std::string, std::string>>& stamp,
                  const std::vector<SummaryRow>& rows) {
  auto field = [&](const std::string& key) {
    for (const auto& [k, v] : stamp)
      if (k == key) return v;
    return std::string();
  };
  std::string commit = field("commit");
  commit = commit.substr(0, commit.find(' '));
  std::ostringstream md;
  md << "Measured by `" << CommandLine(options) << "` on " << field("date") << ", commit " << commit
     << ", " << field("build type") << ", " << field("CPU") << " (" << field("cores")
     << " cores, load " << field("load average at the start (1, 5, 15 min)") << ").\n\n";
  md << "| part | speed | error |\n|---|---|---|\n";
  for (const SummaryRow& r : rows) {
    auto cell = [](std::string text) {
      for (char& c : text)
        if (c == '|' || c == '\n') c = ' ';
      return text.empty() ? std::string("—") : text;
    };
    md << "| " << cell(r.part) << " | " << cell(r.speed) << " | " << cell(r.error) << " |\n";
  }
  const std::string path = options.out_dir + "/summary.md";
  const std::string tmp = path + ".tmp";
  {
    std::ofstream out(tmp);
    out << md.str();
    if (!out) throw std::runtime_error("cannot write " + tmp);
  }
  std::filesystem::rename(tmp, path);
}

void RunReport(const ReportOptions& options) {
  const std::vector<const ReportSection*> sections = SelectSections(options.only);
  if (options.out_dir.empty()) throw InputError("--out: give the directory to write");
  std::error_code error;
  std::filesystem::create_directories(options.out_dir, error);
  if (error || !std::filesystem::is_directory(options.out_dir)) {
    throw InputError("--out: cannot create directory '" + options.out_dir +
                     "': " + error.message());
  }
  ReportSettings settings;
  settings.out_dir = options.out_dir;
  settings.link_prefix = LinkPrefix(options);
  settings.quick = options.quick;
  settings.plots = !options.no_plots && PlotDisplayAvailable();
  if (!options.no_plots && !settings.plots) {
    ReexecUnderXvfb();  // returns only when it cannot
    std::cerr << "spidarcad report: no X display and no xvfb-run: writing tables only (install "
                 "xvfb, or run under xvfb-run -a, for the charts)\n";
  }
  const auto stamp =
      Stamp(options);  // before the run: the load average of the machine's other work
  const auto start = std::chrono::steady_clock::now();
  struct Done {
    const ReportSection* section;
    std::string headline, body, speed, error;
    double seconds;
    bool failed;
  };
  std::vector<Done> done;
  int index = 0;
  for (const ReportSection* section : sections) {
    ProgressBar bar(++index, static_cast<int>(sections.size()), section->name);
    ReportContext ctx(settings, [&bar](double f) { bar.Update(f); });
    const auto section_start = std::chrono::steady_clock::now();
    bool failed = false;
    try {
      section->run(ctx);
    } catch (const std::exception& e) {
      failed = true;
      ctx.md() << "\n**This section failed:** " << e.what() << "\n";
      ctx.Headline(std::string("failed: ") + e.what());
    }
    const double seconds = SecondsSince(section_start);
    bar.Done(failed ? "FAILED" : "done");
    done.push_back({section, ctx.headline(), ctx.body(), ctx.summary_speed(), ctx.summary_error(),
                    seconds, failed});
  }
  const double total = SecondsSince(start);

  std::ostringstream md;
  md << "# spidarcad performance report\n\n"
     << "Generated by `" << CommandLine(options)
     << "`. Every figure below was measured in that run; the charts plot speed against error "
        "on log axes wherever both exist. Times are wall clock (steady clock, medians over "
        "repeats): on a shared machine other work inflates them (see the load average).\n\n";
  md << "| stamp | |\n|---|---|\n";
  for (const auto& [key, value] : stamp) md << "| " << key << " | " << value << " |\n";
  md << "| report wall time | " << Fixed(total, 0) << " s |\n\n";
  if (!settings.plots) {
    md << "**The charts were not drawn (" << (options.no_plots ? "--no-plots" : "no X display")
       << "): tables only.**\n\n";
  }
  md << "## Summary\n\n| part | headline figures | section time |\n|---|---|---|\n";
  for (const Done& d : done) {
    md << "| [" << d.section->title << "](#" << d.section->name << ") | " << d.headline << " | "
       << Fixed(d.seconds, 0) << " s |\n";
  }
  md << "\n";
  for (const Done& d : done) {
    md << "<a id=\"" << d.section->name << "\"></a>\n\n## " << d.section->title << "\n\n"
       << d.body << "\n";
  }
  const std::string path =
      options.markdown.empty() ? options.out_dir + "/report.md" : options.markdown;
  const std::string tmp = path + ".tmp";
  {
    std::ofstream out(tmp);
    out << md.str();
    if (!out) throw std::runtime_error("cannot write " + tmp);
  }
  std::filesystem::rename(tmp, path);
  std::cout << "wrote " << path << " (" << done.size() << " sections, " << Fixed(total, 0)
            << " s)\n"
            << std::flush;
  WriteSummary(options, stamp, [&] {
    std::vector<SummaryRow> rows;
    for (const Done& d : done) {
      rows.push_back(
          {d.section->title, d.failed ? "failed" : d.speed, d.failed ? d.headline : d.error});
    }
    return rows;
  }());
  const bool any_failed =
      std::any_of(done.begin(), done.end(), [](const Done& d) { return d.failed; });
  throw CommandExit{any_failed ? 1 : 0};
}

}  // namespace

void RegisterReportCommand(CLI::App& app) {
  auto options = std::make_shared<ReportOptions>();
  CLI::App* cmd = app.add_subcommand(
      "report", "Performance report: speed against error of every part (markdown, PNG, CSV)");
  cmd->footer(kReportHelp);
  cmd->add_option("--out", options->out_dir, "Directory to write report.md, PNGs and CSVs into")
      ->required()
      ->type_name("DIR");
  cmd->add_option("--markdown", options->markdown,
                  "Write the report's markdown to FILE instead of DIR/report.md; its links to the "
                  "charts and CSVs in DIR are made relative to FILE")
      ->type_name("FILE");
  cmd->add_flag("--quick", options->quick, "Smaller sweeps: a few minutes on a 2-core machine");
  cmd->add_option("--only", options->only,
                  "Comma-separated sections to run (fk, singular, tensions, calibration, "
                  "workspace, implicit, surface, tets, fe, edit, tick, sculpt, hard); default all")
      ->type_name("LIST");
  cmd->add_flag("--no-plots", options->no_plots,
                "Tables and CSVs only: draw no chart (no X display needed)");
  cmd->callback([options]() { RunReport(*options); });
}

}  // namespace spidarcad::app
