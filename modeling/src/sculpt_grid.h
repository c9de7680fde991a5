// Cell coordinates of SculptMesh's uniform vertex grid (sculpt.cc; the self-intersection check
// of sculpt_intersection.cc queries it): 21 bits per axis, offset so that negative cells fit,
// packed into one 63-bit key.
// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>

namespace spidarcad::modeling::sculpt_grid {

constexpr std::int64_t kCellOffset = std::int64_t{1} << 20;
constexpr std::int64_t kCellMask = (std::int64_t{1} << 21) - 1;

// Cell index of coordinate x (m) in cells of edge h (m), clamped to the packable range.
inline std::int64_t CellOf(double x, double h) {
  return std::clamp<std::int64_t>(static_cast<std::int64_t>(std::floor(x / h)) + kCellOffset, 0,
                                  kCellMask);
}

// The key of cell (x, y, z).
inline std::uint64_t Pack(std::int64_t x, std::int64_t y, std::int64_t z) {
  return static_cast<std::uint64_t>(x) << 42 | static_cast<std::uint64_t>(y) << 21 |
         static_cast<std::uint64_t>(z);
}

}  // namespace spidarcad::modeling::sculpt_grid
