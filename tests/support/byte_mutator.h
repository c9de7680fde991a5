// Random byte-level mutations of a file's text for the hard reader tests (flipped bits, random
// bytes, truncation, duplicated and erased spans, inserted number characters), the edits a
// fuzzer makes, with a seeded generator so that a failure reproduces.
// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#pragma once

#include <algorithm>
#include <cstddef>
#include <random>
#include <string>

namespace spidarcad::test_support {

// `bytes` after 1..max_edits random edits, each touching at most max_span bytes.
inline std::string MutateBytes(std::string bytes, std::mt19937& rng, int max_edits,
                               std::size_t max_span) {
  const int edits = 1 + static_cast<int>(rng() % max_edits);
  for (int k = 0; k < edits && !bytes.empty(); ++k) {
    const std::size_t at = rng() % bytes.size();
    const std::size_t span = std::min<std::size_t>(1 + rng() % max_span, bytes.size() - at);
    switch (rng() % 6) {
      case 0:
        bytes[at] = static_cast<char>(bytes[at] ^ (1 << (rng() % 8)));
        break;
      case 1:
        bytes[at] = static_cast<char>(rng() % 256);
        break;
      case 2:
        bytes.resize(at);
        break;
      case 3:
        bytes.insert(at, bytes.substr(at, span));
        break;
      case 4:
        bytes.erase(at, span);
        break;
      default:
        bytes.insert(at, std::string(1, "-9+0e."[rng() % 6]));
        break;
    }
  }
  return bytes;
}

}  // namespace spidarcad::test_support
