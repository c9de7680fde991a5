// SculptMesh's self-intersection check (sculpt.h, "Self-intersection"): do the triangles a stroke
// moves cross each other or any triangle near them?
//
// Broad phase: the moved triangles and every triangle with a vertex in the moved region's box
// (grown by the longest edge, so that any triangle reaching into the box is found) are binned by
// their bounding boxes into cubic cells of twice their mean size; (cell, triangle) entries are
// sorted, and each pair of triangles is examined once, in the cell holding the lowest corner of
// their boxes' overlap. Narrow phase, for pairs with at least one moved triangle:
//   - no shared vertex: the triangles cross when an edge of one crosses the other (in general
//     position the ends of their intersection segment lie on such edges);
//   - one shared vertex s: only the edge opposite s can cross the other triangle (an edge from s
//     meets the other triangle's plane at s alone unless it lies in it);
//   - a shared edge: the triangles can only overlap by folding flat onto each other, seen as
//     normals within 2.6 degrees of opposite.
// Coplanar overlaps other than the folded edge are not detected (they need exact arithmetic and
// do not arise from the deformation fields in practice).
// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#include <algorithm>
#include <array>
#include <cmath>

#include "sculpt_grid.h"
#include "spidarcad/modeling/sculpt.h"

namespace spidarcad::modeling {
namespace {

// Edge neighbours whose normals' dot product is below this are folded onto each other.
constexpr double kFoldedDot = -0.999;

using sculpt_grid::CellOf;
using sculpt_grid::Pack;

// True when segment pq crosses triangle abc (Möller–Trumbore, closed in the segment parameter
// and the barycentric coordinates); a segment parallel to the triangle's plane never does.
bool SegmentCrossesTriangle(const Eigen::Vector3d& p, const Eigen::Vector3d& q,
                            const Eigen::Vector3d& a, const Eigen::Vector3d& b,
                            const Eigen::Vector3d& c) {
  const Eigen::Vector3d d = q - p, e1 = b - a, e2 = c - a;
  const Eigen::Vector3d h = d.cross(e2);
  const double det = e1.dot(h);
  if (!(std::abs(det) > 1e-14 * d.norm() * e1.norm() * e2.norm())) return false;
  const double inv = 1.0 / det;
  const Eigen::Vector3d s = p - a;
  const double u = inv * s.dot(h);
  if (u < 0.0 || u > 1.0) return false;
  const Eigen::Vector3d r = s.cross(e1);
  const double v = inv * d.dot(r);
  if (v < 0.0 || u + v > 1.0) return false;
  const double t = inv * e2.dot(r);
  return t >= 0.0 && t <= 1.0;
}

// True when some edge of triangle x crosses triangle y (corner positions).
bool AnEdgeCrosses(const std::array<Eigen::Vector3d, 3>& x,
                   const std::array<Eigen::Vector3d, 3>& y) {
  for (int k = 0; k < 3; ++k) {
    if (SegmentCrossesTriangle(x[k], x[(k + 1) % 3], y[0], y[1], y[2])) return true;
  }
  return false;
}

}  // namespace

bool SculptMesh::MovedRegionIntersects() {
  const int moved = static_cast<int>(affected_triangles_.size());
  if (moved == 0) return false;
  const double reach_margin = longest_edge_ > 0.0 ? longest_edge_ : grid_cell_;

  // The moved region's box, grown by the longest edge.
  Eigen::AlignedBox3d region;
  for (int t : affected_triangles_) {
    for (int k = 0; k < 3; ++k) region.extend(positions_[triangles_[t][k]]);
  }
  const Eigen::AlignedBox3d reach(region.min().array() - reach_margin,
                                  region.max().array() + reach_margin);

  // Triangles to examine: the moved ones first, then every other one with a vertex in reach.
  const std::uint32_t stamp = NextStamp();
  check_triangles_.clear();
  for (int t : affected_triangles_) {
    triangle_mark_[t] = stamp;
    check_triangles_.push_back(t);
  }
  const auto add_vertex_triangles = [&](int v) {
    if (!reach.contains(positions_[v])) return;
    for (int t : vertex_triangles_[v]) {
      if (triangle_mark_[t] == stamp) continue;
      triangle_mark_[t] = stamp;
      check_triangles_.push_back(t);
    }
  };
  check_vertices_.clear();
  VerticesInCellBox(reach, &check_vertices_);
  for (int v : check_vertices_) add_vertex_triangles(v);

  // Broad phase: (cell, index) entries of every examined triangle's box, sorted by cell. Cells
  // of twice the mean box size hold a few triangles each.
  const int n = static_cast<int>(check_triangles_.size());
  check_boxes_.resize(n);
  double mean_extent = 0.0;
  for (int i = 0; i < n; ++i) {
    const Eigen::Vector3i& tri = triangles_[check_triangles_[i]];
    Eigen::AlignedBox3d box(positions_[tri[0]]);
    box.extend(positions_[tri[1]]);
    box.extend(positions_[tri[2]]);
    check_boxes_[i] = box;
    mean_extent += box.sizes().maxCoeff();
  }
  const double h = std::max(2.0 * mean_extent / n, 1e-12 * region.sizes().maxCoeff() + 1e-300);
  check_entries_.clear();
  check_low_cells_.resize(n);
  for (int i = 0; i < n; ++i) {
    const Eigen::AlignedBox3d& box = check_boxes_[i];
    const std::int64_t x0 = CellOf(box.min().x(), h), x1 = CellOf(box.max().x(), h);
    const std::int64_t y0 = CellOf(box.min().y(), h), y1 = CellOf(box.max().y(), h);
    const std::int64_t z0 = CellOf(box.min().z(), h), z1 = CellOf(box.max().z(), h);
    check_low_cells_[i] = {x0, y0, z0};
    for (std::int64_t x = x0; x <= x1; ++x) {
      for (std::int64_t y = y0; y <= y1; ++y) {
        for (std::int64_t z = z0; z <= z1; ++z) check_entries_.emplace_back(Pack(x, y, z), i);
      }
    }
  }
  std::sort(check_entries_.begin(), check_entries_.end());

  // Narrow phase over the pairs that share a cell, each pair once.
  const size_t entries = check_entries_.size();
  for (size_t begin = 0; begin < entries;) {
    size_t end = begin + 1;
    while (end < entries && check_entries_[end].first == check_entries_[begin].first) ++end;
    const std::uint64_t cell = check_entries_[begin].first;
    for (size_t a = begin; a < end; ++a) {
      const int i = check_entries_[a].second;
      for (size_t b = a + 1; b < end; ++b) {
        const int j = check_entries_[b].second;
        if (i >= moved && j >= moved) continue;  // two unmoved triangles: as they were
        const Eigen::AlignedBox3d& box_i = check_boxes_[i];
        const Eigen::AlignedBox3d& box_j = check_boxes_[j];
        if (!box_i.intersects(box_j)) continue;
        // The overlap's lowest corner is max(min_i, min_j); floor is monotonic, so its cell is
        // the larger of the two boxes' lowest cells, axis by axis.
        const std::array<std::int64_t, 3>& ci = check_low_cells_[i];
        const std::array<std::int64_t, 3>& cj = check_low_cells_[j];
        if (Pack(std::max(ci[0], cj[0]), std::max(ci[1], cj[1]), std::max(ci[2], cj[2])) != cell) {
          continue;  // examined in another cell
        }
        const Eigen::Vector3i& ti = triangles_[check_triangles_[i]];
        const Eigen::Vector3i& tj = triangles_[check_triangles_[j]];
        int shared = 0, shared_at_i = -1;
        for (int k = 0; k < 3; ++k) {
          for (int l = 0; l < 3; ++l) {
            if (ti[k] == tj[l]) {
              ++shared;
              shared_at_i = k;
            }
          }
        }
        const std::array<Eigen::Vector3d, 3> pi = {positions_[ti[0]], positions_[ti[1]],
                                                   positions_[ti[2]]};
        const std::array<Eigen::Vector3d, 3> pj = {positions_[tj[0]], positions_[tj[1]],
                                                   positions_[tj[2]]};
        if (shared == 0) {
          if (AnEdgeCrosses(pi, pj) || AnEdgeCrosses(pj, pi)) return true;
        } else if (shared == 1) {
          // The edges opposite the shared vertex.
          int shared_at_j = 0;
          while (tj[shared_at_j] != ti[shared_at_i]) ++shared_at_j;
          const Eigen::Vector3d& i1 = pi[(shared_at_i + 1) % 3];
          const Eigen::Vector3d& i2 = pi[(shared_at_i + 2) % 3];
          const Eigen::Vector3d& j1 = pj[(shared_at_j + 1) % 3];
          const Eigen::Vector3d& j2 = pj[(shared_at_j + 2) % 3];
          if (SegmentCrossesTriangle(i1, i2, pj[0], pj[1], pj[2]) ||
              SegmentCrossesTriangle(j1, j2, pi[0], pi[1], pi[2])) {
            return true;
          }
        } else if (shared == 2) {
          const Eigen::Vector3d ni = (pi[1] - pi[0]).cross(pi[2] - pi[0]);
          const Eigen::Vector3d nj = (pj[1] - pj[0]).cross(pj[2] - pj[0]);
          const double norms = ni.norm() * nj.norm();
          if (norms > 0.0 && ni.dot(nj) < kFoldedDot * norms) return true;
        }
      }
    }
    begin = end;
  }
  return false;
}

}  // namespace spidarcad::modeling
