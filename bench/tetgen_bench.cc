// TetGen meshing of the platform scene (assets/scenes/platform.json): surface by MeshSurface at
// a cell size (4 and 3 mm: at 2.5 and 2 mm MeshSurface's slivers make TetGen or CheckSurface
// refuse the surface), then TetrahedralizeSurface with and without quality refinement. Reports
// time, tet count and quality as counters. One iteration each (seconds per run). Run:
//   build-dir/bench/tetgen_bench --benchmark_counters_tabular=true
// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#include <benchmark/benchmark.h>

#include <string>

#include "bench_cli.h"
#include "bench_paths.h"
#include "spidarcad/modeling/implicit_evaluator.h"
#include "spidarcad/modeling/scene_io.h"
#include "spidarcad/modeling/surface_mesher.h"
#include "spidarcad/modeling/tetgen_mesher.h"

namespace {

using namespace spidarcad::modeling;

// Args: cell size in 0.1 mm, radius-edge bound in 0.1 (0: none), max volume in mm³ (0: none).
void BM_TetgenPlatform(benchmark::State& state) {
  const double cell = state.range(0) * 1e-4;
  const Scene scene = LoadScene(spidarcad::bench::RepoPath("assets/scenes/platform.json"));
  const CompiledSolid platform = CompiledSolid::Compile(scene.solids[0].root);
  SurfaceMeshSettings surface_settings;
  surface_settings.bounds =
      Eigen::AlignedBox3d(Eigen::Vector3d(-0.01, -0.11, -0.16), Eigen::Vector3d(0.31, 0.11, 0.02));
  surface_settings.cell_size = cell;
  const TriangleMesh surface = MeshSurface(platform, surface_settings);
  TetMeshSettings settings;
  settings.max_radius_edge = state.range(1) * 0.1;
  settings.max_volume = state.range(2) * 1e-9;
  TetMeshStats stats;
  long tets = 0;
  for (auto _ : state) {
    const TetMesh mesh = TetrahedralizeSurface(surface, settings, &stats);
    tets = mesh.tets.cols();
    benchmark::DoNotOptimize(mesh.nodes.data());
  }
  state.counters["triangles"] = static_cast<double>(surface.triangles.cols());
  state.counters["dropped_triangles"] = static_cast<double>(stats.dropped_triangles);
  state.counters["tets"] = static_cast<double>(tets);
  state.counters["check_s"] = stats.check_seconds;
  state.counters["tetgen_s"] = stats.tetgen_seconds;
  state.counters["min_dihedral_deg"] = stats.quality.min_dihedral_deg;
  state.counters["max_dihedral_deg"] = stats.quality.max_dihedral_deg;
  state.counters["max_radius_edge"] = stats.quality.max_radius_edge;
  state.counters["volume_cm3"] = stats.quality.total_volume * 1e6;
  state.counters["surface_volume_cm3"] = MeshVolume(surface) * 1e6;
}
BENCHMARK(BM_TetgenPlatform)
    ->Args({40, 0, 0})
    ->Args({30, 0, 0})
    ->Args({40, 20, 0})
    ->Args({30, 20, 0})
    ->Iterations(1)
    ->Unit(benchmark::kSecond);

}  // namespace

// What this program measures (its --help).
constexpr const char* kBenchDescription =
    "TetGen meshing of the platform scene (assets/scenes/platform.json): surface by MeshSurface "
    "at\n"
    "a cell size (4 and 3 mm: at 2.5 and 2 mm MeshSurface's slivers make TetGen or CheckSurface\n"
    "refuse the surface), then TetrahedralizeSurface with and without quality refinement. Reports "
    "time,\n"
    "tet count and quality as counters. One iteration each (seconds per run). Run:\n"
    "  build-dir/bench/tetgen_bench --benchmark_counters_tabular=true";

int main(int argc, char** argv) {
  return spidarcad::bench::RunBenchmarkMain(argc, argv, kBenchDescription);
}
