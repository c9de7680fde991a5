// Report sections: surface meshing (time against two-sided Hausdorff error, plain and
// sharpened, on solids whose surfaces are known in closed form) and tetrahedral meshing
// (TetGen against CGAL: time, tets, worst dihedral angles, surface and volume error).
// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#include <algorithm>
#include <chrono>
#include <cmath>
#include <functional>
#include <numbers>
#include <random>
#include <string>
#include <unordered_map>
#include <vector>

#include "cli/report_sections.h"
#include "doc/assets.h"
#include "spidarcad/modeling/cgal_mesher.h"
#include "spidarcad/modeling/feature_sharpening.h"
#include "spidarcad/modeling/implicit_evaluator.h"
#include "spidarcad/modeling/scene_io.h"
#include "spidarcad/modeling/surface_mesher.h"
#include "spidarcad/modeling/tet_mesh.h"
#include "spidarcad/modeling/tetgen_mesher.h"
#include "spidarcad/modeling/triangle_closest_point.h"

namespace spidarcad::app {

namespace {

using namespace spidarcad::modeling;
using Vec = Eigen::Vector3d;
constexpr double kPi = std::numbers::pi;

// ---- Distances -------------------------------------------------------------------------

// Squared distance from p to triangle abc (closest point by Voronoi regions).
double PointTriangleDistance2(const Vec& p, const Vec& a, const Vec& b, const Vec& c) {
  return (p - modeling::ClosestPointOnTriangle(p, a, b, c)).squaredNorm();
}

// Nearest-triangle queries through a uniform grid of buckets (each triangle in every bucket
// its bounding box touches).
class TriangleGrid {
 public:
  TriangleGrid(const TriangleMesh& mesh, double bucket) : mesh_(mesh), bucket_(bucket) {
    for (int t = 0; t < mesh.triangles.cols(); ++t) {
      Eigen::AlignedBox3d box;
      for (int k = 0; k < 3; ++k) box.extend(Vec(mesh.vertices.col(mesh.triangles(k, t))));
      const Eigen::Vector3i lo = Cell(box.min()), hi = Cell(box.max());
      for (int x = lo.x(); x <= hi.x(); ++x)
        for (int y = lo.y(); y <= hi.y(); ++y)
          for (int z = lo.z(); z <= hi.z(); ++z) buckets_[Key(x, y, z)].push_back(t);
    }
  }
  // Distance from p to the mesh (exact: searches rings of buckets until no nearer one can be).
  double Distance(const Vec& p) const {
    const Eigen::Vector3i c = Cell(p);
    double best2 = INFINITY;
    for (int ring = 0; ring < 64; ++ring) {
      for (int x = c.x() - ring; x <= c.x() + ring; ++x)
        for (int y = c.y() - ring; y <= c.y() + ring; ++y)
          for (int z = c.z() - ring; z <= c.z() + ring; ++z) {
            if (std::max({std::abs(x - c.x()), std::abs(y - c.y()), std::abs(z - c.z())}) != ring)
              continue;
            const auto it = buckets_.find(Key(x, y, z));
            if (it == buckets_.end()) continue;
            for (int t : it->second) {
              best2 = std::min(best2,
                               PointTriangleDistance2(p, mesh_.vertices.col(mesh_.triangles(0, t)),
                                                      mesh_.vertices.col(mesh_.triangles(1, t)),
                                                      mesh_.vertices.col(mesh_.triangles(2, t))));
            }
          }
      // Every triangle within ring·bucket of p has been seen.
      if (std::sqrt(best2) <= ring * bucket_) break;
    }
    return std::sqrt(best2);
  }

