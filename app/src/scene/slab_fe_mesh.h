// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
// The FE mesh of a solid in slabs across x (modeling/slab_mesher.h), made so that a local edit
// re-meshes only the slabs it reached: the surface on a grid that is kept from the first mesh on
// (MeshSurface is local on a fixed grid: an edit changes triangles within about a cell of it),
// cut by planes placed from the grid box alone (half-way between grid planes, so they stay put
// when the solid changes inside the box; each cross-section gets interior points at the cell
// spacing, SlabCut::section_spacing), each slab tetrahedralized only when its input differs
// from the slab of an earlier mesh (SurfaceHash, then compared in full), and the slabs joined.
// An unchanged slab keeps its nodes and tets bit for bit, in the same local order, so that
// fem::SubstructuredSolver reuses its factor.
//
// Units: m, world frame W. Main thread or a Job's worker.
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <atomic>
#include <cstdint>
#include <filesystem>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "spidarcad/fem/mesh.h"
#include "spidarcad/modeling/implicit_evaluator.h"
#include "spidarcad/modeling/slab_mesher.h"
#include "spidarcad/modeling/tet_mesh.h"

namespace spidarcad::app {

// A solid's FE mesh in slabs, with what is needed to re-mesh it after an edit.
struct SlabFeMesh {
  // Linear tetrahedra of every slab joined (W, m); regions 0: in fem's layout, and in modeling's
  // (shared, e.g. with the mesh object that holds it).
  fem::TetMesh mesh;
  std::shared_ptr<const modeling::TetMesh> volume;
  // Piece of each element: its slab, or its strip of a slab cut into strips (below; fem::
  // SubstructuredSolver's element_block).
  Eigen::VectorXi slab;
  // The cutting planes x = planes[k] (m), and the grid they were placed on.
  std::vector<double> planes;
  Eigen::AlignedBox3d grid_bounds;
  double cell = 0.0;
  // Strips (modeling::SlabCut::strip_planes): slab k cut further across strip_axis at
  // strip_planes[k] (m); empty: no strips. The pieces (slabs, or strips of one) are numbered as
  // the cut numbers them; `slab`, slab_surfaces, slab_tets, remeshed and loaded are per piece.
  int strip_axis = 1;
  std::vector<std::vector<double>> strip_planes;
  // With strips, the slab of each piece (fem::SubstructuredSolver's block_place); else empty.
  std::vector<int> piece_slab;
  // Each piece's closed surface (TetGen's input, canonical order) and its tets.
  std::vector<modeling::TriangleMesh> slab_surfaces;
  std::vector<modeling::TetMesh> slab_tets;
  // Per piece: 1 when TetGen ran for it, 0 when it came from the earlier mesh or the cache
  // directory; and 1 when it came from the cache directory.
  std::vector<char> remeshed;
  std::vector<char> loaded;
  // Wall time (s) of looking pieces up in, and writing them to, the cache directory; and why a
  // piece's file was refused or not written (each line names the piece and the file).
  double cache_read_seconds = 0.0, cache_write_seconds = 0.0;
  std::vector<std::string> cache_notes;
  // Wall time (s) of the surface, the cut, TetGen (the re-meshed pieces, on as many threads as
  // there are cores when modeling::TetgenRunsConcurrently) and the join.
  double surface_seconds = 0.0, cut_seconds = 0.0, tetgen_seconds = 0.0, join_seconds = 0.0;
  // MeshSolidInSlabs: the grid placements its surface was meshed on (1: the first was kept), the
  // kept one's shift (cells along each axis: grid_bounds and planes moved with it, see
  // MeshSolidInSlabs) and the solid's volume (m³, modeling::EstimateSolidVolume over the
  // grid_bounds it was given). 0 from MeshSurfaceInSlabs.
  int grid_placements = 0;
  double grid_shift_cells = 0.0;
  double solid_volume = 0.0;
  // Number of pieces TetGen ran for.
  int num_remeshed() const;
};

// SlabMeshOptions::strips: a slab with over this many times the mean of the surface's triangles
// per slab is cut into strips (the platform's bracket slab: about twice the mean at 5 mm)...
inline constexpr double kStripSlabShare = 1.5;
// ...when it holds at least this many of them (SlabMeshOptions::strip_min_triangles). Strips add
// their planes to the interface group of the slab's plane, whose dense factor an edit of a strip
// then redoes (0.2 s at 5 mm): that pays for a large slab only (the platform at 5 mm, P1: the
// clamped-end edit 1.52-2.18 s -> 1.24-1.61 s; at 10 mm, P2, no gain beyond the run-to-run
// spread; docs/design/2026-12-07-bracket-strips.md).
inline constexpr long kStripMinTriangles = 10000;

// How MeshSolidInSlabs meshes, and what it may reuse.
struct SlabMeshOptions {
  // TetGen's radius-edge bound.
  double max_radius_edge = 2.0;
  // modeling::SurfaceMeshSettings::snap_cells of the surface (0: not snapped; the window uses
  // modeling::kProductSnapCells).
  double snap_cells = 0.0;
  // modeling::SurfaceMeshSettings::flat_coarsen_cells of the surface (0: off; `spidarcad fem
  // --flat-cells`).
  double flat_coarsen_cells = 0.0;
  // The surface by the lattice route (modeling::SurfaceMesher::kLattice; snap_cells unused)
  // instead of marching tetrahedra: fewer, better-shaped triangles, so fewer tetrahedra (the
  // platform at 10 mm in 4 slabs: 15,669 against 24,905) and a smaller interface. Its planes
  // come from SlabPlanes with these options.
  bool lattice = false;
  // Strips per large slab: a slab whose part of the surface holds more than
  // kStripSlabShare times the mean number of triangles per slab is cut into this many strips of
  // nearly equal width across the longer of the grid box's other two axes (spanning the slab's
  // part of the surface; each plane moved off the grid as SlabPlanes moves its planes; 0 or 1: no
  // strips). An earlier mesh's strips are kept (`previous`).
  int strips = 0;
  long strip_min_triangles = kStripMinTriangles;
  // A mesh of an earlier version of the solid (may be null; ignored unless made on the same grid
  // and planes): its slabs whose input is unchanged are taken as they are, and its strips.
  const SlabFeMesh* previous = nullptr;
  // With a directory, a slab not in `previous` is looked for there (<16 hex digits>.slab, keyed
  // by its closed surface and the bound; the surface is compared in full, the file checked by a
  // checksum; a bad file is ignored and noted in cache_notes) and a slab TetGen meshed is written
  // there (a write failure is noted, not thrown).
  std::filesystem::path cache_directory;
  // Polled by the surface mesher, by TetGen and between slabs (may be null): throws
  // modeling::MeshingCancelled or modeling::TetMeshingCancelled.
  const std::atomic<bool>* cancel = nullptr;
  // Fraction done in [0, 1] (may be empty).
  std::function<void(double)> progress;
};

// `slabs` − 1 planes across x cutting `grid_bounds` into slabs of nearly equal width, each moved
// to the nearest half-way point between two grid planes; with options.lattice, to the nearest
// quarter of a cell past a grid plane instead (the lattice mesher's vertices lie on the grid
// planes and half-way between them, and its edges run in those planes: a plane there would hold
// triangles). Give MeshSolidInSlabs the same options.
// With `axis` (0, 1, 2), across that axis instead.
std::vector<double> SlabPlanes(const Eigen::AlignedBox3d& grid_bounds, double cell, int slabs,
                               const SlabMeshOptions& options = {}, int axis = 0);

// Meshes `solid` on the grid (grid_bounds, cell) in the slabs of `planes`: the surface, then
// MeshSurfaceInSlabs with the cell as the spacing. The surface is modeling::
// MeshSurfaceKeepingVolume's: where a wall about a cell thick falls between the grid's planes
// (the surface's volume more than modeling::kSharpVolumeRetry off the solid's), the grid is moved
// by a fraction s of a cell along each axis (modeling::SharpGridPlacement); then the result's
// grid_bounds are the moved grid's and its planes are `planes` + s × cell, which keeps them where
// SlabPlanes put them relative to the grid's planes (grid_placements, grid_shift_cells). A later
// call on the result's grid_bounds and planes keeps the placement, and the slabs an edit did not
// reach. Throws what MeshSurface, CutSurfaceIntoSlabs and TetrahedralizeSlab throw.
SlabFeMesh MeshSolidInSlabs(const modeling::CompiledSolid& solid,
                            const Eigen::AlignedBox3d& grid_bounds, double cell,
                            const std::vector<double>& planes, const SlabMeshOptions& options = {});

// The piece of each element of a mesh made in slabs across x at `planes` and, with strips, in
// strip_planes[k] across strip_axis within slab k (SlabFeMesh::slab, by each element's centroid:
// e.g. of a mesh read back from a document), and the slab of each piece in *piece_slab
// (SlabFeMesh::piece_slab; cleared without strips).
Eigen::VectorXi SlabPieceLabels(const fem::TetMesh& mesh, const std::vector<double>& planes,
                                int strip_axis,
                                const std::vector<std::vector<double>>& strip_planes,
                                std::vector<int>* piece_slab);

// Tetrahedralizes a closed, outward-oriented surface (a sculpt, an imported mesh) in the slabs of
// `planes`: the cut snaps vertices within a tenth of `spacing` (m) onto the planes and puts
// interior points `spacing` apart in the cross-sections. `box` and `spacing` are recorded in the
// result as grid_bounds and cell (what a later call must repeat to reuse its slabs; snap_cells is
// not used). A surface edited in one place (a sculpt stroke moves only the vertices under the
// tool) gives back the slabs it did not reach as they were. Throws what CutSurfaceIntoSlabs and
// TetrahedralizeSlab throw.
SlabFeMesh MeshSurfaceInSlabs(const modeling::TriangleMesh& surface, const Eigen::AlignedBox3d& box,
                              double spacing, const std::vector<double>& planes,
                              const SlabMeshOptions& options = {});

// Planes for MeshSurfaceInSlabs on a surface from no grid (a sculpt): SlabPlanes(box, spacing,
// slabs), each moved by the least multiple of a tenth of the spacing (up to four, either way)
// that leaves no triangle with all three corners within the cut's snap (a tenth of the spacing)
// of it: the cut would snap such a triangle into the plane, and it refuses a triangle in a plane.
// A plane that no move clears stays where SlabPlanes put it.
std::vector<double> SurfaceSlabPlanes(const modeling::TriangleMesh& surface,
                                      const Eigen::AlignedBox3d& box, double spacing, int slabs);

// MeshSurfaceInSlabs's spacing for a surface that came from no grid (m): 1.4 times its median
// edge length, about the cell of a grid surface (whose median edge is about 0.73 cell). Throws
// std::invalid_argument for a surface without edges.
double SurfaceSlabSpacing(const modeling::TriangleMesh& surface);

}  // namespace spidarcad::app
