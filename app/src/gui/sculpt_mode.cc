// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#include "gui/sculpt_mode.h"

#include <GLFW/glfw3.h>
#include <imgui.h>
#include <vtkActor.h>
#include <vtkCellArray.h>
#include <vtkFloatArray.h>
#include <vtkMatrix4x4.h>
#include <vtkNew.h>
#include <vtkPointData.h>
#include <vtkPoints.h>
#include <vtkPolyData.h>
#include <vtkPolyDataMapper.h>
#include <vtkProperty.h>
#include <vtkRenderer.h>
#include <vtkSphereSource.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <memory>
#include <numbers>
#include <stdexcept>
#include <string>
#include <utility>
#include <variant>

#include "doc/command.h"
#include "doc/job.h"
#include "gui/mode.h"
#include "gui/tree_panel.h"
#include "scene/scene_haptics.h"
#include "scene/scene_model.h"
#include "scene/sculpt_document.h"
#include "spidarcad/modeling/triangle_mesh_io.h"

namespace spidarcad::app {
namespace {

constexpr double kDeg = std::numbers::pi / 180.0;

}  // namespace

struct SculptMode::Vtk {
  vtkNew<vtkPoints> points;
  vtkNew<vtkFloatArray> normals;
  vtkNew<vtkCellArray> cells;
  vtkNew<vtkPolyData> poly;
  vtkNew<vtkPolyDataMapper> mapper;
  vtkNew<vtkActor> actor;
  vtkNew<vtkSphereSource> sphere;
  vtkNew<vtkPolyDataMapper> marker_mapper;
  vtkNew<vtkActor> marker;
};

SculptMode::SculptMode(vtkRenderer* renderer, JobQueue* jobs)
    : renderer_(renderer), jobs_(jobs), vtk_(std::make_unique<Vtk>()) {
  Vtk& v = *vtk_;
  v.points->SetDataTypeToFloat();
  v.normals->SetNumberOfComponents(3);
  v.normals->SetName("Normals");
  v.poly->SetPoints(v.points);
  v.poly->SetPolys(v.cells);
  v.poly->GetPointData()->SetNormals(v.normals);
  v.mapper->SetInputData(v.poly);
  v.mapper->ScalarVisibilityOff();
  v.actor->SetMapper(v.mapper);
  v.actor->GetProperty()->SetColor(0.80, 0.58, 0.42);
  v.actor->GetProperty()->SetSpecular(0.2);
  v.actor->GetProperty()->SetInterpolationToPhong();
  v.actor->VisibilityOff();
  v.sphere->SetRadius(1.0);
  v.sphere->SetThetaResolution(24);
  v.sphere->SetPhiResolution(16);
  v.marker_mapper->SetInputConnection(v.sphere->GetOutputPort());
  v.marker->SetMapper(v.marker_mapper);
  v.marker->GetProperty()->SetOpacity(0.25);
  v.marker->GetProperty()->SetColor(0.2, 0.8, 0.3);
  v.marker->PickableOff();
  v.marker->VisibilityOff();
  if (renderer_) {
    renderer_->AddActor(v.actor);
    renderer_->AddActor(v.marker);
  }
  SetWorldToView(haptics::DeviceToWorld{});
  session_.set_async_grids(true);  // the clay's grid is rebuilt off the main thread
}

SculptMode::~SculptMode() {
  if (renderer_) {
    renderer_->RemoveActor(vtk_->actor);
    renderer_->RemoveActor(vtk_->marker);
  }
}

void SculptMode::SetActive(bool active) {
  if (active == active_) return;
  active_ = active;
  if (!active_) {
    session_.CancelStroke();
    field_pending_ = false;
  } else {
    field_pending_ = true;
    choose_target_ = true;
  }
  vtk_->actor->SetVisibility(active_ && session_.has_mesh());
  vtk_->marker->SetVisibility(active_);
}

std::unique_ptr<haptics::ForceField> SculptMode::TakeField() {
  if (!active_ || !field_pending_) return nullptr;
  field_pending_ = false;
  return session_.MakeField();
}

void SculptMode::SetWorldToView(const haptics::DeviceToWorld& X_WD) {
  if (!(X_WD.world_scale > 0.0)) return;
  X_WD_ = X_WD;
  session_.settings().clay_width.grasp.pole_length = X_WD_.world_scale * grip_d_;
  const double inv = 1.0 / X_WD_.world_scale;
  const Eigen::Vector3d& o = X_WD.p_WDo;
  vtk_->actor->SetScale(inv, inv, inv);
  vtk_->actor->SetPosition(-inv * o.x(), -inv * o.y(), -inv * o.z());
}

void SculptMode::LoadMesh(const modeling::TriangleMesh& mesh) {
  session_.SetMesh(mesh);
  recorded_.clear();
  undone_.clear();
  target_ = 0;
  target_name_.clear();
  synced_revision_ = 0;
  Rebuild();
}

void SculptMode::Rebuild() {
  Vtk& v = *vtk_;
  const modeling::SculptMesh* mesh = session_.mesh();
  shown_revision_ = session_.revision();
  if (!mesh) {
    v.actor->VisibilityOff();
    return;
  }
  const int n = mesh->vertex_count();
  v.points->SetNumberOfPoints(n);
  v.normals->SetNumberOfTuples(n);
  float* xyz = static_cast<float*>(v.points->GetData()->GetVoidPointer(0));
  float* nxyz = v.normals->GetPointer(0);
  const auto& p = mesh->positions();
  const auto& nn = mesh->normals();
  for (int i = 0; i < n; ++i) {
    for (int k = 0; k < 3; ++k) {
      xyz[3 * i + k] = static_cast<float>(p[i][k]);
      nxyz[3 * i + k] = static_cast<float>(nn[i][k]);
    }
  }
  v.cells->Reset();
  v.cells->AllocateExact(mesh->triangle_count(), 3 * mesh->triangle_count());
  for (const Eigen::Vector3i& t : mesh->triangles()) {
    const vtkIdType ids[3] = {t[0], t[1], t[2]};
    v.cells->InsertNextCell(3, ids);
  }
  v.points->Modified();
  v.normals->Modified();
  v.cells->Modified();
  v.poly->Modified();
  v.actor->SetVisibility(active_);
}

void SculptMode::UpdateMarker(const Eigen::Vector3d& p_W, SculptFrameEvent event) {
  Vtk& v = *vtk_;
  const double inv = 1.0 / X_WD_.world_scale;
  const double r = session_.settings().tool.radius * inv;
  const Eigen::Vector3d p_marker =
      session_.stroke_active() ? Eigen::Vector3d(p_W + session_.snap_offset()) : p_W;
  const Eigen::Vector3d c = (p_marker - X_WD_.p_WDo) * inv;
  vtkNew<vtkMatrix4x4> m;
  m->Identity();
  for (int k = 0; k < 3; ++k) {
    m->SetElement(k, k, r);
    m->SetElement(k, 3, c[k]);
  }
  v.marker->SetUserMatrix(m);
  if (session_.stroke_active()) {
    v.marker->GetProperty()->SetColor(0.95, 0.55, 0.1);
  } else if (event == SculptFrameEvent::kNoClayInReach) {
    v.marker->GetProperty()->SetColor(0.9, 0.15, 0.1);
  } else {
    v.marker->GetProperty()->SetColor(0.2, 0.8, 0.3);
  }
}

void SculptMode::OnFrame(const haptics::ToolState& tool) {
  if (!active_) return;
  const auto start = std::chrono::steady_clock::now();
  bool key_held = false;
  if (ImGui::GetCurrentContext() != nullptr && !ImGui::GetIO().WantCaptureKeyboard) {
    key_held = ImGui::IsKeyDown(GLFW_KEY_G);
  }
  try {
    last_event_ = strokes_enabled_ ? session_.Step(tool.tool_W, key_held) : SculptFrameEvent::kIdle;
  } catch (const std::exception& e) {
    message_ = e.what();
    last_event_ = SculptFrameEvent::kIdle;
  }
  if (last_event_ == SculptFrameEvent::kBegan) stroke_tool_ = session_.settings().tool.tool;
  if (session_.revision() != shown_revision_) {
    Rebuild();
  } else if (session_.stroke_active() && session_.mesh()) {
    Vtk& v = *vtk_;
    CopyVerticesToFloat(*session_.mesh(), session_.display_vertices(),
                        static_cast<float*>(v.points->GetData()->GetVoidPointer(0)),
                        v.normals->GetPointer(0));
    v.points->Modified();
    v.normals->Modified();
    v.poly->Modified();
  }
  UpdateMarker(tool.tool_W.p_WT, last_event_);
  last_frame_ms_ =
      std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
}

// ---- the Document ----

void SculptMode::SetTarget(ObjectId id) {
  if (id == target_) return;
  if (session_.stroke_active()) session_.CancelStroke();
  target_ = id;
  synced_revision_ = 0;  // loaded at the next Update
}

bool SculptMode::CopyableCached(const DocObject& object) {
  if (std::holds_alternative<SolidData>(object.data)) return true;
  if (!std::holds_alternative<MeshData>(object.data)) return false;
  const auto it = copyable_.find(object.id);
  if (it != copyable_.end() && it->second.first == object.revision) return it->second.second;
  const bool closed = SculptableSurface(object) != nullptr;
  copyable_[object.id] = {object.revision, closed};
  return closed;
}

void SculptMode::Update(const haptics::ToolState& tool, ModeContext& context) {
  // A copy's Job that ended without running its finisher (cancelled) or was dropped.
  if (copy_job_ != nullptr) {
    bool found = false;
    if (context.jobs != nullptr) {
      for (const auto& job : context.jobs->jobs()) {
        if (job.get() != copy_job_) continue;
        found = true;
        if (job->state() == Job::State::kCancelled) {
          message_ = copy_job_title_ + ": cancelled (nothing added)";
          copy_job_ = nullptr;
        }
      }
    }
    if (!found) copy_job_ = nullptr;
  }
  if (!active_) return;
  SyncDocument(context);
  if (copy_request_ != 0) {
    const ObjectId source = std::exchange(copy_request_, 0);
    StartCopy(context, source);
  }
  if (send_to_fe_) {
    send_to_fe_ = false;
    const bool exists = context.model != nullptr && target_ != 0 &&
                        context.model->document().Find(target_) != nullptr;
    if (!exists) {
      message_ = "Send to FE: no sculpt object is sculpted";
    } else {
      if (session_.stroke_active()) session_.CancelStroke();
      if (context.tree != nullptr) context.tree->Select(target_);
      context.switch_to = "fe";
    }
  }
  OnFrame(tool);
  if (last_event_ == SculptFrameEvent::kEnded) RecordStroke(context);
}

void SculptMode::SyncDocument(ModeContext& context) {
  if (context.model == nullptr) return;
  const SceneModel& model = *context.model;
  const Document& doc = model.document();
  if (model.generation() != generation_) {
    // The model loaded another file (a reload from disk): the ids are not the old ones.
    if (generation_ != -1) {
      target_ = 0;
      target_name_.clear();
      synced_revision_ = 0;
      copy_source_ = 0;
      copyable_.clear();
      recorded_.clear();
      undone_.clear();
      if (session_.has_mesh()) session_.ClearMesh();
    }
    generation_ = model.generation();
    choose_target_ = true;
    have_selection_ = false;
    seen_selection_ = 0;
  }
  // The tree's selection: a sculpt object selected there is sculpted; a solid or a mesh with a
  // closed surface is offered for a copy. (Not during a stroke: looked at again after it.)
  const bool has = context.tree != nullptr && context.tree->selection().has_value();
  const ObjectId selected = has ? context.tree->selection()->object : 0;
  const DocObject* selected_object = has ? doc.Find(selected) : nullptr;
  const bool selected_sculpt =
      selected_object != nullptr && std::holds_alternative<SculptData>(selected_object->data);
  if (!session_.stroke_active() && (has != have_selection_ || selected != seen_selection_)) {
    have_selection_ = has;
    seen_selection_ = selected;
    if (selected_sculpt) {
      SetTarget(selected);
    } else if (selected_object != nullptr && CopyableCached(*selected_object)) {
      copy_source_ = selected;
    }
  }
  const auto first_of = [&doc](auto kind_tag) -> ObjectId {
    for (const DocObject& o : doc.objects()) {
      if (std::holds_alternative<decltype(kind_tag)>(o.data)) return o.id;
    }
    return 0;
  };
  if (choose_target_ || launch_pending_) {
    choose_target_ = false;
    if (selected_sculpt) {
      SetTarget(selected);
    } else if (target_ == 0 || doc.Find(target_) == nullptr) {
      if (const ObjectId first = first_of(SculptData{}); first != 0) SetTarget(first);
    }
  }
  if (launch_pending_) {
    launch_pending_ = false;
    if (target_ == 0 || doc.Find(target_) == nullptr) {
      // --mode sculpt on a document without sculpt objects: sculpt a copy of its first solid.
      if (const ObjectId solid = first_of(SolidData{}); solid != 0) {
        StartCopy(context, solid);
      } else {
        message_ = "The document has nothing to sculpt: add a solid, or import a closed mesh";
      }
    }
  }
  if (target_ == 0) return;
  const DocObject* object = doc.Find(target_);
  const auto* data = object != nullptr ? std::get_if<SculptData>(&object->data) : nullptr;
  if (data == nullptr || !data->mesh) {
    // Gone (deleted, or its addition undone): nothing to sculpt until it comes back (redo).
    if (session_.has_mesh()) {
      session_.ClearMesh();
      field_pending_ = true;
    }
    synced_revision_ = 0;
    return;
  }
  target_name_ = object->name;
  if (object->revision == synced_revision_) return;
  if (session_.stroke_active()) session_.CancelStroke();
  // Undo or redo of one of the session's own strokes: equal revisions mean equal content, so the
  // session's inverse (or re-applied) edit gives exactly the Document's mesh, without a reload.
  const bool aligned = static_cast<std::size_t>(session_.undo_count()) == recorded_.size() &&
                       static_cast<std::size_t>(session_.redo_count()) == undone_.size();
  if (aligned && !recorded_.empty() && recorded_.back().second == synced_revision_ &&
      recorded_.back().first == object->revision && session_.Undo()) {
    undone_.push_back(recorded_.back());
    recorded_.pop_back();
    synced_revision_ = object->revision;
    field_pending_ = true;  // republished, as after a reload
    return;
  }
  if (aligned && !undone_.empty() && undone_.back().first == synced_revision_ &&
      undone_.back().second == object->revision && session_.Redo()) {
    recorded_.push_back(undone_.back());
    undone_.pop_back();
    synced_revision_ = object->revision;
    field_pending_ = true;
    return;
  }
  // Changed otherwise in the Document (another edit, an undo further back) or not loaded yet:
  // reload it.
  try {
    session_.SetMesh(*data->mesh);
  } catch (const std::exception& e) {
    session_.ClearMesh();
    message_ = "'" + object->name + "' cannot be sculpted: " + e.what();
  }
  recorded_.clear();
  undone_.clear();
  synced_revision_ = object->revision;
  field_pending_ = true;  // a new field on the reloaded session: the window republishes
}

void SculptMode::RecordStroke(ModeContext& context) {
  const modeling::SculptEdit* edit = session_.last_edit();
  if (context.model == nullptr || target_ == 0 || edit == nullptr || !session_.mesh()) return;
  Document& doc = context.model->document();
  const DocObject* object = doc.Find(target_);
  if (object == nullptr || object->revision != synced_revision_) {
    // The object changed under the stroke: the Document wins, the stroke is dropped.
    message_ = "The sculpt object changed during the stroke: the stroke was dropped";
    session_.ForgetHistory();
    recorded_.clear();
    undone_.clear();
    synced_revision_ = 0;
    return;
  }
  std::unique_ptr<Command> command =
      MakeStrokeCommand(target_, object->name, stroke_tool_, *edit, *session_.mesh());
  // The session keeps its strokes' edits (for undo and redo without a reload) as long as the
  // Document's history could reach them, each with the object's revisions before and after.
  const bool keep = command != nullptr &&
                    recorded_.size() + 1 == static_cast<std::size_t>(session_.undo_count()) &&
                    recorded_.size() < doc.history().max_depth();
  if (!keep) {
    session_.ForgetHistory();
    recorded_.clear();
  }
  undone_.clear();  // the stroke cleared the session's redo list, as Execute clears the Document's
  if (command == nullptr) return;  // nothing moved
  const std::uint64_t before = synced_revision_;
  try {
    doc.Execute(std::move(command));
    // The session already holds what the Document now holds: no reload.
    synced_revision_ = doc.Get(target_).revision;
    if (keep) recorded_.emplace_back(before, synced_revision_);
  } catch (const std::exception& e) {
    message_ = std::string("The stroke could not be recorded, so it was undone: ") + e.what();
    synced_revision_ = 0;  // reload the Document's mesh
  }
}

bool SculptMode::StartCopy(ModeContext& context, ObjectId source) {
  if (context.model == nullptr) {
    message_ = "Sculpt a copy: no document";
    return false;
  }
  SceneModel& model = *context.model;
  Document& doc = model.document();
  const DocObject* object = doc.Find(source);
  if (object == nullptr) {
    message_ = "Sculpt a copy: no object with id " + std::to_string(source) + " in the document";
    return false;
  }
  const std::string source_name = object->name;
  const std::string name = UniqueObjectName(doc, source_name + " sculpt");
  if (const auto surface = SculptableSurface(*object)) {
    try {
      doc.Execute(edit::AddSculpt(name, *surface));
    } catch (const std::exception& e) {
      message_ = "Sculpt a copy of '" + source_name + "': " + e.what();
      return false;
    }
    const ObjectId id = doc.last_created().at(0);
    if (context.tree != nullptr) context.tree->Select(id);
    SetTarget(id);
    message_ = "Added '" + name + "', a copy of '" + source_name + "'";
    return true;
  }
  if (!std::holds_alternative<SolidData>(object->data)) {
    message_ = "Sculpt a copy of '" + source_name + "': it is a " + ObjectKindName(object->data) +
               " object; only solids and mesh objects with a closed surface can be copied";
    return false;
  }
  if (copy_job_ != nullptr) {
    message_ = "Sculpt a copy of '" + source_name + "': " + copy_job_title_ + " is running";
    return false;
  }
  const int index = model.IndexOf(source);
  const SceneObject* compiled = index >= 0 ? &model.objects()[index] : nullptr;
  if (compiled == nullptr || compiled->solid == nullptr ||
      compiled->source_revision != object->revision) {
    const std::string why = compiled != nullptr && !compiled->error.empty()
                                ? compiled->error
                                : "it has not been compiled since its last edit; try again";
    message_ = "Sculpt a copy of '" + source_name + "': " + why;
    return false;
  }
  if (context.jobs == nullptr || !(mesh_cell_ > 0.0)) {
    message_ = "Sculpt a copy of '" + source_name + "': no job queue or mesh cell";
    return false;
  }
  const double cell = mesh_cell_;
  const std::shared_ptr<const modeling::CompiledSolid> solid = compiled->solid;
  const std::uint64_t revision = object->revision;
  const int generation = model.generation();
  const double grid_cell = session_.settings().tool.radius / 3.0;
  SceneModel* model_ptr = &model;
  TreeController* tree = context.tree;
  std::weak_ptr<bool> alive = alive_;
  copy_job_title_ = "Sculpt a copy of " + source_name;
  const std::string title = copy_job_title_;
  Job& job = context.jobs->Start(
      title,
      [this, alive, solid, cell, grid_cell, model_ptr, tree, source, source_name, revision,
       generation, title](JobContext& job_context) -> Job::Finisher {
        try {
          // The solid's box (found on cells of 1/64 of its size) with a margin for that and for
          // the meshing grid.
          job_context.SetPhase("bounds");
          bool unbounded = false;
          Eigen::AlignedBox3d box = SolidBounds(*solid, &unbounded, job_context.cancel_flag());
          if (unbounded)
            throw std::runtime_error("the solid is unbounded: intersect it with a box");
          if (box.isEmpty()) throw std::runtime_error("the solid is empty");
          const double pad = box.sizes().maxCoeff() / 32.0 + 2.0 * cell;
          box.min().array() -= pad;
          box.max().array() += pad;
          job_context.SetPhase("surface");
          modeling::SurfaceMeshSettings settings;
          settings.bounds = box;
          settings.cell_size = cell;
          settings.cancel = job_context.cancel_flag();
          settings.progress = job_context.ProgressRange(0.0, 0.9);
          auto surface = std::make_shared<const modeling::TriangleMesh>(
              modeling::MeshSurface(*solid, settings));
          if (job_context.cancelled()) throw std::runtime_error("cancelled");
          job_context.SetPhase("sculpt grid");
          auto clay = std::make_shared<modeling::SculptMesh>(*surface, grid_cell);
          return [this, alive, model_ptr, tree, surface, clay, source, source_name, revision,
                  generation] {
            if (alive.expired()) return;
            copy_job_ = nullptr;
            // Dropped when another file was loaded or the solid changed while it was meshed.
            Document& doc = model_ptr->document();
            const DocObject* now = doc.Find(source);
            if (model_ptr->generation() != generation || now == nullptr ||
                now->revision != revision) {
              message_ =
                  "'" + source_name + "' changed while it was meshed: no copy was made (try again)";
              return;
            }
            const std::string name = UniqueObjectName(doc, source_name + " sculpt");
            try {
              doc.Execute(edit::AddSculpt(name, *surface));
            } catch (const std::exception& e) {
              message_ = "Sculpt a copy of '" + source_name + "': " + e.what();
              throw;  // the job fails with the reason; the document is as it was
            }
            const ObjectId id = doc.last_created().at(0);
            if (tree != nullptr) tree->Select(id);
            if (session_.stroke_active()) session_.CancelStroke();
            target_ = id;
            target_name_ = name;
            session_.SetMesh(std::make_unique<modeling::SculptMesh>(std::move(*clay)));
            recorded_.clear();
            undone_.clear();
            synced_revision_ = doc.Get(id).revision;
            field_pending_ = true;
            message_ = "Added '" + name + "', a copy of '" + source_name + "'";
          };
        } catch (const std::exception& e) {
          if (job_context.cancelled()) throw;
          // Reported on the main thread: the finisher records the message, then fails the job.
          return [this, alive, text = std::string(e.what()), title] {
            if (!alive.expired()) {
              copy_job_ = nullptr;
              message_ = title + " failed: " + text;
            }
            throw std::runtime_error(text);
          };
        }
      });
  copy_job_ = &job;
  message_ = "Meshing '" + source_name + "' for a sculpt copy...";
  return true;
}

void SculptMode::DrawDocumentPanel(ModeContext& context) {
  Document& doc = context.model->document();
  const bool stroking = session_.stroke_active();
  // The sculpt object sculpted.
  const DocObject* current = target_ != 0 ? doc.Find(target_) : nullptr;
  const std::string shown = current != nullptr ? current->name
                            : target_ != 0     ? target_name_ + " (gone)"
                                               : std::string("(none)");
  ObjectId pick = 0;
  ImGui::BeginDisabled(stroking);
  if (ImGui::BeginCombo("sculpt object", shown.c_str())) {
    bool any = false;
    for (const DocObject& o : doc.objects()) {
      if (!std::holds_alternative<SculptData>(o.data)) continue;
      any = true;
      ImGui::PushID(static_cast<int>(o.id));
      if (ImGui::Selectable(o.name.c_str(), o.id == target_)) pick = o.id;
      ImGui::PopID();
    }
    if (!any) ImGui::TextDisabled("(the document has no sculpt object)");
    ImGui::EndCombo();
  }
  ImGui::EndDisabled();
  if (pick != 0) {
    SetTarget(pick);
    if (context.tree != nullptr) context.tree->Select(pick);
  }
  // A copy of a solid or of a closed mesh, as a new sculpt object.
  const DocObject* source = copy_source_ != 0 ? doc.Find(copy_source_) : nullptr;
  if (source != nullptr && !CopyableCached(*source)) source = nullptr;
  if (ImGui::BeginCombo("copy of", source != nullptr ? source->name.c_str() : "(choose)")) {
    for (const DocObject& o : doc.objects()) {
      if (!CopyableCached(o)) continue;
      const std::string label = o.name + " (" + ObjectKindName(o.data) + ")";
      ImGui::PushID(static_cast<int>(o.id));
      if (ImGui::Selectable(label.c_str(), o.id == copy_source_)) copy_source_ = o.id;
      ImGui::PopID();
    }
    ImGui::EndCombo();
  }
  const bool solid_source = source != nullptr && std::holds_alternative<SolidData>(source->data);
  if (solid_source) {
    float cell_mm = static_cast<float>(mesh_cell_ * 1e3);
    if (ImGui::SliderFloat("mesh cell [mm]", &cell_mm, 0.5f, 5.0f, "%.2f"))
      mesh_cell_ = cell_mm * 1e-3;
  }
  ImGui::BeginDisabled(source == nullptr || copy_pending() || stroking);
  const std::string button =
      source != nullptr ? "Sculpt a copy of '" + source->name + "'" : "Sculpt a copy of ...";
  if (ImGui::Button(button.c_str())) RequestCopy(source->id);
  ImGui::EndDisabled();
  if (copy_pending()) {
    ImGui::SameLine();
    ImGui::TextDisabled("meshing...");
  }
  ImGui::Separator();
}

void SculptMode::DrawPanel(ModeContext* context) {
  // Meshes may land from Jobs between frames.
  if (session_.revision() != shown_revision_) Rebuild();
  const bool with_document = context != nullptr && context->model != nullptr;
  if (with_document) DrawDocumentPanel(*context);
  SculptModeSettings& s = session_.settings();
  const modeling::SculptMesh* mesh = session_.mesh();
  const std::string label = target_ != 0 ? target_name_ : std::string("Clay");
  if (mesh) {
    ImGui::Text("%s: %d vertices, %d triangles, volume %.1f cm^3", label.c_str(),
                mesh->vertex_count(), mesh->triangle_count(), mesh->volume() * 1e6);
  } else {
    ImGui::TextUnformatted(copy_pending() ? "Clay: meshing..." : "Clay: none");
  }
  if (session_.stroke_active() && mesh) {
    const modeling::StrokeStats& st = mesh->stroke_stats();
    ImGui::Text("Stroke: %d vertices, strength %.2f, %.2f ms/frame", st.affected_vertices,
                st.strength, last_frame_ms_);
  } else if (last_event_ == SculptFrameEvent::kNoClayInReach) {
    ImGui::TextColored(ImVec4(1.0f, 0.4f, 0.3f, 1.0f), "No clay within reach of the grip");
  } else {
    ImGui::TextUnformatted("Close the grasp (wheel / [ ]) or hold G at the clay to sculpt");
  }

  static const char* kTools[] = {"grab", "twist", "bend", "push/pull", "smooth"};
  int tool = static_cast<int>(s.tool.tool);
  if (ImGui::Combo("tool", &tool, kTools, 5)) s.tool.tool = static_cast<modeling::SculptTool>(tool);
  float radius_mm = static_cast<float>(s.tool.radius * 1e3);
  if (ImGui::SliderFloat("radius [mm]", &radius_mm, 2.0f, 60.0f, "%.1f"))
    s.tool.radius = radius_mm * 1e-3;
  float stiffness = static_cast<float>(s.tool.stiffness);
  if (ImGui::SliderFloat("stiffness [N/m]", &stiffness, 20.0f, 3000.0f, "%.0f",
                         ImGuiSliderFlags_Logarithmic)) {
    s.tool.stiffness = stiffness;
  }
  ImGui::Checkbox("conserve volume", &s.tool.conserve_volume);
  float edge_mm = static_cast<float>(s.tool.max_edge_length * 1e3);
  if (ImGui::SliderFloat("refine edges over [mm]", &edge_mm, 0.0f, 10.0f,
                         edge_mm <= 0.0f ? "off" : "%.1f")) {
    s.tool.max_edge_length = edge_mm * 1e-3;
  }
  float begin_deg = static_cast<float>(s.stroke_begin_angle / kDeg);
  if (ImGui::SliderFloat("grasp begins stroke below [deg]", &begin_deg, 30.0f, 85.0f, "%.0f")) {
    s.stroke_begin_angle = begin_deg * kDeg;
    s.stroke_end_angle = std::min(std::numbers::pi / 2, s.stroke_begin_angle + 10.0 * kDeg);
    s.tool.grasp_closed_angle = std::min(s.tool.grasp_closed_angle, s.stroke_begin_angle);
  }

  if (with_document) {
    // The Document's one history: the last step, whatever it was (Ctrl+Z / Ctrl+Y).
    Document& doc = context->model->document();
    const History& history = doc.history();
    ImGui::BeginDisabled(!history.CanUndo() || session_.stroke_active());
    if (ImGui::Button("Undo")) {
      if (context->tree != nullptr) {
        context->tree->Undo();
      } else {
        doc.Undo();
      }
    }
    ImGui::EndDisabled();
    ImGui::SameLine();
    ImGui::BeginDisabled(!history.CanRedo() || session_.stroke_active());
    if (ImGui::Button("Redo")) {
      if (context->tree != nullptr) {
        context->tree->Redo();
      } else {
        doc.Redo();
      }
    }
    ImGui::EndDisabled();
    if (history.CanUndo()) {
      ImGui::SameLine();
      ImGui::TextDisabled("%s", history.UndoDescription().c_str());
    }
  } else {
    ImGui::BeginDisabled(!session_.CanUndo());
    if (ImGui::Button("Undo stroke")) session_.Undo();
    ImGui::EndDisabled();
    ImGui::SameLine();
    ImGui::BeginDisabled(!session_.CanRedo());
    if (ImGui::Button("Redo stroke")) session_.Redo();
    ImGui::EndDisabled();
    ImGui::SameLine();
    ImGui::Text("%d / %d", session_.undo_count(), session_.redo_count());
  }

  ImGui::Separator();
  char path[512];
  const bool busy = jobs_ && jobs_->busy();
  std::snprintf(path, sizeof(path), "%s", export_path_.c_str());
  if (ImGui::InputText("export file", path, sizeof(path))) export_path_ = path;
  ImGui::BeginDisabled(!mesh || session_.stroke_active());
  if (ImGui::Button("Export STL")) {
    try {
      modeling::WriteTriangleMesh(session_.ExportMesh(), export_path_);
      message_ = "wrote " + export_path_;
    } catch (const std::exception& e) {
      message_ = e.what();
    }
  }
  ImGui::SameLine();
  ImGui::BeginDisabled(busy || !jobs_);
  if (ImGui::Button("Tetrahedralize for FE")) session_.StartTetrahedralize(jobs_);
  ImGui::EndDisabled();
  if (with_document) {
    ImGui::SameLine();
    ImGui::BeginDisabled(target_ == 0 || context->model->document().Find(target_) == nullptr);
    if (ImGui::Button("Send to FE")) RequestSendToFe();
    ImGui::EndDisabled();
  }
  ImGui::EndDisabled();
  if (session_.tet_mesh()) {
    ImGui::Text("Tet mesh: %ld nodes, %ld tetrahedra",
                static_cast<long>(session_.tet_mesh()->nodes.cols()),
                static_cast<long>(session_.tet_mesh()->tets.cols()));
    ImGui::SameLine();
    if (ImGui::Button("Export VTU")) {
      const std::string vtu =
          std::filesystem::path(export_path_).replace_extension(".vtu").string();
      try {
        modeling::WriteVtu(*session_.tet_mesh(), vtu);
        message_ = "wrote " + vtu;
      } catch (const std::exception& e) {
        message_ = e.what();
      }
    }
  }
  if (!session_.job_message().empty()) ImGui::TextWrapped("%s", session_.job_message().c_str());
  if (!message_.empty()) ImGui::TextWrapped("%s", message_.c_str());
}

}  // namespace spidarcad::app
