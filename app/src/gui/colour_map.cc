// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#include "gui/colour_map.h"

#include <algorithm>
#include <cmath>

namespace spidarcad::app {

Rgb TensionColourMap(double t) {
  if (std::isnan(t)) return {0.5, 0.5, 0.5};
  t = std::clamp(t, 0.0, 1.0);
  const double s = t * 3.0;
  const int k = std::min(static_cast<int>(s), 2);
  const double w = s - k;
  Rgb out;
  for (int c = 0; c < 3; ++c) {
    out[c] = (1.0 - w) * kTensionColourStops[k][c] + w * kTensionColourStops[k + 1][c];
  }
  return out;
}

Rgb TensionColour(double tau, double tau_min, double tau_max) {
  const double span = tau_max - tau_min;
  if (!(span > 0.0)) return TensionColourMap(std::nan(""));
  return TensionColourMap((tau - tau_min) / span);
}

}  // namespace spidarcad::app
