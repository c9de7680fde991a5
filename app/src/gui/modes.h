// The four modes of the window behind the Mode interface (gui/mode.h):
//  - ModelMode: the default. The scene's solids as the Document holds them, felt through the
//    proxy or the six-DOF shell tool (Haptics → Touch), the centring springs in the empty and
//    demo scenes; the Mesh action in its panel. Selection by touch (the paper's Sec. 7): with
//    the grip on a solid, Enter or a short squeeze of the grasp (SqueezeDetector) selects it in
//    the tree; when the scene has snap forces the feature the grip snaps to is highlighted.
//    Modelling by touch (scene/touch_modelling.h): with a primitive kind armed (panel, --place),
//    a translucent ghost of it follows the grip, sized by the grasp and aligned to faces, edges
//    and axes it comes near; P, the panel's Place button or a squeeze places it as a new solid
//    (one command). G, or closing the grasp on the selected node's solid, grabs that node: its
//    ghost follows the grip rigidly (snapping likewise) and letting go moves it (one command).
//    The placing itself, the alignment and the felt pull are a TouchSession
//    (scene/touch_session.h), which `spidarcad run --place` drives too; on the virtual clock
//    the run's session places and the mode only shows its ghost (ShowScriptedTouch).
//  - FeWindowMode, SculptWindowMode, AssemblyWindowMode: the window side of FeMode, SculptMode
//    and AssemblyMode (their own classes keep the VTK and ImGui work and their tests).
// Main thread only.
// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#pragma once

#include <vtkSmartPointer.h>

#include <Eigen/Core>
#include <cstdint>
#include <deque>
#include <limits>
#include <memory>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "gui/assembly_mode.h"
#include "gui/fe_mode.h"
#include "gui/mode.h"
#include "gui/sculpt_mode.h"
#include "scene/scene_fields.h"
#include "scene/scene_model.h"
#include "scene/touch_modelling.h"
#include "scene/touch_session.h"
#include "spidarcad/haptics/snap_field.h"

class vtkActor;
class vtkPolyData;
class vtkRenderer;

namespace spidarcad::app {

// The index in model.objects() of the solid the tool touches: the solid with the smallest value
// (signed distance, m in W) at any of `points_W`, when that value is at most `margin_W`; −1 when
// none is that close (or the scene has no compiled solid).
int TouchedObject(const SceneModel& model, const std::vector<Eigen::Vector3d>& points_W,
                  double margin_W);

// Text of a snapped feature ("vertex 3", "edge 7", "face 2"; "" for none).
std::string SnapTargetText(const haptics::SnapTarget& target);

// The modelling mode (see the file comment).
class ModelMode final : public Mode {
 public:
  // Draws its feature highlight into `renderer`; `springs` (the centring springs, owned by the
  // window) are part of its scene. `pole_length` (d, m in D): the six-DOF tool touches a solid
  // up to this far from the grip centre.
  ModelMode(vtkRenderer* renderer, DemoFieldSettings* springs, double pole_length);
  ~ModelMode() override;

  const char* name() const override { return "Model"; }
  const char* key() const override { return "model"; }
  void Enter() override;
  void Leave() override;
  bool active() const override { return active_; }
  void Update(const haptics::ToolState& tool, ModeContext& context) override;
  void DrawPanel(ModeContext& context) override;
  bool live() const override { return felt_; }
  std::unique_ptr<haptics::HapticScene> BuildScene(ModeContext& context) override;
  bool TakeSceneChanged() override { return std::exchange(changed_, false); }
  std::vector<std::string> Targets(const SceneModel& model) const override;
  // While a node is grabbed: "let go of 'NAME' first ...".
  std::string HistoryHold() const override;

  // False in an assembly scene, whose solids are the parts (felt through the assembly).
  void SetFelt(bool felt) { felt_ = felt; }
  // Places the highlight in the view frame: p_D = (p_W − p_WDo) / s.
  void SetWorldToView(const haptics::DeviceToWorld& X_WD);
  // Selects in the tree the solid the tool touches (TouchedObject at the tool point and the
  // latest contact markers); `how` names the trigger for the status line. True when one was.
  bool SelectTouched(const haptics::ToolState& tool, ModeContext& context, const char* how);
  // The feature the grip snaps to at the latest Update (kNone without snap forces), and the one
  // remembered at the latest selection by touch.
  const haptics::SnapTarget& snapped() const { return snapped_; }
  const haptics::SnapTarget& selected_feature() const { return selected_feature_; }
  // Result of the latest selection by touch ("" before the first).
  const std::string& touch_message() const { return touch_message_; }
  // The highlight actor (tests).
  vtkActor* highlight() const;

