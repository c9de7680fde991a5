// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
// Setting up an FE model from a document object (FE mode's "Set up FE" and "Refresh"), and meshing
// a solid into a mesh object (model mode's Surface and Tetrahedra), without a window: which
// objects can become an FE model, the meshing a Job runs on a copy of the source, and the
// commands that land its result as one undo step (add a mesh object, set up FE, refresh a mesh
// object whose source changed).
//
// Sources: an implicit solid (grid surface, optionally sharpened, then TetGen; or CGAL Mesh_3
// from the function), a sculpt object or a mesh object holding a closed surface (TetGen on that
// surface), a mesh object holding tetrahedra (used as it is). Units: m, SI; the meshes are in
// the world frame W. The Prepare*/command functions run on the main thread; MeshFeSource runs on a
// Job's worker and reads only its input.
#pragma once

#include <Eigen/Geometry>
#include <atomic>
#include <cstdint>
#include <filesystem>
#include <functional>
#include <memory>
#include <optional>
#include <string>

#include "doc/command.h"
#include "doc/document.h"
#include "scene/slab_fe_mesh.h"
#include "spidarcad/modeling/implicit_evaluator.h"
#include "spidarcad/modeling/implicit_node.h"
#include "spidarcad/modeling/surface_mesher.h"
#include "spidarcad/modeling/tet_mesh.h"

