// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#include "gui/assembly_mode.h"

#include <imgui.h>
#include <vtkActor.h>
#include <vtkCellArray.h>
#include <vtkMatrix4x4.h>
#include <vtkNew.h>
#include <vtkPoints.h>
#include <vtkPolyData.h>
#include <vtkPolyDataMapper.h>
#include <vtkPolyDataNormals.h>
#include <vtkProperty.h>
#include <vtkRenderer.h>
#include <vtkSmartPointer.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <iomanip>
#include <sstream>
#include <stdexcept>
#include <utility>
#include <variant>

#include "doc/command.h"
#include "gui/scene_view.h"
#include "spidarcad/modeling/implicit_evaluator.h"
#include "spidarcad/modeling/surface_mesher.h"

namespace spidarcad::app {

namespace {

// Half side of the cube searched for a part's solid about its frame origin, m (as
// BuildAssemblyField).
constexpr double kSearchHalfSide = 0.5;

// The surface of `solid` in its own frame: a cell of 1/40 of its box's largest side, at most
// `max_cell`. Throws std::invalid_argument when the solid is empty near its origin.
modeling::TriangleMesh MeshPartSolid(const modeling::CompiledSolid& solid, double max_cell) {
  const Eigen::Vector3d h = Eigen::Vector3d::Constant(kSearchHalfSide);
  const Eigen::AlignedBox3d rough = modeling::FindBounds(solid, Eigen::AlignedBox3d(-h, h), 0.005);
  if (rough.isEmpty()) throw std::invalid_argument("the solid is empty within 0.5 m of its origin");
  const Eigen::AlignedBox3d box =
      modeling::FindBounds(solid, rough, rough.sizes().maxCoeff() / 64.0);
  if (box.isEmpty()) throw std::invalid_argument("the solid is empty within 0.5 m of its origin");
  const double cell = std::min(max_cell, box.sizes().maxCoeff() / 40.0);
  modeling::SurfaceMeshSettings settings;
  settings.bounds = Eigen::AlignedBox3d(box.min() - Eigen::Vector3d::Constant(2 * cell),
                                        box.max() + Eigen::Vector3d::Constant(2 * cell));
  settings.cell_size = cell;
  return modeling::MeshSurface(solid, settings);
}

std::string StateName(AssemblyPartState s) {
  switch (s) {
    case AssemblyPartState::kFixed:
      return "fixed";
    case AssemblyPartState::kFree:
      return "free";
    case AssemblyPartState::kCarried:
      return "carried";
    case AssemblyPartState::kSeated:
      return "seated";
  }
  return "";
}

const std::array<double, 3>& StateColour(AssemblyPartState s) {
  switch (s) {
    case AssemblyPartState::kFixed:
      return kAssemblyFixedColour;
    case AssemblyPartState::kCarried:
      return kAssemblyCarriedColour;
    case AssemblyPartState::kSeated:
      return kAssemblySeatedColour;
    case AssemblyPartState::kFree:
      break;
  }
  return kAssemblyFreeColour;
}

void SetMatrix(vtkActor* actor, const Eigen::Matrix4d& M) {
  vtkNew<vtkMatrix4x4> m;
  for (int r = 0; r < 4; ++r) {
    for (int c = 0; c < 4; ++c) m->SetElement(r, c, M(r, c));
  }
  actor->SetUserMatrix(m);
}

}  // namespace

struct AssemblyMode::Vtk {
  struct Mesh {
    vtkNew<vtkPolyData> poly;
    vtkNew<vtkPolyDataNormals> normals;
  };
  struct Actor {
    vtkNew<vtkPolyDataMapper> mapper;
    vtkNew<vtkActor> actor;
  };
  std::vector<std::unique_ptr<Mesh>> meshes;
  std::vector<std::string> mesh_keys;          // per mesh: its tree's JSON and the cell
  std::vector<std::unique_ptr<Actor>> actors;  // one per part
  Actor ghost;
  int ghost_mesh = -1;
};

AssemblyMode::AssemblyMode(vtkRenderer* renderer)
    : renderer_(renderer), vtk_(std::make_unique<Vtk>()) {
  vtkActor* g = vtk_->ghost.actor;
  g->SetMapper(vtk_->ghost.mapper);
  vtk_->ghost.mapper->ScalarVisibilityOff();
  g->GetProperty()->SetColor(kAssemblySeatedColour[0], kAssemblySeatedColour[1],
                             kAssemblySeatedColour[2]);
  g->GetProperty()->SetOpacity(0.3);
  g->PickableOff();
  g->VisibilityOff();
  if (renderer_) renderer_->AddActor(g);
}

AssemblyMode::~AssemblyMode() {
  if (renderer_) {
    for (auto& a : vtk_->actors) renderer_->RemoveActor(a->actor);
    renderer_->RemoveActor(vtk_->ghost.actor);
  }
}

void AssemblyMode::Clear() {
  if (renderer_) {
    for (auto& a : vtk_->actors) renderer_->RemoveActor(a->actor);
  }
  vtk_->actors.clear();
  vtk_->meshes.clear();
  vtk_->mesh_keys.clear();
  vtk_->ghost_mesh = -1;
  vtk_->ghost.actor->VisibilityOff();
  parts_.clear();
  inputs_.clear();
  roots_.clear();
  input_ids_.clear();
  input_revisions_.clear();
  if (field_) field_changed_ = true;
  field_.reset();
  state_ = haptics::AssemblyState{};
}

void AssemblyMode::Load(const modeling::Scene& scene, const AssemblySceneSettings& settings,
                        double display_cell) {
  if (scene.parts.empty()) {
    Clear();
    field_changed_ = true;
    from_document_ = false;
    synced_.clear();
    return;
  }
  const std::vector<AssemblyPartInput> inputs = ScenePartInputs(scene);
  const AssemblySceneSettings old = settings_;
  settings_ = settings;
  settings_.field.align.enabled = scene.snap.has_value();  // alignment snap where snap is on
  try {
    Build(inputs, {}, {}, display_cell);
  } catch (...) {
    settings_ = old;
    throw;
  }
  from_document_ = false;
  synced_.clear();
}

void AssemblyMode::LoadDocument(const Document& doc, const AssemblySceneSettings& settings,
                                double display_cell) {
  std::vector<ObjectId> ids;
  const std::vector<AssemblyPartInput> inputs = RigidPartInputs(doc, &ids);
  std::vector<std::pair<ObjectId, std::uint64_t>> signature;
  std::vector<std::uint64_t> revisions;
  for (ObjectId id : ids) {
    revisions.push_back(doc.Get(id).revision);
    signature.emplace_back(id, revisions.back());
  }
  if (inputs.empty()) {
    Clear();
    field_changed_ = true;
  } else {
    const AssemblySceneSettings old = settings_;
    settings_ = settings;
    settings_.field.align.enabled = doc.snap().has_value();  // alignment snap where snap is on
    try {
      Build(inputs, ids, revisions, display_cell);
    } catch (...) {
      settings_ = old;
      throw;
    }
  }
  from_document_ = true;
  synced_ = std::move(signature);
  synced_snap_ = doc.snap().has_value();
  ++rebuilds_;
}

void AssemblyMode::Build(const std::vector<AssemblyPartInput>& inputs,
                         const std::vector<ObjectId>& ids,
                         const std::vector<std::uint64_t>& revisions, double display_cell) {
  if (!(display_cell > 0.0) || !std::isfinite(display_cell)) {
    throw std::invalid_argument("AssemblyMode: display cell " + std::to_string(display_cell) +
                                " must be > 0");
  }
  // Everything that can fail first, so that a failure leaves the mode as it was. The trees are
  // copied so that Reset can rebuild after the scene or document has gone.
  std::vector<std::unique_ptr<modeling::ImplicitNode>> roots;
  std::vector<AssemblyPartInput> owned = inputs;
  for (AssemblyPartInput& in : owned) {
    if (in.root == nullptr) continue;  // BuildAssemblyField names the part
    roots.push_back(std::make_unique<modeling::ImplicitNode>(*in.root));
    in.root = roots.back().get();
  }
  AssemblyGeometryCache cache = cache_;
  std::shared_ptr<haptics::AssemblyField> field = BuildAssemblyField(owned, settings_, &cache);
  // One display mesh per distinct tree: those meshed before at this cell are kept.
  std::ostringstream cell_text;
  cell_text.precision(17);
  cell_text << "|" << display_cell;
  std::vector<std::string> keys;             // per new mesh
  std::vector<int> reuse;                    // per new mesh: index of the kept mesh, or −1
  std::vector<modeling::TriangleMesh> made;  // per new mesh with reuse −1 (in order)
  std::vector<Part> parts;
  for (size_t i = 0; i < owned.size(); ++i) {
    const AssemblyPartInput& in = owned[i];
    Part part;
    part.name = in.name;
    part.solid = in.solid;
    part.fixed = in.fixed;
    part.id = i < ids.size() ? ids[i] : 0;
    part.revision = i < revisions.size() ? revisions[i] : 0;
    const std::string key = modeling::NodeToJson(*in.root).dump() + cell_text.str();
    const auto found = std::find(keys.begin(), keys.end(), key);
    if (found != keys.end()) {
      part.mesh = static_cast<int>(found - keys.begin());
    } else {
      const auto old = std::find(vtk_->mesh_keys.begin(), vtk_->mesh_keys.end(), key);
      if (old != vtk_->mesh_keys.end()) {
        reuse.push_back(static_cast<int>(old - vtk_->mesh_keys.begin()));
      } else {
        reuse.push_back(-1);
        const std::string where = "AssemblyMode: part '" + in.name + "' (solid '" + in.solid + "')";
        try {
          made.push_back(MeshPartSolid(modeling::CompiledSolid::Compile(*in.root), display_cell));
        } catch (const std::exception& e) {
          throw std::invalid_argument(where + ": " + e.what());
        }
      }
      keys.push_back(key);
      part.mesh = static_cast<int>(keys.size()) - 1;
    }
    parts.push_back(std::move(part));
  }

  // Commit.
  if (renderer_) {
    for (auto& a : vtk_->actors) renderer_->RemoveActor(a->actor);
  }
  vtk_->actors.clear();
  std::vector<std::unique_ptr<Vtk::Mesh>> meshes;
  size_t next_made = 0;
  for (size_t k = 0; k < keys.size(); ++k) {
    if (reuse[k] >= 0) {
      meshes.push_back(std::move(vtk_->meshes[reuse[k]]));
      continue;
    }
    auto mesh = std::make_unique<Vtk::Mesh>();
    FillPolyData(made[next_made++], mesh->poly);
    mesh->normals->SetInputData(mesh->poly);
    mesh->normals->SetFeatureAngle(35.0);
    mesh->normals->SplittingOn();
    mesh->normals->ConsistencyOff();
    meshes.push_back(std::move(mesh));
  }
  vtk_->meshes = std::move(meshes);
  vtk_->mesh_keys = std::move(keys);
  for (const Part& part : parts) {
    auto a = std::make_unique<Vtk::Actor>();
    a->mapper->SetInputConnection(vtk_->meshes[part.mesh]->normals->GetOutputPort());
    a->mapper->ScalarVisibilityOff();
    a->actor->SetMapper(a->mapper);
    a->actor->GetProperty()->SetAmbient(0.25);
    a->actor->GetProperty()->SetDiffuse(0.75);
    a->actor->GetProperty()->SetSpecular(0.15);
    if (renderer_) renderer_->AddActor(a->actor);
    vtk_->actors.push_back(std::move(a));
  }
  vtk_->ghost_mesh = -1;
  vtk_->ghost.actor->VisibilityOff();
  inputs_ = std::move(owned);
  roots_ = std::move(roots);
  input_ids_ = ids;
  input_revisions_ = revisions;
  display_cell_ = display_cell;
  cache_ = std::move(cache);
  parts_ = std::move(parts);
  field_ = std::move(field);
  field_changed_ = true;
  message_.clear();
  state_ = haptics::AssemblyState{};
  // What the field published when it was built (its initial poses, the parts built in a seat
  // seated) until its first tick.
  Show(field_->LatestState());
}

bool AssemblyMode::TakeFieldChanged() {
  const bool changed = field_changed_;
  field_changed_ = false;
  return changed;
}

void AssemblyMode::Reset() {
  if (inputs_.empty()) return;
  // Build replaces inputs_ and roots_: hand it copies.
  const std::vector<AssemblyPartInput> inputs = inputs_;
  std::vector<std::unique_ptr<modeling::ImplicitNode>> keep = std::move(roots_);
  const std::vector<ObjectId> ids = input_ids_;
  const std::vector<std::uint64_t> revisions = input_revisions_;
  try {
    Build(inputs, ids, revisions, display_cell_);
  } catch (...) {
    roots_ = std::move(keep);
    throw;
  }
}

namespace {

// True when two poses are equal to round-off (the field copies the poses it is built with).
bool SamePose(const Eigen::Isometry3d& a, const Eigen::Isometry3d& b) {
  return (a.matrix() - b.matrix()).cwiseAbs().maxCoeff() <= 1e-12;
}

}  // namespace

bool AssemblyMode::SyncDocument(Document* doc) {
  // The document's rigid parts now.
  std::vector<std::pair<ObjectId, std::uint64_t>> now;
  for (const DocObject& o : doc->objects()) {
    if (std::holds_alternative<RigidPartData>(o.data)) now.emplace_back(o.id, o.revision);
  }
  if (!from_document_ || now != synced_ || doc->snap().has_value() != synced_snap_) {
    // (Snap turned on or off: the field is rebuilt with its alignment snap on or off.)
    // Changed by something else than this mode (undo, redo, a tree edit, an open): rebuild.
    if (!from_document_ && now.empty()) return false;  // a scene's parts, no document parts
    try {
      LoadDocument(*doc, settings_, display_cell_);
    } catch (const std::exception& e) {
      synced_ = std::move(now);  // not retried until the parts change again
      from_document_ = true;
      message_ =
          std::string("the parts could not be rebuilt (the last good ones are felt): ") + e.what();
    }
    return false;
  }
  if (!field_ || state_.count != size()) return false;
  // Parts let go since the last call: not carried, published pose no longer the document's.
  std::vector<int> moved;
  for (int i = 0; i < size(); ++i) {
    if (parts_[i].fixed || i == state_.carried || parts_[i].id == 0) continue;
    const DocObject* o = doc->Find(parts_[i].id);
    if (o == nullptr) continue;
    if (!SamePose(std::get<RigidPartData>(o->data).X_WP, state_.X_WP[i])) moved.push_back(i);
  }
  if (moved.empty()) return false;
  std::vector<std::unique_ptr<Command>> commands;
  std::string title;
  for (int i : moved) {
    // Re-orthonormalise the carried part's rotation (integrated in the field) for the document.
    Eigen::Isometry3d X = state_.X_WP[i];
    const Eigen::Matrix3d R = X.linear();
    if (!(R.transpose() * R).isIdentity(1e-12)) {
      X.linear() = Eigen::Quaterniond(R).normalized().toRotationMatrix();
    }
    commands.push_back(edit::SetRigidPose(parts_[i].id, X));
    std::string other;
    if (state_.seated[i]) {
      // The seat it sits in: the nearest of its seats.
      double best = INFINITY;
      for (const haptics::AssemblySeat& seat : field_->part(i).seats) {
        const double d =
            ((state_.X_WP[seat.other] * seat.X_OS).translation() - X.translation()).norm();
        if (d < best) {
          best = d;
          other = parts_[seat.other].name;
        }
      }
    }
    if (moved.size() == 1) {
      title = other.empty() ? "Move part " + parts_[i].name
                            : "Seat part " + parts_[i].name + " on " + other;
    } else {
      title += (title.empty() ? "Move parts " : ", ") + parts_[i].name;
    }
  }
  try {
    doc->Execute(std::make_unique<MacroCommand>(title, std::move(commands)));
  } catch (const std::exception& e) {
    message_ = std::string("could not record the move: ") + e.what();
    return false;
  }
  ++commits_;
  // The field already holds these poses: remember the revisions this mode made.
  synced_.clear();
  for (const DocObject& o : doc->objects()) {
    if (std::holds_alternative<RigidPartData>(o.data)) synced_.emplace_back(o.id, o.revision);
  }
  for (int i = 0; i < size(); ++i) {
    if (const DocObject* o = doc->Find(parts_[i].id)) parts_[i].revision = o->revision;
  }
  return true;
}

void AssemblyMode::OnFrame() {
  if (!field_) return;
  Show(field_->LatestState());
}

Eigen::Matrix4d AssemblyMode::ViewMatrix(const Eigen::Isometry3d& X_WP) const {
  // X_DW: p_D = (p_W − p_WDo) / s.
  Eigen::Matrix4d M = Eigen::Matrix4d::Identity();
  M.topLeftCorner<3, 3>() = X_WP.linear() / X_WD_.world_scale;
  M.topRightCorner<3, 1>() = X_WD_.PointToDevice(X_WP.translation());
  return M;
}

void AssemblyMode::Show(const haptics::AssemblyState& state) {
  if (state.count != size()) return;
  state_ = state;
  if (!renderer_) return;
  for (int i = 0; i < size(); ++i) {
    vtkActor* a = vtk_->actors[i]->actor;
    SetMatrix(a, ViewMatrix(state.X_WP[i]));
    const auto& c = StateColour(part_state(i));
    a->GetProperty()->SetColor(c[0], c[1], c[2]);
    const bool carried = state.carried == i;
    a->GetProperty()->SetEdgeVisibility(carried);
    a->GetProperty()->SetEdgeColor(0.55, 0.25, 0.0);
    a->GetProperty()->SetAmbient(carried ? 0.45 : 0.25);
  }
  UpdateGhost();
}

void AssemblyMode::UpdateGhost() {
  vtkActor* g = vtk_->ghost.actor;
  const int c = state_.carried;
  if (!field_ || c < 0 || c >= size() || field_->part(c).seats.empty()) {
    g->VisibilityOff();
    return;
  }
  // The seat nearest the carried part's current position.
  const Eigen::Vector3d p = state_.X_WP[c].translation();
  double best = INFINITY;
  Eigen::Isometry3d X_WS = Eigen::Isometry3d::Identity();
  for (const haptics::AssemblySeat& seat : field_->part(c).seats) {
    const Eigen::Isometry3d candidate = state_.X_WP[seat.other] * seat.X_OS;
    const double d = (candidate.translation() - p).norm();
    if (d < best) {
      best = d;
      X_WS = candidate;
    }
  }
  if (vtk_->ghost_mesh != parts_[c].mesh) {
    vtk_->ghost.mapper->SetInputConnection(vtk_->meshes[parts_[c].mesh]->normals->GetOutputPort());
    vtk_->ghost_mesh = parts_[c].mesh;
  }
  SetMatrix(g, ViewMatrix(X_WS));
  g->VisibilityOn();
}

void AssemblyMode::SetWorldToView(const haptics::DeviceToWorld& X_WD) {
  if (!(X_WD.world_scale > 0.0) || !std::isfinite(X_WD.world_scale)) return;
  X_WD_ = X_WD;
  if (state_.count == size() && size() > 0) Show(state_);
}

AssemblyPartState AssemblyMode::part_state(int i) const {
  if (parts_[i].fixed) return AssemblyPartState::kFixed;
  if (state_.count == size() && state_.carried == i) return AssemblyPartState::kCarried;
  // Seated by the field: released in a seat, or built in one (a document saved with the part
  // seated, an undo back to it) and not picked up since.
  if (state_.count == size() && state_.seated[i]) return AssemblyPartState::kSeated;
  return AssemblyPartState::kFree;
}

int AssemblyMode::graspable_count() const {
  return static_cast<int>(
      std::count_if(parts_.begin(), parts_.end(), [](const Part& p) { return !p.fixed; }));
}

int AssemblyMode::seated_count() const {
  int n = 0;
  for (int i = 0; i < size(); ++i) n += part_state(i) == AssemblyPartState::kSeated;
  return n;
}

std::vector<std::string> AssemblyMode::part_solids() const {
  std::vector<std::string> names;
  for (const Part& p : parts_) {
    if (std::find(names.begin(), names.end(), p.solid) == names.end()) names.push_back(p.solid);
  }
  return names;
}

vtkActor* AssemblyMode::actor(int i) const {
  return renderer_ ? vtk_->actors[i]->actor.GetPointer() : nullptr;
}

std::vector<std::pair<vtkActor*, ObjectId>> AssemblyMode::PickableParts() const {
  std::vector<std::pair<vtkActor*, ObjectId>> out;
  if (!renderer_) return out;
  for (int i = 0; i < size(); ++i) {
    if (parts_[i].id != 0) out.emplace_back(vtk_->actors[i]->actor.GetPointer(), parts_[i].id);
  }
  return out;
}

vtkActor* AssemblyMode::ghost() const {
  return renderer_ ? vtk_->ghost.actor.GetPointer() : nullptr;
}

void AssemblyMode::DrawPanel() {
  if (!has_parts()) {
    ImGui::TextDisabled("The scene has no parts (see docs/scene-format.md, \"parts\").");
    return;
  }
  ImGui::Text("%d of %d parts seated", seated_count(), graspable_count());
  const int c = state_.count == size() ? state_.carried : -1;
  if (c >= 0 && c < size()) {
    ImGui::Text("Carried: %s (open the grasp at its seat to fit it)", parts_[c].name.c_str());
  } else {
    ImGui::TextWrapped(
        "Carried: none. Close the grasp (wheel or [ ]) with a part between the poles "
        "to pick it up; open it near the part's seat to fit it.");
  }
  if (ImGui::BeginTable("assembly_parts", 2,
                        ImGuiTableFlags_SizingStretchProp | ImGuiTableFlags_RowBg)) {
    for (int i = 0; i < size(); ++i) {
      const AssemblyPartState s = part_state(i);
      const auto& colour = StateColour(s);
      ImGui::TableNextRow();
      ImGui::TableNextColumn();
      ImGui::ColorButton(("##c" + std::to_string(i)).c_str(),
                         ImVec4(static_cast<float>(colour[0]), static_cast<float>(colour[1]),
                                static_cast<float>(colour[2]), 1.0f),
                         ImGuiColorEditFlags_NoTooltip | ImGuiColorEditFlags_NoBorder,
                         ImVec2(10, 10));
      ImGui::SameLine();
      ImGui::TextUnformatted(parts_[i].name.c_str());
      ImGui::TableNextColumn();
      ImGui::TextUnformatted(StateName(s).c_str());
    }
    ImGui::EndTable();
  }
  if (ImGui::Button("Reset parts")) {
    try {
      Reset();
      message_ = "parts back at their starting poses";
    } catch (const std::exception& e) {
      message_ = std::string("reset failed: ") + e.what();
    }
  }
  if (!message_.empty()) {
    ImGui::SameLine();
    ImGui::TextDisabled("%s", message_.c_str());
  }
}

std::string FormatAssemblySummary(const AssemblyMode& mode) {
  // The text is scene/assembly_scene.h's (shared with `spidarcad run`).
  std::vector<std::string> names;
  std::vector<bool> fixed;
  for (int i = 0; i < mode.size(); ++i) {
    names.push_back(mode.part_name(i));
    fixed.push_back(mode.part_fixed(i));
  }
  return FormatAssemblySummary(names, fixed, mode.state());
}

}  // namespace spidarcad::app
