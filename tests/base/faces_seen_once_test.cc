// Tests of the boundary-face search (base/include/spidarcad/base/faces_seen_once.h) against a
// count of every key in a map.
// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#include "spidarcad/base/faces_seen_once.h"

#include <gtest/gtest.h>

#include <map>
#include <random>

namespace {

using Key = std::array<int, 3>;

// The keys seen once, in increasing key order, by counting them in a map (a second algorithm).
std::vector<std::size_t> ByMap(const std::vector<Key>& keys) {
  std::map<Key, std::vector<std::size_t>> where;
  for (std::size_t i = 0; i < keys.size(); ++i) where[keys[i]].push_back(i);
  std::vector<std::size_t> once;
  for (const auto& [key, at] : where)
    if (at.size() == 1) once.push_back(at[0]);
  return once;
}

// Random sorted triples over `corners` corners, each key appearing one to three times (shuffled),
// so that singletons, pairs (interior faces) and a few triples (defects) are all there.
std::vector<Key> RandomKeys(int count, int corners, std::mt19937* rng) {
  std::uniform_int_distribution<int> corner(0, corners - 1), times(1, 3);
  std::vector<Key> keys;
  while (static_cast<int>(keys.size()) < count) {
    Key k = {corner(*rng), corner(*rng), corner(*rng)};
    std::sort(k.begin(), k.end());
    for (int t = times(*rng); t > 0; --t) keys.push_back(k);
  }
  std::shuffle(keys.begin(), keys.end(), *rng);
  return keys;
}

TEST(FacesSeenOnce, EqualsACountOfEveryKeyOnBothPaths) {
  std::mt19937 rng(7);
  // Corners below 2^21 take the packed path; the corner 2^21 and above (and a negative one)
  // take the other. Few corners make many repeated keys.
  for (int corners : {5, 40, 2000, 1 << 21, (1 << 21) + 10}) {
    for (int count : {0, 1, 7, 5000}) {
      const std::vector<Key> keys = RandomKeys(count, corners, &rng);
      EXPECT_EQ(spidarcad::base::FacesSeenOnce(keys), ByMap(keys))
          << count << " keys over " << corners << " corners";
    }
  }
  std::vector<Key> keys = RandomKeys(500, 100, &rng);
  keys.push_back({-1, 0, 3});  // not packable
  EXPECT_EQ(spidarcad::base::FacesSeenOnce(keys), ByMap(keys));
  // The packed order is the key order: keys that differ only in their first corner, beyond
  // what the second and third could carry into it.
  const std::vector<Key> high = {{1, 0, 0}, {0, (1 << 21) - 1, (1 << 21) - 1}, {0, 0, 1}};
  EXPECT_EQ(spidarcad::base::FacesSeenOnce(high), (std::vector<std::size_t>{2, 1, 0}));
}

}  // namespace
