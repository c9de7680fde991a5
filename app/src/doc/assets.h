// Where the shipped example scenes and data (assets/) are found, without the source tree.
// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#pragma once

#include <string>

namespace spidarcad::app {

// The path of a shipped asset, given relative to the assets folder (e.g. "scenes/clay.json").
// Looks, in order, in: $SPIDARCAD_ASSETS_DIR; ./assets (a checkout as the working directory);
// <directory of the executable>/../share/spidarcad/assets (an install made by `cmake --install`,
// and the build tree, where the build copies assets/ to build/share/spidarcad/assets). Returns
// the first that exists, else the ./assets path (so that the error names a sensible file).
std::string AssetPath(const std::string& relative);

}  // namespace spidarcad::app