  // ---- modelling by touch (see the file comment) ----
  // Grasp angles of the grab gesture: closing below kGrabClose on the selected node's solid
  // grabs it, opening past kGrabOpen lets go.
  static constexpr double kGrabClose = 60.0 * 3.14159265358979323846 / 180;  // rad
  static constexpr double kGrabOpen = 75.0 * 3.14159265358979323846 / 180;   // rad
  // A grab that moved the node less than this (m in D, and rad) changes nothing.
  static constexpr double kGrabMinMove = 1e-4;
  static constexpr double kGrabMinTurn = 0.1 * 3.14159265358979323846 / 180;
  // Arms placing a primitive of `kind` (its ghost follows the grip); nullopt disarms.
  void SetPlacing(std::optional<PlaceKind> kind);
  const std::optional<PlaceKind>& placing() const { return shown_touch().placing(); }
  // The virtual clock: the scripted run models by touch (its session, null when it does not
  // place): the mode shows that session's ghost and alignment, and places, grabs and arms
  // nothing itself (the run acts on the document).
  void ShowScriptedTouch(const TouchSession* session);
  // Places the ghost as it is now (P, the Place button): one command adding the solid
  // "KIND" (made unique), selected. True when placed; touch_message() says what happened.
  bool PlaceGhost(ModeContext& context);
  // Grabs the selected node of a solid (G): true when it did (a node under a scale or mirror,
  // or a ghost that cannot be meshed, is refused with touch_message()).
  bool StartGrab(const haptics::ToolState& tool, ModeContext& context);
  // Lets go: one command poses the node where its ghost is (none when it barely moved). True
  // when a command ran.
  bool ReleaseGrab(ModeContext& context);
  bool grabbing() const { return grab_.has_value(); }
  // The ghost at the latest Update: its pose in W (aligned), size (placing: PlaceSize) and what
  // it aligned to.
  const Alignment& ghost() const { return shown_touch().ghost(); }
  double ghost_size() const { return shown_touch().ghost_size(); }
  // The alignment's capture distances and pull.
  TouchSnapSettings& touch_snap() { return touch_.snap_settings(); }
  // The ghost actor (tests).
  vtkActor* ghost_actor() const;

 private:
  void UpdateSnapProbe(SceneModel& model);
  void ShowFeature(const haptics::SnapTarget& target);
  // Shows `dots` and polylines `lines` (W) as the highlight, unless `key` is already shown.
  void ShowHighlight(const std::string& key, const std::vector<Eigen::Vector3d>& dots,
                     const std::vector<std::vector<Eigen::Vector3d>>& lines);
  // The "Model by touch" part of the panel.
  void DrawTouchPanel(ModeContext& context);
  // Modelling by touch, per frame.
  void UpdateTouch(const haptics::ToolState& tool, ModeContext& context, bool squeezed);
  // The session whose ghost the mode shows: the scripted run's on the virtual clock, else its own.
  const TouchSession& shown_touch() const {
    return scripted_touch_ != nullptr ? *scripted_touch_ : touch_;
  }
  // Shows `mesh` (once per change of `key`) as the ghost, placed by `X`.
  void ShowGhost(const std::string& key, const modeling::TriangleMesh* mesh,
                 const Eigen::Affine3d& X);
  // Shows the ghost of the primitive `session` places, and its alignment.
  void ShowPlacingGhost(const TouchSession& session);
  // The highlight of an alignment's feature among `features` (or the snap probe's).
  void ShowAlignment(const TouchSnapFeatures& features, const Alignment& alignment);

  vtkRenderer* renderer_;
  DemoFieldSettings* springs_;
  double pole_length_;
  bool active_ = false;
  bool felt_ = true;
  bool changed_ = false;
  SqueezeDetector squeeze_;
  // A main-thread copy of the scene's snap field, evaluated at the latest tool state to find the
  // feature the haptic thread's field snaps to (same features, settings and point).
  std::unique_ptr<haptics::SnapField> snap_probe_;
  haptics::SnapFeatures snap_features_;
  std::uint64_t snap_revision_ = ~std::uint64_t{0};
  int snap_generation_ = -1;
  haptics::SnapTarget snapped_;
  std::string shown_;  // what the highlight shows ("" nothing)
  haptics::SnapTarget selected_feature_;
  std::string touch_message_;
  haptics::DeviceToWorld X_WD_;
  vtkSmartPointer<vtkPolyData> highlight_poly_;
  vtkSmartPointer<vtkActor> highlight_actor_;
  // Modelling by touch.
  struct Grab {
    ObjectId object = 0;
    NodePath path;
    std::string name;
    Eigen::Isometry3d X_WT0, X_WN0, X_AN0;  // grip and node at the start; node in A
    Eigen::Affine3d X_WA;                   // the node's frame (rigid)
    modeling::TriangleMesh mesh_A;          // the node's surface in A
    Eigen::AlignedBox3d box_N;              // its box in N
  };
  TouchSession touch_;     // placing, alignment and the felt pull (the grab's too)
  bool scripted_ = false;  // ShowScriptedTouch was called
  const TouchSession* scripted_touch_ = nullptr;  // the run's session (virtual clock)
  std::optional<Grab> grab_;
  bool grasp_closed_ = false;  // the grab gesture's state (hysteresis)
  bool pending_grab_ = false;  // the panel's Grab button (taken at the next Update)
  std::vector<modeling::TriangleMesh> unit_meshes_;  // per PlaceKind, size 1
  std::string ghost_key_;
  vtkSmartPointer<vtkPolyData> ghost_poly_;
  vtkSmartPointer<vtkActor> ghost_actor_;
};

// FE push (FeMode) as a Mode.
class FeWindowMode final : public Mode {
 public:
  FeWindowMode(vtkRenderer* renderer, JobQueue* jobs) : fe_(renderer, jobs) {}
  const char* name() const override { return "FE push"; }
  const char* key() const override { return "fe"; }
  void Enter() override;
  void Leave() override;
  // Enter, then (at the next Update) precompute the document's first FE model, or set up FE for
  // the selected (else the first) solid and precompute it once it has landed.
  void Launch() override;
  bool active() const override { return fe_.active(); }
  void Update(const haptics::ToolState& tool, ModeContext& context) override;
  void DrawPanel(ModeContext& context) override;
  bool live() const override { return field_ != nullptr && fe_.active(); }
  std::unique_ptr<haptics::HapticScene> BuildScene(ModeContext& context) override;
  bool TakeSceneChanged() override { return std::exchange(changed_, false); }
  std::vector<std::string> Targets(const SceneModel& model) const override;
  // While active with a model, the FE surface stands where its source is drawn (it would
  // z-fight with the source's own actor), so the source is hidden.
  bool draws_targets() const override { return fe_.active() && fe_.model() != nullptr; }
  bool Settled() const override { return fe_.Settled(); }
  std::string Summary(const haptics::ToolState& tool) override;
  FeMode& fe() { return fe_; }

