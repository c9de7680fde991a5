// The faces of a tetrahedral mesh as BoundarySurface and SmoothSlivers take them: the outward
// corner order of each face and every face's sorted corner triple (for base::FacesSeenOnce).
// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#pragma once

#include <algorithm>
#include <array>
#include <vector>

#include "spidarcad/modeling/tet_mesh.h"

namespace spidarcad::modeling::internal {

// Outward faces of a positive tet (0, 1, 2, 3): the face opposite corner c, listed so that its
// right-hand normal points away from c.
inline constexpr int kTetOutwardFaces[4][3] = {{1, 2, 3}, {0, 3, 2}, {0, 1, 3}, {0, 2, 1}};

// Sorted corner triples of every face: entry i is face i % 4 (kTetOutwardFaces) of tet i / 4.
inline std::vector<std::array<int, 3>> TetFaceKeys(const TetMesh& mesh) {
  std::vector<std::array<int, 3>> keys;
  keys.reserve(4 * static_cast<size_t>(mesh.tets.cols()));
  for (Eigen::Index t = 0; t < mesh.tets.cols(); ++t) {
    for (const auto& f : kTetOutwardFaces) {
      std::array<int, 3> key = {mesh.tets(f[0], t), mesh.tets(f[1], t), mesh.tets(f[2], t)};
      std::sort(key.begin(), key.end());
      keys.push_back(key);
    }
  }
  return keys;
}

}  // namespace spidarcad::modeling::internal
