// Feature sharpening of a surface mesh of an implicit solid: marching tetrahedra cuts the sharp
// edges (creases) and corners of boxes and booleans off by up to about one cell; this pass puts
// mesh vertices back onto the creases and corners of the true surface and flips edges so that
// chains of mesh edges run along them.
//
// Method (per iteration):
//  1. Planes of the true surface near each vertex: its own position and its one-ring neighbours
//     (mesh vertices lie on the surface), and the centroid of each adjacent triangle projected
//     onto the surface by Newton steps; each plane is the point with the unit gradient there.
//  2. A vertex whose plane normals spread by more than the crease angle is a feature vertex. Its
//     quadric error function sum_i (n_i·(x - p_i))² is minimised by a truncated SVD as in dual
//     contouring: singular values below singular_threshold × the largest are dropped, so the
//     minimiser is the point of the crease line nearest to the vertex (rank 2) or the corner
//     (rank 3). The point is projected onto the surface by Newton steps (curved creases).
//  3. Feature vertices are moved, nearest target first, when the move is at most
//     max_move_cells cells, keeps every adjacent triangle facing the same way as before and as
//     the surface, makes no triangle sharper than min_angle_deg (unless it already was), keeps
//     the vertex min_separation_cells away from every other vertex, and lowers the sampled
//     distance of the adjacent triangles to the surface, and none of the adjacent triangles then
//     meets, other than along what they share, a triangle around it (the same predicates as
//     CheckSurface). Otherwise the vertex stays.
//  4. Edges next to feature vertices are flipped when the flip lowers the sampled distance of
//     the two triangles to the surface by half, keeps both facing outward, makes no degenerate
//     triangle and folds neither triangle onto, or through, a triangle around it: this turns
//     the chamfer's diagonals into edges along the crease.
//  4b. Only with sliver_angle_deg > 0 (off by default), after the rounds: the triangles with an
//     angle below sliver_angle_deg, worst first, in up to 10 sweeps. A feature vertex that sits on
//     its target (on its crease or corner) is pinned: it neither moves nor goes, except that a
//     crease vertex may merge into a pinned neighbour. Each triangle tries: collapsing each of its
//     edges (into either end, or for two free ends into the midpoint put back on the surface), if
//     that keeps the link condition (the ends share only the two opposite vertices, which keep
//     three or more triangles); snapping its widest corner (over 90°) onto the opposite edge by
//     flipping that edge and moving the corner onto it (onto the crease, by the truncated SVD of
//     step 2 from the planes around the edge's ends, when both ends are pinned: the corner then is
//     pinned too); flipping each of its edges that does not join two pinned vertices; sliding each
//     pinned crease corner (not a corner of the solid) along its crease half way to a pinned
//     neighbour (two creases closer than a cell make needles across the narrow face between them);
//     moving each free corner towards the centroid of its neighbours in its tangent plane and back
//     onto the surface. An operation counts only if the smallest angle of the triangles it makes
//     exceeds that of every triangle it changes or removes (or equals it, within 1e-6 relative, on
//     fewer triangles under sliver_angle_deg), each new triangle faces as the one it replaces (or,
//     after a flip, as the pair did) and as the surface, their sampled distance to the surface
//     stays within the largest of the old one, sliver_deviation_cells and that of the triangles
//     around the corners of the changed ones (on curved faces the neighbours' chords), a crease
//     vertex merged into its neighbour or slid along its crease stays within that same distance of
//     the new triangles (the crease point it marked stays covered), moved vertices keep
//     min_separation_cells, and no changed triangle meets a triangle around it (as in step 3). Of
//     those that count, the one with the largest smallest angle is done. Where none counts, each
//     free corner is moved instead to where the smallest angle of its fan is largest (a pattern
//     search in its tangent plane, back onto the surface; sliver_fan_moves), under the same
//     tests. Collapses remove a vertex and two triangles. With sliver_fallback_deviation_cells, the
//     triangles left under sliver_angle_deg go through the same sweeps again with a looser distance
//     tolerance, and last with their feature vertices released (see that setting).
//  5. Then the triangles with an angle below relax_angle_deg: each corner that is not a feature
//     vertex moves towards the centroid of its neighbours in its tangent plane and back onto the
//     surface, and the longest edge flips (not a crease edge, the pair within 20° of a plane),
//     each kept only if it raises the smallest angle of the triangles it changes, keeps them
//     facing out and unfolded, and does not raise their sampled distance to the surface.
//  3b. Only with insert_corners (off by default): a corner target that no vertex could move onto
//     (step 3) gets a new vertex, splitting one triangle near it into three (see insert_corners).
// Only vertex moves, edge flips, (step 3b) triangle splits and (step 4b) edge collapses that pass
// the link test are used, so the mesh stays closed, manifold, consistently oriented and of the
// same genus; without steps 3b and 4b the vertex count and triangle count are unchanged.
// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#pragma once

