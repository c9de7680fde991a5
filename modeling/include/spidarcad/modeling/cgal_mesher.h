// Tetrahedral meshing straight from the implicit function with CGAL 5.5 Mesh_3: the second
// volume path beside MeshSurface + TetrahedralizeSurface (TetGen). CGAL samples the solid's
// zero set itself (Delaunay refinement of the restricted Delaunay triangulation), so no
// surface mesh is needed and the boundary vertices lie on the surface (to a bisection error of
// about 1e-6 of the box size); sharp edges of boxes and booleans are not preserved as
// polylines (no feature detection for implicit solids), they are cut off by up to about
// facet_distance.
//
// Only src/cgal_mesher.cc includes CGAL (one heavy translation unit: ~50 s, ~3 GB to compile).
//
// Pipeline: seed points (sign changes of the field on a grid of spacing ~facet_size, bisected
// onto the surface) -> Mesh_3 refinement (facets, then cells), stepped here so that `cancel` is
// polled after every step -> optional Lloyd / ODT smoothing, sliver perturbation and exudation
// (cancel is polled between them) -> TetMesh.
// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <atomic>
#include <cstdint>
#include <functional>
#include <stdexcept>
#include <string>

#include "spidarcad/modeling/implicit_evaluator.h"
#include "spidarcad/modeling/surface_mesher.h"
#include "spidarcad/modeling/tet_mesh.h"

namespace spidarcad::modeling {

// Any failure of MeshImplicitWithCgal: bad settings, a box that does not hold the solid, a CGAL
// exception or precondition, an empty result. The message says what to change.
class CgalMeshError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

// Thrown when CgalMeshSettings::cancel is raised (a CgalMeshError, so one catch covers all).
class CgalMeshCancelled : public CgalMeshError {
 public:
  CgalMeshCancelled() : CgalMeshError("CGAL meshing cancelled") {}
};

// Options of MeshImplicitWithCgal (CGAL's Mesh_criteria_3 and optimizer switches). Lengths in m.
// ForSize() gives a consistent set for one target edge length.
struct CgalMeshSettings {
  // Lower bound on the surface triangles' angles (degrees, <= 30 guarantees termination).
  double facet_angle_deg = 25.0;
  // Upper bound on the radius of the surface Delaunay balls (m, > 0): about the surface edge.
  double facet_size = 0.005;
  // Upper bound on the distance between a surface triangle's circumcentre and the centre of its
  // surface Delaunay ball (m, > 0): the chordal error of curved parts.
  double facet_distance = 0.0005;
  // Upper bound on the tets' circumradius over shortest edge (> 1; 2 to 3 is usual; sqrt(6)/4
  // is the regular tet). Slivers are not caught by it: perturb and exude remove them.
  double cell_radius_edge_ratio = 2.5;
  // Upper bound on the tets' circumradius (m); 0: only facet_size and the ratio grade the inside.
  double cell_size = 0.005;
  // Lloyd smoothing (slow, evens out vertex spacing), then ODT smoothing (faster, similar).
  bool lloyd = false;
  bool odt = false;
  // Sliver perturbation and exudation (on by default: they lift the worst dihedral angle from
  // about 1 degree to about 10+ degrees).
  bool perturb = true;
  bool exude = true;
  // Perturbation and exudation target tets with a dihedral angle below this (degrees; 0: keep
  // improving the worst one as long as possible, CGAL's default, much slower).
  double sliver_bound_deg = 10.0;
  // Time limit of Lloyd, ODT and perturbation each (s; 0: none) and iteration cap of Lloyd / ODT.
  // Perturbation can take most of the time on sharp-edged solids (platform at 8 mm: 45 s of
  // 47 s with sliver bound 0 and no limit, measured), hence a default limit. A time limit that
  // is reached makes the mesh depend on the machine's speed; `seed` alone fixes it otherwise.
  double optimizer_time_limit = 10.0;
  // Time limit of exudation (s; 0: none). CGAL 5.5's exuder can run on for minutes on
  // sharp-edged solids (a box with a bore at facet size 5 mm: over 2 min without a limit,
  // measured), so it is bounded by default; perturbation alone already lifts the worst dihedral
  // angle from 0 to about 12 degrees there.
  double exude_time_limit = 5.0;
  int smoothing_iterations = 20;
  // Refuse to grow the triangulation beyond this many vertices (sizes too small for the box).
  long max_vertices = 2'000'000;
  // Seed of every random choice (CGAL's default generator and the domain's), so that one seed
  // gives one mesh.
  std::uint32_t seed = 0;
  // Relative bisection error of surface points (of the box's half-diagonal).
  double relative_error_bound = 1e-6;
  // Polled after every refinement step and between phases; when true, CgalMeshCancelled.
  const std::atomic<bool>* cancel = nullptr;
  // Called with the fraction done in [0, 1] (refinement: a monotone estimate; 1 at the end).
  std::function<void(double)> progress;

  // Settings for a target edge length h (m): facet_size = cell_size = h, facet_distance = h/10.
  static CgalMeshSettings ForSize(double h);
};

// Figures of one MeshImplicitWithCgal run.
struct CgalMeshStats {
  double seconds = 0.0;           // total wall time
  double seed_seconds = 0.0;      // grid seeding
  double refine_seconds = 0.0;    // Mesh_3 refinement
  double optimize_seconds = 0.0;  // Lloyd, ODT, perturb, exude together
  long seed_points = 0;           // initial surface points inserted
  long refine_steps = 0;          // Mesh_3 refinement steps
  long vertices = 0;              // nodes of the output
  long tets = 0;                  // tets of the output
  long boundary_facets = 0;       // surface triangles of the output (Mesh_3's facets in complex)
  double min_dihedral_deg = 0.0;  // worst (smallest) dihedral angle of the output, degrees
  TetQuality quality;             // all figures of the output (MeasureTetQuality)
};

// Meshes the solid (value < 0 inside) inside `bounds` (m) with CGAL Mesh_3. The solid must lie
// strictly inside `bounds` (every grid sample on the box's faces outside) and cross at least one
// edge of the seeding grid. Output tets are positively oriented (TetMesh convention), nodes are
// only the vertices of the tets, regions number the connected components from 1. The solid is
// evaluated through its const, thread-safe Value(). Throws CgalMeshError (see above) and
// CgalMeshCancelled.
TetMesh MeshImplicitWithCgal(const CompiledSolid& solid, const Eigen::AlignedBox3d& bounds,
                             const CgalMeshSettings& settings, CgalMeshStats* stats = nullptr);

// The boundary of a tet mesh whose tets are positively oriented: the faces that belong to one
// tet only, each counter-clockwise seen from outside (right-hand normal out of the mesh), over
// the boundary nodes only (vertices keep the order of their node indices). For a closed mesh of
// the solid it is a closed surface that MeasureSurfaceError and MeshVolume accept; used to
// compare the surfaces of the CGAL and TetGen paths.
TriangleMesh BoundarySurface(const TetMesh& mesh);

}  // namespace spidarcad::modeling
