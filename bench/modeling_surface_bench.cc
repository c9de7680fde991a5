// Surface meshing: speed against error across resolutions, with and without feature sharpening,
// for a box, a box minus a cylinder and the platform scene (assets/scenes/platform.json).
//
// Error is the two-sided Hausdorff distance between mesh and true surface, estimated by sampling:
//  - mesh -> surface: 10 barycentric points on every triangle, distance |f| / |grad f| (first
//    order; exact for the exact-distance box);
//  - surface -> mesh: 20000 points on the true surface (random points of the bounds moved onto
//    the zero set by Newton steps; points outside a convex edge or corner land exactly on it),
//    each measured to the nearest triangle through a uniform grid of triangles.
// Max and mean of both directions are printed as a markdown table after the benchmarks.
// BM_FindBounds: the box search of `spidarcad mesh` on unions of 1,000 to 100,000 spheres (time,
// and how far the box lies beyond the exact one), a second table.
// Run: build-dir/bench/modeling_surface_bench (bench_paths.h finds the scene), about 1-2 min.
// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#include <benchmark/benchmark.h>

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <random>
#include <string>
#include <unordered_map>
#include <vector>

#include "bench_cli.h"
#include "bench_paths.h"
#include "spidarcad/modeling/feature_sharpening.h"
#include "spidarcad/modeling/implicit_evaluator.h"
#include "spidarcad/modeling/scene_io.h"
#include "spidarcad/modeling/surface_mesher.h"

namespace {

using namespace spidarcad::modeling;
using Vec = Eigen::Vector3d;

struct Case {
  std::string name;
  CompiledSolid solid;
  Eigen::AlignedBox3d bounds;
};

// The three solids, built once. The box and the box minus a cylinder sit off the grid planes.
const std::vector<Case>& Cases() {
  static const std::vector<Case> cases = [] {
    std::vector<Case> c;
    const Vec offset(0.0013, -0.0021, 0.0007), size(0.1, 0.08, 0.06);
    const Eigen::AlignedBox3d around(offset - size / 2 - Vec(0.0107, 0.0113, 0.0109),
                                     offset + size / 2 + Vec::Constant(0.01));
    c.push_back({"box",
                 CompiledSolid::Compile(
                     ImplicitNode(TranslateParams{offset}, {ImplicitNode(BoxParams{size})})),
                 around});
    ImplicitNode holed(DifferenceParams{},
                       {ImplicitNode(BoxParams{size}), ImplicitNode(CylinderParams{0.02, 0.2})});
    c.push_back({"box-cylinder",
                 CompiledSolid::Compile(ImplicitNode(TranslateParams{offset}, {holed})), around});
    const Scene scene = LoadScene(spidarcad::bench::RepoPath("assets/scenes/platform.json"));
    c.push_back({"platform", CompiledSolid::Compile(scene.solids.at(0).root),
                 Eigen::AlignedBox3d(Vec(-0.01, -0.11, -0.16), Vec(0.31, 0.11, 0.02))});
    return c;
  }();
  return cases;
}

double PointTriangleDistance2(const Vec& p, const Vec& a, const Vec& b, const Vec& c) {
  // Closest point by Voronoi regions of the triangle (vertices, edges, face).
  const Vec ab = b - a, ac = c - a, ap = p - a;
  const double d1 = ab.dot(ap), d2 = ac.dot(ap);
  if (d1 <= 0 && d2 <= 0) return ap.squaredNorm();
  const Vec bp = p - b;
  const double d3 = ab.dot(bp), d4 = ac.dot(bp);
  if (d3 >= 0 && d4 <= d3) return bp.squaredNorm();
  const double vc = d1 * d4 - d3 * d2;
  if (vc <= 0 && d1 >= 0 && d3 <= 0) return (p - (a + ab * (d1 / (d1 - d3)))).squaredNorm();
  const Vec cp = p - c;
  const double d5 = ab.dot(cp), d6 = ac.dot(cp);
  if (d6 >= 0 && d5 <= d6) return cp.squaredNorm();
  const double vb = d5 * d2 - d1 * d6;
  if (vb <= 0 && d2 >= 0 && d6 <= 0) return (p - (a + ac * (d2 / (d2 - d6)))).squaredNorm();
  const double va = d3 * d6 - d5 * d4;
  if (va <= 0 && (d4 - d3) >= 0 && (d5 - d6) >= 0)
    return (p - (b + (c - b) * ((d4 - d3) / ((d4 - d3) + (d5 - d6))))).squaredNorm();
  const double denom = 1.0 / (va + vb + vc);
  return (p - (a + ab * (vb * denom) + ac * (vc * denom))).squaredNorm();
}

// Nearest-triangle queries through a uniform grid (cells of edge `cell`) of triangle bounding
// boxes.
class TriangleGrid {
 public:
  TriangleGrid(const TriangleMesh& mesh, double cell) : mesh_(mesh), cell_(cell) {
    for (Eigen::Index t = 0; t < mesh.triangles.cols(); ++t) {
      Eigen::AlignedBox3d box;
      for (int k = 0; k < 3; ++k) box.extend(Vec(mesh.vertices.col(mesh.triangles(k, t))));
      const auto lo = Index(box.min()), hi = Index(box.max());
      for (long i = lo[0]; i <= hi[0]; ++i)
        for (long j = lo[1]; j <= hi[1]; ++j)
          for (long k = lo[2]; k <= hi[2]; ++k) cells_[Key(i, j, k)].push_back(static_cast<int>(t));
    }
  }
  // Distance from p to the mesh: cells within `rings` of p's cell, then everything if needed.
  double Distance(const Vec& p) const {
    const auto c = Index(p);
    double best2 = INFINITY;
    const int rings = 1;
    for (long i = c[0] - rings; i <= c[0] + rings; ++i)
      for (long j = c[1] - rings; j <= c[1] + rings; ++j)
        for (long k = c[2] - rings; k <= c[2] + rings; ++k) {
          const auto it = cells_.find(Key(i, j, k));
          if (it == cells_.end()) continue;
          for (int t : it->second) best2 = std::min(best2, Triangle2(p, t));
        }
    if (best2 <= cell_ * cell_) return std::sqrt(best2);  // nothing outside the block can be nearer
    for (Eigen::Index t = 0; t < mesh_.triangles.cols(); ++t)
      best2 = std::min(best2, Triangle2(p, static_cast<int>(t)));
    return std::sqrt(best2);
  }

