// Raw OpenGL calls of the window, kept out of files that include VTK's GL loader.
// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#pragma once

#include <string>
#include <vector>

namespace spidarcad::app {

// Binds the default framebuffer and sets the viewport to the whole window (w by h pixels).
void BindDefaultFramebuffer(int width, int height);

// Clears the default framebuffer to the panel colour.
void ClearDefaultFramebuffer(float r, float g, float b);

// Reads the back buffer of the current context: RGB bytes, rows bottom to top, w·h·3 bytes.
std::vector<unsigned char> ReadBackBuffer(int width, int height);

// Writes RGB bytes (rows bottom to top, as ReadBackBuffer returns them) to a PNG file.
// Returns an empty string on success, else what went wrong.
std::string WritePng(const std::string& path, const std::vector<unsigned char>& rgb, int width,
                     int height);

}  // namespace spidarcad::app
