// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
// Computations of the sculpt tests' own (tests/app/run_sculpt_test.cc, scripted_run_test.cc),
// independent of the sculpt code. Header-only: tests/app globs only *_test.cc files.
#pragma once

#include <Eigen/Core>

#include "spidarcad/modeling/surface_mesher.h"

namespace spidarcad::test_support {

// Enclosed volume of a closed, outward-oriented triangle mesh by the divergence theorem (m³).
inline double EnclosedVolume(const modeling::TriangleMesh& m) {
  double v = 0.0;
  for (Eigen::Index t = 0; t < m.triangles.cols(); ++t) {
    const Eigen::Vector3d a = m.vertices.col(m.triangles(0, t));
    const Eigen::Vector3d b = m.vertices.col(m.triangles(1, t));
    const Eigen::Vector3d c = m.vertices.col(m.triangles(2, t));
    v += a.dot(b.cross(c)) / 6.0;
  }
  return v;
}

}  // namespace spidarcad::test_support
