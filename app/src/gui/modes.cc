// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#include "gui/modes.h"

#include <imgui.h>
#include <vtkActor.h>
#include <vtkCellArray.h>
#include <vtkMatrix4x4.h>
#include <vtkNew.h>
#include <vtkPoints.h>
#include <vtkPolyData.h>
#include <vtkPolyDataMapper.h>
#include <vtkProperty.h>
#include <vtkRenderer.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <variant>

#include "gui/panels.h"
#include "gui/scene_view.h"
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
    : renderer_(renderer), springs_(springs), pole_length_(pole_length), touch_(pole_length) {
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
  ghost_poly_ = vtkSmartPointer<vtkPolyData>::New();
  vtkNew<vtkPolyDataMapper> ghost_mapper;
  ghost_mapper->SetInputData(ghost_poly_);
  ghost_actor_ = vtkSmartPointer<vtkActor>::New();
  ghost_actor_->SetMapper(ghost_mapper);
  ghost_actor_->GetProperty()->SetColor(0.35, 0.75, 1.0);  // light blue: not in the document yet
  ghost_actor_->GetProperty()->SetOpacity(0.55);
  ghost_actor_->PickableOff();
  ghost_actor_->VisibilityOff();
  if (renderer_ != nullptr) renderer_->AddActor(ghost_actor_);
}

ModelMode::~ModelMode() {
  if (renderer_ != nullptr) {
    renderer_->RemoveActor(highlight_actor_);
    renderer_->RemoveActor(ghost_actor_);
  }
}

vtkActor* ModelMode::highlight() const { return highlight_actor_; }

vtkActor* ModelMode::ghost_actor() const { return ghost_actor_; }

void ModelMode::Enter() {
  active_ = true;
  changed_ = true;
}

void ModelMode::Leave() {
  active_ = false;
  snapped_ = {};
  ShowFeature({});
  touch_.SetPlacing(std::nullopt);
  grab_.reset();  // a grab under way when the mode is left changes nothing
  ghost_actor_->VisibilityOff();
  touch_.DropFeltSnap();
}

