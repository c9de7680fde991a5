// Surface meshing: speed against error across resolutions, with and without feature sharpening,
// for a box, a box minus a cylinder and the platform scene (assets/scenes/platform.json), and
// without it for a sphere of radius 50 mm at 4, 2 and 1 mm. Counters: the error figures below and
// SurfaceMeshStats' exact counts (field evaluations, collapses, flips).
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
// BM_MeshSpeed: MeshSurface alone, repeated (CPU time per mesh), on the smooth shapes (sphere at 1
// and 2 mm, torus at 1 mm) and the platform at 4 mm, with snapping off and at kProductSnapCells;
// BM_LatticeSpeed the same for the lattice route.
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
#include "surface_metrics.h"

namespace {

using namespace spidarcad::modeling;
using spidarcad::bench::Vec;

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
    // The smooth solid where the clean-up's cost shows most (the 2-7x slowdown of the mesher's
    // design note: 17 -> 122 ms at r/20; docs/design/2026-12-04-surface-mesher-peers.md).
    c.push_back({"sphere",
                 CompiledSolid::Compile(
                     ImplicitNode(TranslateParams{offset}, {ImplicitNode(SphereParams{0.05})})),
                 Eigen::AlignedBox3d(offset - Vec::Constant(0.06), offset + Vec::Constant(0.06))});
    c.push_back({"torus", CompiledSolid::Compile(ImplicitNode(TorusParams{0.03, 0.01})),
                 Eigen::AlignedBox3d(Vec::Constant(-0.05), Vec::Constant(0.05))});
    return c;
  }();
  return cases;
}

// Points on the true surface of case c (20000, cached per case).
const std::vector<Vec>& SurfaceSamples(const Case& c) {
  static std::unordered_map<std::string, std::vector<Vec>> cache;
  auto& points = cache[c.name];
  if (points.empty()) points = spidarcad::bench::SurfaceSamples(c.solid, c.bounds);
  return points;
}

using Error = spidarcad::bench::HausdorffError;

Error MeasureHausdorff(const Case& c, const TriangleMesh& mesh, double cell) {
  return spidarcad::bench::MeasureHausdorff(c.solid, SurfaceSamples(c), mesh, cell);
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
  // Exact counts that do not drift with the machine's load: a clean-up that starts doing more
  // work per mesh shows here even when the times are too noisy to tell.
  state.counters["evaluations"] = static_cast<double>(mesh_stats.field_evaluations);
  state.counters["collapses"] = static_cast<double>(mesh_stats.collapsed_edges);
  state.counters["flips"] = static_cast<double>(mesh_stats.flipped_edges);
  Rows().push_back({c.name, cell * 1e3, sharp, static_cast<long>(mesh.triangles.cols()),
                    mesh_stats.seconds, sharp ? feature_stats.seconds : 0.0, e,
                    feature_stats.vertices_moved, feature_stats.edges_flipped});
}
BENCHMARK(BM_Surface)
    ->ArgsProduct({{0, 1}, {80, 40, 20, 10}, {0, 1}})
    ->ArgsProduct({{2}, {80, 40, 20}, {0, 1}})
    ->ArgsProduct({{3}, {40, 20, 10}, {0}})
    ->Iterations(1)
    ->Unit(benchmark::kMillisecond);

// SurfaceMeshSettings::snap_cells = state.range(2) / 100 on case state.range(0) at cell
// state.range(1) / 10 mm: the triangle quality it buys and the surface error it costs (the
// snapping sweep of docs/design/2026-12-04-surface-mesher-peers.md). Error: MeasureSurfaceError
// (|value| at vertices, edge midpoints and centroids; one-sided), and the two-sided Hausdorff
// distance (as BM_Surface: hausdorff_mm, the larger of its two directions).
void BM_Snap(benchmark::State& state) {
  const Case& c = Cases().at(static_cast<size_t>(state.range(0)));
  SurfaceMeshSettings settings;
  settings.bounds = c.bounds;
  settings.cell_size = state.range(1) * 1e-4;
  settings.snap_cells = state.range(2) * 0.01;
  TriangleMesh mesh;
  for (auto _ : state) mesh = MeshSurface(c.solid, settings);
  const SurfaceError e = MeasureSurfaceError(c.solid, mesh);
  const Error hausdorff = MeasureHausdorff(c, mesh, settings.cell_size);
  const TriangleAngleStats angles = MeasureTriangleAngles(mesh, 10.0);
  state.SetLabel(c.name);
  state.counters["cell_mm"] = settings.cell_size * 1e3;
  state.counters["snap"] = settings.snap_cells;
  state.counters["hausdorff_mm"] = std::max(hausdorff.out_max, hausdorff.in_max) * 1e3;
  state.counters["triangles"] = static_cast<double>(mesh.triangles.cols());
  state.counters["max_error_mm"] = e.max * 1e3;
  state.counters["rms_error_mm"] = e.rms * 1e3;
  state.counters["min_angle_deg"] = angles.min_angle_deg;
  state.counters["under_10_deg"] = static_cast<double>(angles.small_angle);
}
BENCHMARK(BM_Snap)
    ->ArgsProduct({{3, 4}, {40, 20, 10}, {0, 5, 10, 15, 20, 25}})
    ->ArgsProduct({{2}, {80, 40, 20}, {0, 5, 10, 15, 20, 25}})
    ->Iterations(1)
    ->Unit(benchmark::kMillisecond);

