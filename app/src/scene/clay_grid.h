// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
// The clay's signed distance as the haptic thread reads it: a narrow-band grid sampled from the
// clay's closed triangle mesh, trilinearly interpolated (haptics::DistanceField). Built on the
// main thread or a worker, never on the tick; immutable once built, so that a built grid can be
// handed to the haptic thread (ClayGridChannel, clay_width.h) while the next one is built.
//
// Values: at every node within the band (|φ| < band, band = 3 cells) the exact signed
// distance to the mesh: the nearest triangle's distance, signed by the angle-weighted
// pseudonormal of the nearest feature (face, edge or vertex; Bærentzen and Aanæs 2005: right
// for every point of a closed, consistently oriented mesh). Beyond the band a node holds ±band:
// its sign is the last band node's along its x row (a row starts outside, at the padded box's
// face, and the surface cannot lie between a band node and the next far node, since band > one
// cell). So |φ| never exceeds the true distance by more than the interpolation error, and the
// sign is right wherever the surface is more than a cell away. Outside the grid's box
// φ = band + the distance to the box (a lower bound: the mesh lies at least band inside it).
//
// Local update (Update): after a stroke only nodes within band of a triangle that moved can
// change, so only the box around the stroke's old and new positions (grown by the longest edge,
// the band and a cell) is recomputed from the triangles that reach it, and the rest is copied.
// The far nodes' signs in that box are swept again from the node before it on each x row.
//
// Frames and units: W (the scene, where the clay's vertices are), m. Node (i, j, k) sits at
// origin + h (i, j, k).
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <array>
#include <memory>
#include <vector>

#include "spidarcad/haptics/distance_field.h"

namespace spidarcad::app {

// How a clay grid is sampled.
struct ClayGridSettings {
  double cell = 0.002;         // node spacing h, m (> 0), raised when the box would need more nodes
  long max_nodes = 4'000'000;  // at most this many nodes (4 bytes each)
  // The box is the mesh's bounds grown by this (m, >= 0) beyond band + 2 cells, so that strokes
  // that pull the clay a little outward keep to local updates.
  double slack = 0.01;
};

// A sampled signed distance field of a closed triangle mesh (see the file comment).
class ClayDistanceGrid final : public haptics::DistanceField {
 public:
  // Samples the mesh (positions #V, triangles #F, CCW from outside, closed) over its bounds.
  // Throws std::invalid_argument on an empty mesh, an index out of range or a bad setting.
  static std::shared_ptr<const ClayDistanceGrid> Build(
      const std::vector<Eigen::Vector3d>& positions, const std::vector<Eigen::Vector3i>& triangles,
      const ClayGridSettings& settings = {});
  // `previous` updated for the mesh now (positions, triangles) where it changed inside
  // changed_W (m, W: a box holding every old and new position of the moved vertices); a full
  // Build when the mesh has left previous's box or changed_W is empty.
  static std::shared_ptr<const ClayDistanceGrid> Update(
      const ClayDistanceGrid& previous, const std::vector<Eigen::Vector3d>& positions,
      const std::vector<Eigen::Vector3i>& triangles, const Eigen::AlignedBox3d& changed_W);

  // φ(p_W) (m), trilinear in the grid; gradient of that interpolant (W, 1/1) when asked.
  // Real-time safe.
  double Evaluate(const Eigen::Vector3d& p_W, Eigen::Vector3d* gradient_W) const noexcept override;

  double cell() const { return h_; }
  double band() const { return band_; }
  const Eigen::Vector3d& origin() const { return origin_; }
  const std::array<int, 3>& size() const { return n_; }
  long node_count() const { return static_cast<long>(values_.size()); }
  // Nodes the last Build or Update recomputed (the rest were copied).
  long recomputed_nodes() const { return recomputed_; }
  // The longest edge of the mesh it was built from (m).
  double longest_edge() const { return longest_edge_; }
  const ClayGridSettings& settings() const { return settings_; }
  // The value stored at node (i, j, k) (m).
  double Node(int i, int j, int k) const { return values_[Index(i, j, k)]; }

 private:
  ClayDistanceGrid() = default;
  long Index(int i, int j, int k) const { return (static_cast<long>(k) * n_[1] + j) * n_[0] + i; }
  // Recomputes nodes lo..hi (inclusive, per axis) from the mesh.
  void Fill(const std::vector<Eigen::Vector3d>& positions,
            const std::vector<Eigen::Vector3i>& triangles, const std::array<int, 3>& lo,
            const std::array<int, 3>& hi);

  ClayGridSettings settings_;
  Eigen::Vector3d origin_ = Eigen::Vector3d::Zero();
  double h_ = 0.0;
  double band_ = 0.0;
  std::array<int, 3> n_{0, 0, 0};
  std::vector<float> values_;
  long recomputed_ = 0;
  double longest_edge_ = 0.0;
};

}  // namespace spidarcad::app
