// Closed triangle surface -> quality tetrahedral mesh with TetGen 1.5 (libtet).
//
// TetGen 1.5 handles bad input badly: a self-intersecting surface makes it throw from inside the
// library and crash while unwinding, and an open surface or a bad index can give zero tets
// silently. So TetrahedralizeSurface (1) checks the surface first (CheckSurface: indices,
// degenerate triangles, closed, edge-manifold, consistently oriented, no self-intersections),
// (2) links its own terminatetetgen (src/tetgen_terminate.cc) so that the library's error exits
// that go through that symbol throw TetgenError instead, and (3) checks the output counts and
// indices. Every failure is an exception; the process keeps running.
// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#pragma once

#include <atomic>
#include <functional>
#include <stdexcept>
#include <string>

#include "spidarcad/modeling/surface_mesher.h"
#include "spidarcad/modeling/tet_mesh.h"

namespace spidarcad::modeling {

// A surface that TetGen must not be given: what is wrong and where (triangle / vertex indices).
class SurfaceDefectError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

// TetGen failed (an internal error code, or an output without tetrahedra).
class TetgenError : public std::runtime_error {
 public:
  // code: TetGen's terminatetetgen code (1 out of memory, 2 internal error, 3 self-intersection,
  // 4 small feature, 5 close facets, 10 input error), 0 when the error was found by us.
  TetgenError(int code, const std::string& what) : std::runtime_error(what), code_(code) {}
  int code() const { return code_; }