// Meshes case state.range(0) at cell state.range(1) / 10 mm with `settings` (its other fields) as
// many times as Google Benchmark asks; sets the label and the counters cell_mm, triangles and
// evaluations, and returns the last run's stats.
SurfaceMeshStats TimeMeshing(benchmark::State& state, SurfaceMeshSettings settings) {
  const Case& c = Cases().at(static_cast<size_t>(state.range(0)));
  settings.bounds = c.bounds;
  settings.cell_size = state.range(1) * 1e-4;
  TriangleMesh mesh;
  SurfaceMeshStats stats;
  for (auto _ : state) {
    mesh = MeshSurface(c.solid, settings, &stats);
    benchmark::DoNotOptimize(mesh.vertices.data());
  }
  state.SetLabel(c.name);
  state.counters["cell_mm"] = settings.cell_size * 1e3;
  state.counters["triangles"] = static_cast<double>(mesh.triangles.cols());
  state.counters["evaluations"] = static_cast<double>(stats.field_evaluations);
  return stats;
}

// MeshSurface alone on case state.range(0) at cell state.range(1) / 10 mm with snap_cells =
// state.range(2) / 100, as many meshes as Google Benchmark needs for a stable time (no error
// measurement): the case that shows the mesher itself slowing down (the 5 cm sphere at 1 mm,
// snap 0: 336 ms CPU per mesh before the speed-ups of 2026-12-05, 278 ms after, against about
// 28 ms for a dense marching cubes; docs/design/2026-12-04-surface-mesher-peers.md). Counters:
// triangles and field evaluations (exact, so a change in the work shows when times are noisy).
void BM_MeshSpeed(benchmark::State& state) {
  SurfaceMeshSettings settings;
  settings.snap_cells = state.range(2) * 0.01;
  TimeMeshing(state, settings);
  state.counters["snap"] = settings.snap_cells;
}
BENCHMARK(BM_MeshSpeed)
    ->ArgsProduct({{3}, {10, 20}, {0, static_cast<long>(kProductSnapCells * 100 + 0.5)}})
    ->ArgsProduct({{4}, {10}, {0, static_cast<long>(kProductSnapCells * 100 + 0.5)}})
    ->ArgsProduct({{2}, {40}, {0, static_cast<long>(kProductSnapCells * 100 + 0.5)}})
    ->Unit(benchmark::kMillisecond);

// BM_MeshSpeed for the lattice route (SurfaceMesher::kLattice, default lattice_snap): case
// state.range(0) at cell state.range(1) / 10 mm. The 5 cm sphere at 1 mm took 55-60 ms CPU per mesh
// on 2026-12-06; on 2026-12-07, a slower day, 68-89 ms before that day's bookkeeping changes and
// 55-69 ms after them, alternated (docs/design/2026-12-06-lattice-mesher.md); counters as
// BM_MeshSpeed, plus the
// lattice vertices snapped onto the surface.
void BM_LatticeSpeed(benchmark::State& state) {
  SurfaceMeshSettings settings;
  settings.mesher = SurfaceMesher::kLattice;
  const SurfaceMeshStats stats = TimeMeshing(state, settings);
  state.counters["snapped"] = static_cast<double>(stats.snapped_vertices);
}
BENCHMARK(BM_LatticeSpeed)
    ->ArgsProduct({{3}, {10, 15, 20}})
    ->ArgsProduct({{4}, {10}})
    ->ArgsProduct({{2}, {20, 40}})
    ->Unit(benchmark::kMillisecond);

