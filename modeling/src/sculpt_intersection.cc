// SculptMesh's self-intersection check (sculpt.h, "Self-intersection"): do the triangles a stroke
// moves cross each other or any triangle near them?
//
// Gathering: the moved triangles and every triangle with a vertex in the moved region's box
// (grown by the longest edge, so that any triangle reaching into the box is found). Each gets
// its box, its normal and its edge lengths once per check.
// Broad phase: a dense grid over the gathered boxes, cells of 1.5 times the mean box size (grown
// when the grid would have more than 8 cells per triangle), filled by a counting sort of the
// (cell, triangle) entries; each pair of triangles whose boxes overlap is examined once, in the
// cell holding the lowest corner of the overlap, and only when at least one of them moved.
// Narrow phase, in order:
//   - no shared vertex: the triangles cross when an edge of one crosses the other (in general
//     position the ends of their intersection segment lie on such edges);
//   - one shared vertex s: only the edge opposite s can cross the other triangle (an edge from s
//     meets the other triangle's plane at s alone unless it lies in it);
//   - a shared edge: the triangles can only overlap by folding flat onto each other, seen as
//     normals within 2.6 degrees of opposite.
// An edge is tested against a triangle (SegmentCrossesTriangle) unless both its ends lie on the
// same side of the triangle's plane by more than the rounding error of that test, in which case
// the test would answer false; so the decisions are those of testing every edge.
// Coplanar overlaps other than the folded edge are not detected (they need exact arithmetic and
// do not arise from the deformation fields in practice).
// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#include <algorithm>
#include <array>
#include <cmath>

#include "spidarcad/modeling/sculpt.h"

namespace spidarcad::modeling {
namespace {

using internal::SculptCheckTriangle;

// Edge neighbours whose normals' dot product is below this are folded onto each other.
constexpr double kFoldedDot = -0.999;
// Broad-phase cell edge, in mean box sizes (1.5 to 2 is best on the benchmark's blob).
constexpr double kCellPerExtent = 1.5;
// The broad-phase grid has at most this many cells per gathered triangle (plus kMinCells).
constexpr double kCellsPerTriangle = 8.0;
constexpr double kMinCells = 64.0;
// Plane-side margin, relative to |e1| |e2| (|p - a| + |q - a|) for segment pq against triangle
// abc (e1 = b - a, e2 = c - a): SegmentCrossesTriangle's triple products carry an absolute
// rounding error below 1e-15 of that scale, so ends farther than 1e-13 of it on one side of the
// plane give a parameter t outside [0, 1] there too.
constexpr double kSideMargin = 1e-13;

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

// True when both plane-side values exceed the margin with the same sign: the segment between
// the two points stays strictly on one side of the plane.
bool OneSide(double dp, double dq, double margin) {
  return (dp > margin && dq > margin) || (dp < -margin && dq < -margin);
}

// The narrow phase for triangles x and y whose boxes overlap (see the file comment).
class PairTest {
 public:
  PairTest(const SculptCheckTriangle& x, const SculptCheckTriangle& y) : x_(x), y_(y) {}

  bool Crosses() const {
    int shared = 0, shared_at_x = -1, shared_at_y = -1;
    for (int k = 0; k < 3; ++k) {
      for (int l = 0; l < 3; ++l) {
        if (x_.corners[k] == y_.corners[l]) {
          ++shared;
          shared_at_x = k;
          shared_at_y = l;
        }
      }
    }
    if (shared == 2) {
      const double norms = x_.normal_norm * y_.normal_norm;
      return norms > 0.0 && x_.normal.dot(y_.normal) < kFoldedDot * norms;
    }
    // |p - a| + |q - a| for any corners p, q of one triangle and a of the other, whose boxes
    // overlap, is at most twice the sum of the boxes' diagonals.
    const double reach = 2.0 * (x_.diagonal + y_.diagonal);
    if (shared == 1) {
      // The edges opposite the shared vertex.
      return EdgeCrosses(x_, (shared_at_x + 1) % 3, y_, reach) ||
             EdgeCrosses(y_, (shared_at_y + 1) % 3, x_, reach);
    }
    if (shared != 0) return false;
    // Every edge of one triangle against the other, each skipped when it stays on one side.
    std::array<double, 3> side{};
    const double x_margin = kSideMargin * y_.edge_product * reach;
    for (int k = 0; k < 3; ++k) side[k] = Side(x_.p[k], y_);
    for (int k = 0; k < 3; ++k) {
      if (!OneSide(side[k], side[(k + 1) % 3], x_margin) && Segment(x_, k, y_)) return true;
    }
    const double y_margin = kSideMargin * x_.edge_product * reach;
    for (int k = 0; k < 3; ++k) side[k] = Side(y_.p[k], x_);
    for (int k = 0; k < 3; ++k) {
      if (!OneSide(side[k], side[(k + 1) % 3], y_margin) && Segment(y_, k, x_)) return true;
    }
    return false;
  }

