// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#include "spidarcad/modeling/tet_mesh.h"

#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include <gtest/gtest.h>

namespace spidarcad::modeling {
namespace {

std::string OutPath(const std::string& name) { return std::string(SPIDARCAD_TEST_OUTPUT_DIR) + "/" + name; }

std::string ReadText(const std::string& path) {
  std::ifstream in(path);
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

// Two tets sharing a face: a triangular bipyramid.
TetMesh Bipyramid() {
  TetMesh m;
  m.nodes.resize(3, 5);
  m.nodes << 0, 1, 0, 0.3, 0.3,  //
      0, 0, 1, 0.3, 0.3,         //
      0, 0, 0, 1, -1;
  m.tets.resize(4, 2);
  m.tets << 0, 0,  //
      1, 2,        //
      2, 1,        //
      3, 4;
  m.regions.resize(2);
  m.regions << 7, 9;
  return m;
}

// The numbers inside <DataArray ... Name="name" ...>...</DataArray>.
std::vector<double> ArrayValues(const std::string& xml, const std::string& name) {
  const auto at = xml.find("Name=\"" + name + "\"");
  if (at == std::string::npos) return {};
  const auto begin = xml.find('>', at) + 1, end = xml.find("</DataArray>", at);
  std::istringstream in(xml.substr(begin, end - begin));
  std::vector<double> v;
  for (double x; in >> x;) v.push_back(x);
  return v;
}

TEST(TetMeshIo, VtuHoldsGeometryTopologyAndData) {
  const TetMesh mesh = Bipyramid();
  ASSERT_GT(TetVolume(mesh, 0), 0);
  ASSERT_GT(TetVolume(mesh, 1), 0);
  Eigen::MatrixXd temperature(1, 5), displacement(3, 5), stress(1, 2);
  temperature << 1, 2, 3, 4, 5;
  displacement.setZero();
  displacement(2, 3) = 0.25;
  stress << 1e6, -2e6;
  const std::string path = OutPath("bipyramid.vtu");
  WriteVtu(mesh, path, {{"temperature", temperature}, {"displacement", displacement}}, {{"stress", stress}});
  const std::string xml = ReadText(path);
  EXPECT_NE(xml.find("NumberOfPoints=\"5\" NumberOfCells=\"2\""), std::string::npos);
  EXPECT_EQ(ArrayValues(xml, "connectivity"), (std::vector<double>{0, 1, 2, 3, 0, 2, 1, 4}));
  EXPECT_EQ(ArrayValues(xml, "offsets"), (std::vector<double>{4, 8}));
  EXPECT_EQ(ArrayValues(xml, "types"), (std::vector<double>{10, 10}));
  EXPECT_EQ(ArrayValues(xml, "region"), (std::vector<double>{7, 9}));
  EXPECT_EQ(ArrayValues(xml, "temperature"), (std::vector<double>{1, 2, 3, 4, 5}));
  EXPECT_EQ(ArrayValues(xml, "stress"), (std::vector<double>{1e6, -2e6}));
  const std::vector<double> disp = ArrayValues(xml, "displacement");
  ASSERT_EQ(disp.size(), 15u);
  EXPECT_EQ(disp[3 * 3 + 2], 0.25);
  const std::vector<double> points = ArrayValues(xml, "Points");
  ASSERT_EQ(points.size(), 15u);
  for (int i = 0; i < 15; ++i) EXPECT_EQ(points[i], mesh.nodes.data()[i]);
  // Each tet's volume by hand: base triangle (0,0,0), (1,0,0), (0,1,0) of area 1/2, height 1.
  const std::vector<double> volume = ArrayValues(xml, "volume");
  ASSERT_EQ(volume.size(), 2u);
  EXPECT_NEAR(volume[0], 1.0 / 6.0, 1e-15);
  EXPECT_NEAR(volume[1], 1.0 / 6.0, 1e-15);
}

TEST(TetMeshIo, TetgenNodeAndEleFilesListEverything) {
  const TetMesh mesh = Bipyramid();
  WriteTetgenFiles(mesh, OutPath("bipyramid"));
  std::istringstream node(ReadText(OutPath("bipyramid.node")));
  std::string line;
  std::getline(node, line);  // comment
  int n, dim, attributes, markers;
  node >> n >> dim >> attributes >> markers;
  ASSERT_EQ(n, 5);
  EXPECT_EQ(dim, 3);
  for (int i = 0; i < 5; ++i) {
    int index;
    double x, y, z;
    node >> index >> x >> y >> z;
    EXPECT_EQ(index, i);
    EXPECT_EQ(Eigen::Vector3d(x, y, z), mesh.nodes.col(i));
  }
  std::istringstream ele(ReadText(OutPath("bipyramid.ele")));
  std::getline(ele, line);
  int nt, corners, region_attributes;
  ele >> nt >> corners >> region_attributes;
  ASSERT_EQ(nt, 2);
  EXPECT_EQ(corners, 4);
  for (int t = 0; t < 2; ++t) {
    int index, a, b, c, d, region;
    ele >> index >> a >> b >> c >> d >> region;
    EXPECT_EQ(Eigen::Vector4i(a, b, c, d), mesh.tets.col(t));
    EXPECT_EQ(region, mesh.regions[t]);
  }
}

TEST(TetMeshIo, BadMeshOrArraysOrPathAreErrors) {
  TetMesh mesh = Bipyramid();
  EXPECT_THROW(WriteVtu(mesh, OutPath("x.vtu"), {{"t", Eigen::MatrixXd::Zero(1, 4)}}), std::invalid_argument);
  EXPECT_THROW(WriteVtu(mesh, OutPath("x.vtu"), {}, {{"region", Eigen::MatrixXd::Zero(1, 2)}}), std::invalid_argument);
  try {
    WriteVtu(mesh, "/nonexistent/dir/x.vtu");
    ADD_FAILURE();
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("/nonexistent/dir/x.vtu"), std::string::npos);
  }
  mesh.tets(3, 1) = 5;
  EXPECT_THROW(WriteTetgenFiles(mesh, OutPath("bad")), std::invalid_argument);
}

}  // namespace
}  // namespace spidarcad::modeling
