// The boundary faces of a tetrahedral mesh, found once for both meshes the project holds
// (modeling::TetMesh, fem::TetMesh): a face is on the boundary when its sorted corner triple
// occurs once among the 4 faces of every tetrahedron.
// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#pragma once

#include <algorithm>
#include <array>
#include <cstddef>
#include <numeric>
#include <vector>

namespace spidarcad::base {

// Indices (into `keys`) of the keys that occur exactly once, in increasing key order. keys[i] is
// face i's corner triple, sorted; with 4 faces per tetrahedron, face i is face i % 4 of
// tetrahedron i / 4. A sort of the indices, not a map (4·#tets faces, 10⁵–10⁶).
inline std::vector<std::size_t> FacesSeenOnce(const std::vector<std::array<int, 3>>& keys) {
  std::vector<std::size_t> order(keys.size());
  std::iota(order.begin(), order.end(), std::size_t{0});
  std::sort(order.begin(), order.end(),
            [&keys](std::size_t a, std::size_t b) { return keys[a] < keys[b]; });
  std::vector<std::size_t> once;
  for (std::size_t i = 0; i < order.size();) {
    std::size_t j = i + 1;
    while (j < order.size() && keys[order[j]] == keys[order[i]]) ++j;
    if (j == i + 1) once.push_back(order[i]);
    i = j;
  }
  return once;
}

}  // namespace spidarcad::base
