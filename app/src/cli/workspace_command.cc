// `spidarcad workspace`: deliverable force, moment and grasp torque across the workspace (the
// paper's Sec. 6 experiment), as CSV, a PNG plot and a summary compared with the paper.
// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <iostream>
#include <memory>
#include <sstream>
#include <string>
#include <vector>

#include "cli/cli_common.h"
#include "cli/commands.h"
#include "cli/plot.h"
#include "spidarcad/haptics/workspace.h"

namespace spidarcad::app {

namespace {

constexpr const char* kWorkspaceHelp =
    "Deliverable wrench across the workspace (paper Sec. 6). At each grip pose the largest\n"
    "force (moment, grasp torque) the strings can display in one direction is computed exactly:\n"
    "max s such that A τ = s·e with the other six wrench components exactly zero and every\n"
    "tension in [tmin, tmax] (a 2-variable LP over the null space of A).\n"
    "\n"
    "Sweeps: the grip (rest orientation, grasp 90°) moves from the centre along +x, −x, +y, −y,\n"
    "+z, −z until an attachment point reaches a frame face; and rotates at the centre about\n"
    "±x, ±y, ±z up to --max-angle degrees.\n"
    "\n"
    "CSV columns (one row per sample; units N, N·m, m, degrees):\n"
    "  sweep        'translate' or 'rotate'\n"
    "  axis, sign   the sweep direction sign·axis (axis x, y or z; sign +1 or -1)\n"
    "  distance_m   grip centre distance from the frame centre (translate), 0 for rotate\n"
    "  angle_deg    rotation angle about sign·axis (rotate), 0 for translate\n"
    "  force_N      deliverable force along sign·axis, the direction of expected\n"
    "               deterioration (translate); nan for rotate\n"
    "  force_min_N  smallest deliverable force over ±x, ±y, ±z\n"
    "  moment_pos_Nm, moment_neg_Nm   deliverable moment about +axis / −axis\n"
    "  grasp_close_Nm, grasp_open_Nm  deliverable grasp torque closing (g > 0) / opening (g < 0)\n"
    "A value is 0 when that direction cannot be displayed at all at that pose.\n"
    "\n"
    "Summary: 'full' is the value at the centre (or --rated-force / --rated-moment when the\n"
    "centre delivers more); the summary gives the distance (angle) up to which the value\n"
    "stays >= 95 % of full and where it first falls to <= 1 % of full. The plot's curves for\n"
    "+x/-x/+y/-y coincide by the device's symmetry, as do +z/-z.\n"
    "\n"
    "The PNG needs an X display; without one the CSV is still written, stderr says how to get\n"
    "the PNG (xvfb-run -a -s \"-screen 0 1280x1024x24\" spidarcad workspace ...) and the exit\n"
    "status is 0.\n"
    "\n"
    "Example:\n"
    "  spidarcad workspace --out-csv ws.csv --out-png ws.png --step 0.005";

struct WorkspaceOptions {
  std::string out_csv = "workspace.csv";
  std::string out_png = "workspace.png";
  haptics::WorkspaceSweepSettings sweep;
  haptics::SpidarGeometry geometry;
  double rated_force = 0;   // N, 0: the centre value is "full"
  double rated_moment = 0;  // N·m, 0: the centre value is "full"
};

std::string Num(double v) { return FormatNumber(v); }

std::string Centimetres(double metres) {
  if (std::isnan(metres)) return "never";
  char buffer[32];
  std::snprintf(buffer, sizeof(buffer), "%.1f cm", 100.0 * metres);
  return buffer;
}

std::string Degrees(double degrees) {
  if (std::isnan(degrees)) return "never";
  char buffer[32];
  std::snprintf(buffer, sizeof(buffer), "%.0f°", degrees);
  return buffer;
}

void WriteCsv(const std::vector<haptics::WorkspaceSample>& samples, const std::string& path) {
  std::ofstream out(path);
  if (!out) throw InputError("--out-csv: cannot open '" + path + "' for writing");
  out << "sweep,axis,sign,distance_m,angle_deg,force_N,force_min_N,moment_pos_Nm,moment_neg_Nm,"
         "grasp_close_Nm,grasp_open_Nm\n";
  for (const haptics::WorkspaceSample& s : samples) {
    out << s.sweep << ',' << s.axis << ',' << (s.sign > 0 ? "1" : "-1") << ',' << Num(s.distance)
        << ',' << Num(s.angle_deg) << ',' << Num(s.force) << ',' << Num(s.force_min) << ','
        << Num(s.moment_pos) << ',' << Num(s.moment_neg) << ',' << Num(s.grasp_close) << ','
        << Num(s.grasp_open) << '\n';
  }
  if (!out) throw InputError("--out-csv: error while writing '" + path + "'");
}

std::vector<PlotPanel> MakePanels(const std::vector<haptics::WorkspaceSample>& samples) {
  PlotPanel force{"Force toward the face (direction of expected deterioration)",
                  "grip distance from centre [cm]",
                  "deliverable force [N]",
                  {}};
  PlotPanel moment{"Moment at the centre vs rotation (min of both senses)",
                   "rotation angle [deg]",
                   "deliverable moment [N*m]",
                   {}};
  PlotPanel grasp{"Grasp torque along the translation sweeps (min over close/open)",
                  "grip distance from centre [cm]",
                  "deliverable grasp torque [N*m]",
                  {}};
  int color = 0;
  for (char axis : {'x', 'y', 'z'}) {
    for (int sign : {+1, -1}) {
      const std::string name = std::string(sign > 0 ? "+" : "-") + axis;
      PlotSeries f{"moving " + name + ", force " + name, {}, {}, color, sign < 0};
      PlotSeries m{"about " + name, {}, {}, color, sign < 0};
      PlotSeries g{"moving " + name, {}, {}, color, sign < 0};
      for (const haptics::WorkspaceSample& s : samples) {
        if (s.axis != axis || s.sign != sign) continue;
        if (s.sweep == "translate") {
          f.x.push_back(100.0 * s.distance);
          f.y.push_back(s.force);
          g.x.push_back(100.0 * s.distance);
          g.y.push_back(std::min(s.grasp_close, s.grasp_open));
        } else {
          m.x.push_back(s.angle_deg);
          m.y.push_back(std::min(s.moment_pos, s.moment_neg));
        }
      }
      force.series.push_back(f);
      moment.series.push_back(m);
      grasp.series.push_back(g);
    }
    ++color;
  }
  return {force, moment, grasp};
}

void PrintSummary(const std::vector<haptics::WorkspaceSample>& samples, const WorkspaceOptions& o) {
  std::ostringstream s;
  s << "Deliverable wrench, tensions in [" << Num(o.sweep.tau_min) << ", " << Num(o.sweep.tau_max)
    << "] N, frame half-sides " << Num(o.geometry.a) << ", " << Num(o.geometry.b) << ", "
    << Num(o.geometry.c) << " m, pole " << Num(o.geometry.d) << " m.\n";
  s << "Force toward a face (\"full\" = "
    << (o.rated_force > 0 ? "min(value at the centre, --rated-force " + Num(o.rated_force) + " N)"
                          : std::string("value at the centre"))
    << "; full = >= 95 % of it, zero = <= 1 % of it):\n";
  for (const haptics::SweepFalloff& f :
       haptics::SummarizeSweep(samples, "translate", o.rated_force)) {
    s << "  moving " << (f.sign > 0 ? '+' : '-') << f.axis << ": centre "
      << Num(std::round(f.centre * 100) / 100) << " N, full " << Num(std::round(f.full * 100) / 100)
      << " N up to " << Centimetres(f.last_full) << ", zero from " << Centimetres(f.first_zero)
      << "\n";
  }
  s << "Moment at the centre vs rotation (min of both senses about the axis; \"full\" = "
    << (o.rated_moment > 0 ? "min(centre, --rated-moment " + Num(o.rated_moment) + " N·m)"
                           : std::string("value at 0°"))
    << "):\n";
  for (const haptics::SweepFalloff& f :
       haptics::SummarizeSweep(samples, "rotate", o.rated_moment)) {
    s << "  about " << (f.sign > 0 ? '+' : '-') << f.axis << ": at 0° "
      << Num(std::round(f.centre * 1000) / 1000) << " N·m, full "
      << Num(std::round(f.full * 1000) / 1000) << " N·m up to " << Degrees(f.last_full)
      << ", zero from " << Degrees(f.first_zero) << "\n";
  }
  for (const haptics::WorkspaceSample& w : samples) {
    if (w.sweep == "translate" && w.distance == 0 && w.axis == 'x' && w.sign > 0) {
      s << "Grasp torque at the centre: closing " << Num(std::round(w.grasp_close * 1000) / 1000)
        << " N·m, opening " << Num(std::round(w.grasp_open * 1000) / 1000) << " N·m.\n";
    }
  }
  // Side by side with the paper: the worst of the directions of each group.
  auto worst = [](const std::vector<haptics::SweepFalloff>& fs, const std::string& axes,
                  double* last_full, double* first_zero) {
    *last_full = INFINITY;
    *first_zero = INFINITY;
    for (const haptics::SweepFalloff& f : fs) {
      if (axes.find(f.axis) == std::string::npos) continue;
      *last_full = std::min(*last_full, f.last_full);
      if (!std::isnan(f.first_zero)) *first_zero = std::min(*first_zero, f.first_zero);
    }
    if (std::isinf(*first_zero)) *first_zero = NAN;
  };
  const auto translate = haptics::SummarizeSweep(samples, "translate", o.rated_force);
  const auto rotate = haptics::SummarizeSweep(samples, "rotate", o.rated_moment);
  double xy_full, xy_zero, z_full, z_zero, r_full, r_zero;
  worst(translate, "xy", &xy_full, &xy_zero);
  worst(translate, "z", &z_full, &z_zero);
  worst(rotate, "xyz", &r_full, &r_zero);
  s << "Paper (Sec. 6) vs this model (ideal strings, point attachments, all other wrench\n"
       "components held at zero):\n"
    << "  x and y: paper full within 10 cm, zero about 23 cm out; model full to "
    << Centimetres(xy_full) << ", zero from " << Centimetres(xy_zero) << "\n"
    << "  z:       paper full to 23 cm, zero at 25 cm;           model full to "
    << Centimetres(z_full) << ", zero from " << Centimetres(z_zero)
    << (std::isnan(z_zero) ? " (within the sweep)" : "") << "\n"
    << "  rotation at the centre: paper full to 45°;             model full to " << Degrees(r_full)
    << ", zero from " << Degrees(r_zero) << "\n";
  std::cout << s.str();
}

void RunWorkspace(const WorkspaceOptions& options) {
  ValidateGeometry(options.geometry);
  try {
    options.sweep.Validate();
  } catch (const std::invalid_argument& e) {
    throw InputError(std::string("--step/--angle-step/--max-angle/--tmin/--tmax: ") + e.what());
  }
  if (!std::isfinite(options.rated_force) || options.rated_force < 0 ||
      !std::isfinite(options.rated_moment) || options.rated_moment < 0) {
    throw InputError("--rated-force/--rated-moment: must be finite and >= 0, got " +
                     Num(options.rated_force) + " and " + Num(options.rated_moment));
  }
  const std::vector<haptics::WorkspaceSample> samples =
      haptics::SweepWorkspace(options.geometry, options.sweep);
  WriteCsv(samples, options.out_csv);
  std::cout << "wrote " << options.out_csv << " (" << samples.size() << " samples)\n";
  int status = 0;
  if (!options.out_png.empty()) {
    if (!PlotDisplayAvailable()) {
      std::cerr << "spidarcad workspace: no X display, so " << options.out_png
                << " was not written (the CSV was).\n"
                   "  Get the PNG under a virtual display:\n"
                   "    xvfb-run -a -s \"-screen 0 1280x1024x24\" spidarcad workspace --out-csv "
                << options.out_csv << " --out-png " << options.out_png << "\n";
    } else {
      try {
        WriteLinePlotPng(MakePanels(samples), options.out_png, 1800, 600);
        std::cout << "wrote " << options.out_png << "\n";
      } catch (const std::runtime_error& e) {
        std::cerr << "spidarcad workspace: " << e.what() << "\n";
        status = 1;
      }
    }
  }
  PrintSummary(samples, options);
  std::cout << std::flush;
  throw CommandExit{status};
}

}  // namespace

void RegisterWorkspaceCommand(CLI::App& app) {
  auto options = std::make_shared<WorkspaceOptions>();
  CLI::App* cmd =
      app.add_subcommand("workspace", "Deliverable force across the workspace (CSV, PNG)");
  cmd->footer(kWorkspaceHelp);
  cmd->add_option("--out-csv", options->out_csv, "Sweep CSV to write (default workspace.csv)");
  cmd->add_option("--out-png", options->out_png,
                  "Plot PNG to write (default workspace.png; empty string: no plot)");
  cmd->add_option("--step", options->sweep.step,
                  "Distance between grip positions [m] (default 0.01)");
  cmd->add_option("--angle-step", options->sweep.angle_step_deg,
                  "Angle between grip rotations [deg] (default 5)");
  cmd->add_option("--max-angle", options->sweep.max_angle_deg,
                  "Largest rotation at the centre [deg] (default 90)");
  cmd->add_option("--tmin", options->sweep.tau_min, "Lowest string tension [N] (default 0.2)");
  cmd->add_option("--tmax", options->sweep.tau_max, "Highest string tension [N] (default 8)");
  cmd->add_option("--rated-force", options->rated_force,
                  "Rated force [N] that counts as 'full' in the summary (default 0: the value "
                  "at the centre)");
  cmd->add_option("--rated-moment", options->rated_moment,
                  "Rated moment [N·m] that counts as 'full' in the summary (default 0: the "
                  "value at the centre)");
  AddGeometryOptions(*cmd, &options->geometry);
  cmd->callback([options]() { RunWorkspace(*options); });
}

}  // namespace spidarcad::app