 private:
  Eigen::Vector3i Cell(const Vec& p) const { return (p / bucket_).array().floor().cast<int>(); }
  static long long Key(int x, int y, int z) {
    return (static_cast<long long>(x + 4096) << 26) ^ (static_cast<long long>(y + 4096) << 13) ^
           static_cast<long long>(z + 4096);
  }
  const TriangleMesh& mesh_;
  double bucket_;
  std::unordered_map<long long, std::vector<int>> buckets_;
};

// ---- Solids with closed-form surfaces --------------------------------------------------

struct SurfaceCase {
  std::string name;
  CompiledSolid solid;
  Eigen::AlignedBox3d bounds;
  // Uniform random points on the true surface.
  std::function<std::vector<Vec>(int, std::mt19937*)> sample;
};

std::vector<SurfaceCase> SurfaceCases() {
  std::vector<SurfaceCase> cases;
  const double r = 0.05;
  cases.push_back({"sphere r 50 mm", CompiledSolid::Compile(ImplicitNode(SphereParams{r})),
                   Eigen::AlignedBox3d(Vec::Constant(-0.06), Vec::Constant(0.06)),
                   [r](int n, std::mt19937* rng) {
                     std::normal_distribution<double> normal;
                     std::vector<Vec> out;
                     for (int i = 0; i < n; ++i) {
                       out.push_back(r *
                                     Vec(normal(*rng), normal(*rng), normal(*rng)).normalized());
                     }
                     return out;
                   }});
  const Vec size(0.1, 0.06, 0.04);
  cases.push_back(
      {"box 100×60×40 mm", CompiledSolid::Compile(ImplicitNode(BoxParams{size})),
       Eigen::AlignedBox3d(-0.6 * size - Vec::Constant(0.005), 0.6 * size + Vec::Constant(0.005)),
       [size](int n, std::mt19937* rng) {
         std::uniform_real_distribution<double> u(-0.5, 0.5), pick(0, 1);
         const Vec h = 0.5 * size;
         const double areas[3] = {size.y() * size.z(), size.x() * size.z(), size.x() * size.y()};
         const double total = areas[0] + areas[1] + areas[2];
         std::vector<Vec> out;
         for (int i = 0; i < n; ++i) {
           const double w = pick(*rng) * total;
           const int axis = w < areas[0] ? 0 : (w < areas[0] + areas[1] ? 1 : 2);
           Vec p(u(*rng) * size.x(), u(*rng) * size.y(), u(*rng) * size.z());
           p(axis) = pick(*rng) < 0.5 ? -h(axis) : h(axis);
           out.push_back(p);
         }
         return out;
       }});
  const double cr = 0.03, ch = 0.08;
  cases.push_back(
      {"cylinder r 30 h 80 mm", CompiledSolid::Compile(ImplicitNode(CylinderParams{cr, ch})),
       Eigen::AlignedBox3d(Vec(-0.04, -0.04, -0.05), Vec(0.04, 0.04, 0.05)),
       [cr, ch](int n, std::mt19937* rng) {
         std::uniform_real_distribution<double> u(0, 1);
         const double side = 2 * kPi * cr * ch, cap = kPi * cr * cr;
         std::vector<Vec> out;
         for (int i = 0; i < n; ++i) {
           const double phi = 2 * kPi * u(*rng);
           if (u(*rng) * (side + 2 * cap) < side) {
             out.emplace_back(cr * std::cos(phi), cr * std::sin(phi), (u(*rng) - 0.5) * ch);
           } else {
             const double rho = cr * std::sqrt(u(*rng));
             out.emplace_back(rho * std::cos(phi), rho * std::sin(phi),
                              u(*rng) < 0.5 ? -ch / 2 : ch / 2);
           }
         }
         return out;
       }});
  return cases;
}

struct Hausdorff {
  double mesh_to_surface = 0;  // max over samples on the mesh, m
  double surface_to_mesh = 0;  // max over samples on the true surface, m
  double two_sided() const { return std::max(mesh_to_surface, surface_to_mesh); }
};

// Mesh → surface: |f| (an exact distance for these solids) at 10 points of every triangle;
// surface → mesh: distance from `surface_points` to the nearest triangle.
Hausdorff MeasureHausdorff(const CompiledSolid& solid, const TriangleMesh& mesh,
                           const std::vector<Vec>& surface_points, double cell) {
  Hausdorff h;
  static const double kBary[10][3] = {{1, 0, 0},
                                      {0, 1, 0},
                                      {0, 0, 1},
                                      {.5, .5, 0},
                                      {0, .5, .5},
                                      {.5, 0, .5},
                                      {1. / 3, 1. / 3, 1. / 3},
                                      {.7, .15, .15},
                                      {.15, .7, .15},
                                      {.15, .15, .7}};
  for (int t = 0; t < mesh.triangles.cols(); ++t) {
    const Vec a = mesh.vertices.col(mesh.triangles(0, t)),
              b = mesh.vertices.col(mesh.triangles(1, t)),
              c = mesh.vertices.col(mesh.triangles(2, t));
    for (const auto& w : kBary) {
      h.mesh_to_surface =
          std::max(h.mesh_to_surface, std::abs(solid.Value(w[0] * a + w[1] * b + w[2] * c)));
    }
  }
  const TriangleGrid grid(mesh, 2 * cell);
  for (const Vec& p : surface_points)
    h.surface_to_mesh = std::max(h.surface_to_mesh, grid.Distance(p));
  return h;
}

// ---- Tetrahedral meshing cases ----------------------------------------------------------

struct TetCase {
  std::string name;
  CompiledSolid solid;
  Eigen::AlignedBox3d bounds;
  double exact_volume;  // m³, 0: no closed form
  std::vector<double> sizes;
};

}  // namespace

void ReportSurfaceMeshing(ReportContext& ctx) {
  const std::vector<double> cells =
      ctx.Pick(std::vector<double>{0.008, 0.005, 0.0035},
               std::vector<double>{0.008, 0.005, 0.0035, 0.0025, 0.0018});
  const int samples = ctx.Pick(4000, 20000);
  const std::vector<SurfaceCase> cases = SurfaceCases();
  struct Row {
    std::string solid;
    double cell;
    std::string mesh;  // "plain", "sharpened", "lattice" or "lattice sharpened"
    long triangles;
    double seconds;
    Hausdorff error;
  };
  std::vector<Row> rows;
  int done = 0;
  for (const SurfaceCase& c : cases) {
    std::mt19937 rng(11);
    const std::vector<Vec> points = c.sample(samples, &rng);
    for (double cell : cells) {
      SurfaceMeshSettings settings;
      settings.bounds = c.bounds;
      settings.cell_size = cell;
      TriangleMesh plain;
      const double mesh_s =
          MedianSeconds(ctx.Pick(1, 3), [&] { plain = MeshSurface(c.solid, settings); });
      FeatureSettings features;
      features.cell_size = cell;
      TriangleMesh sharp;
      const double sharpen_s =
          MedianSeconds(ctx.Pick(1, 3), [&] { sharp = SharpenFeatures(c.solid, plain, features); });
      settings.mesher = SurfaceMesher::kLattice;
      TriangleMesh lattice;
      const double lattice_s =
          MedianSeconds(ctx.Pick(1, 3), [&] { lattice = MeshSurface(c.solid, settings); });
      rows.push_back({c.name, cell, "plain", static_cast<long>(plain.triangles.cols()), mesh_s,
                      MeasureHausdorff(c.solid, plain, points, cell)});
      rows.push_back({c.name, cell, "sharpened", static_cast<long>(sharp.triangles.cols()),
                      mesh_s + sharpen_s, MeasureHausdorff(c.solid, sharp, points, cell)});
      // `spidarcad mesh --mesher lattice --sharp`: corners inserted, slivers repaired.
      FeatureSettings lattice_features = features;
      lattice_features.insert_corners = true;
      lattice_features.sliver_angle_deg = kProductSliverAngleDeg;
      lattice_features.sliver_fallback_deviation_cells = kProductSliverFallbackCells;
      TriangleMesh lattice_sharp;
      const double lattice_sharpen_s = MedianSeconds(ctx.Pick(1, 3), [&] {
        lattice_sharp = SharpenFeatures(c.solid, lattice, lattice_features);
      });
      rows.push_back({c.name, cell, "lattice", static_cast<long>(lattice.triangles.cols()),
                      lattice_s, MeasureHausdorff(c.solid, lattice, points, cell)});
      rows.push_back(
          {c.name, cell, "lattice sharpened", static_cast<long>(lattice_sharp.triangles.cols()),
           lattice_s + lattice_sharpen_s, MeasureHausdorff(c.solid, lattice_sharp, points, cell)});
      ctx.Progress(++done / static_cast<double>(cases.size() * cells.size()));
    }
  }
  ctx.md() << "MeshSurface (marching tetrahedra on a grid of cell h, with its clean-up pass), "
              "plain and followed by SharpenFeatures, and its lattice route (body-centred cubic "
              "lattice, vertices snapped onto the surface, no clean-up: `spidarcad mesh`'s "
              "default), plain and sharpened with corners inserted and slivers under 10° "
              "repaired (`spidarcad mesh --mesher lattice --sharp`), on three solids whose "
              "surfaces are known "
              "in closed form (their implicit functions are exact distances). Two-sided "
              "Hausdorff error, sampled: mesh → surface is |f| at 10 points of every triangle, "
              "surface → mesh the distance from "
           << samples
           << " uniform points of the true surface to the nearest triangle. Time: "
              "wall clock of meshing (plus sharpening), median of "
           << ctx.Pick(1, 3) << ".\n";
  std::vector<std::vector<std::string>> table, csv;
  for (const Row& r : rows) {
    table.push_back({r.solid, Fixed(1e3 * r.cell, 1), r.mesh, std::to_string(r.triangles),
                     Sig(r.seconds, 3), Sig(1e3 * r.error.mesh_to_surface, 3),
                     Sig(1e3 * r.error.surface_to_mesh, 3), Sig(1e3 * r.error.two_sided(), 3)});
    csv.push_back({"\"" + r.solid + "\"", Sig(r.cell, 6), r.mesh, std::to_string(r.triangles),
                   Sig(r.seconds, 6), Sig(r.error.mesh_to_surface, 6),
                   Sig(r.error.surface_to_mesh, 6)});
  }
  ctx.Table({"solid", "h mm", "mesh", "triangles", "time s", "mesh→surface mm", "surface→mesh mm",
             "Hausdorff mm"},
            table);
  ctx.Csv(
      "surface_meshing",
      {"solid", "cell_m", "mesh", "triangles", "seconds", "mesh_to_surface_m", "surface_to_mesh_m"},
      csv);
  Chart chart{"Surface meshing: time against two-sided Hausdorff error",
              "time [s]",
              "Hausdorff error [m]",
              true,
              true,
              {}};
  for (size_t k = 0; k < cases.size(); ++k) {
    for (const std::string mesh : {"plain", "sharpened", "lattice", "lattice sharpened"}) {
      // Lattice: squares without a line, diamonds sharpened; sharpened grid surface: dashed.
      const bool lattice = mesh.rfind("lattice", 0) == 0;
      ChartSeries s{cases[k].name + ", " + mesh,
                    {},
                    {},
                    static_cast<int>(k),
                    !lattice,
                    mesh == "sharpened",
                    mesh == "lattice sharpened" ? 2 : 1};
      for (const Row& r : rows) {
        if (r.solid != cases[k].name || r.mesh != mesh) continue;
        s.x.push_back(r.seconds);
        s.y.push_back(r.error.two_sided());
      }
      chart.series.push_back(s);
    }
  }
  ctx.Figure("surface_time_vs_hausdorff", {chart},
             "One curve per solid and variant (dashed: sharpened; squares: the lattice route, "
             "diamonds: the lattice route sharpened), one "
             "point per cell size; "
             "finer cells are slower and more accurate.",
             1000, 620);
  auto find = [&](const std::string& solid, const std::string& mesh) {
    for (const Row& r : rows) {
      if (r.solid == solid && r.mesh == mesh && r.cell == cells.back()) return r;
    }
    return rows.front();
  };
  const Row box_plain = find(cases[1].name, "plain"), box_sharp = find(cases[1].name, "sharpened"),
            box_lattice_sharp = find(cases[1].name, "lattice sharpened");
  const Row sphere_plain = find(cases[0].name, "plain"),
            sphere_lattice = find(cases[0].name, "lattice");
  ctx.Headline("box at h = " + Fixed(1e3 * cells.back(), 1) + " mm: Hausdorff " +
               Sig(1e3 * box_plain.error.two_sided(), 2) + " mm plain, " +
               Sig(1e3 * box_sharp.error.two_sided(), 2) + " mm sharpened, " +
               Sig(1e3 * box_lattice_sharp.error.two_sided(), 2) + " mm lattice sharpened (" +
               Sig(box_plain.seconds, 2) + " s, " + Sig(box_sharp.seconds, 2) + " s, " +
               Sig(box_lattice_sharp.seconds, 2) +
               " s); sphere: " + Sig(1e3 * sphere_plain.error.two_sided(), 2) + " mm in " +
               Sig(sphere_plain.seconds, 2) + " s plain, " +
               Sig(1e3 * sphere_lattice.error.two_sided(), 2) + " mm in " +
               Sig(sphere_lattice.seconds, 2) + " s lattice");
  ctx.Summary(Sig(box_sharp.seconds, 2) + " s (box, h = " + Fixed(1e3 * cells.back(), 1) +
                  " mm, sharpened)",
              Sig(1e3 * box_sharp.error.two_sided(), 2) + " mm two-sided Hausdorff");
}

void ReportTetMeshing(ReportContext& ctx) {
  std::vector<TetCase> cases;
  {
    const double r = 0.05;
    cases.push_back({"sphere r 50 mm", CompiledSolid::Compile(ImplicitNode(SphereParams{r})),
                     Eigen::AlignedBox3d(Vec::Constant(-0.06), Vec::Constant(0.06)),
                     4.0 / 3.0 * kPi * r * r * r,
                     ctx.Pick(std::vector<double>{0.01, 0.006}, {0.01, 0.006, 0.004})});
  }
  {
    const Vec size(0.1, 0.06, 0.04);
    const double bore = 0.012;
    const ImplicitNode root(DifferenceParams{}, {ImplicitNode(BoxParams{size}),
                                                 ImplicitNode(CylinderParams{bore, 0.06})});
    cases.push_back({"box with bore", CompiledSolid::Compile(root),
                     Eigen::AlignedBox3d(Vec(-0.06, -0.04, -0.03), Vec(0.06, 0.04, 0.03)),
                     size.prod() - kPi * bore * bore * size.z(),
                     ctx.Pick(std::vector<double>{0.008, 0.005}, {0.008, 0.005, 0.0035})});
  }
  {
    const Scene scene = LoadScene(AssetPath("scenes/platform.json"));
    cases.push_back({"platform", CompiledSolid::Compile(scene.solids[0].root),
                     Eigen::AlignedBox3d(Vec(-0.01, -0.11, -0.16), Vec(0.31, 0.11, 0.02)), 0.0,
                     ctx.Pick(std::vector<double>{0.008}, {0.008, 0.006, 0.004})});
  }
  struct Row {
    std::string solid, path;
    double h;
    double seconds = NAN;
    long tets = 0;
    TetQuality quality;
    SurfaceError error;
    double volume_error = NAN;  // relative, signed
    std::string failure;
  };
  std::vector<Row> rows;
  int total = 0, done = 0;
  for (const TetCase& c : cases) total += 2 * static_cast<int>(c.sizes.size());
  for (const TetCase& c : cases) {
    for (double h : c.sizes) {
      for (const char* path : {"TetGen", "CGAL"}) {
        Row row;
        row.solid = c.name;
        row.path = path;
        row.h = h;
        try {
          const auto start = std::chrono::steady_clock::now();
          TetMesh tets;
          if (std::string(path) == "TetGen") {
            SurfaceMeshSettings surface;
            surface.bounds = c.bounds;
            surface.cell_size = h;
            TetMeshSettings settings;
            settings.max_radius_edge = 2.0;
            tets = TetrahedralizeSurface(MeshSurface(c.solid, surface), settings);
          } else {
            CgalMeshSettings settings = CgalMeshSettings::ForSize(h);
            settings.cell_radius_edge_ratio = 2.0;
            tets = MeshImplicitWithCgal(c.solid, c.bounds, settings);
          }
          row.seconds = SecondsSince(start);
          row.tets = tets.tets.cols();
          row.quality = MeasureTetQuality(tets);
          row.error = MeasureSurfaceError(c.solid, BoundarySurface(tets));
          if (c.exact_volume > 0) {
            row.volume_error = (row.quality.total_volume - c.exact_volume) / c.exact_volume;
          }
        } catch (const std::exception& e) {
          row.failure = e.what();
        }
        rows.push_back(row);
        ctx.Progress(++done / static_cast<double>(total));
      }
    }
  }
  ctx.md() << "The same solids meshed into tetrahedra two ways: TetGen (MeshSurface at cell h, "
              "then TetrahedralizeSurface with radius-edge bound 2) and CGAL (Mesh_3 from the "
              "implicit function, CgalMeshSettings::ForSize(h), radius-edge 2, perturb and "
              "exude). Surface error: max and RMS of |f| sampled on the tet mesh's boundary; "
              "volume error against the closed form (the platform has none: its volume is "
              "given). One run each, wall clock.\n";
  std::vector<std::vector<std::string>> table, csv;
  for (const Row& r : rows) {
    if (!r.failure.empty()) {
      table.push_back({r.solid, Fixed(1e3 * r.h, 1), r.path, "failed: " + r.failure.substr(0, 80),
                       "", "", "", ""});
      continue;
    }
    const std::string volume = std::isnan(r.volume_error)
                                   ? Sig(r.quality.total_volume * 1e6, 4) + " cm³"
                                   : Fixed(100 * r.volume_error, 2) + " %";
    table.push_back(
        {r.solid, Fixed(1e3 * r.h, 1), r.path, Sig(r.seconds, 3), std::to_string(r.tets),
         Fixed(r.quality.min_dihedral_deg, 1) + " / " + Fixed(r.quality.max_dihedral_deg, 1),
         Sig(1e3 * r.error.max, 3) + " / " + Sig(1e3 * r.error.rms, 3), volume});
    csv.push_back({"\"" + r.solid + "\"", Sig(r.h, 6), r.path, Sig(r.seconds, 6),
                   std::to_string(r.tets), Sig(r.quality.min_dihedral_deg, 6),
                   Sig(r.quality.max_dihedral_deg, 6), Sig(r.error.max, 6), Sig(r.error.rms, 6),
                   Sig(r.volume_error, 6), Sig(r.quality.total_volume, 6)});
  }
  ctx.Table({"solid", "h mm", "path", "time s", "tets", "dihedral min / max °",
             "surface error max / rms mm", "volume"},
            table);
  ctx.Csv("tet_meshing",
          {"solid", "h_m", "path", "seconds", "tets", "min_dihedral_deg", "max_dihedral_deg",
           "surface_error_max_m", "surface_error_rms_m", "volume_error", "volume_m3"},
          csv);
  Chart error{"Tet meshing: time against surface error",
              "time [s]",
              "max surface error [m]",
              true,
              true,
              {}};
  Chart angle{"Tet meshing: time against worst dihedral angle",
              "time [s]",
              "smallest dihedral angle [deg]",
              true,
              false,
              {}};
  for (size_t k = 0; k < cases.size(); ++k) {
    for (int p = 0; p < 2; ++p) {
      const std::string path = p == 0 ? "TetGen" : "CGAL";
      ChartSeries e{path + ", " + cases[k].name, {}, {}, p, true, k > 0, static_cast<int>(k)};
      ChartSeries a = e;
      for (const Row& r : rows) {
        if (r.solid != cases[k].name || r.path != path || !r.failure.empty()) continue;
        e.x.push_back(r.seconds);
        e.y.push_back(r.error.max);
        a.x.push_back(r.seconds);
        a.y.push_back(r.quality.min_dihedral_deg);
      }
      error.series.push_back(e);
      angle.series.push_back(a);
    }
  }
  ctx.Figure("tets_time_vs_error", {error, angle},
             "Colour: TetGen (blue) or CGAL (orange); one curve per solid, one point per size h.");
  auto find = [&](const std::string& path) {
    for (const Row& r : rows) {
      if (r.solid == "box with bore" && r.path == path && r.h == cases[1].sizes.back()) return r;
    }
    return rows.front();
  };
  const Row tg = find("TetGen"), cg = find("CGAL");
  ctx.Headline("box with bore at h = " + Fixed(1e3 * tg.h, 1) + " mm: TetGen " +
               Sig(tg.seconds, 2) + " s, " + std::to_string(tg.tets) + " tets, min dihedral " +
               Fixed(tg.quality.min_dihedral_deg, 1) + "°, volume " +
               Fixed(100 * tg.volume_error, 2) + " %; CGAL " + Sig(cg.seconds, 2) + " s, " +
               std::to_string(cg.tets) + " tets, " + Fixed(cg.quality.min_dihedral_deg, 1) + "°, " +
               Fixed(100 * cg.volume_error, 2) + " %");
  ctx.Summary("TetGen " + Sig(tg.seconds, 2) + " s, CGAL " + Sig(cg.seconds, 2) + " s (" +
                  std::to_string(tg.tets) + " and " + std::to_string(cg.tets) + " tets)",
              "volume " + Fixed(100 * tg.volume_error, 2) + " % / " +
                  Fixed(100 * cg.volume_error, 2) + " %, min dihedral " +
                  Fixed(tg.quality.min_dihedral_deg, 1) + "° / " +
                  Fixed(cg.quality.min_dihedral_deg, 1) + "°");
}

}  // namespace spidarcad::app
