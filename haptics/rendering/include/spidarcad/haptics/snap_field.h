// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
// Snap forces (the paper's selection aid): a gentle pull of the tool point toward vertices,
// edges and faces of the scene near it, so the user can select and align by feel.
//
// Each feature i at distance d_i from the tool point x_t (closest point c_i) pulls with
//   F(d) = F_max · tanh(d / d_s) · w(d),   w(d) = 1 − S((d − r/2) / (r/2)) clamped to [0, 1],
// along (c_i − x_t)/d_i, with S(u) = 3u² − 2u³ (smoothstep), r the capture radius of the
// feature's kind and d_s = r/4 the length over which the pull rises (stiffness F_max/d_s at the
// feature). So the force is ≤ F_max, continuous (zero at the feature itself), and falls to zero
// at d = r with zero slope (C¹): it never jolts. Kinds are layered by priority: vertices over
// edges over faces (give vertices the largest radius). With F_k the sum of the pulls of kind k
// and W_k the largest weight w of kind k,
//   f = F_vertex + (1 − W_vertex)·(F_edge + (1 − W_edge)·F_face),
// so inside half a vertex radius only the vertex pulls (the force points at it), and each layer
// fades in as the one above fades out: the total stays continuous.
// The snapped feature is the nearest one of the highest-priority kind within its radius,
// published as an atomic SnapTarget the app can read from any thread.
#pragma once

#include <Eigen/Core>
#include <atomic>
#include <cstdint>
#include <utility>
#include <vector>

#include "spidarcad/haptics/force_field.h"

namespace spidarcad::haptics {

// Kind of a snap feature.
enum class SnapKind : std::int32_t { kNone = 0, kVertex = 1, kEdge = 2, kFace = 3 };

// A snapped feature: its kind and its index within that kind (−1 and kNone when none).
struct SnapTarget {
  SnapKind kind = SnapKind::kNone;
  int index = -1;
};

// A planar face: a bounded polygon, or (when `polygon_W` is empty) the whole plane through
// `point_W` with normal `normal_W`.
struct SnapFace {
  std::vector<Eigen::Vector3d> polygon_W;  // #V ≥ 3 vertices in order, coplanar, m (or empty)
  Eigen::Vector3d point_W = Eigen::Vector3d::Zero();    // unbounded plane: a point on it, m
  Eigen::Vector3d normal_W = Eigen::Vector3d::UnitZ();  // unbounded plane: its normal
};

// The features to snap to, in W (m).
struct SnapFeatures {
  std::vector<Eigen::Vector3d> vertices_W;                           // #V points
  std::vector<std::pair<Eigen::Vector3d, Eigen::Vector3d>> edges_W;  // #E segments (a, b)
  std::vector<SnapFace> faces_W;                                     // #F faces
};

// Parameters of a SnapField.
struct SnapSettings {
  double max_force = 1.0;                           // F_max, N
  double vertex_radius = 8e-3;                      // capture radius of vertices, m
  double edge_radius = 5e-3;                        // capture radius of edges, m
  double face_radius = 3e-3;                        // capture radius of faces, m
  Eigen::Vector3d tip_T = Eigen::Vector3d::Zero();  // tool point offset in T, m
  // Throws std::invalid_argument naming the field and value when out of range.
  void Validate() const;
};

// The snap field (see the file comment). Features are fixed at construction.
class SnapField final : public ForceField {
 public:
  // Throws std::invalid_argument on bad settings or features (non-finite values, degenerate
  // segments, polygons with fewer than 3 vertices or not planar within 1e-6 of their size,
  // zero normals), naming the feature.
  SnapField(const SnapFeatures& features, const SnapSettings& settings = {});
  ToolWrench Evaluate(const ToolKinematics& tool) noexcept override;
  const char* name() const noexcept override { return "snap"; }

  // Any thread: the feature snapped at the latest Evaluate.
  SnapTarget snapped() const noexcept;
  // The pull magnitude F(d) for a feature at distance d with capture radius r (N).
  static double Pull(double d, double r, double max_force) noexcept;
  // The layer weight w(d) for capture radius r, in [0, 1].
  static double Weight(double d, double r) noexcept;
  // Closest point on face f to x (W); real-time safe.
  Eigen::Vector3d ClosestOnFace(int f, const Eigen::Vector3d& x) const noexcept;
  const SnapSettings& settings() const noexcept { return settings_; }

 private:
  struct Face {
    int first = 0, count = 0;  // polygon vertices in 2D (u, v) in poly2d_, 0 if unbounded
    Eigen::Vector3d origin, normal, u, v;  // plane frame
  };
  SnapSettings settings_;
  std::vector<Eigen::Vector3d> vertices_;
  std::vector<std::pair<Eigen::Vector3d, Eigen::Vector3d>> edges_;
  std::vector<Face> faces_;
  std::vector<Eigen::Vector2d> poly2d_;
  std::atomic<std::int64_t> snapped_{0};  // kind in the low 8 bits, index + 1 above
};

}  // namespace spidarcad::haptics