 private:
  std::array<long, 3> Index(const Vec& p) const {
    return {static_cast<long>(std::floor(p.x() / cell_)),
            static_cast<long>(std::floor(p.y() / cell_)),
            static_cast<long>(std::floor(p.z() / cell_))};
  }
  static long long Key(long i, long j, long k) {
    return ((static_cast<long long>(i) & 0x1fffff) << 42) |
           ((static_cast<long long>(j) & 0x1fffff) << 21) | (static_cast<long long>(k) & 0x1fffff);
  }
  double Triangle2(const Vec& p, int t) const {
    return PointTriangleDistance2(p, mesh_.vertices.col(mesh_.triangles(0, t)),
                                  mesh_.vertices.col(mesh_.triangles(1, t)),
                                  mesh_.vertices.col(mesh_.triangles(2, t)));
  }
  const TriangleMesh& mesh_;
  double cell_;
  std::unordered_map<long long, std::vector<int>> cells_;
};

// Points on the true surface: random points of the bounds, Newton-projected; kept when |f| <= 1e-10
// m.
const std::vector<Vec>& SurfaceSamples(const Case& c) {
  static std::unordered_map<std::string, std::vector<Vec>> cache;
  auto& points = cache[c.name];
  if (!points.empty()) return points;
  std::mt19937 rng(1234);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  while (points.size() < 20000) {
    Vec p = c.bounds.min() + c.bounds.sizes().cwiseProduct(Vec(u(rng), u(rng), u(rng)));
    for (int i = 0; i < 20; ++i) {
      Vec g;
      const double f = c.solid.ValueAndGradient(p, &g);
      if (std::abs(f) <= 1e-12 || g.squaredNorm() < 1e-12) break;
      p -= f / g.squaredNorm() * g;
    }
    if (std::abs(c.solid.Value(p)) <= 1e-10 && c.bounds.contains(p)) points.push_back(p);
  }
  return points;
}

struct Error {
  double out_max = 0, out_mean = 0, in_max = 0, in_mean = 0;
};

Error MeasureHausdorff(const Case& c, const TriangleMesh& mesh, double cell) {
  Error e;
  double area_sum = 0.0;
  for (Eigen::Index t = 0; t < mesh.triangles.cols(); ++t) {
    const Vec a = mesh.vertices.col(mesh.triangles(0, t)),
              b = mesh.vertices.col(mesh.triangles(1, t));
    const Vec d = mesh.vertices.col(mesh.triangles(2, t));
    const double area = 0.5 * (b - a).cross(d - a).norm();
    double sum = 0.0;
    int n = 0;
    for (int i = 0; i <= 3; ++i) {
      for (int j = 0; i + j <= 3; ++j, ++n) {
        Vec g;
        const double f = c.solid.ValueAndGradient((i * a + j * b + (3 - i - j) * d) / 3.0, &g);
        const double dist = std::abs(f) / std::max(g.norm(), 1e-6);
        e.out_max = std::max(e.out_max, dist);
        sum += dist;
      }
    }
    e.out_mean += area * sum / n;
    area_sum += area;
  }
  e.out_mean /= std::max(area_sum, 1e-300);
  const TriangleGrid grid(mesh, 2.0 * cell);
  const auto& samples = SurfaceSamples(c);
  for (const Vec& p : samples) {
    const double d = grid.Distance(p);
    e.in_max = std::max(e.in_max, d);
    e.in_mean += d;
  }
  e.in_mean /= static_cast<double>(samples.size());
  return e;
}

struct Row {
  std::string name;
  double cell_mm;
  bool sharp;
  long triangles;
  double mesh_s, sharpen_s;
  Error error;
  long moved, flipped;
};
std::vector<Row>& Rows() {
  static std::vector<Row> rows;
  return rows;
}

// Meshes case state.range(0) at cell state.range(1) / 10 mm, sharpening when state.range(2).
void BM_Surface(benchmark::State& state) {
  const Case& c = Cases().at(static_cast<size_t>(state.range(0)));
  const double cell = state.range(1) * 1e-4;
  const bool sharp = state.range(2) != 0;
  SurfaceMeshSettings settings;
  settings.bounds = c.bounds;
  settings.cell_size = cell;
  TriangleMesh mesh;
  SurfaceMeshStats mesh_stats;
  FeatureStats feature_stats;
  for (auto _ : state) {
    mesh = MeshSurface(c.solid, settings, &mesh_stats);
    if (sharp) {
      FeatureSettings f;
      f.cell_size = cell;
      mesh = SharpenFeatures(c.solid, std::move(mesh), f, &feature_stats);
    }
  }
  const Error e = MeasureHausdorff(c, mesh, cell);
  state.SetLabel(c.name + (sharp ? " sharp" : " plain"));
  state.counters["cell_mm"] = cell * 1e3;
  state.counters["triangles"] = static_cast<double>(mesh.triangles.cols());
  state.counters["out_max_mm"] = e.out_max * 1e3;
  state.counters["in_max_mm"] = e.in_max * 1e3;
  state.counters["in_mean_mm"] = e.in_mean * 1e3;
  Rows().push_back({c.name, cell * 1e3, sharp, static_cast<long>(mesh.triangles.cols()),
                    mesh_stats.seconds, sharp ? feature_stats.seconds : 0.0, e,
                    feature_stats.vertices_moved, feature_stats.edges_flipped});
}
BENCHMARK(BM_Surface)
    ->ArgsProduct({{0, 1}, {80, 40, 20, 10}, {0, 1}})
    ->ArgsProduct({{2}, {80, 40, 20}, {0, 1}})
    ->Iterations(1)
    ->Unit(benchmark::kMillisecond);

// FindBounds as `spidarcad mesh` calls it (scene/scene_solid.cc): over [-10, 10]^3 at 1 cm, then
// over that box at its largest side / 80, for unions of n spheres of 2 mm radius on a 5 mm
// lattice (n = state.range(0)); error: how far the box lies beyond the closed-form box of the
// spheres, the largest of the six sides.
struct BoundsRow {
  int spheres, tape;
  double coarse_s, fine_s, over_mm;
};
std::vector<BoundsRow>& BoundsRows() {
  static std::vector<BoundsRow> rows;
  return rows;
}

void BM_FindBounds(benchmark::State& state) {
  const int n = static_cast<int>(state.range(0));
  const int side = static_cast<int>(std::ceil(std::cbrt(static_cast<double>(n)) - 1e-9));
  const double radius = 0.002, pitch = 0.005;
  std::vector<ImplicitNode> spheres;
  Eigen::AlignedBox3d exact;
  for (int i = 0; i < n; ++i) {
    const Vec c = pitch * Vec(i % side, i / side % side, i / side / side);
    exact.extend(c - Vec::Constant(radius));
    exact.extend(c + Vec::Constant(radius));
    spheres.emplace_back(TranslateParams{c},
                         std::vector<ImplicitNode>{ImplicitNode(SphereParams{radius})});
  }
  const CompiledSolid solid = CompiledSolid::Compile(ImplicitNode(UnionParams{}, spheres));
  const Eigen::AlignedBox3d search(Vec::Constant(-10), Vec::Constant(10));
  Eigen::AlignedBox3d fine;
  double coarse_s = 0, fine_s = 0;
  for (auto _ : state) {
    const auto t0 = std::chrono::steady_clock::now();
    const Eigen::AlignedBox3d rough = FindBounds(solid, search, 0.01);
    const auto t1 = std::chrono::steady_clock::now();
    fine = FindBounds(solid, rough, rough.sizes().maxCoeff() / 80);
    const auto t2 = std::chrono::steady_clock::now();
    coarse_s = std::chrono::duration<double>(t1 - t0).count();
    fine_s = std::chrono::duration<double>(t2 - t1).count();
  }
  const double over =
      std::max((exact.min() - fine.min()).maxCoeff(), (fine.max() - exact.max()).maxCoeff());
  state.counters["over_mm"] = over * 1e3;
  BoundsRows().push_back({n, solid.instruction_count(), coarse_s, fine_s, over * 1e3});
}
BENCHMARK(BM_FindBounds)
    ->Arg(1000)
    ->Arg(10000)
    ->Arg(100000)
    ->Iterations(1)
    ->Unit(benchmark::kMillisecond);

}  // namespace

