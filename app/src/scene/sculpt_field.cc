// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#include "scene/sculpt_field.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <ctime>
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

double StrokeStrength(const SculptHapticModel& model, double grasp, double squeeze_strength) {
  if (!model.stroke.grasp_controls_strength) return 1.0;
  if (model.squeeze) return squeeze_strength;
  return std::max(modeling::SculptGrabStrength(grasp, model.stroke.grasp_closed_angle),
                  squeeze_strength);
}

Eigen::Isometry3d ClayPlacement(const modeling::StrokeForceModel& model,
                                const Eigen::Isometry3d& X_WT) {
  if (!model.active) return Eigen::Isometry3d::Identity();
  return X_WT * model.X_WT_start.inverse(Eigen::Isometry);
}

namespace {
// CPU time of the calling thread (s): the grid builds' cost, which the machine's load does not
// inflate as it does their wall time.
double ThreadCpuSeconds() {
  timespec ts{};
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
  return static_cast<double>(ts.tv_sec) + 1e-9 * static_cast<double>(ts.tv_nsec);
}

Eigen::Isometry3d ToolPose(const haptics::ToolKinematics& tool) {
  Eigen::Isometry3d X_WT = Eigen::Isometry3d::Identity();
  X_WT.linear() = tool.R_WT;
  X_WT.translation() = tool.p_WT;
  return X_WT;
}
}  // namespace

SculptToolField::SculptToolField(std::shared_ptr<SculptForceChannel> channel,
                                 std::shared_ptr<ClayGridChannel> clay,
                                 const ClayWidthSettings& settings)
    : channel_(std::move(channel)), clay_(std::move(clay)), settings_(settings) {
  if (!channel_) throw std::invalid_argument("SculptToolField: null force channel");
  if (!clay_) throw std::invalid_argument("SculptToolField: null clay grid channel");
  settings_.Validate();
}

haptics::ToolWrench SculptToolField::Evaluate(const haptics::ToolKinematics& tool) noexcept {
  haptics::ToolWrench out;
  const SculptHapticModel& model = channel_->Latest();
  const ClayDistanceGrid* grid = clay_->Acquire();
  const Eigen::Isometry3d X_WT = ToolPose(tool);
  squeeze_ = ClaySqueeze{};
  if (settings_.enabled && grid != nullptr) {
    squeeze_ = ComputeClaySqueeze(*grid, ClayPlacement(model.stroke, X_WT), tool, settings_);
    out.g = squeeze_.g;
  }
  if (!model.stroke.active) return out;
  const double s = StrokeStrength(model, tool.grasp,
                                  SqueezeStrength(squeeze_.squeeze, settings_.full_squeeze_depth));
  const modeling::SculptWrench w = modeling::ComputeStrokeWrenchAtStrength(model.stroke, X_WT, s);
  out.f_T_W = w.f_T_W;
  out.m_T_W = w.m_T_W;
  out.g += w.grasp_torque;
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
  clay_width.Validate();
}

SculptSession::SculptSession()
    : channel_(std::make_shared<SculptForceChannel>(SculptHapticModel{})),
      clay_channel_(std::make_shared<ClayGridChannel>()),
      alive_(std::make_shared<bool>(true)) {}

SculptSession::~SculptSession() {
  if (build_.valid()) build_.wait();
}

Eigen::AlignedBox3d SculptSession::EditBox(const SculptEdit& edit) {
  Eigen::AlignedBox3d box;
  for (const Eigen::Vector3d& p : edit.old_positions) box.extend(p);
  for (const Eigen::Vector3d& p : edit.new_positions) box.extend(p);
  return box;
}

