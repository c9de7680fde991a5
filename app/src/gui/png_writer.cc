// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
// WritePng (gl_capture.h) lives here: it uses VTK, which must not meet <GL/gl.h>.
#include <vtkImageData.h>
#include <vtkNew.h>
#include <vtkPNGWriter.h>

#include <cstring>

#include "gui/gl_capture.h"

namespace spidarcad::app {

std::string WritePng(const std::string& path, const std::vector<unsigned char>& rgb, int width,
                     int height) {
  if (width <= 0 || height <= 0 ||
      rgb.size() != static_cast<size_t>(width) * static_cast<size_t>(height) * 3) {
    return "screenshot: image buffer does not match " + std::to_string(width) + "x" +
           std::to_string(height);
  }
  vtkNew<vtkImageData> image;
  image->SetDimensions(width, height, 1);
  image->AllocateScalars(VTK_UNSIGNED_CHAR, 3);
  // VTK images start at the bottom row, like glReadPixels.
  std::memcpy(image->GetScalarPointer(), rgb.data(), rgb.size());
  vtkNew<vtkPNGWriter> writer;
  writer->SetFileName(path.c_str());
  writer->SetInputData(image);
  writer->Write();
  if (writer->GetErrorCode() != 0) {
    return "screenshot: cannot write PNG file '" + path +
           "' (check that the folder exists "
           "and is writable)";
  }
  return {};
}

}  // namespace spidarcad::app
