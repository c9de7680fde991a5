// Fuzz harness: the cache directory of fem::SubstructuredSolver (block files and interface plane
// files, fem/src/substructure.cc). A small bar in three slabs is factored once into a private
// directory, which leaves three block files and two plane files. Each input edits a copy of one
// of them, signs the edited body with a valid checksum (so that the edit reaches the parser
// rather than stopping at the checksum), writes it in place, and builds a solver from the
// directory. The solver must read the file or refuse it with a note naming it; nothing may
// crash, hang, leak or read out of bounds, and a solver that factored must solve.
//
// Input: byte 0 picks the file (modulo five) and says, by its bit 7, whether the body is cut
// short; then 5-byte edits (u32 offset modulo the body's size, u8 XOR mask); a final u32 is the
// cut length (modulo the size). Seeds: tests/fuzz/corpus/substructure_cache.
// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#include <Eigen/Core>
#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <stdexcept>
#include <string>
#include <vector>

#include "spidarcad/fem/boundary.h"
#include "spidarcad/fem/cache_file.h"
#include "spidarcad/fem/material.h"
#include "spidarcad/fem/mesh.h"
#include "spidarcad/fem/substructure.h"

namespace {

using namespace spidarcad::fem;

struct CachedFile {
  std::filesystem::path path;
  char magic[8];
  std::vector<unsigned char> body;  // between the magic and the checksum
};

// The bar, its conditions and blocks, and the files a first solver left.
struct Setup {
  TetMesh mesh;
  MaterialTable materials{Material{2.0e11, 0.3}};
  BoundaryConditions bcs{0};
  Eigen::VectorXi blocks;
  std::filesystem::path dir;
  std::vector<CachedFile> files;

  Setup() {
    BoxMeshSettings s;
    s.upper = Eigen::Vector3d(0.3, 0.05, 0.04);
    s.nx = 6;
    s.ny = 2;
    s.nz = 2;
    s.order = 2;
    mesh = MakeBoxMesh(s);
    bcs = BoundaryConditions(mesh.num_nodes());
    FixNodesInBox(mesh, Eigen::Vector3d(-1, -1, -1), Eigen::Vector3d(1e-9, 1, 1), &bcs);
    for (int v : NodesInBox(mesh, Eigen::Vector3d(0.3 - 1e-9, -1, -1), Eigen::Vector3d(1, 1, 1)))
      bcs.AddPointLoad(v, Eigen::Vector3d(0.0, 10.0, -100.0));
    blocks = SlabBlocks(mesh, 0, EvenPlanes(mesh, 0, 3));
    const char* tmp = std::getenv("TMPDIR");
    std::string pattern =
        std::string(tmp != nullptr && *tmp != '\0' ? tmp : "/tmp") + "/spidarcad-fuzz-cache-XXXXXX";
    if (mkdtemp(pattern.data()) == nullptr) throw std::runtime_error("mkdtemp failed");
    dir = pattern;
    {
      SubstructuredSolver first(mesh, materials, bcs, blocks, nullptr, dir);
      first.FinishCacheWrites();
    }
    for (const auto& entry : std::filesystem::directory_iterator(dir)) files.push_back(Read(entry));
    std::sort(files.begin(), files.end(),
              [](const CachedFile& a, const CachedFile& b) { return a.path < b.path; });
    if (files.size() != 5) throw std::runtime_error("expected 3 block and 2 plane files");
  }
  ~Setup() {
    std::error_code ec;
    std::filesystem::remove_all(dir, ec);
  }

  static CachedFile Read(const std::filesystem::directory_entry& entry) {
    std::ifstream in(entry.path(), std::ios::binary);
    const std::vector<unsigned char> bytes((std::istreambuf_iterator<char>(in)),
                                           std::istreambuf_iterator<char>());
    CachedFile f;
    f.path = entry.path();
    std::memcpy(f.magic, bytes.data(), 8);
    f.body.assign(bytes.begin() + 8, bytes.end() - 8);
    return f;
  }
};

std::uint32_t U32(const std::uint8_t* p) {
  std::uint32_t v;
  std::memcpy(&v, p, 4);
  return v;
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  static Setup setup;
  if (size == 0) return 0;
  const CachedFile& original = setup.files[data[0] % setup.files.size()];
  const bool cut = (data[0] & 0x80) != 0;
  std::vector<unsigned char> body = original.body;
  std::size_t at = 1;
  for (; at + 5 <= size && !(cut && at + 5 + 4 > size); at += 5)
    body[U32(data + at) % body.size()] ^= data[at + 4];
  if (cut && at + 4 <= size) body.resize(U32(data + at) % body.size());
  if (!WriteCacheFile(original.path, original.magic, body)) return 0;

  SubstructuredSolver solver(setup.mesh, setup.materials, setup.bcs, setup.blocks, nullptr,
                             setup.dir);
  solver.FinishCacheWrites();  // a refused file is written again, whole
  const SubstructureStats& stats = solver.stats();
  const bool edited = body != original.body;
  // Unchanged files are read; an edited one is read (the edit fell on bytes that do not
  // matter, e.g. a timing) or refused with a note naming it.
  if (stats.loaded_blocks + stats.loaded_interface_groups < 4) std::abort();
  if (!edited && !stats.cache_notes.empty()) std::abort();
  for (const std::string& note : stats.cache_notes)
    if (note.find(original.path.string()) == std::string::npos) std::abort();
  if (solver.factor_status().converged) {
    const StaticSolution solution = solver.Solve();
    (void)solution;
  }
  // Put the file back as it was, for the next input.
  if (!WriteCacheFile(original.path, original.magic, original.body)) std::abort();
  return 0;
}
