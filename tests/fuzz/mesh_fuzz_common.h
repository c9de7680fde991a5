// The body of the three triangle-mesh harnesses (STL, OBJ, PLY): the input is written to a
// scratch file with the format's extension and read with modeling::ReadTriangleMesh. Any file
// is either read or refused with a MeshFileError; an accepted mesh has finite coordinates,
// indices in range and no repeated corner, and reads back the same from each format the
// writer supports (PLY binary is exact; OBJ prints 17 digits, also exact).
// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#pragma once

#include <cstddef>
#include <cstdint>
#include <string>

#include "fuzz_support.h"
#include "spidarcad/modeling/triangle_mesh_io.h"

namespace spidarcad::fuzz {

inline void CheckMesh(const char* harness, const modeling::TriangleMesh& mesh) {
  if (!mesh.vertices.allFinite()) Violated(harness, "accepted a non-finite vertex coordinate");
  const long nv = mesh.vertices.cols();
  for (Eigen::Index f = 0; f < mesh.triangles.cols(); ++f) {
    for (int k = 0; k < 3; ++k) {
      const int i = mesh.triangles(k, f);
      if (i < 0 || i >= nv) Violated(harness, "accepted a vertex index out of range");
    }
    if (mesh.triangles(0, f) == mesh.triangles(1, f) ||
        mesh.triangles(1, f) == mesh.triangles(2, f) ||
        mesh.triangles(0, f) == mesh.triangles(2, f)) {
      Violated(harness, "accepted a face that repeats a vertex");
    }
  }
}

inline int RunMeshHarness(const char* harness, const char* extension, const std::uint8_t* data,
                          std::size_t size) {
  static ScratchFile input(std::string("input.") + extension);
  static ScratchFile ply("round-trip.ply");
  static ScratchFile obj("round-trip.obj");
  modeling::TriangleMesh mesh;
  try {
    mesh = modeling::ReadTriangleMesh(input.Write(data, size));
  } catch (const modeling::MeshFileError&) {
    return 0;
  }
  CheckMesh(harness, mesh);
  for (const ScratchFile* out : {&ply, &obj}) {
    modeling::TriangleMesh back;
    try {
      modeling::WriteTriangleMesh(mesh, out->path());
      back = modeling::ReadTriangleMesh(out->path());
    } catch (const modeling::MeshFileError& e) {
      Violated(harness, std::string("an accepted mesh does not round-trip: ") + e.what());
    }
    if (back.vertices.cols() != mesh.vertices.cols() ||
        back.triangles.cols() != mesh.triangles.cols() || back.vertices != mesh.vertices ||
        back.triangles != mesh.triangles) {
      Violated(harness,
               "an accepted mesh changes in a write/read round trip through " + out->path());
    }
  }
  return 0;
}

}  // namespace spidarcad::fuzz
