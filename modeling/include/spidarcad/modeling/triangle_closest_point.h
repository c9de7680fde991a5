// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
// The point of a triangle nearest a point, and which part of the triangle (a corner, an edge,
// the face) it lies on: region tests on the projections of p onto the edges (Voronoi regions
// of the corners and edges, then the face). Any frame and unit, as long as all four points
// share them. Allocation-free; used by the clay's distance grid and the surface figures.
#pragma once

#include <Eigen/Core>

namespace spidarcad::modeling {

// The part of a triangle a closest point lies on.
enum class TriangleFeature { kFace, kVertex0, kVertex1, kVertex2, kEdge01, kEdge12, kEdge20 };

// The point of triangle (a, b, c) nearest p, and the feature it lies on (region tests on the
// barycentric coordinates of p's projection, Voronoi region by region).
inline Eigen::Vector3d ClosestPointOnTriangle(const Eigen::Vector3d& p, const Eigen::Vector3d& a,
                                              const Eigen::Vector3d& b, const Eigen::Vector3d& c,
                                              TriangleFeature* feature = nullptr) {
  TriangleFeature unused;
  if (feature == nullptr) feature = &unused;
  const Eigen::Vector3d ab = b - a, ac = c - a, ap = p - a;
  const double d1 = ab.dot(ap), d2 = ac.dot(ap);
  if (d1 <= 0.0 && d2 <= 0.0) {
    *feature = TriangleFeature::kVertex0;
    return a;
  }
  const Eigen::Vector3d bp = p - b;
  const double d3 = ab.dot(bp), d4 = ac.dot(bp);
  if (d3 >= 0.0 && d4 <= d3) {
    *feature = TriangleFeature::kVertex1;
    return b;
  }
  const double vc = d1 * d4 - d3 * d2;
  if (vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0) {
    *feature = TriangleFeature::kEdge01;
    return a + (d1 / (d1 - d3)) * ab;
  }
  const Eigen::Vector3d cp = p - c;
  const double d5 = ab.dot(cp), d6 = ac.dot(cp);
  if (d6 >= 0.0 && d5 <= d6) {
    *feature = TriangleFeature::kVertex2;
    return c;
  }
  const double vb = d5 * d2 - d1 * d6;
  if (vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0) {
    *feature = TriangleFeature::kEdge20;
    return a + (d2 / (d2 - d6)) * ac;
  }
  const double va = d3 * d6 - d5 * d4;
  if (va <= 0.0 && d4 - d3 >= 0.0 && d5 - d6 >= 0.0) {
    *feature = TriangleFeature::kEdge12;
    return b + ((d4 - d3) / ((d4 - d3) + (d5 - d6))) * (c - b);
  }
  const double sum = va + vb + vc;
  if (!(sum > 0.0)) {  // a degenerate triangle: its nearest corner
    const double da = ap.squaredNorm(), db = bp.squaredNorm(), dc = cp.squaredNorm();
    if (da <= db && da <= dc) {
      *feature = TriangleFeature::kVertex0;
      return a;
    }
    *feature = db <= dc ? TriangleFeature::kVertex1 : TriangleFeature::kVertex2;
    return db <= dc ? b : c;
  }
  *feature = TriangleFeature::kFace;
  return a + (vb / sum) * ab + (vc / sum) * ac;
}

}  // namespace spidarcad::modeling
