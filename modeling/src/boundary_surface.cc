// BoundarySurface (declared in cgal_mesher.h beside the CGAL path it was written for): it needs
// no CGAL, so it lives in a file of its own, which builds that link no mesher (the document fuzz
// harness, tests/fuzz/CMakeLists.txt) can take alone.
// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#include <algorithm>
#include <array>
#include <utility>
#include <vector>

#include "spidarcad/modeling/cgal_mesher.h"

namespace spidarcad::modeling {

TriangleMesh BoundarySurface(const TetMesh& mesh) {
  // Outward faces of a positive tet (0, 1, 2, 3): the face opposite corner c, listed so that its
  // right-hand normal points away from c.
  static constexpr int kFaces[4][3] = {{1, 2, 3}, {0, 3, 2}, {0, 1, 3}, {0, 2, 1}};
  // Every face with its sorted corners as key, sorted by key (a sort, not a map: 4·#tets faces);
  // a key that occurs once is a boundary face. Faces come out in key order.
  struct Face {
    std::array<int, 3> key, oriented;
  };
  std::vector<Face> all;
  all.reserve(4 * static_cast<size_t>(mesh.tets.cols()));
  for (Eigen::Index t = 0; t < mesh.tets.cols(); ++t) {
    for (const auto& f : kFaces) {
      Face face;
      face.oriented = {mesh.tets(f[0], t), mesh.tets(f[1], t), mesh.tets(f[2], t)};
      face.key = face.oriented;
      std::sort(face.key.begin(), face.key.end());
      all.push_back(face);
    }
  }
  std::sort(all.begin(), all.end(), [](const Face& a, const Face& b) { return a.key < b.key; });
  std::vector<const Face*> boundary;
  for (size_t i = 0; i < all.size();) {
    size_t j = i + 1;
    while (j < all.size() && all[j].key == all[i].key) ++j;
    if (j == i + 1) boundary.push_back(&all[i]);
    i = j;
  }
  std::vector<int> new_index(static_cast<size_t>(mesh.nodes.cols()), -1);
  const long count = static_cast<long>(boundary.size());
  for (const Face* f : boundary)
    for (const int v : f->key) new_index[v] = 0;
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
  for (const Face* f : boundary)
    surface.triangles.col(c++) << new_index[f->oriented[0]], new_index[f->oriented[1]],
        new_index[f->oriented[2]];
  return surface;
}

}  // namespace spidarcad::modeling
