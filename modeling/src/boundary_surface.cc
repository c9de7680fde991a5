// BoundarySurface (declared in cgal_mesher.h beside the CGAL path it was written for): it needs
// no CGAL, so it lives in a file of its own, which builds that link no mesher (the document fuzz
// harness, tests/fuzz/CMakeLists.txt) can take alone.
// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#include <algorithm>
#include <array>
#include <map>
#include <utility>
#include <vector>

#include "spidarcad/modeling/cgal_mesher.h"

namespace spidarcad::modeling {

TriangleMesh BoundarySurface(const TetMesh& mesh) {
  // Outward faces of a positive tet (0, 1, 2, 3): the face opposite corner c, listed so that its
  // right-hand normal points away from c.
  static constexpr int kFaces[4][3] = {{1, 2, 3}, {0, 3, 2}, {0, 1, 3}, {0, 2, 1}};
  std::map<std::array<int, 3>, std::pair<int, std::array<int, 3>>>
      faces;  // sorted -> (count, oriented)
  for (Eigen::Index t = 0; t < mesh.tets.cols(); ++t) {
    for (const auto& f : kFaces) {
      const std::array<int, 3> oriented = {mesh.tets(f[0], t), mesh.tets(f[1], t),
                                           mesh.tets(f[2], t)};
      std::array<int, 3> sorted = oriented;
      std::sort(sorted.begin(), sorted.end());
      auto [it, inserted] = faces.emplace(sorted, std::make_pair(1, oriented));
      if (!inserted) ++it->second.first;
    }
  }
  std::vector<int> new_index(static_cast<size_t>(mesh.nodes.cols()), -1);
  long count = 0;
  for (const auto& [key, value] : faces) {
    if (value.first != 1) continue;
    ++count;
    for (const int v : key) new_index[v] = 0;
  }
  int vertices = 0;
  for (int& i : new_index) {
    if (i == 0) i = vertices++;
  }
  TriangleMesh surface;
  surface.vertices.resize(3, vertices);
  for (Eigen::Index v = 0; v < mesh.nodes.cols(); ++v) {
    if (new_index[v] >= 0) surface.vertices.col(new_index[v]) = mesh.nodes.col(v);
  }
  surface.triangles.resize(3, count);
  Eigen::Index c = 0;
  for (const auto& [key, value] : faces) {
    if (value.first != 1) continue;
    surface.triangles.col(c++) << new_index[value.second[0]], new_index[value.second[1]],
        new_index[value.second[2]];
  }
  return surface;
}

}  // namespace spidarcad::modeling
