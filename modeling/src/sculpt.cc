// SculptMesh: adjacency, spatial grid, strokes (deformation fields, volume conservation), force
// model, undo and redo. Refinement and the icosphere are in sculpt_refine.cc.
// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#include "spidarcad/modeling/sculpt.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>
#include <unordered_map>

#include "sculpt_grid.h"

namespace spidarcad::modeling {
namespace {

constexpr double kHalfPi = std::numbers::pi / 2;
// Fraction of the grab force the smooth tool feels (a light drag).
constexpr double kSmoothForceFraction = 0.1;
// Taubin smoothing factors (shrink, then inflate).
constexpr double kTaubinLambda = 0.5;
constexpr double kTaubinMu = -0.53;

double TriangleVolume(const Eigen::Vector3d& a, const Eigen::Vector3d& b,
                      const Eigen::Vector3d& c) {
  return a.dot(b.cross(c)) / 6.0;
}

// Twist angle (rad, in (-π, π]) of rotation R about the unit axis z (swing-twist decomposition).
double TwistAngle(const Eigen::Matrix3d& R, const Eigen::Vector3d& z) {
  const Eigen::Quaterniond q(R);
  double angle = 2.0 * std::atan2(q.vec().dot(z), q.w());
  if (angle > std::numbers::pi) angle -= 2.0 * std::numbers::pi;
  if (angle <= -std::numbers::pi) angle += 2.0 * std::numbers::pi;
  return angle;
}

// Angle-axis vector φ u (rad) of rotation R, |φ| <= π.
Eigen::Vector3d RotationVector(const Eigen::Matrix3d& R) {
  const Eigen::AngleAxisd aa(R);
  return aa.angle() * aa.axis();
}

void ValidateSettings(const SculptToolSettings& s) {
  auto bad = [](const std::string& field, double value, const std::string& why) {
    throw std::invalid_argument("sculpt tool settings: " + field + " = " + std::to_string(value) +
                                ": " + why);
  };
  if (!(s.radius > 0.0) || !std::isfinite(s.radius))
    bad("radius", s.radius, "must be a positive length (m)");
  if (!(s.stiffness > 0.0) || !std::isfinite(s.stiffness))
    bad("stiffness", s.stiffness, "must be positive (N/m)");
  if (!(s.grasp_closed_angle < kHalfPi) || !(s.grasp_closed_angle >= 0.0)) {
    bad("grasp_closed_angle", s.grasp_closed_angle, "must be in [0, pi/2) rad");
  }
  if (s.smooth_iterations < 0 || s.smooth_iterations > 1000) {
    bad("smooth_iterations", s.smooth_iterations, "must be in [0, 1000]");
  }
  if (!(s.max_edge_length >= 0.0) || !std::isfinite(s.max_edge_length)) {
    bad("max_edge_length", s.max_edge_length, "must be >= 0 (m; 0 disables refinement)");
  }
  if (s.max_splits < 0) bad("max_splits", s.max_splits, "must be >= 0");
  switch (s.tool) {
    case SculptTool::kGrab:
    case SculptTool::kTwist:
    case SculptTool::kBend:
    case SculptTool::kPushPull:
    case SculptTool::kSmooth:
      break;
    default:
      bad("tool", static_cast<int>(s.tool), "unknown tool");
  }
}

double Strength(bool grasp_controls, double theta, double closed_angle) {
  return grasp_controls ? SculptGrabStrength(theta, closed_angle) : 1.0;
}

}  // namespace

const char* SculptToolName(SculptTool tool) {
  switch (tool) {
    case SculptTool::kGrab:
      return "grab";
    case SculptTool::kTwist:
      return "twist";
    case SculptTool::kBend:
      return "bend";
    case SculptTool::kPushPull:
      return "push_pull";
    case SculptTool::kSmooth:
      return "smooth";
  }
  return "unknown";
}

double SculptFalloffExponent(double stiffness) {
  return std::clamp(3.0 * std::cbrt(stiffness / kReferenceSculptStiffness), 1.5, 12.0);
}

double SculptFalloffWeight(double r, double radius, double exponent) {
  if (!(r < radius)) return 0.0;
  const double q = r / radius;
  return std::pow(1.0 - q * q, exponent);
}

double SculptGrabStrength(double theta, double closed_angle) {
  if (!std::isfinite(theta)) return 0.0;
  return std::clamp((kHalfPi - theta) / (kHalfPi - closed_angle), 0.0, 1.0);
}

SculptWrench ComputeStrokeWrench(const StrokeForceModel& model, const Eigen::Isometry3d& X_WT,
                                 double theta) noexcept {
  return ComputeStrokeWrenchAtStrength(
      model, X_WT, Strength(model.grasp_controls_strength, theta, model.grasp_closed_angle));
}

SculptWrench ComputeStrokeWrenchAtStrength(const StrokeForceModel& model,
                                           const Eigen::Isometry3d& X_WT, double s) noexcept {
  SculptWrench wrench;
  if (!model.active || !std::isfinite(s)) return wrench;
  s = std::clamp(s, 0.0, 1.0);
  const double k = model.stiffness;
  const double k_rot = k * model.radius * model.radius;
  const Eigen::Vector3d dp = X_WT.translation() - model.X_WT_start.translation();
  const Eigen::Matrix3d R_rel = X_WT.linear() * model.X_WT_start.linear().transpose();
  switch (model.tool) {
    case SculptTool::kGrab:
      wrench.f_T_W = -k * s * dp;
      break;
    case SculptTool::kPushPull:
      wrench.f_T_W = -k * s * dp.dot(model.normal_W) * model.normal_W;
      break;
    case SculptTool::kSmooth:
      wrench.f_T_W = -kSmoothForceFraction * k * s * dp;
      break;
    case SculptTool::kTwist: {
      const Eigen::Vector3d z = model.X_WT_start.linear().col(2);
      wrench.m_T_W = -k_rot * s * TwistAngle(R_rel, z) * z;
      break;
    }
    case SculptTool::kBend:
      wrench.m_T_W = -k_rot * s * RotationVector(R_rel);
      break;
  }
  if (!wrench.f_T_W.allFinite() || !wrench.m_T_W.allFinite()) return SculptWrench{};
  return wrench;
}

SculptMesh::SculptMesh(const TriangleMesh& mesh, double grid_cell) : grid_cell_(grid_cell) {
  if (!(grid_cell > 0.0) || !std::isfinite(grid_cell)) {
    throw std::invalid_argument("SculptMesh: grid_cell = " + std::to_string(grid_cell) +
                                " must be a positive length (m)");
  }
  const Eigen::Index V = mesh.vertices.cols();
  const Eigen::Index F = mesh.triangles.cols();
  if (V < 4 || F < 4) {
    throw std::invalid_argument(
        "SculptMesh: a closed mesh needs at least 4 vertices and 4 triangles (got " +
        std::to_string(V) + " and " + std::to_string(F) + ")");
  }
  if (!mesh.vertices.allFinite())
    throw std::invalid_argument("SculptMesh: a vertex position is not finite");
  std::vector<std::uint64_t> directed;
  directed.reserve(3 * F);
  for (Eigen::Index t = 0; t < F; ++t) {
    for (int k = 0; k < 3; ++k) {
      const int v = mesh.triangles(k, t);
      if (v < 0 || v >= V) {
        throw std::invalid_argument("SculptMesh: triangle " + std::to_string(t) +
                                    " has vertex index " + std::to_string(v) +
                                    " out of range [0, " + std::to_string(V) + ")");
      }
    }
    for (int k = 0; k < 3; ++k) {
      const std::uint64_t a = static_cast<std::uint32_t>(mesh.triangles(k, t));
      const std::uint64_t b = static_cast<std::uint32_t>(mesh.triangles((k + 1) % 3, t));
      if (a == b)
        throw std::invalid_argument("SculptMesh: triangle " + std::to_string(t) +
                                    " repeats vertex " + std::to_string(a));
      directed.push_back(a << 32 | b);
    }
  }
  std::sort(directed.begin(), directed.end());
  for (size_t i = 0; i < directed.size(); ++i) {
    const std::uint64_t e = directed[i];
    const std::string name = std::to_string(e >> 32) + "->" + std::to_string(e & 0xffffffffu);
    if (i + 1 < directed.size() && directed[i + 1] == e) {
      throw std::invalid_argument(
          "SculptMesh: edge " + name +
          " is used twice in one direction (non-manifold or inconsistently oriented)");
    }
    const std::uint64_t reverse = (e & 0xffffffffu) << 32 | e >> 32;
    if (!std::binary_search(directed.begin(), directed.end(), reverse)) {
      throw std::invalid_argument("SculptMesh: edge " + name +
                                  " has no opposite triangle (the mesh is not closed)");
    }
  }
  positions_.resize(V);
  for (Eigen::Index v = 0; v < V; ++v) positions_[v] = mesh.vertices.col(v);
  triangles_.resize(F);
  vertex_triangles_.resize(V);
  for (Eigen::Index t = 0; t < F; ++t) {
    triangles_[t] = mesh.triangles.col(t);
    for (int k = 0; k < 3; ++k) vertex_triangles_[triangles_[t][k]].push_back(static_cast<int>(t));
  }
  normals_.assign(V, Eigen::Vector3d::Zero());
  for (Eigen::Index v = 0; v < V; ++v) RecomputeNormal(static_cast<int>(v));
  vertex_mark_.assign(V, 0);
  triangle_mark_.assign(F, 0);
  vertex_cell_.resize(V);
  for (Eigen::Index v = 0; v < V; ++v) GridInsert(static_cast<int>(v));
  volume_ = ComputeVolume();
  for (Eigen::Index t = 0; t < F; ++t) BoundEdges(static_cast<int>(t));
}

void SculptMesh::BoundEdges(int t) {
  const Eigen::Vector3i& tri = triangles_[t];
  for (int k = 0; k < 3; ++k) {
    longest_edge_ =
        std::max(longest_edge_, (positions_[tri[(k + 1) % 3]] - positions_[tri[k]]).norm());
  }
}

TriangleMesh SculptMesh::ToTriangleMesh() const {
  TriangleMesh mesh;
  mesh.vertices.resize(3, vertex_count());
  for (int v = 0; v < vertex_count(); ++v) mesh.vertices.col(v) = positions_[v];
  mesh.triangles.resize(3, triangle_count());
  for (int t = 0; t < triangle_count(); ++t) mesh.triangles.col(t) = triangles_[t];
  return mesh;
}

double SculptMesh::ComputeVolume() const {
  double volume = 0.0;
  for (const Eigen::Vector3i& t : triangles_)
    volume += TriangleVolume(positions_[t[0]], positions_[t[1]], positions_[t[2]]);
  return volume;
}

std::uint32_t SculptMesh::NextStamp() const {
  if (++stamp_ == 0) {
    std::fill(vertex_mark_.begin(), vertex_mark_.end(), 0);
    std::fill(triangle_mark_.begin(), triangle_mark_.end(), 0);
    stamp_ = 1;
  }
  return stamp_;
}

SculptMesh::CellKey SculptMesh::KeyOf(const Eigen::Vector3d& p) const {
  return sculpt_grid::Pack(sculpt_grid::CellOf(p.x(), grid_cell_),
                           sculpt_grid::CellOf(p.y(), grid_cell_),
                           sculpt_grid::CellOf(p.z(), grid_cell_));
}

void SculptMesh::GridInsert(int v) {
  const CellKey key = KeyOf(positions_[v]);
  grid_[key].push_back(v);
  vertex_cell_[v] = key;
}

void SculptMesh::GridRemove(int v) {
  const auto it = grid_.find(vertex_cell_[v]);
  if (it == grid_.end()) return;
  std::vector<int>& cell = it->second;
  const auto at = std::find(cell.begin(), cell.end(), v);
  if (at != cell.end()) {
    *at = cell.back();
    cell.pop_back();
  }
  if (cell.empty()) grid_.erase(it);
}

void SculptMesh::VerticesInCellBox(const Eigen::AlignedBox3d& box, std::vector<int>* out) const {
  std::array<std::int64_t, 3> lo, hi;
  double cells = 1.0;
  for (int i = 0; i < 3; ++i) {
    lo[i] = sculpt_grid::CellOf(box.min()[i], grid_cell_);
    hi[i] = sculpt_grid::CellOf(box.max()[i], grid_cell_);
    cells *= static_cast<double>(hi[i] - lo[i] + 1);
  }
  if (cells > static_cast<double>(grid_.size())) {
    // Fewer occupied cells than cells in the box: visit those.
    for (const auto& [key, vertices] : grid_) {
      const auto x = static_cast<std::int64_t>(key >> 42 & sculpt_grid::kCellMask);
      const auto y = static_cast<std::int64_t>(key >> 21 & sculpt_grid::kCellMask);
      const auto z = static_cast<std::int64_t>(key & sculpt_grid::kCellMask);
      if (x < lo[0] || x > hi[0] || y < lo[1] || y > hi[1] || z < lo[2] || z > hi[2]) continue;
      out->insert(out->end(), vertices.begin(), vertices.end());
    }
    return;
  }
  for (std::int64_t x = lo[0]; x <= hi[0]; ++x) {
    for (std::int64_t y = lo[1]; y <= hi[1]; ++y) {
      for (std::int64_t z = lo[2]; z <= hi[2]; ++z) {
        const auto it = grid_.find(sculpt_grid::Pack(x, y, z));
        if (it != grid_.end()) out->insert(out->end(), it->second.begin(), it->second.end());
      }
    }
  }
}

void SculptMesh::QueryBall(const Eigen::Vector3d& centre_W, double radius,
                           std::vector<int>* out) const {
  out->clear();
  VerticesInCellBox(Eigen::AlignedBox3d(centre_W.array() - radius, centre_W.array() + radius), out);
  const double r2 = radius * radius;
  out->erase(
      std::remove_if(out->begin(), out->end(),
                     [&](int v) { return !((positions_[v] - centre_W).squaredNorm() < r2); }),
      out->end());
  std::sort(out->begin(), out->end());
}

void SculptMesh::RecomputeNormal(int v) {
  Eigen::Vector3d n = Eigen::Vector3d::Zero();
  for (int t : vertex_triangles_[v]) {
    const Eigen::Vector3i& tri = triangles_[t];
    n += (positions_[tri[1]] - positions_[tri[0]]).cross(positions_[tri[2]] - positions_[tri[0]]);
  }
  const double norm = n.norm();
  if (norm > 0.0) normals_[v] = n / norm;
}

void SculptMesh::RefreshNormalsAround(const std::vector<int>& vertices) {
  const std::uint32_t stamp = NextStamp();
  for (int v : vertices) {
    for (int t : vertex_triangles_[v]) {
      for (int k = 0; k < 3; ++k) {
        const int u = triangles_[t][k];
        if (vertex_mark_[u] == stamp) continue;
        vertex_mark_[u] = stamp;
        RecomputeNormal(u);
      }
    }
  }
}

void SculptMesh::SetTriangle(int t, const Eigen::Vector3i& tri) {
  for (int k = 0; k < 3; ++k) {
    std::vector<int>& list = vertex_triangles_[triangles_[t][k]];
    const auto at = std::find(list.begin(), list.end(), t);
    if (at != list.end()) list.erase(at);
  }
  triangles_[t] = tri;
  for (int k = 0; k < 3; ++k) vertex_triangles_[tri[k]].push_back(t);
}

int SculptMesh::AddVertex(const Eigen::Vector3d& p) {
  const int v = vertex_count();
  positions_.push_back(p);
  normals_.push_back(Eigen::Vector3d::UnitZ());
  vertex_triangles_.emplace_back();
  vertex_mark_.push_back(0);
  vertex_cell_.push_back(0);
  GridInsert(v);
  return v;
}

int SculptMesh::AddTriangle(const Eigen::Vector3i& tri) {
  const int t = triangle_count();
  triangles_.push_back(tri);
  triangle_mark_.push_back(0);
  for (int k = 0; k < 3; ++k) vertex_triangles_[tri[k]].push_back(t);
  return t;
}

double SculptMesh::AffectedVolume() const {
  double volume = 0.0;
  for (int t : affected_triangles_) {
    const Eigen::Vector3i& tri = triangles_[t];
    volume += TriangleVolume(positions_[tri[0]], positions_[tri[1]], positions_[tri[2]]);
  }
  return volume;
}

void SculptMesh::BeginStroke(const SculptToolSettings& settings, const Eigen::Isometry3d& X_WT,
                             double theta) {
  if (stroke_active_) throw std::logic_error("SculptMesh::BeginStroke: a stroke is already active");
  ValidateSettings(settings);
  if (!X_WT.matrix().allFinite())
    throw std::invalid_argument("SculptMesh::BeginStroke: grip pose is not finite");
  settings_ = settings;
  centre_W_ = X_WT.translation();
  QueryBall(centre_W_, settings.radius, &affected_);
  const size_t n = affected_.size();
  const double exponent = SculptFalloffExponent(settings.stiffness);
  start_positions_.resize(n);
  start_normals_.resize(n);
  weights_.resize(n);
  field_positions_.resize(n);
  Eigen::Vector3d mean_normal = Eigen::Vector3d::Zero();
  for (size_t i = 0; i < n; ++i) {
    const int v = affected_[i];
    start_positions_[i] = positions_[v];
    start_normals_[i] = normals_[v];
    weights_[i] =
        SculptFalloffWeight((positions_[v] - centre_W_).norm(), settings.radius, exponent);
    mean_normal += weights_[i] * normals_[v];
  }
  // Affected triangles (an affected corner) and the vertices whose normals they change.
  affected_triangles_.clear();
  std::uint32_t stamp = NextStamp();
  for (int v : affected_) {
    for (int t : vertex_triangles_[v]) {
      if (triangle_mark_[t] == stamp) continue;
      triangle_mark_[t] = stamp;
      affected_triangles_.push_back(t);
    }
  }
  normal_vertices_.clear();
  for (int t : affected_triangles_) {
    for (int k = 0; k < 3; ++k) {
      const int u = triangles_[t][k];
      if (vertex_mark_[u] == stamp) continue;
      vertex_mark_[u] = stamp;
      normal_vertices_.push_back(u);
    }
  }
  affected_start_volume_ = AffectedVolume();

  // Smooth tool: Taubin smoothing of the region (vertices outside it stay fixed), once.
  smooth_targets_.clear();
  if (settings.tool == SculptTool::kSmooth) {
    std::unordered_map<int, int> local;
    local.reserve(2 * n);
    for (size_t i = 0; i < n; ++i) local.emplace(affected_[i], static_cast<int>(i));
    // Neighbours (each once per incident triangle side: every neighbour of a closed manifold
    // vertex appears twice, so the uniform average is unchanged). -1 - u encodes an outside vertex
    // u.
    std::vector<int> offsets(n + 1, 0), neighbours;
    for (size_t i = 0; i < n; ++i) {
      for (int t : vertex_triangles_[affected_[i]]) {
        for (int k = 0; k < 3; ++k) {
          const int u = triangles_[t][k];
          if (u == affected_[i]) continue;
          const auto it = local.find(u);
          neighbours.push_back(it == local.end() ? -1 - u : it->second);
        }
      }
      offsets[i + 1] = static_cast<int>(neighbours.size());
    }
    std::vector<Eigen::Vector3d> x = start_positions_, next(n);
    for (int iteration = 0; iteration < 2 * settings.smooth_iterations; ++iteration) {
      const double factor = iteration % 2 == 0 ? kTaubinLambda : kTaubinMu;
      for (size_t i = 0; i < n; ++i) {
        Eigen::Vector3d sum = Eigen::Vector3d::Zero();
        for (int j = offsets[i]; j < offsets[i + 1]; ++j) {
          const int u = neighbours[j];
          sum += u >= 0 ? x[u] : positions_[-1 - u];
        }
        const int count = offsets[i + 1] - offsets[i];
        next[i] = count > 0 ? Eigen::Vector3d(x[i] + factor * (sum / count - x[i])) : x[i];
      }
      x.swap(next);
    }
    smooth_targets_ = std::move(x);
  }

  force_model_.active = true;
  force_model_.tool = settings.tool;
  force_model_.stiffness = settings.stiffness;
  force_model_.radius = settings.radius;
  force_model_.grasp_controls_strength = settings.grasp_controls_strength;
  force_model_.grasp_closed_angle = settings.grasp_closed_angle;
  force_model_.X_WT_start = X_WT;
  const double mean_norm = mean_normal.norm();
  force_model_.normal_W = mean_norm > 0.0 ? Eigen::Vector3d(mean_normal / mean_norm)
                                          : Eigen::Vector3d(X_WT.linear().col(2));

  // A region that already intersects itself (an imported mesh, say) would stop every stroke at
  // once: it is not checked.
  check_intersections_ = settings.prevent_self_intersection && !CheckMovedRegion();

  stats_ = StrokeStats{};
  stats_.affected_vertices = static_cast<int>(n);
  stats_.affected_triangles = static_cast<int>(affected_triangles_.size());
  stats_.start_volume = volume_;
  stats_.volume = volume_;
  stroke_active_ = true;
  (void)theta;
}

void SculptMesh::ApplyField(const Eigen::Isometry3d& X_WT, double s) {
  const Eigen::Isometry3d& X_WT0 = force_model_.X_WT_start;
  const Eigen::Vector3d dp = X_WT.translation() - X_WT0.translation();
  const Eigen::Matrix3d R_rel = X_WT.linear() * X_WT0.linear().transpose();
  const size_t n = affected_.size();
  const double R = settings_.radius;
  switch (settings_.tool) {
    case SculptTool::kGrab:
      for (size_t i = 0; i < n; ++i)
        positions_[affected_[i]] = start_positions_[i] + s * weights_[i] * dp;
      break;
    case SculptTool::kTwist: {
      const Eigen::Vector3d z = X_WT0.linear().col(2);
      const double alpha = TwistAngle(R_rel, z);
      for (size_t i = 0; i < n; ++i) {
        positions_[affected_[i]] = centre_W_ + Eigen::AngleAxisd(s * weights_[i] * alpha, z) *
                                                   (start_positions_[i] - centre_W_);
      }
      break;
    }
    case SculptTool::kBend: {
      const Eigen::AngleAxisd aa(R_rel);
      const Eigen::Vector3d x = X_WT0.linear().col(0);
      for (size_t i = 0; i < n; ++i) {
        const Eigen::Vector3d r = start_positions_[i] - centre_W_;
        const double t = std::clamp(r.dot(x) / R, -1.0, 1.0);
        positions_[affected_[i]] =
            centre_W_ + Eigen::AngleAxisd(s * weights_[i] * aa.angle() * t, aa.axis()) * r;
      }
      break;
    }
    case SculptTool::kPushPull: {
      const double h = dp.dot(force_model_.normal_W);
      for (size_t i = 0; i < n; ++i)
        positions_[affected_[i]] = start_positions_[i] + s * weights_[i] * h * start_normals_[i];
      break;
    }
    case SculptTool::kSmooth: {
      const double tau = std::min(1.0, dp.norm() / R);
      for (size_t i = 0; i < n; ++i) {
        positions_[affected_[i]] =
            start_positions_[i] +
            s * weights_[i] * tau * (smooth_targets_[i] - start_positions_[i]);
      }
      break;
    }
  }
}

void SculptMesh::ConserveVolume() {
  // Newton's method on λ: every affected vertex moves by λ c_i n_i (start normal) with the ring
  // weight c_i = 4 w_i (1 - w_i): zero at the grab centre (the grabbed material still follows the
  // grip exactly) and at the rim, largest where w = 1/2. (With c = w the correction would have the
  // push/pull field's own shape and cancel it.) The volume is a cubic in λ;
  // dV/dλ = Σ c_i n_i · ∂V/∂p_i with ∂V/∂p_i = Σ_{t ∋ i} (p_j × p_k) / 6 for triangle (i, j, k)
  // in its cyclic order.
  constexpr int kMaxIterations = 8;
  const double tolerance = 1e-12 * std::abs(volume_) + 1e-30;
  stats_.volume_iterations = 0;
  for (int iteration = 0; iteration < kMaxIterations; ++iteration) {
    const double error = AffectedVolume() - affected_start_volume_;
    if (std::abs(error) <= tolerance) break;
    double slope = 0.0;
    for (size_t i = 0; i < affected_.size(); ++i) {
      const double c = 4.0 * weights_[i] * (1.0 - weights_[i]);
      if (c == 0.0) continue;
      const int v = affected_[i];
      Eigen::Vector3d gradient = Eigen::Vector3d::Zero();
      for (int t : vertex_triangles_[v]) {
        const Eigen::Vector3i& tri = triangles_[t];
        const int k = tri[0] == v ? 0 : (tri[1] == v ? 1 : 2);
        gradient += positions_[tri[(k + 1) % 3]].cross(positions_[tri[(k + 2) % 3]]);
      }
      slope += c * start_normals_[i].dot(gradient) / 6.0;
    }
    if (!(std::abs(slope) > 0.0)) break;
    const double step = -error / slope;
    for (size_t i = 0; i < affected_.size(); ++i) {
      positions_[affected_[i]] +=
          step * 4.0 * weights_[i] * (1.0 - weights_[i]) * start_normals_[i];
    }
    ++stats_.volume_iterations;
  }
}

void SculptMesh::Deform(const Eigen::Isometry3d& X_WT, double s) {
  ApplyField(X_WT, s);
  if (settings_.conserve_volume) ConserveVolume();
}

void SculptMesh::UpdateStroke(const Eigen::Isometry3d& X_WT, double theta) {
  if (!stroke_active_) throw std::logic_error("SculptMesh::UpdateStroke: no active stroke");
  UpdateStrokeAtStrength(
      X_WT, Strength(settings_.grasp_controls_strength, theta, settings_.grasp_closed_angle));
}

void SculptMesh::UpdateStrokeAtStrength(const Eigen::Isometry3d& X_WT, double s) {
  if (!stroke_active_) throw std::logic_error("SculptMesh::UpdateStroke: no active stroke");
  if (!X_WT.matrix().allFinite() || !std::isfinite(s)) return;  // ignore a bad sample
  s = std::clamp(s, 0.0, 1.0);
  Deform(X_WT, s);
  stats_.limit = 1.0;
  stats_.intersection_checks = 0;
  if (check_intersections_ && s > 0.0) {
    ++stats_.intersection_checks;
    if (CheckMovedRegion()) {
      // Bisection on the share of the strength: the start (share 0) does not intersect.
      constexpr int kBisections = 8;  // to 1/256 of the stroke
      double free = 0.0, crossing = 1.0;
      for (int k = 0; k < kBisections; ++k) {
        const double share = 0.5 * (free + crossing);
        Deform(X_WT, share * s);
        ++stats_.intersection_checks;
        (CheckMovedRegion() ? crossing : free) = share;
      }
      Deform(X_WT, free * s);
      stats_.limit = free;
    }
  }
  for (int v : normal_vertices_) RecomputeNormal(v);
  stats_.normal_updates = static_cast<int>(normal_vertices_.size());
  stats_.strength = s;
  stats_.volume = volume_ - affected_start_volume_ + AffectedVolume();
}

SculptEdit SculptMesh::EndStroke() {
  if (!stroke_active_) throw std::logic_error("SculptMesh::EndStroke: no active stroke");
  SculptEdit edit;
  edit.old_volume = volume_;
  for (size_t i = 0; i < affected_.size(); ++i) {
    const int v = affected_[i];
    if (positions_[v] == start_positions_[i]) continue;
    edit.moved.push_back(v);
    edit.old_positions.push_back(start_positions_[i]);
    edit.new_positions.push_back(positions_[v]);
  }
  volume_ = volume_ - affected_start_volume_ + AffectedVolume();
  for (int v : edit.moved) {
    if (KeyOf(positions_[v]) == vertex_cell_[v]) continue;
    GridRemove(v);
    GridInsert(v);
  }
  edit.old_vertex_count = vertex_count();
  edit.old_triangle_count = triangle_count();
  if (settings_.max_edge_length > 0.0) {
    edit.splits =
        Refine(affected_triangles_, settings_.max_edge_length, settings_.max_splits, &edit);
  }
  edit.new_volume = volume_;
  // Moved and refined triangles may have longer edges now.
  for (int t : affected_triangles_) BoundEdges(t);
  for (int t = edit.old_triangle_count; t < triangle_count(); ++t) BoundEdges(t);
  stroke_active_ = false;
  force_model_.active = false;
  return edit;
}

void SculptMesh::CancelStroke() {
  if (!stroke_active_) return;
  for (size_t i = 0; i < affected_.size(); ++i) positions_[affected_[i]] = start_positions_[i];
  for (int v : normal_vertices_) RecomputeNormal(v);
  stroke_active_ = false;
  force_model_.active = false;
}

void SculptMesh::Undo(const SculptEdit& edit) {
  if (stroke_active_) throw std::logic_error("SculptMesh::Undo: a stroke is active");
  const int added_vertices = static_cast<int>(edit.added_positions.size());
  const int added_triangles = static_cast<int>(edit.added_triangles.size());
  if (vertex_count() != edit.old_vertex_count + added_vertices ||
      triangle_count() != edit.old_triangle_count + added_triangles) {
    throw std::logic_error(
        "SculptMesh::Undo: the edit is not the last one applied (counts differ)");
  }
  for (int t = triangle_count() - 1; t >= edit.old_triangle_count; --t) {
    for (int k = 0; k < 3; ++k) {
      std::vector<int>& list = vertex_triangles_[triangles_[t][k]];
      const auto at = std::find(list.begin(), list.end(), t);
      if (at != list.end()) list.erase(at);
    }
    triangles_.pop_back();
  }
  triangle_mark_.resize(triangles_.size());
  for (size_t i = 0; i < edit.rewritten.size(); ++i)
    SetTriangle(edit.rewritten[i], edit.old_triangles[i]);
  for (int v = vertex_count() - 1; v >= edit.old_vertex_count; --v) {
    GridRemove(v);
    positions_.pop_back();
    normals_.pop_back();
    vertex_triangles_.pop_back();
    vertex_cell_.pop_back();
  }
  vertex_mark_.resize(positions_.size());
  for (size_t i = 0; i < edit.moved.size(); ++i) {
    const int v = edit.moved[i];
    positions_[v] = edit.old_positions[i];
    GridRemove(v);
    GridInsert(v);
  }
  std::vector<int> around = edit.moved;
  for (const Eigen::Vector3i& tri : edit.old_triangles)
    around.insert(around.end(), tri.data(), tri.data() + 3);
  RefreshNormalsAround(around);
  volume_ = edit.old_volume;
}

void SculptMesh::Redo(const SculptEdit& edit) {
  if (stroke_active_) throw std::logic_error("SculptMesh::Redo: a stroke is active");
  if (vertex_count() != edit.old_vertex_count || triangle_count() != edit.old_triangle_count) {
    throw std::logic_error(
        "SculptMesh::Redo: the mesh is not in the edit's starting state (counts differ)");
  }
  for (size_t i = 0; i < edit.moved.size(); ++i) {
    const int v = edit.moved[i];
    positions_[v] = edit.new_positions[i];
    GridRemove(v);
    GridInsert(v);
  }
  for (const Eigen::Vector3d& p : edit.added_positions) AddVertex(p);
  for (size_t i = 0; i < edit.rewritten.size(); ++i)
    SetTriangle(edit.rewritten[i], edit.new_triangles[i]);
  for (const Eigen::Vector3i& tri : edit.added_triangles) AddTriangle(tri);
  std::vector<int> around = edit.moved;
  for (int v = edit.old_vertex_count; v < vertex_count(); ++v) around.push_back(v);
  for (const Eigen::Vector3i& tri : edit.new_triangles)
    around.insert(around.end(), tri.data(), tri.data() + 3);
  RefreshNormalsAround(around);
  volume_ = edit.new_volume;
}

}  // namespace spidarcad::modeling
