// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
// Tests of the one mesh file reader (doc/mesh_import.h) behind File → Import mesh and
// `spidarcad import`: TetGen text with either numbering, quadratic tets, comments; surfaces and
// tetrahedra come back as modeling's own writers wrote them; bad files name file, line, field.
#include "doc/mesh_import.h"

#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <string>
#include <utility>

#include "doc/input_error.h"
#include "spidarcad/modeling/tet_mesh.h"
#include "spidarcad/modeling/triangle_mesh_io.h"

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

// Found while writing the .node/.ele fuzz harness (tests/fuzz/node_ele_fuzz.cc, seeds in
// tests/fuzz/corpus/node_ele): inputs the parser accepted silently or refused with a wrong reason.
constexpr char kOneTetNodes[] = "4 3 0 0\n0 0 0 0\n1 1 0 0\n2 0 1 0\n3 0 0 1\n";

TEST(MeshImport, TetgenLinesBeyondTheHeaderCountsAreRefusedNotDropped) {
  EXPECT_EQ(ErrorOf([] {
              ParseTetgenFiles(std::string(kOneTetNodes) + "4 1 1 1\n", "1 4 0\n0 0 1 2 3\n",
                               "x.node", "x.ele");
            }),
            "x.node:6: the header announces 4 points, the file has 5 (fix the count in the "
            "header or remove the extra lines)");
  EXPECT_EQ(ErrorOf([] {
              ParseTetgenFiles(kOneTetNodes, "1 4 0\n0 0 1 2 3\n# more\n1 0 1 2 3\n", "x.node",
                               "x.ele");
            }),
            "x.ele:4: the header announces 1 tetrahedra, the file has 2 (fix the count in the "
            "header or remove the extra lines)");
}

TEST(MeshImport, TetgenTetrahedronNumbersAreCheckedLikePointNumbers) {
  const std::string two = std::string(kTwoTetNodes);
  EXPECT_EQ(
      ErrorOf([&] { ParseTetgenFiles(two, "2 4 0\n0 0 1 2 3\nx 0 1 2 4\n", "a.node", "a.ele"); }),
      "a.ele:3: tetrahedron number is not a finite number: 'x'");
  EXPECT_EQ(
      ErrorOf([&] { ParseTetgenFiles(two, "2 4 0\n0 0 1 2 3\n5 0 1 2 4\n", "a.node", "a.ele"); }),
      "a.ele:3: tetrahedron number 5, expected 1");
  EXPECT_EQ(ErrorOf([&] { ParseTetgenFiles(two, "1 4 0\n7 0 1 2 3\n", "a.node", "a.ele"); }),
            "a.ele:2: tetrahedron number 7: numbering starts from 0 or 1");
  // The numbering of the tetrahedra is their own: 1-based tets over 0-based points.
  EXPECT_EQ(ParseTetgenFiles(two, "1 4 0\n1 0 1 2 3\n", "a.node", "a.ele").tets.cols(), 1);
}

TEST(MeshImport, TetgenQuadraticTetsHaveTheirEdgeNodesChecked) {
  const std::string nodes =
      "10 3 0 0\n1 0 0 0\n2 1 0 0\n3 0 1 0\n4 0 0 1\n5 .5 0 0\n6 .5 .5 0\n7 0 .5 0\n"
      "8 0 0 .5\n9 .5 0 .5\n10 0 .5 .5\n";
  EXPECT_EQ(ErrorOf([&] { ParseTetgenFiles(nodes, "1 10 0\n1 1 2 3 4\n", "q.node", "q.ele"); }),
            "q.ele:2: a node number is missing");
  EXPECT_EQ(ErrorOf([&] {
              ParseTetgenFiles(nodes, "1 10 0\n1 1 2 3 4 5 6 7 8 9 11\n", "q.node", "q.ele");
            }),
            "q.ele:2: node 11 is not a point of q.node");
}

TEST(MeshImport, TetgenAttributesThatArePresentAreNumbers) {
  EXPECT_EQ(ErrorOf([] {
              ParseTetgenFiles("4 3 1 1\n0 0 0 0 2.5 1\n1 1 0 0 2.5 one\n2 0 1 0\n3 0 0 1\n",
                               "1 4 0\n0 0 1 2 3\n", "m.node", "m.ele");
            }),
            "m.node:3: the boundary marker is not a finite number: 'one'");
  EXPECT_EQ(ErrorOf([] {
              ParseTetgenFiles("4 3 1 0\n0 0 0 0 nan\n1 1 0 0\n2 0 1 0\n3 0 0 1\n",
                               "1 4 0\n0 0 1 2 3\n", "m.node", "m.ele");
            }),
            "m.node:2: an attribute is not a finite number: 'nan'");
  // Left out, they read as TetGen reads them (0): accepted.
  EXPECT_EQ(ParseTetgenFiles("4 3 2 1\n0 0 0 0\n1 1 0 0 3\n2 0 1 0\n3 0 0 1 1 2 1\n",
                             "1 4 0\n0 0 1 2 3\n", "m.node", "m.ele")
                .nodes.cols(),
            4);
}

