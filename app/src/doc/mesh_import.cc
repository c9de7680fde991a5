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
  *flipped = OrientTetsPositively(
      &m, [&](Eigen::Index t) { return path + ": cell " + std::to_string(t); });
  return m;
}

}  // namespace

bool IsMeshFile(const std::string& path) {
  const std::string ext = LowerExtension(path);
  return ext == ".stl" || ext == ".obj" || ext == ".ply" || ext == ".vtu" || ext == ".node";
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
      const std::string node_text = ReadText(path);  // a missing .node is named first
      if (!fs::exists(ele)) {
        throw InputError(path + ": no " + ele + " beside it (TetGen writes the tetrahedra there)");
      }
      volume = ParseTetgenFiles(node_text, ReadText(ele), path, ele, &found.flipped_tets);
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