#include <atomic>

#include "spidarcad/modeling/implicit_evaluator.h"
#include "spidarcad/modeling/surface_mesher.h"

namespace spidarcad::modeling {

// The sliver_angle_deg the product sharpens with (`spidarcad mesh --sharp`, the FE setup's sharp
// edges): on the platform at 4 mm it takes TetGen from 1.09 M tets, 34 s and a worst dihedral of
// 0.018° to 289 k tets, 3.6 s and 1.41° (docs/design/2026-12-04-surface-mesher-peers.md).
inline constexpr double kProductSliverAngleDeg = 10.0;
// The sliver_fallback_deviation_cells the product repairs with, wherever it sets
// kProductSliverAngleDeg: on the platform at its default cell (`spidarcad mesh --sharp`) it takes
// the triangles under 10° from 96 to none, the largest sampled distance to the surface from
// 0.651 to 0.659 mm (docs/design/2026-12-06-sliver-fallback.md).
inline constexpr double kProductSliverFallbackCells = 0.2;

// Settings of SharpenFeatures.
struct FeatureSettings {
  // Grid cell edge the mesh was made with (m), > 0: scales every length below.
  double cell_size = 0.002;
  // Plane normals near a vertex that spread by more than this (degrees, in (0, 180)) make it a
  // feature vertex.
  double crease_angle_deg = 30.0;
  // Rounds of (target, move, flip); each round sees the neighbourhoods the last one made.
  int iterations = 3;
  // Truncated SVD: singular values of the normal matrix below this fraction of the largest are
  // dropped (in (0, 1)).
  double singular_threshold = 0.1;
  // A vertex moves at most this many cells; farther targets are left alone (> 0).
  double max_move_cells = 1.5;
  // No moved vertex comes closer than this many cells to another vertex (>= 0).
  double min_separation_cells = 0.05;
  // Moves and flips may not make a triangle angle below this (degrees) unless the triangle
  // already had one.
  double min_angle_deg = 1.0;
  // After the rounds, triangles with an angle below this (degrees, in [0, 60); 0, the default:
  // off, until the sharpening tests have been rerun with it) get
  // their corners that are not feature vertices relaxed along the surface and their longest
  // edge flipped where that raises their smallest angle without moving the mesh away from the
  // surface (step 5 at the top of this file).
  double relax_angle_deg = 0.0;
  // After the rounds, triangles with an angle below this (degrees, in [0, 60); 0, the default:
  // off) are repaired by edge collapses, edge flips, snaps of a corner onto the crease edge
  // opposite it, slides of crease vertices along their crease and relaxation moves (step 4b at
  // the top of this file); the vertex and triangle counts then change.
  double sliver_angle_deg = 0.0;
  // Step 3b (off by default): a corner of the solid (rank 3) that no vertex could move onto gets
  // a new vertex there, splitting the triangle nearby that it lowers the sampled distance of most
  // (the same facing, angle, distance and fold tests as a move; none if a vertex lies within half
  // a cell of the corner). Surfaces whose vertices are sparse near corners need it: the lattice
  // mesher snaps the crossings around a box corner into vertices 1.5 to 3 cells away from it.
  // The vertex and triangle counts then change (two triangles and one vertex per corner).
  bool insert_corners = false;
  // The repair may leave a triangle's sampled distance to the surface up to the largest of
  // what the triangles it replaces had, what the triangles around them have, and this many
  // cells (>= 0).
  double sliver_deviation_cells = 0.01;
  // Triangles still sharper than sliver_angle_deg after that repair are repaired again (and
  // what those repairs change), with sliver_deviation_cells (at least 0.001) tripled at each
  // stage up to this many cells, then once more at this many cells with their feature vertices
  // released: they may move or go, as long as the crease or corner point each marked stays as
  // close to the new triangles as the distance bound allows. 0, the default, or any value not
  // above sliver_deviation_cells: no fallback. It trades distance to
  // the surface for angles only where the tight repair failed; a mesh the tight repair leaves
  // with no triangle under sliver_angle_deg comes out the same.
  double sliver_fallback_deviation_cells = 0.0;
  // Rounds of that last stage (in [1, 10]): after each, the feature vertices of the triangles
  // still sharper than sliver_angle_deg, those the round's own collapses and flips made
  // included, are released and the sweeps run again, while a round releases any. 1 is the
  // single release of before 2026-12-06 (the platform at 5 mm, `spidarcad mesh --sharp`: a
  // 9.15° triangle made around a crease vertex after the release; 3 rounds leave none).
  int sliver_release_rounds = 3;
  // Step 4b's last resort for a triangle no operation mends (on by default): each of its free
  // corners moved to where the smallest angle of its fan is largest, searched in its tangent
  // plane in steps from 0.2 cells down to 0.0125 cells, within half a cell, and put back on the
  // surface; done under the tests of every operation. Where a blend is smaller than a cell,
  // the centroid move overshoots or falls short and every other operation leaves some triangle
  // sharper (the platform: 31 of 84 product surfaces from 3 to 13 mm kept triangles under 10°
  // without it, 2 with it; docs/design/2026-12-07-fan-moves.md). false: as before 2026-12-07.
  bool sliver_fan_moves = true;
  // Polled between rounds and passes; when true SharpenFeatures throws MeshingCancelled.
  const std::atomic<bool>* cancel = nullptr;
};

// Figures of one SharpenFeatures run.
struct FeatureStats {
  long feature_vertices = 0;  // vertices classified as crease or corner (last round)
  long corner_vertices = 0;   // of which rank 3 (corners, last round)
  long vertices_moved = 0;    // moves done, over all rounds
  long edges_flipped = 0;     // flips done, over all rounds
  long rejected_moves = 0;    // feature targets a safety test refused
  long corners_inserted = 0;  // step 3b: vertices inserted at corners of the solid
  long relaxed = 0;           // relaxation moves and angle flips (step 5)
  long sliver_collapses = 0;  // step 4b: edge collapses
  long sliver_snaps = 0;      // step 4b: corners snapped onto the opposite edge (with its flip)
  long sliver_flips = 0;      // step 4b: edge flips
  long sliver_moves = 0;      // step 4b: relaxation moves and slides along creases
  double seconds = 0.0;
};

// Moves vertices of mesh (from MeshSurface of solid: closed, manifold, outward-oriented,
// vertices on the surface) onto the creases and corners of solid and flips edges along them
// (see the top of this file). Returns the sharpened mesh, same vertex and triangle counts
// unless settings.insert_corners (step 3b splits triangles) or settings.sliver_angle_deg > 0
// (step 4b collapses edges).
// Throws std::invalid_argument for bad settings or a mesh that is not a closed edge-manifold
// (index out of range, an edge not shared by exactly two triangles), MeshingCancelled on cancel.
TriangleMesh SharpenFeatures(const CompiledSolid& solid, TriangleMesh mesh,
                             const FeatureSettings& settings, FeatureStats* stats = nullptr);

// Grid placements MeshSharpSurface tries, as fractions of a cell along each axis (the grid of
// surface_settings first, then moved by a quarter, an eighth and three eighths of a cell).
inline constexpr double kSharpGridShifts[] = {0.0, 0.25, 0.125, 0.375};

// MeshSharpSurface's volume test: Halton points in the bounds; the volume error (relative to the
// solid's) past which it tries another grid placement, and the tolerance within which two
// placements' volumes count as equal.
inline constexpr int kSharpVolumePoints = 1 << 16;
inline constexpr double kSharpVolumeRetry = 0.05;
inline constexpr double kSharpVolumeTolerance = 0.02;

// Volume of `solid` inside `box` (m³): the share of `points` Halton points (bases 2, 3, 5) of
// the box where its value is negative, times the box's volume.
double EstimateSolidVolume(const CompiledSolid& solid, const Eigen::AlignedBox3d& box, int points);

// `settings` with its grid moved by `shift` cells along each axis, as MeshSharpSurface moves it:
// the bounds grown by a cell on every side (the grid, centred on them, keeps its nodes) and
// moved by the shift. A shift of 0 returns `settings` as they are.
SurfaceMeshSettings SharpGridPlacement(const SurfaceMeshSettings& settings, double shift);

// What MeshSharpSurface (or MeshSurfaceKeepingVolume) made, and how.
struct SharpSurface {
  TriangleMesh mesh;
  SurfaceMeshStats surface;          // of the placement kept
  FeatureStats features;             // of the placement kept
  int placements = 0;                // grid placements meshed (1: the first was kept)
  double grid_shift = 0.0;           // the kept placement's shift, cells along each axis
  long first_under = 0;              // triangles under sliver_angle_deg at the first placement
  double first_min_angle_deg = 0.0;  // smallest triangle angle at the first placement
  double first_volume_error = 0.0;   // (mesh − solid) / solid volume at the first placement
  double solid_volume = 0.0;         // EstimateSolidVolume over the bounds, m³
  double seconds = 0.0;              // wall time of every placement and the estimate, s
};

// MeshSurface of `solid` with `surface_settings`, then SharpenFeatures with `features`. Where
// a part is about a cell thick, its faces and creases fall in one cell: on some grid placements
// whole stretches of it are lost (the platform's 10 mm plate at 10 mm cells whose planes lie on
// its faces: a quarter of its volume left), and the sliver repair can leave triangles sharper
// than features.sliver_angle_deg that no local change mends. When the first placement leaves such
// a triangle, or a volume more than kSharpVolumeRetry off the solid's (EstimateSolidVolume over
// surface_settings.bounds), the grid is moved by the next of kSharpGridShifts cells along each
// axis (SharpGridPlacement: the bounds hold what they held) and the solid meshed and sharpened
// again, until a placement leaves neither. A placement counts only if its volume is as close to
// the solid's as the first's, or within kSharpVolumeTolerance of it. Of those the one kept has a
// volume within kSharpVolumeRetry if any does; then the fewest triangles under the angle (or,
// past kSharpVolumeRetry, the closest volume); then the closest volume (beyond
// kSharpVolumeTolerance), the fewest triangles under the angle, the largest smallest angle; then
// it comes first. A mesh the first placement makes well is that of
// MeshSurface and SharpenFeatures alone, at the cost of one run and the volume estimate. Throws
// what MeshSurface and SharpenFeatures throw.
SharpSurface MeshSharpSurface(const CompiledSolid& solid,
                              const SurfaceMeshSettings& surface_settings,
                              const FeatureSettings& features);

// MeshSurface of `solid` with `surface_settings` on the grid placements MeshSharpSurface tries,
// for the routes that do not sharpen: where the first placement's volume is more than
// kSharpVolumeRetry off the solid's (a wall about a cell thick fallen between grid planes), the
// grid is moved by the next of kSharpGridShifts cells and the solid meshed again, until a
// placement is within it; the one kept is chosen as MeshSharpSurface chooses, with no triangle
// counted as a sliver (features stay empty, first_under 0). Where the first placement keeps the
// volume the mesh is MeshSurface's, at the cost of the volume estimate. Throws what MeshSurface
// throws.
SharpSurface MeshSurfaceKeepingVolume(const CompiledSolid& solid,
                                      const SurfaceMeshSettings& surface_settings);

}  // namespace spidarcad::modeling