 private:
  int code_;
};

// Thrown when TetMeshSettings::cancel is raised.
class TetMeshingCancelled : public std::runtime_error {
 public:
  TetMeshingCancelled() : std::runtime_error("tetrahedral meshing cancelled") {}
};

// Options of TetrahedralizeSurface.
struct TetMeshSettings {
  // Radius-edge ratio bound (TetGen's `q` switch), > 1 to refine (2 is TetGen's default; down to
  // about 1.1 terminates); 0 disables quality refinement. Refinement is costly on surfaces with
  // small angles (MeshSurface output has triangles with angles near 1°): see the README figures.
  double max_radius_edge = 2.0;
  // Smallest dihedral angle TetGen aims for with `q` (degrees, 0: TetGen's default of 0, none).
  double min_dihedral_deg = 0.0;
  // Largest tet volume (m³, TetGen's `a` switch); 0: unbounded.
  double max_volume = 0.0;
  // Keep the input surface triangles as they are (TetGen's `Y`): no Steiner points on the
  // boundary, so the tet faces on the boundary are exactly the input triangles.
  bool preserve_surface = false;
  // Keep every input triangle a facet of its own (TetGen's `M`). By default TetGen merges
  // adjacent (nearly) coplanar facets, which lets it triangulate a box face freely but moves a
  // curved surface by about 1e-7 of its size (volume changes by ~1e-7 relative); with `M` the
  // surface is kept exactly, at the price of worse tets along the kept diagonals.
  bool keep_facets = false;
  // With preserve_surface and keep_facets (the boundary is then exactly the input triangles)
  // and a surface of at least this many triangles (0: never): TetGen meshes the vertices moved
  // by up to perturb_amplitude of the bounding-box diagonal, by a hash of each vertex's
  // position, and the output gets the exact positions back. A grid surface's flat faces and a
  // slab's cut curves hold many coplanar and cospherical points, which send TetGen's predicates to
  // exact arithmetic: moved, the platform's first slab at 5 mm (27,038 triangles) meshes in 0.48 s
  // instead of 0.84 s, with about as many tets under 5° and 10° (its worst angle 0.56° against
  // 1.33°). On small surfaces it gains little, and
  // on the platform's slabs at 10 mm (under 7,000 triangles each) it gave more tets under 5°
  // (docs/design/2026-12-07-edit-stages.md). When a tet's orientation (by the robust predicate)
  // does not survive the move back, or becomes flat, or TetGen fails on the moved surface, it
  // runs again on the exact positions (TetMeshStats::perturbed says which).
  long perturb_from_triangles = 0;
  // The largest move along each axis, as a fraction of the bounding-box diagonal (tests use a
  // large one to make tets turn over when the exact positions come back).
  double perturb_amplitude = 1e-9;
  // Appended to the switches as is (experts; e.g. "M" keeps coplanar facets apart).
  std::string extra_switches;
  // Suppress TetGen's console output (`Q`); false prints its statistics (`V`).
  bool quiet = true;
  // Weld vertices closer than weld_tolerance × (bounding box diagonal) and drop the triangles
  // that collapse (RepairSurface) before checking: MeshSurface can put two vertices at one point
  // where the zero set passes through a grid corner. Negative: no repair.
  double weld_tolerance = 1e-10;
  // Run CheckSurface first (leave on unless the surface is known good: TetGen can crash).
  bool check_surface = true;
  // Polled between stages; when true TetrahedralizeSurface throws TetMeshingCancelled.
  // (TetGen itself cannot be interrupted.)
  const std::atomic<bool>* cancel = nullptr;
  // Called with the fraction done at stage boundaries (0; 0.2 after the check; 0.9 after TetGen;
  // 1).
  std::function<void(double)> progress;
};

// Figures of a TetrahedralizeSurface run.
struct TetMeshStats {
  double check_seconds = 0.0;   // CheckSurface
  double tetgen_seconds = 0.0;  // the library call
  std::string switches;         // the TetGen command line used
  long welded_vertices = 0;     // by RepairSurface
  long dropped_triangles = 0;   // by RepairSurface
  TetQuality quality;           // of the output
  // True when the output came from moved vertices (TetMeshSettings::perturb_from_triangles),
  // false when none were moved or TetGen ran again on the exact ones.
  bool perturbed = false;
};

// Checks that surface bounds a solid TetGen can mesh: indices in range, no degenerate (zero
// area) triangle, every edge shared by exactly two triangles traversing it in opposite
// directions (closed, edge-manifold, consistently oriented), positive enclosed volume (outward
// normals), and no two triangles intersecting other than along shared vertices and edges
// (grid-accelerated triangle-triangle tests). Throws SurfaceDefectError naming the first defect.
void CheckSurface(const TriangleMesh& surface);

// Welds vertices closer than tolerance × (bounding box diagonal) into one (the lowest index,
// keeping its position), drops unused vertices and the triangles that lose a corner to the
// welding. Indices must be in range (SurfaceDefectError otherwise). Returns the number of
// vertices welded and triangles dropped in *welded and *dropped when given.
TriangleMesh RepairSurface(const TriangleMesh& surface, double tolerance, long* welded = nullptr,
                           long* dropped = nullptr);

// Tetrahedralizes the solid surface bounds: TetGen with `p` (keep the surface), `z`, `A`
// (regions), and `q`, `a`, `Y`, `M` as set. The first nodes of the output are the vertices of the
// (repaired) surface, in order; TetGen's Steiner points follow. TetGen fills every region the
// surface encloses: the regions outside the solid (the cavities of a hollow solid, whose inner
// shell faces inward) are dropped, by the winding number of the surface at one tet of each. Output
// tets are positively oriented (see TetMesh). Throws std::invalid_argument for bad settings,
// SurfaceDefectError, TetgenError, TetMeshingCancelled.
TetMesh TetrahedralizeSurface(const TriangleMesh& surface, const TetMeshSettings& settings = {},
                              TetMeshStats* stats = nullptr);

// Whether TetrahedralizeSurface may run on several threads at once. TetGen 1.5 keeps its exact
// predicates' constants and its mesh-walking tables in globals that every run writes again
// (exactinit, tetgenmesh::inittables), and one write goes through an intermediate value, so two
// runs at once are a data race. This program replaces both (tetgen_mesher.cc) with versions that
// write them once, and it gives each thread its own rand and srand while it runs TetGen (which
// shuffles its points with them; glibc has one generator for the process, so runs at once would
// each make another mesh from run to run); the answer is whether libtet's calls reach those
// replacements, which the dynamic linker decides (true in the program's own builds; false, say,
// if libtet were linked with -Bsymbolic). Without the static filter of TetGen's predicates (which
// needs the mesh's bounding box in a global) a predicate returns the same value, after a longer
// error bound check.
bool TetgenRunsConcurrently();

}  // namespace spidarcad::modeling
