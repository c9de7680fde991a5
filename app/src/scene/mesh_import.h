// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
// Mesh files read for import into a document (`spidarcad import`, the window's Import): a
// surface from STL, OBJ or PLY (modeling/triangle_mesh_io.h), or linear tetrahedra from a .vtu
// (modeling's VTU reader) or TetGen's .node with its .ele beside it. Coordinates are taken as
// metres. Tetrahedra are given positive orientation (corners 1 and 2 swapped where negative);
// their boundary surface comes with them.
#pragma once

#include <memory>
#include <string>

#include "spidarcad/modeling/surface_mesher.h"
#include "spidarcad/modeling/tet_mesh.h"

namespace spidarcad::app {

// A mesh read for import.
struct ImportedMesh {
  std::shared_ptr<const modeling::TriangleMesh> surface;  // the file's, or the tets' boundary
  std::shared_ptr<const modeling::TetMesh> volume;        // tetrahedra (VTU, .node), else null
  std::string format;                                     // "stl", "obj", "ply", "vtu" or "node"
  int flipped_tets = 0;  // tetrahedra whose corner order was reversed
};

// Reads a mesh file; the format follows the extension (case-insensitive). Throws InputError
// naming the file, the line (text) or byte offset (binary), the field and the value, and saying
// what to fix: unknown extension, unreadable or malformed file, no triangle or tetrahedron,
// quadratic cells, an index out of range, a degenerate (zero-volume) tetrahedron.
ImportedMesh ReadMeshForImport(const std::string& path);

}  // namespace spidarcad::app