// MeshSharpSurface's volume test (EstimateSolidVolume, kSharpVolumePoints Halton points over the
// case's bounds), which every sharpened surface of the product pays once: case state.range(0).
// Counter: the estimate, cm³.
void BM_SolidVolumeEstimate(benchmark::State& state) {
  const Case& c = Cases().at(static_cast<size_t>(state.range(0)));
  double volume = 0.0;
  for (auto _ : state) {
    volume = EstimateSolidVolume(c.solid, c.bounds, kSharpVolumePoints);
    benchmark::DoNotOptimize(volume);
  }
  state.SetLabel(c.name);
  state.counters["volume_cm3"] = volume * 1e6;
}
BENCHMARK(BM_SolidVolumeEstimate)->DenseRange(0, 4)->Unit(benchmark::kMillisecond);

// What keeps sharpened creases under 10°: MeshSurface (snap_cells = state.range(2) / 100) then
// SharpenFeatures with min_angle_deg = state.range(3), relax_angle_deg = state.range(4) and
// sliver_angle_deg = state.range(5) (the sliver repair, step 4b), on case state.range(0) at cell
// state.range(1) / 10 mm. Counters: the two-sided Hausdorff error (as BM_Surface), the smallest
// angle and the triangles under 5° and 10°, the sharpening's time, the triangle count, and
// closed_manifold (1 when closed, oriented and manifold with the Euler characteristic of the
// unsharpened mesh).
void BM_CreaseFloor(benchmark::State& state) {
  const Case& c = Cases().at(static_cast<size_t>(state.range(0)));
  const double cell = state.range(1) * 1e-4;
  SurfaceMeshSettings settings;
  settings.bounds = c.bounds;
  settings.cell_size = cell;
  settings.snap_cells = state.range(2) * 0.01;
  FeatureSettings f;
  f.cell_size = cell;
  f.min_angle_deg = static_cast<double>(state.range(3));
  f.relax_angle_deg = static_cast<double>(state.range(4));
  f.sliver_angle_deg = static_cast<double>(state.range(5));
  TriangleMesh mesh, plain;
  FeatureStats feature_stats;
  for (auto _ : state) {
    plain = MeshSurface(c.solid, settings);
    mesh = SharpenFeatures(c.solid, plain, f, &feature_stats);
  }
  long euler = 0, plain_euler = 0;
  const bool manifold = spidarcad::bench::IsClosedManifold(mesh, &euler) &&
                        spidarcad::bench::IsClosedManifold(plain, &plain_euler) &&
                        euler == plain_euler;
  const Error e = MeasureHausdorff(c, mesh, cell);
  state.SetLabel(c.name);
  state.counters["hausdorff_mm"] = e.TwoSided() * 1e3;
  state.counters["min_angle_deg"] = MeasureTriangleAngles(mesh).min_angle_deg;
  state.counters["under_5_deg"] = static_cast<double>(MeasureTriangleAngles(mesh, 5.0).small_angle);
  state.counters["under_10_deg"] =
      static_cast<double>(MeasureTriangleAngles(mesh, 10.0).small_angle);
  state.counters["sharpen_s"] = feature_stats.seconds;
  state.counters["triangles"] = static_cast<double>(mesh.triangles.cols());
  state.counters["closed_manifold"] = manifold ? 1.0 : 0.0;
}
BENCHMARK(BM_CreaseFloor)
    ->ArgsProduct({{1}, {40, 20, 10}, {0, 15}, {1, 5, 10}, {0, 10}, {0}})
    ->ArgsProduct({{2}, {80, 40}, {0, 15}, {1, 5, 10}, {0, 10}, {0}})
    // The sliver repair (sliver_angle_deg = 10) after the default floor of 1°.
    ->ArgsProduct({{1}, {40, 20, 10}, {0, 15}, {1}, {0}, {10}})
    ->ArgsProduct({{2}, {80, 40}, {0, 15}, {1}, {0}, {10}})
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
    "BM_Snap: snap_cells 0 to 0.25 on the sphere, a torus and the platform (angles against\n"
    "error); BM_CreaseFloor: the sharpening's min_angle_deg, relax_angle_deg and sliver_angle_deg\n"
    "(the sliver repair; rows /.../1/0/10/) on default and snapped surfaces of the box minus the\n"
    "cylinder and the platform (crease error against angles). Select with\n"
    "--benchmark_filter=BM_Snap etc.\n"
    "BM_MeshSpeed: MeshSurface alone, repeated (CPU time per mesh): sphere at 1 and 2 mm, torus "
    "at\n"
    "1 mm, platform at 4 mm, snap_cells 0 and kProductSnapCells (0.2).\n"
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