void ModelMode::SetWorldToView(const haptics::DeviceToWorld& X_WD) {
  if (!(X_WD.world_scale > 0.0)) return;
  X_WD_ = X_WD;
  touch_.SetWorldScale(X_WD.world_scale);
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

void ModelMode::ShowHighlight(const std::string& key, const std::vector<Eigen::Vector3d>& dots,
                              const std::vector<std::vector<Eigen::Vector3d>>& lines) {
  if (key == shown_) return;
  shown_ = key;
  vtkNew<vtkPoints> points;
  vtkNew<vtkCellArray> verts, cells;
  auto add_point = [&](const Eigen::Vector3d& p) {
    return points->InsertNextPoint(p.x(), p.y(), p.z());
  };
  for (const Eigen::Vector3d& p : dots) {
    const vtkIdType id = add_point(p);
    verts->InsertNextCell(1, &id);
  }
  for (const auto& line : lines) {
    std::vector<vtkIdType> ids;
    for (const Eigen::Vector3d& p : line) ids.push_back(add_point(p));
    if (ids.size() >= 2) cells->InsertNextCell(static_cast<vtkIdType>(ids.size()), ids.data());
  }
  highlight_poly_->Initialize();
  highlight_poly_->SetPoints(points);
  highlight_poly_->SetVerts(verts);
  highlight_poly_->SetLines(cells);
  highlight_poly_->Modified();
  highlight_actor_->SetVisibility(points->GetNumberOfPoints() > 0);
}

namespace {

// A face's outline, closed.
std::vector<Eigen::Vector3d> Outline(const haptics::SnapFace& face) {
  std::vector<Eigen::Vector3d> line = face.polygon_W;
  if (!line.empty()) line.push_back(line.front());
  return line;
}

}  // namespace

void ModelMode::ShowFeature(const haptics::SnapTarget& target) {
  const int i = target.index;
  const std::string key = "snap " + SnapTargetText(target);
  switch (target.kind) {
    case haptics::SnapKind::kVertex:
      if (i >= 0 && i < static_cast<int>(snap_features_.vertices_W.size())) {
        ShowHighlight(key, {snap_features_.vertices_W[i]}, {});
        return;
      }
      break;
    case haptics::SnapKind::kEdge:
      if (i >= 0 && i < static_cast<int>(snap_features_.edges_W.size())) {
        ShowHighlight(key, {},
                      {{snap_features_.edges_W[i].first, snap_features_.edges_W[i].second}});
        return;
      }
      break;
    case haptics::SnapKind::kFace:
      if (i >= 0 && i < static_cast<int>(snap_features_.faces_W.size())) {
        ShowHighlight(key, {}, {Outline(snap_features_.faces_W[i])});
        return;
      }
      break;
    case haptics::SnapKind::kNone:
      break;
  }
  ShowHighlight("", {}, {});
}

void ModelMode::ShowAlignment(const TouchSnapFeatures& features, const Alignment& alignment) {
  const int i = alignment.index;
  const std::string key = "touch " + alignment.Text();
  const haptics::SnapFeatures& f = features.features;
  switch (alignment.kind) {
    case AlignKind::kAxis:
      ShowHighlight(key, {}, {{features.axes[i].a_W, features.axes[i].b_W}});
      return;
    case AlignKind::kEdge:
      ShowHighlight(key, {}, {{f.edges_W[i].first, f.edges_W[i].second}});
      return;
    case AlignKind::kFace:
      ShowHighlight(key, {}, {Outline(f.faces_W[i])});
      return;
    case AlignKind::kVertex:
      ShowHighlight(key, {f.vertices_W[i]}, {});
      return;
    case AlignKind::kNone:
      break;
  }
  ShowHighlight("", {}, {});
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
  const bool touch = placing() || grab_;
  UpdateTouch(tool, context, squeezed);
  if (context.select_key || (squeezed && !touch && !grab_)) {
    SelectTouched(tool, context, context.select_key ? "Enter" : "squeeze");
  }
}

// ---- modelling by touch ----

namespace {

Eigen::Isometry3d GripPose(const haptics::ToolState& tool) {
  Eigen::Isometry3d X = Eigen::Isometry3d::Identity();
  X.linear() = tool.tool_W.R_WT;
  X.translation() = tool.tool_W.p_WT;
  return X;
}

}  // namespace

void ModelMode::SetPlacing(std::optional<PlaceKind> kind) {
  if (scripted_) return;  // the run places
  if (kind && grab_) grab_.reset();
  if (touch_.SetPlacing(kind)) changed_ = true;
  if (!kind) ghost_actor_->VisibilityOff();
}

void ModelMode::ShowScriptedTouch(const TouchSession* session) {
  SetPlacing(std::nullopt);
  grab_.reset();
  scripted_ = true;
  scripted_touch_ = session;
}

void ModelMode::ShowGhost(const std::string& key, const modeling::TriangleMesh* mesh,
                          const Eigen::Affine3d& X) {
  if (key != ghost_key_ && mesh != nullptr) {
    ghost_key_ = key;
    FillPolyData(*mesh, ghost_poly_);
  }
  // The view draws D: p_D = (p_W − p_WDo) / s.
  const double inv = 1.0 / X_WD_.world_scale;
  Eigen::Affine3d view = Eigen::Affine3d::Identity();
  view.scale(inv);
  view.translate(-X_WD_.p_WDo);
  view = view * X;
  vtkNew<vtkMatrix4x4> m;
  for (int r = 0; r < 4; ++r)
    for (int c = 0; c < 4; ++c) m->SetElement(r, c, view.matrix()(r, c));
  ghost_actor_->SetUserMatrix(m);
  ghost_actor_->SetVisibility(true);
}

void ModelMode::ShowPlacingGhost(const TouchSession& session) {
  if (!session.placing() || !(session.ghost_size() > 0.0)) {
    ghost_actor_->VisibilityOff();
    return;
  }
  const int k = static_cast<int>(*session.placing());
  if (unit_meshes_.empty()) {
    for (PlaceKind kind : {PlaceKind::kSphere, PlaceKind::kBox, PlaceKind::kCylinder})
      unit_meshes_.push_back(GhostMesh(PlacedNode(kind, Eigen::Isometry3d::Identity(), 1.0)));
  }
  Eigen::Affine3d X(session.ghost().X_WN.matrix());
  X.scale(session.ghost_size());
  ShowGhost(std::string("place ") + PlaceKindName(*session.placing()), &unit_meshes_[k], X);
  ShowAlignment(session.features(), session.ghost());
}

void ModelMode::UpdateTouch(const haptics::ToolState& tool, ModeContext& context, bool squeezed) {
  if (scripted_) {  // the virtual clock: the run's session acts, the mode shows its ghost
    if (scripted_touch_ != nullptr) {
      ShowPlacingGhost(*scripted_touch_);
      if (!scripted_touch_->message().empty()) touch_message_ = scripted_touch_->message();
    }
    return;
  }
  SceneModel& model = *context.model;
  const double grasp = tool.pose_D.Grasp();
  // The grab gesture: closing on the selected node's solid grabs, opening lets go.
  bool closed_now = false, opened_now = false;
  if (std::isfinite(grasp)) {
    if (!grasp_closed_ && grasp < kGrabClose) closed_now = grasp_closed_ = true;
    if (grasp_closed_ && grasp > kGrabOpen) {
      grasp_closed_ = false;
      opened_now = true;
    }
  }
  const bool grab_key = context.grab_key || std::exchange(pending_grab_, false);
  if (grab_ && (grab_key || opened_now)) {
    ReleaseGrab(context);
  } else if (!grab_ && !touch_.placing() && (grab_key || closed_now)) {
    bool near = grab_key;
    if (!near && context.tree != nullptr && context.tree->selection()) {
      const int i = model.IndexOf(context.tree->selection()->object);
      const bool shell =
          context.workbench != nullptr && context.workbench->contact.tool == ToolModel::kShell;
      const double margin = (kTouchMargin + (shell ? pole_length_ : 0.0)) * X_WD_.world_scale;
      near = i >= 0 && model.objects()[i].solid != nullptr &&
             model.objects()[i].solid->Value(tool.tool_W.p_WT) <= margin;
    }
    if (near) StartGrab(tool, context);
  }
  if (!touch_.placing() && !grab_) {
    ghost_actor_->VisibilityOff();
    return;
  }
  const Eigen::Isometry3d X_WT = GripPose(tool);
  if (!X_WT.matrix().allFinite()) return;
  if (touch_.placing()) {
    // The session's frame: the ghost, the felt pull, and a place on a squeeze or P.
    const TouchSession::PlaceFrame frame =
        touch_.UpdatePlacing(tool, &model.document(), model.generation(), squeezed,
                             squeeze_.last_start(), context.place_key);
    if (frame.felt_changed) changed_ = true;
    ShowPlacingGhost(touch_);
    if (frame.placed && context.tree != nullptr && frame.placed_id != 0)
      context.tree->Select(frame.placed_id);
    if (frame.placed || squeezed || context.place_key) touch_message_ = touch_.message();
    return;
  }
  // Grabbed: the node keeps its pose relative to the grip.
  touch_.UpdateFeatures(model.document(), model.generation(), grab_->object, grab_->path);
  const Eigen::Isometry3d X_WN = X_WT * grab_->X_WT0.inverse() * grab_->X_WN0;
  const Alignment& ghost = touch_.Align(X_WN, grab_->box_N);
  ShowGhost("grab", nullptr, Eigen::Affine3d((ghost.X_WN * grab_->X_AN0.inverse()).matrix()));
  ShowAlignment(touch_.features(), ghost);
  const Eigen::Vector3d h = grab_->box_N.sizes();
  if (touch_.UpdateFeltSnap(0.5 * std::min({h.x(), h.y(), h.z()}))) changed_ = true;
}

std::string ModelMode::HistoryHold() const {
  if (!active_ || !grab_) return "";
  return "let go of '" + grab_->name +
         "' first (open the grasp or press G: the move becomes an undo step when it ends)";
}

bool ModelMode::PlaceGhost(ModeContext& context) {
  if (scripted_) {
    touch_message_ = "place: the scripted run places (virtual clock)";
    return false;
  }
  if (context.model == nullptr) {
    touch_message_ = "place: nothing to place (choose a primitive first)";
    return false;
  }
  const bool placed = touch_.Place(&context.model->document());
  touch_message_ = touch_.message();
  if (placed && context.tree != nullptr && touch_.placed_id() != 0)
    context.tree->Select(touch_.placed_id());
  return placed;
}

bool ModelMode::StartGrab(const haptics::ToolState& tool, ModeContext& context) {
  if (scripted_) return false;  // the run acts on the document
  if (context.model == nullptr || context.tree == nullptr || !context.tree->selection()) {
    touch_message_ = "grab: select a node of a solid first";
    return false;
  }
  const NodeRef ref = *context.tree->selection();
  const Document& doc = context.model->document();
  const DocObject* object = doc.Find(ref.object);
  if (object == nullptr || !std::holds_alternative<SolidData>(object->data)) {
    touch_message_ = "grab: only nodes of solids can be grabbed";
    return false;
  }
  Grab g;
  g.object = ref.object;
  g.path = ref.path;
  g.name = object->name;
  try {
    const modeling::ImplicitNode& node = doc.Node(ref.object, ref.path);
    g.X_WA = FrameOfNode(*TreeOf(*object), ref.path);
    if (!IsRigid(g.X_WA)) {
      touch_message_ =
          "grab: the node sits under a scale or mirror node (a rigid move of it "
          "would not be rigid): select that node instead";
      return false;
    }
    g.X_AN0 = PoseOfNode(node).X_AN;
    g.X_WN0 = Eigen::Isometry3d(g.X_WA.matrix()) * g.X_AN0;
    g.X_WT0 = GripPose(tool);
    if (!g.X_WT0.matrix().allFinite()) return false;
    g.mesh_A = GhostMesh(node);
    const Eigen::Isometry3d X_NA = g.X_AN0.inverse();
    for (int v = 0; v < g.mesh_A.vertices.cols(); ++v)
      g.box_N.extend(X_NA * Eigen::Vector3d(g.mesh_A.vertices.col(v)));
  } catch (const std::exception& e) {
    touch_message_ = std::string("grab: ") + e.what();
    return false;
  }
  grab_ = std::move(g);
  ghost_key_.clear();
  ShowGhost("grab", &grab_->mesh_A, Eigen::Affine3d(grab_->X_WA.matrix()));
  ghost_key_ = "grab";
  touch_message_ = "grabbed '" + grab_->name + "'" +
                   (grab_->path.empty() ? "" : " node " + PathPointer(grab_->path)) +
                   ": move and turn the grip, open the grasp (or G) to let go";
  return true;
}

bool ModelMode::ReleaseGrab(ModeContext& context) {
  if (!grab_) return false;
  const Grab g = std::move(*grab_);
  grab_.reset();
  ghost_actor_->VisibilityOff();
  if (touch_.DropFeltSnap()) changed_ = true;
  const Alignment& ghost = touch_.ghost();
  const Eigen::Isometry3d X_AN =
      Eigen::Isometry3d(g.X_WA.matrix()).inverse() * ghost.X_WN;  // X_WA is rigid
  const double moved = (X_AN.translation() - g.X_AN0.translation()).norm() / X_WD_.world_scale;
  const double turned = Eigen::AngleAxisd(X_AN.linear() * g.X_AN0.linear().transpose()).angle();
  if (moved < kGrabMinMove && turned < kGrabMinTurn) {
    touch_message_ = "let go of '" + g.name + "' where it was (nothing changed)";
    return false;
  }
  try {
    Document& doc = context.model->document();
    doc.Execute(PoseNodeCommand(doc, g.object, g.path, X_AN));
  } catch (const std::exception& e) {
    touch_message_ = std::string("move failed (nothing changed): ") + e.what();
    return false;
  }
  if (context.tree != nullptr) context.tree->Select(g.object, g.path);
  touch_message_ = "moved '" + g.name + "' by touch";
  if (ghost.kind != AlignKind::kNone) touch_message_ += ", aligned to " + ghost.Text();
  return true;
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
  ImGui::PopTextWrapPos();
  DrawTouchPanel(context);
  ImGui::PushTextWrapPos(0.0f);
  if (!touch_message_.empty()) ImGui::TextUnformatted(touch_message_.c_str());
  ImGui::PopTextWrapPos();
}

void ModelMode::DrawTouchPanel(ModeContext& context) {
  ImGui::Separator();
  ImGui::TextUnformatted("Model by touch");
  ImGui::PushTextWrapPos(0.0f);
  if (scripted_) {
    const TouchSession* run = scripted_touch_;
    if (run != nullptr && run->placing()) {
      ImGui::TextColored(
          kHelpColour, "The scripted run places %s (virtual clock): %d placed; ghost %.1f mm.",
          PlaceKindName(*run->placing()), run->placed_count(), 1000.0 * run->ghost_size());
      if (run->ghost().kind != AlignKind::kNone) {
        ImGui::TextColored(ImVec4(0.85f, 0.4f, 0.0f, 1.0f), "aligned to %s",
                           run->ghost().Text().c_str());
      }
    } else {
      ImGui::TextDisabled("(the scripted run does not place: `--place KIND` to model by touch)");
    }
    ImGui::PopTextWrapPos();
    return;
  }
  const std::optional<PlaceKind>& placing = touch_.placing();
  int choice = placing ? 1 + static_cast<int>(*placing) : 0;
  const char* labels[] = {"off", "sphere", "box", "cylinder"};
  for (int i = 0; i < 4; ++i) {
    if (i > 0) ImGui::SameLine();
    if (ImGui::RadioButton(labels[i], choice == i)) {
      choice = i;
      SetPlacing(i == 0 ? std::nullopt : std::optional<PlaceKind>(static_cast<PlaceKind>(i - 1)));
    }
  }
  if (placing) {
    ImGui::TextColored(kHelpColour,
                       "The ghost follows the grip; the grasp sets its size (%.1f mm). P, Place "
                       "or a squeeze adds it as a new solid.",
                       1000.0 * touch_.ghost_size());
    if (ImGui::Button("Place")) PlaceGhost(context);
  } else {
    ImGui::TextColored(kHelpColour,
                       "Choose a primitive to place it with the grip. Grab the selected node: "
                       "G, or close the grasp (below 60°) on its solid; open it to let go.");
  }
  if (grab_) {
    if (ImGui::Button("Let go (G)")) ReleaseGrab(context);
  } else if (!placing && context.tree != nullptr && context.tree->selection()) {
    if (ImGui::Button("Grab selected (G)")) pending_grab_ = true;
  }
  if ((placing || grab_) && touch_.ghost().kind != AlignKind::kNone) {
    ImGui::TextColored(ImVec4(0.85f, 0.4f, 0.0f, 1.0f), "aligned to %s",
                       touch_.ghost().Text().c_str());
  }
  ImGui::PopTextWrapPos();
}

std::unique_ptr<haptics::HapticScene> ModelMode::BuildScene(ModeContext& context) {
  const SceneHapticsOptions contact =
      context.workbench != nullptr ? context.workbench->contact : SceneHapticsOptions{};
  auto scene = context.model->BuildHapticScene(*springs_, contact);
  // While placing or grabbing, the pull toward where the ghost would align.
  if (touch_.felt_snap() != nullptr && (touch_.placing() || grab_))
    scene->Add(std::make_unique<SharedField>(touch_.felt_snap()));
  return scene;
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
