// The window's scene: an app::Document (doc/document.h) holding the implicit solids of a scene
// file (or the built-in demo) with their undo history, where they sit in the device workspace
// (X_WD, chosen at Load and never changed by edits), the compiled solids and their preview
// surfaces (meshed in the background: a view cache, not part of the Document), the HapticScene
// built from them, the Mesh action (a Job whose result lands in the Document as a mesh object:
// one undo step), refreshing a stale mesh object, and export.
//
// Edits go through document() (commands); Refresh() then recompiles the solids whose object
// revision moved and UpdatePreviews() re-meshes their previews: a coarse pass first (live
// preview while a parameter is dragged), then a fine one. A solid that fails to compile keeps its
// last good compiled solid, preview and haptics and carries the error text.
// Meshing runs as Jobs (doc/job.h); a job's result lands on the main thread through its
// finisher, a failed or cancelled job changes nothing, and a result made from an object
// revision that is no longer current is dropped (previews: an older pass never replaces a newer
// one; the Mesh action and Refresh: the job fails saying that the source changed). Main thread only
// (except what the jobs' work functions capture: immutable copies). Copyright the spidarcad
// authors. SPDX-License-Identifier: AGPL-3.0-or-later
#pragma once

#include <Eigen/Geometry>
#include <array>
#include <atomic>
#include <cstdint>
#include <filesystem>
#include <memory>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "doc/document.h"
#include "doc/job.h"
#include "scene/device_session.h"
#include "scene/fe_setup.h"
#include "scene/scene_fields.h"
#include "scene/scene_haptics.h"
#include "spidarcad/haptics/device_to_world.h"
#include "spidarcad/haptics/geometry.h"
#include "spidarcad/haptics/haptic_loop.h"
#include "spidarcad/modeling/implicit_evaluator.h"
#include "spidarcad/modeling/surface_mesher.h"
#include "spidarcad/modeling/tet_mesh.h"

namespace spidarcad::app {

// The scene name of the built-in demo scene (a bracket part and a knob within the device's reach).
inline constexpr const char* kDemoSceneName = "demo";
// The scene name of the empty scene.
inline constexpr const char* kNoSceneName = "none";
// Text of the built-in demo scene (spidarcad-scene JSON, version 1).
const char* DemoSceneJson();

// X_WD of the loop: p_W = world_scale · p_D + p_WDo (haptics/device_to_world.h).
using haptics::DeviceToWorld;

// Places `bounds_W` (the scene's solids, m) in reach of the grip: the scale is the smallest
// s >= 1 for which the box fits 80 % of the grip's travel across x and y and the lower part of
// its travel in z; the device centre maps to 6 cm (in D) above the middle of the box's top, so
// the grip starts outside every solid with the solids below it. The identity for an empty box.
// `travel` is the largest |p0| per axis the grip reaches in D (GripControl::limits()).
DeviceToWorld ChooseDeviceToWorld(const Eigen::AlignedBox3d& bounds_W,
                                  const Eigen::Vector3d& travel);

// Which mesh the Mesh action makes.
enum class MeshKind { kSurface, kTetrahedra };

// One solid of the scene (a solid object of the Document), compiled, and its preview surface.
struct SceneObject {
  ObjectId id = 0;  // the Document object
  std::string name;
  // Last good compiled solid (null only when the object never compiled) and the Document object
  // revision it was compiled from.
  std::shared_ptr<const modeling::CompiledSolid> solid;
  std::uint64_t source_revision = 0;
  // Why the object's current revision could not be compiled or meshed ("" when it is fine), and
  // that revision.
  std::string error;
  std::uint64_t error_revision = 0;
  Eigen::AlignedBox3d bounds_W;            // box of the solid, m (updated when a preview lands)
  std::array<double, 3> colour{};          // RGB in [0, 1] in the view
  modeling::TriangleMesh preview;          // background preview surface (empty until meshed)
  double preview_cell = 0.0;               // its grid cell, m
  double preview_cells_across = 0.0;       // its resolution (cells across the largest side)
  std::uint64_t preview_revision = 0;      // object revision it was meshed from (0: none)
  int preview_sequence = 0;                // start number of the landed preview job (newer wins)
  const Job* preview_job = nullptr;        // preview job in flight (compared with the queue's jobs,
                                           // never dereferenced on its own)
  std::uint64_t preview_job_revision = 0;  // object revision that job meshes
  double preview_job_cells_across = 0.0;   // and its resolution
  int revision = 0;                        // bumped whenever the preview changes
};

// A scene read, compiled and boxed by SceneModel::Prepare, to be taken by SceneModel::Adopt.
// Made on any thread (it shares nothing with a SceneModel); moved to the main thread whole.
struct PreparedScene {
  std::string source;
  std::unique_ptr<Document> doc;
  std::vector<SceneObject> objects;  // one per solid object, compiled, bounds_W found
  std::filesystem::file_time_type mtime{};
  // A version 1 scene file with assembly "parts" (docs/scene-format.md): the window keeps
  // X_WD = identity for it, as `spidarcad run` does. Found while the file is read (once).
  bool assembly = false;
};

// How far SceneModel::Prepare has come, for a progress display on another thread.
struct PrepareProgress {
  std::atomic<int> solids_done{0};   // solids compiled and boxed so far
  std::atomic<int> solids_total{0};  // 0 while the file is read
};

// The scene of the window.
class SceneModel {
 public:
  // Colours given to the solids in order (cycled).
  static const std::array<std::array<double, 3>, 3> kColours;