 private:
  // n·(p - a) for triangle t = (a, b, c) with n = (b - a) × (c - a): the side of t's plane p is on.
  double Side(const Eigen::Vector3d& p, const SculptCheckTriangle& t) const {
    return t.normal.dot(p - t.p[0]);
  }
  // Edge k (corner k to corner k + 1) of triangle e against triangle t.
  bool Segment(const SculptCheckTriangle& e, int k, const SculptCheckTriangle& t) const {
    return SegmentCrossesTriangle(e.p[k], e.p[(k + 1) % 3], t.p[0], t.p[1], t.p[2]);
  }
  // Edge k of triangle e against triangle t, skipping the test when the edge stays on one side.
  bool EdgeCrosses(const SculptCheckTriangle& e, int k, const SculptCheckTriangle& t,
                   double reach) const {
    const double margin = kSideMargin * t.edge_product * reach;
    if (OneSide(Side(e.p[k], t), Side(e.p[(k + 1) % 3], t), margin)) {
      return false;
    }
    return Segment(e, k, t);
  }

  const SculptCheckTriangle& x_;
  const SculptCheckTriangle& y_;
};

// Cell of coordinate x (m) in a grid starting at lo (m) with cells of edge 1 / inv_h (m), clamped
// to [0, cells - 1] (NaN gives 0). Monotonic in x.
int CellOf(double x, double lo, double inv_h, int cells) {
  const double q = (x - lo) * inv_h;
  if (!(q > 0.0)) return 0;
  return q < cells - 1 ? static_cast<int>(q) : cells - 1;  // the cast floors q > 0
}

}  // namespace

bool SculptMesh::MovedRegionIntersects() { return stroke_active_ && CheckMovedRegion(); }

bool SculptMesh::CheckMovedRegion() {
  const int moved = static_cast<int>(affected_triangles_.size());
  if (moved == 0) return false;
  const double reach_margin = longest_edge_ > 0.0 ? longest_edge_ : grid_cell_;

  // The moved region's box (the corners of the moved triangles), grown by the longest edge.
  Eigen::AlignedBox3d region;
  for (int v : normal_vertices_) region.extend(positions_[v]);
  const Eigen::AlignedBox3d reach(region.min().array() - reach_margin,
                                  region.max().array() + reach_margin);

  // Triangles to examine: the moved ones first, then every other one with a vertex in reach.
  const std::uint32_t stamp = NextStamp();
  check_triangles_.clear();
  for (int t : affected_triangles_) {
    triangle_mark_[t] = stamp;
    check_triangles_.push_back(t);
  }
  check_vertices_.clear();
  VerticesInCellBox(reach, &check_vertices_);
  for (int v : check_vertices_) {
    if (!reach.contains(positions_[v])) continue;
    for (int t : vertex_triangles_[v]) {
      if (triangle_mark_[t] == stamp) continue;
      triangle_mark_[t] = stamp;
      check_triangles_.push_back(t);
    }
  }

  // Per triangle: box, normal, edge lengths.
  const int n = static_cast<int>(check_triangles_.size());
  check_data_.resize(n);
  Eigen::AlignedBox3d all;
  double mean_extent = 0.0;
  for (int i = 0; i < n; ++i) {
    SculptCheckTriangle& c = check_data_[i];
    c.corners = triangles_[check_triangles_[i]];
    const Eigen::Vector3d& p0 = c.p[0] = positions_[c.corners[0]];
    const Eigen::Vector3d& p1 = c.p[1] = positions_[c.corners[1]];
    const Eigen::Vector3d& p2 = c.p[2] = positions_[c.corners[2]];
    c.lo = p0.cwiseMin(p1).cwiseMin(p2);
    c.hi = p0.cwiseMax(p1).cwiseMax(p2);
    const Eigen::Vector3d e1 = p1 - p0, e2 = p2 - p0;
    c.normal = e1.cross(e2);
    c.normal_norm = c.normal.norm();
    c.edge_product = std::sqrt(e1.squaredNorm() * e2.squaredNorm());
    const Eigen::Vector3d size = c.hi - c.lo;
    c.diagonal = size.norm();
    mean_extent += size.maxCoeff();
    all.extend(c.lo);
    all.extend(c.hi);
  }
  // A non-finite position is never accepted.
  if (!all.min().allFinite() || !all.max().allFinite()) return true;

  // The grid: cells of kCellPerExtent mean box sizes, fewer when there would be too many.
  const Eigen::Vector3d all_size = all.sizes();
  double h = std::max(kCellPerExtent * mean_extent / n, 1e-12 * all_size.maxCoeff() + 1e-300);
  const double max_cells = kCellsPerTriangle * n + kMinCells;
  std::array<int, 3> dims{};
  for (;;) {
    double cells = 1.0;
    for (int a = 0; a < 3; ++a) cells *= std::floor(all_size[a] / h) + 1.0;
    if (cells <= max_cells) break;
    h *= std::max(1.05, std::cbrt(cells / max_cells));
  }
  for (int a = 0; a < 3; ++a) dims[a] = static_cast<int>(std::floor(all_size[a] / h)) + 1;
  const int cells = dims[0] * dims[1] * dims[2];
  const double inv_h = 1.0 / h;

  // Counting sort of the (cell, triangle) entries by cell; within a cell the triangles keep
  // their order, moved ones first.
  check_cell_start_.assign(cells + 1, 0);
  for (int i = 0; i < n; ++i) {
    SculptCheckTriangle& c = check_data_[i];
    for (int a = 0; a < 3; ++a) {
      c.cell_lo[a] = CellOf(c.lo[a], all.min()[a], inv_h, dims[a]);
      c.cell_hi[a] = CellOf(c.hi[a], all.min()[a], inv_h, dims[a]);
    }
    for (int x = c.cell_lo[0]; x <= c.cell_hi[0]; ++x) {
      for (int y = c.cell_lo[1]; y <= c.cell_hi[1]; ++y) {
        for (int z = c.cell_lo[2]; z <= c.cell_hi[2]; ++z) {
          ++check_cell_start_[(x * dims[1] + y) * dims[2] + z + 1];
        }
      }
    }
  }
  for (int cell = 0; cell < cells; ++cell) check_cell_start_[cell + 1] += check_cell_start_[cell];
  check_entries_.resize(check_cell_start_[cells]);
  for (int i = 0; i < n; ++i) {
    const SculptCheckTriangle& c = check_data_[i];
    for (int x = c.cell_lo[0]; x <= c.cell_hi[0]; ++x) {
      for (int y = c.cell_lo[1]; y <= c.cell_hi[1]; ++y) {
        for (int z = c.cell_lo[2]; z <= c.cell_hi[2]; ++z) {
          // Bits 0-2: the cell is the box's lowest cell along x, y, z.
          const int low = (x == c.cell_lo[0] ? 1 : 0) | (y == c.cell_lo[1] ? 2 : 0) |
                          (z == c.cell_lo[2] ? 4 : 0);
          check_entries_[check_cell_start_[(x * dims[1] + y) * dims[2] + z]++] = i << 3 | low;
        }
      }
    }
  }
  // Each start now holds the next cell's start: shift back.
  for (int cell = cells; cell > 0; --cell) check_cell_start_[cell] = check_cell_start_[cell - 1];
  check_cell_start_[0] = 0;

  // Narrow phase over the pairs that share a cell, each pair once.
  for (int x = 0; x < dims[0]; ++x) {
    for (int y = 0; y < dims[1]; ++y) {
      for (int z = 0; z < dims[2]; ++z) {
        const int cell = (x * dims[1] + y) * dims[2] + z;
        const int begin = check_cell_start_[cell], end = check_cell_start_[cell + 1];
        for (int a = begin; a < end; ++a) {
          const int entry_i = check_entries_[a];
          const int i = entry_i >> 3;
          if (i >= moved) break;  // the rest are unmoved, as are the triangles after them
          const SculptCheckTriangle& ci = check_data_[i];
          for (int b = a + 1; b < end; ++b) {
            const int entry_j = check_entries_[b];
            // The overlap's lowest corner is max(lo_i, lo_j); its cell is the larger of the two
            // boxes' lowest cells, axis by axis (CellOf is monotonic): this cell when, along
            // each axis, it is the lowest cell of one of the boxes.
            if (((entry_i | entry_j) & 7) != 7) continue;  // examined in another cell
            const SculptCheckTriangle& cj = check_data_[entry_j >> 3];
            if (ci.lo.x() > cj.hi.x() || cj.lo.x() > ci.hi.x() || ci.lo.y() > cj.hi.y() ||
                cj.lo.y() > ci.hi.y() || ci.lo.z() > cj.hi.z() || cj.lo.z() > ci.hi.z()) {
              continue;  // the boxes do not overlap
            }
            if (PairTest(ci, cj).Crosses()) return true;
          }
        }
      }
    }
  }
  return false;
}

}  // namespace spidarcad::modeling
