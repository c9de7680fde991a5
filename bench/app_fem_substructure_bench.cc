// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
//
// Edit to first correct felt force on the platform, each case a Google Benchmark run of
// app::MeasureEditToForce (app/src/cli/edit_to_force.h, shared with `spidarcad report`, section
// "edit": what is measured and how). Markdown tables are printed after the run, with the load
// average.
// Arguments: order, cell (um), slabs, lattice (1: every surface by the lattice route, the case
// named "..., lattice"), flat fans coarsened, in hundredths of a cell (0: not; 50: the
// marching-tetrahedra surfaces with SurfaceMeshSettings::flat_coarsen_cells = 0.5, the case
// named "..., flat 0.5"; docs/design/2026-12-06-flat-faces.md). The cases named "..._fe_mode"
// mesh as FE mode meshes a solid: surfaces snapped (modeling::kProductSnapCells), the bracket
// slab in three strips (app::kFeStrips).
// Run: build/bench/app_fem_substructure_bench   (P2 at 10 mm, P1 at 6 mm, P1 at 5 mm: 105k tets)
//      build/bench/app_fem_substructure_bench --benchmark_filter=P2
//      build/bench/app_fem_substructure_bench --benchmark_filter=P2_10mm/2/10000/4/1
#include <benchmark/benchmark.h>

#include <cstdio>
#include <cstdlib>
#include <string>
#include <vector>

#include "bench_cli.h"
#include "bench_paths.h"
#include "cli/edit_to_force.h"
#include "scene/fe_setup.h"
#include "spidarcad/modeling/surface_mesher.h"

namespace spidarcad {
namespace {

std::string ScenePath() {
  if (const char* p = std::getenv("SPIDARCAD_PLATFORM_SCENE"); p && *p) return p;
  return bench::RepoPath("assets/scenes/platform.json");
}

std::vector<app::EditToForceCase>& Cases() {
  static std::vector<app::EditToForceCase> rows;
  return rows;
}

// `fe_mode`: the surfaces snapped and the bracket slab in strips, as FE mode meshes a solid.
void EditToForce(benchmark::State& state, bool fe_mode) {
  const int order = static_cast<int>(state.range(0)), res_um = static_cast<int>(state.range(1));
  const int num_slabs = static_cast<int>(state.range(2));
  const bool lattice = state.range(3) != 0;  // the lattice route's surfaces
  app::EditToForceMeshing meshing;
  meshing.lattice = lattice;
  meshing.flat_cells = state.range(4) * 0.01;
  if (fe_mode) {
    meshing.strips = app::kFeStrips;
    meshing.snap_cells = modeling::kProductSnapCells;
  }
  app::EditToForceCase row;
  for (auto _ : state)
    row = app::MeasureEditToForce(ScenePath(), order, res_um * 1e-6, num_slabs, 4, meshing);
  state.counters["interface_dofs"] = row.interface;
  state.counters["full_s"] = row.full_wall();
  state.counters["edit1_s"] = row.edits.empty() ? 0.0 : row.edits.front().total_wall;
  Cases().push_back(row);
}
void BM_EditToForce(benchmark::State& state) { EditToForce(state, false); }
// As FE mode meshes a solid: snapped surfaces, the bracket slab in strips ("..., 3 strips, snap
// 0.2").
void BM_EditToForceAsFeMode(benchmark::State& state) { EditToForce(state, true); }

void PrintTables() {
  bench::PrintLoadAverage();
  std::printf(" Times in s (wall unless marked cpu).\n\n");
  std::printf("%s", app::EditToForceTables(Cases()).c_str());
}

BENCHMARK(BM_EditToForce)
    ->Name("P2_10mm")
    ->Args({2, 10000, 4, 0, 0})
    ->Args({2, 10000, 6, 0, 0})
    ->Args({2, 10000, 4, 1, 0})
    ->Args({2, 10000, 4, 0, 50})
    ->Args({2, 10000, 6, 1, 0})
    ->Iterations(1)
    ->Unit(benchmark::kSecond);
// The default surface at cells next to 10 mm, where the grid cuts the plate's faces with needles
// and the clean-up coarsens them (docs/design/2026-12-06-flat-faces.md).
BENCHMARK(BM_EditToForce)
    ->Name("P2_near10mm")
    ->Args({2, 9000, 4, 0, 0})
    ->Args({2, 10200, 4, 0, 0})
    ->Iterations(1)
    ->Unit(benchmark::kSecond);
BENCHMARK(BM_EditToForce)
    ->Name("P1_6mm")
    ->Args({1, 6000, 4, 0, 0})
    ->Args({1, 6000, 6, 0, 0})
    ->Args({1, 6000, 4, 1, 0})
    ->Args({1, 6000, 6, 1, 0})
    ->Iterations(1)
    ->Unit(benchmark::kSecond);
// The "100k-tet part with linear elements": the platform at 5 mm cells (about 105k tets).
BENCHMARK(BM_EditToForce)
    ->Name("P1_5mm")
    ->Args({1, 5000, 4, 0, 0})
    ->Args({1, 5000, 4, 1, 0})
    ->Args({1, 5000, 6, 0, 0})
    ->Args({1, 5000, 6, 1, 0})
    ->Iterations(1)
    ->Unit(benchmark::kSecond);
BENCHMARK(BM_EditToForceAsFeMode)
    ->Name("P1_5mm_fe_mode")
    ->Args({1, 5000, 4, 0, 0})
    ->Iterations(1)
    ->Unit(benchmark::kSecond);

}  // namespace
}  // namespace spidarcad

int main(int argc, char** argv) {
  return spidarcad::bench::RunBenchmarkMain(
      argc, argv,
      "Edit to first correct felt force on the platform: slab re-meshing and the substructured "
      "solver (scene/slab_fe_mesh.h, fem/substructure.h) against a full recompute.",
      nullptr, spidarcad::PrintTables);
}