TEST(MeshImport, TetgenSubnormalCoordinatesAreReadAndOverflowIsRefused) {
  // strtod flags a subnormal result with ERANGE; std::stod threw for it, refusing a coordinate
  // that spidarcad's own writer prints (%.17g) for a subnormal value.
  const modeling::TetMesh m = ParseTetgenFiles("4 3 0 0\n0 0 0 1e-310\n1 1 0 0\n2 0 1 0\n3 0 0 1\n",
                                               "1 4 0\n0 0 1 2 3\n", "s.node", "s.ele");
  EXPECT_EQ(m.nodes(2, 0), 1e-310);
  EXPECT_EQ(ErrorOf([] {
              ParseTetgenFiles("4 3 0 0\n0 0 0 0\n1 1e400 0 0\n2 0 1 0\n3 0 0 1\n",
                               "1 4 0\n0 0 1 2 3\n", "s.node", "s.ele");
            }),
            "s.node:3: x is not a finite number: '1e400'");
  // Finite coordinates whose volume is beyond the largest double: not "zero volume".
  EXPECT_EQ(ErrorOf([] {
              ParseTetgenFiles("4 3 0 0\n0 0 0 0\n1 1e200 0 0\n2 0 1e200 0\n3 0 0 1e200\n",
                               "1 4 0\n0 0 1 2 3\n", "h.node", "h.ele");
            }),
            "h.ele:2: tetrahedron 0 has a volume beyond the largest double (its coordinates are "
            "too large)");
}

// Found by the node_ele fuzz harness in CI
// (tests/fuzz/regressions/node_ele/repeated_corner.node_ele): a tetrahedron that names one point
// twice has zero volume, but its computed triple product need not be exactly 0 (here u . (u x w)
// rounds to a nonzero value), so the volume test let it in.
TEST(MeshImport, TetgenTetrahedraThatRepeatAPointAreRefusedWhateverTheirRoundedVolume) {
  const char* nodes = "4 3 0 0\n0 0 5 1e-310\n1 1 0 0\n2 0 1 0\n3 0 0 1\n";
  EXPECT_EQ(ErrorOf([&] { ParseTetgenFiles(nodes, "1 4 0\n1 0 1 1 3\n", "r.node", "r.ele"); }),
            "r.ele:2: tetrahedron 1 repeats node 1 (a tetrahedron needs four distinct corners)");
  EXPECT_EQ(ErrorOf([&] { ParseTetgenFiles(nodes, "1 4 0\n0 3 1 2 3\n", "r.node", "r.ele"); }),
            "r.ele:2: tetrahedron 0 repeats node 3 (a tetrahedron needs four distinct corners)");
}

TEST(MeshImport, TetgenErrorsQuoteBadWordsPrintablyAndShortened) {
  EXPECT_EQ(ErrorOf([] { ParseTetgenFiles("1 3 0 0\n0 0 0 \x01z\x7f\n", "", "b.node", "b.ele"); }),
            "b.node:2: z is not a finite number: '\\x01z\\x7f'");
  EXPECT_EQ(ErrorOf([] {
              ParseTetgenFiles("1 3 0 0\n0 0 0 " + std::string(100, '7') + "x\n", "", "b.node",
                               "b.ele");
            }),
            "b.node:2: z is not a finite number: '" + std::string(40, '7') + "...'");
}

TEST(MeshImport, RecognisesMeshExtensionsInAnyCase) {
  for (const char* yes : {"a.stl", "b.OBJ", "c.Ply", "d.vtu", "e.node"})
    EXPECT_TRUE(IsMeshFile(yes));
  for (const char* no : {"a.json", "b.ele", "c", "d.vtk"}) EXPECT_FALSE(IsMeshFile(no));
}

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

