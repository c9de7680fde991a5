// Charts of `spidarcad report`: speed-against-error scatter plots with log axes, curves, and
// 2-D colour maps, rendered with VTK's charts (vtkChartXY, vtkChartHistogram2D) offscreen
// into PNG files. Needs an X display (the report command re-executes itself under xvfb-run
// when there is none).
// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#pragma once

#include <string>
#include <vector>

namespace spidarcad::app {

// One series of a chart: points (x[k], y[k]); non-finite points, and non-positive ones on a
// log axis, are left out.
struct ChartSeries {
  std::string label;      // legend entry
  std::vector<double> x;  // same length as y
  std::vector<double> y;
  int color = 0;        // palette index (PlotPaletteColor)
  bool lines = false;   // join the points by a line (else markers only)
  bool dashed = false;  // with lines: dashed
  int marker = 0;       // marker shape when !lines: 0 circle, 1 square, 2 diamond, 3 plus, 4 cross
};

// One chart: titles (axis titles carry units), axis scales, series.
struct Chart {
  std::string title;
  std::string x_label;
  std::string y_label;
  bool log_x = false;
  bool log_y = false;
  std::vector<ChartSeries> series;
};

// A scalar field on a regular grid of nx by ny cells covering [x0, x1] × [y0, y1]: value of
// cell (i, j) is values[j * nx + i] (NaN: blank).
struct ColourMap {
  std::string title;
  std::string x_label;
  std::string y_label;
  std::string value_label;  // the colour bar's title, with unit
  int nx = 0, ny = 0;
  double x0 = 0, x1 = 1, y0 = 0, y1 = 1;
  double value_min = 0, value_max = 1;  // colour range
  std::vector<double> values;
};

// Renders the charts side by side into a PNG of width by height pixels. Throws
// std::runtime_error when there is no display or the file cannot be written.
void WriteChartsPng(const std::vector<Chart>& charts, const std::string& path, int width,
                    int height);

// Renders one colour map (with its colour bar) into a PNG. Throws as WriteChartsPng.
void WriteColourMapPng(const ColourMap& map, const std::string& path, int width, int height);

}  // namespace spidarcad::app
