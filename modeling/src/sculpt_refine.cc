// SculptMesh refinement (splitting stretched edges in the touched region) and the icosphere.
// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#include <algorithm>
#include <cmath>
#include <map>
#include <stdexcept>
#include <string>
#include <tuple>

#include "spidarcad/modeling/sculpt.h"

namespace spidarcad::modeling {

// Splits edge a-b at its midpoint m. With t0 = (a, b, c) holding the directed edge a->b and
// t1 = (b, a, d) holding b->a (rotated so), the four triangles become
//   t0 = (a, m, c), t2 = (m, b, c), t1 = (b, m, d), t3 = (m, a, d):
// same orientation, every edge still shared by two opposite triangles. The split is planar, so
// the enclosed volume does not change. Returns false when a->b is no longer an edge.
bool SculptMesh::SplitEdge(int a, int b, SculptEdit* edit, std::vector<int>* new_triangles) {
  int t0 = -1, t1 = -1, k0 = 0, k1 = 0;
  for (int t : vertex_triangles_[a]) {
    const Eigen::Vector3i& tri = triangles_[t];
    for (int k = 0; k < 3; ++k) {
      if (tri[k] == a && tri[(k + 1) % 3] == b) t0 = t, k0 = k;
      if (tri[k] == b && tri[(k + 1) % 3] == a) t1 = t, k1 = k;
    }
  }
  if (t0 < 0 || t1 < 0) return false;
  const int c = triangles_[t0][(k0 + 2) % 3];
  const int d = triangles_[t1][(k1 + 2) % 3];
  if (edit != nullptr) {
    // Remember the original of each pre-existing triangle once (triangle_mark_ holds the
    // refinement's stamp, set by Refine).
    for (int t : {t0, t1}) {
      if (t < edit->old_triangle_count && triangle_mark_[t] != stamp_) {
        triangle_mark_[t] = stamp_;
        edit->rewritten.push_back(t);
        edit->old_triangles.push_back(triangles_[t]);
      }
    }
  }
  const int m = AddVertex(0.5 * (positions_[a] + positions_[b]));
  SetTriangle(t0, Eigen::Vector3i(a, m, c));
  SetTriangle(t1, Eigen::Vector3i(b, m, d));
  const int t2 = AddTriangle(Eigen::Vector3i(m, b, c));
  const int t3 = AddTriangle(Eigen::Vector3i(m, a, d));
  new_triangles->insert(new_triangles->end(), {t0, t1, t2, t3});
  return true;
}

long SculptMesh::Refine(const std::vector<int>& triangles, double max_edge_length, int max_splits,
                        SculptEdit* edit) {
  if (!(max_edge_length > 0.0)) {
    throw std::invalid_argument("SculptMesh::Refine: max_edge_length = " +
                                std::to_string(max_edge_length) + " must be > 0");
  }
  if (stroke_active_ && edit == nullptr)
    throw std::logic_error("SculptMesh::Refine: a stroke is active");
  const int old_vertices = vertex_count();
  if (edit != nullptr) {
    edit->old_vertex_count = old_vertices;
    edit->old_triangle_count = triangle_count();
  }
  NextStamp();  // the stamp SplitEdge marks rewritten triangles with
  const double limit2 = max_edge_length * max_edge_length;
  std::vector<int> current = triangles, next;
  std::vector<std::tuple<double, int, int>> long_edges;
  long splits = 0;
  while (!current.empty() && splits < max_splits) {
    long_edges.clear();
    for (int t : current) {
      if (t < 0 || t >= triangle_count()) continue;
      for (int k = 0; k < 3; ++k) {
        const int a = triangles_[t][k], b = triangles_[t][(k + 1) % 3];
        const double length2 = (positions_[a] - positions_[b]).squaredNorm();
        if (length2 > limit2) long_edges.emplace_back(length2, std::min(a, b), std::max(a, b));
      }
    }
    // Longest first (better shapes), each edge once.
    std::sort(long_edges.begin(), long_edges.end(),
              [](const auto& x, const auto& y) { return x > y; });
    long_edges.erase(std::unique(long_edges.begin(), long_edges.end()), long_edges.end());
    next.clear();
    for (const auto& [length2, a, b] : long_edges) {
      if (splits >= max_splits) break;
      if (SplitEdge(a, b, edit, &next)) ++splits;
    }
    std::sort(next.begin(), next.end());
    next.erase(std::unique(next.begin(), next.end()), next.end());
    current.swap(next);
  }
  std::vector<int> added;
  for (int v = old_vertices; v < vertex_count(); ++v) added.push_back(v);
  RefreshNormalsAround(added);
  if (edit != nullptr) {
    edit->new_triangles.clear();
    for (int t : edit->rewritten) edit->new_triangles.push_back(triangles_[t]);
    edit->added_positions.assign(positions_.begin() + old_vertices, positions_.end());
    edit->added_triangles.assign(triangles_.begin() + edit->old_triangle_count, triangles_.end());
  }
  return splits;
}

TriangleMesh IcosphereMesh(double radius, int subdivisions) {
  if (!(radius > 0.0) || subdivisions < 0 || subdivisions > 9) {
    throw std::invalid_argument("IcosphereMesh: radius = " + std::to_string(radius) +
                                " (must be > 0), subdivisions = " + std::to_string(subdivisions) +
                                " (must be in [0, 9])");
  }
  const double g = (1.0 + std::sqrt(5.0)) / 2.0;
  std::vector<Eigen::Vector3d> vertices = {{-1, g, 0}, {1, g, 0}, {-1, -g, 0}, {1, -g, 0},
                                           {0, -1, g}, {0, 1, g}, {0, -1, -g}, {0, 1, -g},
                                           {g, 0, -1}, {g, 0, 1}, {-g, 0, -1}, {-g, 0, 1}};
  std::vector<Eigen::Vector3i> faces = {
      {0, 11, 5},  {0, 5, 1},  {0, 1, 7},  {0, 7, 10}, {0, 10, 11}, {1, 5, 9}, {5, 11, 4},
      {11, 10, 2}, {10, 7, 6}, {7, 1, 8},  {3, 9, 4},  {3, 4, 2},   {3, 2, 6}, {3, 6, 8},
      {3, 8, 9},   {4, 9, 5},  {2, 4, 11}, {6, 2, 10}, {8, 6, 7},   {9, 8, 1}};
  for (auto& v : vertices) v.normalize();
  for (int level = 0; level < subdivisions; ++level) {
    std::map<std::pair<int, int>, int> midpoint;
    auto Mid = [&](int a, int b) {
      const auto key = std::minmax(a, b);
      const auto [it, inserted] = midpoint.emplace(key, static_cast<int>(vertices.size()));
      if (inserted) vertices.push_back((vertices[a] + vertices[b]).normalized());
      return it->second;
    };
    std::vector<Eigen::Vector3i> finer;
    finer.reserve(4 * faces.size());
    for (const Eigen::Vector3i& f : faces) {
      const int ab = Mid(f[0], f[1]), bc = Mid(f[1], f[2]), ca = Mid(f[2], f[0]);
      finer.emplace_back(f[0], ab, ca);
      finer.emplace_back(f[1], bc, ab);
      finer.emplace_back(f[2], ca, bc);
      finer.emplace_back(ab, bc, ca);
    }
    faces.swap(finer);
  }
  TriangleMesh mesh;
  mesh.vertices.resize(3, static_cast<Eigen::Index>(vertices.size()));
  for (size_t v = 0; v < vertices.size(); ++v)
    mesh.vertices.col(static_cast<Eigen::Index>(v)) = radius * vertices[v];
  mesh.triangles.resize(3, static_cast<Eigen::Index>(faces.size()));
  for (size_t t = 0; t < faces.size(); ++t)
    mesh.triangles.col(static_cast<Eigen::Index>(t)) = faces[t];
  // The face list above is outward for this vertex order; make sure (flip all if not).
  if (MeshVolume(mesh) < 0.0) mesh.triangles.row(1).swap(mesh.triangles.row(2));
  return mesh;
}

}  // namespace spidarcad::modeling
