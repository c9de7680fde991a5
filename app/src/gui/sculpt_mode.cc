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
#include <numbers>
#include <utility>

#include "doc/assets.h"
#include "doc/job.h"
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
  scene_path_ = AssetPath("scenes/clay.json");
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
    if (!session_.has_mesh() && !mesh_requested_ && jobs_) {
      session_.StartMeshScene(jobs_, scene_path_, mesh_cell_);
      mesh_requested_ = true;
    }
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
  const double inv = 1.0 / X_WD_.world_scale;
  const Eigen::Vector3d& o = X_WD.p_WDo;
  vtk_->actor->SetScale(inv, inv, inv);
  vtk_->actor->SetPosition(-inv * o.x(), -inv * o.y(), -inv * o.z());
}

void SculptMode::SetScenePath(const std::string& path) {
  scene_path_ = path;
  mesh_requested_ = false;
}

void SculptMode::LoadMesh(const modeling::TriangleMesh& mesh) {
  session_.SetMesh(mesh);
  mesh_requested_ = true;
  Rebuild();
}

void SculptMode::Rebuild() {
  Vtk& v = *vtk_;
  const modeling::SculptMesh* mesh = session_.mesh();
  shown_revision_ = session_.revision();
  if (!mesh) return;
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
    last_event_ = session_.Step(tool.tool_W, key_held);
  } catch (const std::exception& e) {
    message_ = e.what();
    last_event_ = SculptFrameEvent::kIdle;
  }
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

void SculptMode::DrawPanel() {
  // Meshes may land from Jobs between frames.
  if (session_.revision() != shown_revision_) Rebuild();
  SculptModeSettings& s = session_.settings();
  const modeling::SculptMesh* mesh = session_.mesh();
  if (mesh) {
    ImGui::Text("Clay: %d vertices, %d triangles, volume %.1f cm^3", mesh->vertex_count(),
                mesh->triangle_count(), mesh->volume() * 1e6);
  } else {
    ImGui::TextUnformatted(mesh_requested_ ? "Clay: meshing..." : "Clay: none");
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

  ImGui::BeginDisabled(!session_.CanUndo());
  if (ImGui::Button("Undo stroke")) session_.Undo();
  ImGui::EndDisabled();
  ImGui::SameLine();
  ImGui::BeginDisabled(!session_.CanRedo());
  if (ImGui::Button("Redo stroke")) session_.Redo();
  ImGui::EndDisabled();
  ImGui::SameLine();
  ImGui::Text("%d / %d", session_.undo_count(), session_.redo_count());

  ImGui::Separator();
  char path[512];
  std::snprintf(path, sizeof(path), "%s", scene_path_.c_str());
  if (ImGui::InputText("clay scene", path, sizeof(path))) scene_path_ = path;
  float cell_mm = static_cast<float>(mesh_cell_ * 1e3);
  if (ImGui::SliderFloat("mesh cell [mm]", &cell_mm, 0.5f, 5.0f, "%.2f"))
    mesh_cell_ = cell_mm * 1e-3;
  const bool busy = jobs_ && jobs_->busy();
  ImGui::BeginDisabled(busy || session_.stroke_active() || !jobs_);
  if (ImGui::Button("Mesh clay from scene")) {
    session_.StartMeshScene(jobs_, scene_path_, mesh_cell_);
    mesh_requested_ = true;
  }
  ImGui::EndDisabled();

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
