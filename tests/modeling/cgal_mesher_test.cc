// Tests of MeshImplicitWithCgal (CGAL Mesh_3 from the implicit function) against closed forms
// (sphere and box volumes), the field itself (boundary nodes on the zero set) and a second
// computation of orientation, plus its failure modes: empty box, solid crossing the box, bad
// settings, cancel.
// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#include "spidarcad/modeling/cgal_mesher.h"

#include <gtest/gtest.h>

#include <atomic>
#include <cmath>
#include <map>
#include <set>
#include <string>
#include <vector>

namespace spidarcad::modeling {
namespace {

CompiledSolid Sphere(double r) { return CompiledSolid::Compile(ImplicitNode(SphereParams{r})); }

CompiledSolid Box(const Eigen::Vector3d& size) {
  return CompiledSolid::Compile(ImplicitNode(BoxParams{size}));
}

Eigen::AlignedBox3d Around(double half) {
  return Eigen::AlignedBox3d(Eigen::Vector3d::Constant(-half), Eigen::Vector3d::Constant(half));
}

// Volume of a tet computed here from its corners (independent of TetVolume).
double SignedVolume(const TetMesh& m, Eigen::Index t) {
  const Eigen::Vector3d a = m.nodes.col(m.tets(0, t)), b = m.nodes.col(m.tets(1, t)),
                        c = m.nodes.col(m.tets(2, t)), d = m.nodes.col(m.tets(3, t));
  return (b - a).dot((c - a).cross(d - a)) / 6.0;
}

double Volume(const TetMesh& m) {
  double v = 0.0;
  for (Eigen::Index t = 0; t < m.tets.cols(); ++t) v += SignedVolume(m, t);
  return v;
}

// Nodes on faces that belong to exactly one tet (computed here by counting sorted faces).
std::set<int> BoundaryNodes(const TetMesh& m) {
  std::map<std::vector<int>, int> count;
  for (Eigen::Index t = 0; t < m.tets.cols(); ++t) {
    for (int skip = 0; skip < 4; ++skip) {
      std::vector<int> f;
      for (int c = 0; c < 4; ++c) {
        if (c != skip) f.push_back(m.tets(c, t));
      }
      std::sort(f.begin(), f.end());
      ++count[f];
    }
  }
  std::set<int> nodes;
  for (const auto& [f, n] : count) {
    if (n == 1) nodes.insert(f.begin(), f.end());
  }
  return nodes;
}

// Expects f to throw E with `what` in its message.
template <typename E, typename F>
void ExpectThrowWith(F f, const std::string& what) {
  try {
    f();
    ADD_FAILURE() << "nothing thrown, expected " << what;
  } catch (const E& e) {
    EXPECT_NE(std::string(e.what()).find(what), std::string::npos) << e.what();
  } catch (const std::exception& e) {
    ADD_FAILURE() << "wrong exception type: " << e.what();
  }
}

TEST(CgalMesher, SphereVolumeConvergesToTheClosedForm) {
  const double r = 0.05;
  const double exact = 4.0 / 3.0 * M_PI * r * r * r;
  double previous_error = 1.0;
  for (const double h : {0.02, 0.01}) {
    CgalMeshStats stats;
    const TetMesh mesh =
        MeshImplicitWithCgal(Sphere(r), Around(0.06), CgalMeshSettings::ForSize(h), &stats);
    const double error = std::abs(Volume(mesh) - exact) / exact;
    // An inscribed polyhedron: below the sphere's volume, the gap shrinking with h, and at
    // most (sphere area) × facet_distance, i.e. relative 3 d / r.
    EXPECT_LT(Volume(mesh), exact);
    EXPECT_LT(error, 3.0 * CgalMeshSettings::ForSize(h).facet_distance / r) << "h " << h;
    EXPECT_LT(error, previous_error) << "h " << h;
    previous_error = error;
    EXPECT_EQ(stats.tets, mesh.tets.cols());
    EXPECT_EQ(stats.vertices, mesh.nodes.cols());
    EXPECT_GT(stats.min_dihedral_deg, 0.0);
  }
}

TEST(CgalMesher, EveryTetIsPositiveAndBoundaryNodesLieOnTheSurface) {
  const double r = 0.05, h = 0.012;
  const CgalMeshSettings settings = CgalMeshSettings::ForSize(h);
  CgalMeshStats stats;
  const TetMesh mesh = MeshImplicitWithCgal(Sphere(r), Around(0.07), settings, &stats);
  ASSERT_GT(mesh.tets.cols(), 100);
  ValidateTetMesh(mesh);
  for (Eigen::Index t = 0; t < mesh.tets.cols(); ++t)
    ASSERT_GT(SignedVolume(mesh, t), 0.0) << "tet " << t;
  const std::set<int> boundary = BoundaryNodes(mesh);
  ASSERT_GT(boundary.size(), 20u);
  for (const int i : boundary) {
    // Surface points are bisected to ~1e-6 of the box: far inside the facet distance.
    EXPECT_NEAR(mesh.nodes.col(i).norm(), r, settings.facet_distance) << "node " << i;
    EXPECT_NEAR(mesh.nodes.col(i).norm(), r, 1e-5) << "node " << i;
  }
  // Interior nodes are strictly inside.
  for (Eigen::Index i = 0; i < mesh.nodes.cols(); ++i) {
    if (!boundary.count(static_cast<int>(i))) {
      EXPECT_LT(mesh.nodes.col(i).norm(), r) << "node " << i;
    }
  }
  // BoundarySurface: over the boundary nodes only, outward (each normal points away from the
  // centre), closing a surface whose divergence-theorem volume equals the tets' volume.
  const TriangleMesh surface = BoundarySurface(mesh);
  ASSERT_GT(surface.triangles.cols(), 0);
  EXPECT_EQ(surface.vertices.cols(), static_cast<Eigen::Index>(boundary.size()));
  double enclosed = 0.0;
  for (Eigen::Index f = 0; f < surface.triangles.cols(); ++f) {
    const Eigen::Vector3d a = surface.vertices.col(surface.triangles(0, f)),
                          b = surface.vertices.col(surface.triangles(1, f)),
                          c = surface.vertices.col(surface.triangles(2, f));
    EXPECT_GT((b - a).cross(c - a).dot((a + b + c) / 3.0), 0.0) << "face " << f;
    enclosed += a.dot(b.cross(c)) / 6.0;
  }
  EXPECT_NEAR(enclosed, Volume(mesh), 1e-12);
  // Its vertices are on the sphere: the sampled error is the chordal error at midpoints and
  // centroids, within the facet distance.
  EXPECT_LT(MeasureSurfaceError(Sphere(r), surface).max, settings.facet_distance);
  EXPECT_EQ(surface.triangles.cols(), stats.boundary_facets);
  // One connected solid: one region.
  EXPECT_EQ(mesh.regions.minCoeff(), 1);
  EXPECT_EQ(mesh.regions.maxCoeff(), 1);
}

TEST(CgalMesher, BoxVolumeIsCloseToItsProductOfSides) {
  const Eigen::Vector3d size(0.1, 0.06, 0.04);
  CgalMeshStats stats;
  const TetMesh mesh =
      MeshImplicitWithCgal(Box(size), Around(0.06), CgalMeshSettings::ForSize(0.01), &stats);
  const double exact = size.prod();
  // Sharp edges and corners are cut (no feature preservation): the mesh lies inside the box and
  // misses at most a few percent.
  EXPECT_LT(Volume(mesh), exact);
  EXPECT_NEAR(Volume(mesh), exact, 0.05 * exact);
  for (Eigen::Index i = 0; i < mesh.nodes.cols(); ++i) {
    EXPECT_TRUE((mesh.nodes.col(i).cwiseAbs().array() <= 0.5 * size.array() + 1e-6).all())
        << "node " << i;
  }
  EXPECT_NEAR(stats.quality.total_volume, Volume(mesh), 1e-12);
}

TEST(CgalMesher, TwoSpheresGiveTwoRegionsAndSameSeedSameMesh) {
  const CompiledSolid two = CompiledSolid::Compile(
      ImplicitNode(UnionParams{}, {ImplicitNode(TranslateParams{Eigen::Vector3d(-0.04, 0, 0)},
                                                {ImplicitNode(SphereParams{0.025})}),
                                   ImplicitNode(TranslateParams{Eigen::Vector3d(0.04, 0, 0)},
                                                {ImplicitNode(SphereParams{0.025})})}));
  const Eigen::AlignedBox3d box(Eigen::Vector3d(-0.08, -0.04, -0.04),
                                Eigen::Vector3d(0.08, 0.04, 0.04));
  const CgalMeshSettings settings = CgalMeshSettings::ForSize(0.01);
  const TetMesh a = MeshImplicitWithCgal(two, box, settings);
  const TetMesh b = MeshImplicitWithCgal(two, box, settings);
  EXPECT_EQ(a.regions.minCoeff(), 1);
  EXPECT_EQ(a.regions.maxCoeff(), 2);
  // Tets left of x = 0 share one region, those right of it the other.
  std::map<bool, std::set<int>> regions_by_side;
  for (Eigen::Index t = 0; t < a.tets.cols(); ++t) {
    const double x = (a.nodes.col(a.tets(0, t)) + a.nodes.col(a.tets(1, t)) +
                      a.nodes.col(a.tets(2, t)) + a.nodes.col(a.tets(3, t)))
                         .x();
    regions_by_side[x < 0].insert(a.regions[t]);
  }
  ASSERT_EQ(regions_by_side[true].size(), 1u);
  ASSERT_EQ(regions_by_side[false].size(), 1u);
  EXPECT_NE(*regions_by_side[true].begin(), *regions_by_side[false].begin());
  ASSERT_EQ(a.tets.cols(), b.tets.cols());
  EXPECT_EQ(a.tets, b.tets);
  EXPECT_EQ(a.nodes, b.nodes);
}

TEST(CgalMesher, EmptySolidInTheBoxThrowsSayingSo) {
  // A sphere far from the box.
  const CompiledSolid away = CompiledSolid::Compile(
      ImplicitNode(TranslateParams{Eigen::Vector3d(1, 0, 0)}, {ImplicitNode(SphereParams{0.05})}));
  ExpectThrowWith<CgalMeshError>(
      [&] { MeshImplicitWithCgal(away, Around(0.1), CgalMeshSettings::ForSize(0.01)); },
      "empty in the box");
}

TEST(CgalMesher, SolidCrossingTheBoxThrowsNamingTheBounds) {
  ExpectThrowWith<CgalMeshError>(
      [&] { MeshImplicitWithCgal(Sphere(0.05), Around(0.04), CgalMeshSettings::ForSize(0.01)); },
      "enlarge the bounds");
}

TEST(CgalMesher, BadSettingsThrowNamingTheField) {
  CgalMeshSettings s = CgalMeshSettings::ForSize(0.01);
  s.facet_size = -1.0;
  ExpectThrowWith<CgalMeshError>([&] { MeshImplicitWithCgal(Sphere(0.05), Around(0.06), s); },
                                 "facet_size");
  s = CgalMeshSettings::ForSize(0.01);
  s.cell_radius_edge_ratio = 0.9;
  ExpectThrowWith<CgalMeshError>([&] { MeshImplicitWithCgal(Sphere(0.05), Around(0.06), s); },
                                 "cell_radius_edge_ratio");
  ExpectThrowWith<CgalMeshError>(
      [&] {
        MeshImplicitWithCgal(Sphere(0.05), Eigen::AlignedBox3d(), CgalMeshSettings::ForSize(0.01));
      },
      "bounds");
}

TEST(CgalMesher, TooManyVerticesThrows) {
  CgalMeshSettings s = CgalMeshSettings::ForSize(0.002);
  s.max_vertices = 300;
  ExpectThrowWith<CgalMeshError>([&] { MeshImplicitWithCgal(Sphere(0.05), Around(0.06), s); },
                                 "max_vertices");
}

TEST(CgalMesher, CancelThrowsDuringRefinementAndProgressRises) {
  std::atomic<bool> cancel{false};
  std::vector<double> reported;
  CgalMeshSettings s = CgalMeshSettings::ForSize(0.005);
  s.cancel = &cancel;
  s.progress = [&](double f) {
    reported.push_back(f);
    if (f > 0.1) cancel = true;  // raised mid-refinement
  };
  EXPECT_THROW(MeshImplicitWithCgal(Sphere(0.05), Around(0.06), s), CgalMeshCancelled);
  ASSERT_GE(reported.size(), 2u);
  for (size_t i = 1; i < reported.size(); ++i) EXPECT_GE(reported[i], reported[i - 1]);
  EXPECT_LT(reported.back(), 0.7);  // stopped before the optimizers
  // Raised before the call: nothing is meshed.
  CgalMeshSettings t = CgalMeshSettings::ForSize(0.01);
  std::atomic<bool> raised{true};
  t.cancel = &raised;
  EXPECT_THROW(MeshImplicitWithCgal(Sphere(0.05), Around(0.06), t), CgalMeshCancelled);
  // Not raised: progress ends at 1.
  CgalMeshSettings u = CgalMeshSettings::ForSize(0.01);
  double last = -1.0;
  u.progress = [&](double f) { last = f; };
  MeshImplicitWithCgal(Sphere(0.05), Around(0.06), u);
  EXPECT_EQ(last, 1.0);
}

}  // namespace
}  // namespace spidarcad::modeling
