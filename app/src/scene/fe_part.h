// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
// A document's FE model as a part to touch: the one builder shared by FE mode (the window) and
// `spidarcad run`. It turns an FE model object (FeModelData on a mesh object holding tetrahedra)
// into a ready FeModel (assembled, factored, compliance columns from the disk cache) and the
// FeTouchField that pushes it, with the touch settings FE mode uses.
//
// Felt force and world scale. The touch settings are given as FE mode's panel holds them, as felt
// at the grip; FieldTouchSettings divides the force scale and the coupling stiffness by the world
// scale s of X_WD (p_W = s·p_D + p_WDo), so a grip displacement δ in D (a tool displacement s·δ
// in W) is felt as force_scale · K · δ, and at most coupling · δ, whatever s is. The tool's
// radius is not scaled: it is a size on the part (W), the R of `spidarcad felt`'s definition, so
// that what is felt is the part's stiffness under a tool of that size whatever X_WD's scale (on
// the platform the window's s ≈ 4.6 made a 10 mm radius at the grip 46 mm on the part, a patch
// truncated at kMaxFeContacts at FE mode's default mesh).
//
// Deterministic columns (headless runs). The window lets the column worker compute columns
// ahead of the tool while the contact solve reads the nearest ready column meanwhile: its forces
// depend on thread timing. A scripted run knows its path in advance instead: the model is built
// with the worker stopped, PrepareColumns makes exactly the columns of the candidates near the
// path ready before the first tick (from the disk cache where it has them, computed otherwise),
// and nothing changes the ready set afterwards. Each tick's forces are then a function of the
// tool's path alone; a contact node outside the prepared set reads the nearest prepared column
// (counted in FeContactState::num_substituted), which is deterministic too.
//
// Units: SI (m, N, Pa); meshes and paths in the world frame W. Main thread (or a Job's worker for
// BuildFePart); the field is then handed to the haptic loop.
#pragma once

#include <Eigen/Core>
#include <filesystem>
#include <memory>
#include <string>
#include <vector>

#include "doc/document.h"
#include "scene/fe_grab_field.h"
#include "scene/fe_model.h"
#include "scene/fe_touch_field.h"
#include "spidarcad/haptics/device_to_world.h"
#include "spidarcad/haptics/trajectory.h"

namespace spidarcad::app {

// The physical radius of the FE tool FE mode and `run` start with, m on the part (in W, not
// scaled by X_WD): the radius of the patch every FE push and grab covers
// (scene/fe_touch_field.h, tool patch), the radius `spidarcad felt` measures with.
inline constexpr double kDefaultFeToolRadius = 0.01;

// The touch settings FE mode's panel starts with, as felt at the grip: the tool patch of radius
// kDefaultFeToolRadius (on the part, W), sticking (as `felt` defines K), force scale
// kDefaultFeForceScale, felt force at most 8 N, coupling kDefaultFeCoupling N/m, push (no grasp
// contact; pole length 0.02 m).
FeTouchSettings DefaultFeTouchSettings();

// The settings of the field for panel settings `panel` (felt at the grip) and world scale s
// (> 0; otherwise `panel` is returned as it is): force_scale / s, coupling_stiffness / s and
// the tool radius as it is (a size on the part, W; see the file comment); a tool radius <= 0 is
// kDefaultFeToolRadius.
FeTouchSettings FieldTouchSettings(const FeTouchSettings& panel, double world_scale);

// The field settings for `model` (FieldTouchSettings; the model is not needed any more since the
// tool has a physical size, kept for the callers).
FeTouchSettings ResolvedFieldSettings(const FeModel& model, const FeTouchSettings& panel,
                                      double world_scale);

// Rotational virtual coupling of an FE grab FE mode starts with, felt N·m/rad: the stiffest a
// held twist is ever felt (the simulated hand's wrist is 1 N·m/rad).
inline constexpr double kDefaultFeGrabRotCoupling = 2.0;

// The grab settings FE mode and `run --fe-grab` start with, as felt at the grip: grab radius
// kDefaultFeToolRadius (the tool's physical size, on the part, W), force scale kDefaultFeForceScale
// (force and moment), virtual coupling kDefaultFeCoupling N/m and kDefaultFeGrabRotCoupling
// N·m/rad, felt force at most 8 N and moment at most 0.5 N·m, the grip closing below 70° and
// opening above 80°, the patch factored on the field's worker and ramped in over 5 ms.
FeGrabSettings DefaultFeGrabSettings();

// The grab field's settings for `model`: force_scale / s and coupling_stiffness / s (s the world
// scale, as FieldTouchSettings; the moment is scaled alike, the rotational coupling is not: a
// rotation is the same in W and at the grip), and the radius as it is (a size on the part, W;
// <= 0: kDefaultFeToolRadius).
FeGrabSettings ResolvedGrabSettings(const FeModel& model, const FeGrabSettings& panel,
                                    double world_scale);

// FE mode's grab: the touch field pushes while the grab holds nothing; while the grab holds a
// patch (FeGrabState::held: from the tick the grip closes on the part to the tick it opens),
// only the grab is felt and the touch field is not evaluated (its sphere would push the held
// nodes). Real-time safe as its two fields are.
class FePushGrabField final : public haptics::ForceField {
 public:
  // Both fields on the same model. Throws std::invalid_argument when either is null.
  FePushGrabField(std::unique_ptr<FeTouchField> touch, std::unique_ptr<FeGrabField> grab);
  haptics::ToolWrench Evaluate(const haptics::ToolKinematics& tool) noexcept override;
  const char* name() const noexcept override { return "fe_push_grab"; }
  FeTouchField& touch() { return *touch_; }
  FeGrabField& grab() { return *grab_; }

