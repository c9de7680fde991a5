// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
// Tests of the mesh file reader behind File → Import mesh (doc/mesh_import.h): TetGen text with
// either numbering, quadratic tets, comments, and the errors (file, line, field) of bad files.
#include "doc/mesh_import.h"

#include <gtest/gtest.h>

#include <string>

#include "doc/input_error.h"

namespace spidarcad::app {
namespace {

// The message of the InputError that `parse` throws ("" when none is thrown).
template <typename F>
std::string ErrorOf(F&& parse) {
  try {
    parse();
  } catch (const InputError& e) {
    return e.what();
  }
  return "";
}

constexpr char kTwoTetNodes[] =
    "5 3 1 1  # points, dim, one attribute, markers\n"
    "0  0 0 0  9 1\n"
    "1  1 0 0  9 1\n"
    "2  0 1 0  9 1\n"
    "3  0 0 1  9 1\n"
    "4  0 0 -1 9 1\n";

TEST(MeshImport, ReadsZeroBasedTetgenFilesWithAttributesAndOrientsEveryTet) {
  // Two tets sharing the face 0-1-2, one above and one below it: both positive afterwards, each
  // of volume 1/6.
  const modeling::TetMesh m =
      ParseTetgenFiles(kTwoTetNodes, "2 4 0\n0 0 1 2 3\n1 0 1 2 4\n", "a.node", "a.ele");
  ASSERT_EQ(m.nodes.cols(), 5);
  ASSERT_EQ(m.tets.cols(), 2);
  for (int t = 0; t < 2; ++t) EXPECT_NEAR(modeling::TetVolume(m, t), 1.0 / 6.0, 1e-15) << t;
  EXPECT_EQ(m.regions.size(), 2);
  EXPECT_EQ(m.regions.maxCoeff(), 0);
  EXPECT_EQ(m.nodes.col(4), Eigen::Vector3d(0, 0, -1));
}

TEST(MeshImport, KeepsTheCornersOfQuadraticTets) {
  const std::string nodes =
      "10 3 0 0\n1 0 0 0\n2 1 0 0\n3 0 1 0\n4 0 0 1\n5 .5 0 0\n6 .5 .5 0\n7 0 .5 0\n"
      "8 0 0 .5\n9 .5 0 .5\n10 0 .5 .5\n";
  const modeling::TetMesh m =
      ParseTetgenFiles(nodes, "1 10 0\n1 1 2 3 4 5 6 7 8 9 10\n", "q.node", "q.ele");
  ASSERT_EQ(m.tets.cols(), 1);
  EXPECT_EQ(m.tets.col(0), Eigen::Vector4i(0, 1, 2, 3));
}

TEST(MeshImport, NamesFileLineAndFieldOfBadTetgenFiles) {
  EXPECT_EQ(ErrorOf([] { ParseTetgenFiles("", "1 4 0\n0 0 1 2 3\n", "e.node", "e.ele"); }),
            "e.node: empty .node file (no header line)");
  EXPECT_EQ(ErrorOf([] { ParseTetgenFiles("4 2 0 0\n", "", "d.node", "d.ele"); }),
            "d.node:1: dimension is 2, not 3");
  EXPECT_EQ(ErrorOf([] { ParseTetgenFiles("3 3 0 0\n0 0 0 0\n1 1 0 0\n", "", "s.node", "s.ele"); }),
            "s.node:3: the header announces 3 points, the file has 2");
  EXPECT_EQ(ErrorOf([] { ParseTetgenFiles("2 3 0 0\n0 0 0 0\n2 1 0 0\n", "", "g.node", "g.ele"); }),
            "g.node:3: point number 2, expected 1");
  EXPECT_EQ(ErrorOf([] {
              ParseTetgenFiles(kTwoTetNodes, "1 4 0\n\n# c\n0 0 1 2 5\n", "a.node", "a.ele");
            }),
            "a.ele:4: node 5 is not a point of a.node");
  EXPECT_EQ(ErrorOf([] { ParseTetgenFiles(kTwoTetNodes, "1 6 0\n", "a.node", "a.ele"); }),
            "a.ele:1: nodes per tetrahedron must be 4 or 10");
  // Four points on one plane: a tet of zero volume.
  EXPECT_EQ(ErrorOf([] {
              ParseTetgenFiles("4 3 0 0\n0 0 0 0\n1 1 0 0\n2 0 1 0\n3 1 1 0\n",
                               "1 4 0\n0 0 1 2 3\n", "f.node", "f.ele");
            }),
            "f.ele:2: tetrahedron 0 has zero volume");
}

TEST(MeshImport, RecognisesMeshExtensionsInAnyCase) {
  for (const char* yes : {"a.stl", "b.OBJ", "c.Ply", "d.vtu", "e.node"})
    EXPECT_TRUE(IsMeshFile(yes));
  for (const char* no : {"a.json", "b.ele", "c", "d.vtk"}) EXPECT_FALSE(IsMeshFile(no));
}

}  // namespace
}  // namespace spidarcad::app
