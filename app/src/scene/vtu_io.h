// Tetrahedral meshes of the fem module in .vtu files, through modeling's own VTU reader and
// writer (modeling/tet_mesh.h: ReadVtuGrid / WriteVtuGrid; no VTK reader in the read path),
// and the conversion from modeling's mesh layout to fem's.
//
// Accepted cells: VTK_TETRA (4 nodes) or VTK_QUADRATIC_TETRA (10 nodes, VTK order: corners, then
// midside nodes of edges (0,1), (1,2), (0,2), (0,3), (1,3), (2,3)), one kind per file. Node
// order is kept as in the file. Data arrays are modeling::VtuArrays: k by N, one COLUMN per
// point (or cell), one row per component.
// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#pragma once

#include <Eigen/Core>
#include <string>

#include "spidarcad/fem/mesh.h"
#include "spidarcad/modeling/tet_mesh.h"

namespace spidarcad::app {

// What ReadTetVtu found besides the mesh.
struct VtuReadInfo {
  // Elements whose corner order was negative and was flipped (corners 1 and 2 swapped).
  int flipped_elements = 0;
  // True when the file carried an integer cell array "region" (used as fem region labels).
  bool has_regions = false;
};

// Reads a tetrahedral mesh from a .vtu file. Regions come from a cell array "region" when
// present, else 0. Negatively oriented elements are flipped so that fem's positive-orientation
// rule holds. Throws InputError naming the file and the byte offset, element or array, and
// value (modeling::VtuError's message) when the file cannot be read or is malformed, has no
// points or cells, holds a cell that is not a (quadratic) tetrahedron, mixes the two kinds,
// names a point that does not exist, or has a degenerate (zero-volume) element.
fem::TetMesh ReadTetVtu(const std::string& path, VtuReadInfo* info = nullptr);

// Writes mesh as a .vtu (VTK XML, appended raw binary, ParaView-readable) with cell data
// "region" (Int32) and the given point arrays (k by #V) and cell arrays (k by #T), as Float64.
// Throws std::invalid_argument for an array of the wrong size or a non-finite value and
// std::runtime_error naming the file when it cannot be written.
void WriteTetVtu(const fem::TetMesh& mesh, const std::string& path,
                 const modeling::VtuArrays& point_data = {},
                 const modeling::VtuArrays& cell_data = {});

// fem mesh (nodes #V by 3, elements #T by 4) from modeling's (nodes 3 by V, tets 4 by T); same
// node and element order; regions copied (0 when modeling's are empty).
fem::TetMesh ToFemMesh(const modeling::TetMesh& mesh);

}  // namespace spidarcad::app
