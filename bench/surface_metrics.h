// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
// Figures of a triangle mesh against the implicit solid it approximates, shared by the surface
// benchmarks (modeling_surface_bench, app_surface_peers_bench):
//  - the two-sided Hausdorff distance between mesh and true surface, estimated by sampling:
//    mesh -> surface: 10 barycentric points on every triangle, distance |f| / |grad f| (first
//    order; exact for exact-distance fields); surface -> mesh: points on the true surface
//    (random points of the bounds moved onto the zero set by Newton steps; points outside a
//    convex edge or corner land exactly on it), each measured to the nearest triangle through a
//    uniform grid of triangles;
//  - whether the mesh is closed, consistently oriented and manifold (edges and vertex fans).
#pragma once

#include <algorithm>
#include <array>
#include <cmath>
#include <random>
#include <unordered_map>
#include <utility>
#include <vector>

#include "spidarcad/modeling/implicit_evaluator.h"
#include "spidarcad/modeling/surface_mesher.h"
#include "spidarcad/modeling/triangle_closest_point.h"

namespace spidarcad::bench {

using Vec = Eigen::Vector3d;

inline double PointTriangleDistance2(const Vec& p, const Vec& a, const Vec& b, const Vec& c) {
  return (p - modeling::ClosestPointOnTriangle(p, a, b, c)).squaredNorm();
}

// Nearest-triangle queries through a uniform grid (cells of edge `cell`) of triangle bounding
// boxes.
class TriangleGrid {
 public:
  TriangleGrid(const modeling::TriangleMesh& mesh, double cell) : mesh_(mesh), cell_(cell) {
    for (Eigen::Index t = 0; t < mesh.triangles.cols(); ++t) {
      Eigen::AlignedBox3d box;
      for (int k = 0; k < 3; ++k) box.extend(Vec(mesh.vertices.col(mesh.triangles(k, t))));
      const auto lo = Index(box.min()), hi = Index(box.max());
      for (long i = lo[0]; i <= hi[0]; ++i)
        for (long j = lo[1]; j <= hi[1]; ++j)
          for (long k = lo[2]; k <= hi[2]; ++k) cells_[Key(i, j, k)].push_back(static_cast<int>(t));
    }
  }
  // Distance from p to the mesh: cells within one ring of p's cell, then everything if needed.
  double Distance(const Vec& p) const {
    const auto c = Index(p);
    double best2 = INFINITY;
    for (long i = c[0] - 1; i <= c[0] + 1; ++i)
      for (long j = c[1] - 1; j <= c[1] + 1; ++j)
        for (long k = c[2] - 1; k <= c[2] + 1; ++k) {
          const auto it = cells_.find(Key(i, j, k));
          if (it == cells_.end()) continue;
          for (int t : it->second) best2 = std::min(best2, Triangle2(p, t));
        }
    if (best2 <= cell_ * cell_) return std::sqrt(best2);  // nothing outside the block can be nearer
    for (Eigen::Index t = 0; t < mesh_.triangles.cols(); ++t)
      best2 = std::min(best2, Triangle2(p, static_cast<int>(t)));
    return std::sqrt(best2);
  }

