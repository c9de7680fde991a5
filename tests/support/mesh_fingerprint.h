// A fingerprint of a triangle mesh's exact output: FNV-1a (64 bits) over the bytes of its vertex
// coordinates (doubles, column by column) and then of its triangles' vertex indices. Two meshes
// with the same fingerprint have, but for a hash collision, the same vertices bit for bit in
// the same order and the same triangles. Tests freeze fingerprints to prove that a speed-up
// leaves a mesher's output unchanged.
// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#pragma once

#include <cstddef>
#include <cstdint>

#include "spidarcad/modeling/surface_mesher.h"

namespace spidarcad::test_support {

inline std::uint64_t MeshFingerprint(const modeling::TriangleMesh& mesh) {
  std::uint64_t hash = 14695981039346656037ull;
  auto add = [&hash](const void* data, std::size_t bytes) {
    const unsigned char* p = static_cast<const unsigned char*>(data);
    for (std::size_t i = 0; i < bytes; ++i) {
      hash ^= p[i];
      hash *= 1099511628211ull;
    }
  };
  add(mesh.vertices.data(), sizeof(double) * static_cast<std::size_t>(mesh.vertices.size()));
  add(mesh.triangles.data(), sizeof(int) * static_cast<std::size_t>(mesh.triangles.size()));
  return hash;
}

}  // namespace spidarcad::test_support
