// Fuzz harness: tetrahedral meshes in .vtu files (app::ReadTetVtu on modeling's own VTU reader,
// tet_mesh_io.cc; no VTK). Any file is either read or refused with an InputError; an accepted
// mesh has 4 or 10 nodes per element, finite coordinates, node indices in range and positively
// oriented elements.
// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#include <cstddef>
#include <cstdint>
#include <stdexcept>
#include <string>

#include "doc/input_error.h"
#include "fuzz_support.h"
#include "scene/vtu_io.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  using spidarcad::fuzz::Violated;
  static spidarcad::fuzz::ScratchFile input("input.vtu");
  spidarcad::fem::TetMesh mesh;
  try {
    mesh = spidarcad::app::ReadTetVtu(input.Write(data, size));
  } catch (const spidarcad::app::InputError&) {
    return 0;
  }
  if (mesh.elements.cols() != 4 && mesh.elements.cols() != 10) {
    Violated("vtu", "accepted elements with neither 4 nor 10 nodes");
  }
  if (mesh.nodes.cols() != 3 || !mesh.nodes.allFinite()) {
    Violated("vtu", "accepted non-finite or non-3D node coordinates");
  }
  if (mesh.elements.size() > 0 &&
      (mesh.elements.minCoeff() < 0 || mesh.elements.maxCoeff() >= mesh.nodes.rows())) {
    Violated("vtu", "accepted an element node index out of range");
  }
  try {
    mesh.Validate();
  } catch (const std::invalid_argument& e) {
    Violated("vtu", std::string("accepted a mesh that fem rejects: ") + e.what());
  }
  return 0;
}
