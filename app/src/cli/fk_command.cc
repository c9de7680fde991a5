// `spidarcad fk --batch` and `spidarcad ik --batch`: SPIDAR-G kinematics on CSV streams.
// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#include <charconv>
#include <cmath>
#include <iostream>
#include <memory>
#include <string>
#include <vector>

#include "cli/cli_common.h"
#include "cli/commands.h"
#include "spidarcad/haptics/kinematics.h"

namespace spidarcad::app {

namespace {

using haptics::FkResult;
using haptics::FkStatus;
using haptics::ForwardKinematics;
using haptics::GripPose;
using haptics::SpidarGeometry;
using haptics::Vector8d;

constexpr const char* kFrameHelp =
    "Units: metres and radians. Frame D: origin at the centre of the frame, corners at\n"
    "(±A, ±B, ±C) as the paper's Eq. 3: string i runs from corner Q_i to the grip,\n"
    "  Q1 = ( A, B, C)  Q2 = (-A, B, C)  Q3 = ( A,-B, C)  Q4 = (-A,-B, C)\n"
    "  Q5 = ( A, B,-C)  Q6 = (-A, B,-C)  Q7 = ( A,-B,-C)  Q8 = (-A,-B,-C)\n"
    "Strings are numbered 1..8 as in the paper. The grip is two poles of half-length D\n"
    "crossing at p0 = (x, y, z), with pole vectors p1 = (x1, y1, z1), p2 = (x2, y2, z2),\n"
    "|p1| = |p2| = D. Strings 1, 2 end at p0 + p1; 3, 4 at p0 - p1; 5, 7 at p0 + p2;\n"
    "6, 8 at p0 - p2. At rest p0 = 0, p1 = (0, D, 0), p2 = (D, 0, 0), grasp = pi/2.\n";

std::string Trim(const std::string& s) {
  const auto begin = s.find_first_not_of(" \t\r");
  if (begin == std::string::npos) return "";
  const auto end = s.find_last_not_of(" \t\r");
  return s.substr(begin, end - begin + 1);
}

// Parses one CSV data line into `values`. Returns an empty string on success, otherwise what
// was wrong (which column, which text).
std::string ParseLine(const std::string& line, int expected, std::vector<double>* values) {
  values->clear();
  std::size_t start = 0;
  int column = 0;
  while (true) {
    const std::size_t comma = line.find(',', start);
    const std::string field =
        Trim(line.substr(start, comma == std::string::npos ? std::string::npos : comma - start));
    ++column;
    double v = 0;
    if (field == "nan" || field == "NaN" || field == "NAN") {
      v = std::nan("");
    } else {
      const char* first = field.data();
      const char* last = field.data() + field.size();
      const auto [ptr, ec] = std::from_chars(first, last, v);
      if (field.empty() || ec != std::errc() || ptr != last) {
        return "column " + std::to_string(column) + ": '" + field + "' is not a number";
      }
    }
    values->push_back(v);
    if (comma == std::string::npos) break;
    start = comma + 1;
  }
  if (static_cast<int>(values->size()) != expected) {
    return "expected " + std::to_string(expected) + " comma-separated numbers, found " +
           std::to_string(values->size());
  }
  return "";
}

// Calls `row(line_number, values, error)` for every data line of `in` (blank lines and lines
// starting with '#' are skipped); `error` is empty when the line parsed.
template <typename Row>
void ForEachDataLine(std::istream& in, int expected, Row row) {
  std::string line;
  std::vector<double> values;
  int line_number = 0;
  while (std::getline(in, line)) {
    ++line_number;
    const std::string trimmed = Trim(line);
    if (trimmed.empty() || trimmed[0] == '#') continue;
    const std::string error = ParseLine(trimmed, expected, &values);
    row(line_number, values, error);
  }
}

struct KinematicsOptions {
  SpidarGeometry geometry;
  bool batch = false;
  bool no_header = false;
  double max_residual = haptics::FkSettings{}.max_residual;
  // --bound Q: length tolerance in m; with_bound says whether the option was given.
  double bound = 0;
  bool with_bound = false;
};

void RequireBatch(const KinematicsOptions& options, const char* name) {
  if (!options.batch) {
    throw InputError(std::string(name) +
                     ": only batch mode exists: pass --batch and feed CSV on stdin (see " + name +
                     " --help)");
  }
}

void RunFk(const KinematicsOptions& options) {
  RequireBatch(options, "fk");
  ValidateGeometry(options.geometry);
  if (!(options.max_residual > 0)) {
    throw InputError("fk: --max-residual must be a positive length in metres");
  }
  const bool with_bound = options.with_bound;
  if (with_bound && !(options.bound >= 0 && std::isfinite(options.bound))) {
    throw InputError(
        "fk: --bound must be a length tolerance >= 0 in metres (e.g. 1.2566e-5, "
        "half an encoder count), got " +
        FormatNumber(options.bound));
  }
  haptics::FkSettings settings;
  settings.max_residual = options.max_residual;
  // Lengths known to ±Q: no real error has an RMS above Q, so a second pose fitting within Q
  // could be the true one (FkStatus::kAmbiguous).
  if (with_bound) settings.branch_residual = options.bound;
  // Each line is solved from the closed form (Reset before every line): no warm start, so a
  // line's answer never depends on the lines before it.
  ForwardKinematics fk(options.geometry, settings);
  std::ostream& out = std::cout;
  if (!options.no_header) {
    out << "# x,y,z,x1,y1,z1,x2,y2,z2,grasp_rad,residual_m,status"
        << (with_bound ? ",bound_m\n" : "\n");
  }
  ForEachDataLine(
      std::cin, haptics::kNumStrings,
      [&](int line_number, const std::vector<double>& values, const std::string& error) {
        FkResult r;
        Vector8d lengths = Vector8d::Constant(std::nan(""));
        std::string problem = error;
        for (int k = 0; problem.empty() && k < haptics::kNumStrings; ++k) {
          if (!(values[k] > 0.0) || !std::isfinite(values[k])) {
            problem = "column " + std::to_string(k + 1) + " (l" + std::to_string(k + 1) +
                      "): " + FormatNumber(values[k]) +
                      " is not a positive finite length; write string lengths in metres";
          }
        }
        if (!problem.empty()) {
          std::cerr << "spidarcad fk: <stdin>:" << line_number << ": " << problem
                    << " (status invalid_input)\n";
          r = fk.Solve(Vector8d::Constant(std::nan("")));
        } else {
          fk.Reset();
          lengths = Eigen::Map<const Vector8d>(values.data());
          r = fk.Solve(lengths);
        }
        std::string text;
        for (const Eigen::Vector3d* v : {&r.pose.p0, &r.pose.p1, &r.pose.p2}) {
          for (int k = 0; k < 3; ++k) text += FormatNumber((*v)(k)) + ",";
        }
        text += FormatNumber(r.grasp) + "," + FormatNumber(r.residual) + "," +
                haptics::FkStatusName(r.status);
        if (with_bound) {
          const double bound =
              r.status == FkStatus::kOk
                  ? haptics::FkPositionBound(options.geometry, r.pose, lengths, options.bound)
                        .position
                  : std::nan("");
          text += "," + FormatNumber(bound);
        }
        text += "\n";
        out << text;
      });
  out.flush();
}

void RunIk(const KinematicsOptions& options) {
  RequireBatch(options, "ik");
  ValidateGeometry(options.geometry);
  const double d = options.geometry.d;
  std::ostream& out = std::cout;
  if (!options.no_header) out << "# l1,l2,l3,l4,l5,l6,l7,l8\n";
  ForEachDataLine(
      std::cin, 9,
      [&](int line_number, const std::vector<double>& values, const std::string& error) {
        Vector8d l = Vector8d::Constant(std::nan(""));
        std::string problem = error;
        static const char* const kNames[9] = {"x", "y", "z", "x1", "y1", "z1", "x2", "y2", "z2"};
        for (int k = 0; problem.empty() && k < 9; ++k) {
          if (!std::isfinite(values[k])) {
            problem = "column " + std::to_string(k + 1) + " (" + kNames[k] +
                      "): " + FormatNumber(values[k]) +
                      " is not a finite coordinate; write the pose in metres";
          }
        }
        if (!problem.empty()) {
          std::cerr << "spidarcad ik: <stdin>:" << line_number << ": " << problem
                    << " (lengths nan)\n";
        } else {
          Eigen::Matrix<double, 9, 1> v;
          for (int k = 0; k < 9; ++k) v(k) = values[k];
          const GripPose pose = GripPose::Unpacked(v);
          for (int k = 0; k < 2; ++k) {
            const double norm = (k == 0 ? pose.p1 : pose.p2).norm();
            if (std::abs(norm - d) > 1e-6) {
              std::cerr << "spidarcad ik: <stdin>:" << line_number << ": warning: |p" << k + 1
                        << "| = " << FormatNumber(norm) << " m differs from the pole half-length "
                        << FormatNumber(d) << " m; lengths computed for the points as given\n";
            }
          }
          l = haptics::InverseKinematics(options.geometry, pose);
        }
        std::string text;
        for (int i = 0; i < haptics::kNumStrings; ++i) {
          text += FormatNumber(l(i));
          text += i + 1 < haptics::kNumStrings ? "," : "\n";
        }
        out << text;
      });
  out.flush();
}

}  // namespace

void RegisterFkCommand(CLI::App& app) {
  auto options = std::make_shared<KinematicsOptions>();
  CLI::App* fk = app.add_subcommand(
      "fk", "Forward kinematics: 8 string lengths -> grip pose, grasp and residual (batch CSV)");
  fk->footer(
      std::string(
          "\nInput (stdin): one case per line, l1,l2,...,l8 (string lengths in m). Blank lines "
          "and\n"
          "lines starting with '#' are skipped.\n"
          "Output (stdout): first a header line starting with '#' (omit with --no-header), then\n"
          "exactly one line per input case, in order:\n"
          "  x,y,z,x1,y1,z1,x2,y2,z2,grasp_rad,residual_m,status\n"
          "p0 = (x,y,z) the grip centre, p1, p2 the pole vectors (m), grasp_rad the angle between\n"
          "the poles, residual_m the RMS of (model - measured) lengths. status is one of\n"
          "  ok             the pose below is valid\n"
          "  invalid_input  a field is not a number, the field count is not 8, or a length is\n"
          "                 NaN, infinite, negative or zero (a message on stderr names the line)\n"
          "  unreachable    no pose with its centre inside the frame reproduces the lengths\n"
          "                 (RMS residual above --max-residual)\n"
          "  singular       poles (nearly) parallel or a pose the lengths barely determine\n"
          "  not_converged  the solver ran out of iterations\n"
          "  ambiguous      two distinct poses (branches) both reproduce the lengths within\n"
          "                 --max-residual: the lengths cannot tell which one the grip is in\n"
          "and for every status other than ok all numbers are nan. Every line is solved on its "
          "own\n"
          "(closed form, then Gauss-Newton on all 8 strings): no line depends on another. Exit 0\n"
          "when the input was read, 2 for bad options.\n"
          "With --bound Q a last column bound_m is appended: a worst-case bound (m) on the "
          "distance\n"
          "between the printed centre p0 and the true one when every length is within +-Q m of "
          "the\n"
          "truth (Q = half an encoder count, 1.2566e-5 m, for the paper's quantized encoders). It\n"
          "is inf where the pose is too poorly conditioned for any bound (near the singular set:\n"
          "treat the pose as unreliable) and nan when the status is not ok. With --bound a line "
          "is\n"
          "also refused as ambiguous when a second, distinct pose reproduces its lengths within "
          "an\n"
          "RMS of Q (it could be the true one). See docs/kinematics.md.\n"
          "Without --bound the output is unchanged.\n\n") +
      kFrameHelp +
      "\nExamples (the paper's device: 48 cm frame, 4 cm grip). At rest all 8 strings are\n"
      "0.3939543 m long:\n"
      "  echo 0.3939543,0.3939543,0.3939543,0.3939543,0.3939543,0.3939543,0.3939543,0.3939543 \\\n"
      "    | spidarcad fk --batch\n"
      "  -> 0,0,0,0,0.04,0,0.04,0,0,1.5707...,1e-08,ok (to rounding)\n"
      "Round trip through inverse kinematics:\n"
      "  echo 0.05,0,0.1,0,0.04,0,0.04,0,0 | spidarcad ik --batch | spidarcad fk --batch\n");
  fk->add_flag("--batch", options->batch, "Read cases from stdin, write results to stdout");
  fk->add_flag("--no-header", options->no_header, "Do not write the '#' header line");
  fk->add_option("--max-residual", options->max_residual,
                 "Refuse (unreachable) when the RMS residual exceeds this, in m (default 1e-3;\n"
                 "raise to ~5e-3 for lengths with 0.8 % calibration error)");
  CLI::Option* bound =
      fk->add_option("--bound", options->bound,
                     "Append a column bound_m: worst-case error bound (m) of p0 for lengths known\n"
                     "to +-Q m each (Q >= 0; half an encoder count is 1.2566e-5)");
  AddGeometryOptions(*fk, &options->geometry);
  fk->callback([options, bound]() {
    options->with_bound = bound->count() > 0;
    RunFk(*options);
  });
}

void RegisterIkCommand(CLI::App& app) {
  auto options = std::make_shared<KinematicsOptions>();
  CLI::App* ik =
      app.add_subcommand("ik", "Inverse kinematics: grip pose -> 8 string lengths (batch CSV)");
  ik->footer(
      std::string(
          "\nInput (stdin): one pose per line, x,y,z,x1,y1,z1,x2,y2,z2 (m): centre p0 and pole\n"
          "vectors p1, p2. Blank lines and lines starting with '#' are skipped.\n"
          "Output (stdout): a header line starting with '#' (omit with --no-header), then one "
          "line\n"
          "per input pose: l1,l2,...,l8 (m), l_i = |Q_i - P_(i)| (Eq. 6). A line that is not 9\n"
          "finite numbers (nan and inf included) gives nan lengths and a message on stderr naming\n"
          "the line and column; a pole whose length\n"
          "differs from --pole by more than 1 um gives a warning (lengths are still "
          "computed).\n\n") +
      kFrameHelp +
      "\nExample (rest pose, then a pose 5 cm up with the grip turned 90 degrees about z):\n"
      "  printf '0,0,0,0,0.04,0,0.04,0,0\\n0,0,0.05,-0.04,0,0,0,0.04,0\\n' | spidarcad ik "
      "--batch\n");
  ik->add_flag("--batch", options->batch, "Read poses from stdin, write lengths to stdout");
  ik->add_flag("--no-header", options->no_header, "Do not write the '#' header line");
  AddGeometryOptions(*ik, &options->geometry);
  ik->callback([options]() { RunIk(*options); });
}

}  // namespace spidarcad::app
