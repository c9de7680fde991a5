// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#include <gtest/gtest.h>

#include <cstdio>
#include <fstream>
#include <random>
#include <sstream>
#include <string>
#include <vector>

#include "spidarcad/modeling/tet_mesh.h"
#include "support/byte_mutator.h"
namespace spidarcad::modeling {
namespace {

std::string OutPath(const std::string& name) {
  return std::string(SPIDARCAD_TEST_OUTPUT_DIR) + "/" + name;
}

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
  WriteVtu(mesh, path, {{"temperature", temperature}, {"displacement", displacement}},
           {{"stress", stress}});
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
  EXPECT_THROW(WriteVtu(mesh, OutPath("x.vtu"), {{"t", Eigen::MatrixXd::Zero(1, 4)}}),
               std::invalid_argument);
  EXPECT_THROW(WriteVtu(mesh, OutPath("x.vtu"), {}, {{"region", Eigen::MatrixXd::Zero(1, 2)}}),
               std::invalid_argument);
  try {
    WriteVtu(mesh, "/nonexistent/dir/x.vtu");
    ADD_FAILURE();
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("/nonexistent/dir/x.vtu"), std::string::npos);
  }
  mesh.tets(3, 1) = 5;
  EXPECT_THROW(WriteTetgenFiles(mesh, OutPath("bad")), std::invalid_argument);
}

// A quadratic (10-node) grid with regions and arrays, k by N.
VtuGrid QuadraticGrid() {
  const TetMesh lin = Bipyramid();
  VtuGrid g;
  // Corners, then one midside node per edge of each tet (not shared: enough for IO).
  g.points.resize(3, 5 + 12);
  g.points.leftCols(5) = lin.nodes;
  g.cells.resize(10, 2);
  static constexpr int kEdges[6][2] = {{0, 1}, {1, 2}, {0, 2}, {0, 3}, {1, 3}, {2, 3}};
  for (int t = 0; t < 2; ++t) {
    for (int k = 0; k < 4; ++k) g.cells(k, t) = lin.tets(k, t);
    for (int k = 0; k < 6; ++k) {
      const int v = 5 + 6 * t + k;
      g.points.col(v) = 0.5 * (lin.nodes.col(lin.tets(kEdges[k][0], t)) +
                               lin.nodes.col(lin.tets(kEdges[k][1], t)));
      g.cells(4 + k, t) = v;
    }
  }
  g.regions = lin.regions;
  Eigen::MatrixXd disp(3, 17);
  for (int v = 0; v < 17; ++v) disp.col(v) = Eigen::Vector3d(v, -0.5 * v, 1.0 / (v + 1));
  g.point_data["displacement"] = disp;
  g.cell_data["stress"] = Eigen::RowVector2d(1e6, -2.5e-7);
  return g;
}

TEST(VtuGrid, WriteThenParseIsExactForBothEncodingsAndKeepsTheKByNOrientation) {
  const VtuGrid g = QuadraticGrid();
  for (VtuEncoding enc : {VtuEncoding::kAscii, VtuEncoding::kAppendedRaw}) {
    const std::string path =
        OutPath(enc == VtuEncoding::kAscii ? "grid_ascii.vtu" : "grid_raw.vtu");
    WriteVtuGrid(g, path, enc);
    const VtuGrid back = ReadVtuGrid(path);
    EXPECT_EQ(back.points, g.points);
    EXPECT_EQ(back.cells, g.cells);
    EXPECT_EQ(back.regions, g.regions);
    ASSERT_EQ(back.point_data.count("displacement"), 1u);
    EXPECT_EQ(back.point_data.at("displacement"), g.point_data.at("displacement"));
    EXPECT_EQ(back.cell_data.at("stress"), g.cell_data.at("stress"));
  }
  // The ASCII file, read as text independently: point 3's displacement is the 4th triple.
  const std::vector<double> disp = ArrayValues(ReadText(OutPath("grid_ascii.vtu")), "displacement");
  ASSERT_EQ(disp.size(), 51u);
  EXPECT_EQ(disp[3 * 3 + 1], -1.5);
  EXPECT_EQ(ArrayValues(ReadText(OutPath("grid_ascii.vtu")), "types"), std::vector<double>(2, 24));
}

