// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
// Where the benchmarks find the repository's files: SPIDARCAD_SOURCE_DIR, the source tree's
// absolute path, is defined for every bench by bench/CMakeLists.txt, so a bench runs from any
// working directory (a path derived from __FILE__ is relative under ccache's base_dir).
#pragma once

#include <string>

#ifndef SPIDARCAD_SOURCE_DIR
#error "SPIDARCAD_SOURCE_DIR must be defined (bench/CMakeLists.txt does)"
#endif

namespace spidarcad::bench {

// Absolute path of `relative` (e.g. "assets/scenes/platform.json") in the source tree.
inline std::string RepoPath(const std::string& relative) {
  return std::string(SPIDARCAD_SOURCE_DIR) + "/" + relative;
}

}  // namespace spidarcad::bench
