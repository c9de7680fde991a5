// Surface meshing of an implicit solid: a closed, manifold, consistently oriented triangle mesh
// of the zero set on a regular grid (marching tetrahedra on the Kuhn subdivision of each cube,
// which is conforming across cubes, so the result is watertight). An octree descent with the
// solid's interval bounds skips every region the bounds prove wholly inside or outside; vertex
// positions are refined along the grid edge by regula falsi on the field.
//
// A clean-up pass then removes the zero-area, needle and cap triangles that marching
// tetrahedra makes where the surface passes at or near grid vertices (two mesh vertices at one
// point, collinear corners): edge collapses that respect the link condition (so the mesh stays a
// closed manifold of the same genus; the kept vertex keeps its position on the surface) and
// edge flips between nearly coplanar triangles. No collapse or flip turns a triangle over
// (against the field's gradient) or folds it onto, or through, a triangle around it.
//
// Grid values within 1e-6 cells of zero count as exactly zero, and zero as outside, so rounding
// noise on a face through grid vertices cannot make the surface weave through them; the
// vertices there coincide and are merged, and where the zero set pinches (a feature about one
// cell across) the few that cannot be merged are moved up to a twentieth of their grid edge
// into the solid, as far as their triangles allow without folding.
// So no two vertices of the clean mesh are within TetrahedralizeSurface's weld tolerance (1e-10
// of the box diagonal): welding, which can make a closed manifold non-manifold, finds nothing. A
// wall exactly one cell thick with both faces on grid planes has no grid vertex inside and is lost:
// use cells under half the thinnest wall.
//
// Limits: sharp edges of boxes and booleans are cut off by up to about one cell here;
// SharpenFeatures (feature_sharpening.h) restores them as a post-pass.
// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <atomic>
#include <functional>
#include <string>

#include "spidarcad/modeling/implicit_evaluator.h"

