// Imported triangle meshes (STL, OBJ, PLY) made fit for tetrahedral meshing: what is safe to
// repair is repaired, with a report of every change; what is not is refused before TetGen sees
// it, with an error that names the defect, the first offending triangle or edge (by its place
// in the file) and what to do.
//
// Safe repairs (the solid's shape does not change beyond the weld tolerance): vertices closer
// than the tolerance welded into one; triangles that lose a corner to the welding, and
// zero-area triangles, dropped (a zero-area triangle whose corners are distinct lies along its
// longest edge: the triangle across that edge is split at the middle corner, so no crack opens);
// repeated triangles (the same three vertices) dropped, and a pair of back-to-back triangles
// (the same three vertices, opposite orientation: a membrane of zero thickness) dropped both;
// unused vertices dropped; the orientation made consistent across edges and outward (positive
// enclosed volume).
//
// Refused (MeshDefectError): non-finite coordinates; an open surface (an edge with one
// triangle: a hole or a crack wider than the tolerance); a non-manifold edge (three or more
// triangles on one edge); a non-orientable surface; a self-intersecting surface (two triangles
// that cross, found with CGAL's Polygon_mesh_processing::self_intersections, exact predicates).
//
// Triangle numbers in messages count from 1 in the order the file gives them (an OBJ polygon of
// n corners counts as n - 2 triangles); coordinates are printed in the file's units.
// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#pragma once

#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include "spidarcad/modeling/surface_mesher.h"

namespace spidarcad::modeling {

// The kinds of defect RepairTriangleMesh refuses.
enum class MeshDefect {
  kNonFinite,         // a coordinate is NaN or infinite
  kEmpty,             // no triangle is left
  kOpen,              // an edge has one triangle only
  kNonManifoldEdge,   // an edge has three or more triangles
  kNonOrientable,     // no consistent orientation exists (Moebius-like)
  kSelfIntersection,  // two triangles cross
};

// Name of a defect for messages ("open", "non-manifold edge", ...).
const char* MeshDefectName(MeshDefect defect);

// A mesh RepairTriangleMesh refuses. what() is the whole message: the file (when known), the
// defect, the first offending triangle or edge, and what to do.
class MeshDefectError : public std::runtime_error {
 public:
  // triangle: the first offending triangle (1-based file order), 0 when none applies.
  MeshDefectError(MeshDefect defect, long triangle, const std::string& what)
      : std::runtime_error(what), defect_(defect), triangle_(triangle) {}
  MeshDefect defect() const { return defect_; }
  long triangle() const { return triangle_; }

 private:
  MeshDefect defect_;
  long triangle_;
};

// Options of RepairTriangleMesh.
struct MeshRepairSettings {
  // Vertices closer than weld_tolerance × (bounding box diagonal) are welded (>= 0; 0: only
  // identical coordinates). 1e-9 closes the cracks of float round-off in files written in single
  // precision from double geometry, and is far below any triangle a modeller makes on purpose.
  double weld_tolerance = 1e-9;
  // Zero area: twice the triangle's area <= area_tolerance × (its longest edge)².
  double area_tolerance = 1e-12;
  // Run the self-intersection test (CGAL, exact). It is the costliest check (about 1 s per
  // million triangles); turn it off only for meshes known good.
  bool check_self_intersections = true;
};

// What RepairTriangleMesh changed. All zero: the mesh was fit as it was.
struct MeshRepairReport {
  long input_vertices = 0;
  long input_triangles = 0;
  long welded_vertices = 0;       // merged into another vertex within the tolerance
  long unused_vertices = 0;       // referenced by no (kept) triangle, dropped
  long collapsed_triangles = 0;   // lost a corner to the welding, dropped
  long degenerate_triangles = 0;  // zero area with three distinct corners, dropped
  long split_triangles = 0;       // split at the middle corner of a dropped zero-area triangle
  long duplicate_triangles = 0;   // repeated with the same orientation, dropped
  long back_to_back_pairs = 0;    // pairs with opposite orientation, both dropped
  long flipped_triangles = 0;     // turned over for a consistent, outward orientation
  long output_vertices = 0;
  long output_triangles = 0;
  double seconds = 0.0;  // whole repair and check, wall time

  // Whether anything changed.
  bool Changed() const;
  // One line per kind of change that happened ("welded 3 vertices within 1e-09 m", ...); a single
  // line "no repair needed" when nothing changed.
  std::vector<std::string> Lines() const;
};

// Repairs mesh as described above and checks the result; `source` (a file name, may be empty)
// prefixes every message. Returns a closed, edge-manifold, consistently and outward oriented
// surface with no zero-area triangle and (unless turned off) no self-intersection, fit for
// TetrahedralizeSurface. Throws MeshDefectError, std::invalid_argument for bad settings.
TriangleMesh RepairTriangleMesh(const TriangleMesh& mesh, const MeshRepairSettings& settings = {},
                                MeshRepairReport* report = nullptr, const std::string& source = "");

// Reads a mesh file (ReadTriangleMesh: MeshFileError for a malformed file) and repairs it
// (RepairTriangleMesh with the file as source).
TriangleMesh ImportSolidMesh(const std::string& path, const MeshRepairSettings& settings = {},
                             MeshRepairReport* report = nullptr);

// Pairs of triangles (indices into mesh.triangles, first < second, sorted) that intersect other
// than along the vertices and edges they share, found with CGAL's exact
// Polygon_mesh_processing::self_intersections. The mesh must be a closed, edge-manifold,
// consistently oriented surface without zero-area triangles (what RepairTriangleMesh checks
// before it); vertices where several fans meet are handled. Throws std::invalid_argument if CGAL
// cannot build a halfedge mesh from it.
std::vector<std::pair<int, int>> FindSelfIntersections(const TriangleMesh& mesh);

}  // namespace spidarcad::modeling
