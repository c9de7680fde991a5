// Numbers in messages and CSV output, written the same way by every layer of the app.
// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#pragma once

#include <string>

namespace spidarcad::app {

// Formats a double: the shortest text that reads back to the same value, "nan" for NaN.
std::string FormatNumber(double value);

}  // namespace spidarcad::app
