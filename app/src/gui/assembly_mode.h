// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
// Assembly mode (issue 5): the window's view of the document's rigid parts (rigid_part objects;
// a version 1 scene's `parts`, e.g. assets/scenes/assembly.json, become rigid parts when the
// window opens it, AdoptScenePartsAsRigidParts). The logic is haptics::AssemblyField (built by
// BuildAssemblyField, scene/assembly_scene.h, on the main thread, never on the 1 kHz one); the
// window keeps it in a shared_ptr and puts a SharedField to it into every HapticScene it
// publishes.
//
// The Document is the one source of truth (issue 12): LoadDocument builds the field from the
// rigid parts' trees, poses X_WP, fixed flags and seats and remembers each part's object id and
// revision. SyncDocument, once per frame: when a part the field moved has been let go (not
// carried, its published pose no longer the document's), it puts one command into the
// document's history, "Move part NAME" or "Seat part NAME on OTHER" (edit::SetRigidPose);
// when a rigid part's revision moved for any other reason (undo, redo, a tree edit of its
// solid, a part added or deleted) it rebuilds the field from the document (trees whose geometry
// was built before come from an AssemblyGeometryCache; only changed trees are compiled, sampled
// and meshed again) and the window republishes it. A rebuild drops a carry in progress. This class
// only draws: one actor per part, its surface meshed once per solid in the part's own frame P
// (MeshSurface), placed each frame at the pose X_WP the field published last
// (AssemblyField::LatestState, read here: the main thread is its one reader), coloured by state
// (fixed, free, carried, seated), plus a translucent ghost of the carried part at the seat it is
// nearest to. A panel section lists the parts and resets them.
//
// Frames: the field works in W; the actors are placed in the view frame D by the inverse of
// X_WD (p_D = (p_W − p_WDo) / s), set with SetWorldToView: part i's actor matrix is
// X_DW · X_WP(i). The window uses X_WD = identity for assembly scenes, as `spidarcad run` does,
// so that one trajectory file works in both.
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <array>
#include <cstdint>
#include <memory>
#include <string>
#include <utility>
#include <vector>

#include "doc/document.h"
#include "scene/assembly_scene.h"
#include "spidarcad/haptics/assembly_field.h"
#include "spidarcad/haptics/device_to_world.h"
#include "spidarcad/modeling/scene_io.h"

class vtkRenderer;
class vtkActor;

namespace spidarcad::app {

// Part colours (RGB in [0, 1]).
inline constexpr std::array<double, 3> kAssemblyFixedColour = {0.55, 0.60, 0.70};    // slate
inline constexpr std::array<double, 3> kAssemblyFreeColour = {0.85, 0.72, 0.50};     // sand
inline constexpr std::array<double, 3> kAssemblyCarriedColour = {0.96, 0.55, 0.12};  // orange
inline constexpr std::array<double, 3> kAssemblySeatedColour = {0.30, 0.72, 0.38};   // green

// What a part is doing, for colours, the panel and the summary.
enum class AssemblyPartState { kFixed, kFree, kCarried, kSeated };

// The assembly scene's actors and panel around a shared AssemblyField.
class AssemblyMode {
 public:
  // Adds its actors to `renderer` (may be null: no drawing, for tests of the logic); the
  // renderer must outlive this mode.
  explicit AssemblyMode(vtkRenderer* renderer);
  ~AssemblyMode();
  AssemblyMode(const AssemblyMode&) = delete;
  AssemblyMode& operator=(const AssemblyMode&) = delete;

  // Takes the parts of `scene`: builds the field (BuildAssemblyField with `settings`) and meshes
  // each solid the parts use once, in P, at a cell of 1/40 of its box's largest side (at most
  // `display_cell` m). A scene without parts empties the mode (has_parts() false, no field).
  // Throws std::invalid_argument naming the part or solid when the field or a mesh cannot be
  // made; the mode is then unchanged. settings.field.align.enabled is replaced by whether the
  // scene has snap (the alignment snap of a carried part toward its seat: assembly_field.h).
  void Load(const modeling::Scene& scene, const AssemblySceneSettings& settings = {},
            double display_cell = 0.001);
  // Takes the rigid_part objects of `doc` (in document order) as the parts, as Load does, and
  // remembers their ids and revisions for SyncDocument. A document without rigid parts empties
  // the mode. The alignment snap is on when `doc` has snap. Throws like Load; the mode is then
  // unchanged.
  void LoadDocument(const Document& doc, const AssemblySceneSettings& settings = {},
                    double display_cell = 0.001);
  // Once per frame after OnFrame (main thread): commits the poses of parts let go since the last
  // call as one command in `doc`'s history (returns true then), or rebuilds from `doc` when its
  // rigid parts changed otherwise or its snap was turned on or off (TakeFieldChanged is then
  // true). A rebuild that fails keeps
  // the field and sets message(); it is not retried until the parts change again.
  bool SyncDocument(Document* doc);
  // Object id of part i (0 for a mode loaded from a scene).
  ObjectId part_id(int i) const { return parts_[i].id; }
  // The latest note of the panel: a failed rebuild or commit ("" when none).
  const std::string& message() const { return message_; }
  // Rebuilds so far (LoadDocument and SyncDocument) and commands put into the history.
  int rebuilds() const { return rebuilds_; }
  int commits() const { return commits_; }
  // Trees compiled by the latest build (the others came from the geometry cache).
  int compiled_last() const { return cache_.compiled_last(); }
  // True when the loaded scene has parts.
  bool has_parts() const { return field_ != nullptr; }
  // The field (null without parts). The window puts a SharedField to it into its HapticScenes.
  const std::shared_ptr<haptics::AssemblyField>& field() const { return field_; }
  // True once after Load or Reset made a new field (the HapticScene must then be republished).
  bool TakeFieldChanged();
  // Rebuilds the field from the loaded scene or document: every part back at the pose it was
  // loaded with, none carried. Throws like Load (it cannot fail when Load succeeded).
  void Reset();

