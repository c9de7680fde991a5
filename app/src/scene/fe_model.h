// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
// An FE part ready to be touched (FE mode): a tetrahedral mesh with one material and clamped
// regions, assembled and factored once (fem::StaticSolver; or fem::SubstructuredSolver when the
// mesh comes in slabs, so that a model of an edited part keeps the factors of the slabs the edit
// did not reach: FeModelSettings::element_block and reuse), with lazily computed compliance
// columns of its surface nodes (fem::ColumnCache, reused from the disk cache when the same model
// was seen before), and the stress recovery the display needs (von Mises on the surface).
//
// Frames and units: the mesh is given in the world frame W (m); displacements in m, forces in N
// (ON the body), stresses in Pa. No VTK or ImGui here.
//
// Threads: Build runs on a Job's worker (progress and cancel); a built model is shared between
// the main thread (display, stress) and the haptic thread (FeTouchField reads the ColumnCache).
// Only the ColumnCache's worker uses the StaticSolver while it runs (CHOLMOD is not re-entrant).
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <atomic>
#include <chrono>
#include <cstdint>
#include <filesystem>
#include <functional>
#include <memory>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

#include "doc/document.h"
#include "spidarcad/fem/boundary.h"
#include "spidarcad/fem/column_cache.h"
#include "spidarcad/fem/material.h"
#include "spidarcad/fem/mesh.h"
#include "spidarcad/fem/precompute_cache.h"
#include "spidarcad/fem/static_solver.h"
#include "spidarcad/fem/substructure.h"
#include "spidarcad/modeling/implicit_evaluator.h"

