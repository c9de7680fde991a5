// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#include "gui/fe_mode.h"

#include <imgui.h>
#include <vtkActor.h>
#include <vtkCellArray.h>
#include <vtkDoubleArray.h>
#include <vtkLookupTable.h>
#include <vtkPointData.h>
#include <vtkPoints.h>
#include <vtkPolyData.h>
#include <vtkPolyDataMapper.h>
#include <vtkProperty.h>
#include <vtkRenderer.h>
#include <vtkScalarBarActor.h>
#include <vtkSphereSource.h>
#include <vtkTextProperty.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <utility>

#include "doc/command.h"
#include "scene/scene_model.h"

namespace spidarcad::app {

FeMode::FeMode(vtkRenderer* renderer, JobQueue* jobs)
    : renderer_(renderer), jobs_(jobs), channel_(std::make_shared<FeContactChannel>()) {
  mesh_settings_.mesher = "tetgen";
  touch_settings_ = DefaultFeTouchSettings();  // as `spidarcad run` (scene/fe_part.h)
  // After an edit the tool is usually on the part already: its nearest nodes' columns first, in a
  // block of their own (half the right-hand sides of a full block).
  model_settings_.cache.first_block_nodes = kFeModeFirstColumns;
  touch_settings_.force_scale = std::pow(10.0, log_force_scale_);  // the slider's value
  poly_ = vtkSmartPointer<vtkPolyData>::New();
  scalars_ = vtkSmartPointer<vtkDoubleArray>::New();
  scalars_->SetName("von_mises_MPa");
  lut_ = vtkSmartPointer<vtkLookupTable>::New();
  lut_->SetHueRange(0.667, 0.0);  // blue (low) to red (high)
  lut_->SetTableRange(0.0, 1.0);
  lut_->Build();
  auto mapper = vtkSmartPointer<vtkPolyDataMapper>::New();
  mapper->SetInputData(poly_);
  mapper->SetLookupTable(lut_);
  mapper->SetScalarModeToUsePointData();
  mapper->UseLookupTableScalarRangeOn();
  actor_ = vtkSmartPointer<vtkActor>::New();
  actor_->SetMapper(mapper);
  actor_->VisibilityOff();
  legend_ = vtkSmartPointer<vtkScalarBarActor>::New();
  legend_->SetLookupTable(lut_);
  legend_->SetTitle("von Mises [MPa]");
  legend_->SetNumberOfLabels(5);
  legend_->SetMaximumWidthInPixels(90);
  legend_->GetPositionCoordinate()->SetValue(0.88, 0.1);
  legend_->SetWidth(0.1);
  legend_->SetHeight(0.8);
  legend_->VisibilityOff();
  sphere_source_ = vtkSmartPointer<vtkSphereSource>::New();
  sphere_source_->SetThetaResolution(24);
  sphere_source_->SetPhiResolution(16);
  auto sphere_mapper = vtkSmartPointer<vtkPolyDataMapper>::New();
  sphere_mapper->SetInputConnection(sphere_source_->GetOutputPort());
  sphere_actor_ = vtkSmartPointer<vtkActor>::New();
  sphere_actor_->SetMapper(sphere_mapper);
  sphere_actor_->GetProperty()->SetColor(0.2, 0.8, 0.3);
  sphere_actor_->GetProperty()->SetOpacity(0.35);
  sphere_actor_->VisibilityOff();
  if (renderer_ != nullptr) {
    renderer_->AddActor(actor_);
    renderer_->AddActor(sphere_actor_);
    renderer_->AddActor2D(legend_);
  }
}

FeMode::~FeMode() {
  if (renderer_ != nullptr) {
    renderer_->RemoveActor(actor_);
    renderer_->RemoveActor(sphere_actor_);
    renderer_->RemoveActor2D(legend_);
  }
}

void FeMode::SetWorldToView(const haptics::DeviceToWorld& X_WD) {
  const double s = X_WD.world_scale;
  if (!(s > 0.0)) return;
  const bool rescaled = s != X_WD_.world_scale;
  X_WD_ = X_WD;
  if (rescaled && active_ && model_) QueueField();  // the felt force scale depends on it
  for (vtkActor* a : {actor_.Get(), sphere_actor_.Get()}) {
    a->SetScale(1.0 / s);
    a->SetPosition(-X_WD.p_WDo.x() / s, -X_WD.p_WDo.y() / s, -X_WD.p_WDo.z() / s);
  }
}

void FeMode::SetActive(bool active) {
  if (active == active_) return;
  active_ = active;
  const bool show = active_ && model_ != nullptr;
  actor_->SetVisibility(show);
  legend_->SetVisibility(show);
  sphere_actor_->SetVisibility(show);
  if (active_) {
    if (model_) QueueField();
  } else {
    pending_field_.reset();
    if (model_ && jobs_ != nullptr) {
      std::shared_ptr<FeModel> model = model_;
      jobs_->Start("Save FE columns", [model](JobContext&) -> Job::Finisher {
        std::string error;
        model->SaveColumns(&error);  // best effort: a cache that cannot be written is not an error
        return [] {};
      });
    }
  }
}

void FeMode::SetMesh(fem::TetMesh mesh, std::string name, Eigen::VectorXi slab,
                     std::vector<int> place) {
  DropModel();
  mesh_ = std::make_shared<const fem::TetMesh>(std::move(mesh));
  mesh_slab_ = std::move(slab);
  mesh_place_ = std::move(place);
  mesh_name_ = std::move(name);
  pending_field_.reset();
  actor_->VisibilityOff();
  legend_->VisibilityOff();
  sphere_actor_->VisibilityOff();
  status_ = mesh_name_ + ": " + std::to_string(mesh_->num_elements()) + " tets, " +
            std::to_string(mesh_->num_nodes()) + " nodes; press Precompute";
}

void FeMode::Precompute() {
  if (jobs_ == nullptr || !mesh_ || RunningJob() != nullptr) return;
  FeModelSettings settings = model_settings_;
  settings.element_block = mesh_slab_;
  settings.block_place = mesh_place_;
  if (mesh_slab_.size() > 0) settings.reuse = reuse_model_;
  std::shared_ptr<const fem::TetMesh> mesh = mesh_;
  job_key_ = bound_key_;
  const BoundKey key = bound_key_;
  job_title_ = "FE precompute " + mesh_name_;
  awaiting_title_ = job_title_;
  status_ = "precomputing...";
  std::weak_ptr<int> alive = alive_;
  jobs_->Start(
      job_title_, [this, settings, mesh, key, alive](JobContext& ctx) mutable -> Job::Finisher {
        settings.cancel = ctx.cancel_flag();
        settings.progress = ctx.ProgressRange(0.0, 1.0);
        settings.phase = [&ctx](const std::string& p) { ctx.SetPhase(p); };
        std::shared_ptr<FeModel> model = FeModel::Build(*mesh, settings);
        settings.progress = nullptr;
        settings.phase = nullptr;
        return [this, model, mesh, key, alive] {
          if (!alive.lock()) return;
          awaiting_title_.clear();
          if (mesh != mesh_ || !(key == bound_key_)) return;  // part changed: drop the result
          model_ = model;
          reuse_model_.reset();
          if (key.fe != 0) {
            kept_.emplace_back(key, model);
            if (kept_.size() > kKeptModels) kept_.erase(kept_.begin());
          }
          char line[160];
          std::snprintf(line, sizeof line,
                        "ready: %d nodes clamped, %zu surface nodes, %d columns from disk, %.1f s",
                        model_->num_fixed_nodes(), model_->surface().nodes.size(),
                        model_->imported_nodes(), model_->build_seconds());
          status_ = line;
          if (const fem::SubstructuredSolver* slabs = model_->substructured()) {
            // Pieces: the slabs, or the strips of a slab cut into strips.
            std::snprintf(line, sizeof line, "; %d of %d pieces factored, %d kept",
                          slabs->stats().factored_blocks, slabs->num_blocks(),
                          slabs->stats().reused_blocks);
            status_ += line;
            if (slabs->stats().loaded_blocks > 0) {
              std::snprintf(line, sizeof line, ", %d from the disk cache",
                            slabs->stats().loaded_blocks);
              status_ += line;
            }
          }
          BuildSurfaceActor();
          ShowModel(active_);
          if (active_) QueueField();
        };
      });
}

void FeMode::ShowModel(bool show) {
  actor_->SetVisibility(show);
  legend_->SetVisibility(show);
  sphere_actor_->SetVisibility(show);
}

Job* FeMode::RunningJob() const {
  if (jobs_ == nullptr) return nullptr;
  for (const auto& job : jobs_->jobs())
    if (job->title() == job_title_ && job->state() == Job::State::kRunning) return job.get();
  return nullptr;
}

void FeMode::QueueField() {
  if (!model_) return;
  const FeTouchSettings ts = ResolvedFieldSettings(*model_, touch_settings_, X_WD_.world_scale);
  sphere_source_->SetRadius(ts.tool_radius);
  if (grab_) {
    pending_field_ = std::make_unique<FePushGrabField>(
        std::make_unique<FeTouchField>(model_, ts, channel_),
        std::make_unique<FeGrabField>(
            model_, ResolvedGrabSettings(*model_, grab_settings_, X_WD_.world_scale),
            grab_channel_));
  } else {
    pending_field_ = std::make_unique<FeTouchField>(model_, ts, channel_);
  }
}

std::unique_ptr<haptics::ForceField> FeMode::TakeField() {
  if (!active_ || !pending_field_) return nullptr;
  field_taken_ = true;
  field_start_time_ = -1.0;
  return std::move(pending_field_);
}

bool FeMode::Settled() const {
  if (!active_) return true;
  if (!model_) {
    // A model is about to be asked for (a set-up landed, the document changed).
    if (rebuild_pending_ || precompute_on_bind_) return false;
    // Waiting while a job of ours runs or has succeeded with its finisher still to run.
    if (awaiting_title_.empty() || jobs_ == nullptr) return true;
    for (const auto& job : jobs_->jobs())
      if (job->title() == awaiting_title_ &&
          (job->state() == Job::State::kRunning || job->state() == Job::State::kSucceeded))
        return false;
    return true;
  }
  if (pending_field_ || !field_taken_ || field_start_time_ < 0.0) return false;
  return last_state_.time - field_start_time_ >= kSettleSeconds &&
         model_->cache().WaitUntilIdle(0.0);
}

void FeMode::BuildSurfaceActor() {
  const fem::TetMesh& mesh = model_->mesh();
  auto points = vtkSmartPointer<vtkPoints>::New();
  points->SetDataTypeToDouble();
  points->SetNumberOfPoints(mesh.num_nodes());
  for (int v = 0; v < mesh.num_nodes(); ++v)
    points->SetPoint(v, mesh.nodes(v, 0), mesh.nodes(v, 1), mesh.nodes(v, 2));
  auto tris = vtkSmartPointer<vtkCellArray>::New();
  const fem::MatrixXiR& faces = model_->surface().faces;
  for (Eigen::Index f = 0; f < faces.rows(); ++f) {
    const vtkIdType ids[3] = {faces(f, 0), faces(f, 1), faces(f, 2)};
    tris->InsertNextCell(3, ids);
  }
  scalars_->SetNumberOfValues(mesh.num_nodes());
  scalars_->Fill(0.0);
  poly_->SetPoints(points);
  poly_->SetPolys(tris);
  poly_->GetPointData()->SetScalars(scalars_);
  poly_->Modified();
  magnify_shown_ = -1.0;
  UpdateSurface(nullptr);
}

void FeMode::UpdateSurface(const FeContactState* state) {
  if (!model_) return;
  if (state != nullptr) {
    last_state_ = *state;
    if (field_taken_ && field_start_time_ < 0.0) field_start_time_ = state->time;
  }
  Eigen::VectorXd u_out;
  if (last_grab_.ready) {
    GrabDisplacement(&model_->cache(), last_grab_, &u_out);
  } else {
    ContactDisplacement(&model_->cache(), last_state_, &u_out);
  }
  const Eigen::MatrixX3d u = model_->FullDisplacement(u_out);
  const Eigen::VectorXd vm = model_->NodalVonMises(u_out);
  const fem::TetMesh& mesh = model_->mesh();
  vtkPoints* points = poly_->GetPoints();
  double max_u = 0.0, max_vm = 0.0;
  for (int v : model_->surface().nodes) {
    max_u = std::max(max_u, u.row(v).norm());
    max_vm = std::max(max_vm, vm(v));
  }
  for (int v = 0; v < mesh.num_nodes(); ++v) {
    const Eigen::Vector3d x = mesh.nodes.row(v).transpose() + magnify_ * u.row(v).transpose();
    points->SetPoint(v, x.x(), x.y(), x.z());
    scalars_->SetValue(v, 1e-6 * vm(v));
  }
  points->Modified();
  scalars_->Modified();
  const double top =
      auto_range_ ? std::max(1e-3, 1e-6 * max_vm) : std::max(1e-6, static_cast<double>(range_mpa_));
  lut_->SetTableRange(0.0, top);
  figures_.f_tool_W = last_grab_.ready ? last_grab_.f_tool_W : last_state_.f_tool_W;
  figures_.contacts = last_grab_.ready ? 0 : last_state_.num_contacts;
  figures_.substituted =
      last_grab_.ready ? last_grab_.num_substituted : last_state_.num_substituted;
  figures_.refused = last_grab_.ready ? 0 : last_state_.refused;
  figures_.grabbed = last_grab_.ready ? last_grab_.num_nodes : 0;
  figures_.m_tool_W = last_grab_.ready ? last_grab_.m_tool_W : Eigen::Vector3d::Zero();
  figures_.max_displacement = max_u;
  figures_.max_von_mises = max_vm;
  magnify_shown_ = magnify_;
}

void FeMode::OnFrame(const haptics::ToolState& tool) {
  // Not while a panel value is being dragged: each step of the drag changes the model again.
  const bool dragging = ImGui::GetCurrentContext() != nullptr && ImGui::IsAnyItemActive();
  if (rebuild_pending_ && mesh_ && RunningJob() == nullptr && !dragging) {
    rebuild_pending_ = false;
    Precompute();
  }
  if (!model_) return;
  // Both ends of the model's interface factor for the next edit, once the columns near the tool
  // are ready (or the model has gone untouched for a while): its BLAS would slow those columns.
  if (model_->substructured() != nullptr && !model_->cache().paused() &&
      (model_->cache().has_focus() ? model_->cache().WaitUntilIdle(0.0)
                                   : model_->age_seconds() > kPrepareReuseAfterSeconds))
    model_->PrepareReuseInBackground();
  figures_.ready_columns = model_->cache().ready_nodes();
  const Eigen::Vector3d& p = tool.tool_W.p_WT;
  sphere_actor_->SetVisibility(active_);
  sphere_source_->SetCenter(p.x(), p.y(), p.z());
  if (!active_) return;
  bool fresh = channel_->buffer.Update();
  if (grab_channel_->buffer.Update()) {  // the grab's state (drawn instead while it holds)
    const bool was = last_grab_.ready;
    last_grab_ = grab_channel_->buffer.Read();
    if (last_grab_.ready || was) fresh = true;
  }
  if (fresh || magnify_shown_ != magnify_)
    UpdateSurface(fresh ? &channel_->buffer.Read() : nullptr);
  const bool touching = figures_.contacts > 0 || figures_.grabbed > 0;
  sphere_actor_->GetProperty()->SetColor(touching ? 0.95 : 0.2, touching ? 0.5 : 0.8, 0.2);
}

void FeMode::DrawPanel(SceneModel* model, ObjectId selected) {
  if (model != nullptr) SyncDocument(model, selected);
  ImGui::PushTextWrapPos(0.0f);
  ImGui::TextUnformatted(status_.c_str());
  ImGui::PopTextWrapPos();
  if (model != nullptr) DrawDocumentPanel(model);
  DrawSettingsPanel(model);

  Job* running = RunningJob();
  if (running != nullptr) {
    ImGui::ProgressBar(static_cast<float>(running->progress()), ImVec2(-90, 0),
                       running->phase().c_str());
    ImGui::SameLine();
    if (ImGui::Button("Cancel")) running->Cancel();
  } else {
    if (!mesh_) ImGui::BeginDisabled();
    if (ImGui::Button("Precompute")) RequestModel();
    if (!mesh_) ImGui::EndDisabled();
  }

  ImGui::Separator();
  ImGui::TextUnformatted("Touch");
  bool changed = false;
  float radius_mm = static_cast<float>(1e3 * touch_settings_.tool_radius);
  // The tool's physical radius on the part (W): the patch every push and grab covers.
  if (ImGui::DragFloat("tool radius on the part [mm]", &radius_mm, 0.1f, 0.5f, 50.0f, "%.1f")) {
    touch_settings_.tool_radius = 1e-3 * std::max(0.5f, radius_mm);
    changed = true;
  }
  if (ImGui::SliderFloat("log10 force scale", &log_force_scale_, -8.0f, 0.0f, "%.1f")) {
    touch_settings_.force_scale = std::pow(10.0, log_force_scale_);
    changed = true;
  }
  float coupling = static_cast<float>(touch_settings_.coupling_stiffness);
  if (ImGui::SliderFloat("coupling [N/m] (0: off)", &coupling, 0.0f, 5000.0f, "%.0f")) {
    touch_settings_.coupling_stiffness = std::max(0.0f, coupling);
    changed = true;
  }
  float max_force = static_cast<float>(touch_settings_.max_force);
  if (ImGui::SliderFloat("max felt force [N]", &max_force, 0.5f, 20.0f, "%.1f")) {
    touch_settings_.max_force = max_force;
    changed = true;
  }
  changed |= ImGui::Checkbox("two-point grasp (pole tips)", &touch_settings_.grasp);
  if (touch_settings_.grasp) {
    float pole_mm = static_cast<float>(1e3 * touch_settings_.pole_length);
    if (ImGui::DragFloat("pole length in W [mm]", &pole_mm, 0.5f, 1.0f, 500.0f, "%.1f")) {
      touch_settings_.pole_length = 1e-3 * std::max(1.0f, pole_mm);
      changed = true;
    }
  }
  changed |= ImGui::Checkbox("grasp grabs (6 DOF; push when open)", &grab_);
  if (grab_) {
    float rot = static_cast<float>(grab_settings_.coupling_rot_stiffness);
    if (ImGui::SliderFloat("grab twist coupling [N·m/rad]", &rot, 0.1f, 10.0f, "%.1f")) {
      grab_settings_.coupling_rot_stiffness = std::max(0.1f, rot);
      changed = true;
    }
    grab_settings_.force_scale = touch_settings_.force_scale;
    grab_settings_.tool_radius = touch_settings_.tool_radius;
    grab_settings_.coupling_stiffness = touch_settings_.coupling_stiffness;
  }
  if (changed && active_ && model_) QueueField();

  ImGui::Separator();
  ImGui::SliderFloat("magnify", &magnify_, 1.0f, 10000.0f, "%.0f x", ImGuiSliderFlags_Logarithmic);
  ImGui::Checkbox("auto stress range", &auto_range_);
  if (!auto_range_) ImGui::DragFloat("range [MPa]", &range_mpa_, 1.0f, 0.001f, 10000.0f, "%.3f");
  if (model_) {
    const Eigen::Vector3d& f = figures_.f_tool_W;
    ImGui::Text("reaction on tool: %.3f N  (%.3f, %.3f, %.3f)", f.norm(), f.x(), f.y(), f.z());
    const double felt_scale = FieldTouchSettings(touch_settings_, X_WD_.world_scale).force_scale;
    ImGui::Text("felt: %.3f N (scale %.1e, max %.1f N)",
                std::min(touch_settings_.max_force, felt_scale * f.norm()), felt_scale,
                touch_settings_.max_force);
    ImGui::Text("contacts: %d (%d on borrowed columns)", figures_.contacts, figures_.substituted);
    if (figures_.refused > 0)
      ImGui::TextColored(ImVec4(1.0f, 0.6f, 0.2f, 1.0f),
                         "tool patch truncated: %d nodes beyond %d left out (a smaller tool is "
                         "felt; lower the tool radius or coarsen the mesh)",
                         figures_.refused, kMaxFeContacts);
    if (grab_) {
      const Eigen::Vector3d& m = figures_.m_tool_W;
      ImGui::Text("grabbed: %d nodes, FE moment on tool %.3f N·m (%.3f, %.3f, %.3f)",
                  figures_.grabbed, m.norm(), m.x(), m.y(), m.z());
    }
    ImGui::Text("max displacement: %.4f mm", 1e3 * figures_.max_displacement);
    ImGui::Text("max von Mises: %.3f MPa", 1e-6 * figures_.max_von_mises);
    ImGui::Text("columns ready: %d of %d", figures_.ready_columns,
                model_->cache().num_candidates());
  }
}

// ---- the document ----

FeSourceKind FeMode::KindOf(const Document& doc, ObjectId id) {
  const DocObject* o = doc.Find(id);
  if (o == nullptr) return FeSourceKind::kNone;
  auto it = kinds_.find(id);
  if (it != kinds_.end() && it->second.first == o->revision) return it->second.second;
  const FeSourceKind kind = ClassifyFeSource(doc, id);
  kinds_[id] = {o->revision, kind};
  return kind;
}

FeMode::BoundKey FeMode::KeyOf(const Document& doc, ObjectId fe) {
  BoundKey key;
  const DocObject* o = doc.Find(fe);
  const auto* data = o != nullptr ? std::get_if<FeModelData>(&o->data) : nullptr;
  if (data == nullptr) return key;
  key.fe = fe;
  key.fe_revision = o->revision;
  key.mesh = data->tet_mesh;
  if (const DocObject* mesh = doc.Find(data->tet_mesh)) key.mesh_revision = mesh->revision;
  return key;
}

namespace {

// The kinds FE mode meshes in slabs when asked (FeMode::mesh_in_slabs): those a local edit
// changes in one place (a solid's feature, a sculpt stroke).
bool SlabbedKind(FeSourceKind kind) {
  return kind == FeSourceKind::kSolid || kind == FeSourceKind::kSculpt;
}

// The "Elements: linear / quadratic" radio buttons (`id` tells copies apart); the order chosen.
int ElementOrderChoice(int order, const char* id) {
  ImGui::TextUnformatted("Elements");
  ImGui::SameLine();
  if (ImGui::RadioButton((std::string("linear") + id).c_str(), order != 2)) order = 1;
  ImGui::SameLine();
  if (ImGui::RadioButton((std::string("quadratic") + id).c_str(), order == 2)) order = 2;
  if (ImGui::IsItemHovered())
    ImGui::SetTooltip(
        "10-node tets: no locking in bending. A solid's flat faces are meshed coarser for them "
        "(about a cell), so edits and precomputes are faster");
  return order;
}

// Whether FE mode can choose the object, judged by its kind alone (cheap, every frame; whether a
// surface is closed is checked when it is set up).
bool MayBecomeFeModel(const Document& doc, ObjectId id) {
  const DocObject* o = doc.Find(id);
  if (o == nullptr) return false;
  if (const auto* m = std::get_if<MeshData>(&o->data)) return m->volume || m->surface;
  return !std::holds_alternative<RigidPartData>(o->data);
}

}  // namespace

void FeMode::SyncDocument(SceneModel* model, ObjectId selected) {
  if (model == nullptr) return;
  const Document& doc = model->document();
  if (model->generation() != generation_) {
    // Another document (open, new, reload): ids start again, nothing of the old one applies.
    generation_ = model->generation();
    chosen_ = 0;
    last_selected_ = 0;
    kept_.clear();
    auto_refreshed_ = {0, 0};
    kinds_.clear();
    slab_meshes_.clear();
    reuse_model_.reset();
    pending_text_.clear();
    want_model_ = false;
    rebuild_pending_ = false;
    precompute_on_bind_ = false;
    Rebind(doc, 0);
  }
  // A Job of ours that failed or was cancelled: say so (the newest of that title is ours).
  if (!awaiting_title_.empty() && jobs_ != nullptr) {
    bool listed = false;
    for (auto it = jobs_->jobs().rbegin(); it != jobs_->jobs().rend(); ++it) {
      const Job* job = it->get();
      if (job->title() != awaiting_title_) continue;
      listed = true;
      if (job->state() == Job::State::kFailed) {
        status_ = job->title() + " failed: " + job->error();
        awaiting_title_.clear();
        precompute_on_bind_ = false;
      } else if (job->state() == Job::State::kCancelled) {
        status_ = job->title() + ": cancelled, nothing changed";
        awaiting_title_.clear();
        precompute_on_bind_ = false;
      }
      break;
    }
    if (!listed) {  // the window prunes ended jobs: this one ended without its finisher
      status_ = awaiting_title_ + ": stopped (cancelled or failed), nothing changed";
      awaiting_title_.clear();
      precompute_on_bind_ = false;
    }
    // A refresh that ended without its mesh leaves the model shown as it was: its columns again.
    if (awaiting_title_.empty() && model_) model_->cache().SetPaused(false);
  }
  if (selected != last_selected_) {
    last_selected_ = selected;
    if (selected != 0 && MayBecomeFeModel(doc, selected)) chosen_ = selected;
  }
  if (chosen_ != 0 && !MayBecomeFeModel(doc, chosen_)) chosen_ = 0;
  ObjectId fe = 0;
  if (chosen_ != 0) {
    fe = FeModelFor(doc, chosen_);
  } else {
    for (const DocObject& o : doc.objects()) {
      if (std::holds_alternative<FeModelData>(o.data)) {
        fe = o.id;
        break;
      }
    }
  }
  if (fe != bound_ || KeyOf(doc, fe) != bound_key_) Rebind(doc, fe);
  if (doc.revision() != doc_revision_) {
    doc_revision_ = doc.revision();
    stale_ = bound_key_.mesh != 0 && doc.Find(bound_key_.mesh) != nullptr &&
             doc.IsMeshOutOfDate(bound_key_.mesh);
  }
  // Refresh on edit, while a model is felt, not while a panel value is being dragged: once per
  // revision of the source (a refresh that fails is tried again only after the next edit, and
  // the undo of a refresh is not refreshed again, which would end the redo history).
  const bool dragging = ImGui::GetCurrentContext() != nullptr && ImGui::IsAnyItemActive();
  if (refresh_on_edit_ && stale_ && active_ && model_ && !dragging && RunningJob() == nullptr) {
    const auto& mesh = std::get<MeshData>(doc.Get(bound_key_.mesh).data);
    const DocObject* source = doc.Find(mesh.source);
    const std::pair<ObjectId, std::uint64_t> edit{mesh.source,
                                                  source != nullptr ? source->revision : 0};
    if (source != nullptr && edit != auto_refreshed_) {
      auto_refreshed_ = edit;
      StartRefresh(model);
    }
  }
}

void FeMode::Rebind(const Document& doc, ObjectId fe) {
  const bool same_object = fe == bound_ && fe != 0;
  const BoundKey key = KeyOf(doc, fe);
  const BoundKey old_key = bound_key_;
  bound_ = fe;
  bound_key_ = key;
  doc_revision_ = 0;  // recompute staleness
  // A precompute of what is no longer shown is of no use.
  if (Job* running = RunningJob(); running != nullptr && awaiting_title_ == job_title_ &&
                                   job_key_ != key && job_title_.rfind("FE precompute", 0) == 0) {
    running->Cancel();
  }
  if (!same_object) want_model_ = false;
  if (fe == 0) {
    mesh_.reset();
    DropModel();
    pending_field_.reset();
    ShowModel(false);
    mesh_name_.clear();
    if (awaiting_title_.empty()) status_ = "no FE model: choose an object and set up FE";
    return;
  }
  const DocObject& o = doc.Get(fe);
  const auto& data = std::get<FeModelData>(o.data);
  model_settings_ = ApplyFeModelData(data, model_settings_);
  model_settings_.design = FeDesignOf(doc, data.tet_mesh);  // the tool pushes along its normals
  preset_ = -1;
  for (int i = 0; i < static_cast<int>(std::size(kMaterialPresets)); ++i) {
    if (kMaterialPresets[i].material.youngs_modulus == data.material.youngs_modulus &&
        kMaterialPresets[i].material.poisson_ratio == data.material.poisson_ratio)
      preset_ = i;
  }
  box_fixed_ = !data.fixed_boxes.empty();
  if (box_fixed_) {
    for (int k = 0; k < 3; ++k) {
      box_[k] = static_cast<float>(data.fixed_boxes[0].min()[k]);
      box_[3 + k] = static_cast<float>(data.fixed_boxes[0].max()[k]);
    }
  }
  if (old_key.fe == key.fe && old_key.mesh == key.mesh &&
      old_key.mesh_revision == key.mesh_revision && mesh_) {
    // Only the FE settings changed: same mesh, new model (the slabs whose content the change left,
    // e.g. far from a moved clamp, keep their factors).
    DropModel();
    pending_field_.reset();
    ShowModel(false);
    mesh_name_ = o.name;
    // (While a job of ours runs, e.g. the re-mesh an order switch started, its status stays.)
    if (awaiting_title_.empty()) status_ = o.name + ": settings changed; press Precompute";
  } else {
    try {
      fem::TetMesh mesh = FeMeshOf(doc, data);
      Eigen::VectorXi slab;
      std::vector<int> place;
      if (const std::shared_ptr<const SlabFeMesh> slabs = SlabsOf(doc, data.tet_mesh)) {
        slab = slabs->slab;
        place = slabs->piece_slab;
      } else if (const MeshSettings& ms = std::get<MeshData>(doc.Get(data.tet_mesh).data).settings;
                 !ms.slab_planes.empty()) {
        // e.g. a document opened from a file
        slab = SlabPieceLabels(mesh, ms.slab_planes, ms.slab_strip_axis, ms.slab_strips, &place);
      }
      SetMesh(std::move(mesh), o.name, std::move(slab), std::move(place));
    } catch (const std::exception& e) {
      mesh_.reset();
      status_ = o.name + ": " + e.what();
      return;
    }
  }
  if (precompute_on_bind_) {
    precompute_on_bind_ = false;
    want_model_ = true;
  }
  for (const auto& [kept_key, kept_model] : kept_) {
    if (kept_key != key) continue;
    model_ = kept_model;
    model_->cache().SetPaused(false);
    status_ = o.name + ": ready (kept from before: " + std::to_string(model_->num_fixed_nodes()) +
              " nodes clamped)";
    BuildSurfaceActor();
    ShowModel(active_);
    if (active_) QueueField();
    return;
  }
  if (want_model_) rebuild_pending_ = true;
}

void FeMode::DropModel() {
  if (!model_) return;
  // Its columns are no longer wanted, and its worker would take the cores from the next model's
  // precomputation; the haptic thread may still read its ready columns until a new field lands.
  model_->cache().SetPaused(true);
  if (model_->substructured()) reuse_model_ = model_;
  model_.reset();
}

std::filesystem::path FeMode::SlabCacheDirectory() const {
  if (!model_settings_.use_disk_cache) return {};
  return model_settings_.cache_directory.empty() ? fem::DefaultCacheDirectory()
                                                 : model_settings_.cache_directory;
}

std::shared_ptr<const SlabFeMesh> FeMode::SlabsOf(const Document& doc, ObjectId mesh) const {
  const DocObject* o = doc.Find(mesh);
  const auto* data = o != nullptr ? std::get_if<MeshData>(&o->data) : nullptr;
  if (data == nullptr || !data->volume) return nullptr;
  for (const auto& slabs : slab_meshes_)
    if (slabs->volume == data->volume) return slabs;
  return nullptr;
}

void FeMode::RequestModel() {
  want_model_ = true;
  Precompute();
}

bool FeMode::Execute(SceneModel* model, std::unique_ptr<Command> command) {
  try {
    model->document().Execute(std::move(command));
    return true;
  } catch (const std::exception& e) {
    status_ = std::string("not changed: ") + e.what();
    return false;
  }
}

bool FeMode::StartSetUp(SceneModel* model, ObjectId source, bool check_budget, bool precompute) {
  if (model == nullptr) return false;
  Document& doc = model->document();
  const FeSourceKind kind = KindOf(doc, source);
  const DocObject* o = doc.Find(source);
  if (kind == FeSourceKind::kNone || o == nullptr) {
    status_ = "set up FE: choose a solid, sculpt or mesh (that one cannot become an FE model)";
    return false;
  }
  chosen_ = source;
  if (const ObjectId fe = FeModelFor(doc, source); fe != 0) {
    SyncDocument(model, last_selected_);
    if (precompute && bound_ == fe) RequestModel();
    return true;
  }
  const int order = model_settings_.order == 2 ? 2 : 1;
  if (kind == FeSourceKind::kVolumeMesh) {
    precompute_on_bind_ = precompute;
    if (!Execute(model, SetUpFeOnMesh(doc, source, order))) return false;
    SyncDocument(model, last_selected_);
    return true;
  }
  if (jobs_ == nullptr || RunningJob() != nullptr) {
    status_ = "set up FE: wait for the running job";
    return false;
  }
  FeMeshInput input;
  try {
    input = PrepareFeMesh(doc, source, mesh_settings_);
    input.element_order = order;
    input.settings.flat_cells = FlatCellsForOrder(input.kind, input.settings, order);
    if (mesh_in_slabs_ && SlabbedKind(input.kind)) {
      input.slabs = kFeSlabs;
      input.strips = mesh_strips_;
      input.strip_min_triangles = mesh_strip_min_triangles_;
      input.cache_directory = SlabCacheDirectory();
    }
  } catch (const std::exception& e) {
    status_ = std::string("set up FE: ") + e.what();
    return false;
  }
  if (check_budget && input.kind == FeSourceKind::kSolid && input.settings.mesher != "cgal") {
    StartEstimateJob(model, o->name, input, precompute);
    return true;
  }
  precompute_on_bind_ = precompute;
  StartMeshJob(model, input, false, 0);
  return true;
}

void FeMode::StartEstimateJob(SceneModel* model, const std::string& name, const FeMeshInput& input,
                              bool precompute) {
  job_title_ = "Estimate the mesh of " + input.source_name;
  awaiting_title_ = job_title_;
  status_ = "set up FE: estimating the mesh of '" + input.source_name + "'...";
  std::weak_ptr<int> alive = alive_;
  const int generation = model->generation();
  jobs_->Start(
      job_title_,
      [this, model, name, input, precompute, generation, alive](JobContext& ctx) -> Job::Finisher {
        ctx.SetPhase("box");
        ctx.SetProgress(0.0);
        std::string question = LargeMeshQuestion(name, input, ctx.cancel_flag());
        ctx.SetProgress(1.0);
        return [this, model, input, precompute, generation, alive, question = std::move(question)] {
          if (!alive.lock()) return;
          awaiting_title_.clear();
          if (model->generation() != generation) return;  // another document
          if (!question.empty()) {
            pending_input_ = input;
            pending_precompute_ = precompute;
            pending_text_ = question;
            status_ = "set up FE: waiting for an answer (the mesh is large)";
            return;
          }
          precompute_on_bind_ = precompute;
          StartMeshJob(model, input, false, 0);
        };
      });
}

void FeMode::ConfirmSetUp(SceneModel* model, bool proceed) {
  if (pending_text_.empty()) return;
  pending_text_.clear();
  if (!proceed || model == nullptr) {
    status_ = "set up FE: cancelled, nothing changed";
    return;
  }
  precompute_on_bind_ = pending_precompute_;
  StartMeshJob(model, pending_input_, false, 0);
}

bool FeMode::StartRefresh(SceneModel* model) {
  if (model == nullptr || bound_key_.mesh == 0 || jobs_ == nullptr || RunningJob() != nullptr)
    return false;
  try {
    FeMeshInput input = PrepareFeRemesh(model->document(), bound_key_.mesh);
    // The mesh follows the FE model's element order (flat faces coarsened for quadratic).
    input.settings.flat_cells =
        FlatCellsForOrder(input.kind, input.settings, BoundElementOrder(model->document()));
    if (mesh_in_slabs_ && SlabbedKind(input.kind)) {
      input.slabs = kFeSlabs;
      input.strips = mesh_strips_;
      input.strip_min_triangles = mesh_strip_min_triangles_;
      input.previous_slabs = SlabsOf(model->document(), bound_key_.mesh);
      input.cache_directory = SlabCacheDirectory();
    }
    want_model_ = want_model_ || model_ != nullptr;
    StartMeshJob(model, input, true, bound_key_.mesh);
    // The model shown is about to be replaced: its worker gives the cores to the refresh (its
    // ready columns are still felt). Let go again if the refresh fails or is cancelled.
    if (model_) model_->cache().SetPaused(true);
  } catch (const std::exception& e) {
    status_ = std::string("refresh: ") + e.what();
    return false;
  }
  return true;
}

void FeMode::StartMeshJob(SceneModel* model, const FeMeshInput& input, bool refresh_mesh,
                          ObjectId mesh) {
  job_title_ = (refresh_mesh ? "Refresh mesh of " : "Set up FE for ") + input.source_name;
  awaiting_title_ = job_title_;
  status_ = (refresh_mesh ? "meshing '" : "meshing '") + input.source_name + "' (" +
            (input.settings.mesher == "cgal" ? "CGAL" : "TetGen") + ")...";
  std::weak_ptr<int> alive = alive_;
  const int generation = model->generation();
  jobs_->Start(job_title_,
               [this, model, input, refresh_mesh, mesh, generation,
                alive](JobContext& ctx) -> Job::Finisher {
                 ctx.SetPhase(input.kind == FeSourceKind::kSolid && input.settings.mesher == "cgal"
                                  ? "CGAL Mesh_3"
                                  : "surface and TetGen");
                 auto result = std::make_shared<FeMeshResult>(
                     MeshFeSource(input, ctx.cancel_flag(), ctx.ProgressRange(0.0, 1.0)));
                 return [this, model, input, refresh_mesh, mesh, generation, result, alive] {
                   if (!alive.lock()) return;
                   awaiting_title_.clear();
                   if (model->generation() != generation) {  // another document: drop it
                     precompute_on_bind_ = false;
                     return;
                   }
                   if (result->slabs) {  // for SlabsOf, before the command lands (Rebind)
                     slab_meshes_.push_back(result->slabs);
                     if (slab_meshes_.size() > kKeptModels + 1)
                       slab_meshes_.erase(slab_meshes_.begin());
                   }
                   std::unique_ptr<Command> command =
                       refresh_mesh ? RefreshFeMesh(mesh, input, *result) : SetUpFe(input, *result);
                   if (!Execute(model, std::move(command))) {
                     precompute_on_bind_ = false;
                     if (model_) model_->cache().SetPaused(false);  // still the one shown
                     return;  // the source changed meanwhile: status_ says so
                   }
                   char line[200];
                   std::snprintf(line, sizeof line, "%s: %ld tets, %ld nodes",
                                 refresh_mesh ? "refreshed" : "set up",
                                 static_cast<long>(result->volume->tets.cols()),
                                 static_cast<long>(result->volume->nodes.cols()));
                   status_ = line;
                   if (!result->slab_note.empty()) status_ += "; " + result->slab_note;
                   if (!refresh_mesh) chosen_ = input.source;
                 };
               });
}

bool FeMode::EditMaterial(SceneModel* model, const fem::Material& material, bool dragging) {
  if (model == nullptr || bound_ == 0) return false;
  return Execute(model, edit::SetFeMaterial(bound_, material, dragging));
}

bool FeMode::EditFixedBoxes(SceneModel* model, std::vector<Eigen::AlignedBox3d> boxes) {
  if (model == nullptr || bound_ == 0) return false;
  return Execute(model, edit::SetFixedBoxes(bound_, std::move(boxes)));
}

bool FeMode::EditElementOrder(SceneModel* model, int order) {
  if (model == nullptr || bound_ == 0) return false;
  if (!Execute(model, edit::SetElementOrder(bound_, order))) return false;
  // A solid's mesh made for the other order is meshed again for this one (flat faces coarsened
  // for quadratic elements, kept for linear ones): a second undo step. With a job running, the
  // panel offers the Refresh instead.
  if (!MeshFitsOrder(model->document()) && RunningJob() == nullptr && StartRefresh(model)) {
    status_ = order == 2 ? "re-meshing for quadratic elements (flat faces coarser)..."
                         : "re-meshing for linear elements (flat faces finer)...";
  }
  return true;
}

int FeMode::BoundElementOrder(const Document& doc) const {
  const DocObject* fe = doc.Find(bound_);
  const auto* data = fe != nullptr ? std::get_if<FeModelData>(&fe->data) : nullptr;
  return data != nullptr ? data->element_order : model_settings_.order;
}

bool FeMode::MeshFitsOrder(const Document& doc) const {
  const DocObject* mesh = doc.Find(bound_key_.mesh);
  const auto* m = mesh != nullptr ? std::get_if<MeshData>(&mesh->data) : nullptr;
  if (m == nullptr || m->source == 0 || doc.Find(m->source) == nullptr) return true;
  const FeSourceKind kind = ClassifyFeSource(doc, m->source);
  return m->settings.flat_cells == FlatCellsForOrder(kind, m->settings, BoundElementOrder(doc));
}

void FeMode::DrawDocumentPanel(SceneModel* model) {
  const Document& doc = model->document();
  // The objects FE mode can use.
  std::string preview = "(choose)";
  if (const DocObject* c = doc.Find(chosen_)) preview = c->name;
  if (ImGui::BeginCombo("object", preview.c_str())) {
    for (const DocObject& o : doc.objects()) {
      const FeSourceKind kind = KindOf(doc, o.id);
      if (kind == FeSourceKind::kNone) continue;
      const std::string label =
          o.name + "  (" + FeSourceKindText(kind) + ")##" + std::to_string(o.id);
      if (ImGui::Selectable(label.c_str(), o.id == chosen_)) chosen_ = o.id;
    }
    ImGui::EndCombo();
  }
  const FeSourceKind kind = KindOf(doc, chosen_);
  const bool busy = RunningJob() != nullptr;
  if (bound_ == 0 && kind != FeSourceKind::kNone) {
    const DocObject& source = doc.Get(chosen_);
    if (kind == FeSourceKind::kSolid) {
      ImGui::TextUnformatted("Mesher");
      ImGui::SameLine();
      const bool cgal = mesh_settings_.mesher == "cgal";
      if (ImGui::RadioButton("TetGen", !cgal)) mesh_settings_.mesher = "tetgen";
      ImGui::SameLine();
      if (ImGui::RadioButton("CGAL", cgal)) {
        mesh_settings_.mesher = "cgal";
        mesh_settings_.sharp_edges = false;
        mesh_settings_.surface_mesher.clear();
      }
      if (!cgal) {
        ImGui::Checkbox("sharp edges", &mesh_settings_.sharp_edges);
        ImGui::SameLine();
        bool lattice = mesh_settings_.surface_mesher == "lattice";
        if (ImGui::Checkbox("lattice", &lattice))
          mesh_settings_.surface_mesher = lattice ? "lattice" : "";
        if (ImGui::IsItemHovered())
          ImGui::SetTooltip(
              "Surface by the lattice route: fewer, better-shaped triangles, so fewer tets and "
              "faster edits in slabs; else marching tetrahedra and its clean-up");
      }
      if (!cgal && !mesh_settings_.sharp_edges) {
        ImGui::Checkbox("in slabs (local edits refactor only what they reach)", &mesh_in_slabs_);
      }
      float cell_mm = static_cast<float>(1e3 * mesh_settings_.cell_size);
      if (ImGui::DragFloat("cell [mm] (0: auto)", &cell_mm, 0.2f, 0.0f, 100.0f, "%.1f"))
        mesh_settings_.cell_size = 1e-3 * std::max(0.0f, cell_mm);
    } else if (kind != FeSourceKind::kVolumeMesh) {
      ImGui::TextDisabled("TetGen meshes its closed surface.");
    }
    model_settings_.order = ElementOrderChoice(model_settings_.order, "##setup");
    if (busy) ImGui::BeginDisabled();
    const std::string label = "Set up FE for " + source.name;
    if (ImGui::Button(label.c_str())) {
      MeshSettings saved = mesh_settings_;
      if (kind != FeSourceKind::kSolid) {  // only solids have a mesher choice
        mesh_settings_.mesher.clear();
        mesh_settings_.sharp_edges = false;
        mesh_settings_.surface_mesher.clear();
      }
      StartSetUp(model, chosen_);
      mesh_settings_ = saved;
    }
    if (busy) ImGui::EndDisabled();
  } else if (bound_ == 0 && chosen_ != 0) {
    ImGui::TextDisabled("(its surface is not closed: TetGen cannot fill it)");
  } else if (bound_ != 0) {
    const DocObject& fe = doc.Get(bound_);
    const DocObject* mesh = doc.Find(bound_key_.mesh);
    ImGui::TextDisabled("FE model '%s' on mesh '%s'", fe.name.c_str(),
                        mesh != nullptr ? mesh->name.c_str() : "?");
    if (stale_) {
      const auto& md = std::get<MeshData>(mesh->data);
      const DocObject* src = doc.Find(md.source);
      ImGui::TextColored(ImVec4(0.9f, 0.55f, 0.1f, 1.0f), "stale: %s changed since it was meshed",
                         src != nullptr ? src->name.c_str() : "its source");
      if (busy || src == nullptr) ImGui::BeginDisabled();
      if (ImGui::Button("Refresh")) StartRefresh(model);
      if (busy || src == nullptr) ImGui::EndDisabled();
    }
    if (!stale_ && !MeshFitsOrder(doc)) {
      ImGui::TextColored(ImVec4(0.9f, 0.55f, 0.1f, 1.0f),
                         BoundElementOrder(doc) == 2
                             ? "the mesh was made for linear elements (flat faces fine)"
                             : "the mesh was made for quadratic elements (flat faces coarse)");
      if (busy) ImGui::BeginDisabled();
      if (ImGui::Button("Re-mesh for this order")) StartRefresh(model);
      if (busy) ImGui::EndDisabled();
    }
    ImGui::Checkbox("refresh on edit", &refresh_on_edit_);
    if (const auto slabs = SlabsOf(doc, bound_key_.mesh)) {
      ImGui::SameLine();
      ImGui::TextDisabled("(mesh in %zu slabs)", slabs->slab_tets.size());
    }
  }
  // The over-budget question.
  if (!pending_text_.empty() && !ImGui::IsPopupOpen("Large mesh")) ImGui::OpenPopup("Large mesh");
  if (ImGui::BeginPopupModal("Large mesh", nullptr, ImGuiWindowFlags_AlwaysAutoResize)) {
    ImGui::PushTextWrapPos(ImGui::GetFontSize() * 30.0f);
    ImGui::TextUnformatted(pending_text_.c_str());
    ImGui::PopTextWrapPos();
    if (ImGui::Button("Proceed")) {
      ConfirmSetUp(model, true);
      ImGui::CloseCurrentPopup();
    }
    ImGui::SameLine();
    if (ImGui::Button("Cancel") || pending_text_.empty()) {
      ConfirmSetUp(model, false);
      ImGui::CloseCurrentPopup();
    }
    ImGui::EndPopup();
  }
  ImGui::Separator();
}

void FeMode::DrawSettingsPanel(SceneModel* model) {
  // Bound to a document FE model: every change is a command on it (the mode follows at the
  // next SyncDocument). Otherwise (a mesh given by SetMesh) the settings are the mode's own.
  const bool bound = model != nullptr && bound_ != 0;
  if (model != nullptr && !bound) ImGui::BeginDisabled();
  ImGui::TextUnformatted("Material");
  fem::Material material = model_settings_.material;
  bool material_changed = false, dragging = false;
  for (int i = 0; i < static_cast<int>(std::size(kMaterialPresets)); ++i) {
    if (i > 0) ImGui::SameLine();
    if (ImGui::RadioButton(kMaterialPresets[i].name, preset_ == i)) {
      material = kMaterialPresets[i].material;
      material_changed = true;
    }
  }
  float e_gpa = static_cast<float>(material.youngs_modulus * 1e-9);
  if (ImGui::DragFloat("E [GPa]", &e_gpa, 0.5f, 0.001f, 1000.0f, "%.3f")) {
    material.youngs_modulus = std::max(1e-3f, e_gpa) * 1e9;
    material_changed = dragging = true;
  }
  const bool e_released = ImGui::IsItemDeactivatedAfterEdit();
  float nu = static_cast<float>(material.poisson_ratio);
  if (ImGui::DragFloat("nu", &nu, 0.005f, 0.0f, 0.49f, "%.3f")) {
    material.poisson_ratio = std::clamp(nu, 0.0f, 0.49f);
    material_changed = dragging = true;
  }
  const bool nu_released = ImGui::IsItemDeactivatedAfterEdit();
  if (material_changed) {
    if (bound) {
      EditMaterial(model, material, dragging);
    } else {
      model_settings_.material = material;
      preset_ = -1;
      for (int i = 0; i < static_cast<int>(std::size(kMaterialPresets)); ++i)
        if (kMaterialPresets[i].material.youngs_modulus == material.youngs_modulus &&
            kMaterialPresets[i].material.poisson_ratio == material.poisson_ratio)
          preset_ = i;
    }
  }
  if (bound && (e_released || nu_released)) model->document().EndDrag();

  ImGui::TextUnformatted("Fixed region");
  bool boxes_changed = false;
  if (ImGui::RadioButton("minimum-x face (wall)", !box_fixed_) && box_fixed_) {
    box_fixed_ = false;
    boxes_changed = true;
  }
  ImGui::SameLine();
  if (ImGui::RadioButton("box", box_fixed_) && !box_fixed_) {
    box_fixed_ = true;
    boxes_changed = true;
  }
  if (box_fixed_) {
    ImGui::InputFloat3("min [m]", box_);
    boxes_changed |= ImGui::IsItemDeactivatedAfterEdit();
    ImGui::InputFloat3("max [m]", box_ + 3);
    boxes_changed |= ImGui::IsItemDeactivatedAfterEdit();
  }
  if (boxes_changed) {
    std::vector<Eigen::AlignedBox3d> boxes;
    if (box_fixed_)
      boxes.emplace_back(Eigen::Vector3d(box_[0], box_[1], box_[2]),
                         Eigen::Vector3d(box_[3], box_[4], box_[5]));
    if (bound) {
      EditFixedBoxes(model, std::move(boxes));
    } else {
      model_settings_.fixed_boxes = std::move(boxes);
    }
  }
  const int order = ElementOrderChoice(model_settings_.order, "");
  if (order != model_settings_.order) {
    if (bound) {
      EditElementOrder(model, order);
    } else {
      model_settings_.order = order;
    }
  }
  if (model != nullptr && !bound) ImGui::EndDisabled();
}

std::string FormatFeSummary(const FeMode& mode, const haptics::ToolState& tool) {
  const FeLiveFigures& f = mode.figures();
  char text[512];
  std::snprintf(text, sizeof text,
                "fe: %s; columns ready %d; contacts %d (substituted %d); FE force on tool "
                "(%.4g, %.4g, %.4g) N; max displacement %.3g mm; max von Mises %.3g MPa\n"
                "fe tool: p_WT (%.4f, %.4f, %.4f) m; commanded force D (%.3f, %.3f, %.3f) N\n",
                mode.status().c_str(), f.ready_columns, f.contacts, f.substituted, f.f_tool_W.x(),
                f.f_tool_W.y(), f.f_tool_W.z(), 1e3 * f.max_displacement, 1e-6 * f.max_von_mises,
                tool.tool_W.p_WT.x(), tool.tool_W.p_WT.y(), tool.tool_W.p_WT.z(), tool.wrench_D(0),
                tool.wrench_D(1), tool.wrench_D(2));
  return text;
}

}  // namespace spidarcad::app
