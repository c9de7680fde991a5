// The window's fixed docked layout (ImGui 1.86 has no docking): the menu bar across the top, the
// document panel (tree and the selected object's properties) on the left, the active mode's panel
// on the right, a collapsible strip of device and loop figures across the bottom, and the 3D
// viewport in the rectangle left over. Computed from the window size every frame, so the panels
// follow resizes. Pixels, origin at the window's top-left corner, y down (ImGui's convention).
// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#pragma once

namespace spidarcad::app {

// An axis-aligned rectangle in window pixels (x right, y down).
struct Rect {
  float x = 0.0f;
  float y = 0.0f;
  float w = 0.0f;
  float h = 0.0f;
  float right() const { return x + w; }
  float bottom() const { return y + h; }
  float area() const { return w * h; }
  // True when the point (px, py) lies inside (left and top edges included).
  bool Contains(float px, float py) const {
    return px >= x && px < right() && py >= y && py < bottom();
  }
  // Area shared with `other` (0 when they only touch).
  float OverlapArea(const Rect& other) const;
};

// The rectangles of the layout.
struct WindowLayout {
  Rect menu;      // the main menu bar
  Rect left;      // document tree and properties
  Rect right;     // the active mode's panel
  Rect bottom;    // device and loop figures (its title bar only when collapsed)
  Rect viewport;  // the 3D view: what is left
};

// Sizes the layout is computed from (pixels).
struct LayoutSizes {
  float menu_height = 19.0f;       // the menu bar's height (ImGui reports it each frame)
  float left_width = 380.0f;       // document panel (at most 35 % of the window width)
  float right_width = 340.0f;      // mode panel (at most 30 % of the window width)
  float bottom_height = 246.0f;    // figures strip when open (at most 40 % of the height)
  float collapsed_height = 22.0f;  // figures strip when collapsed (its title bar)
  bool bottom_collapsed = false;
};

// The layout of a `width` × `height` window: the left and right panels run from the menu bar
// down to the strip, the strip spans the whole width at the bottom, the viewport fills the rest.
// The rectangles tile the window exactly (no gaps, no overlaps); each is at least 1 pixel in
// size when the window is at least 200 × 200.
WindowLayout ComputeLayout(float width, float height, const LayoutSizes& sizes = {});

}  // namespace spidarcad::app
