// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#include "cli/report_plot.h"

#include <vtkAxis.h>
#include <vtkChartHistogram2D.h>
#include <vtkChartLegend.h>
#include <vtkChartMatrix.h>
#include <vtkChartXY.h>
#include <vtkColorLegend.h>
#include <vtkColorTransferFunction.h>
#include <vtkContextScene.h>
#include <vtkContextView.h>
#include <vtkDoubleArray.h>
#include <vtkImageData.h>
#include <vtkNew.h>
#include <vtkPNGWriter.h>
#include <vtkPen.h>
#include <vtkPlotPoints.h>
#include <vtkRenderWindow.h>
#include <vtkRenderer.h>
#include <vtkTable.h>
#include <vtkTextProperty.h>
#include <vtkVector.h>
#include <vtkWindowToImageFilter.h>

#include <algorithm>
#include <cmath>
#include <fstream>
#include <stdexcept>

#include "cli/plot.h"

namespace spidarcad::app {

namespace {

void CheckWritable(const std::string& path) {
  if (!PlotDisplayAvailable()) {
    throw std::runtime_error("cannot render " + path +
                             ": no X display (run under xvfb-run -a -s "
                             "\"-screen 0 1280x1024x24\")");
  }
  std::ofstream probe(path, std::ios::binary);
  if (!probe) throw std::runtime_error("cannot write " + path);
}

void StyleAxes(vtkChart* chart, const std::string& title, const std::string& x_label,
               const std::string& y_label) {
  chart->SetTitle(title);
  chart->GetTitleProperties()->SetFontSize(15);
  for (int side : {vtkAxis::BOTTOM, vtkAxis::LEFT}) {
    vtkAxis* axis = chart->GetAxis(side);
    axis->SetTitle(side == vtkAxis::BOTTOM ? x_label : y_label);
    axis->GetTitleProperties()->SetFontSize(13);
    axis->GetLabelProperties()->SetFontSize(11);
  }
}

// Adds one series to an XY chart; false when no point could be shown.
bool AddSeries(vtkChart* chart, const Chart& c, const ChartSeries& s) {
  vtkNew<vtkTable> table;
  vtkNew<vtkDoubleArray> xs, ys;
  xs->SetName("x");
  ys->SetName(s.label.c_str());
  table->AddColumn(xs);
  table->AddColumn(ys);
  std::vector<std::pair<double, double>> points;
  for (size_t k = 0; k < s.x.size() && k < s.y.size(); ++k) {
    const double x = s.x[k], y = s.y[k];
    if (!std::isfinite(x) || !std::isfinite(y)) continue;
    if ((c.log_x && x <= 0) || (c.log_y && y <= 0)) continue;
    points.emplace_back(x, y);
  }
  if (points.empty()) return false;
  table->SetNumberOfRows(static_cast<vtkIdType>(points.size()));
  for (size_t k = 0; k < points.size(); ++k) {
    table->SetValue(static_cast<vtkIdType>(k), 0, points[k].first);
    table->SetValue(static_cast<vtkIdType>(k), 1, points[k].second);
  }
  const bool lines = s.lines && points.size() >= 2;  // a line needs two points
  vtkPlot* plot = chart->AddPlot(lines ? vtkChart::LINE : vtkChart::POINTS);
  plot->SetInputData(table, 0, 1);
  const unsigned char* rgb = PlotPaletteColor(s.color);
  plot->SetColor(rgb[0], rgb[1], rgb[2], 255);
  plot->SetLabel(s.label);
  if (auto* markers = vtkPlotPoints::SafeDownCast(plot)) {
    static const int kStyles[] = {vtkPlotPoints::CIRCLE, vtkPlotPoints::SQUARE,
                                  vtkPlotPoints::DIAMOND, vtkPlotPoints::PLUS,
                                  vtkPlotPoints::CROSS};
    markers->SetMarkerStyle(lines ? vtkPlotPoints::NONE : kStyles[((s.marker % 5) + 5) % 5]);
    markers->SetMarkerSize(8.0f);
  }
  if (lines) {
    plot->SetWidth(2.0f);
    if (s.dashed) plot->GetPen()->SetLineType(vtkPen::DASH_LINE);
  }
  return true;
}

}  // namespace

void WriteChartsPng(const std::vector<Chart>& charts, const std::string& path, int width,
                    int height) {
  CheckWritable(path);
  vtkNew<vtkContextView> view;
  view->GetRenderer()->SetBackground(1.0, 1.0, 1.0);
  view->GetRenderWindow()->SetSize(width, height);
  view->GetRenderWindow()->SetOffScreenRendering(1);
  vtkNew<vtkChartMatrix> matrix;
  view->GetScene()->AddItem(matrix);
  matrix->SetSize(vtkVector2i(static_cast<int>(charts.size()), 1));
  matrix->SetGutter(vtkVector2f(90.0f, 60.0f));
  matrix->SetBorders(70, 50, 20, 30);  // left, bottom, right, top: room for the axis titles
  for (size_t p = 0; p < charts.size(); ++p) {
    const Chart& c = charts[p];
    vtkChart* chart = matrix->GetChart(vtkVector2i(static_cast<int>(p), 0));
    StyleAxes(chart, c.title, c.x_label, c.y_label);
    chart->GetAxis(vtkAxis::BOTTOM)->SetLogScale(c.log_x);
    chart->GetAxis(vtkAxis::LEFT)->SetLogScale(c.log_y);
    bool any = false;
    for (const ChartSeries& s : c.series) any = AddSeries(chart, c, s) || any;
    chart->SetShowLegend(any);
    chart->GetLegend()->SetHorizontalAlignment(vtkChartLegend::RIGHT);
    chart->GetLegend()->SetVerticalAlignment(vtkChartLegend::TOP);
    chart->GetLegend()->GetLabelProperties()->SetFontSize(11);
  }
  SaveChartPng(view, path);
}

void WriteColourMapPng(const ColourMap& map, const std::string& path, int width, int height) {
  CheckWritable(path);
  if (map.nx <= 0 || map.ny <= 0 || map.values.size() != static_cast<size_t>(map.nx) * map.ny) {
    throw std::runtime_error("colour map " + map.title + ": values do not fill the grid");
  }
  vtkNew<vtkContextView> view;
  view->GetRenderer()->SetBackground(1.0, 1.0, 1.0);
  view->GetRenderWindow()->SetSize(width, height);
  view->GetRenderWindow()->SetOffScreenRendering(1);
  vtkNew<vtkChartHistogram2D> chart;
  view->GetScene()->AddItem(chart);
  vtkNew<vtkImageData> image;
  image->SetExtent(0, map.nx - 1, 0, map.ny - 1, 0, 0);
  const double dx = (map.x1 - map.x0) / map.nx, dy = (map.y1 - map.y0) / map.ny;
  image->SetOrigin(map.x0, map.y0, 0.0);
  image->SetSpacing(dx, dy, 1.0);
  image->AllocateScalars(VTK_DOUBLE, 1);
  for (int j = 0; j < map.ny; ++j) {
    for (int i = 0; i < map.nx; ++i) {
      *static_cast<double*>(image->GetScalarPointer(i, j, 0)) = map.values[j * map.nx + i];
    }
  }
  chart->SetInputData(image);
  vtkNew<vtkColorTransferFunction> colours;
  // Dark blue (low) through teal and yellow (high): readable in grey too.
  const double lo = map.value_min, hi = std::max(map.value_max, map.value_min + 1e-12);
  colours->AddRGBPoint(lo, 0.27, 0.00, 0.33);
  colours->AddRGBPoint(lo + 0.25 * (hi - lo), 0.23, 0.32, 0.55);
  colours->AddRGBPoint(lo + 0.50 * (hi - lo), 0.13, 0.57, 0.55);
  colours->AddRGBPoint(lo + 0.75 * (hi - lo), 0.37, 0.79, 0.38);
  colours->AddRGBPoint(hi, 0.99, 0.91, 0.14);
  colours->SetNanColor(1.0, 1.0, 1.0);
  colours->Build();
  chart->SetTransferFunction(colours);
  StyleAxes(chart, map.title, map.x_label, map.y_label);
  if (auto* legend = vtkColorLegend::SafeDownCast(chart->GetLegend())) {
    legend->SetTitle(map.value_label);
  }
  SaveChartPng(view, path);
}

}  // namespace spidarcad::app