void SculptSession::RequestGrid(bool whole, const Eigen::AlignedBox3d& changed) {
  if (!mesh_) return;
  if (!whole && changed.isEmpty()) return;  // nothing moved
  if (whole || !grid_) {
    grid_wanted_ = true;
    grid_whole_ = true;
  } else {
    grid_wanted_ = true;
    grid_changed_.extend(changed);
  }
  if (async_grids_) {
    PollGridBuild();
    return;
  }
  // At once (deterministic): the same work as a build on a thread.
  const double start = ThreadCpuSeconds();
  try {
    grid_ = grid_whole_ ? ClayDistanceGrid::Build(mesh_->positions(), mesh_->triangles(),
                                                  settings_.clay_width.grid)
                        : ClayDistanceGrid::Update(*grid_, mesh_->positions(), mesh_->triangles(),
                                                   grid_changed_);
  } catch (const std::invalid_argument& e) {
    grid_.reset();
    job_message_ = std::string("Clay width off: ") + e.what();
  }
  grid_seconds_ = ThreadCpuSeconds() - start;
  grid_nodes_ = grid_ ? grid_->recomputed_nodes() : 0;
  ++grid_builds_;
  grid_wanted_ = false;
  grid_whole_ = false;
  grid_changed_.setEmpty();
  clay_channel_->Offer(grid_);
}

void SculptSession::StartGridBuild() {
  if (build_.valid() || !grid_wanted_ || !mesh_) return;
  // The build works on copies: the clay changes on this thread meanwhile.
  auto positions = std::make_shared<const std::vector<Eigen::Vector3d>>(mesh_->positions());
  auto triangles = std::make_shared<const std::vector<Eigen::Vector3i>>(mesh_->triangles());
  std::shared_ptr<const ClayDistanceGrid> base = grid_whole_ ? nullptr : grid_;
  const Eigen::AlignedBox3d changed = grid_changed_;
  const ClayGridSettings settings = settings_.clay_width.grid;
  grid_wanted_ = false;
  grid_whole_ = false;
  grid_changed_.setEmpty();
  build_generation_ = generation_;
  double* seconds = &build_seconds_;
  build_ =
      std::async(std::launch::async,
                 [positions, triangles, base, changed, settings,
                  seconds]() -> std::shared_ptr<const ClayDistanceGrid> {
                   const double start = ThreadCpuSeconds();
                   std::shared_ptr<const ClayDistanceGrid> grid;
                   try {
                     grid = base ? ClayDistanceGrid::Update(*base, *positions, *triangles, changed)
                                 : ClayDistanceGrid::Build(*positions, *triangles, settings);
                   } catch (const std::exception&) {
                     grid.reset();
                   }
                   *seconds = ThreadCpuSeconds() - start;
                   return grid;
                 });
}

void SculptSession::PollGridBuild() {
  if (build_.valid() && build_.wait_for(std::chrono::seconds(0)) == std::future_status::ready) {
    std::shared_ptr<const ClayDistanceGrid> grid = build_.get();
    if (build_generation_ == generation_) {  // not for a clay since replaced
      grid_ = std::move(grid);
      grid_seconds_ = build_seconds_;
      grid_nodes_ = grid_ ? grid_->recomputed_nodes() : 0;
      ++grid_builds_;
      clay_channel_->Offer(grid_);
    }
  }
  clay_channel_->Collect();
  StartGridBuild();
}

void SculptSession::FinishGridBuild() {
  while (build_.valid() || grid_wanted_) {
    if (build_.valid()) build_.wait();
    PollGridBuild();
    if (!mesh_) break;
  }
}

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
  ++generation_;
  grid_.reset();
  clay_channel_->Offer(nullptr);  // no width until the new clay's grid lands
  grid_changed_.setEmpty();
  RequestGrid(true, grid_changed_);
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
  ++generation_;
  grid_.reset();
  grid_wanted_ = false;
  clay_channel_->Offer(nullptr);
}

void SculptSession::ForgetHistory() {
  undo_.clear();
  redo_.clear();
}

void SculptSession::Publish(const StrokeForceModel& model, bool squeeze) {
  published_.stroke = model;
  published_.squeeze = squeeze && model.active;
  channel_->Write(published_);
}

Eigen::Isometry3d SculptSession::StrokePose(const haptics::ToolKinematics& tool) const {
  Eigen::Isometry3d X = Eigen::Isometry3d::Identity();
  X.linear() = tool.R_WT;
  X.translation() = tool.p_WT + snap_offset_;
  return X;
}

