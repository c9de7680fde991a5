// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
// Slab-conforming meshing: the cut slabs are closed and add up to the solid, the slab meshes
// join conformingly on the planes (every face inside the joined mesh is shared by exactly two
// tets), and an edit inside one slab leaves the other slabs' inputs and tetrahedra bit for bit.
#include "spidarcad/modeling/slab_mesher.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <map>
#include <set>
#include <stdexcept>
#include <string>
#include <vector>

#include "spidarcad/modeling/implicit_evaluator.h"
#include "spidarcad/modeling/implicit_node.h"

namespace spidarcad::modeling {
namespace {

constexpr double kCell = 0.01;

// A 0.3 × 0.1 × 0.02 m plate with a vertical hole of radius 8 mm at x = hole_x.
CompiledSolid PlateWithHole(double hole_x) {
  ImplicitNode plate(BoxParams{Eigen::Vector3d(0.3, 0.1, 0.02)});
  ImplicitNode hole(TranslateParams{Eigen::Vector3d(hole_x, 0.01, 0.0)},
                    {ImplicitNode(CylinderParams{0.008, 0.1})});
  return CompiledSolid::Compile(ImplicitNode(DifferenceParams{}, {plate, hole}));
}

TriangleMesh Surface(const CompiledSolid& solid) {
  SurfaceMeshSettings s;
  // A fixed grid (whole cells from the origin): an edit does not move it.
  s.bounds =
      Eigen::AlignedBox3d(Eigen::Vector3d(-0.17, -0.07, -0.03), Eigen::Vector3d(0.17, 0.07, 0.03));
  s.cell_size = kCell;
  return MeshSurface(solid, s);
}

SlabCut Cut(double section_spacing = 0.0) {
  SlabCut cut;
  cut.axis = 0;
  cut.planes = {-0.0755, 0.0245};  // off the grid planes and off the plate's faces
  cut.snap = 0.1 * kCell;
  cut.section_spacing = section_spacing;
  return cut;
}

// Distance in the plane x = const from (y, z) of p to the segment ab.
double DistanceToSegment(const Eigen::Vector3d& p, const Eigen::Vector3d& a,
                         const Eigen::Vector3d& b) {
  const Eigen::Vector2d q(p.y(), p.z()), qa(a.y(), a.z()), qb(b.y(), b.z());
  const Eigen::Vector2d d = qb - qa;
  const double t = std::clamp((q - qa).dot(d) / d.squaredNorm(), 0.0, 1.0);
  return (q - qa - t * d).norm();
}

// Boundary faces of a tet mesh (faces of exactly one tet) and faces shared by more than two.
struct FaceCount {
  long boundary = 0, shared_by_more = 0, boundary_on_planes = 0;
};
FaceCount CountFaces(const TetMesh& mesh, const std::vector<double>& planes) {
  std::map<std::array<int, 3>, int> faces;
  for (Eigen::Index t = 0; t < mesh.tets.cols(); ++t)
    for (int skip = 0; skip < 4; ++skip) {
      std::array<int, 3> f{};
      int n = 0;
      for (int j = 0; j < 4; ++j)
        if (j != skip) f[n++] = mesh.tets(j, t);
      std::sort(f.begin(), f.end());
      ++faces[f];
    }
  FaceCount count;
  for (const auto& [f, n] : faces) {
    if (n > 2) ++count.shared_by_more;
    if (n != 1) continue;
    ++count.boundary;
    for (double c : planes)
      if (mesh.nodes(0, f[0]) == c && mesh.nodes(0, f[1]) == c && mesh.nodes(0, f[2]) == c)
        ++count.boundary_on_planes;
  }
  return count;
}

// Area of a planar section, signed by its triangles' orientation about +axis (m²).
double SignedArea(const TriangleMesh& section, int axis) {
  double area = 0.0;
  for (Eigen::Index f = 0; f < section.triangles.cols(); ++f) {
    const Eigen::Vector3d a = section.vertices.col(section.triangles(0, f)),
                          b = section.vertices.col(section.triangles(1, f)),
                          c = section.vertices.col(section.triangles(2, f));
    area += 0.5 * (b - a).cross(c - a)[axis];
  }
  return area;
}

// Each piece's surface is closed and TetGen meshes it to its own volume; returns the pieces'
// tets, and their summed surface volume in *volume.
std::vector<TetMesh> MeshPieces(const SlabSurfaces& slabs, double* volume) {
  *volume = 0.0;
  std::vector<TetMesh> tets;
  for (std::size_t k = 0; k < slabs.slabs.size(); ++k) {
    SCOPED_TRACE("piece " + std::to_string(k));
    const TriangleMesh& s = slabs.slabs[k];
    EXPECT_NO_THROW(CheckSurface(s));
    *volume += MeshVolume(s);
    TetMeshSettings ts;
    ts.max_radius_edge = 2.0;
    tets.push_back(TetrahedralizeSlab(s, ts));
    EXPECT_NEAR(TotalVolume(tets.back()), MeshVolume(s), 1e-12 * MeshVolume(s));
  }
  return tets;
}

// The joined pieces conform: no face shared by more than two tets, none left on a slab plane, the
// boundary is the pieces' faces less both sides of every section, and no tet is inverted.
void ExpectConformingJoin(const SlabSurfaces& slabs, const SlabTetMesh& joined,
                          const std::vector<double>& planes) {
  EXPECT_NO_THROW(ValidateTetMesh(joined.mesh));
  const FaceCount faces = CountFaces(joined.mesh, planes);
  EXPECT_EQ(faces.shared_by_more, 0);
  EXPECT_EQ(faces.boundary_on_planes, 0);  // the planes are inside the joined mesh
  long surface_faces = 0;
  for (const TriangleMesh& s : slabs.slabs) surface_faces += s.triangles.cols();
  for (const TriangleMesh& s : slabs.sections) surface_faces -= 2 * s.triangles.cols();
  EXPECT_EQ(faces.boundary, surface_faces);
  for (Eigen::Index t = 0; t < joined.mesh.tets.cols(); ++t)
    ASSERT_GT(TetVolume(joined.mesh, t), 0.0);
}

// With and without interior points in the sections (SlabCut::section_spacing).
TEST(SlabMesher, SlabsAreClosedAndJoinConformingly) {
  for (const double spacing : {0.0, 0.5 * kCell}) {
    SCOPED_TRACE("section spacing " + std::to_string(spacing));
    const TriangleMesh surface = Surface(PlateWithHole(0.1));
    const SlabSurfaces slabs = CutSurfaceIntoSlabs(surface, Cut(spacing));
    ASSERT_EQ(slabs.slabs.size(), 3u);
    ASSERT_EQ(slabs.sections.size(), 2u);
    double volume = 0.0;
    const std::vector<TetMesh> tets = MeshPieces(slabs, &volume);
    // The slabs add up to the solid (the cut and the snap keep the volume to rounding: a snapped
    // vertex moves along the axis by at most `snap`, which changes the volume a little).
    EXPECT_NEAR(volume, MeshVolume(surface), 2e-3 * MeshVolume(surface));
    // Each section is the plate's 0.1 × 0.02 m cross-section (the hole lies in the middle slab).
    for (const TriangleMesh& section : slabs.sections) {
      const double area = SignedArea(section, 0);  // counter-clockwise seen from +x: positive
      // Marching tetrahedra chamfers the section's four edges by up to a cell.
      EXPECT_NEAR(area, 0.1 * 0.02, 0.15 * 0.002);
      std::printf("section area %.4e m^2 (0.1 x 0.02 = 2e-3), %ld triangles, %ld vertices\n", area,
                  static_cast<long>(section.triangles.cols()),
                  static_cast<long>(section.vertices.cols()));
      // Interior points (on no boundary edge of the section) lie half a spacing or more from the
      // boundary; without a spacing there are none.
      std::map<std::pair<int, int>, int> edge_use;
      for (Eigen::Index f = 0; f < section.triangles.cols(); ++f)
        for (int j = 0; j < 3; ++j) {
          const int u = section.triangles(j, f), w = section.triangles((j + 1) % 3, f);
          ++edge_use[{std::min(u, w), std::max(u, w)}];
        }
      std::vector<char> on_boundary(section.vertices.cols(), 0);
      std::vector<std::pair<int, int>> boundary;
      for (const auto& [e, uses] : edge_use)
        if (uses == 1) {
          boundary.push_back(e);
          on_boundary[e.first] = on_boundary[e.second] = 1;
        }
      int interior = 0;
      for (Eigen::Index i = 0; i < section.vertices.cols(); ++i) {
        if (on_boundary[i]) continue;
        ++interior;
        for (const auto& [u, w] : boundary)
          ASSERT_GE(DistanceToSegment(section.vertices.col(i), section.vertices.col(u),
                                      section.vertices.col(w)),
                    0.5 * spacing - 1e-12);
      }
      if (spacing > 0) {
        EXPECT_GT(interior, 0);
      } else {
        EXPECT_EQ(interior, 0);
      }
    }
    ExpectConformingJoin(slabs, JoinSlabs(tets), Cut().planes);
  }
}

TEST(SlabMesher, EditInsideOneSlabLeavesTheOtherSlabsBitForBit) {
  // The hole moves by 6 mm inside the middle slab (x from −0.0755 to 0.0245).
  const SlabSurfaces before = CutSurfaceIntoSlabs(Surface(PlateWithHole(-0.03)), Cut());
  const SlabSurfaces after = CutSurfaceIntoSlabs(Surface(PlateWithHole(-0.024)), Cut());
  ASSERT_EQ(before.slabs.size(), after.slabs.size());
  EXPECT_NE(SurfaceHash(before.slabs[1]), SurfaceHash(after.slabs[1]));
  for (int k : {0, 2}) {
    SCOPED_TRACE(k);
    EXPECT_EQ(SurfaceHash(before.slabs[k]), SurfaceHash(after.slabs[k]));
    TetMeshSettings ts;
    ts.max_radius_edge = 2.0;
    const TetMesh a = TetrahedralizeSlab(before.slabs[k], ts);
    const TetMesh b = TetrahedralizeSlab(after.slabs[k], ts);
    ASSERT_EQ(a.nodes.cols(), b.nodes.cols());
    ASSERT_EQ(a.tets.cols(), b.tets.cols());
    EXPECT_TRUE((a.nodes.array() == b.nodes.array()).all());
    EXPECT_TRUE((a.tets.array() == b.tets.array()).all());
  }
  for (int p : {0, 1}) EXPECT_EQ(SurfaceHash(before.sections[p]), SurfaceHash(after.sections[p]));
}

// Strips: the middle slab cut across y into three (one strip plane through the hole), the last
// into two. The pieces are closed, add up to the solid and join conformingly; a node on a line
// where a strip plane meets a slab plane is shared by three pieces' tets.
TEST(SlabMesher, StripsAreClosedAndJoinConformingly) {
  for (const double spacing : {0.0, 0.5 * kCell}) {
    SCOPED_TRACE("section spacing " + std::to_string(spacing));
    const TriangleMesh surface = Surface(PlateWithHole(-0.03));
    SlabCut cut = Cut(spacing);
    cut.strip_axis = 1;
    cut.strip_planes = {{}, {-0.0205, 0.0105}, {0.0045}};  // 0.0105: through the hole
    const SlabSurfaces slabs = CutSurfaceIntoSlabs(surface, cut);
    ASSERT_EQ(slabs.slabs.size(), 6u);
    ASSERT_EQ(slabs.sections.size(), 5u);
    double volume = 0.0;
    const std::vector<TetMesh> tets = MeshPieces(slabs, &volume);
    EXPECT_NEAR(volume, MeshVolume(surface), 2e-3 * MeshVolume(surface));
    // The strip sections: the plate's 0.1 (slab width) × 0.02 m section across y, less the hole's
    // chord for the plane through it (x from −0.0755 to 0.0245 or 0.15).
    const double widths[3] = {0.1, 0.1 - 2 * std::sqrt(0.008 * 0.008 - 0.0005 * 0.0005),
                              0.15 - 0.0245};
    for (int j = 0; j < 3; ++j) {
      const TriangleMesh& section = slabs.sections[2 + j];
      const double area = SignedArea(section, 1);  // counter-clockwise seen from +y: positive
      // Marching tetrahedra chamfers the plate's edges and the hole by up to a cell.
      EXPECT_NEAR(area, widths[j] * 0.02, 0.2 * widths[j] * 0.02) << "strip section " << j;
    }
    const SlabTetMesh joined = JoinSlabs(tets);
    EXPECT_NEAR(TotalVolume(joined.mesh), volume, 1e-12 * volume);
    // Every piece face on a section (strip sections included) is matched by its neighbour's.
    ExpectConformingJoin(slabs, joined, cut.planes);
    // Nodes on the lines x = plane, y = strip plane belong to three pieces.
    std::vector<std::set<int>> pieces_of(joined.mesh.nodes.cols());
    for (Eigen::Index t = 0; t < joined.mesh.tets.cols(); ++t)
      for (int j = 0; j < 4; ++j) pieces_of[joined.mesh.tets(j, t)].insert(joined.slab(t));
    long on_three = 0;
    for (const std::set<int>& p : pieces_of) on_three += p.size() == 3;
    EXPECT_GT(on_three, 0);
  }
}

// A block 60 mm thick with a tube along y through it that the second slab plane cuts: that
// section is two wide strips above and below the tube, so each strip plane's line crosses it in
// two stretches, with interior points on both sides. Three strip planes in the middle slab (two
// of them 3 mm apart, so that one line's points are inserted next to the other's stretch), one
// in the last: the pieces are closed and join conformingly.
TEST(SlabMesher, StripLinesAcrossASectionInTwoStretchesKeepThePiecesClosed) {
  ImplicitNode block(BoxParams{Eigen::Vector3d(0.3, 0.1, 0.06)});
  ImplicitNode tube(TranslateParams{Eigen::Vector3d(0.03, 0.0, 0.0)},
                    {ImplicitNode(RotateParams{Eigen::Vector3d(1, 0, 0), 1.5707963267948966},
                                  {ImplicitNode(CylinderParams{0.012, 0.2})})});
  const TriangleMesh surface =
      Surface(CompiledSolid::Compile(ImplicitNode(DifferenceParams{}, {block, tube})));
  SlabCut cut = Cut(0.5 * kCell);
  cut.strip_planes = {{}, {-0.0155, -0.0045, -0.0015}, {-0.0015}};  // off the grid planes
  const SlabSurfaces slabs = CutSurfaceIntoSlabs(surface, cut);
  ASSERT_EQ(slabs.slabs.size(), 7u);
  double volume = 0.0;
  const std::vector<TetMesh> tets = MeshPieces(slabs, &volume);
  EXPECT_NEAR(volume, MeshVolume(surface), 2e-3 * MeshVolume(surface));
  ExpectConformingJoin(slabs, JoinSlabs(tets), cut.planes);
  // The section at x = 0.0245 m misses the tube's band: two parts, each crossed by every line.
  const double band = 2 * std::sqrt(0.012 * 0.012 - 0.0055 * 0.0055);
  EXPECT_NEAR(SignedArea(slabs.sections[1], 0), 0.1 * (0.06 - band), 0.1 * 0.1 * 0.06);
}

TEST(SlabMesher, EditInsideOneStripLeavesTheOtherPiecesBitForBit) {
  // The hole (y from 0.002 to 0.018 m) moves by 6 mm along x inside the middle slab's upper
  // strip (y > −0.0155).
  SlabCut cut = Cut();
  cut.strip_planes = {{}, {-0.0155}, {}};
  const SlabSurfaces before = CutSurfaceIntoSlabs(Surface(PlateWithHole(-0.03)), cut);
  const SlabSurfaces after = CutSurfaceIntoSlabs(Surface(PlateWithHole(-0.024)), cut);
  ASSERT_EQ(before.slabs.size(), 4u);
  ASSERT_EQ(after.slabs.size(), 4u);
  EXPECT_NE(SurfaceHash(before.slabs[2]), SurfaceHash(after.slabs[2]));
  for (int k : {0, 1, 3}) {
    SCOPED_TRACE(k);
    EXPECT_EQ(SurfaceHash(before.slabs[k]), SurfaceHash(after.slabs[k]));
  }
  for (int p : {0, 1, 2})
    EXPECT_EQ(SurfaceHash(before.sections[p]), SurfaceHash(after.sections[p]));
}

TEST(SlabMesher, RefusesBadCutsAndAPlaneOnAFace) {
  const TriangleMesh surface = Surface(PlateWithHole(0.1));
  SlabCut bad = Cut();
  bad.axis = 3;
  EXPECT_THROW(CutSurfaceIntoSlabs(surface, bad), std::invalid_argument);
  bad = Cut();
  bad.planes = {0.0, 0.0};
  EXPECT_THROW(CutSurfaceIntoSlabs(surface, bad), std::invalid_argument);
  bad = Cut();
  bad.snap = -1.0;
  EXPECT_THROW(CutSurfaceIntoSlabs(surface, bad), std::invalid_argument);
  bad = Cut(-kCell);
  EXPECT_THROW(CutSurfaceIntoSlabs(surface, bad), std::invalid_argument);
  bad = Cut(std::nan(""));
  EXPECT_THROW(CutSurfaceIntoSlabs(surface, bad), std::invalid_argument);
  bad = Cut(1e-7);  // 1e6 × 2e5 grid points on the 0.1 × 0.02 m section
  try {
    CutSurfaceIntoSlabs(surface, bad);
    ADD_FAILURE() << "a 0.1 um section spacing was accepted";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("section_spacing"), std::string::npos) << e.what();
  }
  // A plane on the plate's top face z = 0.01 (axis z), where triangles lie in the plane.
  bad = Cut();
  bad.axis = 2;
  bad.planes = {0.01};
  bad.snap = 1e-6;
  EXPECT_THROW(CutSurfaceIntoSlabs(surface, bad), std::invalid_argument);
  // Strips: one list per slab, increasing, across another axis.
  bad = Cut();
  bad.strip_planes = {{0.0}, {0.0}};
  EXPECT_THROW(CutSurfaceIntoSlabs(surface, bad), std::invalid_argument);
  bad.strip_planes = {{0.0}, {0.01, 0.01}, {}};
  EXPECT_THROW(CutSurfaceIntoSlabs(surface, bad), std::invalid_argument);
  bad.strip_planes = {{0.0}, {}, {}};
  bad.strip_axis = 0;
  EXPECT_THROW(CutSurfaceIntoSlabs(surface, bad), std::invalid_argument);
  // A strip plane on the plate's top face (strips across z).
  bad.strip_axis = 2;
  bad.strip_planes = {{}, {0.01}, {}};
  bad.snap = 1e-6;
  EXPECT_THROW(CutSurfaceIntoSlabs(surface, bad), std::invalid_argument);
}

}  // namespace
}  // namespace spidarcad::modeling
