// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
// Internal to modeling/: the triangle-triangle predicates of CheckSurface (tetgen_mesher.cc),
// shared with the surface mesher's clean-up and the sharpening pass so that what they let
// through CheckSurface will not call an intersection (same predicates, same tolerances).
#pragma once

#include <Eigen/Core>
#include <array>
#include <cmath>
#include <limits>

namespace spidarcad::modeling::internal {

// Sign of the orientation of d against the plane of (a, b, c) (six times the signed volume of
// (a, b, c, d), > 0 when d is below the counter-clockwise triangle abc), 0 when within rounding
// (1e-12 of the product of the edge lengths at d): nearly coplanar counts as coplanar.
inline int OrientSign(const Eigen::Vector3d& a, const Eigen::Vector3d& b, const Eigen::Vector3d& c,
                      const Eigen::Vector3d& d) {
  const Eigen::Vector3d ad = a - d, bd = b - d, cd = c - d;
  const double v = ad.dot(bd.cross(cd));
  // The test below without its three square roots: squares compared with a margin (1e-6,
  // relative) far above their rounding (a few 1e-16), so where this decides, the test with the
  // square roots decides the same; only within the margin is it run as it stands.
  const double tolerance2 = 1e-24 * (ad.squaredNorm() * bd.squaredNorm() * cd.squaredNorm());
  if (tolerance2 > 1e-280 && tolerance2 < 1e280) {  // far from underflow and overflow
    const double v2 = v * v;
    if (v2 > tolerance2 * (1.0 + 1e-6)) return v > 0 ? 1 : -1;
    if (v2 < tolerance2 * (1.0 - 1e-6)) return 0;
  }
  const double scale = ad.norm() * bd.norm() * cd.norm();
  if (std::abs(v) <= 1e-12 * scale) return 0;
  return v > 0 ? 1 : -1;
}

// Whether point t, in the plane of triangle abc, lies in the closed triangle (within rounding).
inline bool PointInTriangle(const Eigen::Vector3d& t, const Eigen::Vector3d& a,
                            const Eigen::Vector3d& b, const Eigen::Vector3d& c) {
  const Eigen::Vector3d n = (b - a).cross(c - a);
  const Eigen::Vector3d corner[3] = {a, b, c};
  for (int k = 0; k < 3; ++k) {
    const Eigen::Vector3d& u = corner[k];
    const Eigen::Vector3d& v = corner[(k + 1) % 3];
    if (n.dot((v - u).cross(t - u)) < -1e-12 * n.norm() * (v - u).norm() * (t - u).norm())
      return false;
  }
  return true;
}

// Whether segment pq meets triangle abc (touching counts). A segment lying in (or within
// rounding of) the triangle's plane is reported as not meeting it: coplanar contacts are not
// detected here (TetGen reports them, and its error is caught).
// sp and sq: OrientSign(a, b, c, p) and OrientSign(a, b, c, q).
inline bool SegmentMeetsTriangle(const Eigen::Vector3d& p, const Eigen::Vector3d& q,
                                 const Eigen::Vector3d& a, const Eigen::Vector3d& b,
                                 const Eigen::Vector3d& c, int sp, int sq) {
  if (sp == sq) return false;  // same side, or both in the plane
  // One endpoint in the plane: they meet iff that endpoint lies in the (closed) triangle.
  if (sp == 0) return PointInTriangle(p, a, b, c);
  if (sq == 0) return PointInTriangle(q, a, b, c);
  const int s1 = OrientSign(p, q, a, b), s2 = OrientSign(p, q, b, c), s3 = OrientSign(p, q, c, a);
  const bool has_pos = s1 > 0 || s2 > 0 || s3 > 0, has_neg = s1 < 0 || s2 < 0 || s3 < 0;
  return !(has_pos && has_neg) && (has_pos || has_neg);
}
inline bool SegmentMeetsTriangle(const Eigen::Vector3d& p, const Eigen::Vector3d& q,
                                 const Eigen::Vector3d& a, const Eigen::Vector3d& b,
                                 const Eigen::Vector3d& c) {
  return SegmentMeetsTriangle(p, q, a, b, c, OrientSign(a, b, c, p), OrientSign(a, b, c, q));
}

// Two triangles sharing an edge, a (corners pa, fa the one off the edge) and b (q its corner off
// the edge): folded when q lies in a's plane on the same side of the shared edge as a's corner.
inline bool FoldedOnSharedEdge(const std::array<Eigen::Vector3d, 3>& pa, int fa,
                               const Eigen::Vector3d& q) {
  const Eigen::Vector3d e0 = pa[(fa + 1) % 3], e1 = pa[(fa + 2) % 3];
  const Eigen::Vector3d n = (e1 - e0).cross(pa[fa] - e0);
  if (std::abs(n.dot(q - e0)) > 1e-12 * n.norm() * (q - e0).norm()) return false;
  const Eigen::Vector3d edge = e1 - e0;
  return edge.cross(pa[fa] - e0).dot(edge.cross(q - e0)) > 0;
}

// Whether triangles a and b (vertex indices ia, ib; corner positions pa, pb) meet other than
// along what they share: a duplicated triangle, a shared edge with the two folded onto each
// other, a shared vertex with an opposite edge through the other triangle, or disjoint
// triangles crossing.
inline bool TrianglesMeet(const std::array<int, 3>& ia, const std::array<Eigen::Vector3d, 3>& pa,
                          const std::array<int, 3>& ib, const std::array<Eigen::Vector3d, 3>& pb) {
  auto in = [](const std::array<int, 3>& t, int v) { return t[0] == v || t[1] == v || t[2] == v; };
  int shared = 0;
  for (int v : ia) shared += in(ib, v);
  if (shared >= 3) return true;
  if (shared == 2) {
    // Folded: the unshared vertex of b in a's plane, on the same side of the shared edge as
    // a's unshared vertex.
    int fa = 0, gb = 0;
    while (in(ib, ia[fa])) ++fa;
    while (in(ia, ib[gb])) ++gb;
    return FoldedOnSharedEdge(pa, fa, pb[gb]);
  }
  if (shared == 1) {
    // Away from the shared vertex, only the opposite edges can cross the other triangle.
    int ea[2], eb[2], na = 0, nb = 0;
    for (int k = 0; k < 3; ++k) {
      if (!in(ib, ia[k])) ea[na++] = k;
      if (!in(ia, ib[k])) eb[nb++] = k;
    }
    return SegmentMeetsTriangle(pa[ea[0]], pa[ea[1]], pb[0], pb[1], pb[2]) ||
           SegmentMeetsTriangle(pb[eb[0]], pb[eb[1]], pa[0], pa[1], pa[2]);
  }
  // Disjoint: every edge of each against the other triangle (SegmentMeetsTriangle, with the
  // sides of each corner against the other's plane computed once: each is asked twice).
  int side_a[3], side_b[3];
  for (int k = 0; k < 3; ++k) {
    side_a[k] = OrientSign(pb[0], pb[1], pb[2], pa[k]);
    side_b[k] = OrientSign(pa[0], pa[1], pa[2], pb[k]);
  }
  for (int k = 0; k < 3; ++k) {
    const int l = (k + 1) % 3;
    if (SegmentMeetsTriangle(pa[k], pa[l], pb[0], pb[1], pb[2], side_a[k], side_a[l])) return true;
    if (SegmentMeetsTriangle(pb[k], pb[l], pa[0], pa[1], pa[2], side_b[k], side_b[l])) return true;
  }
  return false;
}

// TrianglesMeet(ia, pa, ib, pb), the same answer with fewer determinants: the side of a corner
// of one triangle against the other's plane (OrientSign) is read from that plane's normal where
// it is clear by far, and only computed by OrientSign where it is not. na and nb: the normals
// (pa[1] - pa[0]).cross(pa[2] - pa[0]) and the same of pb; diagonal2: the squared diagonal of a
// box holding all six corners (so it bounds every distance between them). With w = n · (p -
// corner 0), (w² > 1e-22 diagonal2³) clears by far both the rounding of w and of OrientSign's
// determinant (each within about 1e-14 diagonal³ of the exact value, which is -w's) and
// OrientSign's tolerance (at most 1e-12 diagonal³), so OrientSign gives -sign(w) there; and
// for two triangles sharing an edge, the fold test (whose normal is the same exact normal)
// says false when the unshared corner is that clear of the plane.
inline bool TrianglesMeet(const std::array<int, 3>& ia, const std::array<Eigen::Vector3d, 3>& pa,
                          const Eigen::Vector3d& na, const std::array<int, 3>& ib,
                          const std::array<Eigen::Vector3d, 3>& pb, const Eigen::Vector3d& nb,
                          double diagonal2) {
  auto in = [](const std::array<int, 3>& t, int v) { return t[0] == v || t[1] == v || t[2] == v; };
  int shared = 0;
  for (int v : ia) shared += in(ib, v);
  if (shared >= 3) return true;
  // Far from underflow and overflow (and not NaN), where the bounds above hold; elsewhere no
  // side is read from the normals.
  const double threshold2 = diagonal2 > 1e-60 && diagonal2 < 1e60
                                ? 1e-22 * diagonal2 * diagonal2 * diagonal2
                                : std::numeric_limits<double>::infinity();
  // OrientSign(t[0], t[1], t[2], p) for triangle t of normal n: from the normal where clear
  // (a small function, inlined), else OrientSign.
  auto clear_side = [threshold2](const Eigen::Vector3d& n, const Eigen::Vector3d& base,
                                 const Eigen::Vector3d& p) {
    const double w = n.dot(p - base);
    return w * w > threshold2 ? (w > 0.0 ? -1 : 1) : 0;
  };
  auto side = [&clear_side](const std::array<Eigen::Vector3d, 3>& t, const Eigen::Vector3d& n,
                            const Eigen::Vector3d& p) {
    const int s = clear_side(n, t[0], p);
    return s != 0 ? s : OrientSign(t[0], t[1], t[2], p);
  };
  if (shared == 2) {
    int fa = 0, gb = 0;
    while (in(ib, ia[fa])) ++fa;
    while (in(ia, ib[gb])) ++gb;
    const double w = na.dot(pb[gb] - pa[0]);
    if (w * w > threshold2) return false;  // clear of a's plane: not folded
    return FoldedOnSharedEdge(pa, fa, pb[gb]);
  }
  if (shared == 1) {
    int ea[2], eb[2], na_count = 0, nb_count = 0;
    for (int k = 0; k < 3; ++k) {
      if (!in(ib, ia[k])) ea[na_count++] = k;
      if (!in(ia, ib[k])) eb[nb_count++] = k;
    }
    const Eigen::Vector3d &p = pa[ea[0]], &q = pa[ea[1]], &r = pb[eb[0]], &s = pb[eb[1]];
    // Most often all four are clear, each pair on one side: no segment meets.
    const int sp = clear_side(nb, pb[0], p), sq = clear_side(nb, pb[0], q);
    const int sr = clear_side(na, pa[0], r), ss = clear_side(na, pa[0], s);
    if (sp != 0 && sp == sq && sr != 0 && sr == ss) return false;
    return SegmentMeetsTriangle(p, q, pb[0], pb[1], pb[2], sp != 0 ? sp : side(pb, nb, p),
                                sq != 0 ? sq : side(pb, nb, q)) ||
           SegmentMeetsTriangle(r, s, pa[0], pa[1], pa[2], sr != 0 ? sr : side(pa, na, r),
                                ss != 0 ? ss : side(pa, na, s));
  }
  int side_a[3], side_b[3];
  for (int k = 0; k < 3; ++k) {
    side_a[k] = side(pb, nb, pa[k]);
    side_b[k] = side(pa, na, pb[k]);
  }
  for (int k = 0; k < 3; ++k) {
    const int l = (k + 1) % 3;
    if (SegmentMeetsTriangle(pa[k], pa[l], pb[0], pb[1], pb[2], side_a[k], side_a[l])) return true;
    if (SegmentMeetsTriangle(pb[k], pb[l], pa[0], pa[1], pa[2], side_b[k], side_b[l])) return true;
  }
  return false;
}

}  // namespace spidarcad::modeling::internal
