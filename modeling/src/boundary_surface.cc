// BoundarySurface (declared in cgal_mesher.h beside the CGAL path it was written for): it needs
// no CGAL, so it lives in a file of its own, which builds that link no mesher (the document fuzz
// harness, tests/fuzz/CMakeLists.txt) can take alone.
// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#include <algorithm>
#include <array>
#include <utility>
#include <vector>

#include "spidarcad/base/faces_seen_once.h"
#include "spidarcad/modeling/cgal_mesher.h"
#include "tet_faces.h"

namespace spidarcad::modeling {

TriangleMesh BoundarySurface(const TetMesh& mesh) {
  const std::vector<std::array<int, 3>> keys = internal::TetFaceKeys(mesh);
  const std::vector<std::size_t> boundary = base::FacesSeenOnce(keys);
  // Face i of the list: face i % 4 of tet i / 4, oriented outward.
  const auto corner = [&](std::size_t i, int k) {
    return mesh.tets(internal::kTetOutwardFaces[i % 4][k], static_cast<Eigen::Index>(i / 4));
  };
  std::vector<int> new_index(static_cast<size_t>(mesh.nodes.cols()), -1);
  const long count = static_cast<long>(boundary.size());
  for (const std::size_t i : boundary)
    for (const int v : keys[i]) new_index[v] = 0;
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
  for (const std::size_t i : boundary)
    surface.triangles.col(c++) << new_index[corner(i, 0)], new_index[corner(i, 1)],
        new_index[corner(i, 2)];
  return surface;
}

}  // namespace spidarcad::modeling
