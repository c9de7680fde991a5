// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
// Golden-result comparison for the headless regression runs (tests/app/regression_test.cc):
// numeric CSV tables (a header line naming the columns, '#' comment lines allowed), compared
// column by column with an absolute tolerance per signal. A failed comparison says which signal
// diverged, at which row and time, the expected and actual values and by how much (and how many
// rows of that signal are out of tolerance, and the worst difference).
// Header-only (inline): tests/app globs only *_test.cc files.
#pragma once

#include <charconv>
#include <cmath>
#include <cstdlib>
#include <fstream>
#include <sstream>
#include <stdexcept>
#include <string>
#include <system_error>
#include <vector>

namespace spidarcad::test_support {

// A numeric table: named columns, rows of numbers (NaN allowed, written "nan").
struct CsvTable {
  std::vector<std::string> columns;
  std::vector<std::vector<double>> rows;  // each rows[i].size() == columns.size()
  // Index of the column named `name`, or -1.
  int Column(const std::string& name) const {
    for (std::size_t i = 0; i < columns.size(); ++i) {
      if (columns[i] == name) return static_cast<int>(i);
    }
    return -1;
  }
};

// Splits a line at commas.
inline std::vector<std::string> SplitCsvLine(const std::string& line) {
  std::vector<std::string> fields;
  std::string field;
  std::stringstream in(line);
  while (std::getline(in, field, ',')) fields.push_back(field);
  if (!line.empty() && line.back() == ',') fields.emplace_back();
  return fields;
}

// The lines of a CSV file (a header line first) with the columns named in `dropped` removed
// (as the header names them), each line's fields joined by commas again: for comparing two
// runs' outputs byte for byte but for their wall-clock columns. Empty when the file is missing.
inline std::vector<std::string> CsvLinesWithout(const std::string& path,
                                                const std::vector<std::string>& dropped) {
  std::ifstream in(path);
  std::string line;
  std::vector<std::string> lines;
  std::vector<bool> keep;
  while (std::getline(in, line)) {
    const std::vector<std::string> fields = SplitCsvLine(line);
    if (keep.empty()) {
      for (const std::string& f : fields) {
        bool drop = false;
        for (const std::string& d : dropped) drop = drop || f == d;
        keep.push_back(!drop);
      }
    }
    std::string joined;
    for (std::size_t i = 0; i < fields.size(); ++i) {
      if (i < keep.size() && !keep[i]) continue;
      joined += (joined.empty() ? "" : ",") + fields[i];
    }
    lines.push_back(joined);
  }
  return lines;
}

// Parses a table; `source` names it in errors. Throws std::runtime_error naming the source,
// line and column of a field that is not a number or a row of the wrong length.
inline CsvTable ParseCsvTable(std::istream& in, const std::string& source) {
  CsvTable table;
  std::string line;
  int line_number = 0;
  bool have_header = false;
  while (std::getline(in, line)) {
    ++line_number;
    if (line.empty() || line[0] == '#') continue;
    std::vector<std::string> fields = SplitCsvLine(line);
    if (!have_header) {
      table.columns = fields;
      have_header = true;
      continue;
    }
    if (fields.size() != table.columns.size()) {
      throw std::runtime_error(source + ":" + std::to_string(line_number) + ": " +
                               std::to_string(fields.size()) + " fields, the header has " +
                               std::to_string(table.columns.size()));
    }
    std::vector<double> row(fields.size());
    for (std::size_t i = 0; i < fields.size(); ++i) {
      const std::string& f = fields[i];
      char* end = nullptr;
      row[i] = std::strtod(f.c_str(), &end);
      if (f.empty() || end != f.c_str() + f.size()) {
        throw std::runtime_error(source + ":" + std::to_string(line_number) + ": field '" +
                                 table.columns[i] + "': '" + f + "' is not a number");
      }
    }
    table.rows.push_back(std::move(row));
  }
  if (!have_header) throw std::runtime_error(source + ": no header line");
  return table;
}

// Reads a table file. Throws std::runtime_error when it cannot be read or parsed.
inline CsvTable ReadCsvTable(const std::string& path) {
  std::ifstream in(path);
  if (!in) throw std::runtime_error(path + ": cannot read");
  return ParseCsvTable(in, path);
}

// Shortest text that reads back to exactly v ("nan" for NaN).
inline std::string ShortestNumber(double v) {
  if (std::isnan(v)) return "nan";
  char buffer[64];
  const auto result = std::to_chars(buffer, buffer + sizeof(buffer), v);
  return std::string(buffer, result.ptr);
}

// Writes a table with `comment` lines (each prefixed "# ") first. Throws on failure.
inline void WriteCsvTable(const CsvTable& table, const std::string& path,
                          const std::vector<std::string>& comment) {
  std::ofstream out(path);
  if (!out) throw std::runtime_error(path + ": cannot write");
  for (const std::string& c : comment) out << "# " << c << "\n";
  for (std::size_t i = 0; i < table.columns.size(); ++i) out << (i ? "," : "") << table.columns[i];
  out << "\n";
  for (const auto& row : table.rows) {
    for (std::size_t i = 0; i < row.size(); ++i) out << (i ? "," : "") << ShortestNumber(row[i]);
    out << "\n";
  }
  if (!out) throw std::runtime_error(path + ": failed writing");
}

// Every `every`-th row (0, every, 2·every, ... and the last row) and only the named columns,
// in that order. Throws std::runtime_error for a missing column or every < 1.
inline CsvTable Decimate(const CsvTable& table, int every, const std::vector<std::string>& keep) {
  if (every < 1) throw std::runtime_error("Decimate: every must be >= 1");
  CsvTable out;
  std::vector<int> index;
  for (const std::string& name : keep) {
    const int c = table.Column(name);
    if (c < 0) throw std::runtime_error("Decimate: no column '" + name + "'");
    index.push_back(c);
    out.columns.push_back(name);
  }
  for (std::size_t r = 0; r < table.rows.size(); ++r) {
    if (r % every != 0 && r + 1 != table.rows.size()) continue;
    std::vector<double> row;
    for (int c : index) row.push_back(table.rows[r][c]);
    out.rows.push_back(std::move(row));
  }
  return out;
}

// Absolute tolerance of one signal (column), with its unit for messages.
struct SignalTolerance {
  std::string column;
  double tolerance = 0.0;
  std::string unit;
};

// The first row where a signal left its tolerance, with totals for that signal.
struct Divergence {
  std::string column;
  std::string unit;
  std::size_t row = 0;  // 0-based data row of the first divergence
  double time = NAN;    // the row's "t" (NaN when the table has no t column)
  double expected = 0.0;
  double actual = 0.0;
  double difference = 0.0;  // |actual − expected| (inf when one side is NaN)
  double tolerance = 0.0;
  std::size_t rows_over = 0;    // rows of this signal out of tolerance
  double max_difference = 0.0;  // worst |actual − expected| of this signal
};

// Result of CompareToGolden.
struct GoldenComparison {
  std::vector<std::string> structural;  // missing columns, different row counts
  std::vector<Divergence> divergences;  // one per diverging signal, in tolerance-list order
  bool ok() const { return structural.empty() && divergences.empty(); }
  // Human-readable report of every problem ("" when ok).
  std::string Report() const {
    std::ostringstream os;
    os.precision(10);
    for (const std::string& s : structural) os << s << "\n";
    for (const Divergence& d : divergences) {
      os << "signal '" << d.column << "' diverged at row " << d.row << " (t = " << d.time
         << " s): expected " << d.expected << ", actual " << d.actual << ", off by " << d.difference
         << " " << d.unit << " (tolerance " << d.tolerance << " " << d.unit << "); " << d.rows_over
         << " rows out of tolerance, worst " << d.max_difference << " " << d.unit << "\n";
    }
    return os.str();
  }
};

// Compares `actual` with `golden` row by row on the listed signals: |a − e| <= tolerance, NaN
// matching only NaN. Rows are matched by index (both tables decimated the same way).
inline GoldenComparison CompareToGolden(const CsvTable& golden, const CsvTable& actual,
                                        const std::vector<SignalTolerance>& signals) {
  GoldenComparison result;
  if (golden.rows.size() != actual.rows.size()) {
    result.structural.push_back("row count: golden has " + std::to_string(golden.rows.size()) +
                                " rows, actual " + std::to_string(actual.rows.size()));
  }
  const std::size_t rows = std::min(golden.rows.size(), actual.rows.size());
  const int t_column = actual.Column("t");
  for (const SignalTolerance& s : signals) {
    const int ge = golden.Column(s.column), ac = actual.Column(s.column);
    if (ge < 0 || ac < 0) {
      result.structural.push_back("signal '" + s.column + "' missing from the " +
                                  (ge < 0 ? "golden" : "actual") + " table");
      continue;
    }
    Divergence d;
    for (std::size_t r = 0; r < rows; ++r) {
      const double e = golden.rows[r][ge], a = actual.rows[r][ac];
      double diff;
      if (std::isnan(e) || std::isnan(a)) {
        diff = std::isnan(e) && std::isnan(a) ? 0.0 : INFINITY;
      } else {
        diff = std::abs(a - e);
      }
      if (!(diff <= s.tolerance)) {
        if (d.rows_over == 0) {
          d.column = s.column;
          d.unit = s.unit;
          d.row = r;
          d.time = t_column >= 0 ? actual.rows[r][t_column] : NAN;
          d.expected = e;
          d.actual = a;
          d.difference = diff;
          d.tolerance = s.tolerance;
        }
        ++d.rows_over;
        d.max_difference = std::max(d.max_difference, diff);
      }
    }
    if (d.rows_over > 0) result.divergences.push_back(d);
  }
  return result;
}

}  // namespace spidarcad::test_support
