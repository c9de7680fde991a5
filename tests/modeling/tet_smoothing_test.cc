// Tests of the sliver smoothing of tetrahedral meshes (modeling/include/spidarcad/modeling/
// tet_smoothing.h), on TetGen's tets of the platform: what must not change (boundary, fixed
// vertices, connectivity, volume) checked node by node, and the angles it must raise measured
// again with MeasureTetQuality and DihedralAngles, not taken from its own figures.
// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#include "spidarcad/modeling/tet_smoothing.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <set>
#include <stdexcept>
#include <string>
#include <vector>

#include "spidarcad/modeling/implicit_evaluator.h"
#include "spidarcad/modeling/scene_io.h"
#include "spidarcad/modeling/surface_mesher.h"
#include "spidarcad/modeling/tetgen_mesher.h"

namespace spidarcad::modeling {
namespace {

// The platform's tets as `spidarcad mesh --tets tetgen` makes them at 8 mm.
TetMesh PlatformTets() {
  const Scene scene = LoadScene(std::string(SPIDARCAD_SOURCE_DIR) + "/assets/scenes/platform.json");
  const CompiledSolid platform = CompiledSolid::Compile(scene.solids[0].root);
  SurfaceMeshSettings s;
  s.bounds =
      Eigen::AlignedBox3d(Eigen::Vector3d(-0.02, -0.12, -0.17), Eigen::Vector3d(0.32, 0.12, 0.03));
  s.cell_size = 0.008;
  s.snap_cells = kProductSnapCells;
  return TetrahedralizeSurface(MeshSurface(platform, s));
}

// The nodes on a boundary face (a face of one tet only).
std::set<int> BoundaryNodes(const TetMesh& mesh) {
  std::multiset<std::vector<int>> faces;
  for (Eigen::Index t = 0; t < mesh.tets.cols(); ++t)
    for (int k = 0; k < 4; ++k) {
      std::vector<int> f;
      for (int j = 0; j < 4; ++j)
        if (j != k) f.push_back(mesh.tets(j, t));
      std::sort(f.begin(), f.end());
      faces.insert(f);
    }
  std::set<int> nodes;
  for (const auto& f : faces)
    if (faces.count(f) == 1) nodes.insert(f.begin(), f.end());
  return nodes;
}

long CountUnder(const TetMesh& mesh, double deg) {
  long n = 0;
  for (Eigen::Index t = 0; t < mesh.tets.cols(); ++t) {
    const auto p = [&](int k) -> Eigen::Vector3d { return mesh.nodes.col(mesh.tets(k, t)); };
    n += DihedralAngles(p(0), p(1), p(2), p(3)).minCoeff() * 180.0 / M_PI < deg;
  }
  return n;
}

// On the platform's tets at 8 mm, smoothing to 10°: the boundary nodes bit for bit where they
// were, the tets the same, every tet positive, the volume the same to rounding; fewer tets under
// 10° and under 5°, the smallest dihedral angle no lower and the largest radius-edge ratio no
// higher, all measured again; the figures it reports equal those measured.
TEST(TetSmoothing, RaisesTheSmallestAnglesWithoutMovingTheBoundaryOrChangingTheTets) {
  const TetMesh before = PlatformTets();
  TetMesh after = before;
  const TetSmoothingStats stats = SmoothSlivers(&after);
  const std::set<int> boundary = BoundaryNodes(before);
  ASSERT_EQ(after.nodes.cols(), before.nodes.cols());
  EXPECT_TRUE(after.tets == before.tets);
  EXPECT_TRUE(after.regions == before.regions);
  long moved_nodes = 0;
  for (Eigen::Index v = 0; v < before.nodes.cols(); ++v) {
    const bool moved = after.nodes.col(v) != before.nodes.col(v);
    moved_nodes += moved;
    if (boundary.count(static_cast<int>(v)) != 0) {
      EXPECT_FALSE(moved) << "boundary node " << v;
    }
  }
  const TetQuality q0 = MeasureTetQuality(before), q1 = MeasureTetQuality(after);
  EXPECT_GT(q1.min_volume, 0.0);
  EXPECT_NEAR(q1.total_volume, q0.total_volume, 1e-12 * q0.total_volume);
  EXPECT_GE(q1.min_dihedral_deg, q0.min_dihedral_deg);
  EXPECT_LE(q1.max_radius_edge, q0.max_radius_edge);
  const long under10_0 = CountUnder(before, 10.0), under10_1 = CountUnder(after, 10.0);
  const long under5_0 = CountUnder(before, 5.0), under5_1 = CountUnder(after, 5.0);
  std::printf(
      "%ld tets: under 10 deg %ld -> %ld, under 5 deg %ld -> %ld, smallest %.2f -> %.2f "
      "deg, %ld nodes moved, %.2f s\n",
      static_cast<long>(before.tets.cols()), under10_0, under10_1, under5_0, under5_1,
      q0.min_dihedral_deg, q1.min_dihedral_deg, moved_nodes, stats.seconds);
  EXPECT_GT(under10_0, 0);  // the case has slivers to mend
  EXPECT_LT(under10_1, under10_0 / 2);
  EXPECT_LE(under5_1, under5_0);
  EXPECT_GT(moved_nodes, 0);
  EXPECT_LE(moved_nodes, stats.moved);  // a node can move in more than one pass
  EXPECT_EQ(stats.under_target_before, under10_0);
  EXPECT_EQ(stats.under_target_after, under10_1);
  EXPECT_DOUBLE_EQ(stats.min_dihedral_before_deg, q0.min_dihedral_deg);
  EXPECT_DOUBLE_EQ(stats.min_dihedral_after_deg, q1.min_dihedral_deg);
}

// Fixed nodes stay, whatever they are; the settings and the flags are checked.
TEST(TetSmoothing, KeepsFixedNodesAndRefusesBadSettings) {
  const TetMesh before = PlatformTets();
  std::vector<char> fixed(static_cast<size_t>(before.nodes.cols()), 0);
  for (size_t v = 0; v < fixed.size(); v += 2) fixed[v] = 1;  // every other node
  TetMesh after = before;
  const TetSmoothingStats stats = SmoothSlivers(&after, {}, fixed);
  EXPECT_GT(stats.moved, 0);
  for (Eigen::Index v = 0; v < before.nodes.cols(); v += 2)
    EXPECT_TRUE(after.nodes.col(v) == before.nodes.col(v)) << "fixed node " << v;
  EXPECT_GT(MeasureTetQuality(after).min_volume, 0.0);

  auto refused = [&](const TetSmoothingSettings& s, const std::vector<char>& flags,
                     const std::string& what) {
    TetMesh copy = before;
    try {
      SmoothSlivers(&copy, s, flags);
      ADD_FAILURE() << what << " accepted";
    } catch (const std::invalid_argument& e) {
      EXPECT_NE(std::string(e.what()).find(what), std::string::npos) << e.what();
    }
    EXPECT_TRUE(copy.nodes == before.nodes) << what;
  };
  for (double deg : {0.0, -1.0, 60.0, std::nan("")}) {
    TetSmoothingSettings s;
    s.target_dihedral_deg = deg;
    refused(s, {}, "target_dihedral_deg");
  }
  TetSmoothingSettings no_sweeps;
  no_sweeps.sweeps = 0;
  refused(no_sweeps, {}, "sweeps");
  TetSmoothingSettings bad_bound;
  bad_bound.max_radius_edge = INFINITY;
  refused(bad_bound, {}, "max_radius_edge");
  refused({}, std::vector<char>(3, 0), "fixed flags");
}

}  // namespace
}  // namespace spidarcad::modeling
