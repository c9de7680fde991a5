// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#include "scene/vtu_io.h"

#include <Eigen/Geometry>
#include <cmath>
#include <sstream>
#include <stdexcept>
#include <string>
#include <utility>

#include "doc/input_error.h"

namespace spidarcad::app {
namespace {

double CornerVolume(const fem::TetMesh& mesh, int e) {
  const Eigen::Vector3d x0 = mesh.nodes.row(mesh.elements(e, 0)).transpose();
  const Eigen::Vector3d a = mesh.nodes.row(mesh.elements(e, 1)).transpose() - x0;
  const Eigen::Vector3d b = mesh.nodes.row(mesh.elements(e, 2)).transpose() - x0;
  const Eigen::Vector3d c = mesh.nodes.row(mesh.elements(e, 3)).transpose() - x0;
  return a.dot(b.cross(c)) / 6.0;
}

}  // namespace

fem::TetMesh ReadTetVtu(const std::string& path, VtuReadInfo* info) {
  modeling::VtuGrid grid;
  try {
    grid = modeling::ReadVtuGrid(path);
  } catch (const modeling::VtuError& e) {
    throw InputError(std::string(e.what()) +
                     " (the reader takes VTK XML UnstructuredGrid files of VTK_TETRA or "
                     "VTK_QUADRATIC_TETRA cells; re-export the mesh from ParaView or spidarcad)");
  }
  const int npe = static_cast<int>(grid.cells.rows());
  fem::TetMesh mesh;
  mesh.nodes = grid.points.transpose();
  mesh.elements = grid.cells.transpose();
  const bool has_regions = grid.regions.size() == grid.cells.cols();
  mesh.regions = has_regions ? grid.regions : Eigen::VectorXi::Zero(grid.cells.cols());

  int flipped = 0;
  for (int e = 0; e < mesh.num_elements(); ++e) {
    const double volume = CornerVolume(mesh, e);
    if (!(volume != 0.0) || !std::isfinite(volume)) {
      std::ostringstream s;
      s << path << ": cell " << e << " is degenerate (corner volume " << volume
        << " m^3); remove or repair it";
      throw InputError(s.str());
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
                 const modeling::VtuArrays& point_data, const modeling::VtuArrays& cell_data) {
  const int npe = mesh.NodesPerElement();
  if (npe != 4 && npe != 10) {
    throw std::invalid_argument("WriteTetVtu: elements have " + std::to_string(npe) +
                                " columns, expected 4 or 10");
  }
  modeling::VtuGrid grid;
  grid.points = mesh.nodes.transpose();
  grid.cells = mesh.elements.transpose();
  grid.regions = mesh.regions.size() == mesh.num_elements()
                     ? mesh.regions
                     : Eigen::VectorXi::Zero(mesh.num_elements());
  grid.point_data = point_data;
  grid.cell_data = cell_data;
  modeling::WriteVtuGrid(grid, path, modeling::VtuEncoding::kAppendedRaw);
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