 private:
  std::unique_ptr<FeTouchField> touch_;
  std::unique_ptr<FeGrabField> grab_;
};

// The FE model objects of a document, in document order.
std::vector<ObjectId> FeModelsOf(const Document& doc);

// The object the mesh of FE model `fe` was made from (MeshData::source), 0 when there is none
// (an imported mesh) or `fe` is not an FE model.
ObjectId FeModelSource(const Document& doc, ObjectId fe);

// How BuildFePart builds a part.
struct FePartOptions {
  // Touch settings as felt at the grip (FE mode's panel).
  FeTouchSettings touch = DefaultFeTouchSettings();
  // World scale s of X_WD (world metres per grip metre, > 0).
  double world_scale = 1.0;
  // Also build the grab field (FePart::grab_field) with these settings, as felt at the grip.
  bool grab = false;
  FeGrabSettings grab_settings = DefaultFeGrabSettings();
  // Everything of FeModel::Build the document does not set (disk cache, column settings,
  // progress, cancel); the FE model's material, regions, clamps, loads and order override it.
  FeModelSettings model;
};

// A built FE part.
struct FePart {
  ObjectId fe = 0;      // the FE model object
  ObjectId mesh = 0;    // its mesh object
  ObjectId source = 0;  // what that mesh was made from (0: none)
  std::string name;     // the FE model object's name
  std::shared_ptr<FeModel> model;
  // The channel the field publishes each tick's contact state to.
  std::shared_ptr<FeContactChannel> channel;
  // The field (moved out by the caller into a HapticScene).
  std::unique_ptr<FeTouchField> field;
  // With FePartOptions::grab: the grab field on the same model and its channel (else null).
  std::shared_ptr<FeGrabChannel> grab_channel;
  std::unique_ptr<FeGrabField> grab_field;
};

// The design of mesh object `mesh` (FeModelSettings::design): its source solid compiled, when the
// mesh was made from a solid and is up to date with it (Document::IsMeshOutOfDate); else null
// (an imported mesh, a sculpt or surface source, a solid edited since, a tree that does not
// compile).
std::shared_ptr<const modeling::CompiledSolid> FeDesignOf(const Document& doc, ObjectId mesh);

// Builds FE model `fe` of `doc` now (on the calling thread): FeMeshOf, then FeModel::Build with
// ApplyFeModelData(data, options.model) and, unless options.model has one, the design
// FeDesignOf(doc, its mesh), then the field with ResolvedFieldSettings. Throws
// DocumentError when `fe` is not an FE model or its mesh is missing, and what FeModel::Build and
// FeTouchField throw (std::invalid_argument naming the setting, std::runtime_error).
FePart BuildFePart(const Document& doc, ObjectId fe, const FePartOptions& options);

// Candidate indices (FeModel::cache()) of the unclamped surface nodes within `radius` (m) of the
// polyline `path_W` (W, m; one point: a ball), nearest the path first (ties by index).
std::vector<int> CandidatesNearPath(const FeModel& model,
                                    const std::vector<Eigen::Vector3d>& path_W, double radius);

// What PrepareColumns did.
struct FeColumnPlan {
  int requested = 0;     // candidates asked for (clamped ones are never condensed)
  int from_disk = 0;     // of those, read from the disk cache
  int computed = 0;      // computed now
  int ready = 0;         // ready afterwards (requested minus those the memory bound left out)
  double seconds = 0.0;  // wall time
  bool saved = false;    // the disk cache was updated with the computed columns
};

// Makes exactly the columns of `candidates` ready (see the file comment): the worker must be
// stopped (FeModelSettings::cache.start_worker = false). Columns the disk cache gave that are not
// asked for are dropped; missing ones are computed in the order given (blocks of the settings'
// block_nodes) until the cache's memory bound is reached: the candidates listed last are the ones
// left out when not all fit (FeColumnPlan::ready says how many did). When
// columns were computed and `save` is set, the disk file of the model's key is rewritten with
// what it held plus them (`cache_directory`, empty: fem::DefaultCacheDirectory()); a failed
// write is not an error (saved stays false). Throws std::logic_error when the worker runs.
FeColumnPlan PrepareColumns(FeModel* model, const std::vector<int>& candidates, bool save,
                            const std::filesystem::path& cache_directory = {});

// How far the grip may leave a scripted trajectory (m of grip motion, D) and still find its FE
// columns ready: the simulated hand's spring (300 N/m) yields 2.7 cm under the 8 N an FE part is
// felt with at most; the nominal calibration's errors add millimetres.
inline constexpr double kFeTrajectoryMargin = 0.03;

// The grip centre's path of a trajectory in W: its samples through X_WD (positions are
// interpolated linearly between samples, so the polyline is the path), leaving out samples within
// `spacing` (m, W) of the last one kept (the first and last are always kept).
std::vector<Eigen::Vector3d> TrajectoryPathW(const haptics::Trajectory& trajectory,
                                             const haptics::DeviceToWorld& X_WD, double spacing);

// The columns a scripted run of `trajectory` on `part` needs, made ready before it starts:
// PrepareColumns on the candidates within reach of TrajectoryPathW(trajectory, X_WD, r/4), reach
// = r + s·kFeTrajectoryMargin (+ the pole length with grasp contact), r and the pole length those
// of the part's field (W), s the world scale of X_WD; with a grab field, r is the larger of the
// touch and grab radii. `save` and `cache_directory` as
// PrepareColumns.
FeColumnPlan PrepareTrajectoryColumns(FePart* part, const haptics::Trajectory& trajectory,
                                      const haptics::DeviceToWorld& X_WD, bool save,
                                      const std::filesystem::path& cache_directory = {});

// A contact state of an FE part solved in full (no condensation, no columns).
struct FeSolvedState {
  Eigen::VectorXd displacement;       // 3·#V (node-major), m
  Eigen::VectorXd element_von_mises;  // #T, Pa, at each element's centroid
  Eigen::VectorXd von_mises;          // #V, Pa: the elements' values averaged by volume
};

// Solves `model` (its mesh after the order upgrade, materials, clamps and loads) with the contact
// nodes of `state` moved to their targets (fem::StaticSolver: a full sparse solve); no contact:
// the loads alone. Throws std::runtime_error saying why when the factorisation or solve fails.
FeSolvedState SolveFeState(const FeModel& model, const FeContactState& state);

// The same for a grab state: the grabbed nodes held at their targets (none unless ready).
FeSolvedState SolveFeGrabState(const FeModel& model, const FeGrabState& state);

// Writes `solved` on the model's mesh as .vtu (WriteTetVtu): point data "displacement" (3, m)
// and "von_mises" (Pa), cell data "von_mises" (Pa). Throws what WriteTetVtu throws.
void WriteFeStateVtu(const FeModel& model, const FeSolvedState& solved, const std::string& path);

}  // namespace spidarcad::app
