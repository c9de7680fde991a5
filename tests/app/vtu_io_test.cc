// Tests of the .vtu reader and writer for tetrahedral meshes (app/src/scene/vtu_io.h, on
// modeling's own VTU reader): round trips, every encoding VTK's own writer produces read back
// exactly, orientation repair checked against element geometry, arrays read back with plain
// VTK (what ParaView uses), refusals of files that hold no tetrahedra, hostile files (issue 15)
// and a mutation loop over VTK-written files.
// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later

#include "scene/vtu_io.h"

#include <gtest/gtest.h>
#include <vtkCellData.h>
#include <vtkCellType.h>
#include <vtkDataArray.h>
#include <vtkDoubleArray.h>
#include <vtkIntArray.h>
#include <vtkPointData.h>
#include <vtkPoints.h>
#include <vtkSmartPointer.h>
#include <vtkUnstructuredGrid.h>
#include <vtkXMLUnstructuredGridReader.h>
#include <vtkXMLUnstructuredGridWriter.h>

#include <cmath>
#include <cstdint>
#include <cstdio>
#include <fstream>
#include <random>
#include <sstream>
#include <string>
#include <vector>

#include "cli/cli_common.h"
#include "spidarcad/fem/mesh.h"
#include "spidarcad/modeling/tet_mesh.h"
#include "support/byte_mutator.h"
#include "vtk_writer_support.h"
namespace spidarcad::app {
namespace {

std::string OutputPath(const std::string& name) {
  return std::string(SPIDARCAD_TEST_OUTPUT_DIR) + "/" + name;
}

fem::TetMesh SmallBox(int order) {
  fem::BoxMeshSettings s;
  s.upper = Eigen::Vector3d(0.3, 0.1, 0.05);
  s.nx = 3;
  s.ny = 2;
  s.nz = 1;
  s.order = order;
  fem::TetMesh mesh = fem::MakeBoxMesh(s);
  fem::LabelRegionInBox(Eigen::Vector3d(0.15, -1, -1), Eigen::Vector3d(1, 1, 1), 7, &mesh);
  return mesh;
}

// Expects f to throw InputError whose message contains every string of `parts`.
template <typename F>
void ExpectInputError(F f, std::initializer_list<std::string> parts) {
  try {
    f();
    ADD_FAILURE() << "nothing thrown";
  } catch (const InputError& e) {
    for (const std::string& part : parts) {
      EXPECT_NE(std::string(e.what()).find(part), std::string::npos)
          << "'" << part << "' not in: " << e.what();
    }
  }
}

TEST(VtuIo, WriteThenReadKeepsNodesElementsAndRegionsForBothOrders) {
  for (int order : {1, 2}) {
    const fem::TetMesh mesh = SmallBox(order);
    const std::string path = OutputPath("vtu_roundtrip_" + std::to_string(order) + ".vtu");
    WriteTetVtu(mesh, path);
    VtuReadInfo info;
    const fem::TetMesh back = ReadTetVtu(path, &info);
    EXPECT_EQ(back.Order(), order);
    EXPECT_EQ(info.flipped_elements, 0);
    EXPECT_TRUE(info.has_regions);
    ASSERT_EQ(back.nodes.rows(), mesh.nodes.rows());
    EXPECT_EQ((back.nodes - mesh.nodes).cwiseAbs().maxCoeff(), 0.0);  // binary doubles
    EXPECT_TRUE(back.elements == mesh.elements);
    EXPECT_TRUE(back.regions == mesh.regions);
    EXPECT_EQ(back.regions.maxCoeff(), 7);
  }
}

TEST(VtuIo, ArraysReadBackWithPlainVtkReader) {
  const fem::TetMesh mesh = SmallBox(1);
  // Arrays are k by N: one column per point (or cell).
  Eigen::MatrixXd disp(3, mesh.num_nodes());
  for (int v = 0; v < mesh.num_nodes(); ++v) disp.col(v) = 2.0 * mesh.nodes.row(v).transpose();
  Eigen::RowVectorXd cell_value(mesh.num_elements());
  for (int e = 0; e < mesh.num_elements(); ++e) cell_value(e) = 0.5 * e;
  const std::string path = OutputPath("vtu_arrays.vtu");
  WriteTetVtu(mesh, path, {{"displacement", disp}}, {{"value", cell_value}});

  auto reader = vtkSmartPointer<vtkXMLUnstructuredGridReader>::New();
  reader->SetFileName(path.c_str());
  reader->Update();
  vtkUnstructuredGrid* grid = reader->GetOutput();
  ASSERT_EQ(grid->GetNumberOfPoints(), mesh.num_nodes());
  ASSERT_EQ(grid->GetNumberOfCells(), mesh.num_elements());
  EXPECT_EQ(grid->GetCellType(0), VTK_TETRA);
  vtkDataArray* d = grid->GetPointData()->GetArray("displacement");
  ASSERT_NE(d, nullptr);
  ASSERT_EQ(d->GetNumberOfComponents(), 3);
  for (int v = 0; v < mesh.num_nodes(); ++v) {
    double p[3];
    grid->GetPoint(v, p);
    for (int i = 0; i < 3; ++i) EXPECT_EQ(d->GetComponent(v, i), 2.0 * p[i]);
  }
  vtkDataArray* c = grid->GetCellData()->GetArray("value");
  ASSERT_NE(c, nullptr);
  for (int e = 0; e < mesh.num_elements(); ++e) EXPECT_EQ(c->GetTuple1(e), 0.5 * e);
  EXPECT_NE(grid->GetCellData()->GetArray("region"), nullptr);

  // A column count that does not match is refused, and so is the N by k orientation.
  EXPECT_THROW(WriteTetVtu(mesh, path, {{"bad", Eigen::MatrixXd::Zero(3, 1)}}),
               std::invalid_argument);
  EXPECT_THROW(WriteTetVtu(mesh, path, {{"bad", Eigen::MatrixXd::Zero(mesh.num_nodes(), 3)}}),
               std::invalid_argument);
}

TEST(VtuIo, NegativelyOrientedCellsAreFlippedConsistently) {
  // Write a quadratic box with every element mirrored (corners 1 and 2 swapped, midside nodes
  // listed as if for that corner order), then check the read mesh geometrically: positive
  // corner volume, and each midside node at the midpoint of the edge VTK's order says.
  fem::TetMesh mesh = SmallBox(2);
  for (int e = 0; e < mesh.num_elements(); ++e) {
    const Eigen::Matrix<int, 1, 10> r = mesh.elements.row(e);
    // New corners (0, 2, 1, 3): edges (0,1)->(0,2), (1,2)->(2,1), (0,2)->(0,1), (0,3),
    // (1,3)->(2,3), (2,3)->(1,3).
    const int reordered[10] = {r[0], r[2], r[1], r[3], r[6], r[5], r[4], r[7], r[9], r[8]};
    for (int j = 0; j < 10; ++j) mesh.elements(e, j) = reordered[j];
  }
  const std::string path = OutputPath("vtu_flipped.vtu");
  WriteTetVtu(mesh, path);
  VtuReadInfo info;
  const fem::TetMesh back = ReadTetVtu(path, &info);
  EXPECT_EQ(info.flipped_elements, mesh.num_elements());
  for (int e = 0; e < back.num_elements(); ++e) {
    EXPECT_GT(back.CornerVolume(e), 0.0);
    for (int k = 0; k < 6; ++k) {
      const Eigen::RowVector3d mid = 0.5 * (back.nodes.row(back.elements(e, fem::kTetEdges[k][0])) +
                                            back.nodes.row(back.elements(e, fem::kTetEdges[k][1])));
      EXPECT_LT((back.nodes.row(back.elements(e, 4 + k)) - mid).norm(), 1e-15)
          << "element " << e << " edge " << k;
    }
  }
}

TEST(VtuIo, RefusesMissingFilesGarbageAndNonTetrahedralCells) {
  ExpectInputError([] { ReadTetVtu(OutputPath("no_such_mesh.vtu")); },
                   {"no_such_mesh.vtu", "cannot open"});
  const std::string garbage = OutputPath("vtu_garbage.vtu");
  std::ofstream(garbage) << "this is not XML\n";
  ExpectInputError([&] { ReadTetVtu(garbage); }, {"vtu_garbage.vtu"});

  // A hexahedron written with VTK itself.
  auto grid = vtkSmartPointer<vtkUnstructuredGrid>::New();
  auto points = vtkSmartPointer<vtkPoints>::New();
  for (int i = 0; i < 8; ++i) points->InsertNextPoint(i & 1, (i >> 1) & 1, (i >> 2) & 1);
  grid->SetPoints(points);
  const vtkIdType hex[8] = {0, 1, 3, 2, 4, 5, 7, 6};
  grid->InsertNextCell(VTK_HEXAHEDRON, 8, hex);
  const std::string hex_path = OutputPath("vtu_hex.vtu");
  auto writer = vtkSmartPointer<vtkXMLUnstructuredGridWriter>::New();
  writer->SetFileName(hex_path.c_str());
  writer->SetInputData(grid);
  ASSERT_EQ(writer->Write(), 1);
  ExpectInputError([&] { ReadTetVtu(hex_path); }, {"vtu_hex.vtu", "cell 0", "VTK_HEXAHEDRON"});

  // A degenerate (flat) tetrahedron.
  fem::TetMesh flat;
  flat.nodes.resize(4, 3);
  flat.nodes << 0, 0, 0, 1, 0, 0, 0, 1, 0, 1, 1, 0;
  flat.elements.resize(1, 4);
  flat.elements << 0, 1, 2, 3;
  flat.regions = Eigen::VectorXi::Zero(1);
  const std::string flat_path = OutputPath("vtu_flat.vtu");
  WriteTetVtu(flat, flat_path);
  ExpectInputError([&] { ReadTetVtu(flat_path); }, {"vtu_flat.vtu", "cell 0", "degenerate"});
}

TEST(VtuIo, ToFemMeshTransposesModelingLayout) {
  modeling::TetMesh m;
  m.nodes.resize(3, 5);
  m.nodes << 0, 1, 0, 0, 1,  //
      0, 0, 1, 0, 1,         //
      0, 0, 0, 1, 1;
  m.tets.resize(4, 2);
  m.tets << 0, 1,  //
      1, 2,        //
      2, 3,        //
      3, 4;
  const fem::TetMesh f = ToFemMesh(m);
  ASSERT_EQ(f.nodes.rows(), 5);
  ASSERT_EQ(f.elements.rows(), 2);
  for (int v = 0; v < 5; ++v) {
    for (int i = 0; i < 3; ++i) EXPECT_EQ(f.nodes(v, i), m.nodes(i, v));
  }
  for (int t = 0; t < 2; ++t) {
    for (int j = 0; j < 4; ++j) EXPECT_EQ(f.elements(t, j), m.tets(j, t));
  }
  EXPECT_TRUE(f.regions.isZero());
  EXPECT_EQ(f.regions.size(), 2);
}

// Every encoding VTK 9's XML writer produces (ascii; inline base64; appended raw or base64;
// each plain or zlib in several blocks, UInt32 or UInt64 headers, either byte order) reads back
// exactly through the app's reader, with arrays in the k by N orientation.
TEST(VtuIo, ReadsEveryEncodingVtkWritesExactly) {
  for (int order : {1, 2}) {
    const fem::TetMesh mesh = SmallBox(order);
    for (const VtkEncoding& enc : AllVtkEncodings()) {
      const std::string path = OutputPath("vtu_vtk_" + enc.Name() + std::to_string(order) + ".vtu");
      WriteWithVtk(mesh, enc, path);
      VtuReadInfo info;
      const fem::TetMesh back = ReadTetVtu(path, &info);
      ASSERT_EQ(back.num_nodes(), mesh.num_nodes()) << enc.Name();
      EXPECT_EQ((back.nodes - mesh.nodes).cwiseAbs().maxCoeff(), 0.0) << enc.Name();
      EXPECT_TRUE(back.elements == mesh.elements) << enc.Name();
      EXPECT_TRUE(back.regions == mesh.regions) << enc.Name();
      EXPECT_TRUE(info.has_regions);
      const modeling::VtuGrid grid = modeling::ReadVtuGrid(path);
      const Eigen::MatrixXd& position = grid.point_data.at("position");
      ASSERT_EQ(position.rows(), 3);
      ASSERT_EQ(position.cols(), mesh.num_nodes());
      for (int v = 0; v < mesh.num_nodes(); ++v)
        for (int i = 0; i < 3; ++i)
          EXPECT_EQ(position(i, v), 2 * mesh.nodes(v, i) + i) << enc.Name();
    }
  }
}

// The file with the given text replaced (the text must occur).
std::string Replace(std::string text, const std::string& from, const std::string& to) {
  const size_t at = text.find(from);
  EXPECT_NE(at, std::string::npos) << from;
  if (at != std::string::npos) text.replace(at, from.size(), to);
  return text;
}

// Hostile files of issue 15: each is refused with InputError naming the file, the byte offset
// and the offending value, and never reaches a solver or VTK.
TEST(HardVtu, HostileFilesAreRefusedNamingByteFieldAndValue) {
  fem::TetMesh tiny;
  tiny.nodes.resize(8, 3);
  tiny.nodes << 0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0, 1, 1, 1, 0, 1, 0, 1, 0, 1, 1, 1, 1, 1;
  tiny.elements.resize(2, 4);
  tiny.elements << 0, 1, 2, 3, 1, 4, 2, 7;
  tiny.regions = Eigen::VectorXi::Zero(2);
  const std::string good_path = OutputPath("vtu_hostile_good.vtu");
  modeling::VtuGrid g;
  g.points = tiny.nodes.transpose();
  g.cells = tiny.elements.transpose();
  g.regions = tiny.regions;
  g.cell_data["value"] = Eigen::RowVector2d(1.0, 2.0);
  modeling::WriteVtuGrid(g, good_path, modeling::VtuEncoding::kAscii);
  std::stringstream text;
  text << std::ifstream(good_path).rdbuf();
  const std::string good = text.str();
  ASSERT_NO_THROW(ReadTetVtu(good_path));
  // A zlib-compressed, inline-binary variant written by VTK for the corrupted-binary case.
  const std::string zlib_path = OutputPath("vtu_hostile_zlib.vtu");
  const std::string zlib = WriteWithVtk(tiny, {1, false, true, false, false}, zlib_path);
  const size_t data_at = zlib.find("format=\"binary\"");
  ASSERT_NE(data_at, std::string::npos);
  std::string corrupt = zlib;
  const size_t payload = corrupt.find('>', data_at) + 30;
  corrupt[payload] = corrupt[payload] == 'A' ? 'B' : 'A';

  struct Case {
    std::string name, bytes;
    std::vector<std::string> expected;
  };
  const std::vector<Case> cases = {
      {"point_1e9",
       Replace(good, "1 4 2 7", "1 4 2 1000000000"),
       {"connectivity", "1000000000", "byte "}},
      {"point_2p32", Replace(good, "1 4 2 7", "1 4 2 4294967300"), {"connectivity", "4294967300"}},
      {"negative_cells",
       Replace(good, "NumberOfCells=\"2\"", "NumberOfCells=\"-1\""),
       {"NumberOfCells", "-1"}},
      {"short_cell_array",
       Replace(good, " 1 2\n", " 1\n"),
       {"Name=\"value\"", "1 values, expected 2"}},
      {"region_nan",
       Replace(Replace(good, "type=\"Int32\" Name=\"region\"", "type=\"Float64\" Name=\"region\""),
               "          0 0\n", "          0 nan\n"),
       {"region", "nan", "not an integer"}},
      {"corrupt_zlib", corrupt, {"byte "}},
      {"truncated", good.substr(0, good.size() / 2), {"byte "}},
      {"wrong_offsets", Replace(good, " 4 8\n", " 4 9\n"), {"offsets", "9"}},
  };
  for (const Case& c : cases) {
    const std::string path = OutputPath("vtu_hostile_" + c.name + ".vtu");
    std::ofstream(path, std::ios::binary) << c.bytes;
    std::vector<std::string> parts = c.expected;
    parts.push_back(path);
    try {
      ReadTetVtu(path);
      ADD_FAILURE() << c.name << ": nothing thrown";
    } catch (const InputError& e) {
      for (const std::string& part : parts)
        EXPECT_NE(std::string(e.what()).find(part), std::string::npos)
            << c.name << ": '" << part << "' not in: " << e.what();
    }
  }
  RecordProperty("figure", std::to_string(cases.size()) + " of " + std::to_string(cases.size()) +
                               " hostile files refused with byte offset and value");
  RecordProperty("bar", "every one refused with InputError naming file, byte and value");
}

// Mutation loop (not a fuzzer): VTK-written files in eight encodings, each mutated 60 times
// with a fixed seed (bit flips, byte overwrites, truncation, duplicated or deleted spans,
// inserted digits or signs). modeling::ParseVtuGrid must read the result or throw VtuError:
// never crash, hang or throw anything else.
TEST(HardVtuMutation, ReaderReadsOrRefusesEveryMutatedVtkFile) {
  const fem::TetMesh mesh = SmallBox(1);
  std::vector<std::string> seeds;
  for (const VtkEncoding& enc : AllVtkEncodings()) {
    if (enc.big_endian || enc.header64) continue;  // eight seeds: the other axes are tested above
    seeds.push_back(WriteWithVtk(mesh, enc, OutputPath("vtu_seed_" + enc.Name() + ".vtu")));
  }
  seeds.push_back(WriteWithVtk(mesh, {2, false, true, true, true}, OutputPath("vtu_seed_be.vtu")));
  std::mt19937 rng(20261202);
  int read = 0, refused = 0, other = 0;
  for (const std::string& seed : seeds) {
    for (int m = 0; m < 60; ++m) {
      const std::string bytes = test_support::MutateBytes(seed, rng, 3, 16);
      try {
        modeling::ParseVtuGrid(bytes, "mutant");
        ++read;
      } catch (const modeling::VtuError&) {
        ++refused;
      } catch (...) {
        ++other;
      }
    }
  }
  std::printf("%zu mutated files: %d read, %d refused with VtuError, %d other exceptions\n",
              seeds.size() * 60, read, refused, other);
  EXPECT_EQ(other, 0);
  EXPECT_GT(refused, 0);
  RecordProperty("figure", std::to_string(read + refused + other) +
                               " mutants: " + std::to_string(read) + " read, " +
                               std::to_string(refused) + " refused (VtuError), " +
                               std::to_string(other) + " other, 0 crashes");
  RecordProperty("bar", "no crash and no exception other than VtuError");
}

}  // namespace
}  // namespace spidarcad::app
