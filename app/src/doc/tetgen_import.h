// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
// TetGen's text files (.node with the .ele beside it) read into tetrahedra, and the orientation
// check shared with the VTU path of doc/mesh_import.h. Kept apart from mesh_import.cc (which
// also builds the boundary surface through modeling's CGAL code) so that the .node/.ele fuzz
// harness (tests/fuzz/node_ele_fuzz.cc) links this parser alone.
#pragma once

#include <functional>
#include <string>

#include "spidarcad/modeling/tet_mesh.h"

namespace spidarcad::app {

// TetGen's .node text (and the .ele text beside it) as positively oriented tetrahedra, metres as
// written; `node_file` and `ele_file` name them in errors; *flipped (when given) counts the
// tetrahedra that were reoriented (corners 1 and 2 swapped).
// The .node file: a header "points [dimension=3 [attributes [markers 0|1]]]", then one line
// "number x y z [attributes...] [marker]" per point, numbered consecutively from 0 or 1. The
// .ele file: a header "tetrahedra [nodes per tet 4|10 [region attributes]]", then one line
// "number n0 n1 n2 n3 [6 more for 10 nodes] [region]" per tetrahedron, numbered consecutively
// from 0 or 1, node numbers counted like the points. '#' starts a comment; blank lines are
// skipped. Throws InputError naming file, line and field: a missing or malformed number, a
// number beyond the largest double, a node that is not a point, more or fewer lines than the
// header announces, a tetrahedron that repeats a node or has zero or non-finite volume.
modeling::TetMesh ParseTetgenFiles(const std::string& node_text, const std::string& ele_text,
                                   const std::string& node_file, const std::string& ele_file,
                                   int* flipped = nullptr);

// Swaps corners 1 and 2 of every negatively oriented tetrahedron of *mesh and returns how many
// it swapped; throws InputError "<where(t)> has zero volume" (or a non-finite one) for the first
// degenerate tetrahedron t, leaving *mesh partly reoriented. The callers refuse repeated corners
// before (a repeated corner's rounded volume need not be exactly 0).
int OrientTetsPositively(modeling::TetMesh* mesh,
                         const std::function<std::string(Eigen::Index)>& where);

}  // namespace spidarcad::app
