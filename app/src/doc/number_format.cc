// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#include "doc/number_format.h"

#include <charconv>
#include <cmath>

namespace spidarcad::app {

std::string FormatNumber(double value) {
  if (std::isnan(value)) return "nan";
  char buffer[64];
  auto [ptr, ec] = std::to_chars(buffer, buffer + sizeof(buffer), value);
  return std::string(buffer, ptr);
}

}  // namespace spidarcad::app
