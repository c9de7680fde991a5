// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#include "scene/sculpt_field.h"

#include <chrono>
#include <cmath>
#include <limits>
#include <sstream>
#include <stdexcept>
#include <utility>

#include "doc/job.h"
#include "scene/scene_solid.h"
#include "scene/worker_process.h"
#include "spidarcad/modeling/tetgen_mesher.h"

namespace spidarcad::app {

using modeling::SculptEdit;
using modeling::SculptMesh;
using modeling::StrokeForceModel;

SculptToolField::SculptToolField(std::shared_ptr<SculptForceChannel> channel)
    : channel_(std::move(channel)) {
  if (!channel_) throw std::invalid_argument("SculptToolField: null force channel");
}

haptics::ToolWrench SculptToolField::Evaluate(const haptics::ToolKinematics& tool) noexcept {
  haptics::ToolWrench out;
  const StrokeForceModel& model = channel_->Latest();
  if (!model.active) return out;
  Eigen::Isometry3d X_WT = Eigen::Isometry3d::Identity();
  X_WT.linear() = tool.R_WT;
  X_WT.translation() = tool.p_WT;
  const modeling::SculptWrench w = modeling::ComputeStrokeWrench(model, X_WT, tool.grasp);
  out.f_T_W = w.f_T_W;
  out.m_T_W = w.m_T_W;
  out.g = w.grasp_torque;
  return out;
}

void SculptModeSettings::Validate() const {
  auto fail = [](const std::string& field, double value, const std::string& rule) {
    std::ostringstream s;
    s << "sculpt mode setting " << field << " = " << value << ": " << rule;
    throw std::invalid_argument(s.str());
  };
  if (!(tool.radius > 0.0) || !std::isfinite(tool.radius))
    fail("radius", tool.radius, "must be > 0 m");
  if (!(tool.stiffness > 0.0) || !std::isfinite(tool.stiffness))
    fail("stiffness", tool.stiffness, "must be > 0 N/m");
  if (!(tool.max_edge_length >= 0.0))
    fail("max_edge_length", tool.max_edge_length, "must be >= 0 m");
  if (!(stroke_begin_angle > 0.0 && stroke_begin_angle < std::numbers::pi / 2)) {
    fail("stroke_begin_angle", stroke_begin_angle, "must be in (0, pi/2) rad");
  }
  if (!(stroke_end_angle >= stroke_begin_angle && stroke_end_angle <= std::numbers::pi)) {
    fail("stroke_end_angle", stroke_end_angle, "must be in [stroke_begin_angle, pi] rad");
  }
  if (!std::isfinite(snap_distance)) fail("snap_distance", snap_distance, "must be finite");
}

SculptSession::SculptSession()
    : channel_(std::make_shared<SculptForceChannel>(StrokeForceModel{})),
      alive_(std::make_shared<bool>(true)) {}

SculptSession::~SculptSession() = default;

void SculptSession::SetMesh(const modeling::TriangleMesh& mesh, double grid_cell) {
  const double cell = grid_cell > 0.0 ? grid_cell : settings_.tool.radius / 3.0;
  SetMesh(std::make_unique<SculptMesh>(mesh, cell));
}

void SculptSession::SetMesh(std::unique_ptr<SculptMesh> mesh) {
  if (!mesh) throw std::invalid_argument("SculptSession::SetMesh: null mesh");
  if (mesh_ && mesh_->stroke_active()) mesh_->CancelStroke();
  mesh_ = std::move(mesh);
  undo_.clear();
  redo_.clear();
  display_vertices_.clear();
  tet_mesh_.reset();
  Publish(StrokeForceModel{});
  ++revision_;
}

void SculptSession::ClearMesh() {
  if (mesh_ && mesh_->stroke_active()) mesh_->CancelStroke();
  mesh_.reset();
  undo_.clear();
  redo_.clear();
  display_vertices_.clear();
  tet_mesh_.reset();
  Publish(StrokeForceModel{});
  ++revision_;
}

void SculptSession::ForgetHistory() {
  undo_.clear();
  redo_.clear();
}

void SculptSession::Publish(const StrokeForceModel& model) {
  published_ = model;
  channel_->Write(model);
}

Eigen::Isometry3d SculptSession::StrokePose(const haptics::ToolKinematics& tool) const {
  Eigen::Isometry3d X = Eigen::Isometry3d::Identity();
  X.linear() = tool.R_WT;
  X.translation() = tool.p_WT + snap_offset_;
  return X;
}

void SculptSession::BeginStroke(const haptics::ToolKinematics& tool, bool key_held,
                                SculptFrameEvent* event) {
  settings_.Validate();
  if (!tool.p_WT.allFinite() || !tool.R_WT.allFinite() || !std::isfinite(tool.grasp)) {
    *event = SculptFrameEvent::kIdle;
    return;
  }
  const double snap =
      settings_.snap_distance > 0.0 ? settings_.snap_distance : settings_.tool.radius;
  mesh_->QueryBall(tool.p_WT, snap, &query_);
  if (query_.empty()) {
    *event = SculptFrameEvent::kNoClayInReach;
    return;
  }
  int nearest = query_.front();
  double best = std::numeric_limits<double>::infinity();
  for (int v : query_) {
    const double d = (mesh_->positions()[v] - tool.p_WT).squaredNorm();
    if (d < best) {
      best = d;
      nearest = v;
    }
  }
  grab_centre_ = mesh_->positions()[nearest];
  snap_offset_ = grab_centre_ - tool.p_WT;
  modeling::SculptToolSettings tool_settings = settings_.tool;
  if (key_held) tool_settings.grasp_controls_strength = false;
  key_stroke_ = key_held;
  const Eigen::Isometry3d X = StrokePose(tool);
  mesh_->BeginStroke(tool_settings, X, tool.grasp);

  // Display set: the moved vertices and their one-ring (whose normals change too).
  mark_.assign(mesh_->vertex_count(), 0);
  display_vertices_.clear();
  for (int v : mesh_->stroke_vertices()) {
    for (int t : mesh_->VertexTriangles(v)) {
      const Eigen::Vector3i& tri = mesh_->triangles()[t];
      for (int k = 0; k < 3; ++k) {
        if (!mark_[tri[k]]) {
          mark_[tri[k]] = 1;
          display_vertices_.push_back(tri[k]);
        }
      }
    }
  }

  StrokeForceModel model = mesh_->force_model();
  model.X_WT_start.translation() -= snap_offset_;  // the haptic side sees the unshifted grip
  Publish(model);
  mesh_->UpdateStroke(X, tool.grasp);
  *event = SculptFrameEvent::kBegan;
}

SculptFrameEvent SculptSession::Step(const haptics::ToolKinematics& tool, bool key_held) {
  if (!mesh_) return SculptFrameEvent::kIdle;
  if (!mesh_->stroke_active()) {
    if (!(tool.grasp < settings_.stroke_begin_angle || key_held)) return SculptFrameEvent::kIdle;
    SculptFrameEvent event = SculptFrameEvent::kIdle;
    BeginStroke(tool, key_held, &event);
    return event;
  }
  const bool open = !(tool.grasp < settings_.stroke_end_angle);
  const bool end = key_stroke_ ? !key_held : (open && !key_held);
  if (end) {
    Publish(StrokeForceModel{});
    undo_.push_back(mesh_->EndStroke());
    redo_.clear();
    display_vertices_.clear();
    ++revision_;
    return SculptFrameEvent::kEnded;
  }
  mesh_->UpdateStroke(StrokePose(tool), tool.grasp);
  return SculptFrameEvent::kUpdated;
}

double SculptSession::volume() const {
  if (!mesh_) return 0.0;
  return mesh_->stroke_active() ? mesh_->stroke_stats().volume : mesh_->volume();
}

void SculptSession::CancelStroke() {
  if (!stroke_active()) return;
  Publish(StrokeForceModel{});
  mesh_->CancelStroke();
  display_vertices_.clear();
  ++revision_;
}

bool SculptSession::Undo() {
  if (!CanUndo()) return false;
  mesh_->Undo(undo_.back());
  redo_.push_back(std::move(undo_.back()));
  undo_.pop_back();
  ++revision_;
  return true;
}

bool SculptSession::Redo() {
  if (!CanRedo()) return false;
  mesh_->Redo(redo_.back());
  undo_.push_back(std::move(redo_.back()));
  redo_.pop_back();
  ++revision_;
  return true;
}

std::unique_ptr<haptics::ForceField> SculptSession::MakeField() const {
  return std::make_unique<SculptToolField>(channel_);
}

modeling::TriangleMesh SculptSession::ExportMesh() const {
  if (!mesh_) return {};
  return mesh_->ToTriangleMesh();
}

bool SculptSession::StartTetrahedralize(JobQueue* jobs, const modeling::TetMeshSettings& settings) {
  if (!mesh_ || stroke_active()) return false;
  auto surface = std::make_shared<const modeling::TriangleMesh>(ExportMesh());
  std::weak_ptr<bool> alive = alive_;
  jobs->Start(
      "Tetrahedralize clay",
      [this, alive, surface, settings](JobContext& context) -> Job::Finisher {
        try {
          const auto start = std::chrono::steady_clock::now();
          context.SetPhase("checking surface");
          modeling::CheckSurface(*surface);
          context.SetProgress(0.2);
          context.SetPhase("tetrahedra");
          modeling::TetMeshSettings s = settings;
          s.cancel = context.cancel_flag();
          s.progress = context.ProgressRange(0.2, 1.0);
          auto tets = std::make_shared<const modeling::TetMesh>(
              TetrahedralizeCancellable(*surface, s));  // a child process Cancel kills
          const double seconds =
              std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
          std::ostringstream message;
          message << tets->nodes.cols() << " nodes, " << tets->tets.cols() << " tetrahedra in "
                  << seconds << " s";
          return [this, alive, tets, text = message.str()] {
            if (alive.expired()) return;
            tet_mesh_ = tets;
            job_message_ = text;
          };
        } catch (const std::exception& e) {
          if (context.cancelled()) throw;
          // Report on the main thread: the finisher records the message, then fails the job.
          return [this, alive, text = std::string("Tetrahedralize failed: ") + e.what()] {
            if (!alive.expired()) job_message_ = text;
            throw std::runtime_error(text);
          };
        }
      });
  return true;
}

void SculptSession::StartMeshScene(JobQueue* jobs, const std::string& scene_path, double cell) {
  std::weak_ptr<bool> alive = alive_;
  const double grid_cell = settings_.tool.radius / 3.0;
  jobs->Start("Mesh clay",
              [this, alive, scene_path, cell, grid_cell](JobContext& context) -> Job::Finisher {
                try {
                  context.SetPhase("surface");
                  SceneSolidGrid grid = PrepareSceneSolid(scene_path, "", cell);
                  modeling::SurfaceMeshSettings s;
                  s.bounds = grid.bounds;
                  s.cell_size = grid.cell;
                  s.cancel = context.cancel_flag();
                  s.progress = context.ProgressRange(0.0, 0.9);
                  const modeling::TriangleMesh surface = modeling::MeshSurface(grid.compiled, s);
                  context.SetPhase("sculpt grid");
                  auto mesh = std::make_shared<SculptMesh>(surface, grid_cell);
                  return [this, alive, mesh] {
                    if (alive.expired()) return;
                    SetMesh(std::make_unique<SculptMesh>(std::move(*mesh)));
                    std::ostringstream text;
                    text << "clay: " << mesh_->vertex_count() << " vertices, "
                         << mesh_->triangle_count() << " triangles";
                    job_message_ = text.str();
                  };
                } catch (const std::exception& e) {
                  if (context.cancelled()) throw;
                  return [this, alive, text = std::string("Meshing the clay failed: ") + e.what()] {
                    if (!alive.expired()) job_message_ = text;
                    throw std::runtime_error(text);
                  };
                }
              });
}

void CopyVerticesToFloat(const SculptMesh& mesh, const std::vector<int>& vertices, float* xyz,
                         float* nxyz) {
  const auto& p = mesh.positions();
  const auto& n = mesh.normals();
  for (int v : vertices) {
    float* out = xyz + 3 * static_cast<std::size_t>(v);
    out[0] = static_cast<float>(p[v].x());
    out[1] = static_cast<float>(p[v].y());
    out[2] = static_cast<float>(p[v].z());
    if (nxyz) {
      float* m = nxyz + 3 * static_cast<std::size_t>(v);
      m[0] = static_cast<float>(n[v].x());
      m[1] = static_cast<float>(n[v].y());
      m[2] = static_cast<float>(n[v].z());
    }
  }
}

}  // namespace spidarcad::app
