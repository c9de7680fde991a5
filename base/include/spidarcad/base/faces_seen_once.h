// The boundary faces of a tetrahedral mesh, found once for both meshes the project holds
// (modeling::TetMesh, fem::TetMesh): a face is on the boundary when its sorted corner triple
// occurs once among the 4 faces of every tetrahedron.
// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#pragma once

#include <algorithm>
#include <array>
#include <cstddef>
#include <cstdint>
#include <numeric>
#include <utility>
#include <vector>

namespace spidarcad::base {

// Indices (into `keys`) of the keys that occur exactly once, in increasing key order. keys[i] is
// face i's corner triple, sorted; with 4 faces per tetrahedron, face i is face i % 4 of
// tetrahedron i / 4 (4·#tets faces, 10⁵–10⁶). Corners in [0, 2²¹) with fewer than 2³² keys (every
// mesh the product makes): each triple packed into one 64-bit word in the same order, and the
// (word, index) pairs radix-sorted, several times faster than sorting the indices through the
// keys, which is what any other input gets. Both give the same list.
inline std::vector<std::size_t> FacesSeenOnce(const std::vector<std::array<int, 3>>& keys) {
  constexpr int kBits = 21;
  const bool packable = keys.size() < (std::size_t{1} << 32) &&
                        std::all_of(keys.begin(), keys.end(), [](const std::array<int, 3>& k) {
                          return k[0] >= 0 && k[1] >= 0 && k[2] >= 0 && k[0] < (1 << kBits) &&
                                 k[1] < (1 << kBits) && k[2] < (1 << kBits);
                        });
  // The entries of a sorted run of n, by position, whose neighbours differ from them.
  std::vector<std::size_t> once;
  auto singletons = [&once](std::size_t n, auto same, auto index) {
    for (std::size_t i = 0; i < n;) {
      std::size_t j = i + 1;
      while (j < n && same(i, j)) ++j;
      if (j == i + 1) once.push_back(index(i));
      i = j;
    }
  };
  if (packable) {
    std::vector<std::pair<std::uint64_t, std::uint32_t>> words(keys.size());
    for (std::size_t i = 0; i < keys.size(); ++i)
      words[i] = {(std::uint64_t(keys[i][0]) << (2 * kBits)) |
                      (std::uint64_t(keys[i][1]) << kBits) | std::uint64_t(keys[i][2]),
                  static_cast<std::uint32_t>(i)};
    // Least significant digit first, 11 bits a pass (6 passes for 63 bits): stable, so equal
    // words keep their index order, as the comparison sort of the pairs would give.
    std::vector<std::pair<std::uint64_t, std::uint32_t>> spare(words.size());
    constexpr int kDigit = 11;
    for (int shift = 0; shift < 3 * kBits; shift += kDigit) {
      std::vector<std::size_t> start((std::size_t{1} << kDigit) + 1, 0);
      for (const auto& w : words) ++start[((w.first >> shift) & ((1u << kDigit) - 1)) + 1];
      for (std::size_t d = 1; d < start.size(); ++d) start[d] += start[d - 1];
      for (const auto& w : words) spare[start[(w.first >> shift) & ((1u << kDigit) - 1)]++] = w;
      words.swap(spare);
    }
    singletons(
        words.size(),
        [&](std::size_t i, std::size_t j) { return words[i].first == words[j].first; },
        [&](std::size_t i) { return std::size_t{words[i].second}; });
    return once;
  }
  std::vector<std::size_t> order(keys.size());
  std::iota(order.begin(), order.end(), std::size_t{0});
  std::sort(order.begin(), order.end(),
            [&keys](std::size_t a, std::size_t b) { return keys[a] < keys[b]; });
  singletons(
      order.size(), [&](std::size_t i, std::size_t j) { return keys[order[i]] == keys[order[j]]; },
      [&](std::size_t i) { return order[i]; });
  return once;
}

}  // namespace spidarcad::base
