// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#include "scene/mesh_import.h"

#include <algorithm>
#include <cctype>
#include <charconv>
#include <cmath>
#include <fstream>
#include <stdexcept>
#include <utility>
#include <vector>

#include "doc/input_error.h"
#include "spidarcad/modeling/cgal_mesher.h"
#include "spidarcad/modeling/triangle_mesh_io.h"

namespace spidarcad::app {
namespace {

std::string LowerExtension(const std::string& path) {
  const auto slash = path.find_last_of('/');
  const auto dot = path.find_last_of('.');
  if (dot == std::string::npos || (slash != std::string::npos && dot < slash)) return "";
  std::string ext = path.substr(dot + 1);
  for (char& c : ext) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return ext;
}

// One non-blank line of a TetGen text file: its number and its fields ('#' starts a comment).
struct Record {
  int line = 0;
  std::vector<std::string> fields;
};

std::vector<Record> ReadRecords(const std::string& path, const std::string& what) {
  std::ifstream in(path);
  if (!in) throw InputError(path + ": cannot open the " + what + " for reading (check the path)");
  std::vector<Record> records;
  std::string text;
  int line = 0;
  while (std::getline(in, text)) {
    ++line;
    const auto hash = text.find('#');
    if (hash != std::string::npos) text.resize(hash);
    Record r;
    r.line = line;
    std::size_t i = 0;
    while (i < text.size()) {
      while (i < text.size() && std::isspace(static_cast<unsigned char>(text[i]))) ++i;
      std::size_t j = i;
      while (j < text.size() && !std::isspace(static_cast<unsigned char>(text[j]))) ++j;
      if (j > i) r.fields.push_back(text.substr(i, j - i));
      i = j;
    }
    if (!r.fields.empty()) records.push_back(std::move(r));
  }
  return records;
}

// Field k of a record as a finite number; errors name file, line, field and value.
double Number(const std::string& path, const Record& r, std::size_t k, const std::string& field) {
  const std::string where = path + ":" + std::to_string(r.line) + ": field " + field + ": ";
  if (k >= r.fields.size()) {
    throw InputError(where + "missing (the line has " + std::to_string(r.fields.size()) +
                     " fields); TetGen's format is described in docs/cli.md#import");
  }
  const std::string& text = r.fields[k];
  double value = 0.0;
  const auto result = std::from_chars(text.data(), text.data() + text.size(), value);
  if (result.ec != std::errc() || result.ptr != text.data() + text.size() || !std::isfinite(value))
    throw InputError(where + "'" + text + "' is not a finite number");
  return value;
}

// Field k as an integer in [lo, hi].
long Integer(const std::string& path, const Record& r, std::size_t k, const std::string& field,
             long lo, long hi) {
  const double value = Number(path, r, k, field);
  if (value != std::floor(value) || value < static_cast<double>(lo) ||
      value > static_cast<double>(hi)) {
    throw InputError(path + ":" + std::to_string(r.line) + ": field " + field + ": '" +
                     r.fields[k] + "' is not an integer in [" + std::to_string(lo) + ", " +
                     std::to_string(hi) + "]");
  }
  return static_cast<long>(value);
}

// Largest count accepted in a TetGen header (a guard against absurd allocations).
constexpr long kMaxCount = 100000000;

modeling::TetMesh ReadTetgen(const std::string& node_path) {
  const std::string base = node_path.substr(0, node_path.size() - 5);
  const std::string ele_path = base + ".ele";
  const std::vector<Record> nodes = ReadRecords(node_path, ".node file");
  if (nodes.empty()) throw InputError(node_path + ": empty file (no header line)");
  const Record& h = nodes.front();
  const long n = Integer(node_path, h, 0, "number of points", 1, kMaxCount);
  const long dim = Integer(node_path, h, 1, "dimension", 3, 3);
  const long nattr =
      h.fields.size() > 2 ? Integer(node_path, h, 2, "number of attributes", 0, 64) : 0;
  const long nmark = h.fields.size() > 3 ? Integer(node_path, h, 3, "boundary markers", 0, 1) : 0;
  if (static_cast<long>(nodes.size()) - 1 != n) {
    throw InputError(node_path + ":" + std::to_string(h.line) + ": field number of points: the " +
                     "header says " + std::to_string(n) + " points, the file has " +
                     std::to_string(nodes.size() - 1) + " point lines");
  }
  modeling::TetMesh mesh;
  mesh.nodes.resize(3, n);
  long first = 0;
  for (long i = 0; i < n; ++i) {
    const Record& r = nodes[static_cast<std::size_t>(i) + 1];
    if (r.fields.size() != static_cast<std::size_t>(1 + dim + nattr + nmark)) {
      throw InputError(node_path + ":" + std::to_string(r.line) + ": expected " +
                       std::to_string(1 + dim + nattr + nmark) +
                       " fields (index x y z, attributes, marker), got " +
                       std::to_string(r.fields.size()));
    }
    const long index = Integer(node_path, r, 0, "index", 0, kMaxCount + 1);
    if (i == 0) {
      if (index != 0 && index != 1)
        throw InputError(node_path + ":" + std::to_string(r.line) +
                         ": field index: the first point must be numbered 0 or 1, got " +
                         r.fields[0]);
      first = index;
    } else if (index != first + i) {
      throw InputError(node_path + ":" + std::to_string(r.line) + ": field index: expected " +
                       std::to_string(first + i) + " (points numbered in order), got " +
                       r.fields[0]);
    }
    for (int a = 0; a < 3; ++a)
      mesh.nodes(a, i) = Number(node_path, r, 1 + a, std::string(1, static_cast<char>('x' + a)));
  }
  const std::vector<Record> eles = ReadRecords(ele_path, ".ele file beside the .node file");
  if (eles.empty()) throw InputError(ele_path + ": empty file (no header line)");
  const Record& eh = eles.front();
  const long nt = Integer(ele_path, eh, 0, "number of tetrahedra", 1, kMaxCount);
  const long npe = Integer(ele_path, eh, 1, "nodes per tetrahedron", 4, 10);
  if (npe != 4) {
    throw InputError(ele_path + ":" + std::to_string(eh.line) +
                     ": field nodes per tetrahedron: " + std::to_string(npe) +
                     " (quadratic tetrahedra); import linear (4-node) tetrahedra, `spidarcad fem "
                     "--order 2` adds the midside nodes");
  }
  const long eattr =
      eh.fields.size() > 2 ? Integer(ele_path, eh, 2, "number of attributes", 0, 64) : 0;
  if (static_cast<long>(eles.size()) - 1 != nt) {
    throw InputError(ele_path + ":" + std::to_string(eh.line) +
                     ": field number of tetrahedra: the header says " + std::to_string(nt) +
                     ", the file has " + std::to_string(eles.size() - 1) + " tetrahedron lines");
  }
  mesh.tets.resize(4, nt);
  mesh.regions = Eigen::VectorXi::Zero(nt);
  for (long t = 0; t < nt; ++t) {
    const Record& r = eles[static_cast<std::size_t>(t) + 1];
    if (r.fields.size() != static_cast<std::size_t>(1 + 4 + eattr)) {
      throw InputError(ele_path + ":" + std::to_string(r.line) + ": expected " +
                       std::to_string(1 + 4 + eattr) + " fields (index n0 n1 n2 n3" +
                       (eattr > 0 ? " region" : "") + "), got " + std::to_string(r.fields.size()));
    }
    for (int k = 0; k < 4; ++k) {
      mesh.tets(k, t) = static_cast<int>(
          Integer(ele_path, r, 1 + k, "n" + std::to_string(k), first, first + n - 1) - first);
    }
    if (eattr > 0)
      mesh.regions(t) = static_cast<int>(Integer(ele_path, r, 5, "region", -1000000, 1000000));
  }
  return mesh;
}

modeling::TetMesh ReadVtu(const std::string& path) {
  modeling::VtuGrid grid;
  try {
    grid = modeling::ReadVtuGrid(path);
  } catch (const modeling::VtuError& e) {
    throw InputError(e.what());
  }
  if (grid.points.cols() == 0 || grid.cells.cols() == 0)
    throw InputError(path + ": no points or no cells: nothing to import");
  if (grid.cells.rows() != 4) {
    throw InputError(path + ": cells: " + std::to_string(grid.cells.rows()) +
                     "-node (quadratic) tetrahedra; import linear (4-node) tetrahedra, `spidarcad "
                     "fem --order 2` adds the midside nodes");
  }
  modeling::TetMesh mesh;
  mesh.nodes = grid.points;
  mesh.tets = grid.cells;
  mesh.regions = grid.regions.size() == grid.cells.cols()
                     ? grid.regions
                     : Eigen::VectorXi::Zero(grid.cells.cols()).eval();
  return mesh;
}

}  // namespace

ImportedMesh ReadMeshForImport(const std::string& path) {
  const std::string ext = LowerExtension(path);
  ImportedMesh out;
  out.format = ext;
  if (ext == "stl" || ext == "obj" || ext == "ply") {
    modeling::TriangleMesh surface;
    try {
      surface = modeling::ReadTriangleMesh(path);
    } catch (const modeling::MeshFileError& e) {
      throw InputError(e.what());
    }
    if (surface.triangles.cols() == 0) throw InputError(path + ": no triangle: nothing to import");
    out.surface = std::make_shared<modeling::TriangleMesh>(std::move(surface));
    return out;
  }
  modeling::TetMesh mesh;
  if (ext == "vtu") {
    mesh = ReadVtu(path);
  } else if (ext == "node") {
    mesh = ReadTetgen(path);
  } else {
    throw InputError(
        path + ": unknown mesh file extension '" + ext +
        "' (import reads .stl, .obj, .ply surfaces and .vtu or .node/.ele tetrahedra)");
  }
  // Positive orientation; a flat tetrahedron has no volume to simulate.
  for (Eigen::Index t = 0; t < mesh.tets.cols(); ++t) {
    for (int k = 0; k < 4; ++k) {
      if (mesh.tets(k, t) < 0 || mesh.tets(k, t) >= mesh.nodes.cols()) {
        throw InputError(path + ": tetrahedron " + std::to_string(t) + ": node " +
                         std::to_string(mesh.tets(k, t)) + " does not exist (" +
                         std::to_string(mesh.nodes.cols()) + " points)");
      }
    }
    const double volume = modeling::TetVolume(mesh, t);
    if (volume == 0.0 || !std::isfinite(volume)) {
      throw InputError(path + ": tetrahedron " + std::to_string(t) +
                       " is degenerate (zero volume): remove it or remesh");
    }
    if (volume < 0.0) {
      std::swap(mesh.tets(1, t), mesh.tets(2, t));
      ++out.flipped_tets;
    }
  }
  try {
    modeling::ValidateTetMesh(mesh);
  } catch (const std::invalid_argument& e) {
    throw InputError(path + ": " + e.what());
  }
  auto volume = std::make_shared<modeling::TetMesh>(std::move(mesh));
  out.surface = std::make_shared<modeling::TriangleMesh>(modeling::BoundarySurface(*volume));
  out.volume = std::move(volume);
  return out;
}

}  // namespace spidarcad::app
