// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
//
// TetGen on the platform's slabs as FE mode cuts them (the grid surface snapped as in FE mode, the
// four slabs of SlabPlanes across x, sections spaced a cell apart), with and without the vertices
// moved (TetMeshSettings::perturb_from_triangles, modeling/tetgen_mesher.h): time against the
// tets' quality on the exact positions (worst dihedral angle, tets with a dihedral angle under 5°
// and under 10°). docs/design/2026-12-07-edit-stages.md has the figures.
// Arguments: cell (um), slab (0..3), moved (0: exact positions; 1: moved, from any size).
// Run: build/bench/app_slab_tetgen_bench
//      build/bench/app_slab_tetgen_bench --benchmark_filter='/5000/0/'
#include <benchmark/benchmark.h>

#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <map>
#include <string>
#include <vector>

#include "bench_cli.h"
#include "bench_paths.h"
#include "scene/scene_solid.h"
#include "scene/slab_fe_mesh.h"
#include "spidarcad/modeling/slab_mesher.h"
#include "spidarcad/modeling/surface_mesher.h"
#include "spidarcad/modeling/tet_mesh.h"

namespace spidarcad {
namespace {

std::string ScenePath() {
  if (const char* p = std::getenv("SPIDARCAD_PLATFORM_SCENE"); p && *p) return p;
  return bench::RepoPath("assets/scenes/platform.json");
}

// The platform's slab surfaces at a cell, cut as FE mode cuts them (cached per cell).
const modeling::SlabSurfaces& Slabs(int cell_um) {
  static std::map<int, modeling::SlabSurfaces> cache;
  auto it = cache.find(cell_um);
  if (it != cache.end()) return it->second;
  const app::SceneSolidGrid grid = app::PrepareSceneSolid(ScenePath(), "", cell_um * 1e-6);
  modeling::SurfaceMeshSettings ss;
  ss.bounds = grid.bounds;
  ss.cell_size = grid.cell;
  ss.snap_cells = modeling::kProductSnapCells;
  modeling::SlabCut cut;
  cut.planes = app::SlabPlanes(grid.bounds, grid.cell, 4);
  cut.snap = 0.1 * grid.cell;  // as MeshSurfaceInSlabs cuts
  cut.section_spacing = grid.cell;
  return cache[cell_um] =
             modeling::CutSurfaceIntoSlabs(modeling::MeshSurface(grid.compiled, ss), cut);
}

struct Row {
  int cell_um = 0, slab = 0, moved = 0;
  long triangles = 0, tets = 0, under5 = 0, under10 = 0;
  double seconds = 0.0, worst = 0.0;
};

std::vector<Row>& Rows() {
  static std::vector<Row> rows;
  return rows;
}

void BM_SlabTetgen(benchmark::State& state) {
  Row row;
  row.cell_um = static_cast<int>(state.range(0));
  row.slab = static_cast<int>(state.range(1));
  row.moved = static_cast<int>(state.range(2));
  const modeling::TriangleMesh& surface = Slabs(row.cell_um).slabs.at(row.slab);
  modeling::TetMeshSettings ts;
  ts.max_radius_edge = 2.0;  // FE mode's bound
  ts.preserve_surface = true;
  ts.keep_facets = true;
  ts.weld_tolerance = -1.0;
  ts.perturb_from_triangles = row.moved;
  modeling::TetMeshStats stats;
  modeling::TetMesh mesh;
  for (auto _ : state) mesh = modeling::TetrahedralizeSurface(surface, ts, &stats);
  if (stats.perturbed != (row.moved != 0)) state.SkipWithError("the moved vertices were not kept");
  row.triangles = surface.triangles.cols();
  row.tets = mesh.tets.cols();
  row.seconds = stats.tetgen_seconds;
  row.worst = 180.0;
  for (Eigen::Index t = 0; t < mesh.tets.cols(); ++t) {
    const double worst =
        modeling::DihedralAngles(mesh.nodes.col(mesh.tets(0, t)), mesh.nodes.col(mesh.tets(1, t)),
                                 mesh.nodes.col(mesh.tets(2, t)), mesh.nodes.col(mesh.tets(3, t)))
            .minCoeff() *
        (180.0 / 3.14159265358979323846);  // rad -> deg
    row.worst = std::min(row.worst, worst);
    row.under5 += worst < 5.0;
    row.under10 += worst < 10.0;
  }
  state.counters["tets"] = static_cast<double>(row.tets);
  state.counters["min_dihedral_deg"] = row.worst;
  state.counters["under_5deg"] = static_cast<double>(row.under5);
  state.counters["under_10deg"] = static_cast<double>(row.under10);
  Rows().push_back(row);
}

void PrintTables() {
  bench::PrintLoadAverage();
  std::printf(
      " TetGen's wall time (s) on each slab of the platform; quality on the exact positions.\n\n"
      "| cell mm | slab | triangles | vertices | TetGen s | tets | worst dihedral ° | tets < 5° "
      "| tets < 10° |\n|---|---|---|---|---|---|---|---|---|\n");
  for (const Row& r : Rows())
    std::printf("| %g | %d | %ld | %s | %.3f | %ld | %.2f | %ld | %ld |\n", r.cell_um * 1e-3,
                r.slab, r.triangles, r.moved ? "moved" : "exact", r.seconds, r.tets, r.worst,
                r.under5, r.under10);
}

void Args(benchmark::internal::Benchmark* b) {
  for (int cell : {4000, 5000, 6000, 8000, 10000})
    for (int slab = 0; slab < 4; ++slab)
      for (int moved = 0; moved < 2; ++moved) b->Args({cell, slab, moved});
}

BENCHMARK(BM_SlabTetgen)->Apply(Args)->Iterations(1)->Unit(benchmark::kMillisecond);

}  // namespace
}  // namespace spidarcad

int main(int argc, char** argv) {
  return spidarcad::bench::RunBenchmarkMain(
      argc, argv,
      "TetGen on the platform's FE slabs with the vertices exact or moved "
      "(TetMeshSettings::perturb_from_triangles): time against the tets' dihedral angles.",
      nullptr, spidarcad::PrintTables);
}
