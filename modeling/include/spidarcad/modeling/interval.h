// Closed intervals [lo, hi] of doubles and the interval arithmetic the implicit evaluator uses to
// bound a field over an axis-aligned box. Every operation returns an interval that contains
// every value the exact operation takes over its argument intervals (inclusion property). All
// functions are noexcept and allocate nothing.
// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#pragma once

#include <algorithm>
#include <cmath>

namespace spidarcad::modeling {

// A closed interval [lo, hi] with lo <= hi.
struct Interval {
  double lo = 0.0;
  double hi = 0.0;

  // The degenerate interval [v, v].
  static constexpr Interval Point(double v) noexcept { return {v, v}; }
  // True when v lies in [lo, hi].
  constexpr bool Contains(double v) const noexcept { return lo <= v && v <= hi; }
  // hi - lo.
  constexpr double Width() const noexcept { return hi - lo; }
};

inline Interval operator+(Interval a, Interval b) noexcept { return {a.lo + b.lo, a.hi + b.hi}; }
inline Interval operator+(Interval a, double b) noexcept { return {a.lo + b, a.hi + b}; }
inline Interval operator+(double a, Interval b) noexcept { return b + a; }
inline Interval operator-(Interval a) noexcept { return {-a.hi, -a.lo}; }
inline Interval operator-(Interval a, Interval b) noexcept { return {a.lo - b.hi, a.hi - b.lo}; }
inline Interval operator-(Interval a, double b) noexcept { return {a.lo - b, a.hi - b}; }
inline Interval operator-(double a, Interval b) noexcept { return {a - b.hi, a - b.lo}; }
inline Interval operator*(Interval a, double s) noexcept {
  return s >= 0.0 ? Interval{a.lo * s, a.hi * s} : Interval{a.hi * s, a.lo * s};
}
inline Interval operator*(double s, Interval a) noexcept { return a * s; }
inline Interval operator*(Interval a, Interval b) noexcept {
  const double p1 = a.lo * b.lo, p2 = a.lo * b.hi, p3 = a.hi * b.lo, p4 = a.hi * b.hi;
  return {std::min(std::min(p1, p2), std::min(p3, p4)),
          std::max(std::max(p1, p2), std::max(p3, p4))};
}

// Interval of |x| over a.
inline Interval Abs(Interval a) noexcept {
  if (a.lo >= 0.0) return a;
  if (a.hi <= 0.0) return -a;
  return {0.0, std::max(-a.lo, a.hi)};
}
// Interval of x² over a (tighter than a * a, which ignores that both factors are equal).
inline Interval Square(Interval a) noexcept {
  const Interval m = Abs(a);
  return {m.lo * m.lo, m.hi * m.hi};
}
// Interval of √x over a ∩ [0, ∞).
inline Interval Sqrt(Interval a) noexcept {
  return {std::sqrt(std::max(a.lo, 0.0)), std::sqrt(std::max(a.hi, 0.0))};
}
inline Interval Min(Interval a, Interval b) noexcept {
  return {std::min(a.lo, b.lo), std::min(a.hi, b.hi)};
}
inline Interval Max(Interval a, Interval b) noexcept {
  return {std::max(a.lo, b.lo), std::max(a.hi, b.hi)};
}
inline Interval Min(Interval a, double b) noexcept {
  return {std::min(a.lo, b), std::min(a.hi, b)};
}
inline Interval Max(Interval a, double b) noexcept {
  return {std::max(a.lo, b), std::max(a.hi, b)};
}
// Interval of clamp(x, lo, hi) over a (requires lo <= hi).
inline Interval Clamp(Interval a, double lo, double hi) noexcept { return Min(Max(a, lo), hi); }
// Intersection of two intervals known to share the true range (used to combine two valid bounds).
// Should rounding make the two bounds miss each other, the gap is returned instead.
inline Interval Intersect(Interval a, Interval b) noexcept {
  const double lo = std::max(a.lo, b.lo), hi = std::min(a.hi, b.hi);
  return lo <= hi ? Interval{lo, hi} : Interval{hi, lo};
}

}  // namespace spidarcad::modeling
