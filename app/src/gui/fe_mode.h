// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
// FE mode of the window (modes.md contract): pick a document object (an FE model, or a solid,
// sculpt or mesh that can become one: "Set up FE" meshes it in a Job and lands a mesh object and
// an FE model as one undo step), set its material, clamped region and element order (commands
// on the FE model object, undoable with the rest of the document), precompute (a Job with
// progress and cancel), then push it with the grip: the reaction force is felt (FeTouchField)
// and shown as numbers, and the deformed surface is drawn coloured by von Mises stress with a
// legend (MPa), the displacement magnified by a slider. The mode follows the document: when the
// FE model or its mesh changes (an edit, undo, redo, an open) the model shown is dropped and, if
// one was asked for, precomputed again (the last few models are kept, so undo brings one back at
// once). A mesh whose source changed since it was meshed shows as stale, with Refresh.
//
// The logic lives in scene/fe_model.h and scene/fe_touch_field.h (no VTK, no ImGui, tested
// headless in tests/app/fe_mode_test.cc); this class is the thin VTK/ImGui layer. Main thread
// only. The haptic thread is the single producer of the column focus (FeTouchField::Evaluate).
#pragma once

#include <vtkSmartPointer.h>

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <cmath>
#include <cstdint>
#include <map>
#include <memory>
#include <string>
#include <utility>
#include <vector>

#include "doc/document.h"
#include "doc/job.h"
#include "scene/fe_model.h"
#include "scene/fe_part.h"  // FieldTouchSettings: the settings of the field FeMode publishes
#include "scene/fe_setup.h"
#include "scene/fe_touch_field.h"
#include "spidarcad/fem/mesh.h"
#include "spidarcad/haptics/device_to_world.h"
#include "spidarcad/haptics/force_field.h"
#include "spidarcad/haptics/haptic_loop.h"

class vtkRenderer;
class vtkActor;
class vtkPolyData;
class vtkLookupTable;
class vtkScalarBarActor;
class vtkSphereSource;
class vtkDoubleArray;

namespace spidarcad::app {

// Candidates of the first block of columns a model of FE mode computes
// (fem::ColumnCacheSettings::first_block_nodes): the nodes nearest the tool, ready in about half
// the time of a full block of 16 (bench/app_fe_mode_edit_bench.cc measures edit to felt force).
inline constexpr int kFeModeFirstColumns = 8;

class SceneModel;

// Figures of the live FE state shown in the panel (and read by tests/demos).
struct FeLiveFigures {
  // FE force on the tool (unscaled), N, in W.
  Eigen::Vector3d f_tool_W = Eigen::Vector3d::Zero();
  // Contact nodes, and how many still read a substitute column.
  int contacts = 0;
  int substituted = 0;
  // Nodes of the tool's patch left out (the patch had more than kMaxFeContacts; a smaller punch
  // is felt).
  int refused = 0;
  // Largest displacement magnitude of a surface node, m.
  double max_displacement = 0.0;
  // Largest nodal von Mises stress on the surface, Pa.
  double max_von_mises = 0.0;
  // Columns ready in the cache.
  int ready_columns = 0;
  // Grab (FeMode::grab()): nodes held (0: none; the figures above are then the push's), and the
  // FE moment on the tool about the grip centre, N·m, W (unscaled).
  int grabbed = 0;
  Eigen::Vector3d m_tool_W = Eigen::Vector3d::Zero();
};

// The FE mode.
class FeMode {
 public:
  // Adds the mode's actors (deformed part, legend, tool sphere) to `renderer`, hidden until the
  // mode is active and a model is ready. `jobs` runs meshing and precomputation. Both must
  // outlive the mode.
  FeMode(vtkRenderer* renderer, JobQueue* jobs);
  ~FeMode();
  FeMode(const FeMode&) = delete;
  FeMode& operator=(const FeMode&) = delete;

  // Shows or hides the actors. Activating with a ready model queues a field for TakeField;
  // deactivating saves the ready columns to the disk cache (a Job) and publishes nothing.
  void SetActive(bool active);
  // True while active.
  bool active() const { return active_; }
  // ImGui widgets of the panel (no Begin/End). `model` (may be null: no document) is the scene
  // whose document the panel edits; `selected` the object selected in the tree (0: none).
  void DrawPanel(SceneModel* model = nullptr, ObjectId selected = 0);
  // Follows the document of `model` (call every frame before OnFrame and DrawPanel): takes the
  // tree's selection `selected` as the chosen object when FE mode can use it, binds to the FE
  // model of the chosen object (FeModelFor; else the document's first FE model while nothing is
  // chosen) and, when that FE model or its mesh changed since the last call, drops the model
  // shown and rebuilds it from the document (from the kept models, or by precomputing again
  // when a model had been asked for). Also picks up failed set-up and refresh Jobs.
  void SyncDocument(SceneModel* model, ObjectId selected);
  // Per frame: reads the latest contact state and updates the deformed surface and figures.
  void OnFrame(const haptics::ToolState& tool);
  // The force field to publish when it changed since the last call (new model, new tool
  // settings, activation), else nullptr. Inactive: nullptr.
  std::unique_ptr<haptics::ForceField> TakeField();

