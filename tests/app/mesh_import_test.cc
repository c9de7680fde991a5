// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
// Mesh files read for import (scene/mesh_import.cc): surfaces and tetrahedra come back as
// written by modeling's own writers; bad files name the file, line and field.
#include "scene/mesh_import.h"

#include <gtest/gtest.h>

#include <cmath>
#include <fstream>
#include <string>
#include <utility>

#include "doc/input_error.h"
#include "spidarcad/modeling/triangle_mesh_io.h"

namespace spidarcad::app {
namespace {

std::string OutputPath(const std::string& name) {
  return std::string(SPIDARCAD_TEST_OUTPUT_DIR) + "/mesh_import_" + name;
}

// Two tetrahedra sharing the face (1, 2, 3); the second one written with negative orientation.
modeling::TetMesh TwoTets() {
  modeling::TetMesh m;
  m.nodes.resize(3, 5);
  m.nodes << 0, 1, 0, 0, 1, 0, 0, 1, 0, 1, 0, 0, 0, 1, 1;
  m.tets.resize(4, 2);
  m.tets << 0, 4, 1, 1, 2, 2, 3, 3;
  m.regions.resize(2);
  m.regions << 1, 2;
  return m;
}

std::string ErrorOf(const std::string& path) {
  try {
    ReadMeshForImport(path);
  } catch (const InputError& e) {
    return e.what();
  }
  return "(no error)";
}

TEST(MeshImport, TetgenFilesComeBackWithRegionsAndPositiveOrientation) {
  const modeling::TetMesh written = TwoTets();
  ASSERT_GT(modeling::TetVolume(written, 0), 0.0);
  ASSERT_LT(modeling::TetVolume(written, 1), 0.0);
  const std::string base = OutputPath("two");
  modeling::WriteTetgenFiles(written, base);
  const ImportedMesh read = ReadMeshForImport(base + ".node");
  ASSERT_TRUE(read.volume);
  EXPECT_EQ(read.format, "node");
  EXPECT_EQ(read.volume->nodes, written.nodes);
  EXPECT_EQ(read.volume->tets.col(0), written.tets.col(0));
  EXPECT_EQ(read.volume->regions, written.regions);
  EXPECT_EQ(read.flipped_tets, 1);
  EXPECT_GT(modeling::TetVolume(*read.volume, 1), 0.0);
  EXPECT_NEAR(modeling::TotalVolume(*read.volume),
              std::abs(modeling::TetVolume(written, 0)) + std::abs(modeling::TetVolume(written, 1)),
              1e-15);
  // The boundary of two tetrahedra glued on a face: 6 triangles.
  ASSERT_TRUE(read.surface);
  EXPECT_EQ(read.surface->triangles.cols(), 6);
}

TEST(MeshImport, VtuAndStlComeBackAsWritten) {
  const modeling::TetMesh written = TwoTets();
  modeling::TetMesh positive = written;
  std::swap(positive.tets(1, 1), positive.tets(2, 1));
  const std::string vtu = OutputPath("two.vtu");
  modeling::WriteVtu(positive, vtu);
  const ImportedMesh from_vtu = ReadMeshForImport(vtu);
  ASSERT_TRUE(from_vtu.volume);
  EXPECT_EQ(from_vtu.volume->tets, positive.tets);
  EXPECT_EQ(from_vtu.volume->regions, positive.regions);
  EXPECT_EQ(from_vtu.flipped_tets, 0);

  const std::string stl = OutputPath("two.stl");
  modeling::WriteTriangleMesh(*from_vtu.surface, stl, modeling::MeshFileFormat::kStlAscii);
  const ImportedMesh from_stl = ReadMeshForImport(stl);
  EXPECT_FALSE(from_stl.volume);
  ASSERT_TRUE(from_stl.surface);
  EXPECT_EQ(from_stl.surface->triangles.cols(), 6);
  EXPECT_EQ(from_stl.surface->vertices.cols(), 5);
}

TEST(MeshImport, BadFilesNameTheFileLineAndField) {
  const std::string base = OutputPath("bad");
  std::ofstream(base + ".node") << "# points\n4 3 0 0\n0 0 0 0\n1 1 0 0\n2 0 x 0\n3 0 0 1\n";
  std::ofstream(base + ".ele") << "1 4 0\n0 0 1 2 3\n";
  std::string what = ErrorOf(base + ".node");
  EXPECT_NE(what.find(base + ".node:5: field y: 'x' is not a finite number"), std::string::npos)
      << what;

  std::ofstream(base + ".node") << "4 3 0 0\n0 0 0 0\n1 1 0 0\n2 0 1 0\n3 0 0 1\n";
  std::ofstream(base + ".ele") << "1 4 0\n0 0 1 2 9\n";
  what = ErrorOf(base + ".node");
  EXPECT_NE(what.find(base + ".ele:2: field n3: '9' is not an integer in [0, 3]"),
            std::string::npos)
      << what;

  std::ofstream(base + ".ele") << "1 4 0\n0 0 1 2 0\n";
  what = ErrorOf(base + ".node");
  EXPECT_NE(what.find("tetrahedron 0"), std::string::npos) << what;

  const std::string stl = OutputPath("bad.stl");
  std::ofstream(stl) << "solid x\n facet normal 0 0 1\n  outer loop\n   vertex 0 0 zero\n";
  what = ErrorOf(stl);
  EXPECT_NE(what.find(stl + ":4"), std::string::npos) << what;

  what = ErrorOf(OutputPath("part.step"));
  EXPECT_NE(what.find("unknown mesh file extension 'step'"), std::string::npos) << what;
  what = ErrorOf(OutputPath("missing.node"));
  EXPECT_NE(what.find("missing.node: cannot open"), std::string::npos) << what;
}

}  // namespace
}  // namespace spidarcad::app
