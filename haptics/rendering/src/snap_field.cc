// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#include "spidarcad/haptics/snap_field.h"

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <string>

namespace spidarcad::haptics {

namespace {
void Require(bool ok, const std::string& what) {
  if (!ok) throw std::invalid_argument(what);
}
bool PositiveFinite(double v) { return v > 0 && std::isfinite(v); }

Eigen::Vector3d ClosestOnSegment(const Eigen::Vector3d& a, const Eigen::Vector3d& b,
                                 const Eigen::Vector3d& x) {
  const Eigen::Vector3d ab = b - a;
  const double t = std::clamp(ab.dot(x - a) / ab.squaredNorm(), 0.0, 1.0);
  return a + t * ab;
}
Eigen::Vector2d ClosestOnSegment2(const Eigen::Vector2d& a, const Eigen::Vector2d& b,
                                  const Eigen::Vector2d& x) {
  const Eigen::Vector2d ab = b - a;
  const double t = std::clamp(ab.dot(x - a) / ab.squaredNorm(), 0.0, 1.0);
  return a + t * ab;
}

// One layer's accumulation: sum of pulls, largest weight, nearest captured feature.
struct Layer {
  Eigen::Vector3d force = Eigen::Vector3d::Zero();
  double weight = 0.0;
  double nearest = std::numeric_limits<double>::infinity();
  int index = -1;
  void Add(const Eigen::Vector3d& x, const Eigen::Vector3d& c, double r, double max_force, int i) {
    const Eigen::Vector3d delta = c - x;
    const double d = delta.norm();
    if (!(d < r)) return;
    if (d < nearest) {
      nearest = d;
      index = i;
    }
    weight = std::max(weight, SnapField::Weight(d, r));
    if (d > 0) force += (SnapField::Pull(d, r, max_force) / d) * delta;
  }
};
}  // namespace

void SnapSettings::Validate() const {
  Require(max_force >= 0 && std::isfinite(max_force),
          "SnapSettings.max_force = " + std::to_string(max_force) + ": must be finite and >= 0");
  Require(
      PositiveFinite(vertex_radius),
      "SnapSettings.vertex_radius = " + std::to_string(vertex_radius) + ": must be finite and > 0");
  Require(PositiveFinite(edge_radius),
          "SnapSettings.edge_radius = " + std::to_string(edge_radius) + ": must be finite and > 0");
  Require(PositiveFinite(face_radius),
          "SnapSettings.face_radius = " + std::to_string(face_radius) + ": must be finite and > 0");
  Require(tip_T.allFinite(), "SnapSettings.tip_T: must be finite");
}

double SnapField::Weight(double d, double r) noexcept {
  const double u = std::clamp((d - 0.5 * r) / (0.5 * r), 0.0, 1.0);
  return 1.0 - u * u * (3.0 - 2.0 * u);
}

double SnapField::Pull(double d, double r, double max_force) noexcept {
  if (!(d < r) || !(d > 0)) return 0.0;
  return max_force * std::tanh(4.0 * d / r) * Weight(d, r);
}

SnapField::SnapField(const SnapFeatures& features, const SnapSettings& settings)
    : settings_(settings), vertices_(features.vertices_W), edges_(features.edges_W) {
  settings_.Validate();
  for (std::size_t i = 0; i < vertices_.size(); ++i) {
    Require(vertices_[i].allFinite(), "SnapField: vertex " + std::to_string(i) + " is not finite");
  }
  for (std::size_t i = 0; i < edges_.size(); ++i) {
    Require(edges_[i].first.allFinite() && edges_[i].second.allFinite(),
            "SnapField: edge " + std::to_string(i) + " is not finite");
    Require((edges_[i].second - edges_[i].first).norm() > 0,
            "SnapField: edge " + std::to_string(i) + " has zero length");
  }
  for (std::size_t i = 0; i < features.faces_W.size(); ++i) {
    const SnapFace& in = features.faces_W[i];
    const std::string name = "SnapField: face " + std::to_string(i);
    Face face;
    if (in.polygon_W.empty()) {
      const double n = in.normal_W.norm();
      Require(in.point_W.allFinite() && n > 0 && std::isfinite(n),
              name + ": point or normal not finite, or zero normal");
      face.origin = in.point_W;
      face.normal = in.normal_W / n;
    } else {
      Require(in.polygon_W.size() >= 3, name + ": a polygon needs at least 3 vertices, has " +
                                            std::to_string(in.polygon_W.size()));
      Eigen::Vector3d normal = Eigen::Vector3d::Zero();  // Newell's method
      double size = 0;
      for (std::size_t k = 0; k < in.polygon_W.size(); ++k) {
        const Eigen::Vector3d& a = in.polygon_W[k];
        const Eigen::Vector3d& b = in.polygon_W[(k + 1) % in.polygon_W.size()];
        Require(a.allFinite(), name + ": vertex " + std::to_string(k) + " is not finite");
        normal += a.cross(b);
        size = std::max(size, (b - a).norm());
      }
      Require(normal.norm() > 0, name + ": the polygon has zero area");
      face.normal = normal.normalized();
      face.origin = in.polygon_W[0];
      for (std::size_t k = 0; k < in.polygon_W.size(); ++k) {
        Require(std::abs(face.normal.dot(in.polygon_W[k] - face.origin)) <= 1e-6 * size,
                name + ": vertex " + std::to_string(k) + " is off the polygon's plane");
      }
    }
    face.u = face.normal.unitOrthogonal();
    face.v = face.normal.cross(face.u);
    face.first = static_cast<int>(poly2d_.size());
    face.count = static_cast<int>(in.polygon_W.size());
    for (const Eigen::Vector3d& p : in.polygon_W) {
      poly2d_.emplace_back(face.u.dot(p - face.origin), face.v.dot(p - face.origin));
    }
    faces_.push_back(face);
  }
}

Eigen::Vector3d SnapField::ClosestOnFace(int f, const Eigen::Vector3d& x) const noexcept {
  const Face& face = faces_[f];
  const Eigen::Vector3d rel = x - face.origin;
  const Eigen::Vector2d q(face.u.dot(rel), face.v.dot(rel));
  Eigen::Vector2d c = q;
  if (face.count > 0) {
    // Inside test by crossings (even-odd), else the nearest boundary point.
    bool inside = false;
    double best = std::numeric_limits<double>::infinity();
    Eigen::Vector2d nearest = q;
    for (int k = 0; k < face.count; ++k) {
      const Eigen::Vector2d& a = poly2d_[face.first + k];
      const Eigen::Vector2d& b = poly2d_[face.first + (k + 1) % face.count];
      if ((a.y() > q.y()) != (b.y() > q.y())) {
        const double x_cross = a.x() + (q.y() - a.y()) * (b.x() - a.x()) / (b.y() - a.y());
        if (q.x() < x_cross) inside = !inside;
      }
      const Eigen::Vector2d p = ClosestOnSegment2(a, b, q);
      const double d = (p - q).squaredNorm();
      if (d < best) {
        best = d;
        nearest = p;
      }
    }
    if (!inside) c = nearest;
  }
  return face.origin + c.x() * face.u + c.y() * face.v;
}

ToolWrench SnapField::Evaluate(const ToolKinematics& tool) noexcept {
  const SnapSettings& s = settings_;
  const Eigen::Vector3d r_tip = tool.R_WT * s.tip_T;
  const Eigen::Vector3d x = tool.p_WT + r_tip;
  Layer vertex, edge, face;
  for (int i = 0; i < static_cast<int>(vertices_.size()); ++i) {
    vertex.Add(x, vertices_[i], s.vertex_radius, s.max_force, i);
  }
  for (int i = 0; i < static_cast<int>(edges_.size()); ++i) {
    edge.Add(x, ClosestOnSegment(edges_[i].first, edges_[i].second, x), s.edge_radius, s.max_force,
             i);
  }
  for (int i = 0; i < static_cast<int>(faces_.size()); ++i) {
    face.Add(x, ClosestOnFace(i, x), s.face_radius, s.max_force, i);
  }
  ToolWrench w;
  w.f_T_W = vertex.force + (1.0 - vertex.weight) * (edge.force + (1.0 - edge.weight) * face.force);
  w.m_T_W = r_tip.cross(w.f_T_W);
  SnapTarget target;
  if (vertex.index >= 0) {
    target = {SnapKind::kVertex, vertex.index};
  } else if (edge.index >= 0) {
    target = {SnapKind::kEdge, edge.index};
  } else if (face.index >= 0) {
    target = {SnapKind::kFace, face.index};
  }
  snapped_.store(
      static_cast<std::int64_t>(target.kind) | (static_cast<std::int64_t>(target.index + 1) << 8),
      std::memory_order_release);
  return w;
}

SnapTarget SnapField::snapped() const noexcept {
  const std::int64_t packed = snapped_.load(std::memory_order_acquire);
  SnapTarget t;
  t.kind = static_cast<SnapKind>(packed & 0xff);
  t.index = static_cast<int>(packed >> 8) - 1;
  return t;
}

}  // namespace spidarcad::haptics