namespace spidarcad::modeling {

// A triangle mesh: vertices (3 by V, m) and triangles (3 by F, vertex indices), each triangle
// counter-clockwise seen from outside the solid (right-hand normal points out).
struct TriangleMesh {
  Eigen::Matrix3Xd vertices;
  Eigen::Matrix3Xi triangles;
};

// MeshSurface's two routes.
enum class SurfaceMesher {
  // Marching tetrahedra on the Kuhn subdivision of the grid's cubes, octree-pruned, then the
  // clean-up pass described above (the library's default: its frozen meshes).
  kMarchingTetrahedra,
  // Marching tetrahedra on the body-centred cubic lattice of the grid's corners and cell centres,
  // with every lattice vertex whose nearest crossing lies within lattice_snap of its edge moved
  // onto the surface first, so the crossings around it are one vertex and no clean-up is needed;
  // blocks of 4³ cells that the interval bounds place away from the surface are not sampled.
  // Closed and manifold (a snap that would join two fans at one vertex is undone); a lattice
  // vertex that cannot snap (a feature thinner than about two cells) keeps its edge crossings
  // at least 25 % of the edge away from it. Sharp edges are cut off as by the other route.
  // Figures: docs/design/2026-12-06-lattice-mesher.md.
  kLattice,
};

// Settings of MeshSurface.
struct SurfaceMeshSettings {
  // Region to mesh (m). The solid is clipped to it: where the solid crosses the region's
  // boundary the mesh is closed along the boundary, so the result is always closed.
  Eigen::AlignedBox3d bounds;
  // Grid cell edge (m), > 0. The grid has ceil(extent / cell_size) cells per axis.
  double cell_size = 0.002;
  // Regula falsi steps placing each vertex on its grid edge (0: linear interpolation only).
  int refine_steps = 4;
  // Clean-up pass (see above); false gives the raw marching-tetrahedra mesh.
  bool clean = true;
  // Clean-up: edges shorter than short_edge_fraction × cell_size are collapsed.
  double short_edge_fraction = 0.1;
  // Clean-up: triangles with an angle below this (degrees) get their short edge collapsed
  // (needles) or their long edge flipped (caps) when that keeps the surface's shape.
  double small_angle_deg = 15.0;
  // Clean-up: grid values within snap_cells × cell_size of zero count as zero (in [0, 0.25]; at
  // least 1e-6 is always used), so the surface runs through those grid vertices and the mesh
  // vertices that would crowd around them are one vertex there, then moved onto the surface.
  // Above 0 it also turns on a clean-up that never makes the worst triangle worse (collapses
  // keep the sharpest angle they replace or 15°) and then relaxes the corners of the triangles
  // still under 15° along the surface. 0.15 gives a worst angle of 9.4° to 15° on a sphere at
  // r/12 to r/50 (0.2: none under 10°), with 1 to 30 % more rms surface error; the library keeps 0
  // as its default (its frozen meshes), the product meshes with kProductSnapCells. Where the band
  // makes the zero set pinch at a grid vertex (a hole narrower than the band beside it) and the
  // clean-up cannot move the vertices there apart without a fold, that grid vertex keeps its own
  // value and the solid is meshed again (until 2026-12-05 this left self-intersections, e.g. in the
  // platform at 10 mm). An inside value within the band is snapped only where a grid neighbour lies
  // deeper than the band, so a wall thinner than 1 + 2 × snap_cells cells is kept (it was lost
  // before). Figures: docs/design/2026-12-04-surface-mesher-peers.md.
  double snap_cells = 0.0;
  // Clean-up, last: edges shorter than flat_coarsen_cells × cell_size are collapsed where the
  // vertex that goes lies in a flat fan (its triangles' normals within 0.01° of one another:
  // planar but for rounding), under the clean-up's other guards and with its angle guard (no fan's
  // worst triangle gets sharper than it was or than 15°); with snapping, the triangles still under
  // 15° are then polished again (in [0, 1]; 0: off). A face parallel to grid planes is cut alike
  // in every cell; where that cut makes no needle the clean-up has nothing to collapse and the face
  // keeps the raw triangles, several per cell face: the platform's plate top had 4,112 triangles
  // at 10 mm against 1,130 at 10.2 mm, its surface 15,120 against 6,302, and TetGen made 25,470
  // tets of it against 12,994.
  // Coarsening flat fans leaves the surface's shape as it was. Off by default everywhere (0.5
  // evens the platform's counts; `spidarcad mesh|fem|felt --flat-cells`): P2 models of the
  // coarsened surfaces have half the nodes at the same accuracy, but P1 ones lock more in bending.
  // Figures: docs/design/2026-12-06-flat-faces.md.
  double flat_coarsen_cells = 0.0;
  // Clean-up, with snapping, last of all: each triangle still sharper than this (degrees, in
  // [0, 20]; 0: off) is mended by the first of these that raises the smallest angle around it:
  // its pinch (vertices SeparateCoincident moved apart) opened wider along the same grid edges;
  // the clean-up's collapses and flips with edges up to a grid cube's diagonal; its cap flattened
  // into the neighbour across the long edge; a flip of another edge; a corner relaxed along the
  // surface. The moves keep what they change within the mesh's largest sampled distance to the
  // surface before the pass. A mesh with no triangle under the angle is left as it is. The
  // snapped marching-tetrahedra route left triangles under 10° (down to 1.8°) at holes about a
  // cell across; with this, none over the scene solids, across cells and grid placements.
  // Figures: docs/design/2026-12-06-mend-pass.md.
  double mend_angle_deg = 10.0;
  // Which route meshes the solid (see SurfaceMesher).
  SurfaceMesher mesher = SurfaceMesher::kMarchingTetrahedra;
  // kLattice: a lattice vertex moves onto the surface when its nearest crossing is within this
  // fraction of the lattice edge (in [0, kMaxLatticeSnap]; 0, or clean = false: no vertex moves).
  double lattice_snap = 0.35;
  // Polled during meshing; when it becomes true MeshSurface throws MeshingCancelled.
  const std::atomic<bool>* cancel = nullptr;
  // Called now and then with the fraction done in [0, 1].
  std::function<void(double)> progress;
};

// The largest SurfaceMeshSettings::lattice_snap MeshSurface accepts.
inline constexpr double kMaxLatticeSnap = 0.45;

// The snap_cells the product meshes with (`spidarcad mesh`, --snap-cells): SurfaceMeshSettings
// keeps 0 as its own default, so the library's frozen meshes stay as they are. Measured in
// docs/design/2026-12-04-surface-mesher-peers.md (addendum 2026-12-05).
inline constexpr double kProductSnapCells = 0.2;

// Figures of one MeshSurface run.
struct SurfaceMeshStats {
  long grid_cells = 0;       // cells of the full grid
  long evaluated_cells = 0;  // cells the interval bounds could not rule out
  long field_evaluations = 0;
  long collapsed_edges = 0;   // by the clean-up pass
  long flat_collapses = 0;    // of collapsed_edges: in flat fans (flat_coarsen_cells)
  long snapped_vertices = 0;  // kLattice: lattice vertices moved onto the surface
  long flipped_edges = 0;     // by the clean-up pass
  double seconds = 0.0;
};

// Thrown when SurfaceMeshSettings::cancel is raised.
class MeshingCancelled : public std::runtime_error {
 public:
  MeshingCancelled() : std::runtime_error("surface meshing cancelled") {}
};

// A box containing every part of the solid inside `search` (m), found by an octree descent with
// the interval bounds down to cells of edge <= `resolution`; it overestimates the tight box by
// at most about one cell per side. Empty when the bounds prove the solid absent from `search`.
// An unbounded solid (a half-space) fills the search box. One best-first search per side of the
// box, without recursion: its cost grows with the boxes needed to pin down each extreme (about
// the extreme's radius of curvature / resolution near a smooth pole), not with the whole
// surface. A resolution finer than kMinFindBoundsFraction of the search box's largest side is
// raised to it, which bounds that cost (and the depth) whatever the resolution (even 5e-324).
// Throws std::invalid_argument for a non-finite or empty search box or a resolution not > 0,
// and MeshingCancelled when `cancel` (may be null) is raised: it is read before every box is
// classified, so a long tape (a union of 100,000 primitives: seconds in all) stops within one
// classification.
Eigen::AlignedBox3d FindBounds(const CompiledSolid& solid, const Eigen::AlignedBox3d& search,
                               double resolution, const std::atomic<bool>* cancel = nullptr);
// Finest resolution FindBounds descends to, as a fraction of the search box's largest side.
inline constexpr double kMinFindBoundsFraction = 1.0 / (1 << 16);

// The cost of a MeshSurface run, estimated from the settings and a coarse octree look at the
// solid (EstimateSurfaceMesh) before any fine work. Counts are doubles: they may exceed every
// integer type, or be +inf for an absurd cell size.
struct SurfaceMeshEstimate {
  double grid_cells = 0.0;       // cells of the full grid: the product of ceil(extent / cell_size)
  double surface_cells = 0.0;    // cells the surface is expected to cross (meshed cells)
  double triangles = 0.0;        // triangles of the mesh, about four per surface cell
  int tape_instructions = 0;     // instructions run by one field evaluation
  double evaluation_cost = 0.0;  // instructions' worth of one evaluation (EvaluationCost())
  double evaluations = 0.0;      // field evaluations (grid vertices, refinement, bounds, clean-up)
  double work = 0.0;             // tape instructions executed: evaluations × evaluation_cost
  double bytes = 0.0;            // peak memory of the run, bytes
  // The figures on one line, e.g. "grid 1.2e+07 cells, surface ~3.1e+05 cells, ...".
  std::string Describe() const;
};

// Estimates the cost of MeshSurface(solid, settings) (docs/limits.md) cheaply (a few thousand
// interval classifications at most): counts the cells the interval bounds cannot rule out on a
// coarse grid of at most 32 cells across (fewer, down to 4, for tapes over 2000 instructions) and
// scales the count by the area ratio (coarse cell / cell)². Conservative: interval bounds are
// loose, so surface_cells errs high. Throws std::invalid_argument for bounds or a cell size
// MeshSurface would refuse as malformed (not for a grid that is merely too large: that is what the
// estimate is for).
SurfaceMeshEstimate EstimateSurfaceMesh(const CompiledSolid& solid,
                                        const SurfaceMeshSettings& settings);

// Meshes the zero set of solid inside settings.bounds. Throws std::invalid_argument for bad
// settings (empty bounds, cell_size <= 0, a grid over 2^30 cells) and MeshingCancelled.
TriangleMesh MeshSurface(const CompiledSolid& solid, const SurfaceMeshSettings& settings,
                         SurfaceMeshStats* stats = nullptr);

// Error of a mesh against the solid, measured as |value| at every vertex, edge midpoint and
// triangle centroid: for an exact-distance solid it is the distance to the true surface, so
// `max` is a sampled one-sided Hausdorff distance (mesh to surface), m.
struct SurfaceError {
  double max = 0.0;
  double rms = 0.0;
};
// Measures SurfaceError of mesh against solid.
SurfaceError MeasureSurfaceError(const CompiledSolid& solid, const TriangleMesh& mesh);

// Triangle shape figures of a mesh.
struct TriangleAngleStats {
  double min_angle_deg = 0.0;  // smallest angle of any triangle, degrees (0 for no triangles)
  long small_angle = 0;        // triangles with an angle below the threshold
  long zero_area = 0;          // triangles whose cross product is exactly zero
};
// Measures TriangleAngleStats of mesh; small_angle counts angles below small_angle_deg.
TriangleAngleStats MeasureTriangleAngles(const TriangleMesh& mesh, double small_angle_deg = 5.0);

// Enclosed volume of a closed, outward-oriented mesh (divergence theorem), m³.
double MeshVolume(const TriangleMesh& mesh);

}  // namespace spidarcad::modeling