std::string FileErrorOf(const std::string& path) {
  try {
    ReadMeshFile(path);
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
  MeshFileInfo info;
  const MeshData read = ReadMeshFile(base + ".node", &info);
  ASSERT_TRUE(read.volume);
  EXPECT_EQ(info.format, "node");
  EXPECT_EQ(read.volume->nodes, written.nodes);
  EXPECT_EQ(read.volume->tets.col(0), written.tets.col(0));
  EXPECT_EQ(read.volume->regions, written.regions);
  EXPECT_EQ(info.flipped_tets, 1);
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
  MeshFileInfo vtu_info;
  const MeshData from_vtu = ReadMeshFile(vtu, &vtu_info);
  ASSERT_TRUE(from_vtu.volume);
  EXPECT_EQ(from_vtu.volume->tets, positive.tets);
  EXPECT_EQ(from_vtu.volume->regions, positive.regions);
  EXPECT_EQ(vtu_info.flipped_tets, 0);

  const std::string stl = OutputPath("two.stl");
  modeling::WriteTriangleMesh(*from_vtu.surface, stl, modeling::MeshFileFormat::kStlAscii);
  const MeshData from_stl = ReadMeshFile(stl);
  EXPECT_FALSE(from_stl.volume);
  ASSERT_TRUE(from_stl.surface);
  EXPECT_EQ(from_stl.surface->triangles.cols(), 6);
  EXPECT_EQ(from_stl.surface->vertices.cols(), 5);
}

TEST(MeshImport, BadFilesNameTheFileLineAndFieldThroughReadMeshFile) {
  const std::string base = OutputPath("bad");
  std::ofstream(base + ".node") << "# points\n4 3 0 0\n0 0 0 0\n1 1 0 0\n2 0 x 0\n3 0 0 1\n";
  std::ofstream(base + ".ele") << "1 4 0\n0 0 1 2 3\n";
  std::string what = FileErrorOf(base + ".node");
  EXPECT_NE(what.find(base + ".node:5: y is not a finite number: 'x'"), std::string::npos) << what;

  std::ofstream(base + ".node") << "4 3 0 0\n0 0 0 0\n1 1 0 0\n2 0 1 0\n3 0 0 1\n";
  std::ofstream(base + ".ele") << "1 4 0\n0 0 1 2 9\n";
  what = FileErrorOf(base + ".node");
  EXPECT_NE(what.find(base + ".ele:2: node 9 is not a point of " + base + ".node"),
            std::string::npos)
      << what;

  std::ofstream(base + ".ele") << "1 4 0\n0 0 1 2 0\n";
  what = FileErrorOf(base + ".node");
  EXPECT_NE(what.find("tetrahedron 0"), std::string::npos) << what;

  // A .node that is not there is named, not its .ele; a .ele that is not there is named next.
  const std::string missing = OutputPath("missing");
  std::filesystem::remove(missing + ".node");  // written below by an earlier run
  std::filesystem::remove(missing + ".ele");
  what = FileErrorOf(missing + ".node");
  EXPECT_NE(what.find(missing + ".node: cannot open the file"), std::string::npos) << what;
  std::ofstream(missing + ".node") << "4 3 0 0\n0 0 0 0\n1 1 0 0\n2 0 1 0\n3 0 0 1\n";
  what = FileErrorOf(missing + ".node");
  EXPECT_NE(what.find("no " + missing + ".ele beside it"), std::string::npos) << what;

  // A .vtu cell that names one point twice (whatever its rounded volume): refused by the reader.
  const std::string vtu = OutputPath("repeated.vtu");
  std::ofstream(vtu) << "<?xml version=\"1.0\"?>\n<VTKFile type=\"UnstructuredGrid\" "
                        "version=\"0.1\" byte_order=\"LittleEndian\">\n<UnstructuredGrid>\n"
                        "<Piece NumberOfPoints=\"4\" NumberOfCells=\"1\">\n<Points>\n"
                        "<DataArray type=\"Float64\" NumberOfComponents=\"3\" format=\"ascii\">\n"
                        "0 5 1e-310 1 0 0 0 1 0 0 0 1\n</DataArray>\n</Points>\n<Cells>\n"
                        "<DataArray type=\"Int64\" Name=\"connectivity\" format=\"ascii\">\n"
                        "0 1 1 3\n</DataArray>\n"
                        "<DataArray type=\"Int64\" Name=\"offsets\" format=\"ascii\">\n4\n"
                        "</DataArray>\n"
                        "<DataArray type=\"UInt8\" Name=\"types\" format=\"ascii\">\n10\n"
                        "</DataArray>\n</Cells>\n</Piece>\n</UnstructuredGrid>\n</VTKFile>\n";
  what = FileErrorOf(vtu);
  EXPECT_NE(
      what.find(vtu + ": byte 294: <DataArray Name=\"connectivity\">: cell 0 names point 1 twice"),
      std::string::npos)
      << what;

  const std::string stl = OutputPath("bad.stl");
  std::ofstream(stl) << "solid x\n facet normal 0 0 1\n  outer loop\n   vertex 0 0 zero\n";
  what = FileErrorOf(stl);
  EXPECT_NE(what.find(stl + ":4"), std::string::npos) << what;

  what = FileErrorOf(OutputPath("part.step"));
  EXPECT_NE(what.find("part.step: not a mesh file (import .stl, .obj, .ply, .vtu or .node)"),
            std::string::npos)
      << what;
  what = FileErrorOf(OutputPath("missing.node"));
  EXPECT_NE(what.find("missing.node: no "), std::string::npos) << what;
  EXPECT_NE(what.find("missing.ele beside it"), std::string::npos) << what;
}

}  // namespace
}  // namespace spidarcad::app