 private:
  FeMode fe_;
  std::shared_ptr<haptics::ForceField> field_;  // the latest field FeMode handed out
  bool launched_ = false;
  bool launch_done_ = false;
  bool changed_ = false;
};

// Sculpt (SculptMode) as a Mode: sculpts a sculpt object of the Document (see gui/sculpt_mode.h).
class SculptWindowMode final : public Mode {
 public:
  SculptWindowMode(vtkRenderer* renderer, JobQueue* jobs) : sculpt_(renderer, jobs) {}
  const char* name() const override { return "Sculpt"; }
  const char* key() const override { return "sculpt"; }
  void Enter() override;
  void Leave() override;
  // Enter, then the Document's first sculpt object, else a sculpt copy of its first solid.
  void Launch() override;
  bool active() const override { return sculpt_.active(); }
  void Update(const haptics::ToolState& tool, ModeContext& context) override;
  void DrawPanel(ModeContext& context) override;
  bool live() const override { return field_ != nullptr && sculpt_.active(); }
  std::unique_ptr<haptics::HapticScene> BuildScene(ModeContext& context) override;
  bool TakeSceneChanged() override { return std::exchange(changed_, false); }
  // The sculpt object sculpted, if any.
  std::vector<std::string> Targets(const SceneModel& model) const override;
  // False while a sculpt copy is being meshed.
  bool Settled() const override { return !sculpt_.copy_pending(); }
  // While a stroke is under way: "finish the sculpt stroke first ...".
  std::string HistoryHold() const override;
  SculptMode& sculpt() { return sculpt_; }

 private:
  SculptMode sculpt_;
  std::shared_ptr<haptics::ForceField> field_;
  bool changed_ = false;
};

// Assembly (AssemblyMode) as a Mode on the document's rigid parts: available when it has some;
// its field is felt whenever no other mode's part is live in a document without solids (it is
// then the base mode, AppWindow::BaseMode), else while it is the active mode. Update commits the
// parts let go as commands and follows undo, redo and tree edits of the parts (AssemblyMode).
class AssemblyWindowMode final : public Mode {
 public:
  explicit AssemblyWindowMode(vtkRenderer* renderer) : assembly_(renderer) {}
  const char* name() const override { return "Assembly"; }
  const char* key() const override { return "assembly"; }
  bool available() const override { return assembly_.has_parts(); }
  void Enter() override { active_ = true; }
  void Leave() override { active_ = false; }
  bool active() const override { return active_; }
  void Update(const haptics::ToolState& tool, ModeContext& context) override;
  void DrawPanel(ModeContext& context) override;
  bool live() const override { return assembly_.has_parts(); }
  std::unique_ptr<haptics::HapticScene> BuildScene(ModeContext& context) override;
  bool TakeSceneChanged() override { return assembly_.TakeFieldChanged(); }
  std::vector<std::string> Targets(const SceneModel& model) const override;
  bool draws_targets() const override { return true; }
  std::string Summary(const haptics::ToolState& tool) override;
  // While a part is carried: "let go of part 'NAME' first ...".
  std::string HistoryHold() const override;
  AssemblyMode& assembly() { return assembly_; }

 private:
  AssemblyMode assembly_;
  bool active_ = false;
};

}  // namespace spidarcad::app
