// Tests of the .vtu reader and writer for tetrahedral meshes (app/src/cli/vtu_io.h): round
// trips, orientation repair checked against element geometry, arrays read back with plain VTK,
// and refusals of files that hold no tetrahedra.
// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#include <cmath>
#include <fstream>
#include <string>

#include <gtest/gtest.h>
#include <vtkCellData.h>
#include <vtkCellType.h>
#include <vtkDataArray.h>
#include <vtkPointData.h>
#include <vtkPoints.h>
#include <vtkSmartPointer.h>
#include <vtkUnstructuredGrid.h>
#include <vtkXMLUnstructuredGridReader.h>
#include <vtkXMLUnstructuredGridWriter.h>

#include "cli/cli_common.h"
#include "scene/vtu_io.h"
#include "spidarcad/fem/mesh.h"

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
  Eigen::MatrixXd disp(mesh.num_nodes(), 3);
  for (int v = 0; v < mesh.num_nodes(); ++v) disp.row(v) = 2.0 * mesh.nodes.row(v);
  Eigen::VectorXd cell_value(mesh.num_elements());
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

  // A row count that does not match is refused.
  EXPECT_THROW(WriteTetVtu(mesh, path, {{"bad", Eigen::MatrixXd::Zero(3, 1)}}),
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

}  // namespace
}  // namespace spidarcad::app
