// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
// Reading a mesh file into a mesh object's data (File → Import mesh, files dropped on the
// window, edit::ImportMesh): a surface from STL, OBJ or PLY (modeling/triangle_mesh_io.h), or
// tetrahedra from VTU (modeling/tet_mesh.h) or TetGen's .node with the .ele beside it. Metres,
// as the files hold them; quadratic (10-node) tetrahedra keep their corners; tetrahedra with a
// negative orientation are flipped (corners 1 and 2 swapped); a VTU "region" cell array or a
// TetGen region attribute becomes the regions; tetrahedra come with their boundary surface.
// This is the one mesh file reader of the app: the window's Import, dropped files and
// `spidarcad import` all read through it.
#pragma once

#include <string>

#include "doc/document.h"
#include "doc/tetgen_import.h"  // ParseTetgenFiles

namespace spidarcad::app {

// True for the extensions ReadMeshFile reads (.stl .obj .ply .vtu .node, any case).
bool IsMeshFile(const std::string& path);

// What ReadMeshFile found besides the mesh.
struct MeshFileInfo {
  std::string format;    // "stl", "obj", "ply", "vtu" or "node"
  int flipped_tets = 0;  // tetrahedra written with negative orientation (corners 1, 2 swapped)
};

// The mesh object data of the file at `path` (import_source = path; no source object): a
// surface, or tetrahedra with their boundary surface. Throws InputError naming the file and the
// line (text formats) or byte offset, the field and the value when the file cannot be read or
// holds no usable mesh (no triangles, no tetrahedra, an index out of range, a degenerate
// tetrahedron). Fills *info when given.
MeshData ReadMeshFile(const std::string& path, MeshFileInfo* info = nullptr);

}  // namespace spidarcad::app
