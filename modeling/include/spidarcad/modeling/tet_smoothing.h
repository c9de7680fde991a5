// Sliver smoothing of a tetrahedral mesh: the vertices inside the mesh moved, one at a time, to
// where the smallest dihedral angle of the tetrahedra around them is largest. The boundary (and
// any vertex the caller fixes) stays where it is, so the surface, the volume and the
// connectivity do not change.
// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#pragma once

#include <vector>

#include "spidarcad/modeling/tet_mesh.h"

namespace spidarcad::modeling {

struct TetSmoothingSettings {
  // Tetrahedra with a dihedral angle under this (degrees, in (0, 60)) get their free corners
  // moved, worst first.
  double target_dihedral_deg = 10.0;
  // Passes over the tetrahedra still under the target (>= 1); a pass that moves nothing ends.
  int sweeps = 3;
  // A move may not leave a tet around the vertex with a radius-edge ratio over the largest of
  // this and what those tets had before (TetGen's `q` bound, TetMeshSettings::max_radius_edge).
  double max_radius_edge = 2.0;
};

struct TetSmoothingStats {
  long moved = 0;  // vertex moves made, over all passes
  int sweeps = 0;  // passes run
  double min_dihedral_before_deg = 0.0, min_dihedral_after_deg = 0.0;
  long under_target_before = 0, under_target_after = 0;  // tets under target_dihedral_deg
  double seconds = 0.0;
};

// Moves the free vertices of the tets of `mesh` whose smallest dihedral angle is under the
// target (each vertex searched at most once a pass, from the worst tet it is a corner of): free
// means not on the boundary (a corner of a face of one tet only) and not marked in `fixed` (size 0
// or one entry per node). Each move is a pattern search from the vertex (the 26 directions of a
// cube's neighbours, steps from 0.3 of its shortest edge halved down to 0.01 of it) that raises the
// smallest dihedral angle of the tets around it and keeps every one of them positive; a vertex is
// never moved to where that smallest angle would be lower, nor where a tet around it would exceed
// the radius-edge bound (max_radius_edge). Throws std::invalid_argument for bad settings or a mesh
// ValidateTetMesh refuses.
TetSmoothingStats SmoothSlivers(TetMesh* mesh, const TetSmoothingSettings& settings = {},
                                const std::vector<char>& fixed = {});

}  // namespace spidarcad::modeling
