// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#include "scene/vtu_io.h"

#include <cmath>
#include <fstream>
#include <stdexcept>
#include <string>

#include <Eigen/Geometry>
#include <vtkCellArray.h>
#include <vtkCellData.h>
#include <vtkCellType.h>
#include <vtkCommand.h>
#include <vtkDataArray.h>
#include <vtkDoubleArray.h>
#include <vtkIdList.h>
#include <vtkIntArray.h>
#include <vtkPointData.h>
#include <vtkPoints.h>
#include <vtkSmartPointer.h>
#include <vtkUnstructuredGrid.h>
#include <vtkXMLUnstructuredGridReader.h>
#include <vtkXMLUnstructuredGridWriter.h>

#include "doc/input_error.h"

namespace spidarcad::app {
namespace {

// Collects VTK error and warning events of one algorithm instead of printing them.
class ErrorCollector : public vtkCommand {
 public:
  static ErrorCollector* New() { return new ErrorCollector; }
  void Execute(vtkObject*, unsigned long event, void* data) override {
    if (event == vtkCommand::ErrorEvent) {
      if (!errors.empty()) errors += "; ";
      std::string text = data ? static_cast<const char*>(data) : "unknown VTK error";
      while (!text.empty() && (text.back() == '\n' || text.back() == ' ')) text.pop_back();
      errors += text;
    }
  }
  std::string errors;
};

const char* CellTypeName(int type) {
  switch (type) {
    case VTK_VERTEX: return "VTK_VERTEX";
    case VTK_LINE: return "VTK_LINE";
    case VTK_TRIANGLE: return "VTK_TRIANGLE";
    case VTK_QUAD: return "VTK_QUAD";
    case VTK_TETRA: return "VTK_TETRA";
    case VTK_HEXAHEDRON: return "VTK_HEXAHEDRON";
    case VTK_WEDGE: return "VTK_WEDGE";
    case VTK_PYRAMID: return "VTK_PYRAMID";
    case VTK_QUADRATIC_TETRA: return "VTK_QUADRATIC_TETRA";
    default: return "another cell type";
  }
}

double CornerVolume(const fem::TetMesh& mesh, int e) {
  const Eigen::Vector3d x0 = mesh.nodes.row(mesh.elements(e, 0)).transpose();
  const Eigen::Vector3d a = mesh.nodes.row(mesh.elements(e, 1)).transpose() - x0;
  const Eigen::Vector3d b = mesh.nodes.row(mesh.elements(e, 2)).transpose() - x0;
  const Eigen::Vector3d c = mesh.nodes.row(mesh.elements(e, 3)).transpose() - x0;
  return a.dot(b.cross(c)) / 6.0;
}

}  // namespace

fem::TetMesh ReadTetVtu(const std::string& path, VtuReadInfo* info) {
  if (!std::ifstream(path).good()) {
    throw InputError(path + ": cannot open the mesh file (missing or unreadable)");
  }
  auto reader = vtkSmartPointer<vtkXMLUnstructuredGridReader>::New();
  auto errors = vtkSmartPointer<ErrorCollector>::New();
  reader->AddObserver(vtkCommand::ErrorEvent, errors);
  if (!reader->CanReadFile(path.c_str())) {
    throw InputError(path + ": not a VTK XML UnstructuredGrid (.vtu) file");
  }
  reader->SetFileName(path.c_str());
  reader->Update();
  vtkUnstructuredGrid* grid = reader->GetOutput();
  if (!errors->errors.empty()) {
    throw InputError(path + ": VTK could not read the file: " + errors->errors);
  }
  if (grid == nullptr || grid->GetNumberOfPoints() == 0) {
    throw InputError(path + ": the mesh has no points");
  }
  const vtkIdType num_cells = grid->GetNumberOfCells();
  if (num_cells == 0) throw InputError(path + ": the mesh has no cells");

  const int first_type = grid->GetCellType(0);
  if (first_type != VTK_TETRA && first_type != VTK_QUADRATIC_TETRA) {
    throw InputError(path + ": cell 0 is " + CellTypeName(first_type) + " (type " +
                     std::to_string(first_type) +
                     "); only VTK_TETRA (10) and VTK_QUADRATIC_TETRA (24) cells are accepted");
  }
  const int npe = first_type == VTK_TETRA ? 4 : 10;

  fem::TetMesh mesh;
  const vtkIdType num_points = grid->GetNumberOfPoints();
  mesh.nodes.resize(num_points, 3);
  for (vtkIdType v = 0; v < num_points; ++v) {
    double p[3];
    grid->GetPoint(v, p);
    for (int i = 0; i < 3; ++i) {
      if (!std::isfinite(p[i])) {
        throw InputError(path + ": point " + std::to_string(v) + " has a non-finite coordinate");
      }
      mesh.nodes(v, i) = p[i];
    }
  }
  mesh.elements.resize(num_cells, npe);
  auto ids = vtkSmartPointer<vtkIdList>::New();
  for (vtkIdType c = 0; c < num_cells; ++c) {
    const int type = grid->GetCellType(c);
    if (type != first_type) {
      throw InputError(path + ": cell " + std::to_string(c) + " is " + CellTypeName(type) +
                       " (type " + std::to_string(type) + ") but cell 0 is " +
                       CellTypeName(first_type) + "; one kind of tetrahedron per file");
    }
    grid->GetCellPoints(c, ids);
    if (ids->GetNumberOfIds() != npe) {
      throw InputError(path + ": cell " + std::to_string(c) + " has " +
                       std::to_string(ids->GetNumberOfIds()) + " points, expected " +
                       std::to_string(npe));
    }
    for (int j = 0; j < npe; ++j) mesh.elements(c, j) = static_cast<int>(ids->GetId(j));
  }

  mesh.regions = Eigen::VectorXi::Zero(num_cells);
  bool has_regions = false;
  if (vtkDataArray* region = grid->GetCellData()->GetArray("region")) {
    if (region->GetNumberOfComponents() == 1 && region->GetNumberOfTuples() == num_cells) {
      has_regions = true;
      for (vtkIdType c = 0; c < num_cells; ++c) {
        mesh.regions(c) = static_cast<int>(region->GetTuple1(c));
      }
    }
  }

  int flipped = 0;
  for (int e = 0; e < mesh.num_elements(); ++e) {
    const double volume = CornerVolume(mesh, e);
    if (!(volume != 0.0) || !std::isfinite(volume)) {
      throw InputError(path + ": cell " + std::to_string(e) + " is degenerate (corner volume " +
                       std::to_string(volume) + " m^3)");
    }
    if (volume < 0.0) {
      // Swap corners 1 and 2; for 10-node cells the midside nodes of edges (0,1) <-> (0,2)
      // (local 4 <-> 6) and (1,3) <-> (2,3) (local 8 <-> 9) swap with them.
      std::swap(mesh.elements(e, 1), mesh.elements(e, 2));
      if (npe == 10) {
        std::swap(mesh.elements(e, 4), mesh.elements(e, 6));
        std::swap(mesh.elements(e, 8), mesh.elements(e, 9));
      }
      ++flipped;
    }
  }
  try {
    mesh.Validate();
  } catch (const std::invalid_argument& e) {
    throw InputError(path + ": " + e.what());
  }
  if (info != nullptr) {
    info->flipped_elements = flipped;
    info->has_regions = has_regions;
  }
  return mesh;
}

void WriteTetVtu(const fem::TetMesh& mesh, const std::string& path,
                 const VtuDataArrays& point_data, const VtuDataArrays& cell_data) {
  const int npe = mesh.NodesPerElement();
  if (npe != 4 && npe != 10) {
    throw std::invalid_argument("WriteTetVtu: elements have " + std::to_string(npe) +
                                " columns, expected 4 or 10");
  }
  auto grid = vtkSmartPointer<vtkUnstructuredGrid>::New();
  auto points = vtkSmartPointer<vtkPoints>::New();
  points->SetDataTypeToDouble();
  points->SetNumberOfPoints(mesh.num_nodes());
  for (int v = 0; v < mesh.num_nodes(); ++v) {
    points->SetPoint(v, mesh.nodes(v, 0), mesh.nodes(v, 1), mesh.nodes(v, 2));
  }
  grid->SetPoints(points);
  grid->Allocate(mesh.num_elements());
  const int type = npe == 4 ? VTK_TETRA : VTK_QUADRATIC_TETRA;
  vtkIdType ids[10];
  for (int e = 0; e < mesh.num_elements(); ++e) {
    for (int j = 0; j < npe; ++j) ids[j] = mesh.elements(e, j);
    grid->InsertNextCell(type, npe, ids);
  }
  auto region = vtkSmartPointer<vtkIntArray>::New();
  region->SetName("region");
  region->SetNumberOfTuples(mesh.num_elements());
  for (int e = 0; e < mesh.num_elements(); ++e) {
    region->SetValue(e, mesh.regions.size() == mesh.num_elements() ? mesh.regions(e) : 0);
  }
  grid->GetCellData()->AddArray(region);

  auto add = [](const VtuDataArrays& arrays, Eigen::Index rows, const char* where,
                vtkDataSetAttributes* target) {
    for (const auto& [name, values] : arrays) {
      if (values.rows() != rows || values.cols() < 1) {
        throw std::invalid_argument("WriteTetVtu: " + std::string(where) + " array '" + name +
                                    "' has " + std::to_string(values.rows()) + " rows, expected " +
                                    std::to_string(rows));
      }
      auto array = vtkSmartPointer<vtkDoubleArray>::New();
      array->SetName(name.c_str());
      array->SetNumberOfComponents(static_cast<int>(values.cols()));
      array->SetNumberOfTuples(rows);
      for (Eigen::Index r = 0; r < rows; ++r) {
        for (Eigen::Index c = 0; c < values.cols(); ++c) {
          array->SetComponent(r, static_cast<int>(c), values(r, c));
        }
      }
      target->AddArray(array);
    }
  };
  add(point_data, mesh.num_nodes(), "point", grid->GetPointData());
  add(cell_data, mesh.num_elements(), "cell", grid->GetCellData());

  auto writer = vtkSmartPointer<vtkXMLUnstructuredGridWriter>::New();
  auto errors = vtkSmartPointer<ErrorCollector>::New();
  writer->AddObserver(vtkCommand::ErrorEvent, errors);
  writer->SetFileName(path.c_str());
  writer->SetInputData(grid);
  writer->SetDataModeToBinary();
  if (writer->Write() != 1 || !errors->errors.empty()) {
    throw std::runtime_error(path + ": cannot write the .vtu file" +
                             (errors->errors.empty() ? "" : ": " + errors->errors));
  }
}

fem::TetMesh ToFemMesh(const modeling::TetMesh& mesh) {
  fem::TetMesh out;
  out.nodes = mesh.nodes.transpose();
  out.elements = mesh.tets.transpose();
  if (mesh.regions.size() == mesh.tets.cols()) {
    out.regions = mesh.regions;
  } else {
    out.regions = Eigen::VectorXi::Zero(mesh.tets.cols());
  }
  return out;
}

}  // namespace spidarcad::app