namespace spidarcad::app {

// What FE mode can do with an object.
enum class FeSourceKind {
  kNone,         // nothing (a rigid part, an open surface, a missing object)
  kFeModel,      // an FE model: used as it is
  kVolumeMesh,   // a mesh object with tetrahedra: an FE model is added on it
  kSurfaceMesh,  // a mesh object with a closed surface only: TetGen on it
  kSolid,        // an implicit solid: meshed (TetGen or CGAL)
  kSculpt,       // a sculpt object: TetGen on its (closed) mesh
};

// The kind of object `id` for FE mode (kNone when it has none or is not in the document).
FeSourceKind ClassifyFeSource(const Document& doc, ObjectId id);
// Short text of a kind ("solid", "sculpt", "surface mesh", "volume mesh", "FE model", "").
const char* FeSourceKindText(FeSourceKind kind);
// True when every edge of the mesh is shared by exactly two triangles in opposite directions
// (closed, edge-manifold, consistently oriented) and it has at least four triangles and four
// vertices (a tetrahedron: the fewest that bound a solid).
bool IsClosedSurface(const modeling::TriangleMesh& mesh);

// The FE model FE mode works on for object `id`: the object itself for an FE model; for a mesh
// the first FE model on it; for a solid, sculpt or surface mesh the first FE model on a mesh made
// from it (MeshData::source == id). 0 when there is none.
ObjectId FeModelFor(const Document& doc, ObjectId id);

// Cells across the largest side of a solid's box when no cell size is given.
inline constexpr double kFeCellsAcross = 25.0;

// Everything a meshing Job needs, copied from the document on the main thread.
struct FeMeshInput {
  ObjectId source = 0;                // the object meshed
  std::uint64_t source_revision = 0;  // its revision when copied
  std::string source_name;            // its name
  FeSourceKind kind = FeSourceKind::kNone;
  modeling::ImplicitNode root;  // the solid's tree (kSolid)
  std::shared_ptr<const modeling::TriangleMesh>
      surface;            // the closed surface (kSculpt, kSurfaceMesh)
  MeshSettings settings;  // how to mesh (cell_size 0: from the solid's size)
  // Make tetrahedra (true), or the boundary surface only (false: a solid's grid surface,
  // sharpened when settings.sharp_edges; a surface source's surface as it is).
  bool volume = true;
  // Tetrahedra of a solid or a sculpt in this many slabs across x (scene/slab_fe_mesh.h: a
  // solid's grid surface snapped as in one piece, or the sculpt's surface as it is, cut by
  // planes, TetGen per slab, the slabs joined), so that an FE model of it can be factored in
  // slabs and a later edit re-meshes and refactors only the slabs it reached. A sculpt's planes
  // and cross-section points are spaced by SurfaceSlabSpacing (1.4 median edges). 0: in one piece.
  // A solid's slabs are cut from the lattice route's surface with surface_mesher "lattice"
  // (SlabMeshOptions::lattice). Ignored (one piece) with settings.sharp_edges, max_tet_volume or
  // mesher "cgal", for a surface only and for the other kinds; a source the slabs fail for (a plane
  // through a gap in it) is meshed in one piece, FeMeshResult::slab_note saying why.
  int slabs = 0;
  // A solid's large slabs in this many strips (SlabMeshOptions::strips; 0: none), and the least
  // number of surface triangles a slab needs for them (SlabMeshOptions::strip_min_triangles).
  int strips = 0;
  long strip_min_triangles = kStripMinTriangles;
  // The slab mesh of an earlier version of the source (may be null): its box, spacing and planes
  // are kept, and its slabs whose input is unchanged are taken as they are, when it was made in
  // as many slabs and its box holds the source's (a solid: also at the same cell size).
  std::shared_ptr<const SlabFeMesh> previous_slabs;
  // In slabs: a slab that is not in previous_slabs is looked up in this directory, and a slab
  // TetGen meshed is written there (SlabMeshOptions::cache_directory); empty: neither.
  std::filesystem::path cache_directory;
  // The element order (1 or 2) SetUpFe gives the FE model it adds.
  int element_order = 1;
};

// MeshSettings::flat_cells of a solid FE mode meshes for quadratic elements: marching
// tetrahedra's flat faces coarsened to about a cell (edges under half a cell collapsed where the
// surface is planar). Quadratic elements keep their accuracy on the coarser faces with about half
// the nodes; linear ones lock more in bending on them, so they keep the plain surface
// (docs/design/2026-12-06-flat-faces.md, docs/fem.md §5).
inline constexpr double kQuadraticFlatCells = 0.5;

// The MeshSettings::flat_cells FE mode meshes `kind` with for elements of `order` (1 or 2):
// kQuadraticFlatCells for quadratic elements on a solid meshed by TetGen on the plain
// marching-tetrahedra surface (not CGAL, the lattice or sharp edges), else 0.
double FlatCellsForOrder(FeSourceKind kind, const MeshSettings& settings, int order);

// Slabs FE mode meshes a solid in (FeMeshInput::slabs): four measured best on the platform
// (docs/design/2026-12-05-interface-by-planes.md: six made the interface two thirds larger and
// every edit slower).
inline constexpr int kFeSlabs = 4;

// Strips FE mode cuts a solid's large slab into (FeMeshInput::strips): the platform's bracket
// slab, which holds about half of the part and all four bolt holes, into three across y, so that
// widening the holes re-meshes and refactors the two outer strips, not the whole slab
// (docs/design/2026-12-07-bracket-strips.md: four strips put a plane within a cell of the holes
// at 10 mm, and made the interface larger).
inline constexpr int kFeStrips = 3;

// The input to mesh `source` (a solid, sculpt or surface mesh) with `settings`. Throws
// DocumentError naming the object and what is wrong: not such a source, an open surface,
// mesher "cgal", sharp_edges or surface_mesher "lattice" for anything but a solid, the lattice
// with "cgal", an unknown surface mesher, a negative or non-finite setting, flat_cells outside
// [0, 1] or with anything but a solid meshed by TetGen on the marching-tetrahedra surface.
FeMeshInput PrepareFeMesh(const Document& doc, ObjectId source, const MeshSettings& settings);

// The input to mesh mesh object `mesh` again from its source with its stored settings, making
// what it holds (tetrahedra, or a surface only). Throws DocumentError when it is not a mesh made
// from a source, or the source is gone.
FeMeshInput PrepareFeRemesh(const Document& doc, ObjectId mesh);

// The input to mesh solid `source` into a mesh object (model mode's Mesh action): tetrahedra
// when `volume`, else its surface only. Throws DocumentError naming the object and what is wrong
// (as PrepareFeMesh, with messages starting "mesh"; mesher "cgal" needs `volume`).
FeMeshInput PrepareSolidMesh(const Document& doc, ObjectId source, const MeshSettings& settings,
                             bool volume);

// What a meshing Job made.
struct FeMeshResult {
  std::shared_ptr<const modeling::TriangleMesh> surface;  // boundary surface (m, W)
  std::shared_ptr<const modeling::TetMesh> volume;        // linear tetrahedra (m, W)
  MeshSettings settings;  // the settings used, cell_size resolved (0 for a surface source)
  // The mesh in slabs (FeMeshInput::slabs), whose `volume` is `volume`; null in one piece.
  std::shared_ptr<const SlabFeMesh> slabs;
  // Why slabs were asked for but the mesh is in one piece ("meshed in one piece: in 4 slabs it
  // failed (...)"), else "".
  std::string slab_note;
};

// Compiles a solid's tree and finds the box it is meshed on at `cell` m (<= 0: the largest side
// of its box found at 1 cm (which overestimates by up to about 1 cm per side) / kFeCellsAcross,
// returned in *cell): the solid's box padded by two cells. Throws
// std::invalid_argument naming `name` when the tree does not compile, the solid is empty or
// unbounded (reaches 10 m from the origin); modeling::MeshingCancelled when `cancel` (may be
// null) is raised during the box search.
Eigen::AlignedBox3d FeSolidBounds(const modeling::ImplicitNode& root, const std::string& name,
                                  double* cell, modeling::CompiledSolid* compiled,
                                  const std::atomic<bool>* cancel = nullptr);

// The cost of meshing a solid input's surface (as `spidarcad mesh` estimates it before running);
// nullopt for the other kinds and for CGAL. Its box search takes seconds for a long tape (a
// union of 100,000 spheres: about 6 s), so the window runs it in a Job: `cancel` (may be null)
// is read before every box it classifies. Throws as FeSolidBounds.
std::optional<modeling::SurfaceMeshEstimate> EstimateFeMesh(
    const FeMeshInput& input, const std::atomic<bool>* cancel = nullptr);
// The estimate's figure past `spidarcad mesh`'s default budget (docs/limits.md: 2^27 grid cells,
// 2 GiB, 2e11 tape instructions) as text ("estimated grid cells 3e8 is over 1.34e8"), or "" when
// it is within it.
std::string FeMeshOverBudget(const modeling::SurfaceMeshEstimate& estimate);
// The question to ask before meshing `input` of the object called `name` when its estimate is
// past that budget ("Meshing 'NAME' is large: ... (estimate; the limits ...)."); "" when it is
// within it or cannot be estimated (CGAL). Throws as EstimateFeMesh.
std::string LargeMeshQuestion(const std::string& name, const FeMeshInput& input,
                              const std::atomic<bool>* cancel = nullptr);

// Meshes the input (worker thread): a solid on the grid (MeshSurface, by the lattice route with
// surface_mesher "lattice"; SharpenFeatures when sharp_edges, inserting corners on the lattice)
// then TetGen, or CGAL Mesh_3; a closed surface by TetGen. Without input.volume
// the result holds the surface only (no TetGen; volume null). Polls `cancel` (throws
// the meshers' cancellation exceptions) and reports progress in [0, 1]. Throws
// std::invalid_argument or std::runtime_error saying what failed (empty surface, TetGen or CGAL
// errors).
FeMeshResult MeshFeSource(const FeMeshInput& input, const std::atomic<bool>* cancel = nullptr,
                          const std::function<void(double)>& progress = {});

// One undo step "Mesh NAME (surface)" or "Mesh NAME (tetrahedra)" (as input.volume): adds the
// mesh object "NAME surface" or "NAME tets" (names made unique) with source, source revision,
// settings and the meshes of `mesh`. Afterwards doc.last_created() is {mesh}. Do throws
// DocumentError (and changes nothing) when the source is gone or has changed since `input` was
// copied; the constructor throws std::invalid_argument when `mesh` lacks what input asked for.
std::unique_ptr<Command> AddMeshOf(const FeMeshInput& input, FeMeshResult mesh);

// One undo step "Set up FE for NAME": adds the mesh object "NAME tets" (source, source revision,
// settings, surface and volume of `mesh`) and the FE model "NAME FE" on it: steel, clamped at the
// minimum-x face (no fixed boxes), elements of input.element_order. Afterwards doc.last_created()
// is {mesh, FE model}. Do throws DocumentError (and changes nothing) when the source is gone or has
// changed since `input` was copied.
std::unique_ptr<Command> SetUpFe(const FeMeshInput& input, FeMeshResult mesh);

// One undo step "Set up FE for NAME" on a mesh object that holds tetrahedra: the FE model
// "NAME FE" (steel, minimum-x face clamp, elements of `element_order`). The new id is in
// doc.last_created().
std::unique_ptr<Command> SetUpFeOnMesh(const Document& doc, ObjectId mesh, int element_order = 1);

// One undo step "Refresh NAME mesh": the mesh object `mesh` gets the new surface and volume (or
// surface only, when input.volume is false), made from its source at input.source_revision with
// its stored settings; its FE models keep their
// settings (their precompute keys are cleared: the columns were of the old mesh). Do throws
// DocumentError when the source has changed since `input` was copied.
std::unique_ptr<Command> RefreshFeMesh(ObjectId mesh, const FeMeshInput& input,
                                       FeMeshResult result);

}  // namespace spidarcad::app