  // Places the actors in the view frame: p_D = (p_W − p_WDo) / s (s > 0), as SculptMode does.
  void SetWorldToView(const haptics::DeviceToWorld& X_WD);
  // The part to work on (tetrahedra in W, m); drops the current model (precompute again).
  // `slab` (each element's slab, SlabFeMesh::slab; empty: one piece) makes the next model
  // factored in slabs; the dropped model, when it was in slabs, lends the next one the factors
  // of the slabs that are unchanged (FeModelSettings::reuse). `place`: the slab of each block
  // when slabs have strips (SlabFeMesh::piece_slab; FeModelSettings::block_place).
  void SetMesh(fem::TetMesh mesh, std::string name, Eigen::VectorXi slab = {},
               std::vector<int> place = {});
  // Starts the precomputation Job with model_settings() (synced from the bound FE model).
  void Precompute();
  // Precomputes the bound model now and again whenever it changes (what the Precompute button
  // does).
  void RequestModel();

  // ---- the document (main thread; `model` is the window's scene) ----
  // Chooses object `id` (as picking it in the panel's list does); binds at the next SyncDocument.
  void Choose(ObjectId id) { chosen_ = id; }
  // Sets up FE for object `source` (FeSourceKind): an FE model is chosen as it is; a volume mesh
  // gets an FE model at once (one command); a solid, sculpt or closed surface mesh is meshed with
  // mesh_settings() in a Job whose finisher executes SetUpFe (a source changed meanwhile drops
  // the result). The new FE model has model_settings().order's elements; a solid's flat faces
  // are meshed for that order (FlatCellsForOrder). With `check_budget`, a solid meshed by TetGen is
  // first estimated in a Job
  // ("Estimate the mesh of NAME", phase "box": its box search takes seconds for a long tape;
  // cancellable, nothing changes then); when it lands, a cost within `spidarcad mesh`'s default
  // budget starts the mesh Job, a cost past it is not started: pending_setup() then says why
  // and ConfirmSetUp decides. `precompute` precomputes the FE model once it is bound. Returns
  // false (status() says why) when nothing was started.
  bool StartSetUp(SceneModel* model, ObjectId source, bool check_budget = true,
                  bool precompute = false);
  // The over-budget question of the last StartSetUp ("" when none is pending).
  const std::string& pending_setup() const { return pending_text_; }
  // Answers it: Proceed starts the Job, Cancel drops it.
  void ConfirmSetUp(SceneModel* model, bool proceed);
  // Meshes the bound FE model's mesh again from its source with its stored settings, flat faces
  // as its element order wants them (FlatCellsForOrder; a Job whose finisher executes
  // RefreshFeMesh). False when there is nothing to refresh.
  bool StartRefresh(SceneModel* model);
  // Whether the bound model's mesh was made for its element order: a solid's mesh by TetGen on
  // the marching-tetrahedra surface has MeshSettings::flat_cells == FlatCellsForOrder (true for
  // every other mesh, and with nothing bound).
  bool MeshFitsOrder(const Document& doc) const;
  // Sets the bound FE model's material (a command; `dragging` merges with the previous drag
  // step), its clamp (empty: the minimum-x face) or its element order. False (status() says why)
  // when there is no bound model or the document refused the edit. A new order whose mesh no
  // longer fits it (MeshFitsOrder) starts a refresh when no job is running.
  bool EditMaterial(SceneModel* model, const fem::Material& material, bool dragging = false);
  bool EditFixedBoxes(SceneModel* model, std::vector<Eigen::AlignedBox3d> boxes);
  bool EditElementOrder(SceneModel* model, int order);
  // The FE model object the mode works on (0: none), and the chosen object.
  ObjectId bound_object() const { return bound_; }
  ObjectId chosen_object() const { return chosen_; }
  // True when the bound FE model's mesh was made from a source that has changed since.
  bool stale() const { return stale_; }
  // How "Set up FE" meshes a solid (mesher, sharp edges, cell size; 0: from its size).
  MeshSettings& mesh_settings() { return mesh_settings_; }
  // Set up and Refresh mesh a solid or a sculpt in kFeSlabs slabs (FeMeshInput::slabs), so that
  // a refresh after a local edit (a feature, a stroke) re-meshes and refactors only the slabs the
  // edit reached; on by default.
  bool& mesh_in_slabs() { return mesh_in_slabs_; }
  // In slabs, a solid's large slabs in this many strips (FeMeshInput::strips; kFeStrips by
  // default, 0: none), from this many surface triangles on (FeMeshInput::strip_min_triangles).
  int& mesh_strips() { return mesh_strips_; }
  long& mesh_strip_min_triangles() { return mesh_strip_min_triangles_; }
  // Refresh a stale mesh by itself while the mode is on and a model is shown (the old model stays
  // felt until the new one is ready), once per revision of its source (so not after the undo of
  // a refresh); on by default.
  bool& refresh_on_edit() { return refresh_on_edit_; }
  // The slab mesh mesh object `mesh` holds now, when this mode made it in slabs (null: in one
  // piece, made elsewhere, or forgotten: the mode remembers kKeptModels of them).
  std::shared_ptr<const SlabFeMesh> SlabsOf(const Document& doc, ObjectId mesh) const;
  // The bound FE model's element order (model_settings().order with nothing bound).
  int BoundElementOrder(const Document& doc) const;
  // Where set-up and refresh keep slab meshes (FeMeshInput::cache_directory): the model
  // settings' disk cache directory when the disk cache is on, else none.
  std::filesystem::path SlabCacheDirectory() const;

