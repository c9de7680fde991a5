// Always-on checks of internal invariants (not of user input, which gets exceptions that say
// where it was wrong). A failed check prints what failed and where to stderr and aborts: it marks a
// bug in spidarcad, never a bad file or option. Not for the haptic tick: the tick never aborts
// (a NaN or a missed deadline gives zero force instead).
// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#pragma once

#include <cstdio>
#include <cstdlib>

namespace spidarcad::base::internal {

// Prints "spidarcad: internal error at FILE:LINE: check 'CONDITION' failed: MESSAGE" and aborts.
[[noreturn]] inline void CheckFailed(const char* file, int line, const char* condition,
                                     const char* message) {
  std::fprintf(stderr, "spidarcad: internal error at %s:%d: check '%s' failed%s%s\n", file, line,
               condition, message[0] != '\0' ? ": " : "", message);
  std::fflush(stderr);
  std::abort();
}

}  // namespace spidarcad::base::internal

// Aborts with the condition's text, file and line when `condition` is false. Evaluated in every
// build type (unlike assert).
#define SPIDARCAD_CHECK(condition)    \
  ((condition) ? static_cast<void>(0) \
               : ::spidarcad::base::internal::CheckFailed(__FILE__, __LINE__, #condition, ""))

// As SPIDARCAD_CHECK, with a message (a string literal or const char*) saying what broke.
#define SPIDARCAD_CHECK_MSG(condition, message) \
  ((condition)                                  \
       ? static_cast<void>(0)                   \
       : ::spidarcad::base::internal::CheckFailed(__FILE__, __LINE__, #condition, (message)))
