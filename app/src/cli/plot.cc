// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#include "cli/plot.h"

#include <sys/stat.h>
#include <vtkAxis.h>
#include <vtkChart.h>
#include <vtkChartLegend.h>
#include <vtkChartMatrix.h>
#include <vtkContextScene.h>
#include <vtkContextView.h>
#include <vtkDoubleArray.h>
#include <vtkNew.h>
#include <vtkPNGWriter.h>
#include <vtkPen.h>
#include <vtkPlot.h>
#include <vtkRenderWindow.h>
#include <vtkRenderer.h>
#include <vtkTable.h>
#include <vtkTextProperty.h>
#include <vtkVector.h>
#include <vtkWindowToImageFilter.h>

#include <cmath>
#include <cstdlib>
#include <fstream>
#include <stdexcept>

namespace spidarcad::app {

namespace {
// Colour-blind-friendly palette (Okabe-Ito), RGB.
constexpr unsigned char kPalette[8][3] = {{0, 114, 178},   {213, 94, 0},  {0, 158, 115},
                                          {204, 121, 167}, {230, 159, 0}, {86, 180, 233},
                                          {0, 0, 0},       {240, 228, 66}};
}  // namespace

const unsigned char* PlotPaletteColor(int index) { return kPalette[((index % 8) + 8) % 8]; }

bool PlotDisplayAvailable() {
  const char* display = std::getenv("DISPLAY");
  if (display == nullptr || display[0] == '\0') return false;
  const std::string d(display);
  if (d[0] != ':') return true;  // remote or forwarded display: trust it
  const std::string number =
      d.substr(1, d.find('.') == std::string::npos ? std::string::npos : d.find('.') - 1);
  struct stat info;
  return stat(("/tmp/.X11-unix/X" + number).c_str(), &info) == 0;
}

void WriteLinePlotPng(const std::vector<PlotPanel>& panels, const std::string& path, int width,
                      int height) {
  if (!PlotDisplayAvailable()) {
    throw std::runtime_error("cannot render " + path +
                             ": no X display (run under xvfb-run -a -s "
                             "\"-screen 0 1280x1024x24\")");
  }
  {
    std::ofstream probe(path, std::ios::binary);
    if (!probe) throw std::runtime_error("cannot write " + path);
  }
  vtkNew<vtkContextView> view;
  view->GetRenderer()->SetBackground(1.0, 1.0, 1.0);
  view->GetRenderWindow()->SetSize(width, height);
  view->GetRenderWindow()->SetOffScreenRendering(1);
  vtkNew<vtkChartMatrix> matrix;
  view->GetScene()->AddItem(matrix);
  matrix->SetSize(vtkVector2i(static_cast<int>(panels.size()), 1));
  matrix->SetGutter(vtkVector2f(70.0f, 60.0f));
  for (size_t p = 0; p < panels.size(); ++p) {
    const PlotPanel& panel = panels[p];
    vtkChart* chart = matrix->GetChart(vtkVector2i(static_cast<int>(p), 0));
    chart->SetTitle(panel.title);
    chart->GetTitleProperties()->SetFontSize(16);
    chart->GetAxis(vtkAxis::BOTTOM)->SetTitle(panel.x_label);
    chart->GetAxis(vtkAxis::LEFT)->SetTitle(panel.y_label);
    chart->GetAxis(vtkAxis::BOTTOM)->GetTitleProperties()->SetFontSize(14);
    chart->GetAxis(vtkAxis::LEFT)->GetTitleProperties()->SetFontSize(14);
    chart->SetShowLegend(true);
    chart->GetLegend()->SetHorizontalAlignment(vtkChartLegend::RIGHT);
    chart->GetLegend()->SetVerticalAlignment(vtkChartLegend::TOP);
    for (const PlotSeries& s : panel.series) {
      vtkNew<vtkTable> table;
      vtkNew<vtkDoubleArray> xs, ys;
      xs->SetName(panel.x_label.c_str());
      ys->SetName(s.label.c_str());
      table->AddColumn(xs);
      table->AddColumn(ys);
      size_t count = 0;
      for (size_t k = 0; k < s.x.size() && k < s.y.size(); ++k) {
        if (std::isfinite(s.x[k]) && std::isfinite(s.y[k])) ++count;
      }
      table->SetNumberOfRows(static_cast<vtkIdType>(count));
      vtkIdType row = 0;
      for (size_t k = 0; k < s.x.size() && k < s.y.size(); ++k) {
        if (!std::isfinite(s.x[k]) || !std::isfinite(s.y[k])) continue;
        table->SetValue(row, 0, s.x[k]);
        table->SetValue(row, 1, s.y[k]);
        ++row;
      }
      vtkPlot* line = chart->AddPlot(vtkChart::LINE);
      line->SetInputData(table, 0, 1);
      const unsigned char* c = PlotPaletteColor(s.color);
      line->SetColor(c[0], c[1], c[2], 255);
      line->SetWidth(2.5f);
      line->SetLabel(s.label);
      if (s.dashed) line->GetPen()->SetLineType(vtkPen::DASH_LINE);
    }
  }
  SaveChartPng(view, path);
}

void SaveChartPng(vtkContextView* view, const std::string& path) {
  view->GetRenderWindow()->Render();
  vtkNew<vtkWindowToImageFilter> grab;
  grab->SetInput(view->GetRenderWindow());
  grab->ReadFrontBufferOff();
  grab->Update();
  vtkNew<vtkPNGWriter> writer;
  writer->SetFileName(path.c_str());
  writer->SetInputConnection(grab->GetOutputPort());
  writer->Write();
  if (writer->GetErrorCode() != 0) throw std::runtime_error("cannot write " + path);
}

}  // namespace spidarcad::app
