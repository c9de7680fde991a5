// Helpers shared by the window tests: the haptic runtime ticked on a virtual clock, the demo
// panel's centring springs as a scene, and screenshots read back and counted by colour.
// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#pragma once

#include <vtkImageData.h>
#include <vtkNew.h>
#include <vtkPNGReader.h>
#include <vtkSmartPointer.h>

#include <Eigen/Core>
#include <algorithm>
#include <cmath>
#include <cstddef>
#include <memory>
#include <string>

#include "gui/colour_map.h"
#include "scene/haptic_runtime.h"
#include "scene/scene_fields.h"

namespace spidarcad::app::window_test {

// `ticks` ticks of 1 ms on a virtual clock, called directly (no thread).
inline void RunTicks(HapticRuntime* runtime, int ticks) {
  haptics::TickTiming timing;
  for (int k = 0; k < ticks; ++k) {
    runtime->Tick(timing);
    ++timing.tick;
  }
}

// A scene of the centring springs only, in device coordinates (X_WD = identity).
inline std::unique_ptr<haptics::HapticScene> SpringScene(const DemoFieldSettings& field) {
  auto scene = std::make_unique<haptics::HapticScene>();
  scene->Add(std::make_unique<CentringSpringField>(
      field, haptics::DeviceToWorld{1.0, Eigen::Vector3d::Zero()}));
  return scene;
}

// The PNG at `path` as an image (rows bottom up, unsigned char components); 0×0 when unreadable.
inline vtkSmartPointer<vtkImageData> ReadPng(const std::string& path) {
  vtkNew<vtkPNGReader> reader;
  reader->SetFileName(path.c_str());
  reader->Update();
  auto image = vtkSmartPointer<vtkImageData>::New();
  image->DeepCopy(reader->GetOutput());
  return image;
}

// Pixels in columns [i0, i1) and rows [j0, j1) (bottom up) whose chromaticity (r, g, b)/(r+g+b)
// lies within `tolerance` of rgb's in every channel; pixels darker than r+g+b = 60 are skipped
// (shading keeps chromaticity, not brightness).
inline int CountChromaticity(vtkImageData* image, int i0, int i1, int j0, int j1, const Rgb& rgb,
                             double tolerance) {
  int dims[3];
  image->GetDimensions(dims);
  const int comps = image->GetNumberOfScalarComponents();
  const auto* px = static_cast<const unsigned char*>(image->GetScalarPointer());
  const double s = rgb[0] + rgb[1] + rgb[2];
  int count = 0;
  for (int j = std::max(0, j0); j < std::min(dims[1], j1); ++j) {
    for (int i = std::max(0, i0); i < std::min(dims[0], i1); ++i) {
      const unsigned char* p = px + (static_cast<std::size_t>(j) * dims[0] + i) * comps;
      const double ps = p[0] + p[1] + p[2];
      if (ps < 60) continue;
      double err = 0;
      for (int k = 0; k < 3; ++k) err = std::max(err, std::abs(p[k] / ps - rgb[k] / s));
      if (err < tolerance) ++count;
    }
  }
  return count;
}

}  // namespace spidarcad::app::window_test
