// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#include "spidarcad/fem/mesh.h"

#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <cmath>
#include <set>
#include <stdexcept>
#include <string>

namespace spidarcad::fem {
namespace {

BoxMeshSettings Box(int nx, int ny, int nz, HexSplit split, int order) {
  BoxMeshSettings s;
  s.lower = Eigen::Vector3d(-0.1, 0.2, 0.0);
  s.upper = Eigen::Vector3d(0.5, 0.5, 0.2);
  s.nx = nx;
  s.ny = ny;
  s.nz = nz;
  s.split = split;
  s.order = order;
  return s;
}

class BoxMeshTest : public ::testing::TestWithParam<HexSplit> {};

TEST_P(BoxMeshTest, FillsTheBoxWithPositiveTetrahedraWhenSplit) {
  const auto s = Box(3, 2, 4, GetParam(), 1);
  const TetMesh mesh = MakeBoxMesh(s);
  const int per_cell = GetParam() == HexSplit::kSix ? 6 : 5;
  EXPECT_EQ(mesh.num_nodes(), 4 * 3 * 5);
  EXPECT_EQ(mesh.num_elements(), 3 * 2 * 4 * per_cell);
  double volume = 0.0;
  for (int e = 0; e < mesh.num_elements(); ++e) {
    EXPECT_GT(mesh.CornerVolume(e), 0.0) << "element " << e;
    volume += mesh.CornerVolume(e);
  }
  EXPECT_NEAR(volume, 0.6 * 0.3 * 0.2, 1e-14);
  EXPECT_NO_THROW(mesh.Validate());
}

TEST_P(BoxMeshTest, SurfaceIsClosedAndOutwardWhenExtracted) {
  const auto s = Box(3, 2, 4, GetParam(), 1);
  const TetMesh mesh = MakeBoxMesh(s);
  const Surface surf = ExtractSurface(mesh);
  // Conforming mesh: each boundary quad gives two triangles, no interior face is left over.
  EXPECT_EQ(surf.faces.rows(), 2 * 2 * (3 * 2 + 2 * 4 + 3 * 4));
  // Divergence theorem: ∮ n dA = 0 and ∮ (x·n)/3 dA = volume.
  Eigen::Vector3d area_normal = Eigen::Vector3d::Zero();
  double volume = 0.0;
  for (int f = 0; f < surf.faces.rows(); ++f) {
    const Eigen::Vector3d a = mesh.nodes.row(surf.faces(f, 0)).transpose();
    const Eigen::Vector3d b = mesh.nodes.row(surf.faces(f, 1)).transpose();
    const Eigen::Vector3d c = mesh.nodes.row(surf.faces(f, 2)).transpose();
    const Eigen::Vector3d an = 0.5 * (b - a).cross(c - a);
    area_normal += an;
    volume += ((a + b + c) / 3.0).dot(an) / 3.0;
  }
  EXPECT_LT(area_normal.norm(), 1e-14);
  EXPECT_NEAR(volume, 0.6 * 0.3 * 0.2, 1e-14);
  // Surface nodes are exactly those on a face of the box (brute force on coordinates).
  std::set<int> expected;
  for (int v = 0; v < mesh.num_nodes(); ++v) {
    const Eigen::Vector3d p = mesh.nodes.row(v).transpose();
    bool on = false;
    for (int i = 0; i < 3; ++i)
      on = on || std::abs(p(i) - s.lower(i)) < 1e-12 || std::abs(p(i) - s.upper(i)) < 1e-12;
    if (on) expected.insert(v);
  }
  EXPECT_EQ(std::set<int>(surf.nodes.begin(), surf.nodes.end()), expected);
}

INSTANTIATE_TEST_SUITE_P(Splits, BoxMeshTest, ::testing::Values(HexSplit::kFive, HexSplit::kSix));

TEST(MakeQuadratic, AddsOneSharedMidpointPerEdgeWhenUpgraded) {
  const TetMesh lin = MakeBoxMesh(Box(2, 2, 1, HexSplit::kSix, 1));
  const TetMesh quad = MakeQuadratic(lin);
  ASSERT_EQ(quad.NodesPerElement(), 10);
  // Unique edges counted independently.
  std::set<std::pair<int, int>> edges;
  for (int e = 0; e < lin.num_elements(); ++e)
    for (int a = 0; a < 4; ++a)
      for (int b = a + 1; b < 4; ++b) {
        const int u = lin.elements(e, a), v = lin.elements(e, b);
        edges.insert({std::min(u, v), std::max(u, v)});
      }
  EXPECT_EQ(quad.num_nodes(), lin.num_nodes() + static_cast<int>(edges.size()));
  for (int e = 0; e < quad.num_elements(); ++e)
    for (int k = 0; k < 6; ++k) {
      const Eigen::RowVector3d mid = 0.5 * (quad.nodes.row(quad.elements(e, kTetEdges[k][0])) +
                                            quad.nodes.row(quad.elements(e, kTetEdges[k][1])));
      EXPECT_LT((quad.nodes.row(quad.elements(e, 4 + k)) - mid).norm(), 1e-15);
    }
  const Surface surf = ExtractSurface(quad);
  ASSERT_EQ(surf.faces6.rows(), surf.faces.rows());
  // Quadratic surface nodes: corners plus the midpoints of boundary edges; every surface node
  // of the 10-node mesh lies on the box boundary.
  for (int v : surf.nodes) {
    const Eigen::Vector3d p = quad.nodes.row(v).transpose();
    const Eigen::Vector3d lo(-0.1, 0.2, 0.0), hi(0.5, 0.5, 0.2);
    bool on = false;
    for (int i = 0; i < 3; ++i)
      on = on || std::abs(p(i) - lo(i)) < 1e-12 || std::abs(p(i) - hi(i)) < 1e-12;
    EXPECT_TRUE(on) << "node " << v;
  }
  EXPECT_EQ(TetEdgeNode(2, 1), 5);
  EXPECT_EQ(TetEdgeNode(3, 2), 9);
}

TEST(TetMesh, ValidateNamesElementWhenIndexOutOfRangeOrInverted) {
  TetMesh mesh = MakeBoxMesh(Box(1, 1, 1, HexSplit::kSix, 1));
  mesh.elements(2, 3) = 99;
  try {
    mesh.Validate();
    FAIL() << "no throw";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("element 2"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("99"), std::string::npos) << e.what();
  }
  mesh = MakeBoxMesh(Box(1, 1, 1, HexSplit::kSix, 1));
  std::swap(mesh.elements(4, 0), mesh.elements(4, 1));
  try {
    mesh.Validate();
    FAIL() << "no throw";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("element 4"), std::string::npos) << e.what();
  }
  EXPECT_THROW(MakeBoxMesh(Box(0, 1, 1, HexSplit::kSix, 1)), std::invalid_argument);
  EXPECT_THROW(MakeBoxMesh(Box(1, 1, 1, HexSplit::kSix, 3)), std::invalid_argument);
}

TEST(LabelRegionInBox, LabelsElementsWhoseCentroidIsInsideWhenCalled) {
  TetMesh mesh = MakeBoxMesh(Box(4, 1, 1, HexSplit::kSix, 1));
  LabelRegionInBox(Eigen::Vector3d(0.2, -1, -1), Eigen::Vector3d(1, 1, 1), 7, &mesh);
  int labelled = 0;
  for (int e = 0; e < mesh.num_elements(); ++e) {
    double cx = 0.0;
    for (int k = 0; k < 4; ++k) cx += mesh.nodes(mesh.elements(e, k), 0) / 4.0;
    EXPECT_EQ(mesh.regions(e), cx >= 0.2 ? 7 : 0);
    labelled += mesh.regions(e) == 7;
  }
  EXPECT_EQ(labelled, 2 * 6);  // cells x in [0.2, 0.5]: two of four
}

}  // namespace
}  // namespace spidarcad::fem
