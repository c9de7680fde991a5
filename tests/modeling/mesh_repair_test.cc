// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
// RepairTriangleMesh and FindSelfIntersections. The HardMeshImport suite is the meshing part of
// the hard cases (issue 14): open, non-manifold, duplicate, degenerate and self-intersecting
// input, each repaired (and then accepted by CheckSurface and TetGen, an independent checker
// and consumer) or refused with the file, the defect and the first offending triangle named.
#include "spidarcad/modeling/mesh_repair.h"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <string>
#include <vector>

#include "spidarcad/modeling/tetgen_mesher.h"
#include "spidarcad/modeling/triangle_mesh_io.h"

namespace spidarcad::modeling {
namespace {

std::string OutPath(const std::string& name) {
  return std::string(SPIDARCAD_TEST_OUTPUT_DIR) + "/" + name;
}

// An axis-aligned box as 12 outward (counter-clockwise from outside) triangles over 8 vertices.
TriangleMesh BoxSurface(const Eigen::Vector3d& lo, const Eigen::Vector3d& hi) {
  TriangleMesh m;
  m.vertices.resize(3, 8);
  for (int i = 0; i < 8; ++i) {
    m.vertices.col(i) << ((i & 1) ? hi.x() : lo.x()), ((i & 2) ? hi.y() : lo.y()),
        ((i & 4) ? hi.z() : lo.z());
  }
  m.triangles.resize(3, 12);
  m.triangles << 0, 1, 4, 5, 0, 1, 2, 3, 0, 2, 1, 3,  //
      2, 2, 5, 7, 1, 5, 6, 6, 4, 4, 3, 7,             //
      1, 3, 6, 6, 4, 4, 3, 7, 2, 6, 5, 5;
  return m;
}

TriangleMesh UnitBox() { return BoxSurface(Eigen::Vector3d::Zero(), Eigen::Vector3d::Ones()); }

// Concatenates two meshes (no vertex shared).
TriangleMesh Join(const TriangleMesh& a, const TriangleMesh& b) {
  TriangleMesh m;
  m.vertices.resize(3, a.vertices.cols() + b.vertices.cols());
  m.vertices << a.vertices, b.vertices;
  m.triangles.resize(3, a.triangles.cols() + b.triangles.cols());
  m.triangles << a.triangles, (b.triangles.array() + static_cast<int>(a.vertices.cols())).matrix();
  return m;
}

// Appends triangle t.
void AddTriangle(TriangleMesh* m, int a, int b, int c) {
  m->triangles.conservativeResize(3, m->triangles.cols() + 1);
  m->triangles.col(m->triangles.cols() - 1) << a, b, c;
}

// Removes triangle f.
TriangleMesh WithoutTriangle(const TriangleMesh& m, int f) {
  TriangleMesh out = m;
  out.triangles.resize(3, m.triangles.cols() - 1);
  for (int g = 0, k = 0; g < m.triangles.cols(); ++g)
    if (g != f) out.triangles.col(k++) = m.triangles.col(g);
  return out;
}

// Every triangle with its own three vertices (a "soup", as a naive exporter writes).
TriangleMesh Soup(const TriangleMesh& m, double jitter) {
  TriangleMesh out;
  out.vertices.resize(3, 3 * m.triangles.cols());
  out.triangles.resize(3, m.triangles.cols());
  for (int f = 0; f < m.triangles.cols(); ++f)
    for (int k = 0; k < 3; ++k) {
      // A deterministic jitter, different for every copy: up to `jitter` on each coordinate.
      const double s = jitter * (3 * f + k + 1) / (3.0 * static_cast<double>(m.triangles.cols()));
      out.vertices.col(3 * f + k) = m.vertices.col(m.triangles(k, f)).array() + s;
      out.triangles(k, f) = 3 * f + k;
    }
  return out;
}

// Tetrahedralizes with TetGen (its own CheckSurface first) and returns the volume of the tets.
double TetVolume(const TriangleMesh& surface) {
  TetMeshStats stats;
  TetrahedralizeSurface(surface, TetMeshSettings{}, &stats);
  return stats.quality.total_volume;
}

// Runs f, which must throw MeshDefectError of `defect`, and returns the error's message and
// triangle.
template <typename F>
std::pair<std::string, long> ExpectDefect(F f, MeshDefect defect) {
  try {
    f();
    ADD_FAILURE() << "no MeshDefectError, expected " << MeshDefectName(defect);
  } catch (const MeshDefectError& e) {
    EXPECT_EQ(e.defect(), defect) << e.what();
    return {e.what(), e.triangle()};
  }
  return {"", 0};
}

bool Contains(const std::string& text, const std::string& part) {
  return text.find(part) != std::string::npos;
}

TEST(MeshRepair, LeavesAClosedBoxUnchanged) {
  MeshRepairReport report;
  const TriangleMesh out = RepairTriangleMesh(UnitBox(), {}, &report);
  EXPECT_FALSE(report.Changed());
  ASSERT_EQ(report.Lines().size(), 1u);
  EXPECT_EQ(report.Lines()[0], "no repair needed");
  EXPECT_EQ(out.vertices, UnitBox().vertices);
  EXPECT_EQ(out.triangles, UnitBox().triangles);
}

TEST(MeshRepair, RefusesBadSettings) {
  MeshRepairSettings settings;
  settings.weld_tolerance = -1.0;
  EXPECT_THROW(RepairTriangleMesh(UnitBox(), settings), std::invalid_argument);
  settings.weld_tolerance = std::numeric_limits<double>::quiet_NaN();
  EXPECT_THROW(RepairTriangleMesh(UnitBox(), settings), std::invalid_argument);
}

TEST(MeshRepair, RefusesANonFiniteVertexNamingIt) {
  TriangleMesh box = UnitBox();
  box.vertices(1, 5) = std::numeric_limits<double>::quiet_NaN();
  const auto [what, triangle] = ExpectDefect(
      [&] { RepairTriangleMesh(box, {}, nullptr, "part.stl"); }, MeshDefect::kNonFinite);
  EXPECT_TRUE(Contains(what, "part.stl: vertex 6")) << what;
}

TEST(FindSelfIntersections, FindsNoneOnDisjointBoxesAndAgreesWithCheckSurfaceOnOverlap) {
  const TriangleMesh apart =
      Join(UnitBox(), BoxSurface(Eigen::Vector3d(2, 0, 0), Eigen::Vector3d(3, 1, 1)));
  EXPECT_TRUE(FindSelfIntersections(apart).empty());
  // Offset on every axis so that no two faces are coplanar: CheckSurface's own predicates (a
  // second algorithm, floating point with tolerances) find a crossing pair too, and CGAL's list
  // holds the pair CheckSurface names.
  const TriangleMesh overlap =
      Join(UnitBox(), BoxSurface(Eigen::Vector3d(0.5, 0.4, 0.3), Eigen::Vector3d(1.5, 1.4, 1.3)));
  const auto pairs = FindSelfIntersections(overlap);
  ASSERT_FALSE(pairs.empty());
  for (const auto& [f, g] : pairs) {
    EXPECT_LT(f, 12);  // every crossing is between the two boxes
    EXPECT_GE(g, 12);
  }
  try {
    CheckSurface(overlap);
    ADD_FAILURE() << "CheckSurface accepted overlapping boxes";
  } catch (const SurfaceDefectError& e) {
    const std::string what = e.what();
    ASSERT_TRUE(Contains(what, "intersects itself")) << what;
    bool named = false;
    for (const auto& [f, g] : pairs)
      named |= Contains(what, "triangles " + std::to_string(f) + " (") &&
               Contains(what, " and " + std::to_string(g) + " (");
    EXPECT_TRUE(named) << what;
  }
}

TEST(HardMeshImport, DropsDuplicateAndBackToBackTrianglesAndTetGenMeshesTheRest) {
  TriangleMesh box = UnitBox();
  AddTriangle(&box, box.triangles(0, 3), box.triangles(1, 3), box.triangles(2, 3));  // repeat
  AddTriangle(&box, box.triangles(1, 7), box.triangles(2, 7), box.triangles(0, 7));  // rotated
  // A back-to-back pair inside the box (a membrane): both must go.
  box.vertices.conservativeResize(3, 11);
  box.vertices.col(8) << 0.2, 0.2, 0.5;
  box.vertices.col(9) << 0.8, 0.2, 0.5;
  box.vertices.col(10) << 0.5, 0.8, 0.5;
  AddTriangle(&box, 8, 9, 10);
  AddTriangle(&box, 8, 10, 9);
  MeshRepairReport report;
  const TriangleMesh out = RepairTriangleMesh(box, {}, &report);
  EXPECT_EQ(report.duplicate_triangles, 2);
  EXPECT_EQ(report.back_to_back_pairs, 1);
  EXPECT_EQ(report.unused_vertices, 3);
  EXPECT_EQ(out.triangles.cols(), 12);
  EXPECT_NO_THROW(CheckSurface(out));
  const double volume = TetVolume(out);
  RecordProperty("figure", "16 triangles (2 repeats, 1 back-to-back pair) -> " +
                               std::to_string(out.triangles.cols()) + " triangles; tet volume " +
                               std::to_string(volume) + " m^3");
  RecordProperty("bar", "12 triangles, CheckSurface passes, tet volume 1 m^3 within 1e-12");
  EXPECT_NEAR(volume, 1.0, 1e-12);
}

TEST(HardMeshImport, DropsAZeroAreaTriangleAndSplitsItsNeighbourSoNoCrackOpens) {
  // Split triangle 4 of the box (the y = 0 face: 0 1 5 ... ) along one edge at its midpoint m
  // and fill the crack with the zero-area triangle (c, a, m), as a T-junction in an STL does.
  TriangleMesh box = UnitBox();
  // Find the triangle across the edge (0, 1) from triangle 4, which holds 0 -> 1.
  const int a = 0, c = 1;
  int u = -1;
  for (int f = 0; f < 12; ++f)
    for (int k = 0; k < 3; ++k)
      if (box.triangles(k, f) == c && box.triangles((k + 1) % 3, f) == a) u = f;
  ASSERT_GE(u, 0);
  int e = -1;
  for (int k = 0; k < 3; ++k)
    if (box.triangles(k, u) != a && box.triangles(k, u) != c) e = box.triangles(k, u);
  box.vertices.conservativeResize(3, 9);
  const int m = 8;
  box.vertices.col(m) = 0.5 * (box.vertices.col(a) + box.vertices.col(c));
  box.triangles.col(u) << c, m, e;
  AddTriangle(&box, m, a, e);
  AddTriangle(&box, c, a, m);  // zero area, closes the crack
  EXPECT_THROW(CheckSurface(box), SurfaceDefectError);
  MeshRepairReport report;
  const TriangleMesh out = RepairTriangleMesh(box, {}, &report);
  EXPECT_EQ(report.degenerate_triangles, 1);
  EXPECT_EQ(report.split_triangles, 1);
  EXPECT_EQ(out.triangles.cols(), 14);
  EXPECT_NO_THROW(CheckSurface(out));
  const double volume = TetVolume(out);
  RecordProperty("figure", "1 zero-area triangle dropped, 1 split; tet volume " +
                               std::to_string(volume) + " m^3");
  RecordProperty("bar", "CheckSurface passes, tet volume 1 m^3 within 1e-12");
  EXPECT_NEAR(volume, 1.0, 1e-12);
}

TEST(HardMeshImport, WeldsATriangleSoupWithinTheTolerance) {
  // 36 vertices, the copies of a corner up to 1.7e-11 apart (the tolerance is 1e-9 x sqrt(3)).
  const TriangleMesh soup = Soup(UnitBox(), 1e-11);
  MeshRepairReport report;
  const TriangleMesh out = RepairTriangleMesh(soup, {}, &report);
  EXPECT_EQ(report.welded_vertices, 28);
  EXPECT_EQ(out.vertices.cols(), 8);
  EXPECT_NO_THROW(CheckSurface(out));
  // A tolerance below the jitter leaves a soup: every edge open.
  MeshRepairSettings tight;
  tight.weld_tolerance = 1e-13;
  const auto [what, triangle] = ExpectDefect(
      [&] { RepairTriangleMesh(soup, tight, nullptr, "soup.obj"); }, MeshDefect::kOpen);
  EXPECT_EQ(triangle, 1);
  RecordProperty("figure", "36 soup vertices -> " + std::to_string(out.vertices.cols()) +
                               " after welding; with tolerance 1e-13: " + what);
  RecordProperty("bar", "8 vertices, CheckSurface passes; refused as open below the jitter");
  EXPECT_TRUE(Contains(what, "soup.obj: the surface is open: 36 edges")) << what;
}

TEST(HardMeshImport, TurnsInconsistentAndInsideOutTrianglesOverKeepingACavityInward) {
  // A hollow box: outer [0,3]^3 and a cavity [1,2]^3, both written outward (the cavity must
  // face inward), with three outer triangles flipped on top.
  TriangleMesh hollow = Join(BoxSurface(Eigen::Vector3d::Zero(), Eigen::Vector3d::Constant(3)),
                             BoxSurface(Eigen::Vector3d::Ones(), Eigen::Vector3d::Constant(2)));
  for (int f : {0, 5, 9}) std::swap(hollow.triangles(1, f), hollow.triangles(2, f));
  MeshRepairReport report;
  const TriangleMesh out = RepairTriangleMesh(hollow, {}, &report);
  EXPECT_EQ(report.flipped_triangles, 3 + 12);
  EXPECT_NO_THROW(CheckSurface(out));
  EXPECT_NEAR(MeshVolume(out), 27.0 - 1.0, 1e-12);
  const double volume = TetVolume(out);
  RecordProperty("figure", "15 triangles turned over; enclosed volume " +
                               std::to_string(MeshVolume(out)) + " m^3, tets " +
                               std::to_string(volume) + " m^3");
  RecordProperty("bar", "26 m^3 (27 - 1 cavity) within 1e-12");
  EXPECT_NEAR(volume, 26.0, 1e-12);
  // The whole surface inside out: every triangle turned over.
  TriangleMesh inverted = UnitBox();
  inverted.triangles.row(1).swap(inverted.triangles.row(2));
  const TriangleMesh fixed = RepairTriangleMesh(inverted, {}, &report);
  EXPECT_EQ(report.flipped_triangles, 12);
  EXPECT_NEAR(MeshVolume(fixed), 1.0, 1e-12);
}

TEST(HardMeshImport, RefusesAnOpenSurfaceNamingTheFileAndTheFirstBoundaryEdge) {
  const std::string path = OutPath("hard_open_box.stl");
  WriteTriangleMesh(WithoutTriangle(UnitBox(), 4), path);
  const auto [what, triangle] = ExpectDefect([&] { ImportSolidMesh(path); }, MeshDefect::kOpen);
  RecordProperty("figure", what);
  RecordProperty("bar", "refused (MeshDefectError kOpen) naming the file, the edge, the triangle");
  EXPECT_TRUE(Contains(what, path + ": the surface is open: 3 edges have one triangle only"))
      << what;
  EXPECT_TRUE(Contains(what, "the edge from (")) << what;
  EXPECT_TRUE(Contains(what, "triangle " + std::to_string(triangle) + " of the file")) << what;
  EXPECT_GE(triangle, 1);
  EXPECT_TRUE(Contains(what, "Close the holes")) << what;
}

TEST(HardMeshImport, RefusesANonManifoldEdgeNamingIt) {
  // Two boxes sharing the edge x = 1, y = 1 (welded: the corners coincide), as one STL.
  const std::string path = OutPath("hard_edge_boxes.stl");
  WriteTriangleMesh(Join(UnitBox(), BoxSurface(Eigen::Vector3d(1, 1, 0), Eigen::Vector3d(2, 2, 1))),
                    path);
  const auto [what, triangle] =
      ExpectDefect([&] { ImportSolidMesh(path); }, MeshDefect::kNonManifoldEdge);
  RecordProperty("figure", what);
  RecordProperty("bar", "refused (kNonManifoldEdge) naming the file, the edge and its 4 triangles");
  EXPECT_TRUE(Contains(what, path + ": the surface is non-manifold: 1 edges")) << what;
  EXPECT_TRUE(Contains(what, "the edge from (1, 1, 0) to (1, 1, 1)") ||
              Contains(what, "the edge from (1, 1, 1) to (1, 1, 0)"))
      << what;
  EXPECT_TRUE(Contains(what, "shared by 4 triangles")) << what;
}

TEST(HardMeshImport, RefusesASelfIntersectingSurfaceNamingTheFirstPair) {
  const std::string path = OutPath("hard_overlap_boxes.obj");
  WriteTriangleMesh(
      Join(UnitBox(), BoxSurface(Eigen::Vector3d(0.5, 0.4, 0.3), Eigen::Vector3d(1.5, 1.4, 1.3))),
      path);
  const auto [what, triangle] =
      ExpectDefect([&] { ImportSolidMesh(path); }, MeshDefect::kSelfIntersection);
  RecordProperty("figure", what);
  RecordProperty("bar", "refused (kSelfIntersection) naming the file and a crossing pair");
  EXPECT_TRUE(Contains(what, path + ": the surface intersects itself")) << what;
  // The first triangle of the named pair is in the first box (file triangles 1..12), the second
  // in the other (13..24).
  EXPECT_GE(triangle, 1);
  EXPECT_LE(triangle, 12);
  EXPECT_TRUE(Contains(what, "triangle " + std::to_string(triangle) + " and triangle 1")) << what;
}

TEST(HardMeshImport, AcceptsTwoBoxesTouchingAtOneCorner) {
  // A vertex where two fans meet is no self-intersection: TetGen meshes both boxes.
  TriangleMesh boxes =
      Join(UnitBox(), BoxSurface(Eigen::Vector3d::Ones(), Eigen::Vector3d(2, 2, 2)));
  const TriangleMesh out = RepairTriangleMesh(boxes);
  EXPECT_EQ(out.vertices.cols(), 15);  // the shared corner welded
  const double volume = TetVolume(out);
  RecordProperty("figure",
                 "boxes touching at a corner: tet volume " + std::to_string(volume) + " m^3");
  RecordProperty("bar", "accepted, 2 m^3 within 1e-12");
  EXPECT_NEAR(volume, 2.0, 1e-12);
}

TEST(HardMeshImport, RefusesAFileThatIsOnlyAMembrane) {
  TriangleMesh sheet;
  sheet.vertices = Eigen::Matrix3d::Identity();
  sheet.triangles.resize(3, 2);
  sheet.triangles << 0, 0, 1, 2, 2, 1;
  const auto [what, triangle] = ExpectDefect(
      [&] { RepairTriangleMesh(sheet, {}, nullptr, "sheet.ply"); }, MeshDefect::kEmpty);
  EXPECT_TRUE(Contains(what, "sheet.ply: no triangle is left of 2")) << what;
  (void)triangle;
  RecordProperty("figure", "2-triangle membrane refused: " + what);
  RecordProperty("bar", "refused as empty (MeshDefect::kEmpty), naming the file");
}

}  // namespace
}  // namespace spidarcad::modeling