namespace spidarcad::app {

// Thrown by FeModel::Build when its cancel flag was raised; nothing was kept or written.
class FeModelCancelled : public std::runtime_error {
 public:
  FeModelCancelled() : std::runtime_error("FE precompute cancelled") {}
};

// A named material preset of the FE panel.
struct MaterialPreset {
  const char* name;
  fem::Material material;  // E [Pa], ν [-]
};

// Steel (200 GPa, 0.30), aluminium (70 GPa, 0.33), ABS (2.3 GPa, 0.35).
inline constexpr MaterialPreset kMaterialPresets[] = {
    {"steel", {200.0e9, 0.30}},
    {"aluminium", {70.0e9, 0.33}},
    {"ABS", {2.3e9, 0.35}},
};

// Settings of FeModel::Build (libfive style: documented fields, progress, cancel).
// Default thickness of the clamped minimum-x face layer as a fraction of the part's largest
// bounding-box side (FeModelSettings::min_x_tolerance < 0): 3 mm on the 0.3 m platform, which
// holds its wall face x = 0 and the weld lip 1 mm proud of it at every cell size.
inline constexpr double kMinXFaceLayer = 0.01;

// Least cosine between a surface node's design normal (the gradient of the solid it was meshed
// from) and its mesh normal for the design normal to be taken (FeModel::design_normals): 60
// degrees. Beyond it the node is on a crease the gradient resolves to one side only, or the design
// is not the mesh's, and the mesh normal is kept.
inline constexpr double kDesignNormalAgreement = 0.5;

class FeModel;

struct FeModelSettings {
  // The material of the part (of every region not listed in region_materials).
  fem::Material material = kMaterialPresets[0].material;
  // Materials of single regions (fem::TetMesh::regions labels, each listed once). Empty: one
  // material, and the mesh's region labels are ignored (set to 0).
  std::vector<RegionMaterial> region_materials;
  // Element order: 1 (4-node) or 2 (10-node, midside nodes added with fem::MakeQuadratic).
  int order = 1;
  // Clamped regions: every node inside one of these boxes (W, m) is fixed. Empty: the nodes on
  // the minimum-x face (x <= min x + min_x_tolerance), e.g. the wall of
  // assets/scenes/platform.json.
  std::vector<Eigen::AlignedBox3d> fixed_boxes;
  // Thickness of the minimum-x face layer, m; < 0: kMinXFaceLayer times the largest side of the
  // mesh's bounding box (the same layer at every cell size).
  double min_x_tolerance = -1.0;
  // Loads: each box's total force (N, W) spread evenly over the mesh nodes inside its box (W, m,
  // closed; counted after the order upgrade, so midside nodes take their share). They give the
  // model's baseline displacement (fem::ColumnCache::baseline()); the reaction of the clamps
  // balances them.
  std::vector<FeLoad> loads;
  // The design the mesh was made from (the implicit solid, W, m), when it is known and the mesh is
  // up to date with it; null: none. Its gradient gives the design normals of the surface nodes
  // (FeModel::design_normals), which FE mode's tool pushes along; the model's stiffness does not
  // depend on it.
  std::shared_ptr<const modeling::CompiledSolid> design;
  // Slab (block) of each element of the mesh given to Build (scene/slab_fe_mesh.h's
  // SlabFeMesh::slab), in its element order; empty: one piece. With labels the model is factored
  // by fem::SubstructuredSolver (the same displacements as the one-piece factor to about 1e-12
  // relative), and the factor of each slab whose content (elements, nodes, material, clamps) is
  // unchanged from `reuse` is shared instead of recomputed.
  Eigen::VectorXi element_block;
  // With element_block: the slab of each block when slabs have strips (SlabFeMesh::piece_slab,
  // fem::SubstructuredSolver's block_place); empty: each block is a slab.
  std::vector<int> block_place;
  // A model of an earlier version of the part (may be null; read only, while Build runs: the
  // factors it shares are reference counted). Used only with element_block, when it was itself
  // built in slabs.
  std::shared_ptr<const FeModel> reuse;
  // Lazy compliance columns (precision, memory bound, worker). start_worker is honoured after
  // the disk cache was imported.
  fem::ColumnCacheSettings cache;
  // Look up (and later save) columns in the disk cache.
  bool use_disk_cache = true;
  // Disk cache directory; empty: fem::DefaultCacheDirectory(). In slabs, with use_disk_cache,
  // each slab's factor and the interface planes are looked up there and written there (by the
  // solver's own thread: fem::SubstructuredSolver), so that a reopened document, or a model that
  // differs from an earlier one by a local edit, reads the slabs it shares instead of factoring
  // them.
  std::filesystem::path cache_directory;
  // Bound (bytes) of the slab factors, interface planes and slab meshes (FeMeshInput's) in the
  // cache directory together: before it factors in slabs, Build removes the least recently used
  // files above it (fem::PruneCacheDirectory). Column sets are not counted.
  std::uintmax_t cache_max_bytes = std::uintmax_t{4} << 30;
  // Fraction done in [0, 1] at phase boundaries; may be empty.
  std::function<void(double)> progress;
  // Phase text ("factor", "columns", ...); may be empty.
  std::function<void(const std::string&)> phase;
  // When not null and set, Build throws FeModelCancelled at the next phase boundary, or within
  // milliseconds while CHOLMOD factorises when a worker program is set (the window: the
  // factorisation then runs in a child process that the flag kills, scene/worker_process.h).
  // In slabs it is read before each slab's factorisation and before the interface's (in this
  // process: a cancel waits for the slab being factored).
  const std::atomic<bool>* cancel = nullptr;
};

// An assembled, factored FE part with lazy surface compliance columns.
class FeModel {
 public:
  // Builds the model: validates, upgrades to `settings.order`, clamps, assembles and factors,
  // extracts the surface, precomputes per-element stress operators of the surface elements,
  // creates the ColumnCache (imports columns from the disk cache when its key matches).
  // Throws std::invalid_argument for a bad mesh, material or constraint (naming what),
  // std::runtime_error when the factorisation fails, FeModelCancelled on cancel. Either a
  // whole model comes back or nothing does.
  static std::unique_ptr<FeModel> Build(fem::TetMesh mesh, const FeModelSettings& settings);
  // Stops the column worker first.
  ~FeModel();
  FeModel(const FeModel&) = delete;
  FeModel& operator=(const FeModel&) = delete;

