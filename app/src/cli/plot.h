// A small PNG line-plot helper (VTK vtkChartXY rendered offscreen). Needs an X display: run
// under `xvfb-run -a -s "-screen 0 1280x1024x24"` on a machine without a screen.
// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#pragma once

#include <string>
#include <vector>

class vtkContextView;

namespace spidarcad::app {

// One line of a plot: points (x[k], y[k]); non-finite points are left out.
struct PlotSeries {
  std::string label;      // legend entry
  std::vector<double> x;  // same length as y
  std::vector<double> y;
  int color = 0;  // index into a fixed palette of 8 distinct colours
  bool dashed = false;
};

// One chart: a title, axis titles (with units) and its lines.
struct PlotPanel {
  std::string title;
  std::string x_label;
  std::string y_label;
  std::vector<PlotSeries> series;
};

// RGB of colour `index` of the fixed 8-colour palette (Okabe-Ito, colour-blind friendly);
// any integer index wraps around.
const unsigned char* PlotPaletteColor(int index);

// True when an X display looks reachable (DISPLAY set and, for a local display ":N", its
// socket /tmp/.X11-unix/XN exists). VTK aborts the process without one.
bool PlotDisplayAvailable();

// Renders the panels side by side into a PNG of width by height pixels at `path`.
// Throws std::runtime_error when there is no display or the file cannot be written.
void WriteLinePlotPng(const std::vector<PlotPanel>& panels, const std::string& path,
                      int width = 1400, int height = 600);

// Renders a chart view (off screen) and writes it as a PNG at `path`. Throws
// std::runtime_error when the file cannot be written.
void SaveChartPng(vtkContextView* view, const std::string& path);

}  // namespace spidarcad::app