// What this program measures (its --help).
constexpr const char* kBenchDescription =
    "Surface meshing: speed against error across resolutions, with and without feature "
    "sharpening,\n"
    "for a box, a box minus a cylinder and the platform scene (assets/scenes/platform.json).\n"
    "\n"
    "Error is the two-sided Hausdorff distance between mesh and true surface, estimated by "
    "sampling:\n"
    " - mesh -> surface: 10 barycentric points on every triangle, distance |f| / |grad f| (first\n"
    "   order; exact for the exact-distance box);\n"
    " - surface -> mesh: 20000 points on the true surface (random points of the bounds moved onto\n"
    "   the zero set by Newton steps; points outside a convex edge or corner land exactly on it),\n"
    "   each measured to the nearest triangle through a uniform grid of triangles.\n"
    "Max and mean of both directions are printed as a markdown table after the benchmarks.\n"
    "BM_FindBounds: the box search of `spidarcad mesh` (1 cm over [-10, 10]^3, then size/80) on\n"
    "unions of 1,000 to 100,000 spheres, its time and how far the box lies beyond the exact one.\n"
    "Run: build-dir/bench/modeling_surface_bench (bench_paths.h finds the scene), about 1-2 min.";

// Tables printed after the benchmarks.
void PrintAfterRun() {
  std::printf(
      "\n| solid | cell mm | sharpen | triangles | mesh s | sharpen s | mesh->surface max mm | "
      "mean mm |"
      " surface->mesh max mm | mean mm | moved | flipped |\n");
  std::printf("|---|---|---|---|---|---|---|---|---|---|---|---|\n");
  for (const Row& r : Rows()) {
    std::printf("| %s | %g | %s | %ld | %.3f | %.3f | %.4f | %.5f | %.4f | %.5f | %ld | %ld |\n",
                r.name.c_str(), r.cell_mm, r.sharp ? "yes" : "no", r.triangles, r.mesh_s,
                r.sharpen_s, r.error.out_max * 1e3, r.error.out_mean * 1e3, r.error.in_max * 1e3,
                r.error.in_mean * 1e3, r.sharp ? r.moved : 0L, r.sharp ? r.flipped : 0L);
  }
}

void PrintAll() {
  if (!Rows().empty()) PrintAfterRun();
  if (BoundsRows().empty()) return;
  std::printf(
      "\n| spheres | tape | FindBounds 1 cm over [-10, 10]^3, s | then at size/80, s | "
      "beyond the exact box, mm |\n|---|---|---|---|---|\n");
  for (const BoundsRow& r : BoundsRows())
    std::printf("| %d | %d | %.3f | %.3f | %.2f |\n", r.spheres, r.tape, r.coarse_s, r.fine_s,
                r.over_mm);
}

int main(int argc, char** argv) {
  return spidarcad::bench::RunBenchmarkMain(argc, argv, kBenchDescription, nullptr, PrintAll);
}
