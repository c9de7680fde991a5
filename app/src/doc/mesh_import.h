// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
// Reading a mesh file into a mesh object's data (File → Import mesh, files dropped on the
// window, edit::ImportMesh): a surface from STL, OBJ or PLY (modeling/triangle_mesh_io.h), or
// tetrahedra from VTU (modeling/tet_mesh.h) or TetGen's .node with the .ele beside it. Metres,
// as the files hold them; quadratic (10-node) tetrahedra keep their corners; tetrahedra with a
// negative orientation are flipped (corners 1 and 2 swapped); a VTU "region" cell array or a
// TetGen region attribute becomes the regions.
#pragma once

#include <string>

#include "doc/document.h"

namespace spidarcad::app {

// True for the extensions ReadMeshFile reads (.stl .obj .ply .vtu .node, any case).
bool IsMeshFile(const std::string& path);

// The mesh object data of the file at `path` (import_source = path; no source object). Throws
// InputError naming the file and the line (text formats) or byte offset, the field and the
// value when the file cannot be read or holds no usable mesh (no triangles, no tetrahedra, an
// index out of range, a degenerate tetrahedron).
MeshData ReadMeshFile(const std::string& path);

// TetGen's .node text (and the .ele text beside it) as tetrahedra; `node_file` and `ele_file`
// name them in errors. Exposed for tests.
modeling::TetMesh ParseTetgenFiles(const std::string& node_text, const std::string& ele_text,
                                   const std::string& node_file, const std::string& ele_file);

}  // namespace spidarcad::app
