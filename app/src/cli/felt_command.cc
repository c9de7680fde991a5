// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
// `spidarcad felt`: the felt stiffness of an FE part against the mesh's cell size
// (scene/felt_stiffness.h), as a table, a CSV and a PNG plot.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <iostream>
#include <map>
#include <memory>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

#include "cli/cli_common.h"
#include "cli/commands.h"
#include "cli/plot.h"
#include "cli/report_common.h"
#include "cli/report_plot.h"
#include "scene/fe_touch_field.h"
#include "scene/felt_stiffness.h"

namespace spidarcad::app {
namespace {

struct FeltOptions {
  std::string scene;
  std::string solid;
  std::string cells = "0.012,0.010,0.008,0.006,0.005,0.004";
  std::string orders = "1,2";
  std::vector<std::string> probes;
  double tool_radius = 0.01;
  double coupling = kDefaultFeCoupling;
  double force_scale = kDefaultFeForceScale;
  std::string csv;
  std::string plot;
  std::string from_csv;
  std::string mesher = "tetrahedra";
  double flat_cells = 0.0;  // --flat-cells
};

// Samples from a CSV written by --csv (header line first).
std::vector<FeltSample> ReadSamples(const std::string& path) {
  std::ifstream in(path);
  if (!in) throw InputError("--from-csv: cannot read " + path);
  std::vector<FeltSample> samples;
  std::string line;
  int number = 0;
  while (std::getline(in, line)) {
    if (++number == 1 || line.empty()) continue;
    std::stringstream fields(line);
    FeltSample x;
    std::string cell, order, nodes, patch, k, felt;
    std::getline(fields, x.probe, ',');
    std::getline(fields, cell, ',');
    std::getline(fields, order, ',');
    std::getline(fields, nodes, ',');
    std::getline(fields, patch, ',');
    std::getline(fields, k, ',');
    std::getline(fields, felt, ',');
    try {
      x.cell = std::stod(cell);
      x.order = std::stoi(order);
      x.nodes = std::stoi(nodes);
      x.patch_nodes = std::stoi(patch);
      x.stiffness = std::stod(k);
      x.felt = std::stod(felt);
    } catch (const std::exception&) {
      throw InputError("--from-csv " + path + " line " + std::to_string(number) +
                       ": expected probe,cell_m,order,nodes,patch_nodes,stiffness,felt");
    }
    samples.push_back(x);
  }
  if (samples.empty()) throw InputError("--from-csv " + path + ": no sample");
  return samples;
}

std::vector<double> ParseNumbers(const std::string& text, const std::string& option) {
  std::vector<double> values;
  std::stringstream in(text);
  std::string field;
  while (std::getline(in, field, ',')) {
    std::size_t used = 0;
    double v = 0.0;
    try {
      v = std::stod(field, &used);
    } catch (const std::exception&) {
      used = 0;
    }
    if (used == 0 || used != field.size() || !std::isfinite(v))
      throw InputError(option + " '" + text + "': '" + field + "' is not a finite number");
    values.push_back(v);
  }
  if (values.empty()) throw InputError(option + ": no value given");
  return values;
}

// NAME,X,Y,Z[,DX,DY,DZ]
FeltProbe ParseProbe(const std::string& text) {
  const std::size_t comma = text.find(',');
  if (comma == std::string::npos || comma == 0)
    throw InputError("--probe '" + text + "': expected NAME,X,Y,Z[,DX,DY,DZ]");
  FeltProbe p;
  p.name = text.substr(0, comma);
  const std::vector<double> v = ParseNumbers(text.substr(comma + 1), "--probe");
  if (v.size() != 3 && v.size() != 6)
    throw InputError("--probe '" + text +
                     "': expected NAME,X,Y,Z[,DX,DY,DZ] (3 or 6 numbers, got " +
                     std::to_string(v.size()) + ")");
  p.point = Eigen::Vector3d(v[0], v[1], v[2]);
  if (v.size() == 6) {
    p.direction = Eigen::Vector3d(v[3], v[4], v[5]);
    if (!(p.direction.norm() > 0.0))
      throw InputError("--probe '" + text + "': the direction must not be zero");
    p.direction.normalize();
  }
  return p;
}

void RunFelt(const FeltOptions& o) {
  FeltSweepSettings s;
  s.scene_path = o.scene;
  s.solid = o.solid;
  s.cells = ParseNumbers(o.cells, "--cells");
  for (double h : s.cells)
    if (!(h > 0.0)) throw InputError("--cells '" + o.cells + "': cell sizes must be > 0 m");
  s.orders.clear();
  for (double v : ParseNumbers(o.orders, "--orders")) {
    if (v != 1.0 && v != 2.0) throw InputError("--orders '" + o.orders + "': orders are 1 or 2");
    s.orders.push_back(static_cast<int>(v));
  }
  for (const std::string& p : o.probes) s.probes.push_back(ParseProbe(p));
  if (!(o.tool_radius > 0.0) || !std::isfinite(o.tool_radius))
    throw InputError("--tool-radius: must be a finite length > 0 m");
  if (!(o.coupling >= 0.0) || !std::isfinite(o.coupling))
    throw InputError("--coupling: must be >= 0 N/m");
  if (!(o.force_scale > 0.0) || !std::isfinite(o.force_scale))
    throw InputError("--force-scale: must be > 0");
  s.tool_radius = o.tool_radius;
  s.coupling_stiffness = o.coupling;
  s.force_scale = o.force_scale;
  s.lattice = LatticeMesherOption(o.mesher, "tetrahedra");
  CheckFlatCellsOption(o.flat_cells, s.lattice);
  s.flat_cells = o.flat_cells;
  std::ofstream csv;
  if (!o.from_csv.empty()) {
    // Plot (and summarise) a finished or interrupted run: its cells and orders.
  } else if (!o.csv.empty()) {
    csv.open(o.csv);
    if (!csv) throw InputError("--csv: cannot write " + o.csv);
    csv << "probe,cell_m,order,nodes,patch_nodes,stiffness_n_per_m,felt_n_per_m\n";
  }
  std::cout << "probe   cell_mm order   nodes patch  stiffness_N/m  felt_N/m\n";
  const auto print = [&](const FeltSample& x) {
    char line[160];
    std::snprintf(line, sizeof line, "%-7s %7.1f %5d %7d %5d %14.6g %9.4g\n", x.probe.c_str(),
                  1e3 * x.cell, x.order, x.nodes, x.patch_nodes, x.stiffness, x.felt);
    std::cout << line << std::flush;
    if (csv) {
      csv.precision(10);
      csv << x.probe << "," << x.cell << "," << x.order << "," << x.nodes << "," << x.patch_nodes
          << "," << x.stiffness << "," << x.felt << "\n";
      csv.flush();
    }
  };
  std::vector<FeltSample> samples;
  if (o.from_csv.empty()) {
    try {
      samples = MeasureFeltStiffness(s, print);
    } catch (const std::invalid_argument& e) {
      throw InputError(e.what());  // a probe that misses the part, a bad mesh or setting
    }
  } else {
    samples = ReadSamples(o.from_csv);
    s.cells.clear();
    s.orders.clear();
    for (const FeltSample& x : samples) {
      print(x);
      if (std::find(s.cells.begin(), s.cells.end(), x.cell) == s.cells.end())
        s.cells.push_back(x.cell);
      if (std::find(s.orders.begin(), s.orders.end(), x.order) == s.orders.end())
        s.orders.push_back(x.order);
    }
  }

  // Converged value per probe: the finest P2 (or the finest of the highest order run), and the
  // Richardson extrapolation of that order's two finest cells (p = 1) as a check.
  const int top = *std::max_element(s.orders.begin(), s.orders.end());
  std::map<std::string, std::vector<const FeltSample*>> by_probe;  // top order, cell descending
  for (const FeltSample& x : samples)
    if (x.order == top) by_probe[x.probe].push_back(&x);
  std::map<std::string, double> converged;
  for (auto& [name, list] : by_probe) {
    std::sort(list.begin(), list.end(),
              [](const FeltSample* a, const FeltSample* b) { return a->cell > b->cell; });
    const FeltSample* fine = list.back();
    converged[name] = fine->stiffness;
    std::cout << "converged " << name << ": K = " << Sig(fine->stiffness, 6) << " N/m (P" << top
              << " at " << Sig(1e3 * fine->cell, 3) << " mm), felt "
              << Sig(FeltStiffness(fine->stiffness, s.coupling_stiffness, s.force_scale), 5)
              << " N/m";
    if (list.size() >= 2) {
      const FeltSample* prev = list[list.size() - 2];
      const double rich =
          RichardsonExtrapolate(prev->cell, prev->stiffness, fine->cell, fine->stiffness, 1.0);
      std::cout << "; Richardson (p = 1) from " << Sig(1e3 * prev->cell, 3) << " and "
                << Sig(1e3 * fine->cell, 3) << " mm: " << Sig(rich, 6) << " N/m ("
                << Sig(100.0 * (fine->stiffness / rich - 1.0), 2) << " % from the finest)";
    }
    std::cout << "\n";
  }

  if (!o.plot.empty()) {
    if (!PlotDisplayAvailable()) throw InputError("--plot: no X display (run under xvfb-run -a)");
    Chart k_chart, felt_chart;
    k_chart.title =
        "Part stiffness K of the tool's patch (r = " + Sig(1e3 * s.tool_radius, 3) + " mm)";
    k_chart.x_label = "cell size (mm)";
    k_chart.y_label = "K (N/m)";
    k_chart.log_x = true;
    k_chart.log_y = true;
    felt_chart.title = "Felt stiffness (k_c = " + Sig(s.coupling_stiffness, 4) +
                       " N/m, sigma = " + Sig(s.force_scale, 3) + ")";
    felt_chart.x_label = "cell size (mm)";
    felt_chart.y_label = "felt stiffness (N/m)";
    felt_chart.log_x = true;
    int colour = 0;
    for (const auto& [name, value] : converged) {
      for (int order : s.orders) {
        ChartSeries k, f;
        k.label = f.label = name + " P" + std::to_string(order);
        k.color = f.color = colour;
        k.lines = f.lines = true;
        k.dashed = f.dashed = order == 1;
        for (const FeltSample& x : samples) {
          if (x.probe != name || x.order != order) continue;
          k.x.push_back(1e3 * x.cell);
          k.y.push_back(x.stiffness);
          f.x.push_back(1e3 * x.cell);
          f.y.push_back(x.felt);
        }
        k_chart.series.push_back(k);
        felt_chart.series.push_back(f);
      }
      ChartSeries ck, cf;
      ck.label = cf.label = name + " converged";
      ck.color = cf.color = colour;
      ck.marker = cf.marker = 4;
      const double lo = 1e3 * *std::min_element(s.cells.begin(), s.cells.end()),
                   hi = 1e3 * *std::max_element(s.cells.begin(), s.cells.end());
      for (double x : {lo, std::sqrt(lo * hi), hi}) {
        ck.x.push_back(x);
        ck.y.push_back(value);
        cf.x.push_back(x);
        cf.y.push_back(FeltStiffness(value, s.coupling_stiffness, s.force_scale));
      }
      k_chart.series.push_back(ck);
      felt_chart.series.push_back(cf);
      colour += 2;
    }
    try {
      WriteChartsPng({k_chart, felt_chart}, o.plot, 1500, 560);
    } catch (const std::exception& e) {
      throw InputError(std::string("--plot: ") + e.what());
    }
    std::cout << "wrote " << o.plot << "\n";
  }
}

}  // namespace

void RegisterFeltCommand(CLI::App& app) {
  auto o = std::make_shared<FeltOptions>();
  CLI::App* cmd = app.add_subcommand(
      "felt",
      "Felt stiffness of an FE part's tool patch against the mesh's cell size (table, PNG)");
  cmd->footer(
      "Meshes the scene's solid (the first, or --solid NAME) at each --cells size (surface grid,\n"
      "marching tetrahedra or with --mesher lattice the lattice route, then TetGen), builds a "
      "steel FE model of each --orders element order clamped at its\n"
      "minimum-x face (as FE mode), and at each probe measures the part stiffness K (N/m): the\n"
      "force per metre that moves the tool's patch (every free surface node within --tool-radius\n"
      "of the probe point whose normal faces the tool) rigidly along the push direction, from a\n"
      "full sparse solve\n"
      "(as fem --grab). The felt stiffness is K through FE mode's virtual coupling:\n"
      "1/(1/k_c + 1/(sigma K)). Prints a table, the converged value (finest cell of the highest\n"
      "order, with the Richardson extrapolation of its two finest cells as a check), writes\n"
      "--csv and --plot (PNG; needs an X display: xvfb-run -a); --from-csv re-plots a --csv file\n"
      "(also one cut short). Default probes (platform.json):\n"
      "corner 0.29,0.09,0.01 and gusset 0.10,0,0.01, both pushed down (0,0,-1).\n"
      "\n"
      "Examples (the first, every default cell in both orders, takes several minutes on two\n"
      "cores, most of them at 4 mm; the second about half a minute):\n"
      "  xvfb-run -a spidarcad felt assets/scenes/platform.json --plot felt.png --csv felt.csv\n"
      "  xvfb-run -a spidarcad felt --cells 0.012,0.008 --plot felt.png");
  cmd->add_option("scene", o->scene, "Scene (.json; default assets/scenes/platform.json)");
  cmd->add_option("--solid", o->solid, "Solid of the scene (default: the first)");
  cmd->add_option("--cells", o->cells, "Surface grid cells, m (default 0.012,...,0.004)");
  cmd->add_option("--orders", o->orders, "Element orders (default 1,2)");
  cmd->add_option("--probe", o->probes,
                  "NAME,X,Y,Z[,DX,DY,DZ]: probe point (m) and push direction (default down)");
  cmd->add_option("--mesher", o->mesher,
                  "Surface of the solid: tetrahedra (default; as FE mode) or lattice");
  cmd->add_option("--flat-cells", o->flat_cells,
                  "Tetrahedra surface: collapse edges shorter than this fraction of a cell in "
                  "flat fans before TetGen (in [0, 1]; default 0: off, as FE mode)");
  cmd->add_option("--tool-radius", o->tool_radius, "Tool radius, m (default 0.01)");
  cmd->add_option("--coupling", o->coupling, "Virtual coupling k_c, N/m (default 1500)");
  cmd->add_option("--force-scale", o->force_scale, "Force scale sigma (default 1e-4)");
  cmd->add_option("--csv", o->csv, "CSV to write");
  cmd->add_option("--plot", o->plot, "PNG to write");
  cmd->add_option("--from-csv", o->from_csv,
                  "Measure nothing: summarise and plot the samples of this --csv file");
  cmd->callback([o] { RunFelt(*o); });
}

}  // namespace spidarcad::app
