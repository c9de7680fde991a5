// Internal: signed distance formulas of the primitives and the blend operators, written once as
// templates over the scalar type: double (value), Dual (value and gradient, forward mode) and,
// for the branch-free ones, Interval (bounds over a box). Local frames: every primitive is
// centred at its local origin, axis along local z where it has one. Convention: < 0 inside.
// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#pragma once

#include <algorithm>
#include <cmath>

#include "spidarcad/modeling/interval.h"

namespace spidarcad::modeling::internal {

// Value with its gradient with respect to the world point (forward-mode dual number).
// Trivially constructible so that a stack of them costs nothing to declare.
struct Dual {
  double v;
  double gx, gy, gz;
};

inline Dual Constant(double v) noexcept { return {v, 0.0, 0.0, 0.0}; }
inline Dual operator+(Dual a, Dual b) noexcept {
  return {a.v + b.v, a.gx + b.gx, a.gy + b.gy, a.gz + b.gz};
}
inline Dual operator+(Dual a, double b) noexcept { return {a.v + b, a.gx, a.gy, a.gz}; }
inline Dual operator+(double a, Dual b) noexcept { return b + a; }
inline Dual operator-(Dual a) noexcept { return {-a.v, -a.gx, -a.gy, -a.gz}; }
inline Dual operator-(Dual a, Dual b) noexcept {
  return {a.v - b.v, a.gx - b.gx, a.gy - b.gy, a.gz - b.gz};
}
inline Dual operator-(Dual a, double b) noexcept { return {a.v - b, a.gx, a.gy, a.gz}; }
inline Dual operator-(double a, Dual b) noexcept { return {a - b.v, -b.gx, -b.gy, -b.gz}; }
inline Dual operator*(Dual a, double s) noexcept { return {a.v * s, a.gx * s, a.gy * s, a.gz * s}; }
inline Dual operator*(double s, Dual a) noexcept { return a * s; }
inline Dual operator*(Dual a, Dual b) noexcept {
  return {a.v * b.v, a.gx * b.v + a.v * b.gx, a.gy * b.v + a.v * b.gy, a.gz * b.v + a.v * b.gz};
}
inline Dual Abs(Dual a) noexcept { return a.v < 0.0 ? -a : a; }
inline Dual Square(Dual a) noexcept { return a * a; }
// √a; the derivative is taken as zero where a <= 0 (the field's kink, e.g. a sphere's centre).
inline Dual Sqrt(Dual a) noexcept {
  if (a.v <= 0.0) return Constant(0.0);
  const double s = std::sqrt(a.v);
  const double d = 0.5 / s;
  return {s, a.gx * d, a.gy * d, a.gz * d};
}
inline Dual Min(Dual a, Dual b) noexcept { return a.v <= b.v ? a : b; }
inline Dual Max(Dual a, Dual b) noexcept { return a.v >= b.v ? a : b; }
inline Dual Min(Dual a, double b) noexcept { return a.v <= b ? a : Constant(b); }
inline Dual Max(Dual a, double b) noexcept { return a.v >= b ? a : Constant(b); }
inline Dual Clamp(Dual a, double lo, double hi) noexcept { return Min(Max(a, lo), hi); }

inline double Abs(double a) noexcept { return std::fabs(a); }
inline double Square(double a) noexcept { return a * a; }
inline double Sqrt(double a) noexcept { return std::sqrt(std::max(a, 0.0)); }
inline double Min(double a, double b) noexcept { return std::min(a, b); }
inline double Max(double a, double b) noexcept { return std::max(a, b); }
inline double Clamp(double a, double lo, double hi) noexcept {
  return std::min(std::max(a, lo), hi);
}

// The value part of a scalar (for branch decisions).
inline double ValueOf(double a) noexcept { return a; }
inline double ValueOf(Dual a) noexcept { return a.v; }

// √(x² + y²) with a well-defined gradient (zero at the origin).
template <typename T>
T Length2(T x, T y) noexcept {
  return Sqrt(Square(x) + Square(y));
}
// √(x² + y² + z²).
template <typename T>
T Length3(T x, T y, T z) noexcept {
  return Sqrt(Square(x) + Square(y) + Square(z));
}

// Sphere of radius r. Exact distance.
template <typename T>
T SphereField(T x, T y, T z, double r) noexcept {
  return Length3(x, y, z) - r;
}

// Box with half-extents (hx, hy, hz). Exact distance.
template <typename T>
T BoxField(T x, T y, T z, double hx, double hy, double hz) noexcept {
  const T dx = Abs(x) - hx, dy = Abs(y) - hy, dz = Abs(z) - hz;
  const T outside = Length3(Max(dx, 0.0), Max(dy, 0.0), Max(dz, 0.0));
  const T inside = Min(Max(dx, Max(dy, dz)), 0.0);
  return outside + inside;
}

// Box with half-extents (hx, hy, hz) whose edges and corners are rounded with radius r
// (r <= every half-extent). Exact distance.
template <typename T>
T RoundedBoxField(T x, T y, T z, double hx, double hy, double hz, double r) noexcept {
  return BoxField(x, y, z, hx - r, hy - r, hz - r) - r;
}

// Cylinder of radius r along z, z in [-hh, hh]. Exact distance.
template <typename T>
T CylinderField(T x, T y, T z, double r, double hh) noexcept {
  const T dr = Length2(x, y) - r;
  const T dz = Abs(z) - hh;
  return Min(Max(dr, dz), 0.0) + Length2(Max(dr, 0.0), Max(dz, 0.0));
}

// Torus around z: centre circle of radius big_r in the xy plane, tube radius small_r. Exact.
template <typename T>
T TorusField(T x, T y, T z, double big_r, double small_r) noexcept {
  return Length2(Length2(x, y) - big_r, z) - small_r;
}

// Half-space n·q <= d (n unit). Exact distance.
template <typename T>
T HalfSpaceField(T x, T y, T z, double nx, double ny, double nz, double d) noexcept {
  return x * nx + y * ny + z * nz - d;
}

// Capsule: points within r of the segment a-b. inv_len2 = 1 / |b - a|² (0 for a point).
// Exact distance.
template <typename T>
T CapsuleField(T x, T y, T z, const double* a, const double* b, double r,
               double inv_len2) noexcept {
  const double bax = b[0] - a[0], bay = b[1] - a[1], baz = b[2] - a[2];
  const T pax = x - a[0], pay = y - a[1], paz = z - a[2];
  const T h = Clamp((pax * bax + pay * bay + paz * baz) * inv_len2, 0.0, 1.0);
  return Length3(pax - h * bax, pay - h * bay, paz - h * baz) - r;
}

// Squared distance from (px, py) to the segment (ax, ay)-(bx, by); also returns the vector
// from the closest point to p in (dx, dy).
template <typename T>
void SegmentOffset2(T px, T py, double ax, double ay, double bx, double by, T* dx, T* dy) noexcept {
  const double ex = bx - ax, ey = by - ay;
  const double len2 = ex * ex + ey * ey;
  const T wx = px - ax, wy = py - ay;
  if (len2 <= 0.0) {
    *dx = wx;
    *dy = wy;
    return;
  }
  const T h = Clamp((wx * ex + wy * ey) * (1.0 / len2), 0.0, 1.0);
  *dx = wx - h * ex;
  *dy = wy - h * ey;
}

// The signed distance to the line of the edge a -> b (positive on the side of its normal
// (ey, -ex), the outward one when the boundary runs counter-clockwise; `ccw` false flips it),
// when p lies within 1e-9 of the edge's length of the edge's inside (d2: the squared distance to
// the edge): the distance to the edge to rounding, with the normal for gradient. Exact distances
// built from the offset to the nearest point lose its direction on the edge to rounding, where
// Newton's steps onto a flat wall put points: their gradient came out zero or pointing inwards.
template <typename T>
bool SignedDistanceOnEdge2(T x, T y, double ax, double ay, double bx, double by, bool ccw,
                           double d2, T* out) noexcept {
  const double ex = bx - ax, ey = by - ay;
  const double len2 = ex * ex + ey * ey;
  if (!(len2 > 0.0) || !(d2 <= 1e-18 * len2)) return false;
  const double s = ((ValueOf(x) - ax) * ex + (ValueOf(y) - ay) * ey) / len2;
  if (!(s > 0.0 && s < 1.0)) return false;
  const double len = std::sqrt(len2);
  const double nx = (ccw ? ey : -ey) / len, ny = (ccw ? -ex : ex) / len;
  *out = (x - ax) * nx + (y - ay) * ny;
  return true;
}

// Frustum of a cone along z: radius r_bottom at z = -hh, r_top at z = +hh. Exact distance,
// computed in the (ρ, z) half-plane as the distance to the profile's three boundary segments.
template <typename T>
T ConeField(T x, T y, T z, double r_bottom, double r_top, double hh) noexcept {
  const T rho = Length2(x, y);
  const double seg[3][4] = {
      {0.0, -hh, r_bottom, -hh}, {r_bottom, -hh, r_top, hh}, {r_top, hh, 0.0, hh}};
  T best_x{}, best_y{};
  double best = INFINITY;
  int best_seg = 0;
  for (int i = 0; i < 3; ++i) {
    const double* s = seg[i];
    T dx, dy;
    SegmentOffset2(rho, z, s[0], s[1], s[2], s[3], &dx, &dy);
    const double d2 = ValueOf(dx) * ValueOf(dx) + ValueOf(dy) * ValueOf(dy);
    if (d2 < best) {
      best = d2;
      best_x = dx;
      best_y = dy;
      best_seg = i;
    }
  }
  // The profile runs counter-clockwise in the (ρ, z) half-plane.
  const double* s = seg[best_seg];
  T on_edge;
  if (SignedDistanceOnEdge2(rho, z, s[0], s[1], s[2], s[3], true, best, &on_edge)) return on_edge;
  const double zv = ValueOf(z);
  const double t = (zv + hh) / (2.0 * hh);
  const bool inside = std::fabs(zv) <= hh && ValueOf(rho) <= r_bottom + (r_top - r_bottom) * t;
  const T d = Length2(best_x, best_y);
  return inside ? -d : d;
}

// Whether the polygon of n vertices xy[2i], xy[2i+1] runs counter-clockwise (positive signed
// area). A constant of the profile: compiled tapes store it with the profile.
inline bool PolygonIsCounterClockwise(const double* xy, int n) noexcept {
  double area2 = 0.0;
  for (int i = 0, j = n - 1; i < n; j = i++)
    area2 += xy[2 * j] * xy[2 * i + 1] - xy[2 * i] * xy[2 * j + 1];
  return area2 > 0.0;
}

// Signed distance in the plane to a simple polygon of n vertices xy[2i], xy[2i+1] running
// counter-clockwise when `ccw` (PolygonIsCounterClockwise), else clockwise; negative inside
// (even-odd rule). Exact distance; on an edge, that of SignedDistanceOnEdge2 (the edge's outward
// normal for gradient).
template <typename T>
T PolygonField2(T x, T y, const double* xy, int n, bool ccw) noexcept {
  T best_x{}, best_y{};
  double best = INFINITY;
  int best_edge = -1;
  bool inside = false;
  const double px = ValueOf(x), py = ValueOf(y);
  for (int i = 0, j = n - 1; i < n; j = i++) {
    const double ax = xy[2 * j], ay = xy[2 * j + 1], bx = xy[2 * i], by = xy[2 * i + 1];
    T dx, dy;
    SegmentOffset2(x, y, ax, ay, bx, by, &dx, &dy);
    const double d2 = ValueOf(dx) * ValueOf(dx) + ValueOf(dy) * ValueOf(dy);
    if (d2 < best) {
      best = d2;
      best_x = dx;
      best_y = dy;
      best_edge = i;
    }
    // Even-odd crossing of the ray from p towards +x.
    if ((ay > py) != (by > py)) {
      const double cross_x = ax + (py - ay) * (bx - ax) / (by - ay);
      if (px < cross_x) inside = !inside;
    }
  }
  if (best_edge >= 0) {
    const int i = best_edge, j = i == 0 ? n - 1 : i - 1;
    T on_edge;
    if (SignedDistanceOnEdge2(x, y, xy[2 * j], xy[2 * j + 1], xy[2 * i], xy[2 * i + 1], ccw, best,
                              &on_edge))
      return on_edge;
  }
  const T d = Length2(best_x, best_y);
  return inside ? -d : d;
}

// A planar profile (polygon in local xy, counter-clockwise when `ccw`) extruded along z over
// [-hh, hh]. Exact distance.
template <typename T>
T ExtrusionField(T x, T y, T z, const double* xy, int n, bool ccw, double hh) noexcept {
  const T d2 = PolygonField2(x, y, xy, n, ccw);
  const T dz = Abs(z) - hh;
  return Min(Max(d2, dz), 0.0) + Length2(Max(d2, 0.0), Max(dz, 0.0));
}

// Quadratic polynomial smooth minimum with blend radius r >= 0 (r = 0: plain min). Its partial
// derivatives lie in [0, 1] and sum to 1, so it keeps a Lipschitz-1 bound; it lies at most r/4
// below min(a, b) and equals it where |a - b| >= r.
template <typename T>
T SmoothMin(T a, T b, double r) noexcept {
  if (r <= 0.0) return Min(a, b);
  const T h = Max(r - Abs(a - b), 0.0) * (1.0 / r);
  return Min(a, b) - h * h * (0.25 * r);
}
// Smooth maximum: -SmoothMin(-a, -b, r).
template <typename T>
T SmoothMax(T a, T b, double r) noexcept {
  return -SmoothMin(-a, -b, r);
}
// Interval versions: SmoothMin and SmoothMax are non-decreasing in both arguments, so their
// range over a box of arguments is spanned by the two corners.
inline Interval SmoothMin(Interval a, Interval b, double r) noexcept {
  return {SmoothMin(a.lo, b.lo, r), SmoothMin(a.hi, b.hi, r)};
}
inline Interval SmoothMax(Interval a, Interval b, double r) noexcept {
  return {SmoothMax(a.lo, b.lo, r), SmoothMax(a.hi, b.hi, r)};
}

}  // namespace spidarcad::modeling::internal