  // Preview resolutions (cells across the largest side of a solid's box): the coarse first pass
  // after an edit and the fine pass that follows once the object stops changing.
  static constexpr double kCoarseCellsAcross = 16.0;
  static constexpr double kFineCellsAcross = 48.0;

  SceneModel();
  ~SceneModel();
  SceneModel(const SceneModel&) = delete;
  SceneModel& operator=(const SceneModel&) = delete;

  // Loads `source`: kDemoSceneName, kNoSceneName or a scene file path, into a new Document (the
  // undo history starts empty). Compiles every solid and finds its box; places the scene with
  // ChooseDeviceToWorld(travel), or keeps `*keep` when given (a reload: the running loop's X_WD
  // cannot change). Throws std::runtime_error (or modeling::SceneError) naming the file and
  // solid when that fails; the model (and its Document) is then unchanged.
  void Load(const std::string& source, const Eigen::Vector3d& travel,
            const DeviceToWorld* keep = nullptr);
  // Load in two steps, so that the slow one can run off the main thread. Prepare reads
  // `source` into a new Document, compiles every solid and finds its box, touching no
  // SceneModel (any thread). `cancel` (may be null) is read after the file is read, after each
  // solid's compilation and before every box classification: modeling::MeshingCancelled when
  // it is raised. `progress` (may be null) is updated as it goes. It throws as Load. Adopt then
  // makes it this model's scene (main thread), placed as Load places it; it does not throw.
  static PreparedScene Prepare(const std::string& source, const std::atomic<bool>* cancel = nullptr,
                               PrepareProgress* progress = nullptr);
  void Adopt(PreparedScene&& prepared, const Eigen::Vector3d& travel,
             const DeviceToWorld* keep = nullptr);
  // Writes the Document as a scene file (temporary file renamed over `path`), which becomes the
  // source (its new mtime is not taken for an outside change). Throws modeling::SceneError.
  void Save(const std::string& path);
  // Brings the compiled solids in line with the Document after edits, undo or redo: recompiles
  // every solid object whose revision moved (a failure keeps the last good solid and sets
  // `error`), adds and drops objects. Returns true
  // when the set of compiled solids changed (the haptic scene must be rebuilt). Cheap when the
  // Document's revision has not moved.
  bool Refresh();
  // Starts preview jobs where needed, at most one in flight per object: a coarse pass for an
  // object whose preview is not from its current revision, else a fine pass when the preview
  // is coarse. Cancels a fine pass in flight when its object has changed since. Call once per
  // frame after JobQueue::Poll.
  void UpdatePreviews(JobQueue* jobs, double coarse_cells_across = kCoarseCellsAcross,
                      double fine_cells_across = kFineCellsAcross);
  // Starts a preview-surface job per compiled solid (cell = largest side / cells_across).
  void StartPreviewJobs(JobQueue* jobs, double cells_across = kFineCellsAcross);
  // Starts the Mesh action on solid `index` of objects() (scene/fe_setup.h): kSurface, its grid
  // surface at settings.cell_size m (sharpened when settings.sharp_edges); kTetrahedra, TetGen
  // (radius-edge bound 2 unless set) on that surface, or CGAL Mesh_3 (settings.mesher "cgal").
  // The job ("Surface of NAME" / "Tetrahedra of NAME") lands as one undo step, AddMeshOf: the
  // mesh object "NAME surface" / "NAME tets" (source, source revision, settings), whose id
  // TakeLandedMesh then returns. It fails, changing nothing, when the solid changed or was
  // deleted while it ran (the error says so); a cancelled job changes nothing. Returns the job.
  // Throws std::out_of_range for a bad index, std::invalid_argument when the solid does not
  // compile or the cell size is not > 0, DocumentError for bad settings.
  Job& StartMeshJob(JobQueue* jobs, int index, MeshKind kind, const MeshSettings& settings);
  // What StartMeshJob with these arguments would cost when that is past `spidarcad mesh`'s
  // default budget (docs/limits.md), as a sentence for the user naming the figure and the
  // estimate; "" when it is within the budget or cannot be estimated before meshing (CGAL).
  // Throws as StartMeshJob.
  std::string MeshJobOverBudget(int index, MeshKind kind, const MeshSettings& settings) const;
  // Starts meshing mesh object `mesh` again from its source with its stored settings
  // (PrepareFeRemesh): the job "Refresh NAME" lands as one undo step, RefreshFeMesh (FE models
  // on it keep their settings); fails, changing nothing, when the source changed meanwhile.
  // Throws DocumentError when `mesh` is not a mesh made from a source or the source is gone.
  Job& StartRefreshJob(JobQueue* jobs, ObjectId mesh);
  // The mesh object the latest Mesh action landed (0: none since the last call); cleared.
  ObjectId TakeLandedMesh() { return std::exchange(landed_mesh_, 0); }
  // True once the scene file changed on disk since it was loaded or saved (checked by mtime),
  // unless the Document has unsaved edits (a reload would lose them).
  bool SourceChanged() const;
  // Takes the scene file's present modification time as seen, so that SourceChanged is false
  // until the file changes again (a reload that failed or was cancelled is not retried).
  void TakeSourceChange();