void SculptSession::BeginStroke(const haptics::ToolKinematics& tool, bool key_held,
                                const Eigen::Vector3d* pinch, SculptFrameEvent* event) {
  settings_.Validate();
  if (!tool.p_WT.allFinite() || !tool.R_WT.allFinite() || !std::isfinite(tool.grasp)) {
    *event = SculptFrameEvent::kIdle;
    return;
  }
  if (pinch != nullptr) {
    // A squeeze: the clay between the fingers, if any of it is within the tool radius.
    mesh_->QueryBall(*pinch, settings_.tool.radius, &query_);
    if (query_.empty()) {
      *event = SculptFrameEvent::kNoClayInReach;
      return;
    }
    grab_centre_ = *pinch;
  } else {
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
  }
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
  Publish(model, pinch != nullptr);
  held_strength_ = 0.0;
  UpdateStroke(tool);
  *event = SculptFrameEvent::kBegan;
}

void SculptSession::UpdateStroke(const haptics::ToolKinematics& tool) {
  const double s_now = SqueezeStrength(squeeze_.squeeze, settings_.clay_width.full_squeeze_depth);
  double s = StrokeStrength(published_, tool.grasp, s_now);
  if (published_.squeeze) {
    held_strength_ = std::max(held_strength_, s);
    s = held_strength_;
  }
  stroke_strength_ = s;
  mesh_->UpdateStrokeAtStrength(StrokePose(tool), s);
}

void SculptSession::SenseClay(const haptics::ToolKinematics& tool) {
  squeeze_ = ClaySqueeze{};
  if (!grid_ || !settings_.clay_width.enabled) return;
  Eigen::Isometry3d X_WT = Eigen::Isometry3d::Identity();
  X_WT.linear() = tool.R_WT;
  X_WT.translation() = tool.p_WT;
  squeeze_ = ComputeClaySqueeze(*grid_, ClayPlacement(published_.stroke, X_WT), tool,
                                settings_.clay_width);
}

SculptFrameEvent SculptSession::Step(const haptics::ToolKinematics& tool, bool key_held) {
  if (async_grids_) PollGridBuild();
  if (!mesh_) return SculptFrameEvent::kIdle;
  SenseClay(tool);
  if (!mesh_->stroke_active()) {
    stroke_strength_ = 0.0;
    SculptFrameEvent event = SculptFrameEvent::kIdle;
    if (!key_held && squeeze_.squeeze >= settings_.clay_width.grasp.grab_depth) {
      const Eigen::Vector3d pinch = 0.5 * (squeeze_.contact_W[0] + squeeze_.contact_W[1]);
      BeginStroke(tool, false, &pinch, &event);
      return event;
    }
    if (!(tool.grasp < settings_.stroke_begin_angle || key_held)) return SculptFrameEvent::kIdle;
    BeginStroke(tool, key_held, nullptr, &event);
    return event;
  }
  bool end = false;
  if (key_stroke_) {
    end = !key_held;
  } else if (published_.squeeze) {
    end = !(squeeze_.squeeze > 0.0) && !key_held;  // the fingers let go of the clay
  } else {
    end = !(tool.grasp < settings_.stroke_end_angle) && !key_held;
  }
  if (end) {
    Publish(StrokeForceModel{});
    undo_.push_back(mesh_->EndStroke());
    redo_.clear();
    display_vertices_.clear();
    ++revision_;
    stroke_strength_ = 0.0;
    RequestGrid(false, EditBox(undo_.back()));
    return SculptFrameEvent::kEnded;
  }
  UpdateStroke(tool);
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
  RequestGrid(false, EditBox(redo_.back()));
  return true;
}

bool SculptSession::Redo() {
  if (!CanRedo()) return false;
  mesh_->Redo(redo_.back());
  undo_.push_back(std::move(redo_.back()));
  redo_.pop_back();
  ++revision_;
  RequestGrid(false, EditBox(undo_.back()));
  return true;
}

std::unique_ptr<haptics::ForceField> SculptSession::MakeField() const {
  return std::make_unique<SculptToolField>(channel_, clay_channel_, settings_.clay_width);
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
