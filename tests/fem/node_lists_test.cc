// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
// detail::NearestAllowed (fem/src/node_lists.h), the neighbour lists of ColumnCache: the grid
// search must give exactly the brute force's lists, ties (a lattice) and points outside the
// allowed ones' box included.
#include "node_lists.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <random>
#include <utility>
#include <vector>

namespace spidarcad::fem::detail {
namespace {

// The O(n²) search ColumnCache did before: sort (squared distance, index), take k.
std::vector<int> BruteForce(const std::vector<Eigen::Vector3d>& p, const std::vector<char>& allowed,
                            int k) {
  const int n = static_cast<int>(p.size());
  std::vector<int> out(static_cast<std::size_t>(n) * k, -1);
  std::vector<std::pair<double, int>> d;
  for (int b = 0; b < n; ++b) {
    d.clear();
    for (int c = 0; c < n; ++c)
      if (c != b && allowed[c]) d.emplace_back((p[c] - p[b]).squaredNorm(), c);
    const int m = std::min<int>(k, static_cast<int>(d.size()));
    std::partial_sort(d.begin(), d.begin() + m, d.end());
    for (int i = 0; i < m; ++i) out[static_cast<std::size_t>(b) * k + i] = d[i].second;
  }
  return out;
}

TEST(NearestAllowed, EqualsTheBruteForceOnVolumesSurfacesLatticesAndLines) {
  std::mt19937 rng(20261202);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  std::vector<std::vector<Eigen::Vector3d>> sets(4);
  for (int i = 0; i < 1500; ++i) sets[0].emplace_back(u(rng), 0.3 * u(rng), 0.01 * u(rng));
  for (int i = 0; i < 1500; ++i) {
    Eigen::Vector3d v(u(rng), u(rng), u(rng));
    sets[1].push_back(0.05 * v.normalized());  // a sphere's surface
  }
  for (int x = 0; x < 12; ++x)  // a lattice: many equal distances
    for (int y = 0; y < 12; ++y)
      for (int z = 0; z < 6; ++z) sets[2].emplace_back(0.01 * x, 0.01 * y, 0.01 * z);
  for (int i = 0; i < 400; ++i)
    sets[3].emplace_back(0.001 * (i % 97), 0.0, 0.0);  // a line, repeats
  for (std::size_t s = 0; s < sets.size(); ++s) {
    const std::vector<Eigen::Vector3d>& p = sets[s];
    std::vector<char> allowed(p.size(), 1);
    // Some not allowed, among them the extremes (outside the allowed points' box).
    for (std::size_t i = 0; i < p.size(); i += 7) allowed[i] = 0;
    for (int k : {0, 1, 16, 40}) {
      EXPECT_EQ(NearestAllowed(p, allowed, k), BruteForce(p, allowed, k))
          << "set " << s << " k " << k;
    }
  }
  // Fewer allowed points than k, and none at all.
  std::vector<char> few(sets[1].size(), 0);
  few[3] = few[500] = few[900] = 1;
  EXPECT_EQ(NearestAllowed(sets[1], few, 16), BruteForce(sets[1], few, 16));
  const std::vector<char> none(sets[1].size(), 0);
  EXPECT_EQ(NearestAllowed(sets[1], none, 4), BruteForce(sets[1], none, 4));
}

}  // namespace
}  // namespace spidarcad::fem::detail