  // The Document (edit it through commands, then call Refresh).
  Document& document() { return *doc_; }
  // Read-only Document.
  const Document& document() const { return *doc_; }
  // Position of the scene object of Document object `id` in objects(), or -1.
  int IndexOf(ObjectId id) const;

  // The haptic scene of the solids as `spidarcad run` renders them: the compiled solids go
  // through the same builder (scene/scene_haptics.h BuildSolidFields) with `options` (tool
  // model, stiffness, damping, friction, shell: as felt at the grip; the defaults are run's) at
  // this model's X_WD (options.world_scale and p_WDo are not read); a snap field when the
  // Document's scene has "snap" (features found again when the Document changed); the centring
  // springs when field.enabled. Each contact field is wrapped so that its state carries over
  // from the scene built by the previous call (scene/scene_fields.h: the same field when its
  // solid and the options are unchanged, else a warm start): call this for every scene the
  // window publishes. Throws std::invalid_argument for bad options.
  std::unique_ptr<haptics::HapticScene> BuildHapticScene(const DemoFieldSettings& field,
                                                         const SceneHapticsOptions& options = {});
  // The markers of the contact fields of the latest BuildHapticScene (one per solid for the
  // proxy, one for the shell), as their fields last published them. Main thread only (it is the
  // one reader of their triple buffers).
  std::vector<ContactMarker> ContactMarkers();

