// TetGen 1.5 ends every error through terminatetetgen(tetgenmesh*, int). Its header defines it
// inline: free the mesh's memory, then `throw int` (with TETLIBRARY) - and the tetgenmesh
// destructor frees the same memory again while the exception unwinds, which crashes the process.
// libtet.so exports it as a weak symbol and calls it through the PLT, so this strong definition
// replaces it: no freeing here (the destructor frees once), and a TetgenError the caller can
// catch. This file must not include tetgen.h (that would bring the inline definition).
// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#include <string>

#include "spidarcad/modeling/tetgen_mesher.h"

class tetgenmesh;

namespace {

std::string Describe(int code) {
  switch (code) {
    case 1:
      return "out of memory";
    case 2:
      return "internal error";
    case 3:
      return "the surface intersects itself";
    case 4:
      return "a very small input feature (TetGen's -T tolerance)";
    case 5:
      return "two very close input facets";
    case 10:
      return "input error";
    default:
      return "error code " + std::to_string(code);
  }
}

}  // namespace

// Called by libtet on every error; must not return.
void terminatetetgen(tetgenmesh* /*mesh*/, int code) {
  throw spidarcad::modeling::TetgenError(code, "TetGen failed: " + Describe(code));
}

namespace spidarcad::modeling::internal {
// Referenced from tetgen_mesher.cc so that the linker pulls this object out of the static
// library (and with it the terminatetetgen above).
int TetgenTerminateAnchor() { return 1; }
}  // namespace spidarcad::modeling::internal
