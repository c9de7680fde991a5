// Tetrahedral meshes in VTK XML unstructured grid files (.vtu), read and written with VTK's
// vtkXMLUnstructuredGridReader / Writer, and the conversion from modeling's mesh layout to fem's.
//
// Accepted cells: VTK_TETRA (4 nodes) or VTK_QUADRATIC_TETRA (10 nodes, VTK order: corners, then
// midside nodes of edges (0,1), (1,2), (0,2), (0,3), (1,3), (2,3)), one kind per file. Node
// order is kept as in the file.
// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#pragma once

#include <map>
#include <string>

#include <Eigen/Core>

#include "spidarcad/fem/mesh.h"
#include "spidarcad/modeling/tet_mesh.h"

namespace spidarcad::app {

// Data arrays written with a mesh: name -> values, one ROW per point (or cell), one column per
// component (1 for a scalar, 3 for a vector).
using VtuDataArrays = std::map<std::string, Eigen::MatrixXd>;

// What ReadTetVtu found besides the mesh.
struct VtuReadInfo {
  // Elements whose corner order was negative and was flipped (corners 1 and 2 swapped).
  int flipped_elements = 0;
  // True when the file carried an integer cell array "region" (used as fem region labels).
  bool has_regions = false;
};

// Reads a tetrahedral mesh from a .vtu file. Regions come from a cell array "region" when
// present, else 0. Negatively oriented elements are flipped so that fem's positive-orientation
// rule holds. Throws InputError naming the file (and the cell, its type or the array) when the
// file cannot be read, has no points or cells, holds a cell that is not a (quadratic)
// tetrahedron, mixes the two kinds, or has a degenerate (zero-volume) element.
fem::TetMesh ReadTetVtu(const std::string& path, VtuReadInfo* info = nullptr);

// Writes mesh as a .vtu (VTK XML, binary appended, ParaView-readable) with cell data "region"
// (Int32) and the given point arrays (#V rows) and cell arrays (#T rows), as Float64. Throws
// std::invalid_argument for an array of the wrong row count and std::runtime_error naming the
// file when it cannot be written.
void WriteTetVtu(const fem::TetMesh& mesh, const std::string& path,
                 const VtuDataArrays& point_data = {}, const VtuDataArrays& cell_data = {});

// fem mesh (nodes #V by 3, elements #T by 4) from modeling's (nodes 3 by V, tets 4 by T); same
// node and element order; regions copied (0 when modeling's are empty).
fem::TetMesh ToFemMesh(const modeling::TetMesh& mesh);

}  // namespace spidarcad::app
