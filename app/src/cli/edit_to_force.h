// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
// Edit to first correct felt force on the platform (assets/scenes/platform.json), shared by
// build/bench/app_fem_substructure_bench and `spidarcad report` (section "edit"). A series of
// edits of growing size, each followed through the slab route (scene/slab_fe_mesh.h re-meshes the
// slabs the edit reached, fem::SubstructuredSolver refactors them and the planes of S from the
// first changed one on, SolveFreeInBlocks gives the felt patch's compliance from the patch's slab
// and S) against a full recompute as FE mode does it today (surface, one-piece TetGen,
// StaticSolver, the patch's columns). Steel, clamped at the wall face (MinXFaceNodes), the 8
// plate-top nodes nearest the free corner as the tool's patch.
//   edits   load holes r 4 -> 4.5 mm (last slab), bolt holes r 5.5 -> 6 mm (first slab),
//           gusset shortened 0.2 -> 0.17 m (the slabs it spans), plate 10 -> 11 mm (every slab)
// The edited scenes are written to <temp>/spidarcad-edit-bench/. During each update a 1 kHz
// contact tick runs on the old model (16 contacts on its ColumnCache, as FE mode keeps the old
// model until the new one is ready) on a haptics::LoopRunner: SCHED_FIFO 80 when permitted.
// Times: wall s (steady clock); CPU: process CPU s (CHOLMOD and OpenBLAS use every core).
#pragma once

#include <string>
#include <vector>

#include "spidarcad/modeling/tet_mesh.h"

namespace spidarcad::app {

// One edit followed through the slab route.
struct EditToForceRow {
  std::string edit;                                   // what was changed
  int remeshed = 0, refactored = 0, slabs = 0;        // slabs re-meshed and refactored, of slabs
  long long remeshed_tets = 0;                        // tets of the re-meshed slabs
  int planes = 0, planes_refactored = 0;              // planes of S (a chain), refactored
  double surface = 0, cut = 0, tetgen = 0, join = 0;  // the slab mesh's stages, s
  double blocks = 0;     // assembly, factorisation and S_b of the refactored slabs, s
  double interface = 0;  // S, s
  double patch = 0;      // the patch's compliance block, s
  double total_wall = 0, total_cpu = 0;  // edit -> first correct force (from reading the scene)
  double error = 0;  // relative difference of the patch block from a monolithic solve
  // The probe tick during the update: how it was scheduled (RealtimeStatusName: "fifo", ...),
  // ticks, thread CPU p99.9 and max, wake-up lateness p99.9 (µs; the runner's histogram gives
  // its maximum above 10 ms).
  std::string scheduling;
  int ticks = 0;
  double tick_cpu_p999 = 0, tick_cpu_max = 0, tick_late_p999 = 0;
};

// One case (element order, cell, slabs) with its full recompute and its edits.
struct EditToForceCase {
  // e.g. "P2 10 mm, 4 slabs" (", lattice" with the lattice surface, ", 3 strips", ", snap 0.2"
  // with snapped surfaces, ", flat 0.5" with flat fans coarsened)
  std::string name;
  int order = 1;    // element order
  double cell = 0;  // cell size, m
  int num_slabs = 0;
  bool lattice = false;         // every surface by the lattice route
  double flat_cells = 0.0;      // SurfaceMeshSettings::flat_coarsen_cells of every surface
  int strips = 0;               // SlabMeshOptions::strips (0: none)
  double snap_cells = 0.0;      // SurfaceMeshSettings::snap_cells of every surface
  int free = 0, interface = 0;  // free dofs, interface dofs of the fresh slab model
  double full_mesh = 0, full_factor = 0, full_patch = 0, full_cpu = 0;  // today's recompute, s
  double slab_fresh_wall = 0, slab_fresh_cpu = 0;  // every slab meshed and factored, s
  // The fresh model's interface factor completed from both ends for the edits to reuse
  // (SubstructuredSolver::PrepareReuse, which FE mode runs in the background), wall s.
  double prepare_reuse = 0;
  struct Quality {
    int tets = 0;
    modeling::TetQuality q;
    double hausdorff = 0.0;  // sampled one-sided surface error, m
  } one_piece, slabs;        // the one-piece mesh and the joined slab mesh
  std::vector<EditToForceRow> edits;
  double full_wall() const { return full_mesh + full_factor + full_patch; }
};

// How a case meshes: the surface route and the pieces.
struct EditToForceMeshing {
  bool lattice = false;     // every surface by the lattice route (SlabMeshOptions::lattice)
  double flat_cells = 0.0;  // > 0: flat fans coarsened (SurfaceMeshSettings::flat_coarsen_cells)
  // > 1: a large slab cut into this many strips, each a block of the solver, as FE mode cuts the
  // platform's bracket slab (SlabMeshOptions::strips, kFeStrips)
  int strips = 0;
  // SurfaceMeshSettings::snap_cells of every marching-tetrahedra surface (FE mode:
  // modeling::kProductSnapCells)
  double snap_cells = 0.0;
};

// Measures one case on the scene at `scene_path` (the platform): element order 1 or 2, cell
// size (m), number of slabs, the first `num_edits` edits of the list above (1..4), every surface
// (the full recompute's and the slabs') meshed as `meshing` says. Throws what meshing and
// loading throw.
EditToForceCase MeasureEditToForce(const std::string& scene_path, int order, double cell, int slabs,
                                   int num_edits = 4, const EditToForceMeshing& meshing = {});

// The markdown tables of `cases` (cases, edits, the tick during the update, mesh quality).
std::string EditToForceTables(const std::vector<EditToForceCase>& cases);

}  // namespace spidarcad::app
