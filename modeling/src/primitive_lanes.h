// Internal: the scalar types of primitives.h widened to W points at once (structure of arrays),
// so that the same templates (SphereField, BoxField, SmoothMin, ...) and the same tape loop
// evaluate W points per pass. Lanes<W> stands for double (values), DualLanes<W> for Dual (value
// and gradient). Every operation is the scalar one applied lane by lane, in the same order and
// with the same selections (ties, signed zeros and NaN included), so each lane's result is
// bit-identical to the scalar evaluation of its point. The loops have a fixed trip count W and
// no branches (selections are written as conditional expressions), which GCC vectorizes at -O2
// for the baseline x86-64 target (SSE2: two doubles per register). Bit-identity needs the
// scalar and the lane arithmetic to round alike: no fused multiply-add in either, which the
// evaluator's source guarantees with -ffp-contract=off (modeling/CMakeLists.txt).
// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#pragma once

#include <algorithm>
#include <cmath>

#include "primitives.h"

namespace spidarcad::modeling::internal {

// W doubles: one per point.
template <int W>
struct Lanes {
  double v[W];
};

// W duals: value and gradient (world frame) per point.
template <int W>
struct DualLanes {
  double v[W];
  double gx[W], gy[W], gz[W];
};

// ---- Lanes<W>: the double operations of primitives.h, lane by lane.

template <int W>
inline Lanes<W> Broadcast(double a) noexcept {
  Lanes<W> r;
  for (int i = 0; i < W; ++i) r.v[i] = a;
  return r;
}
template <int W>
inline Lanes<W> operator+(const Lanes<W>& a, const Lanes<W>& b) noexcept {
  Lanes<W> r;
  for (int i = 0; i < W; ++i) r.v[i] = a.v[i] + b.v[i];
  return r;
}
template <int W>
inline Lanes<W> operator+(const Lanes<W>& a, double b) noexcept {
  Lanes<W> r;
  for (int i = 0; i < W; ++i) r.v[i] = a.v[i] + b;
  return r;
}
template <int W>
inline Lanes<W> operator-(const Lanes<W>& a) noexcept {
  Lanes<W> r;
  for (int i = 0; i < W; ++i) r.v[i] = -a.v[i];
  return r;
}
template <int W>
inline Lanes<W> operator-(const Lanes<W>& a, const Lanes<W>& b) noexcept {
  Lanes<W> r;
  for (int i = 0; i < W; ++i) r.v[i] = a.v[i] - b.v[i];
  return r;
}
template <int W>
inline Lanes<W> operator-(const Lanes<W>& a, double b) noexcept {
  Lanes<W> r;
  for (int i = 0; i < W; ++i) r.v[i] = a.v[i] - b;
  return r;
}
template <int W>
inline Lanes<W> operator-(double a, const Lanes<W>& b) noexcept {
  Lanes<W> r;
  for (int i = 0; i < W; ++i) r.v[i] = a - b.v[i];
  return r;
}
template <int W>
inline Lanes<W> operator*(const Lanes<W>& a, const Lanes<W>& b) noexcept {
  Lanes<W> r;
  for (int i = 0; i < W; ++i) r.v[i] = a.v[i] * b.v[i];
  return r;
}
template <int W>
inline Lanes<W> operator*(const Lanes<W>& a, double s) noexcept {
  Lanes<W> r;
  for (int i = 0; i < W; ++i) r.v[i] = a.v[i] * s;
  return r;
}
template <int W>
inline Lanes<W> operator*(double s, const Lanes<W>& a) noexcept {
  Lanes<W> r;
  for (int i = 0; i < W; ++i) r.v[i] = s * a.v[i];
  return r;
}
template <int W>
inline Lanes<W> Abs(const Lanes<W>& a) noexcept {
  Lanes<W> r;
  for (int i = 0; i < W; ++i) r.v[i] = std::fabs(a.v[i]);
  return r;
}
template <int W>
inline Lanes<W> Square(const Lanes<W>& a) noexcept {
  return a * a;
}
// As Sqrt(double): √max(a, 0) (std::max(a, 0.0) is a < 0 ? 0 : a, NaN passes through).
template <int W>
inline Lanes<W> Sqrt(const Lanes<W>& a) noexcept {
  Lanes<W> r;
  for (int i = 0; i < W; ++i) r.v[i] = std::sqrt(a.v[i] < 0.0 ? 0.0 : a.v[i]);
  return r;
}
// std::min(a, b) is b < a ? b : a; std::max(a, b) is a < b ? b : a.
template <int W>
inline Lanes<W> Min(const Lanes<W>& a, const Lanes<W>& b) noexcept {
  Lanes<W> r;
  for (int i = 0; i < W; ++i) r.v[i] = b.v[i] < a.v[i] ? b.v[i] : a.v[i];
  return r;
}
template <int W>
inline Lanes<W> Max(const Lanes<W>& a, const Lanes<W>& b) noexcept {
  Lanes<W> r;
  for (int i = 0; i < W; ++i) r.v[i] = a.v[i] < b.v[i] ? b.v[i] : a.v[i];
  return r;
}
template <int W>
inline Lanes<W> Min(const Lanes<W>& a, double b) noexcept {
  Lanes<W> r;
  for (int i = 0; i < W; ++i) r.v[i] = b < a.v[i] ? b : a.v[i];
  return r;
}
template <int W>
inline Lanes<W> Max(const Lanes<W>& a, double b) noexcept {
  Lanes<W> r;
  for (int i = 0; i < W; ++i) r.v[i] = a.v[i] < b ? b : a.v[i];
  return r;
}
template <int W>
inline Lanes<W> Clamp(const Lanes<W>& a, double lo, double hi) noexcept {
  return Min(Max(a, lo), hi);
}

// ---- DualLanes<W>: the Dual operations of primitives.h, lane by lane.

template <int W>
inline DualLanes<W> ConstantLanes(double a) noexcept {
  DualLanes<W> r;
  for (int i = 0; i < W; ++i) {
    r.v[i] = a;
    r.gx[i] = 0.0;
    r.gy[i] = 0.0;
    r.gz[i] = 0.0;
  }
  return r;
}
template <int W>
inline DualLanes<W> operator+(const DualLanes<W>& a, const DualLanes<W>& b) noexcept {
  DualLanes<W> r;
  for (int i = 0; i < W; ++i) {
    r.v[i] = a.v[i] + b.v[i];
    r.gx[i] = a.gx[i] + b.gx[i];
    r.gy[i] = a.gy[i] + b.gy[i];
    r.gz[i] = a.gz[i] + b.gz[i];
  }
  return r;
}
template <int W>
inline DualLanes<W> operator+(const DualLanes<W>& a, double b) noexcept {
  DualLanes<W> r = a;
  for (int i = 0; i < W; ++i) r.v[i] = a.v[i] + b;
  return r;
}
template <int W>
inline DualLanes<W> operator-(const DualLanes<W>& a) noexcept {
  DualLanes<W> r;
  for (int i = 0; i < W; ++i) {
    r.v[i] = -a.v[i];
    r.gx[i] = -a.gx[i];
    r.gy[i] = -a.gy[i];
    r.gz[i] = -a.gz[i];
  }
  return r;
}
template <int W>
inline DualLanes<W> operator-(const DualLanes<W>& a, const DualLanes<W>& b) noexcept {
  DualLanes<W> r;
  for (int i = 0; i < W; ++i) {
    r.v[i] = a.v[i] - b.v[i];
    r.gx[i] = a.gx[i] - b.gx[i];
    r.gy[i] = a.gy[i] - b.gy[i];
    r.gz[i] = a.gz[i] - b.gz[i];
  }
  return r;
}
template <int W>
inline DualLanes<W> operator-(const DualLanes<W>& a, double b) noexcept {
  DualLanes<W> r = a;
  for (int i = 0; i < W; ++i) r.v[i] = a.v[i] - b;
  return r;
}
template <int W>
inline DualLanes<W> operator-(double a, const DualLanes<W>& b) noexcept {
  DualLanes<W> r;
  for (int i = 0; i < W; ++i) {
    r.v[i] = a - b.v[i];
    r.gx[i] = -b.gx[i];
    r.gy[i] = -b.gy[i];
    r.gz[i] = -b.gz[i];
  }
  return r;
}
template <int W>
inline DualLanes<W> operator*(const DualLanes<W>& a, double s) noexcept {
  DualLanes<W> r;
  for (int i = 0; i < W; ++i) {
    r.v[i] = a.v[i] * s;
    r.gx[i] = a.gx[i] * s;
    r.gy[i] = a.gy[i] * s;
    r.gz[i] = a.gz[i] * s;
  }
  return r;
}
template <int W>
inline DualLanes<W> operator*(double s, const DualLanes<W>& a) noexcept {
  return a * s;
}
template <int W>
inline DualLanes<W> operator*(const DualLanes<W>& a, const DualLanes<W>& b) noexcept {
  DualLanes<W> r;
  for (int i = 0; i < W; ++i) {
    r.v[i] = a.v[i] * b.v[i];
    r.gx[i] = a.gx[i] * b.v[i] + a.v[i] * b.gx[i];
    r.gy[i] = a.gy[i] * b.v[i] + a.v[i] * b.gy[i];
    r.gz[i] = a.gz[i] * b.v[i] + a.v[i] * b.gz[i];
  }
  return r;
}
// As Abs(Dual): a.v < 0 ? −a : a.
template <int W>
inline DualLanes<W> Abs(const DualLanes<W>& a) noexcept {
  DualLanes<W> r;
  for (int i = 0; i < W; ++i) {
    const bool negative = a.v[i] < 0.0;
    r.v[i] = negative ? -a.v[i] : a.v[i];
    r.gx[i] = negative ? -a.gx[i] : a.gx[i];
    r.gy[i] = negative ? -a.gy[i] : a.gy[i];
    r.gz[i] = negative ? -a.gz[i] : a.gz[i];
  }
  return r;
}
template <int W>
inline DualLanes<W> Square(const DualLanes<W>& a) noexcept {
  return a * a;
}
// As Sqrt(Dual): zero (value and gradient) where a.v <= 0, else √a.v with gradient g·0.5/√a.v.
// The root is taken of 1 in the lanes that are zeroed, so no lane raises an invalid operation.
template <int W>
inline DualLanes<W> Sqrt(const DualLanes<W>& a) noexcept {
  // Separate loops, each simple enough for GCC's if-conversion and vectorizer at -O2.
  double s[W], d[W];
  for (int i = 0; i < W; ++i) s[i] = a.v[i] <= 0.0 ? 1.0 : a.v[i];
  for (int i = 0; i < W; ++i) s[i] = std::sqrt(s[i]);
  for (int i = 0; i < W; ++i) d[i] = 0.5 / s[i];
  DualLanes<W> r;
  for (int i = 0; i < W; ++i) r.v[i] = a.v[i] <= 0.0 ? 0.0 : s[i];
  // The products are taken in every lane, then selected (a conditional product would be a
  // branch: GCC does not speculate a multiplication that may raise a floating-point flag).
  for (int i = 0; i < W; ++i) r.gx[i] = a.gx[i] * d[i];
  for (int i = 0; i < W; ++i) r.gy[i] = a.gy[i] * d[i];
  for (int i = 0; i < W; ++i) r.gz[i] = a.gz[i] * d[i];
  for (int i = 0; i < W; ++i) r.gx[i] = a.v[i] <= 0.0 ? 0.0 : r.gx[i];
  for (int i = 0; i < W; ++i) r.gy[i] = a.v[i] <= 0.0 ? 0.0 : r.gy[i];
  for (int i = 0; i < W; ++i) r.gz[i] = a.v[i] <= 0.0 ? 0.0 : r.gz[i];
  return r;
}
// As Min(Dual, Dual): a where a.v <= b.v, else b. Max: a where a.v >= b.v, else b.
template <int W>
inline DualLanes<W> Min(const DualLanes<W>& a, const DualLanes<W>& b) noexcept {
  DualLanes<W> r;
  for (int i = 0; i < W; ++i) {
    const bool first = a.v[i] <= b.v[i];
    r.v[i] = first ? a.v[i] : b.v[i];
    r.gx[i] = first ? a.gx[i] : b.gx[i];
    r.gy[i] = first ? a.gy[i] : b.gy[i];
    r.gz[i] = first ? a.gz[i] : b.gz[i];
  }
  return r;
}
template <int W>
inline DualLanes<W> Max(const DualLanes<W>& a, const DualLanes<W>& b) noexcept {
  DualLanes<W> r;
  for (int i = 0; i < W; ++i) {
    const bool first = a.v[i] >= b.v[i];
    r.v[i] = first ? a.v[i] : b.v[i];
    r.gx[i] = first ? a.gx[i] : b.gx[i];
    r.gy[i] = first ? a.gy[i] : b.gy[i];
    r.gz[i] = first ? a.gz[i] : b.gz[i];
  }
  return r;
}
// As Min(Dual, double): a where a.v <= b, else the constant b. Max likewise with >=.
template <int W>
inline DualLanes<W> Min(const DualLanes<W>& a, double b) noexcept {
  DualLanes<W> r;
  for (int i = 0; i < W; ++i) {
    const bool first = a.v[i] <= b;
    r.v[i] = first ? a.v[i] : b;
    r.gx[i] = first ? a.gx[i] : 0.0;
    r.gy[i] = first ? a.gy[i] : 0.0;
    r.gz[i] = first ? a.gz[i] : 0.0;
  }
  return r;
}
template <int W>
inline DualLanes<W> Max(const DualLanes<W>& a, double b) noexcept {
  DualLanes<W> r;
  for (int i = 0; i < W; ++i) {
    const bool first = a.v[i] >= b;
    r.v[i] = first ? a.v[i] : b;
    r.gx[i] = first ? a.gx[i] : 0.0;
    r.gy[i] = first ? a.gy[i] : 0.0;
    r.gz[i] = first ? a.gz[i] : 0.0;
  }
  return r;
}
template <int W>
inline DualLanes<W> Clamp(const DualLanes<W>& a, double lo, double hi) noexcept {
  return Min(Max(a, lo), hi);
}

// One lane of a DualLanes as a Dual, and back.
template <int W>
inline Dual LaneOf(const DualLanes<W>& a, int i) noexcept {
  return {a.v[i], a.gx[i], a.gy[i], a.gz[i]};
}
template <int W>
inline void SetLane(DualLanes<W>* a, int i, const Dual& d) noexcept {
  a->v[i] = d.v;
  a->gx[i] = d.gx;
  a->gy[i] = d.gy;
  a->gz[i] = d.gz;
}

}  // namespace spidarcad::modeling::internal
