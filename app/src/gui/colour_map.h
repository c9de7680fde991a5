// Tension colour map of the window: blue for τ_min through teal and yellow to red for τ_max.
// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#pragma once

#include <array>

namespace spidarcad::app {

// An RGB colour with components in [0, 1].
using Rgb = std::array<double, 3>;

// Colour of the normalised value t in [0, 1] (clamped; NaN gives grey): blue (0) → teal (1/3)
// → yellow (2/3) → red (1), linear between the stops.
Rgb TensionColourMap(double t);

// Colour of a tension τ (N) between tau_min (blue) and tau_max (red).
Rgb TensionColour(double tau, double tau_min, double tau_max);

// Stops of TensionColourMap, at t = 0, 1/3, 2/3, 1.
inline constexpr std::array<Rgb, 4> kTensionColourStops = {{
    {0.10, 0.32, 0.95},  // blue: τ_min
    {0.05, 0.72, 0.68},  // teal
    {0.96, 0.80, 0.10},  // yellow
    {0.86, 0.08, 0.08},  // red: τ_max
}};

}  // namespace spidarcad::app