  const std::vector<SceneObject>& objects() const { return objects_; }
  const DeviceToWorld& device_to_world() const { return x_wd_; }
  // Replaces X_WD (the window on the virtual clock takes the scripted run's, scripted_run.h).
  void set_device_to_world(const DeviceToWorld& x_wd) { x_wd_ = x_wd; }
  const std::string& source() const { return source_; }
  const std::string& description() const { return doc_->description(); }
  // Incremented by every Load (jobs of an older scene are dropped when they finish).
  int generation() const { return generation_; }

 private:
  // Starts one preview job for `object` (an element of objects_) at this resolution.
  void StartPreview(JobQueue* jobs, SceneObject* object, double cells_across);
  // Starts a job meshing `input` whose finisher (unless the scene was reloaded meanwhile)
  // executes on the Document AddMeshOf (mesh 0: a new mesh object, recorded for TakeLandedMesh)
  // or RefreshFeMesh of mesh object `mesh`.
  Job& StartDocumentMeshJob(JobQueue* jobs, std::string title, FeMeshInput input, ObjectId mesh);
  // The meshing input of StartMeshJob (checked as it says).
  FeMeshInput MeshJobInput(int index, MeshKind kind, const MeshSettings& settings) const;

  // The contact fields of the latest BuildHapticScene: per solid object (proxy) or one for the
  // scene (shell, id 0), what they were built from, the field that runs (`current`), the fresh
  // one its wrapper falls back on, and the channel that carries state to the next scene.
  struct ContactEntry {
    ObjectId id = 0;
    ToolModel tool = ToolModel::kProxy;
    std::vector<const modeling::CompiledSolid*> solids;
    SceneHapticsOptions options;
    double world_scale = 0.0;
    std::shared_ptr<haptics::ForceField> current;
    std::shared_ptr<haptics::ForceField> fallback;
    std::shared_ptr<ContactChannel> channel;
  };
  // The entry of `id` from contacts_ (moved out), or a new one; brings `current` up to date
  // with what ran (the fallback, when its wrapper used it) and drops it when the key changed.
  ContactEntry TakeContactEntry(ObjectId id, ToolModel tool,
                                const std::vector<const modeling::CompiledSolid*>& solids,
                                const SceneHapticsOptions& options, double world_scale);

  std::vector<ContactEntry> contacts_;
  std::optional<SnapInput> snap_input_;  // snap features of the Document at snap_revision_
  std::uint64_t snap_revision_ = 0;
  int snap_generation_ = -1;
  double snap_tolerance_ = 0.0;
  std::unique_ptr<Document> doc_;
  std::uint64_t synced_revision_ = 0;  // Document revision objects_ were brought in line with
  int preview_counter_ = 0;
  ObjectId landed_mesh_ = 0;
  std::vector<SceneObject> objects_;
  DeviceToWorld x_wd_;
  std::string source_;
  std::filesystem::file_time_type mtime_{};
  int generation_ = 0;
};

// Writes `mesh` to `path` (.stl binary, .obj, .ply binary by extension). Returns "" on success,
// else the error text (empty mesh, unknown extension, unwritable file).
std::string ExportSurface(const modeling::TriangleMesh& mesh, const std::string& path);
// Writes `mesh` to `path`: .vtu (VTK XML), or TetGen's .node/.ele (path ending in .node, .ele
// or without extension gives base.node and base.ele). Returns "" or the error text.
std::string ExportTetrahedra(const modeling::TetMesh& mesh, const std::string& path);

}  // namespace spidarcad::app