 private:
  std::array<long, 3> Index(const Vec& p) const {
    return {static_cast<long>(std::floor(p.x() / cell_)),
            static_cast<long>(std::floor(p.y() / cell_)),
            static_cast<long>(std::floor(p.z() / cell_))};
  }
  static long long Key(long i, long j, long k) {
    return ((static_cast<long long>(i) & 0x1fffff) << 42) |
           ((static_cast<long long>(j) & 0x1fffff) << 21) | (static_cast<long long>(k) & 0x1fffff);
  }
  double Triangle2(const Vec& p, int t) const {
    return PointTriangleDistance2(p, mesh_.vertices.col(mesh_.triangles(0, t)),
                                  mesh_.vertices.col(mesh_.triangles(1, t)),
                                  mesh_.vertices.col(mesh_.triangles(2, t)));
  }
  const modeling::TriangleMesh& mesh_;
  double cell_;
  std::unordered_map<long long, std::vector<int>> cells_;
};

// `count` points on the true surface: random points of `bounds` (seed 1234), Newton-projected;
// kept when |f| <= 1e-10 m.
inline std::vector<Vec> SurfaceSamples(const modeling::CompiledSolid& solid,
                                       const Eigen::AlignedBox3d& bounds, int count = 20000) {
  std::vector<Vec> points;
  std::mt19937 rng(1234);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  while (static_cast<int>(points.size()) < count) {
    Vec p = bounds.min() + bounds.sizes().cwiseProduct(Vec(u(rng), u(rng), u(rng)));
    for (int i = 0; i < 20; ++i) {
      Vec g;
      const double f = solid.ValueAndGradient(p, &g);
      if (std::abs(f) <= 1e-12 || g.squaredNorm() < 1e-12) break;
      p -= f / g.squaredNorm() * g;
    }
    if (std::abs(solid.Value(p)) <= 1e-10 && bounds.contains(p)) points.push_back(p);
  }
  return points;
}

// Sampled Hausdorff distances (m): mesh -> surface (out_) and surface -> mesh (in_).
struct HausdorffError {
  double out_max = 0, out_mean = 0, in_max = 0, in_mean = 0;
  double TwoSided() const { return std::max(out_max, in_max); }
};

// HausdorffError of mesh against solid; `samples` from SurfaceSamples, `cell` the mesh's cell.
inline HausdorffError MeasureHausdorff(const modeling::CompiledSolid& solid,
                                       const std::vector<Vec>& samples,
                                       const modeling::TriangleMesh& mesh, double cell) {
  HausdorffError e;
  double area_sum = 0.0;
  for (Eigen::Index t = 0; t < mesh.triangles.cols(); ++t) {
    const Vec a = mesh.vertices.col(mesh.triangles(0, t)),
              b = mesh.vertices.col(mesh.triangles(1, t));
    const Vec d = mesh.vertices.col(mesh.triangles(2, t));
    const double area = 0.5 * (b - a).cross(d - a).norm();
    double sum = 0.0;
    int n = 0;
    for (int i = 0; i <= 3; ++i) {
      for (int j = 0; i + j <= 3; ++j, ++n) {
        Vec g;
        const double f = solid.ValueAndGradient((i * a + j * b + (3 - i - j) * d) / 3.0, &g);
        const double dist = std::abs(f) / std::max(g.norm(), 1e-6);
        e.out_max = std::max(e.out_max, dist);
        sum += dist;
      }
    }
    e.out_mean += area * sum / n;
    area_sum += area;
  }
  e.out_mean /= std::max(area_sum, 1e-300);
  const TriangleGrid grid(mesh, 2.0 * cell);
  for (const Vec& p : samples) {
    const double d = grid.Distance(p);
    e.in_max = std::max(e.in_max, d);
    e.in_mean += d;
  }
  e.in_mean /= std::max<double>(1.0, static_cast<double>(samples.size()));
  return e;
}

// Whether every directed edge occurs once and its reverse once (closed, consistently oriented,
// edge-manifold) and the triangles around every vertex form a single fan (vertex-manifold);
// *euler gets V - E + F (V: vertices used by a triangle).
inline bool IsClosedManifold(const modeling::TriangleMesh& mesh, long* euler = nullptr) {
  std::vector<std::pair<long long, int>> directed;  // (a * V + b, third corner c)
  const long long nv = mesh.vertices.cols();
  directed.reserve(3 * static_cast<size_t>(mesh.triangles.cols()));
  for (Eigen::Index t = 0; t < mesh.triangles.cols(); ++t) {
    for (int k = 0; k < 3; ++k) {
      const int a = mesh.triangles(k, t), b = mesh.triangles((k + 1) % 3, t),
                c = mesh.triangles((k + 2) % 3, t);
      if (a == b || a < 0 || a >= nv || b < 0 || b >= nv) return false;
      directed.emplace_back(a * nv + b, c);
    }
  }
  std::sort(directed.begin(), directed.end());
  for (size_t i = 0; i < directed.size(); ++i) {
    if (i > 0 && directed[i].first == directed[i - 1].first) return false;  // edge used twice
    const long long a = directed[i].first / nv, b = directed[i].first % nv;
    if (!std::binary_search(directed.begin(), directed.end(), std::make_pair(b * nv + a, -1),
                            [](const auto& x, const auto& y) { return x.first < y.first; }))
      return false;  // open edge
  }
  // Fan walk per vertex: triangle (v, b, c) maps b -> c; one cycle must visit all of them.
  std::vector<std::vector<std::pair<int, int>>> link(static_cast<size_t>(nv));
  for (const auto& [key, c] : directed) link[key / nv].emplace_back(static_cast<int>(key % nv), c);
  long used = 0;
  for (auto& fan : link) {
    if (fan.empty()) continue;
    ++used;
    std::sort(fan.begin(), fan.end());
    int at = fan.front().first;
    size_t steps = 0;
    do {
      const auto it = std::lower_bound(fan.begin(), fan.end(), std::make_pair(at, -1));
      if (it == fan.end() || it->first != at) return false;
      at = it->second;
      ++steps;
    } while (at != fan.front().first && steps <= fan.size());
    if (steps != fan.size()) return false;
  }
  if (euler != nullptr)
    *euler =
        used - static_cast<long>(directed.size() / 2) + static_cast<long>(mesh.triangles.cols());
  return true;
}

}  // namespace spidarcad::bench
