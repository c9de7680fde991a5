// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#include "cli/report_common.h"

#include <cmath>
#include <cstdio>
#include <fstream>
#include <stdexcept>

namespace spidarcad::app {

ReportContext::ReportContext(const ReportSettings& settings, std::function<void(double)> progress)
    : settings_(settings), progress_(std::move(progress)) {}

void ReportContext::Figure(const std::string& name, const std::vector<Chart>& charts,
                           const std::string& caption, int width, int height) {
  const std::string file = name + ".png";
  if (!settings_.plots) {
    markdown_ << "\n*Figure " << file << " skipped (no X display).* " << caption << "\n\n";
    return;
  }
  try {
    WriteChartsPng(charts, settings_.out_dir + "/" + file, width, height);
    files_.push_back(file);
    markdown_ << "\n![" << name << "](" << settings_.link_prefix << file << ")\n\n*" << caption
              << "*\n\n";
  } catch (const std::exception& e) {
    markdown_ << "\n*Figure " << file << " failed: " << e.what() << "* " << caption << "\n\n";
  }
}

std::string ReportContext::MapFigure(const std::string& name, const ColourMap& map, int width,
                                     int height) {
  const std::string file = name + ".png";
  if (!settings_.plots) return "*(" + file + " skipped: no X display)*";
  try {
    WriteColourMapPng(map, settings_.out_dir + "/" + file, width, height);
    files_.push_back(file);
    return "![" + name + "](" + settings_.link_prefix + file + ")";
  } catch (const std::exception& e) {
    return std::string("*(") + file + " failed: " + e.what() + ")*";
  }
}

void ReportContext::Csv(const std::string& name, const std::vector<std::string>& header,
                        const std::vector<std::vector<std::string>>& rows) {
  const std::string file = name + ".csv";
  std::ofstream out(settings_.out_dir + "/" + file);
  if (!out) throw std::runtime_error("cannot write " + settings_.out_dir + "/" + file);
  auto line = [&](const std::vector<std::string>& fields) {
    for (size_t i = 0; i < fields.size(); ++i) out << (i ? "," : "") << fields[i];
    out << '\n';
  };
  line(header);
  for (const auto& row : rows) line(row);
  if (!out) throw std::runtime_error("error while writing " + settings_.out_dir + "/" + file);
  files_.push_back(file);
  markdown_ << "Data: [" << file << "](" << settings_.link_prefix << file << ").\n\n";
}

void ReportContext::Table(const std::vector<std::string>& header,
                          const std::vector<std::vector<std::string>>& rows) {
  auto line = [&](const std::vector<std::string>& fields) {
    markdown_ << '|';
    for (const std::string& f : fields) markdown_ << ' ' << f << " |";
    markdown_ << '\n';
  };
  markdown_ << '\n';
  line(header);
  markdown_ << '|';
  for (size_t i = 0; i < header.size(); ++i) markdown_ << "---|";
  markdown_ << '\n';
  for (const auto& row : rows) line(row);
  markdown_ << '\n';
}

std::string Sig(double v, int digits) {
  if (std::isnan(v)) return "n/a";
  char buffer[64];
  std::snprintf(buffer, sizeof buffer, "%.*g", digits, v);
  return buffer;
}

std::string Fixed(double v, int decimals) {
  if (std::isnan(v)) return "n/a";
  char buffer[64];
  std::snprintf(buffer, sizeof buffer, "%.*f", decimals, v);
  return buffer;
}

double MedianSeconds(int repeats, const std::function<void()>& work) {
  std::vector<double> times;
  for (int r = 0; r < std::max(1, repeats); ++r) {
    const auto start = std::chrono::steady_clock::now();
    work();
    times.push_back(SecondsSince(start));
  }
  return Median(times);
}

double Median(std::vector<double> values) { return Quantile(std::move(values), 0.5); }

double Quantile(std::vector<double> values, double p) {
  if (values.empty()) return NAN;
  const double rank = std::ceil(std::clamp(p, 0.0, 1.0) * values.size());
  const size_t k = std::min(values.size() - 1, static_cast<size_t>(std::max(1.0, rank)) - 1);
  std::nth_element(values.begin(), values.begin() + k, values.end());
  return values[k];
}

}  // namespace spidarcad::app
