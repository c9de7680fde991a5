// Slab-conforming tetrahedral meshing: a closed surface is cut by planes across one axis into
// slabs, each slab is closed by the cross-sections on its planes (triangulated once in 2D and
// shared by the two slabs on either side), and each slab is tetrahedralized on its own with the
// surface kept as given (TetGen `Y`, `M`). The slab meshes join conformingly on the planes, and
// a slab whose closed surface did not change gives the same tetrahedra bit for bit (its input is
// put in a canonical order: vertices sorted by position, triangles by vertex), so after a local
// edit only the slabs the edit reached need TetGen again.
//
// Cutting. A vertex within `snap` (m) of a plane is moved onto it; a triangle that crosses a plane
// is split along it (the crossing point of an edge is shared by both triangles on the edge, so
// the cut surface stays closed and manifold). Cross-sections are the constrained Delaunay
// triangulation (CGAL) of the cut curves' vertices (and, with `section_spacing`, of interior grid
// points), inside the curves (odd nesting). Orientation: a triangle is counter-clockwise seen from
// outside its slab.
//
// Locality. The cut, the sections and each slab's input depend only on the surface near the
// slab. With a surface mesher that is local too (MeshSurface on a fixed grid is: an edit changes
// triangles within about a cell of it, docs/design/2026-12-02-edit-to-feel.md), an edit inside one
// slab and more than a cell from its planes leaves every other slab's tetrahedra unchanged.
// Frames and units: the surface's (m).
// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#pragma once

#include <cstdint>
#include <vector>

#include "spidarcad/modeling/surface_mesher.h"
#include "spidarcad/modeling/tet_mesh.h"
#include "spidarcad/modeling/tetgen_mesher.h"

namespace spidarcad::modeling {

// Where to cut.
struct SlabCut {
  // Axis across which the planes lie: 0, 1, 2 = x, y, z.
  int axis = 0;
  // Plane coordinates along the axis (m), strictly increasing: planes.size() + 1 slabs.
  std::vector<double> planes;
  // Vertices within this distance of a plane (m) are moved onto it (>= 0): keeps slivers out of
  // the cut (a tenth of the surface's cell is a fair choice).
  double snap = 0.0;
  // Spacing (m) of interior points added to each cross-section (0: none, the cut points only):
  // the points of a square grid of this spacing, anchored at the origin, that lie inside the
  // section and at least half a spacing from its cut curves. Shared by the two slabs like the
  // section, they keep TetGen (which may add no point to a kept boundary) from spanning a wide
  // section with slivers.
  double section_spacing = 0.0;
  // Strips: slab k is cut further by the planes p[strip_axis] = strip_planes[k][j] (strictly
  // increasing; an empty list leaves slab k whole) into strip_planes[k].size() + 1 pieces. Empty
  // (the default): no strips. Else one list per slab. A strip plane ends on the slab's planes:
  // the slab's cross-sections there hold its line as a constrained path (the same points seen
  // from the strip section and from the neighbouring slab), so the pieces still join
  // conformingly. A slab that holds most of a part (a bracket with its bolt holes) is split so
  // that an edit re-meshes and refactors a part of it.
  int strip_axis = 1;
  std::vector<std::vector<double>> strip_planes;
};

// A surface cut into closed slab surfaces.
struct SlabSurfaces {
  // Closed surface of each piece, in canonical order: the slabs (the solid between planes k−1
  // and k) in order, a slab with strips as its strips in order across the strip axis.
  std::vector<TriangleMesh> slabs;
  // Cross-section of each plane: triangles on the plane, counter-clockwise seen from +axis (or
  // +strip_axis); the slab planes' first, then the strip planes' slab by slab.
  std::vector<TriangleMesh> sections;
  // Vertices moved onto planes, and triangles split by them.
  long snapped_vertices = 0;
  long split_triangles = 0;
};

// Cuts a closed, outward-oriented surface. Throws std::invalid_argument for a bad axis or strip
// axis, planes not strictly increasing, strip planes not one list per slab or closer than two
// snaps (within a slab, or unequal ones of neighbouring slabs), a negative snap or
// section spacing (or one giving a section over 1e7 grid points), or a plane that a triangle lies
// in (a face of the
// solid on the plane: move the plane), and SurfaceDefectError when a cross-section cannot be
// triangulated (cut curves that cross, a strip plane's line across them) or a plane misses its
// part of the solid (a section with no area).
SlabSurfaces CutSurfaceIntoSlabs(const TriangleMesh& surface, const SlabCut& cut);

// FNV-1a 64 of a surface's vertices and triangles (the identity of a slab's input).
std::uint64_t SurfaceHash(const TriangleMesh& surface);

// A tetrahedral mesh made of slabs.
struct SlabTetMesh {
  // Every slab's tetrahedra, nodes on the planes shared (welded by exact position).
  TetMesh mesh;
  // Slab of each tet (0 .. #slabs − 1), in mesh.tets order: slab 0's tets first, then slab 1's...
  Eigen::VectorXi slab;
};

// Slab surfaces of at least this many triangles are meshed from perturbed vertices
// (TetMeshSettings::perturb_from_triangles): the platform's slabs at 5 and 6 mm, not at 8 or 10.
inline constexpr long kSlabPerturbFromTriangles = 8000;

// Tetrahedralizes one slab's closed surface: TetrahedralizeSurface with preserve_surface and
// keep_facets on (the cross-sections must stay as they are) and perturb_from_triangles set to
// kSlabPerturbFromTriangles, the rest of `settings` as given.
TetMesh TetrahedralizeSlab(const TriangleMesh& slab_surface, TetMeshSettings settings,
                           TetMeshStats* stats = nullptr);

// Joins slab meshes (in slab order) into one: nodes of neighbouring slabs with the same position
// become one node (only those on the slabs' shared planes can coincide). Node order: slab 0's
// nodes, then each later slab's nodes that are new, in its own order. Regions are kept.
SlabTetMesh JoinSlabs(const std::vector<TetMesh>& slabs);

}  // namespace spidarcad::modeling