  // Main thread, once per frame: reads the field's latest published state (the initial poses
  // before its first tick) and places and colours the actors (Show).
  void OnFrame();
  // Places part i's actor at X_DW · state.X_WP[i] and colours it by its state; shows the ghost
  // of the carried part at its nearest seat. `state.count` must be size() (else ignored).
  void Show(const haptics::AssemblyState& state);

  // Places the actors in the view frame: p_D = (p_W − p_WDo) / s (s > 0).
  void SetWorldToView(const haptics::DeviceToWorld& X_WD);
  // ImGui widgets of the panel section (no Begin/End): the parts and their states, how many are
  // seated, what is carried, and "Reset parts" (which calls Reset).
  void DrawPanel();

  // Parts: count, names, fixed or graspable, state in the last shown state.
  int size() const { return static_cast<int>(parts_.size()); }
  const std::string& part_name(int i) const { return parts_[i].name; }
  bool part_fixed(int i) const { return parts_[i].fixed; }
  AssemblyPartState part_state(int i) const;
  // Graspable parts, and how many of them are seated, in the last shown state.
  int graspable_count() const;
  int seated_count() const;
  // The last state shown (count 0 before the first Show).
  const haptics::AssemblyState& state() const { return state_; }
  // Names of the scene solids the parts are made of: the window hides their static actors (the
  // solids sit at their own frame origins; the parts draw them where they are).
  std::vector<std::string> part_solids() const;
  // The part actors with their document object ids, for picking in the view (parts loaded from
  // a scene, id 0, are left out; empty without a renderer).
  std::vector<std::pair<vtkActor*, ObjectId>> PickableParts() const;
  // Part i's actor and the ghost actor (tests); null without a renderer.
  vtkActor* actor(int i) const;
  vtkActor* ghost() const;
  // The matrix X_DW · X_WP placing a part's P coordinates in D (4×4 homogeneous).
  Eigen::Matrix4d ViewMatrix(const Eigen::Isometry3d& X_WP) const;

 private:
  struct Vtk;
  struct Part {
    std::string name;
    std::string solid;
    bool fixed = false;
    int mesh = -1;               // index of its mesh in vtk_
    ObjectId id = 0;             // document object (0: a scene's)
    std::uint64_t revision = 0;  // its revision the field holds
  };
  // Builds field, meshes and actors from `inputs` (roots owned by roots_ or the caller);
  // `ids`/`revisions` empty for a scene. Strong guarantee.
  void Build(const std::vector<AssemblyPartInput>& inputs, const std::vector<ObjectId>& ids,
             const std::vector<std::uint64_t>& revisions, double display_cell);
  void Clear();
  void UpdateGhost();

  vtkRenderer* renderer_;
  std::unique_ptr<Vtk> vtk_;
  // What Reset rebuilds from: the inputs of the latest build with their trees owned here.
  std::vector<AssemblyPartInput> inputs_;
  std::vector<std::unique_ptr<modeling::ImplicitNode>> roots_;
  std::vector<ObjectId> input_ids_;
  std::vector<std::uint64_t> input_revisions_;
  double display_cell_ = 0.001;
  AssemblySceneSettings settings_;
  bool synced_snap_ = false;  // whether the document had snap on at the last LoadDocument
  AssemblyGeometryCache cache_;
  // (id, revision) of the document's rigid parts at the latest sync or failed rebuild.
  std::vector<std::pair<ObjectId, std::uint64_t>> synced_;
  bool from_document_ = false;
  int rebuilds_ = 0;
  int commits_ = 0;
  std::shared_ptr<haptics::AssemblyField> field_;
  std::vector<Part> parts_;
  haptics::AssemblyState state_;
  bool field_changed_ = false;
  haptics::DeviceToWorld X_WD_;
  std::string message_;
};

// One line for stdout, e.g. "assembly: 1 of 5 parts seated (right_arm), carried: none\n", of the
// last shown state (the text of FormatAssemblySummary in scene/assembly_scene.h, as `run`).
std::string FormatAssemblySummary(const AssemblyMode& mode);

}  // namespace spidarcad::app
