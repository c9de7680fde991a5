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

namespace spidarcad::app {

FeMode::FeMode(vtkRenderer* renderer, JobQueue* jobs)
    : renderer_(renderer), jobs_(jobs), channel_(std::make_shared<FeContactChannel>()) {
  touch_settings_.tool_radius = 0.0;  // auto: the mesh's mean edge length
  touch_settings_.force_scale = std::pow(10.0, log_force_scale_);
  touch_settings_.max_force = 8.0;
  touch_settings_.coupling_stiffness = kDefaultFeCoupling;
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

void FeMode::SetMesh(fem::TetMesh mesh, std::string name) {
  mesh_ = std::make_shared<const fem::TetMesh>(std::move(mesh));
  mesh_name_ = std::move(name);
  model_.reset();
  pending_field_.reset();
  actor_->VisibilityOff();
  legend_->VisibilityOff();
  sphere_actor_->VisibilityOff();
  status_ = mesh_name_ + ": " + std::to_string(mesh_->num_elements()) + " tets, " +
            std::to_string(mesh_->num_nodes()) + " nodes; press Precompute";
}

void FeMode::MeshPlatform(double resolution) {
  if (jobs_ == nullptr) return;
  status_ = "meshing the platform...";
  std::weak_ptr<int> alive = alive_;
  awaiting_title_ = "Mesh platform (FE)";
  jobs_->Start(awaiting_title_, [this, resolution, alive](JobContext& ctx) -> Job::Finisher {
    ctx.SetPhase("surface and TetGen");
    auto mesh = std::make_shared<fem::TetMesh>(MeshSceneSolidForFe(
        PlatformScenePath(), "platform", resolution, ctx.cancel_flag(), ctx.ProgressRange(0, 1)));
    return [this, mesh, alive] {
      if (!alive.lock()) return;
      awaiting_title_.clear();
      SetMesh(std::move(*mesh), "platform");
    };
  });
}

void FeMode::Precompute() {
  if (jobs_ == nullptr || !mesh_ || RunningJob() != nullptr) return;
  FeModelSettings settings = model_settings_;
  settings.fixed_boxes.clear();
  if (box_fixed_)
    settings.fixed_boxes.emplace_back(Eigen::Vector3d(box_[0], box_[1], box_[2]),
                                      Eigen::Vector3d(box_[3], box_[4], box_[5]));
  std::shared_ptr<const fem::TetMesh> mesh = mesh_;
  job_title_ = "FE precompute " + mesh_name_;
  awaiting_title_ = job_title_;
  status_ = "precomputing...";
  std::weak_ptr<int> alive = alive_;
  jobs_->Start(job_title_, [this, settings, mesh, alive](JobContext& ctx) mutable -> Job::Finisher {
    settings.cancel = ctx.cancel_flag();
    settings.progress = ctx.ProgressRange(0.0, 1.0);
    settings.phase = [&ctx](const std::string& p) { ctx.SetPhase(p); };
    std::shared_ptr<FeModel> model = FeModel::Build(*mesh, settings);
    settings.progress = nullptr;
    settings.phase = nullptr;
    return [this, model, mesh, alive] {
      if (!alive.lock()) return;
      awaiting_title_.clear();
      if (mesh != mesh_) return;  // part changed: drop the result
      model_ = model;
      char line[160];
      std::snprintf(line, sizeof line,
                    "ready: %d nodes clamped, %zu surface nodes, %d columns from disk, %.1f s",
                    model_->num_fixed_nodes(), model_->surface().nodes.size(),
                    model_->imported_nodes(), model_->build_seconds());
      status_ = line;
      BuildSurfaceActor();
      const bool show = active_;
      actor_->SetVisibility(show);
      legend_->SetVisibility(show);
      sphere_actor_->SetVisibility(show);
      if (active_) QueueField();
    };
  });
}

Job* FeMode::RunningJob() const {
  if (jobs_ == nullptr) return nullptr;
  for (const auto& job : jobs_->jobs())
    if (job->title() == job_title_ && job->state() == Job::State::kRunning) return job.get();
  return nullptr;
}

void FeMode::QueueField() {
  if (!model_) return;
  FeTouchSettings ts = FieldTouchSettings(touch_settings_, X_WD_.world_scale);
  if (!(ts.tool_radius > 0.0)) ts.tool_radius = model_->mean_edge_length();
  sphere_source_->SetRadius(ts.tool_radius);
  pending_field_ = std::make_unique<FeTouchField>(model_, ts, channel_);
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
  ContactDisplacement(&model_->cache(), last_state_, &u_out);
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
  figures_.f_tool_W = last_state_.f_tool_W;
  figures_.contacts = last_state_.num_contacts;
  figures_.substituted = last_state_.num_substituted;
  figures_.max_displacement = max_u;
  figures_.max_von_mises = max_vm;
  magnify_shown_ = magnify_;
}

void FeMode::OnFrame(const haptics::ToolState& tool) {
  if (!model_) return;
  figures_.ready_columns = model_->cache().ready_nodes();
  const Eigen::Vector3d& p = tool.tool_W.p_WT;
  sphere_actor_->SetVisibility(active_);
  sphere_source_->SetCenter(p.x(), p.y(), p.z());
  if (!active_) return;
  const bool fresh = channel_->buffer.Update();
  if (fresh || magnify_shown_ != magnify_)
    UpdateSurface(fresh ? &channel_->buffer.Read() : nullptr);
  sphere_actor_->GetProperty()->SetColor(figures_.contacts > 0 ? 0.95 : 0.2,
                                         figures_.contacts > 0 ? 0.5 : 0.8, 0.2);
}

void FeMode::DrawPanel() {
  ImGui::TextWrapped("%s", status_.c_str());
  if (ImGui::Button("Mesh the platform")) MeshPlatform(1e-3 * resolution_mm_);
  ImGui::SameLine();
  ImGui::SetNextItemWidth(90);
  ImGui::DragFloat("cell [mm]", &resolution_mm_, 0.2f, 3.0f, 30.0f, "%.1f");

  ImGui::Separator();
  ImGui::TextUnformatted("Material");
  for (int i = 0; i < static_cast<int>(std::size(kMaterialPresets)); ++i) {
    if (i > 0) ImGui::SameLine();
    if (ImGui::RadioButton(kMaterialPresets[i].name, preset_ == i)) {
      preset_ = i;
      model_settings_.material = kMaterialPresets[i].material;
    }
  }
  float e_gpa = static_cast<float>(model_settings_.material.youngs_modulus * 1e-9);
  if (ImGui::DragFloat("E [GPa]", &e_gpa, 0.5f, 0.001f, 1000.0f, "%.3f")) {
    model_settings_.material.youngs_modulus = std::max(1e-3f, e_gpa) * 1e9;
    preset_ = -1;
  }
  float nu = static_cast<float>(model_settings_.material.poisson_ratio);
  if (ImGui::DragFloat("nu", &nu, 0.005f, 0.0f, 0.49f, "%.3f")) {
    model_settings_.material.poisson_ratio = std::clamp(nu, 0.0f, 0.49f);
    preset_ = -1;
  }
  ImGui::TextUnformatted("Fixed region");
  if (ImGui::RadioButton("minimum-x face (wall)", !box_fixed_)) box_fixed_ = false;
  ImGui::SameLine();
  if (ImGui::RadioButton("box", box_fixed_)) box_fixed_ = true;
  if (box_fixed_) {
    ImGui::InputFloat3("min [m]", box_);
    ImGui::InputFloat3("max [m]", box_ + 3);
  }
  int order = model_settings_.order;
  ImGui::TextUnformatted("Elements");
  ImGui::SameLine();
  if (ImGui::RadioButton("linear", order == 1)) model_settings_.order = 1;
  ImGui::SameLine();
  if (ImGui::RadioButton("quadratic", order == 2)) model_settings_.order = 2;

  Job* running = RunningJob();
  if (running != nullptr) {
    ImGui::ProgressBar(static_cast<float>(running->progress()), ImVec2(-90, 0),
                       running->phase().c_str());
    ImGui::SameLine();
    if (ImGui::Button("Cancel")) running->Cancel();
  } else {
    if (!mesh_) ImGui::BeginDisabled();
    if (ImGui::Button("Precompute")) Precompute();
    if (!mesh_) ImGui::EndDisabled();
  }

  ImGui::Separator();
  ImGui::TextUnformatted("Touch");
  bool changed = false;
  float radius_mm = static_cast<float>(1e3 * touch_settings_.tool_radius);
  if (ImGui::DragFloat("tool radius [mm] (0: auto)", &radius_mm, 0.1f, 0.0f, 100.0f, "%.1f")) {
    touch_settings_.tool_radius = 1e-3 * std::max(0.0f, radius_mm);
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
    ImGui::Text("max displacement: %.4f mm", 1e3 * figures_.max_displacement);
    ImGui::Text("max von Mises: %.3f MPa", 1e-6 * figures_.max_von_mises);
    ImGui::Text("columns ready: %d of %d", figures_.ready_columns,
                model_->cache().num_candidates());
  }
}

FeTouchSettings FieldTouchSettings(const FeTouchSettings& panel, double world_scale) {
  FeTouchSettings ts = panel;
  if (world_scale > 0.0) {
    ts.force_scale = panel.force_scale / world_scale;
    ts.coupling_stiffness = panel.coupling_stiffness / world_scale;
  }
  return ts;
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
