// Fuzz harness: TetGen .node/.ele text (app::ParseTetgenFiles, behind File > Import mesh and
// `spidarcad import`). One input holds both files: the bytes before the first NUL byte are the
// .node text, the bytes after it the .ele text (no NUL: an empty .ele). Any pair is either read
// or refused with an InputError whose message starts with the name of one of the two files; an
// accepted mesh has finite coordinates, node indices in range, four distinct corners per
// tetrahedron, positive finite volumes and one region per tetrahedron, passes
// modeling::ValidateTetMesh, and comes back unchanged (and with nothing flipped) through
// modeling::WriteTetgenFiles and ParseTetgenFiles.
// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <fstream>
#include <sstream>
#include <stdexcept>
#include <string>

#include "doc/input_error.h"
#include "doc/tetgen_import.h"
#include "fuzz_support.h"
#include "spidarcad/modeling/tet_mesh.h"

namespace {

using spidarcad::fuzz::Violated;
constexpr char kHarness[] = "node_ele";
constexpr char kNodeName[] = "fuzz.node";
constexpr char kEleName[] = "fuzz.ele";

std::string ReadAll(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  std::stringstream text;
  text << in.rdbuf();
  return text.str();
}

bool StartsWith(const std::string& s, const std::string& prefix) {
  return s.compare(0, prefix.size(), prefix) == 0;
}

// base + ".node" and base + ".ele" in a private directory, both removed at exit.
struct RoundTripFiles {
  spidarcad::fuzz::ScratchFile node{"round-trip.node"};
  std::string base = node.path().substr(0, node.path().size() - 5);
  ~RoundTripFiles() { std::remove((base + ".ele").c_str()); }
};

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  namespace app = spidarcad::app;
  namespace modeling = spidarcad::modeling;
  static RoundTripFiles files;
  const std::string bytes(reinterpret_cast<const char*>(data), size);
  const std::size_t split = bytes.find('\0');
  const std::string node_text = bytes.substr(0, split);
  const std::string ele_text = split == std::string::npos ? "" : bytes.substr(split + 1);

  modeling::TetMesh mesh;
  int flipped = -1;
  try {
    mesh = app::ParseTetgenFiles(node_text, ele_text, kNodeName, kEleName, &flipped);
  } catch (const app::InputError& e) {
    const std::string what = e.what();
    if (!StartsWith(what, std::string(kNodeName) + ":") &&
        !StartsWith(what, std::string(kEleName) + ":")) {
      Violated(kHarness, "a refusal does not name the file: " + what);
    }
    return 0;
  }

  const Eigen::Index nv = mesh.nodes.cols(), nt = mesh.tets.cols();
  if (mesh.nodes.rows() != 3 || nv == 0 || mesh.tets.rows() != 4 || nt == 0)
    Violated(kHarness, "accepted a mesh without points or tetrahedra");
  if (mesh.regions.size() != nt) Violated(kHarness, "accepted a mesh without one region per tet");
  if (!mesh.nodes.allFinite()) Violated(kHarness, "accepted a non-finite coordinate");
  if (flipped < 0 || flipped > nt) Violated(kHarness, "flipped count out of range");
  for (Eigen::Index t = 0; t < nt; ++t) {
    for (int k = 0; k < 4; ++k) {
      if (mesh.tets(k, t) < 0 || mesh.tets(k, t) >= nv)
        Violated(kHarness, "accepted a node index out of range");
    }
    const double v = modeling::TetVolume(mesh, t);
    if (!(v > 0.0) || !std::isfinite(v))
      Violated(kHarness, "accepted a tetrahedron whose volume is not positive and finite");
  }
  try {
    modeling::ValidateTetMesh(mesh);
  } catch (const std::invalid_argument& e) {
    Violated(kHarness, std::string("accepted a mesh that modeling rejects: ") + e.what());
  }

  modeling::TetMesh back;
  int flipped_back = -1;
  try {
    modeling::WriteTetgenFiles(mesh, files.base);
    back = app::ParseTetgenFiles(ReadAll(files.base + ".node"), ReadAll(files.base + ".ele"),
                                 kNodeName, kEleName, &flipped_back);
  } catch (const std::exception& e) {
    Violated(kHarness, std::string("an accepted mesh does not round-trip: ") + e.what());
  }
  if (back.nodes != mesh.nodes || back.tets != mesh.tets || back.regions != mesh.regions ||
      flipped_back != 0) {
    Violated(kHarness,
             "an accepted mesh changes in a WriteTetgenFiles/ParseTetgenFiles round trip");
  }
  return 0;
}
