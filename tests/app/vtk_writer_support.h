// VTK's own XML writer for the tests of .vtu input (tests/app): a fem mesh as a VTK grid and
// every encoding vtkXMLUnstructuredGridWriter can store it in (ascii, inline base64, appended
// raw or base64, plain or zlib, UInt32 or UInt64 headers, either byte order), so that the
// readers are tested on the files ParaView and VTK write.
// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#pragma once

#include <gtest/gtest.h>
#include <vtkCellData.h>
#include <vtkCellType.h>
#include <vtkDoubleArray.h>
#include <vtkIntArray.h>
#include <vtkPointData.h>
#include <vtkPoints.h>
#include <vtkSmartPointer.h>
#include <vtkUnstructuredGrid.h>
#include <vtkXMLUnstructuredGridWriter.h>

#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include "spidarcad/fem/mesh.h"

namespace spidarcad::app {

// The fem mesh as a VTK grid (cells VTK_TETRA or VTK_QUADRATIC_TETRA, "region" Int32, and a
// point array "position" holding 2·x + (0, 1, 2)).
inline vtkSmartPointer<vtkUnstructuredGrid> ToVtkGrid(const fem::TetMesh& mesh) {
  auto grid = vtkSmartPointer<vtkUnstructuredGrid>::New();
  auto points = vtkSmartPointer<vtkPoints>::New();
  points->SetDataTypeToDouble();
  for (int v = 0; v < mesh.num_nodes(); ++v)
    points->InsertNextPoint(mesh.nodes(v, 0), mesh.nodes(v, 1), mesh.nodes(v, 2));
  grid->SetPoints(points);
  const int npe = mesh.NodesPerElement();
  for (int e = 0; e < mesh.num_elements(); ++e) {
    vtkIdType ids[10];
    for (int j = 0; j < npe; ++j) ids[j] = mesh.elements(e, j);
    grid->InsertNextCell(npe == 4 ? VTK_TETRA : VTK_QUADRATIC_TETRA, npe, ids);
  }
  auto region = vtkSmartPointer<vtkIntArray>::New();
  region->SetName("region");
  for (int e = 0; e < mesh.num_elements(); ++e) region->InsertNextValue(mesh.regions(e));
  grid->GetCellData()->AddArray(region);
  auto position = vtkSmartPointer<vtkDoubleArray>::New();
  position->SetName("position");
  position->SetNumberOfComponents(3);
  for (int v = 0; v < mesh.num_nodes(); ++v) {
    const double t[3] = {2 * mesh.nodes(v, 0), 2 * mesh.nodes(v, 1) + 1, 2 * mesh.nodes(v, 2) + 2};
    position->InsertNextTuple(t);
  }
  grid->GetPointData()->AddArray(position);
  return grid;
}

// One way VTK's writer can store a file.
struct VtkEncoding {
  int mode;  // 0 ascii, 1 binary (inline base64), 2 appended
  bool encode_appended, zlib, header64, big_endian;
  std::string Name() const {
    const char* modes[] = {"ascii", "binary", "appended"};
    return std::string(modes[mode]) + (mode == 2 ? (encode_appended ? "-base64" : "-raw") : "") +
           (zlib ? "-zlib" : "") + (header64 ? "-u64" : "-u32") + (big_endian ? "-be" : "-le");
  }
};

// Every encoding of VtkEncoding (ascii once; binary and appended in every combination).
inline std::vector<VtkEncoding> AllVtkEncodings() {
  std::vector<VtkEncoding> out;
  out.push_back({0, false, false, false, false});
  for (int mode : {1, 2})
    for (bool encode : {false, true}) {
      if (mode == 1 && encode) continue;
      for (bool zlib : {false, true})
        for (bool header64 : {false, true})
          for (bool big : {false, true}) out.push_back({mode, encode, zlib, header64, big});
    }
  return out;
}

// Writes mesh to path with VTK's writer in encoding enc; returns the file's bytes.
inline std::string WriteWithVtk(const fem::TetMesh& mesh, const VtkEncoding& enc,
                                const std::string& path) {
  auto writer = vtkSmartPointer<vtkXMLUnstructuredGridWriter>::New();
  writer->SetFileName(path.c_str());
  writer->SetInputData(ToVtkGrid(mesh));
  if (enc.mode == 0) writer->SetDataModeToAscii();
  if (enc.mode == 1) writer->SetDataModeToBinary();
  if (enc.mode == 2) writer->SetDataModeToAppended();
  writer->SetEncodeAppendedData(enc.encode_appended);
  if (enc.zlib) {
    writer->SetCompressorTypeToZLib();
    writer->SetBlockSize(256);  // several blocks per array
  } else {
    writer->SetCompressorTypeToNone();
  }
  if (enc.header64) {
    writer->SetHeaderTypeToUInt64();
  } else {
    writer->SetHeaderTypeToUInt32();
  }
  if (enc.big_endian) {
    writer->SetByteOrderToBigEndian();
  } else {
    writer->SetByteOrderToLittleEndian();
  }
  EXPECT_EQ(writer->Write(), 1) << enc.Name();
  std::ifstream in(path, std::ios::binary);
  std::stringstream bytes;
  bytes << in.rdbuf();
  return bytes.str();
}

}  // namespace spidarcad::app
