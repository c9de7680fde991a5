// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#include "gui/modes.h"

#include <imgui.h>
#include <vtkActor.h>
#include <vtkCellArray.h>
#include <vtkNew.h>
#include <vtkPoints.h>
#include <vtkPolyData.h>
#include <vtkPolyDataMapper.h>
#include <vtkProperty.h>
#include <vtkRenderer.h>

#include <algorithm>
#include <cmath>
#include <limits>

#include "gui/panels.h"
#include "gui/tree_panel.h"
#include "gui/workbench_panels.h"
#include "scene/shared_field.h"
#include "scene/snap_features.h"

namespace spidarcad::app {

namespace {

constexpr double kTouchMargin = 0.004;  // m in D: how near a solid the grip counts as on it
constexpr double kMarkerMaxAge = 0.1;   // s: older contact markers belong to an older scene

const ImVec4 kHelpColour(0.35f, 0.38f, 0.45f, 1.0f);

}  // namespace

bool SqueezeDetector::Update(double t, double grasp) {
  if (!std::isfinite(t) || !std::isfinite(grasp)) return false;
  if (!samples_.empty() && t < samples_.back().first) samples_.clear();  // the clock restarted
  samples_.emplace_back(t, grasp);
  while (samples_.size() > 1 && t - samples_.front().first > kHistory) samples_.pop_front();
  // The smallest angle of the last kWindow s.
  std::size_t lowest = samples_.size() - 1;
  for (std::size_t i = samples_.size(); i-- > 0 && t - samples_[i].first <= kWindow;) {
    if (samples_[i].second < samples_[lowest].second) lowest = i;
  }
  // Where the closing toward it began: back from the lowest sample while the angle rises
  // (going back in time), allowing kNoise of jitter.
  std::size_t first = lowest;
  while (first > 0 && samples_[first - 1].second >= samples_[first].second - kNoise) --first;
  // The gesture starts when the angle last left its top (a steady hold before it is not part
  // of the squeeze).
  double top = samples_[first].second;
  for (std::size_t i = first; i <= lowest; ++i) top = std::max(top, samples_[i].second);
  std::size_t start = first;
  for (std::size_t i = first; i <= lowest; ++i) {
    if (samples_[i].second >= top - kNoise) start = i;
  }
  const double low = samples_[lowest].second;
  const bool deep = samples_[start].second - low >= kDepth && grasp - low >= kDepth;
  if (deep && t - samples_[start].first <= kWindow) {
    samples_.clear();
    samples_.emplace_back(t, grasp);
    return true;
  }
  return false;
}

int TouchedObject(const SceneModel& model, const std::vector<Eigen::Vector3d>& points_W,
                  double margin_W) {
  int best = -1;
  double best_value = std::numeric_limits<double>::infinity();
  const auto& objects = model.objects();
  for (int i = 0; i < static_cast<int>(objects.size()); ++i) {
    if (objects[i].solid == nullptr) continue;
    for (const Eigen::Vector3d& p : points_W) {
      if (!p.allFinite()) continue;
      const double v = objects[i].solid->Value(p);
      if (v < best_value) {
        best_value = v;
        best = i;
      }
    }
  }
  return best_value <= margin_W ? best : -1;
}

std::string SnapTargetText(const haptics::SnapTarget& target) {
  switch (target.kind) {
    case haptics::SnapKind::kVertex:
      return "vertex " + std::to_string(target.index);
    case haptics::SnapKind::kEdge:
      return "edge " + std::to_string(target.index);
    case haptics::SnapKind::kFace:
      return "face " + std::to_string(target.index);
    case haptics::SnapKind::kNone:
      break;
  }
  return "";
}

// ---- ModelMode ----

ModelMode::ModelMode(vtkRenderer* renderer, DemoFieldSettings* springs, double pole_length)
    : renderer_(renderer), springs_(springs), pole_length_(pole_length) {
  highlight_poly_ = vtkSmartPointer<vtkPolyData>::New();
  vtkNew<vtkPolyDataMapper> mapper;
  mapper->SetInputData(highlight_poly_);
  highlight_actor_ = vtkSmartPointer<vtkActor>::New();
  highlight_actor_->SetMapper(mapper);
  highlight_actor_->GetProperty()->SetColor(1.0, 0.45, 0.0);  // orange: the snapped feature
  highlight_actor_->GetProperty()->SetLineWidth(5.0f);
  highlight_actor_->GetProperty()->SetPointSize(14.0f);
  highlight_actor_->GetProperty()->SetRenderPointsAsSpheres(true);
  highlight_actor_->GetProperty()->SetLighting(false);
  highlight_actor_->PickableOff();
  highlight_actor_->VisibilityOff();
  if (renderer_ != nullptr) renderer_->AddActor(highlight_actor_);
}

ModelMode::~ModelMode() {
  if (renderer_ != nullptr) renderer_->RemoveActor(highlight_actor_);
}

vtkActor* ModelMode::highlight() const { return highlight_actor_; }

void ModelMode::Enter() {
  active_ = true;
  changed_ = true;
}

void ModelMode::Leave() {
  active_ = false;
  snapped_ = {};
  ShowFeature({});
}

void ModelMode::SetWorldToView(const haptics::DeviceToWorld& X_WD) {
  if (!(X_WD.world_scale > 0.0)) return;
  X_WD_ = X_WD;
  const double inv = 1.0 / X_WD.world_scale;
  const Eigen::Vector3d& o = X_WD.p_WDo;
  highlight_actor_->SetScale(inv, inv, inv);
  highlight_actor_->SetPosition(-inv * o.x(), -inv * o.y(), -inv * o.z());
}

void ModelMode::UpdateSnapProbe(SceneModel& model) {
  const Document& doc = model.document();
  if (snap_generation_ == model.generation() && snap_revision_ == doc.revision()) return;
  snap_generation_ = model.generation();
  snap_revision_ = doc.revision();
  snap_probe_.reset();
  snap_features_ = {};
  if (!doc.snap()) return;
  try {
    snap_features_ = ExtractSnapFeatures(doc.ToScene(), SceneHapticsOptions{}.snap_tolerance);
    haptics::SnapSettings settings;
    settings.max_force = doc.snap()->max_force;
    settings.vertex_radius = doc.snap()->vertex_radius;
    settings.edge_radius = doc.snap()->edge_radius;
    settings.face_radius = doc.snap()->face_radius;
    snap_probe_ = std::make_unique<haptics::SnapField>(snap_features_, settings);
  } catch (const std::exception&) {
    snap_probe_.reset();  // a tree that does not evaluate: no snap forces either
    snap_features_ = {};
  }
}

void ModelMode::ShowFeature(const haptics::SnapTarget& target) {
  if (target.kind == shown_.kind && target.index == shown_.index) return;
  shown_ = target;
  vtkNew<vtkPoints> points;
  vtkNew<vtkCellArray> verts, lines;
  auto add_point = [&](const Eigen::Vector3d& p) {
    return points->InsertNextPoint(p.x(), p.y(), p.z());
  };
  const int i = target.index;
  switch (target.kind) {
    case haptics::SnapKind::kVertex:
      if (i >= 0 && i < static_cast<int>(snap_features_.vertices_W.size())) {
        const vtkIdType id = add_point(snap_features_.vertices_W[i]);
        verts->InsertNextCell(1, &id);
      }
      break;
    case haptics::SnapKind::kEdge:
      if (i >= 0 && i < static_cast<int>(snap_features_.edges_W.size())) {
        const vtkIdType ids[2] = {add_point(snap_features_.edges_W[i].first),
                                  add_point(snap_features_.edges_W[i].second)};
        lines->InsertNextCell(2, ids);
      }
      break;
    case haptics::SnapKind::kFace:
      if (i >= 0 && i < static_cast<int>(snap_features_.faces_W.size())) {
        const auto& polygon = snap_features_.faces_W[i].polygon_W;
        std::vector<vtkIdType> ids;
        for (const Eigen::Vector3d& p : polygon) ids.push_back(add_point(p));
        if (!ids.empty()) {
          ids.push_back(ids.front());  // closed outline
          lines->InsertNextCell(static_cast<vtkIdType>(ids.size()), ids.data());
        }
      }
      break;
    case haptics::SnapKind::kNone:
      break;
  }
  highlight_poly_->Initialize();
  highlight_poly_->SetPoints(points);
  highlight_poly_->SetVerts(verts);
  highlight_poly_->SetLines(lines);
  highlight_poly_->Modified();
  highlight_actor_->SetVisibility(points->GetNumberOfPoints() > 0);
}

void ModelMode::Update(const haptics::ToolState& tool, ModeContext& context) {
  if (!active_ || context.model == nullptr) return;
  UpdateSnapProbe(*context.model);
  snapped_ = {};
  if (snap_probe_ != nullptr && tool.tool_W.p_WT.allFinite()) {
    snap_probe_->Evaluate(tool.tool_W);
    snapped_ = snap_probe_->snapped();
  }
  ShowFeature(snapped_);
  const bool squeezed = squeeze_.Update(tool.time, tool.pose_D.Grasp());
  if (context.select_key || squeezed) {
    SelectTouched(tool, context, context.select_key ? "Enter" : "squeeze");
  }
}

bool ModelMode::SelectTouched(const haptics::ToolState& tool, ModeContext& context,
                              const char* how) {
  SceneModel& model = *context.model;
  std::vector<Eigen::Vector3d> points = {tool.tool_W.p_WT};
  for (const ContactMarker& m : model.ContactMarkers()) {
    if (m.contact && m.time >= 0.0 && std::abs(tool.time - m.time) <= kMarkerMaxAge) {
      points.push_back(m.p_W);
    }
  }
  // The six-DOF tool touches with its poles, up to d from the grip centre.
  const bool shell =
      context.workbench != nullptr && context.workbench->contact.tool == ToolModel::kShell;
  const double margin = (kTouchMargin + (shell ? pole_length_ : 0.0)) * X_WD_.world_scale;
  const int index = TouchedObject(model, points, margin);
  if (index < 0) {
    touch_message_ = std::string(how) + ": the grip touches no solid";
    return false;
  }
  const SceneObject& object = model.objects()[index];
  if (context.tree != nullptr) context.tree->Select(object.id);
  if (context.workbench != nullptr) context.workbench->selected = index;
  selected_feature_ = snapped_;
  touch_message_ = "selected '" + object.name + "' by touch (" + how + ")";
  if (selected_feature_.kind != haptics::SnapKind::kNone) {
    touch_message_ += ", snapped to " + SnapTargetText(selected_feature_);
  }
  return true;
}

void ModelMode::DrawPanel(ModeContext& context) {
  ImGui::TextColored(kHelpColour, "The scene's solids, as the tree holds them.");
  if (!felt_) ImGui::TextDisabled("(assembly scene: the parts are felt through the assembly)");
  if (context.model != nullptr && context.jobs != nullptr && context.workbench != nullptr) {
    ImGui::Separator();
    ImGui::TextUnformatted("Mesh the selected solid");
    DrawMeshControls(context.model, context.jobs, context.workbench);
  }
  // The centring springs belong to the built-in scenes (on when there is nothing to touch).
  if (context.model != nullptr &&
      (context.model->source() == kDemoSceneName || context.model->source() == kNoSceneName)) {
    ImGui::Separator();
    ImGui::TextUnformatted("Centring springs (demo field)");
    if (DrawSpringControls(springs_)) changed_ = true;
  }
  ImGui::Separator();
  ImGui::TextUnformatted("Select by touch");
  ImGui::PushTextWrapPos(0.0f);
  ImGui::TextColored(kHelpColour,
                     "Touch a solid with the grip, then press Enter or squeeze the grasp "
                     "(close and open by 10° within 0.4 s).");
  if (snap_probe_ != nullptr) {
    ImGui::TextDisabled("snap forces on: %zu vertices, %zu edges, %zu faces",
                        snap_features_.vertices_W.size(), snap_features_.edges_W.size(),
                        snap_features_.faces_W.size());
    if (snapped_.kind != haptics::SnapKind::kNone) {
      ImGui::TextColored(ImVec4(0.85f, 0.4f, 0.0f, 1.0f), "snapped to %s",
                         SnapTargetText(snapped_).c_str());
    }
  }
  if (!touch_message_.empty()) ImGui::TextUnformatted(touch_message_.c_str());
  ImGui::PopTextWrapPos();
}

std::unique_ptr<haptics::HapticScene> ModelMode::BuildScene(ModeContext& context) {
  const SceneHapticsOptions contact =
      context.workbench != nullptr ? context.workbench->contact : SceneHapticsOptions{};
  return context.model->BuildHapticScene(*springs_, contact);
}

std::vector<std::string> ModelMode::Targets(const SceneModel& model) const {
  std::vector<std::string> names;
  for (const SceneObject& o : model.objects()) names.push_back(o.name);
  return names;
}

// ---- FeWindowMode ----

void FeWindowMode::Enter() {
  fe_.SetActive(true);
  changed_ = true;
}

void FeWindowMode::Leave() {
  fe_.SetActive(false);
  changed_ = true;
}

void FeWindowMode::Launch() {
  Enter();
  launched_ = true;
}

namespace {

// The Document object selected in the tree (0: none).
ObjectId SelectedObject(const ModeContext& context) {
  if (context.tree == nullptr || !context.tree->selection()) return 0;
  return context.tree->selection()->object;
}

}  // namespace

void FeWindowMode::Update(const haptics::ToolState& tool, ModeContext& context) {
  fe_.SyncDocument(context.model, SelectedObject(context));
  if (launched_ && !launch_done_ && context.model != nullptr) {
    // --mode fe: the document's first FE model, else the selected (or first) solid, set up.
    launch_done_ = true;
    const Document& doc = context.model->document();
    if (fe_.bound_object() != 0) {
      fe_.RequestModel();
    } else {
      ObjectId solid = 0;
      const ObjectId selected = SelectedObject(context);
      if (selected != 0 && ClassifyFeSource(doc, selected) == FeSourceKind::kSolid)
        solid = selected;
      for (const DocObject& o : doc.objects()) {
        if (solid == 0 && std::holds_alternative<SolidData>(o.data)) solid = o.id;
      }
      if (solid != 0)
        fe_.StartSetUp(context.model, solid, /*check_budget=*/true, /*precompute=*/true);
    }
  }
  fe_.OnFrame(tool);
  if (auto f = fe_.TakeField()) {
    field_ = std::shared_ptr<haptics::ForceField>(std::move(f));
    changed_ = true;
  } else if (field_ != nullptr && fe_.model() == nullptr) {
    field_.reset();  // the model was dropped (the document changed): nothing of it is felt
    changed_ = true;
  }
}

void FeWindowMode::DrawPanel(ModeContext& context) {
  fe_.DrawPanel(context.model, SelectedObject(context));
}

std::unique_ptr<haptics::HapticScene> FeWindowMode::BuildScene(ModeContext&) {
  auto scene = std::make_unique<haptics::HapticScene>();
  if (field_) scene->Add(std::make_unique<SharedField>(field_));
  return scene;
}

std::vector<std::string> FeWindowMode::Targets(const SceneModel& model) const {
  if (fe_.mesh_name().empty()) return {};
  std::vector<std::string> names = {fe_.mesh_name()};
  // The object the FE model's mesh was made from (solid, sculpt or imported mesh), if any.
  const Document& doc = model.document();
  const DocObject* fe = doc.Find(fe_.bound_object());
  const auto* data = fe != nullptr ? std::get_if<FeModelData>(&fe->data) : nullptr;
  const DocObject* mesh = data != nullptr ? doc.Find(data->tet_mesh) : nullptr;
  const auto* mesh_data = mesh != nullptr ? std::get_if<MeshData>(&mesh->data) : nullptr;
  if (mesh_data != nullptr) {
    names.push_back(mesh->name);
    if (const DocObject* source = doc.Find(mesh_data->source)) names.push_back(source->name);
  }
  return names;
}

std::string FeWindowMode::Summary(const haptics::ToolState& tool) {
  return fe_.active() ? FormatFeSummary(fe_, tool) : "";
}

// ---- SculptWindowMode ----

void SculptWindowMode::Enter() {
  sculpt_.SetActive(true);
  changed_ = true;
}

void SculptWindowMode::Leave() {
  sculpt_.SetActive(false);
  changed_ = true;
}

void SculptWindowMode::Launch() {
  Enter();
  sculpt_.Launch();
}

void SculptWindowMode::Update(const haptics::ToolState& tool, ModeContext& context) {
  sculpt_.Update(tool, context);
  if (auto f = sculpt_.TakeField()) {
    field_ = std::shared_ptr<haptics::ForceField>(std::move(f));
    changed_ = true;
  }
}

void SculptWindowMode::DrawPanel(ModeContext& context) { sculpt_.DrawPanel(&context); }

std::string SculptWindowMode::HistoryHold() const {
  if (!sculpt_.active() || !sculpt_.stroke_active()) return "";
  return "finish the sculpt stroke first (open the grasp: the stroke becomes an undo step when "
         "it ends)";
}

std::unique_ptr<haptics::HapticScene> SculptWindowMode::BuildScene(ModeContext&) {
  auto scene = std::make_unique<haptics::HapticScene>();
  if (field_) scene->Add(std::make_unique<SharedField>(field_));
  return scene;
}

std::vector<std::string> SculptWindowMode::Targets(const SceneModel& model) const {
  const ObjectId id = sculpt_.target();
  if (id == 0 || model.document().Find(id) == nullptr) return {};
  return {model.document().Get(id).name};
}

// ---- AssemblyWindowMode ----

void AssemblyWindowMode::Update(const haptics::ToolState&, ModeContext& context) {
  assembly_.OnFrame();
  // Parts let go become commands; undo, redo and tree edits of the parts rebuild the field.
  if (context.model != nullptr) assembly_.SyncDocument(&context.model->document());
}

void AssemblyWindowMode::DrawPanel(ModeContext&) {
  if (!assembly_.has_parts()) {
    ImGui::TextDisabled(
        "This document has no rigid parts (rigid_part objects, or a scene file's \"parts\" "
        "such as assets/scenes/assembly.json).");
    if (!assembly_.message().empty()) ImGui::TextWrapped("%s", assembly_.message().c_str());
    return;
  }
  assembly_.DrawPanel();
}

std::unique_ptr<haptics::HapticScene> AssemblyWindowMode::BuildScene(ModeContext&) {
  auto scene = std::make_unique<haptics::HapticScene>();
  if (assembly_.field()) scene->Add(std::make_unique<SharedField>(assembly_.field()));
  return scene;
}

std::vector<std::string> AssemblyWindowMode::Targets(const SceneModel&) const {
  return assembly_.part_solids();
}

std::string AssemblyWindowMode::HistoryHold() const {
  const int carried = assembly_.state().carried;
  if (!active_ || carried < 0 || carried >= assembly_.size()) return "";
  return "let go of part '" + assembly_.part_name(carried) +
         "' first (undo and redo wait while a part is carried: its move becomes an undo step "
         "when it is put down)";
}

std::string AssemblyWindowMode::Summary(const haptics::ToolState&) {
  if (!assembly_.has_parts()) return "";
  assembly_.OnFrame();  // the field's last tick
  return FormatAssemblySummary(assembly_);
}

}  // namespace spidarcad::app
