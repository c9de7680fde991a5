// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
// Hard cases of meshing implicit solids across the surface mesher, TetGen and CGAL (issue 14):
// pinched zero sets, features thinner than a cell, and one shape from 1 mm to 10 m. Each test
// records its measured figure and its pass line; the figures are compared with closed forms
// (volumes) and across scales, not with earlier output.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <numbers>
#include <string>
#include <vector>

#include "spidarcad/modeling/cgal_mesher.h"
#include "spidarcad/modeling/implicit_evaluator.h"
#include "spidarcad/modeling/implicit_node.h"
#include "spidarcad/modeling/mesh_repair.h"
#include "spidarcad/modeling/scene_io.h"
#include "spidarcad/modeling/surface_mesher.h"
#include "spidarcad/modeling/tetgen_mesher.h"

namespace spidarcad::modeling {
namespace {

std::string Format(const char* format, double a, double b = 0.0, double c = 0.0, double d = 0.0) {
  char buffer[256];
  std::snprintf(buffer, sizeof buffer, format, a, b, c, d);
  return buffer;
}

ImplicitNode At(const Eigen::Vector3d& t, ImplicitNode child) {
  return ImplicitNode(TranslateParams{t}, {std::move(child)});
}

ImplicitNode Box(const Eigen::Vector3d& lo, const Eigen::Vector3d& hi) {
  return At(0.5 * (lo + hi), ImplicitNode(BoxParams{hi - lo}));
}

// Surface mesh of solid in bounds at cell h.
TriangleMesh Surface(const CompiledSolid& solid, const Eigen::AlignedBox3d& bounds, double h) {
  SurfaceMeshSettings s;
  s.bounds = bounds;
  s.cell_size = h;
  return MeshSurface(solid, s);
}

TEST(HardMeshPinched, TwoSpheresTouchingAtAPointMeshAsAValidSolid) {
  // Spheres of radius r touching at the origin. The grid (cell r/10 on a box from -2.1r) has no
  // vertex at the touching point, so the zero set there is pinched between grid vertices.
  const double r = 0.02, h = r / 10.0;
  const CompiledSolid solid = CompiledSolid::Compile(
      ImplicitNode(UnionParams{}, {At(Eigen::Vector3d(-r, 0, 0), ImplicitNode(SphereParams{r})),
                                   At(Eigen::Vector3d(r, 0, 0), ImplicitNode(SphereParams{r}))}));
  const Eigen::AlignedBox3d bounds(Eigen::Vector3d(-2.1 * r, -1.13 * r, -1.17 * r),
                                   Eigen::Vector3d(2.1 * r, 1.13 * r, 1.17 * r));
  const TriangleMesh surface = Surface(solid, bounds, h);
  EXPECT_NO_THROW(CheckSurface(surface));
  MeshRepairReport report;
  EXPECT_NO_THROW(RepairTriangleMesh(surface, {}, &report));
  EXPECT_FALSE(report.Changed());
  TetMeshStats stats;
  TetrahedralizeSurface(surface, {}, &stats);
  const double exact = 2.0 * 4.0 / 3.0 * std::numbers::pi * r * r * r;
  const double tet_error = std::abs(stats.quality.total_volume - exact) / exact;
  // CGAL from the function: it may join or separate the spheres at the pinch, but must give a
  // valid mesh of about the right volume, or an exception (never an abort).
  CgalMeshSettings cgal = CgalMeshSettings::ForSize(2.0 * h);
  cgal.optimizer_time_limit = 0.0;
  cgal.exude_time_limit = 0.0;
  cgal.sliver_bound_deg = 5.0;
  CgalMeshStats cgal_stats;
  double cgal_error = -1.0;
  try {
    MeshImplicitWithCgal(solid, bounds, cgal, &cgal_stats);
    cgal_error = std::abs(cgal_stats.quality.total_volume - exact) / exact;
  } catch (const CgalMeshError& e) {
    ADD_FAILURE() << "CGAL refused the pinched spheres: " << e.what();
  }
  RecordProperty("figure", Format("TetGen: volume error %.3g %%, min dihedral %.3g deg; CGAL: "
                                  "volume error %.3g %%, min dihedral %.3g deg",
                                  100 * tet_error, stats.quality.min_dihedral_deg, 100 * cgal_error,
                                  cgal_stats.quality.min_dihedral_deg));
  // TetGen keeps the pinch (two fans of the surface meet there) and leaves a sliver beside it
  // (q bounds the radius-edge ratio, not the dihedral angle); CGAL's facets of size r/5 cut the
  // spheres' curvature (chordal loss).
  RecordProperty("bar",
                 "closed valid surface; volume within 1 % (TetGen) and 3 % (CGAL, facets r/5) "
                 "of 8/3 pi r^3; min dihedral > 0.1 deg (TetGen) and > 3 deg (CGAL)");
  EXPECT_LT(tet_error, 0.01);
  EXPECT_GE(cgal_error, 0.0);
  EXPECT_LT(cgal_error, 0.03);
  EXPECT_GT(stats.quality.min_dihedral_deg, 0.1);
  EXPECT_GT(cgal_stats.quality.min_dihedral_deg, 3.0);
}

TEST(HardMeshPinched, TwoBoxesSharingAnEdgeMeshAsAValidSolid) {
  // Two boxes a x a x b that meet along the z axis only; the grid is offset so the shared edge
  // runs between grid vertices.
  const double a = 0.02, b = 0.01, h = a / 12.0;
  const CompiledSolid solid = CompiledSolid::Compile(
      ImplicitNode(UnionParams{}, {Box(Eigen::Vector3d(0, 0, 0), Eigen::Vector3d(a, a, b)),
                                   Box(Eigen::Vector3d(-a, -a, 0), Eigen::Vector3d(0, 0, b))}));
  const Eigen::AlignedBox3d bounds(Eigen::Vector3d(-1.137 * a, -1.129 * a, -0.23 * b),
                                   Eigen::Vector3d(1.113 * a, 1.121 * a, 1.21 * b));
  const TriangleMesh surface = Surface(solid, bounds, h);
  EXPECT_NO_THROW(CheckSurface(surface));
  TetMeshStats stats;
  TetrahedralizeSurface(surface, {}, &stats);
  const double exact = 2.0 * a * a * b;
  const double tet_error = std::abs(stats.quality.total_volume - exact) / exact;
  RecordProperty("figure", Format("TetGen: volume error %.3g %% (edges cut off by about a cell), "
                                  "min dihedral %.3g deg",
                                  100 * tet_error, stats.quality.min_dihedral_deg));
  RecordProperty("bar", "closed valid surface, TetGen meshes it; volume within 10 %");
  EXPECT_LT(tet_error, 0.10);
  EXPECT_GT(stats.quality.min_dihedral_deg, 0.5);
}

TEST(HardMeshThin, HolesAboutACellAcrossLeaveNoTriangleUnderTenDegrees) {
  // The platform's 8 mm load holes and 11 mm bolt holes at cells from 6.25 to 9.75 mm, on the
  // product's snapped route, each cell on two grid placements: the zero set pinches in holes about
  // a cell across, and the triangles across the opened pinch were needles and caps (down to 1.9°
  // with the mend pass off, mend_angle_deg = 0). The bar: no angle under 10° with the pass, a
  // valid surface, the largest sampled distance to the surface no larger than without it.
  const Scene scene = LoadScene(std::string(SPIDARCAD_SOURCE_DIR) + "/assets/scenes/platform.json");
  const CompiledSolid solid = CompiledSolid::Compile(scene.solids.at(0).root);
  int meshes = 0, needed = 0;
  double worst_off = 180.0, worst_on = 180.0, worst_error_rise = 0.0;
  for (int k = 0; k <= 14; ++k) {
    const double h = 0.00625 + 0.00025 * k;
    for (double shift : {0.0, 0.37}) {
      const Eigen::Vector3d lo =
          Eigen::Vector3d(-0.02, -0.12, -0.17) + Eigen::Vector3d::Constant(shift * h);
      SurfaceMeshSettings s;
      s.bounds = Eigen::AlignedBox3d(lo, lo + Eigen::Vector3d(0.34, 0.24, 0.2));
      s.cell_size = h;
      s.snap_cells = kProductSnapCells;
      const TriangleMesh on = MeshSurface(solid, s);
      s.mend_angle_deg = 0.0;
      const TriangleMesh off = MeshSurface(solid, s);
      const double angle_on = MeasureTriangleAngles(on).min_angle_deg;
      const double angle_off = MeasureTriangleAngles(off).min_angle_deg;
      const std::string what = Format("cell %.5g m, shift %.2g", h, shift);
      EXPECT_GE(angle_on, 10.0) << what;
      EXPECT_NO_THROW(CheckSurface(on)) << what;
      const double rise =
          (MeasureSurfaceError(solid, on).max - MeasureSurfaceError(solid, off).max) / h;
      EXPECT_LE(rise, 1e-9) << what;
      ++meshes;
      needed += angle_off < 10.0;
      worst_off = std::min(worst_off, angle_off);
      worst_on = std::min(worst_on, angle_on);
      worst_error_rise = std::max(worst_error_rise, rise);
    }
  }
  RecordProperty("figure",
                 Format("%.0f meshes: %.0f with triangles under 10 deg without the mend "
                        "pass (worst %.3g deg); with it the worst is %.3g deg",
                        meshes, needed, worst_off, worst_on) +
                     Format(", the largest surface distance %+.2g cells", worst_error_rise));
  RecordProperty("bar",
                 "every angle >= 10 deg, CheckSurface passes, largest sampled surface distance "
                 "no more than without the pass; the pass had work (some mesh under "
                 "10 deg without it)");
  EXPECT_GT(needed, 0);
}

TEST(HardMeshThin, AFinThinnerThanACellIsLostOrKeptButTheSurfaceStaysValid) {
  // A cube of edge c with a fin of thickness t sticking out by c/2 on +x, at cells h with
  // t = 0.3 h (thinner than a cell) and t = 2 h (resolved). The figure is the share of the fin's
  // volume the mesh keeps; the bar is a valid surface and a body within 3 %.
  const double c = 0.02, h = c / 20.0;
  std::string figure;
  for (double ratio : {0.3, 2.0}) {
    const double t = ratio * h;
    const CompiledSolid solid = CompiledSolid::Compile(
        ImplicitNode(UnionParams{}, {Box(Eigen::Vector3d::Zero(), Eigen::Vector3d::Constant(c)),
                                     Box(Eigen::Vector3d(c * 0.9, 0.5 * (c - t), 0.1 * c),
                                         Eigen::Vector3d(1.5 * c, 0.5 * (c + t), 0.9 * c))}));
    const Eigen::AlignedBox3d bounds(Eigen::Vector3d::Constant(-0.073 * c),
                                     Eigen::Vector3d(1.58 * c, 1.07 * c, 1.07 * c));
    const TriangleMesh surface = Surface(solid, bounds, h);
    EXPECT_NO_THROW(CheckSurface(surface)) << "t = " << ratio << " h";
    TetMeshStats stats;
    TetrahedralizeSurface(surface, {}, &stats);
    const double body = c * c * c, fin = 0.5 * c * t * 0.8 * c;
    const double kept = (stats.quality.total_volume - body) / fin;
    figure += Format("t = %.1f h: (V - V_body) / V_fin = %.0f %%, min dihedral %.3g deg; ", ratio,
                     100 * kept, stats.quality.min_dihedral_deg);
    // Whatever happens to the fin, the body is there: volume at least the body's within 3 %,
    // at most body + fin + 3 %.
    EXPECT_GT(stats.quality.total_volume, 0.97 * body) << "t = " << ratio << " h";
    EXPECT_LT(stats.quality.total_volume, 1.03 * (body + fin)) << "t = " << ratio << " h";
    if (ratio >= 1.0) {
      EXPECT_GT(kept, 0.5) << "a fin of two cells must be kept";
    }
  }
  RecordProperty("figure", figure);
  // Below a cell the fin falls between grid vertices and is lost (V - V_body < 0: the body's
  // edge at the fin's root is rounded too); at two cells it is kept.
  RecordProperty("bar",
                 "valid closed surface at both; volume in [0.97 body, 1.03 (body + fin)]; "
                 "a 2-cell fin keeps over half its volume");
}

TEST(HardMeshScale, TheSameShapeFromOneMillimetreToTenMetresMeshesAlike) {
  // A torus of major radius 0.35 s and minor radius 0.15 s (an exact distance field, so |f| at
  // the mesh is its distance to the true surface), meshed at cell s/32 (surface, then TetGen)
  // and facet size s/16 (CGAL, optimizers without time limits so that the mesh depends on the
  // seed only), for s = 1 mm .. 10 m. Relative figures must not depend on s: the meshers have no
  // absolute length anywhere.
  struct Row {
    double s, surface_error, tetgen_dihedral, tetgen_volume, cgal_error, cgal_dihedral, cgal_volume;
  };
  std::vector<Row> rows;
  for (double s : {1e-3, 1e-2, 1.0, 10.0}) {
    const double major = 0.35 * s, minor = 0.15 * s;
    const CompiledSolid solid = CompiledSolid::Compile(ImplicitNode(TorusParams{major, minor}));
    const Eigen::AlignedBox3d bounds(Eigen::Vector3d(-0.5371, -0.5413, -0.1937) * s,
                                     Eigen::Vector3d(0.5413, 0.5371, 0.1971) * s);
    const TriangleMesh surface = Surface(solid, bounds, s / 32.0);
    TetMeshStats stats;
    TetrahedralizeSurface(surface, {}, &stats);
    CgalMeshSettings cgal = CgalMeshSettings::ForSize(s / 16.0);
    cgal.optimizer_time_limit = 0.0;
    cgal.exude_time_limit = 0.0;
    CgalMeshStats cgal_stats;
    const TetMesh tets = MeshImplicitWithCgal(solid, bounds, cgal, &cgal_stats);
    const double exact = 2.0 * std::numbers::pi * std::numbers::pi * major * minor * minor;
    rows.push_back({s, MeasureSurfaceError(solid, surface).max / s, stats.quality.min_dihedral_deg,
                    stats.quality.total_volume / exact - 1.0,
                    MeasureSurfaceError(solid, BoundarySurface(tets)).max / s,
                    cgal_stats.quality.min_dihedral_deg,
                    cgal_stats.quality.total_volume / exact - 1.0});
  }
  std::string figure;
  for (const Row& r : rows) {
    figure += Format("s = %g m: surface error %.3g s, ", r.s, r.surface_error) +
              Format("TetGen min dihedral %.3g deg, volume %+.3g %%; ", r.tetgen_dihedral,
                     100 * r.tetgen_volume) +
              Format("CGAL error %.3g s, min dihedral %.3g deg, volume %+.3g %%; ", r.cgal_error,
                     r.cgal_dihedral, 100 * r.cgal_volume);
  }
  RecordProperty("figure", figure);
  // TetGen's q switch bounds the radius-edge ratio, not the dihedral angle: slivers remain, and
  // which ones survive changes with the rounding of the scaled coordinates (0.2 to 0.6 degrees
  // measured), while the volume does not move.
  RecordProperty("bar",
                 "at every scale: surface error <= 0.005 s, CGAL error <= 0.02 s; volume "
                 "within 1 % (TetGen) and 3.5 % (CGAL, facets s/16); min dihedral >= 0.1 deg "
                 "(TetGen) and >= 5 deg (CGAL); across scales equal within 1e-6 (surface error, "
                 "TetGen volume) and 5 % (CGAL error and min dihedral)");
  for (const Row& r : rows) {
    EXPECT_LE(r.surface_error, 0.005) << "s = " << r.s;
    EXPECT_LE(r.cgal_error, 0.02) << "s = " << r.s;
    EXPECT_LT(std::abs(r.tetgen_volume), 0.01) << "s = " << r.s;
    EXPECT_LT(std::abs(r.cgal_volume), 0.035) << "s = " << r.s;
    EXPECT_GE(r.tetgen_dihedral, 0.1) << "s = " << r.s;
    EXPECT_GE(r.cgal_dihedral, 5.0) << "s = " << r.s;
    EXPECT_NEAR(r.surface_error, rows[2].surface_error, 1e-6 * rows[2].surface_error)
        << "s = " << r.s;
    EXPECT_NEAR(r.tetgen_volume, rows[2].tetgen_volume, 1e-6) << "s = " << r.s;
    EXPECT_NEAR(r.cgal_error, rows[2].cgal_error, 0.05 * rows[2].cgal_error) << "s = " << r.s;
    EXPECT_NEAR(r.cgal_dihedral, rows[2].cgal_dihedral, 0.05 * rows[2].cgal_dihedral)
        << "s = " << r.s;
  }
}

}  // namespace
}  // namespace spidarcad::modeling
