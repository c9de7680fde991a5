// The framework of `spidarcad report`: a section writes markdown, CSV tables and PNG charts
// into the report directory through a ReportContext, and adds one headline row to the summary
// table. Sections are plain functions listed in a registry (ReportSections); adding one is a
// new function and a line in the registry.
// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#pragma once

#include <algorithm>
#include <chrono>
#include <functional>
#include <sstream>
#include <string>
#include <vector>

#include "cli/report_plot.h"

namespace spidarcad::app {

// What one report run was asked for.
struct ReportSettings {
  std::string out_dir;      // where report.md, the PNGs and the CSVs go
  std::string link_prefix;  // prepended to the report's links to those files ("" or "DIR/")
  bool quick = false;       // smaller sweeps (the whole report in minutes on 2 cores)
  bool plots = true;        // false: no X display, tables only
};

// The section's view of the report: its markdown body, its files, its progress and headline.
class ReportContext {
 public:
  // `progress(fraction)` is called by Progress with the section's fraction done in [0, 1].
  ReportContext(const ReportSettings& settings, std::function<void(double)> progress);

  // True for --quick.
  bool quick() const { return settings_.quick; }
  // `quick_value` under --quick, else `full_value`.
  template <class T>
  T Pick(const T& quick_value, const T& full_value) const {
    return settings_.quick ? quick_value : full_value;
  }
  // The section's markdown body (after its heading).
  std::ostringstream& md() { return markdown_; }
  // Writes `charts` side by side to DIR/<name>.png and embeds it with `caption`; without a
  // display writes the caption and says the figure was skipped. Sizes in pixels.
  void Figure(const std::string& name, const std::vector<Chart>& charts, const std::string& caption,
              int width = 1500, int height = 560);
  // Writes a colour map to DIR/<name>.png and returns the markdown image link (or a note).
  std::string MapFigure(const std::string& name, const ColourMap& map, int width = 620,
                        int height = 520);
  // Writes DIR/<name>.csv (header and rows of already formatted fields) and links it.
  void Csv(const std::string& name, const std::vector<std::string>& header,
           const std::vector<std::vector<std::string>>& rows);
  // Appends a markdown table to the body.
  void Table(const std::vector<std::string>& header,
             const std::vector<std::vector<std::string>>& rows);
  // The section's row of the summary table at the top of report.md (one sentence of figures).
  void Headline(const std::string& text) { headline_ = text; }
  // The section's row of DIR/summary.md (the README's table): its headline speed and error
  // figures, each a few words with units ("1.2 µs per pose", "0.3 mm mean position error").
  void Summary(const std::string& speed, const std::string& error) {
    summary_speed_ = speed;
    summary_error_ = error;
  }
  // Reports the fraction of the section done, in [0, 1].
  void Progress(double fraction) const {
    if (progress_) progress_(std::clamp(fraction, 0.0, 1.0));
  }

  const std::string& headline() const { return headline_; }
  const std::string& summary_speed() const { return summary_speed_; }
  const std::string& summary_error() const { return summary_error_; }
  std::string body() const { return markdown_.str(); }
  // Files the section wrote (names relative to the report directory).
  const std::vector<std::string>& files() const { return files_; }
  const ReportSettings& settings() const { return settings_; }

 private:
  ReportSettings settings_;
  std::function<void(double)> progress_;
  std::ostringstream markdown_;
  std::string headline_;
  std::string summary_speed_, summary_error_;
  std::vector<std::string> files_;
};

// One section of the report: a short name for --only, a title, the function that runs it.
struct ReportSection {
  std::string name;   // e.g. "fk"
  std::string title;  // e.g. "Forward kinematics"
  std::function<void(ReportContext&)> run;
};

// Every section, in report order (report_command.cc).
const std::vector<ReportSection>& ReportSections();

// Formats v with `digits` significant digits ("%.*g"); "n/a" for NaN.
std::string Sig(double v, int digits = 3);
// Formats v with `decimals` decimals ("%.*f"); "n/a" for NaN.
std::string Fixed(double v, int decimals);

// Seconds since `start` (steady clock).
inline double SecondsSince(std::chrono::steady_clock::time_point start) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

// Median over `repeats` runs of the wall time of `work()`, s (steady clock).
double MedianSeconds(int repeats, const std::function<void()>& work);

// Median of a copy of `values` (NaN when empty).
double Median(std::vector<double> values);
// The p-quantile (p in [0, 1], nearest rank) of a copy of `values` (NaN when empty).
double Quantile(std::vector<double> values, double p);

}  // namespace spidarcad::app