  // Model settings the next Precompute uses (editable by code as by the panel).
  FeModelSettings& model_settings() { return model_settings_; }
  // Touch settings of the next field, as felt at the grip (DefaultFeTouchSettings; tool_radius on
  // the part, W, not scaled).
  FeTouchSettings& touch_settings() { return touch_settings_; }
  // Grasp grabs (the next field is an FePushGrabField: push, and closing the grip on the part
  // grabs it in six DOF) instead of squeezing or nothing; off by default. The grab settings as
  // felt at the grip (DefaultFeGrabSettings; the tool radius follows the touch's).
  bool& grab() { return grab_; }
  FeGrabSettings& grab_settings() { return grab_settings_; }
  // The ready model (null before the first precomputation finished).
  const std::shared_ptr<FeModel>& model() const { return model_; }
  // Live figures of the last OnFrame.
  const FeLiveFigures& figures() const { return figures_; }
  // True when a screenshot of the mode may be taken: the mode is off; or nothing is running
  // and there is no model (a job failed or nothing was asked); or the live field has run for
  // kSettleSeconds of loop time since it was published and the column worker has caught up
  // with the tool.
  bool Settled() const;
  // Loop time the live field runs before Settled(), s.
  static constexpr double kSettleSeconds = 0.5;
  // A model in slabs completes its interface factor for the next edit
  // (FeModel::PrepareReuseInBackground) once the column worker is idle for the tool's focus, or
  // this long after it was built when nothing touches it, s.
  static constexpr double kPrepareReuseAfterSeconds = 2.0;
  // Name of the part (the mesh given to SetMesh; "" before one).
  const std::string& mesh_name() const { return mesh_name_; }
  // Status line (what is happening or went wrong).
  const std::string& status() const { return status_; }

 private:
  void BuildSurfaceActor();
  void UpdateSurface(const FeContactState* state);
  void QueueField();
  Job* RunningJob() const;
  void ShowModel(bool show);
  void Rebind(const Document& doc, ObjectId fe);
  // Drops model_ (pausing its column worker; kept as reuse_model_ when it is in slabs).
  void DropModel();
  void StartMeshJob(SceneModel* model, const FeMeshInput& input, bool refresh_mesh, ObjectId mesh);
  // The over-budget estimate of set-up `input` (of the object called `name`) in a Job; its
  // finisher asks (pending_setup) or starts the mesh Job.
  void StartEstimateJob(SceneModel* model, const std::string& name, const FeMeshInput& input,
                        bool precompute);
  bool Execute(SceneModel* model, std::unique_ptr<Command> command);
  void DrawDocumentPanel(SceneModel* model);
  void DrawSettingsPanel(SceneModel* model);

  // Revisions the shown model was made from: the FE model's and its mesh's.
  struct BoundKey {
    ObjectId fe = 0;
    std::uint64_t fe_revision = 0;
    ObjectId mesh = 0;
    std::uint64_t mesh_revision = 0;
    bool operator==(const BoundKey&) const = default;
  };
  static BoundKey KeyOf(const Document& doc, ObjectId fe);
  // ClassifyFeSource, remembered per object revision (a closed-surface check walks every edge).
  FeSourceKind KindOf(const Document& doc, ObjectId id);
  std::map<ObjectId, std::pair<std::uint64_t, FeSourceKind>> kinds_;

