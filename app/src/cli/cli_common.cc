// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#include "cli/cli_common.h"

#include <charconv>
#include <cmath>
#include <cstdio>
#include <functional>
#include <sstream>

#include "spidarcad/modeling/feature_sharpening.h"

namespace spidarcad::app {

namespace {
std::string Trim(const std::string& s) {
  const auto begin = s.find_first_not_of(" \t\r");
  if (begin == std::string::npos) return "";
  const auto end = s.find_last_not_of(" \t\r");
  return s.substr(begin, end - begin + 1);
}
}  // namespace

void ForEachCsvRecord(std::istream& in, const std::string& source, int expected_fields,
                      const std::function<void(const std::vector<double>&, int)>& row) {
  std::string line;
  int line_number = 0;
  std::vector<double> values;
  while (std::getline(in, line)) {
    ++line_number;
    const std::string trimmed = Trim(line);
    if (trimmed.empty() || trimmed[0] == '#') continue;
    values.clear();
    std::stringstream fields(trimmed);
    std::string field;
    int column = 0;
    while (std::getline(fields, field, ',')) {
      ++column;
      const std::string f = Trim(field);
      double v = 0;
      const char* first = f.data();
      const char* last = f.data() + f.size();
      auto [ptr, ec] = std::from_chars(first, last, v);
      if (f == "nan" || f == "NaN") {
        v = std::nan("");
      } else if (f.empty() || ec != std::errc() || ptr != last) {
        throw InputError(source + ":" + std::to_string(line_number) + ": column " +
                         std::to_string(column) + ": '" + f + "' is not a number");
      }
      values.push_back(v);
    }
    if (expected_fields > 0 && static_cast<int>(values.size()) != expected_fields) {
      throw InputError(source + ":" + std::to_string(line_number) + ": expected " +
                       std::to_string(expected_fields) + " comma-separated numbers, found " +
                       std::to_string(values.size()));
    }
    row(values, line_number);
  }
}

void AddGeometryOptions(CLI::App& command, haptics::SpidarGeometry* geometry, bool* given) {
  command
      .add_option_function<std::vector<double>>(
          "--frame",
          [geometry, given](const std::vector<double>& v) {
            geometry->a = v[0];
            geometry->b = v[1];
            geometry->c = v[2];
            if (given != nullptr) *given = true;
          },
          "Frame half-sides A,B,C in metres (default 0.24,0.24,0.24: the paper's 48 cm frame)")
      ->delimiter(',')
      ->expected(3);
  command.add_option_function<double>(
      "--pole",
      [geometry, given](double d) {
        geometry->d = d;
        if (given != nullptr) *given = true;
      },
      "Pole half-length D in metres (default 0.04: the paper's 4 cm grip)");
}

bool LatticeMesherOption(const std::string& mesher, const char* default_route) {
  if (!mesher.empty() && mesher != "lattice" && mesher != "tetrahedra")
    throw InputError("--mesher '" + mesher + "': give lattice or tetrahedra (the default is " +
                     default_route + ")");
  return mesher == "lattice";
}

void CheckFlatCellsOption(double flat_cells, bool lattice) {
  if (!(flat_cells >= 0.0 && flat_cells <= 1.0))
    throw InputError("--flat-cells " + FormatNumber(flat_cells) +
                     ": give a fraction of the cell in [0, 1] (0, the default, turns it off)");
  if (flat_cells > 0.0 && lattice)
    throw InputError(
        "--flat-cells coarsens the marching-tetrahedra surface; the lattice surface has no "
        "clean-up pass: drop one of --flat-cells and --mesher lattice");
}

void ValidateGeometry(const haptics::SpidarGeometry& geometry) {
  try {
    geometry.Validate();
  } catch (const std::invalid_argument& e) {
    throw InputError(std::string("--frame/--pole: ") + e.what());
  }
}

std::string VolumeOffWarning(double off, double cell, const std::string& way_out) {
  if (!(std::abs(off) > modeling::kSharpVolumeRetry)) return "";
  char percent[32];
  std::snprintf(percent, sizeof percent, "%.3g", 100.0 * std::abs(off));
  return std::string("warning: the mesh holds ") + percent + " % " + (off < 0.0 ? "less" : "more") +
         " volume than the solid: a part about a cell thick or thinner can fall between the "
         "grid's planes at --resolution " +
         FormatNumber(cell) + "; " + way_out + "\n";
}

}  // namespace spidarcad::app
