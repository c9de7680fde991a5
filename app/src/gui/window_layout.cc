// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#include "gui/window_layout.h"

#include <algorithm>
#include <cmath>

namespace spidarcad::app {

float Rect::OverlapArea(const Rect& other) const {
  const float w_overlap = std::min(right(), other.right()) - std::max(x, other.x);
  const float h_overlap = std::min(bottom(), other.bottom()) - std::max(y, other.y);
  return w_overlap > 0.0f && h_overlap > 0.0f ? w_overlap * h_overlap : 0.0f;
}

WindowLayout ComputeLayout(float width, float height, const LayoutSizes& sizes) {
  WindowLayout l;
  width = std::max(width, 1.0f);
  height = std::max(height, 1.0f);
  // Whole pixels, so that the VTK viewport and the ImGui windows meet exactly.
  const float menu = std::round(std::clamp(sizes.menu_height, 0.0f, 0.2f * height));
  const float strip =
      std::round(sizes.bottom_collapsed ? std::min(sizes.collapsed_height, 0.2f * height)
                                        : std::min(sizes.bottom_height, 0.4f * height));
  const float left = std::round(std::min(sizes.left_width, 0.35f * width));
  const float right = std::round(std::min(sizes.right_width, 0.30f * width));
  const float middle_h = std::max(height - menu - strip, 1.0f);
  l.menu = {0.0f, 0.0f, width, menu};
  l.left = {0.0f, menu, left, middle_h};
  l.right = {width - right, menu, right, middle_h};
  l.bottom = {0.0f, menu + middle_h, width, height - menu - middle_h};
  l.viewport = {left, menu, std::max(width - left - right, 1.0f), middle_h};
  return l;
}

}  // namespace spidarcad::app
