// The error type for bad user input, shared by every layer of the app (doc, scene, cli, gui).
// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#pragma once

#include <stdexcept>
#include <string>

namespace spidarcad::app {

// Bad user input (a file, an option, a field): what() says what was wrong and where (file, line,
// field, value) and how to fix it. The CLI prints it and exits with status 2; the window shows it;
// a command that throws it leaves the Document unchanged.
class InputError : public std::runtime_error {
 public:
  explicit InputError(const std::string& message) : std::runtime_error(message) {}
};

}  // namespace spidarcad::app