// The existing WriteVtu output (ASCII) reads back through the reader: one reader, one writer.
TEST(VtuGrid, WriteVtuOutputReadsBackWithItsQualityArrays) {
  const TetMesh mesh = Bipyramid();
  WriteVtu(mesh, OutPath("bipyramid_back.vtu"));
  const VtuGrid back = ReadVtuGrid(OutPath("bipyramid_back.vtu"));
  EXPECT_EQ(back.points, mesh.nodes);
  EXPECT_EQ(Eigen::Matrix4Xi(back.cells), mesh.tets);
  EXPECT_EQ(back.regions, mesh.regions);
  EXPECT_NEAR(back.cell_data.at("volume")(0, 1), 1.0 / 6.0, 1e-15);
}

// What the reader does not take is refused by name.
TEST(VtuGrid, RefusesUnsupportedContentNamingIt) {
  const VtuGrid g = QuadraticGrid();
  WriteVtuGrid(g, OutPath("grid_edit.vtu"), VtuEncoding::kAscii);
  const std::string good = ReadText(OutPath("grid_edit.vtu"));
  auto error_of = [](const std::string& bytes) -> std::string {
    try {
      ParseVtuGrid(bytes, "edited");
    } catch (const VtuError& e) {
      EXPECT_EQ(e.source(), "edited");
      return e.what();
    }
    return "";
  };
  auto edit = [&](const std::string& from, const std::string& to) {
    std::string bytes = good;
    const size_t at = bytes.find(from);
    EXPECT_NE(at, std::string::npos) << from;
    if (at != std::string::npos) bytes.replace(at, from.size(), to);
    return bytes;
  };
  EXPECT_NE(error_of(edit("header_type=\"UInt64\"",
                          "header_type=\"UInt64\" compressor=\"vtkLZ4DataCompressor\""))
                .find("vtkLZ4DataCompressor"),
            std::string::npos);
  EXPECT_NE(error_of(edit("type=\"UnstructuredGrid\"", "type=\"PolyData\"")).find("PolyData"),
            std::string::npos);
  EXPECT_NE(error_of(edit("24 24", "24 12")).find("type 12"), std::string::npos);
  EXPECT_NE(error_of(edit("24 24", "24 10")).find("one kind of tetrahedron"), std::string::npos);
  EXPECT_NE(
      error_of(edit("</Piece>", "</Piece><Piece NumberOfPoints=\"1\" NumberOfCells=\"1\"></Piece>"))
          .find("2 <Piece>"),
      std::string::npos);
  EXPECT_NE(error_of(edit("NumberOfPoints=\"17\"", "NumberOfPoints=\"1e3\"")).find("1e3"),
            std::string::npos);
  EXPECT_NE(error_of(edit("NumberOfPoints=\"17\"", "NumberOfPoints=\"16\"")).find("48 values"),
            std::string::npos);
  EXPECT_NE(error_of("").find("no XML element"), std::string::npos);
  EXPECT_NE(error_of(good.substr(0, 300)).find("ends inside"), std::string::npos);
  EXPECT_EQ(error_of(good), "");
  EXPECT_THROW(ReadVtuGrid(OutPath("no_such.vtu")), VtuError);
}

// Mutation loop over the writer's own files (ASCII and appended raw): the reader reads the
// result or throws VtuError, nothing else, never crashes. Fixed seed.
TEST(HardVtuMutation, ParseVtuGridReadsOrRefusesEveryMutatedFile) {
  const VtuGrid g = QuadraticGrid();
  std::vector<std::string> seeds;
  for (VtuEncoding enc : {VtuEncoding::kAscii, VtuEncoding::kAppendedRaw}) {
    const std::string path =
        OutPath(enc == VtuEncoding::kAscii ? "seed_ascii.vtu" : "seed_raw.vtu");
    WriteVtuGrid(g, path, enc);
    seeds.push_back(ReadText(path));
  }
  std::mt19937 rng(14015);
  int read = 0, refused = 0, other = 0;
  for (const std::string& seed : seeds) {
    for (int m = 0; m < 200; ++m) {
      const std::string bytes = test_support::MutateBytes(seed, rng, 4, 32);
      try {
        ParseVtuGrid(bytes, "mutant");
        ++read;
      } catch (const VtuError&) {
        ++refused;
      } catch (...) {
        ++other;
      }
    }
  }
  std::printf("400 mutated files: %d read, %d refused, %d other exceptions\n", read, refused,
              other);
  EXPECT_EQ(other, 0);
  EXPECT_GT(refused, 200);
  RecordProperty("figure", "400 mutants: " + std::to_string(read) + " read, " +
                               std::to_string(refused) + " refused, " + std::to_string(other) +
                               " other, 0 crashes");
  RecordProperty("bar", "no crash and no exception other than VtuError");
}

}  // namespace
}  // namespace spidarcad::modeling
