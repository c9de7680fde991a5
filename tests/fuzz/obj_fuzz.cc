// Fuzz harness: Wavefront OBJ files through modeling::ReadTriangleMesh (see mesh_fuzz_common.h).
// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#include "mesh_fuzz_common.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  return spidarcad::fuzz::RunMeshHarness("obj", "obj", data, size);
}