  // The mesh (W, m), after the order upgrade.
  const fem::TetMesh& mesh() const { return mesh_; }
  // Its boundary.
  const fem::Surface& surface() const { return surface_; }
  // The material used.
  const fem::Material& material() const { return material_; }
  // Constraints and loads (clamps and the settings' box loads).
  const fem::BoundaryConditions& bcs() const { return *bcs_; }
  // Materials by region.
  const fem::MaterialTable& materials() const { return *materials_; }
  // Mesh nodes of each load of the settings (in order), each sharing its force evenly.
  const std::vector<std::vector<int>>& load_nodes() const { return load_nodes_; }
  // The factored model: one of the two is set. The one-piece factor (use only while the cache
  // worker is stopped: CHOLMOD's solve is not re-entrant); null in slabs.
  const fem::StaticSolver* static_solver() const { return solver_.get(); }
  // The factor in slabs (its solves are re-entrant); null in one piece.
  const fem::SubstructuredSolver* substructured() const { return substructured_.get(); }
  // Completes the factor in slabs from both ends for the next edit's model
  // (fem::SubstructuredSolver::PrepareReuse) on a thread of the model's own: started once (later
  // calls do nothing; nothing in one piece). Its dense BLAS takes the cores, so FE mode starts it
  // once the columns near the tool are ready. A model built with this one as its reuse model
  // before it has finished waits for it (or runs it, when it was never started).
  void PrepareReuseInBackground();
  // Waits until the preparation started by PrepareReuseInBackground has finished (returns at
  // once when it was not started).
  void WaitReusePrepared();
  // True once PrepareReuseInBackground has started it (call from the thread that starts it).
  bool reuse_preparation_started() const { return prepare_reuse_.joinable(); }
  // Seconds since Build returned this model.
  double age_seconds() const;
  // Its status (a built model's converged).
  const fem::SolveStatus& factor_status() const;
  // The lazy compliance columns: candidates = surface nodes, outputs = nodes of the surface
  // elements (so that their stress can be recovered from the columns).
  fem::ColumnCache& cache() { return *cache_; }
  const fem::ColumnCache& cache() const { return *cache_; }
  // Number of clamped nodes.
  int num_fixed_nodes() const { return num_fixed_nodes_; }
  // Mean length of the boundary edges, m (a natural tool radius).
  double mean_edge_length() const { return mean_edge_; }
  // Outward unit normal of each candidate (surface node), #candidates by 3 (area-weighted
  // average of its faces' normals).
  const Eigen::MatrixX3d& candidate_normals() const { return normals_; }
  // Outward unit normal of the design's surface at each candidate, #candidates by 3: the
  // normalised gradient of FeModelSettings::design at the node's position where it is finite and
  // within kDesignNormalAgreement of the mesh's normal, else the mesh's normal
  // (candidate_normals). Without a design, candidate_normals. A coarse mesh cannot follow a
  // rounded edge: its facets there slope by degrees where the design is flat (4.6 degrees near
  // the platform's free corner at 12.5 mm cells), and the design normal is the surface's.
  const Eigen::MatrixX3d& design_normals() const { return design_normals_; }
  // Candidates whose design normal came from the design (0 without one).
  int num_design_normals() const { return num_design_normals_; }
  // Nodes whose columns came from the disk cache.
  int imported_nodes() const { return imported_nodes_; }
  // Disk-cache key of the columns.
  std::uint64_t cache_key() const { return key_; }
  // Wall time of Build, s.
  double build_seconds() const { return build_seconds_; }

  // Elements that own a boundary face (sorted, unique).
  const std::vector<int>& surface_elements() const { return surface_elements_; }
  // Output-list index of mesh node v, or −1 if v is not an output node.
  int OutputIndexOfNode(int v) const { return output_index_[v]; }

  // Von Mises stress (Pa) at the centroid of each surface element (#surface_elements) for the
  // output displacement u_out (3·#outputs, as ColumnCache/CachedContactSolver produce).
  // Allocates: main thread.
  Eigen::VectorXd SurfaceElementVonMises(const Eigen::VectorXd& u_out) const;
  // Volume-weighted average of SurfaceElementVonMises onto the nodes of those elements;
  // returns #V values (0 for nodes in no surface element), Pa.
  Eigen::VectorXd NodalVonMises(const Eigen::VectorXd& u_out) const;
  // Scatters u_out (3·#outputs) into a full displacement (#V by 3, zero at non-output nodes).
  Eigen::MatrixX3d FullDisplacement(const Eigen::VectorXd& u_out) const;

  // Writes the ready columns to the disk cache (stops and restarts the worker). Returns false
  // and the reason in *error when it cannot be written or use_disk_cache was off.
  bool SaveColumns(std::string* error = nullptr);

