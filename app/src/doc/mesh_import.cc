// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#include "doc/mesh_import.h"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <memory>
#include <sstream>
#include <vector>

#include "doc/input_error.h"
#include "spidarcad/modeling/cgal_mesher.h"
#include "spidarcad/modeling/tet_mesh.h"
#include "spidarcad/modeling/triangle_mesh_io.h"

namespace spidarcad::app {

namespace {

namespace fs = std::filesystem;

std::string LowerExtension(const std::string& path) {
  std::string ext = fs::path(path).extension().string();
  for (char& c : ext) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return ext;
}

std::string ReadText(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw InputError(path + ": cannot open the file (check the path and permissions)");
  std::stringstream text;
  text << in.rdbuf();
  return text.str();
}

// The non-empty lines of a TetGen file without their '#' comments, with their 1-based numbers,
// each split into words.
struct Line {
  int number = 0;
  std::vector<std::string> words;
};

std::vector<Line> SplitLines(const std::string& text) {
  std::vector<Line> out;
  std::istringstream in(text);
  std::string raw;
  int number = 0;
  while (std::getline(in, raw)) {
    ++number;
    raw = raw.substr(0, raw.find('#'));
    std::istringstream words(raw);
    Line line{number, {}};
    for (std::string w; words >> w;) line.words.push_back(w);
    if (!line.words.empty()) out.push_back(std::move(line));
  }
  return out;
}

[[noreturn]] void Fail(const std::string& file, int line, const std::string& what) {
  throw InputError(file + ":" + std::to_string(line) + ": " + what);
}

double Number(const std::string& file, const Line& line, int k, const char* field) {
  if (k >= static_cast<int>(line.words.size()))
    Fail(file, line.number, std::string(field) + " is missing");
  const std::string& w = line.words[k];
  try {
    size_t used = 0;
    const double v = std::stod(w, &used);
    if (used == w.size() && std::isfinite(v)) return v;
  } catch (const std::exception&) {
  }
  Fail(file, line.number, std::string(field) + " is not a finite number: '" + w + "'");
}

long Integer(const std::string& file, const Line& line, int k, const char* field) {
  const double v = Number(file, line, k, field);
  if (v != std::floor(v) || std::abs(v) > 2e9)
    Fail(file, line.number, std::string(field) + " is not an integer: '" + line.words[k] + "'");
  return static_cast<long>(v);
}

double SignedVolume(const modeling::TetMesh& m, Eigen::Index t) {
  const Eigen::Vector3d a = m.nodes.col(m.tets(0, t)), b = m.nodes.col(m.tets(1, t)),
                        c = m.nodes.col(m.tets(2, t)), d = m.nodes.col(m.tets(3, t));
  return (b - a).dot((c - a).cross(d - a)) / 6.0;
}

// Flips negatively oriented tets; throws naming the first degenerate one (`where(t)` says
// where tet t came from).
// Returns the number flipped.
template <typename Where>
int OrientTets(modeling::TetMesh* m, Where&& where) {
  int flipped = 0;
  for (Eigen::Index t = 0; t < m->tets.cols(); ++t) {
    const double v = SignedVolume(*m, t);
    if (v == 0.0 || !std::isfinite(v)) throw InputError(where(t) + " has zero volume");
    if (v < 0.0) {
      std::swap(m->tets(1, t), m->tets(2, t));
      ++flipped;
    }
  }
  return flipped;
}

modeling::TetMesh FromVtu(const std::string& path, int* flipped) {
  modeling::VtuGrid grid;
  try {
    grid = modeling::ReadVtuGrid(path);
  } catch (const std::exception& e) {
    throw InputError(e.what());
  }
  if (grid.cells.cols() == 0) throw InputError(path + ": the file holds no tetrahedra");
  modeling::TetMesh m;
  m.nodes = grid.points;
  m.tets = grid.cells.topRows(4);
  m.regions = grid.regions.size() == grid.cells.cols() ? grid.regions
                                                       : Eigen::VectorXi::Zero(grid.cells.cols());
  *flipped = OrientTets(&m, [&](Eigen::Index t) { return path + ": cell " + std::to_string(t); });
  return m;
}

}  // namespace

bool IsMeshFile(const std::string& path) {
  const std::string ext = LowerExtension(path);
  return ext == ".stl" || ext == ".obj" || ext == ".ply" || ext == ".vtu" || ext == ".node";
}

modeling::TetMesh ParseTetgenFiles(const std::string& node_text, const std::string& ele_text,
                                   const std::string& node_file, const std::string& ele_file,
                                   int* flipped) {
  const std::vector<Line> nodes = SplitLines(node_text);
  if (nodes.empty()) throw InputError(node_file + ": empty .node file (no header line)");
  const Line& nh = nodes[0];
  const long count = Integer(node_file, nh, 0, "the number of points");
  const long dim = nh.words.size() > 1 ? Integer(node_file, nh, 1, "the dimension") : 3;
  const long attributes = nh.words.size() > 2 ? Integer(node_file, nh, 2, "attributes") : 0;
  const long markers = nh.words.size() > 3 ? Integer(node_file, nh, 3, "boundary markers") : 0;
  if (dim != 3) Fail(node_file, nh.number, "dimension is " + std::to_string(dim) + ", not 3");
  if (count <= 0) Fail(node_file, nh.number, "the number of points must be > 0");
  if (attributes < 0 || markers < 0 || markers > 1)
    Fail(node_file, nh.number, "attributes must be >= 0 and boundary markers 0 or 1");
  if (static_cast<long>(nodes.size()) - 1 < count) {
    Fail(node_file, nodes.back().number,
         "the header announces " + std::to_string(count) + " points, the file has " +
             std::to_string(nodes.size() - 1));
  }
  modeling::TetMesh m;
  m.nodes.resize(3, count);
  long base = 0;
  for (long k = 0; k < count; ++k) {
    const Line& line = nodes[k + 1];
    const long index = Integer(node_file, line, 0, "the point number");
    if (k == 0) {
      if (index != 0 && index != 1)
        Fail(node_file, line.number, "points must be numbered from 0 or 1");
      base = index;
    } else if (index != base + k) {
      Fail(node_file, line.number,
           "point number " + std::to_string(index) + ", expected " + std::to_string(base + k));
    }
    for (int i = 0; i < 3; ++i) {
      static const char* kAxes[3] = {"x", "y", "z"};
      m.nodes(i, k) = Number(node_file, line, 1 + i, kAxes[i]);
    }
  }

  const std::vector<Line> eles = SplitLines(ele_text);
  if (eles.empty()) throw InputError(ele_file + ": empty .ele file (no header line)");
  const Line& eh = eles[0];
  const long tets = Integer(ele_file, eh, 0, "the number of tetrahedra");
  const long per = eh.words.size() > 1 ? Integer(ele_file, eh, 1, "nodes per tetrahedron") : 4;
  const long region = eh.words.size() > 2 ? Integer(ele_file, eh, 2, "region attribute") : 0;
  if (tets <= 0) Fail(ele_file, eh.number, "the number of tetrahedra must be > 0");
  if (per != 4 && per != 10) Fail(ele_file, eh.number, "nodes per tetrahedron must be 4 or 10");
  if (static_cast<long>(eles.size()) - 1 < tets) {
    Fail(ele_file, eles.back().number,
         "the header announces " + std::to_string(tets) + " tetrahedra, the file has " +
             std::to_string(eles.size() - 1));
  }
  m.tets.resize(4, tets);
  m.regions = Eigen::VectorXi::Zero(tets);  // 0: unknown, as TetGen without -A
  for (long t = 0; t < tets; ++t) {
    const Line& line = eles[t + 1];
    for (int c = 0; c < 4; ++c) {
      const long n = Integer(ele_file, line, 1 + c, "a node number") - base;
      if (n < 0 || n >= count) {
        Fail(ele_file, line.number,
             "node " + line.words[1 + c] + " is not a point of " + node_file);
      }
      m.tets(c, t) = static_cast<int>(n);
    }
    if (region > 0) m.regions(t) = static_cast<int>(Integer(ele_file, line, 1 + per, "the region"));
  }
  const int flips = OrientTets(&m, [&](Eigen::Index t) {
    return ele_file + ":" + std::to_string(eles[t + 1].number) + ": tetrahedron " +
           eles[t + 1].words[0];
  });
  if (flipped != nullptr) *flipped = flips;
  return m;
}

MeshData ReadMeshFile(const std::string& path, MeshFileInfo* info) {
  const std::string ext = LowerExtension(path);
  MeshData data;
  data.import_source = path;
  MeshFileInfo found;
  found.format = ext.empty() ? ext : ext.substr(1);
  if (ext == ".stl" || ext == ".obj" || ext == ".ply") {
    modeling::TriangleMesh mesh;
    try {
      mesh = modeling::ReadTriangleMesh(path);
    } catch (const std::exception& e) {
      throw InputError(e.what());
    }
    if (mesh.triangles.cols() == 0) throw InputError(path + ": the file holds no triangles");
    data.surface = std::make_shared<const modeling::TriangleMesh>(std::move(mesh));
  } else if (ext == ".vtu" || ext == ".node") {
    modeling::TetMesh volume;
    if (ext == ".vtu") {
      volume = FromVtu(path, &found.flipped_tets);
    } else {
      const std::string ele = fs::path(path).replace_extension(".ele").string();
      if (!fs::exists(ele)) {
        throw InputError(path + ": no " + ele + " beside it (TetGen writes the tetrahedra there)");
      }
      volume = ParseTetgenFiles(ReadText(path), ReadText(ele), path, ele, &found.flipped_tets);
    }
    try {
      modeling::ValidateTetMesh(volume);
    } catch (const std::invalid_argument& e) {
      throw InputError(path + ": " + e.what());
    }
    data.surface =
        std::make_shared<const modeling::TriangleMesh>(modeling::BoundarySurface(volume));
    data.volume = std::make_shared<const modeling::TetMesh>(std::move(volume));
  } else {
    throw InputError(path + ": not a mesh file (import .stl, .obj, .ply, .vtu or .node)");
  }
  if (info != nullptr) *info = found;
  return data;
}

}  // namespace spidarcad::app
