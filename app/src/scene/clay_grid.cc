// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#include "scene/clay_grid.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <stdexcept>
#include <string>

#include "spidarcad/modeling/triangle_closest_point.h"

namespace spidarcad::app {

namespace {

// Band half-width in cells: a node is a band node when |φ| < kBandCells · h (> 1, see the file
// comment).
constexpr double kBandCells = 3.0;

void CheckMesh(const std::vector<Eigen::Vector3d>& positions,
               const std::vector<Eigen::Vector3i>& triangles) {
  if (positions.empty() || triangles.empty())
    throw std::invalid_argument("clay grid: the mesh has no vertices or no triangles");
  const int n = static_cast<int>(positions.size());
  for (std::size_t t = 0; t < triangles.size(); ++t) {
    for (int k = 0; k < 3; ++k) {
      if (triangles[t][k] < 0 || triangles[t][k] >= n) {
        throw std::invalid_argument("clay grid: triangle " + std::to_string(t) + " has vertex " +
                                    std::to_string(triangles[t][k]) + ", not in [0, " +
                                    std::to_string(n) + ")");
      }
    }
  }
  for (const Eigen::Vector3d& p : positions) {
    if (!p.allFinite()) throw std::invalid_argument("clay grid: a vertex is not finite");
  }
}

double LongestEdge(const std::vector<Eigen::Vector3d>& positions,
                   const std::vector<Eigen::Vector3i>& triangles) {
  double longest = 0.0;
  for (const Eigen::Vector3i& tri : triangles) {
    for (int k = 0; k < 3; ++k) {
      longest = std::max(longest, (positions[tri[(k + 1) % 3]] - positions[tri[k]]).squaredNorm());
    }
  }
  return std::sqrt(longest);
}

Eigen::AlignedBox3d Bounds(const std::vector<Eigen::Vector3d>& positions) {
  Eigen::AlignedBox3d box;
  for (const Eigen::Vector3d& p : positions) box.extend(p);
  return box;
}

}  // namespace

std::shared_ptr<const ClayDistanceGrid> ClayDistanceGrid::Build(
    const std::vector<Eigen::Vector3d>& positions, const std::vector<Eigen::Vector3i>& triangles,
    const ClayGridSettings& settings) {
  if (!(settings.cell > 0.0) || !std::isfinite(settings.cell))
    throw std::invalid_argument("clay grid: cell must be > 0 m");
  if (!(settings.slack >= 0.0) || !std::isfinite(settings.slack))
    throw std::invalid_argument("clay grid: slack must be >= 0 m");
  if (settings.max_nodes < 8) throw std::invalid_argument("clay grid: max_nodes must be >= 8");
  CheckMesh(positions, triangles);
  std::shared_ptr<ClayDistanceGrid> grid(new ClayDistanceGrid());
  grid->settings_ = settings;
  const Eigen::AlignedBox3d bounds = Bounds(positions);
  double h = settings.cell;
  for (int attempt = 0; attempt < 64; ++attempt) {
    const double margin = kBandCells * h + 2.0 * h + settings.slack;
    const Eigen::Vector3d extent = bounds.sizes() + Eigen::Vector3d::Constant(2.0 * margin);
    double nodes = 1.0;
    for (int a = 0; a < 3; ++a) nodes *= std::ceil(extent[a] / h) + 1.0;
    if (nodes <= static_cast<double>(settings.max_nodes)) {
      grid->origin_ = bounds.min() - Eigen::Vector3d::Constant(margin);
      for (int a = 0; a < 3; ++a) grid->n_[a] = static_cast<int>(std::ceil(extent[a] / h)) + 1;
      break;
    }
    h *= 1.01 * std::cbrt(nodes / static_cast<double>(settings.max_nodes));
  }
  if (grid->n_[0] == 0) throw std::invalid_argument("clay grid: the mesh is too large to sample");
  grid->h_ = h;
  grid->band_ = kBandCells * h;
  grid->values_.assign(static_cast<std::size_t>(grid->n_[0]) * grid->n_[1] * grid->n_[2],
                       static_cast<float>(grid->band_));
  grid->longest_edge_ = LongestEdge(positions, triangles);
  grid->Fill(positions, triangles, {0, 0, 0}, {grid->n_[0] - 1, grid->n_[1] - 1, grid->n_[2] - 1});
  return grid;
}

std::shared_ptr<const ClayDistanceGrid> ClayDistanceGrid::Update(
    const ClayDistanceGrid& previous, const std::vector<Eigen::Vector3d>& positions,
    const std::vector<Eigen::Vector3i>& triangles, const Eigen::AlignedBox3d& changed_W) {
  CheckMesh(positions, triangles);
  const double h = previous.h_;
  const Eigen::AlignedBox3d bounds = Bounds(positions);
  const Eigen::Vector3d top =
      previous.origin_ +
      h * Eigen::Vector3d(previous.n_[0] - 1, previous.n_[1] - 1, previous.n_[2] - 1);
  const Eigen::AlignedBox3d inner(
      previous.origin_ + Eigen::Vector3d::Constant(previous.band_ + 2.0 * h),
      top - Eigen::Vector3d::Constant(previous.band_ + 2.0 * h));
  if (changed_W.isEmpty() || !inner.contains(bounds))
    return Build(positions, triangles, previous.settings_);
  std::shared_ptr<ClayDistanceGrid> grid(new ClayDistanceGrid(previous));
  grid->longest_edge_ = LongestEdge(positions, triangles);
  const double grow =
      std::max(previous.longest_edge_, grid->longest_edge_) + previous.band_ + 2.0 * h;
  std::array<int, 3> lo{}, hi{};
  for (int a = 0; a < 3; ++a) {
    lo[a] = std::max(
        0, static_cast<int>(std::floor((changed_W.min()[a] - grow - grid->origin_[a]) / h)));
    hi[a] =
        std::min(grid->n_[a] - 1,
                 static_cast<int>(std::ceil((changed_W.max()[a] + grow - grid->origin_[a]) / h)));
    if (hi[a] < lo[a]) {
      grid->recomputed_ = 0;
      return grid;
    }
  }
  grid->Fill(positions, triangles, lo, hi);
  return grid;
}

void ClayDistanceGrid::Fill(const std::vector<Eigen::Vector3d>& positions,
                            const std::vector<Eigen::Vector3i>& triangles,
                            const std::array<int, 3>& lo, const std::array<int, 3>& hi) {
  const int nv = static_cast<int>(positions.size());
  const int nt = static_cast<int>(triangles.size());
  const double h = h_, band = band_;
  const Eigen::Vector3d box_lo = origin_ + h * Eigen::Vector3d(lo[0], lo[1], lo[2]);
  const Eigen::Vector3d box_hi = origin_ + h * Eigen::Vector3d(hi[0], hi[1], hi[2]);

  // The triangles that reach the box (their bounds grown by the band overlap it).
  std::vector<int> reach;
  for (int t = 0; t < nt; ++t) {
    const Eigen::Vector3i& tri = triangles[t];
    const Eigen::Vector3d tmin =
        positions[tri[0]].cwiseMin(positions[tri[1]]).cwiseMin(positions[tri[2]]);
    const Eigen::Vector3d tmax =
        positions[tri[0]].cwiseMax(positions[tri[1]]).cwiseMax(positions[tri[2]]);
    if (((tmin.array() - band) <= box_hi.array()).all() &&
        ((tmax.array() + band) >= box_lo.array()).all()) {
      reach.push_back(t);
    }
  }

  // Pseudonormals of those triangles: unit face normals, edge normals (the sum of the two
  // faces' normals) and angle-weighted vertex normals, through a vertex-to-triangle table.
  std::vector<int> start(nv + 1, 0), incident(3 * static_cast<std::size_t>(nt));
  for (const Eigen::Vector3i& tri : triangles)
    for (int k = 0; k < 3; ++k) ++start[tri[k] + 1];
  for (int v = 0; v < nv; ++v) start[v + 1] += start[v];
  {
    std::vector<int> fill(start.begin(), start.end() - 1);
    for (int t = 0; t < nt; ++t)
      for (int k = 0; k < 3; ++k) incident[fill[triangles[t][k]]++] = t;
  }
  auto face_normal = [&](int t) {
    const Eigen::Vector3i& tri = triangles[t];
    const Eigen::Vector3d n =
        (positions[tri[1]] - positions[tri[0]]).cross(positions[tri[2]] - positions[tri[0]]);
    const double norm = n.norm();
    return norm > 0.0 ? Eigen::Vector3d(n / norm) : Eigen::Vector3d::Zero();
  };
  std::vector<std::uint8_t> vertex_done(nv, 0);
  std::vector<Eigen::Vector3d> vertex_normal(nv, Eigen::Vector3d::Zero());
  auto vertex_pseudonormal = [&](int v) -> const Eigen::Vector3d& {
    if (vertex_done[v]) return vertex_normal[v];
    Eigen::Vector3d sum = Eigen::Vector3d::Zero();
    for (int i = start[v]; i < start[v + 1]; ++i) {
      const Eigen::Vector3i& tri = triangles[incident[i]];
      const int k = tri[0] == v ? 0 : (tri[1] == v ? 1 : 2);
      const Eigen::Vector3d e1 = positions[tri[(k + 1) % 3]] - positions[v];
      const Eigen::Vector3d e2 = positions[tri[(k + 2) % 3]] - positions[v];
      const double angle = std::atan2(e1.cross(e2).norm(), e1.dot(e2));
      sum += angle * face_normal(incident[i]);
    }
    vertex_done[v] = 1;
    vertex_normal[v] = sum;
    return vertex_normal[v];
  };
  // The triangle across the directed edge a -> b of triangle t (the one holding b -> a).
  auto across = [&](int t, int a, int b) {
    for (int i = start[b]; i < start[b + 1]; ++i) {
      const int u = incident[i];
      if (u == t) continue;
      const Eigen::Vector3i& tri = triangles[u];
      for (int k = 0; k < 3; ++k)
        if (tri[k] == b && tri[(k + 1) % 3] == a) return u;
    }
    return -1;
  };

  const int sx = hi[0] - lo[0] + 1, sy = hi[1] - lo[1] + 1, sz = hi[2] - lo[2] + 1;
  const long count = static_cast<long>(sx) * sy * sz;
  std::vector<double> best(count, band), value(count, band);
  auto local = [&](int i, int j, int k) {
    return (static_cast<long>(k - lo[2]) * sy + (j - lo[1])) * sx + (i - lo[0]);
  };
  for (int t : reach) {
    const Eigen::Vector3i& tri = triangles[t];
    const Eigen::Vector3d& a = positions[tri[0]];
    const Eigen::Vector3d& b = positions[tri[1]];
    const Eigen::Vector3d& c = positions[tri[2]];
    const Eigen::Vector3d n = face_normal(t);
    std::array<int, 3> i0{}, i1{};
    bool empty = false;
    for (int ax = 0; ax < 3; ++ax) {
      const double tmin = std::min({a[ax], b[ax], c[ax]}) - band;
      const double tmax = std::max({a[ax], b[ax], c[ax]}) + band;
      i0[ax] = std::max(lo[ax], static_cast<int>(std::ceil((tmin - origin_[ax]) / h)));
      i1[ax] = std::min(hi[ax], static_cast<int>(std::floor((tmax - origin_[ax]) / h)));
      empty = empty || i1[ax] < i0[ax];
    }
    if (empty) continue;
    Eigen::Vector3d edge_normal[3];
    bool edges_known = false;
    for (int k = i0[2]; k <= i1[2]; ++k) {
      for (int j = i0[1]; j <= i1[1]; ++j) {
        for (int i = i0[0]; i <= i1[0]; ++i) {
          const Eigen::Vector3d p = origin_ + h * Eigen::Vector3d(i, j, k);
          const long at = local(i, j, k);
          if (std::abs((p - a).dot(n)) >= best[at]) continue;  // the plane is nearer than it
          modeling::TriangleFeature feature;
          const Eigen::Vector3d q = modeling::ClosestPointOnTriangle(p, a, b, c, &feature);
          const double d = (p - q).norm();
          if (!(d < best[at])) continue;
          Eigen::Vector3d normal;
          switch (feature) {
            case modeling::TriangleFeature::kFace:
              normal = n;
              break;
            case modeling::TriangleFeature::kVertex0:
            case modeling::TriangleFeature::kVertex1:
            case modeling::TriangleFeature::kVertex2:
              normal = vertex_pseudonormal(
                  tri[feature == modeling::TriangleFeature::kVertex0
                          ? 0
                          : (feature == modeling::TriangleFeature::kVertex1 ? 1 : 2)]);
              break;
            default: {
              if (!edges_known) {
                for (int e = 0; e < 3; ++e) {
                  const int u = across(t, tri[e], tri[(e + 1) % 3]);
                  edge_normal[e] = n + (u >= 0 ? face_normal(u) : Eigen::Vector3d::Zero());
                }
                edges_known = true;
              }
              normal = edge_normal[feature == modeling::TriangleFeature::kEdge01   ? 0
                                   : feature == modeling::TriangleFeature::kEdge12 ? 1
                                                                                   : 2];
            }
          }
          best[at] = d;
          value[at] = (p - q).dot(normal) < 0.0 ? -d : d;
        }
      }
    }
  }
  // Far nodes: the sign of the last band node along the x row (outside at the box's face).
  for (int k = lo[2]; k <= hi[2]; ++k) {
    for (int j = lo[1]; j <= hi[1]; ++j) {
      bool inside = lo[0] > 0 && values_[Index(lo[0] - 1, j, k)] < 0.0f;
      for (int i = lo[0]; i <= hi[0]; ++i) {
        const long at = local(i, j, k);
        double v = value[at];
        if (best[at] < band) {
          inside = v < 0.0;
        } else {
          v = inside ? -band : band;
        }
        values_[Index(i, j, k)] = static_cast<float>(v);
      }
    }
  }
  recomputed_ = count;
}

double ClayDistanceGrid::Evaluate(const Eigen::Vector3d& p_W,
                                  Eigen::Vector3d* gradient_W) const noexcept {
  const Eigen::Vector3d u = (p_W - origin_) / h_;
  Eigen::Vector3d clamped;
  for (int a = 0; a < 3; ++a) clamped[a] = std::clamp(u[a], 0.0, static_cast<double>(n_[a] - 1));
  if (!u.allFinite()) {
    if (gradient_W != nullptr) *gradient_W = Eigen::Vector3d::Zero();
    return band_;
  }
  if (clamped != u) {
    // Outside the box: band + the distance to it.
    const Eigen::Vector3d out = h_ * (u - clamped);
    const double d = out.norm();
    if (gradient_W != nullptr) *gradient_W = out / d;
    return band_ + d;
  }
  int i[3];
  double f[3];
  for (int a = 0; a < 3; ++a) {
    i[a] = std::min(static_cast<int>(u[a]), n_[a] - 2);
    f[a] = u[a] - i[a];
  }
  double c[2][2][2];
  for (int dz = 0; dz < 2; ++dz)
    for (int dy = 0; dy < 2; ++dy)
      for (int dx = 0; dx < 2; ++dx)
        c[dz][dy][dx] = values_[Index(i[0] + dx, i[1] + dy, i[2] + dz)];
  const double fx = f[0], fy = f[1], fz = f[2];
  const double c00 = c[0][0][0] + fx * (c[0][0][1] - c[0][0][0]);
  const double c10 = c[0][1][0] + fx * (c[0][1][1] - c[0][1][0]);
  const double c01 = c[1][0][0] + fx * (c[1][0][1] - c[1][0][0]);
  const double c11 = c[1][1][0] + fx * (c[1][1][1] - c[1][1][0]);
  const double c0 = c00 + fy * (c10 - c00);
  const double c1 = c01 + fy * (c11 - c01);
  const double value = c0 + fz * (c1 - c0);
  if (gradient_W != nullptr) {
    const double dx0 =
        (c[0][0][1] - c[0][0][0]) + fy * ((c[0][1][1] - c[0][1][0]) - (c[0][0][1] - c[0][0][0]));
    const double dx1 =
        (c[1][0][1] - c[1][0][0]) + fy * ((c[1][1][1] - c[1][1][0]) - (c[1][0][1] - c[1][0][0]));
    const double gx = dx0 + fz * (dx1 - dx0);
    const double gy = (c10 - c00) + fz * ((c11 - c01) - (c10 - c00));
    const double gz = c1 - c0;
    *gradient_W = Eigen::Vector3d(gx, gy, gz) / h_;
  }
  return value;
}

}  // namespace spidarcad::app
