// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
// Tests of the window's docked layout (gui/window_layout.h): at several window sizes, open and
// collapsed, the menu bar, the three panels and the viewport cover every pixel of the window
// exactly once (checked pixel by pixel, independently of the rectangle arithmetic).
#include "gui/window_layout.h"

#include <gtest/gtest.h>

#include <array>
#include <cmath>
#include <string>

namespace spidarcad::app {
namespace {

// Every pixel centre of a width × height window lies in exactly one of the layout's rectangles;
// returns the number of pixels that do not (0 when they tile the window).
int UntiledPixels(const WindowLayout& l, int width, int height) {
  const std::array<Rect, 5> rects = {l.menu, l.left, l.right, l.bottom, l.viewport};
  int bad = 0;
  for (int y = 0; y < height; ++y) {
    for (int x = 0; x < width; ++x) {
      int covering = 0;
      for (const Rect& r : rects) covering += r.Contains(x + 0.5f, y + 0.5f) ? 1 : 0;
      if (covering != 1) ++bad;
    }
  }
  return bad;
}

TEST(ComputeLayout, PanelsAndViewportTileTheWindowAtEverySizeOpenOrCollapsed) {
  const std::array<std::array<int, 2>, 4> sizes = {
      {{1280, 800}, {1100, 720}, {800, 600}, {200, 200}}};
  for (const auto& size : sizes) {
    for (const bool collapsed : {false, true}) {
      LayoutSizes sizes_in;
      sizes_in.menu_height = 20.5f;  // ImGui's menu bar with the 14.5 px font
      sizes_in.bottom_collapsed = collapsed;
      const int w = size[0], h = size[1];
      const WindowLayout l = ComputeLayout(static_cast<float>(w), static_cast<float>(h), sizes_in);
      const std::string where =
          std::to_string(w) + "x" + std::to_string(h) + (collapsed ? " collapsed" : " open");
      EXPECT_EQ(UntiledPixels(l, w, h), 0) << where;
      for (const Rect& panel : {l.menu, l.left, l.right, l.bottom}) {
        EXPECT_EQ(panel.OverlapArea(l.viewport), 0.0f) << where;
      }
      EXPECT_GE(l.viewport.w, 1.0f) << where;
      EXPECT_GE(l.viewport.h, 1.0f) << where;
      // Docked where the brief puts them: document left, mode right, figures at the bottom.
      EXPECT_EQ(l.left.x, 0.0f) << where;
      EXPECT_EQ(l.right.right(), static_cast<float>(w)) << where;
      EXPECT_EQ(l.bottom.bottom(), static_cast<float>(h)) << where;
      EXPECT_EQ(l.bottom.w, static_cast<float>(w)) << where;
      EXPECT_EQ(l.viewport.x, l.left.right()) << where;
      EXPECT_EQ(l.viewport.right(), l.right.x) << where;
    }
  }
}

TEST(ComputeLayout, PanelsKeepTheirWidthsWhereThereIsRoomAndShrinkInSmallWindows) {
  const LayoutSizes sizes;
  const WindowLayout big = ComputeLayout(1280.0f, 800.0f, sizes);
  EXPECT_EQ(big.left.w, sizes.left_width);
  EXPECT_EQ(big.right.w, sizes.right_width);
  EXPECT_EQ(big.bottom.h, sizes.bottom_height);
  EXPECT_EQ(big.viewport.w, 1280.0f - sizes.left_width - sizes.right_width);
  // 800 wide: 35 % and 30 % of the width; 500 high: the strip at most 40 % of the height.
  const WindowLayout small = ComputeLayout(800.0f, 500.0f, sizes);
  EXPECT_EQ(small.left.w, 280.0f);
  EXPECT_EQ(small.right.w, 240.0f);
  EXPECT_EQ(small.bottom.h, 200.0f);
  // Collapsing the strip gives its height to the viewport and the side panels.
  LayoutSizes collapsed = sizes;
  collapsed.bottom_collapsed = true;
  const WindowLayout c = ComputeLayout(1280.0f, 800.0f, collapsed);
  EXPECT_EQ(c.bottom.h, collapsed.collapsed_height);
  EXPECT_EQ(c.viewport.h - big.viewport.h, sizes.bottom_height - collapsed.collapsed_height);
}

TEST(Rect, OverlapAreaIsTheSharedAreaAndZeroForRectanglesThatOnlyTouch) {
  const Rect a{0, 0, 10, 10};
  EXPECT_EQ(a.OverlapArea({5, 5, 10, 10}), 25.0f);
  EXPECT_EQ(a.OverlapArea({10, 0, 5, 5}), 0.0f);
  EXPECT_EQ(a.OverlapArea({2, 3, 1, 1}), 1.0f);
  EXPECT_TRUE(a.Contains(0, 0));
  EXPECT_FALSE(a.Contains(10, 5));
}

}  // namespace
}  // namespace spidarcad::app
