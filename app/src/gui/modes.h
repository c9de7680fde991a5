// The four modes of the window behind the Mode interface (gui/mode.h):
//  - ModelMode: the default. The scene's solids as the Document holds them, felt through the
//    proxy or the six-DOF shell tool (Haptics → Touch), the centring springs in the empty and
//    demo scenes; the Mesh action in its panel. Selection by touch (the paper's Sec. 7): with
//    the grip on a solid, Enter or a short squeeze of the grasp (SqueezeDetector) selects it in
//    the tree; when the scene has snap forces the feature the grip snaps to is highlighted.
//  - FeWindowMode, SculptWindowMode, AssemblyWindowMode: the window side of FeMode, SculptMode
//    and AssemblyMode (their own classes keep the VTK and ImGui work and their tests).
// Main thread only.
// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#pragma once

#include <vtkSmartPointer.h>

#include <Eigen/Core>
#include <cstdint>
#include <deque>
#include <memory>
#include <string>
#include <utility>
#include <vector>

#include "gui/assembly_mode.h"
#include "gui/fe_mode.h"
#include "gui/mode.h"
#include "gui/sculpt_mode.h"
#include "scene/scene_fields.h"
#include "scene/scene_model.h"
#include "spidarcad/haptics/snap_field.h"

class vtkActor;
class vtkPolyData;
class vtkRenderer;

namespace spidarcad::app {

// Detects a short squeeze of the grasp: from where the closing began, the angle closes by at
// least kDepth and opens again by at least kDepth, the whole gesture within kWindow seconds.
class SqueezeDetector {
 public:
  static constexpr double kWindow = 0.4;                                 // s
  static constexpr double kDepth = 10.0 * 3.14159265358979323846 / 180;  // rad (10°)
  static constexpr double kNoise = 0.5 * 3.14159265358979323846 / 180;   // rad of jitter ignored
  static constexpr double kHistory = 2.0;                                // s of samples kept
  // Adds the grasp angle θ (rad) at time t (s, increasing); true when this sample completes a
  // squeeze (once per squeeze: the history restarts after one).
  bool Update(double t, double grasp);

 private:
  std::deque<std::pair<double, double>> samples_;  // (t, θ) within the last kHistory s
};

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

 private:
  void UpdateSnapProbe(SceneModel& model);
  void ShowFeature(const haptics::SnapTarget& target);

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
  haptics::SnapTarget shown_;
  haptics::SnapTarget selected_feature_;
  std::string touch_message_;
  haptics::DeviceToWorld X_WD_;
  vtkSmartPointer<vtkPolyData> highlight_poly_;
  vtkSmartPointer<vtkActor> highlight_actor_;
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