  vtkRenderer* renderer_;
  JobQueue* jobs_;
  bool active_ = false;
  std::string mesh_name_;
  std::shared_ptr<const fem::TetMesh> mesh_;
  Eigen::VectorXi mesh_slab_;    // slab of each element of mesh_ (empty: one piece)
  std::vector<int> mesh_place_;  // slab of each block when slabs have strips (else empty)
  std::shared_ptr<FeModel> model_;
  // The last model in slabs that was dropped for a new mesh: the next precompute shares its
  // unchanged slabs' factors (reset when that precompute lands or the document changes).
  std::shared_ptr<const FeModel> reuse_model_;
  std::shared_ptr<FeContactChannel> channel_;
  std::unique_ptr<haptics::ForceField> pending_field_;
  FeModelSettings model_settings_;
  FeTouchSettings touch_settings_;
  bool grab_ = false;
  FeGrabSettings grab_settings_ = DefaultFeGrabSettings();
  std::shared_ptr<FeGrabChannel> grab_channel_ = std::make_shared<FeGrabChannel>();
  FeGrabState last_grab_;
  FeLiveFigures figures_;
  std::string status_ = "no part: choose an object and set up FE";
  std::string job_title_;
  // Panel state.
  int preset_ = 0;
  bool box_fixed_ = false;
  float box_[6] = {-1.0f, -1.0f, -1.0f, 0.001f, 1.0f, 1.0f};
  float magnify_ = 100.0f;
  float log_force_scale_ = static_cast<float>(std::log10(kDefaultFeForceScale));
  bool auto_range_ = true;
  float range_mpa_ = 100.0f;
  double magnify_shown_ = -1.0;
  haptics::DeviceToWorld X_WD_;
  // VTK.
  vtkSmartPointer<vtkPolyData> poly_;
  vtkSmartPointer<vtkDoubleArray> scalars_;
  vtkSmartPointer<vtkActor> actor_;
  vtkSmartPointer<vtkLookupTable> lut_;
  vtkSmartPointer<vtkScalarBarActor> legend_;
  vtkSmartPointer<vtkSphereSource> sphere_source_;
  vtkSmartPointer<vtkActor> sphere_actor_;
  FeContactState last_state_;
  // A field was handed out by TakeField; loop time of its first published state (−1: none yet).
  bool field_taken_ = false;
  // Title of the mesh or precompute Job whose finisher has not run yet (empty: none).
  std::string awaiting_title_;
  double field_start_time_ = -1.0;
  // The document side.
  int generation_ = -1;         // SceneModel::generation() of the document followed
  ObjectId last_selected_ = 0;  // tree selection at the last SyncDocument
  ObjectId chosen_ = 0;         // the object chosen (tree or panel list)
  ObjectId bound_ = 0;          // FE model object shown
  BoundKey bound_key_;
  BoundKey job_key_;  // what the running precompute was started from
  bool stale_ = false;
  bool want_model_ = false;          // a model was asked for: rebuild it when the document changes
  bool rebuild_pending_ = false;     // precompute when the running job is done
  bool precompute_on_bind_ = false;  // set-up asked to precompute the FE model it lands
  std::uint64_t doc_revision_ = 0;   // Document::revision() at the last SyncDocument
  MeshSettings mesh_settings_;
  FeMeshInput pending_input_;  // a set-up waiting for the over-budget answer
  bool pending_precompute_ = false;
  std::string pending_text_;
  // Models made lately (newest last), by the revisions they were made from.
  std::vector<std::pair<BoundKey, std::shared_ptr<FeModel>>> kept_;
  static constexpr std::size_t kKeptModels = 3;
  // Slab meshes this mode made lately (newest last; SlabsOf finds them by their volume).
  std::vector<std::shared_ptr<const SlabFeMesh>> slab_meshes_;
  bool mesh_in_slabs_ = true;
  int mesh_strips_ = kFeStrips;
  long mesh_strip_min_triangles_ = kStripMinTriangles;
  bool refresh_on_edit_ = true;
  // The source and its revision of the last refresh on edit.
  std::pair<ObjectId, std::uint64_t> auto_refreshed_{0, 0};
  // Finishers of this mode's Jobs run only while the mode lives (they hold a weak_ptr to this).
  std::shared_ptr<int> alive_ = std::make_shared<int>(0);
};

// Two lines for the end of a scripted run (--frames, --screenshot): the FE part's state (columns
// ready, contacts, FE force on the tool) and the tool's position and the wrench the loop
// commanded at the last tick (D, N).
std::string FormatFeSummary(const FeMode& mode, const haptics::ToolState& tool);

}  // namespace spidarcad::app