 private:
  FeModel() = default;
  fem::TetMesh mesh_;
  fem::Material material_;
  fem::Surface surface_;
  std::unique_ptr<fem::MaterialTable> materials_;
  std::unique_ptr<fem::BoundaryConditions> bcs_;
  std::unique_ptr<fem::StaticSolver> solver_;
  std::unique_ptr<fem::SubstructuredSolver> substructured_;
  std::unique_ptr<fem::ColumnCache> cache_;
  // Completes substructured_'s interface factor from both ends once the model is ready
  // (fem::SubstructuredSolver::PrepareReuse): the next edit's model keeps the planes beyond it.
  std::thread prepare_reuse_;
  std::chrono::steady_clock::time_point built_at_;
  std::vector<int> output_nodes_, output_index_;
  std::vector<int> surface_elements_;
  std::vector<Eigen::MatrixXd> stress_ops_;  // per surface element: D·B at the centroid, 6 by 3·npe
  std::vector<double> element_volume_;
  Eigen::MatrixX3d normals_;
  Eigen::MatrixX3d design_normals_;
  int num_design_normals_ = 0;
  std::vector<std::vector<int>> load_nodes_;
  int num_fixed_nodes_ = 0;
  double mean_edge_ = 0.0;
  int imported_nodes_ = 0;
  std::uint64_t key_ = 0;
  bool use_disk_cache_ = false;
  std::filesystem::path cache_directory_;
  double build_seconds_ = 0.0;
};

// The FE setup of a document's FE model in `base` (which keeps everything else: disk cache,
// column settings, progress, cancel): material, region materials, fixed boxes, loads and element
// order. Empty fixed_boxes keep Build's default clamp (the minimum-x face).
FeModelSettings ApplyFeModelData(const FeModelData& data, FeModelSettings base = {});

// The linear tetrahedral mesh of a document FE model (W, m; regions as stored). Throws
// DocumentError when the model's mesh object is missing or holds no volume mesh.
fem::TetMesh FeMeshOf(const Document& doc, const FeModelData& data);

// A material table: `material` for every region but those of `regions`. Throws
// std::invalid_argument naming the region when one is listed twice or its material is invalid.
fem::MaterialTable MakeMaterialTable(const fem::Material& material,
                                     const std::vector<RegionMaterial>& regions);

// Adds every load to bcs: its force split evenly over the mesh nodes inside its box (closed).
// Returns the nodes of each load. Throws std::invalid_argument naming the load (its index and
// box) when its box is empty or holds no node, or its force is not finite.
std::vector<std::vector<int>> AddBoxLoads(const fem::TetMesh& mesh,
                                          const std::vector<FeLoad>& loads,
                                          fem::BoundaryConditions* bcs);

// The nodes FeModel::Build clamps when no fixed box is given: the minimum-x face layer, every node
// with x <= min x + tolerance (m; < 0: kMinXFaceLayer times the largest side of the nodes'
// bounding box). Mesh node indices, ascending.
std::vector<int> MinXFaceNodes(const fem::TetMesh& mesh, double tolerance = -1.0);

// Meshes solid `solid_name` (empty: the first) of a scene file for FE: surface on a grid of
// `resolution` m (modeling::MeshSurface; by the lattice route with `lattice`, else marching
// tetrahedra with modeling::SurfaceMeshSettings::flat_coarsen_cells = `flat_cells`), then TetGen
// (quality bound 2), linear tetrahedra in W. Polls `cancel` between stages (throws
// FeModelCancelled) and reports progress in [0, 1]. Throws InputError naming the file or solid on
// bad input, modeling's errors on meshing failure.
fem::TetMesh MeshSceneSolidForFe(const std::string& scene_path, const std::string& solid_name,
                                 double resolution, const std::atomic<bool>* cancel = nullptr,
                                 const std::function<void(double)>& progress = {},
                                 bool lattice = false, double flat_cells = 0.0);

// assets/scenes/platform.json of the source tree (the demo part of FE mode):
// $SPIDARCAD_PLATFORM_SCENE when set, else found from this source file's location, else relative to
// the working directory.
std::string PlatformScenePath();

// Adds to u (3·#outputs of `cache`, m) the displacement under nodal forces ON the body at n
// slots: slot s acts at candidate node candidate[s] with force force[3s..3s+2] (N), read from
// the column of candidate substitute[s] shifted to candidate[s] (as
// CachedContactSolver::OutputDisplacement does; substitute −1: no column). Each column is pinned
// while it is read; a column evicted meanwhile, or holding only its near rows so far
// (ColumnCacheSettings::near_rows_first), is skipped. Returns the slots skipped. Main
// thread (the drawing of a pushed or grabbed FE part).
int AddSlotForcesDisplacement(fem::ColumnCache* cache, int n, const int* candidate,
                              const int* substitute, const double* force, double* u);

}  // namespace spidarcad::app
