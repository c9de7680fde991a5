// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
//
// FE figures on the platform scene (assets/scenes/platform.json, the paper's Fig. 7: a
// 0.3 × 0.2 × 0.01 m plate on a wall bracket with a gusset), meshed by modeling (MeshSurface on
// a grid of `resolution`, then TetGen), linear or quadratic (MakeQuadratic), steel, clamped
// at the wall face x = 0, 200 N down on the free end of the plate (x >= 0.296 m).
//   BM_PlatformPrecompute/order/res_um   meshing, assembly, factorisation, 64 compliance
//                                        nodes, memory; free-end deflection against the finest
//                                        quadratic mesh of the run (the reference).
//   BM_PlatformTick/order/res_um/k       one haptic tick, k pushed plate-top nodes.
//   BM_PlatformFullSolve/order/res_um    the same k = 16 contact as a full sparse solve.
//   BM_PlatformColumnCache/order/res_um  background worker: columns/s for the 48 top nodes
//                                        nearest the free end, memory per node (double).
// A markdown table is printed after the run. The scene is found at $SPIDARCAD_PLATFORM_SCENE,
// else <source>/assets/scenes/platform.json (from this file's path), else
// assets/scenes/platform.json in the working directory.
// Run: build/bench/app_fem_platform_bench
#include <benchmark/benchmark.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <ctime>
#include <map>
#include <memory>
#include <string>
#include <vector>

#include "bench_cli.h"
#include "bench_paths.h"
#include "scene/scene_solid.h"
#include "scene/vtu_io.h"
#include "spidarcad/fem/column_cache.h"
#include "spidarcad/fem/condensation.h"
#include "spidarcad/modeling/surface_mesher.h"
#include "spidarcad/modeling/tetgen_mesher.h"

namespace spidarcad {
namespace {

constexpr double kLoad = 200.0;  // N, down, on the free end
constexpr int kCondensed = 64;   // eager compliance nodes (tick benchmarks)
constexpr int kCacheNodes = 48;  // column-cache benchmark
const fem::Material kSteel{2.0e11, 0.3};

// CPU time of the process, s (on a shared machine wall time counts others' work too).
double CpuSeconds() {
  timespec ts{};
  clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &ts);
  return ts.tv_sec + 1e-9 * ts.tv_nsec;
}

std::string ScenePath() {
  if (const char* p = std::getenv("SPIDARCAD_PLATFORM_SCENE"); p && *p) return p;
  return spidarcad::bench::RepoPath("assets/scenes/platform.json");
}

struct Platform {
  fem::TetMesh mesh;
  fem::MaterialTable materials{kSteel};
  std::unique_ptr<fem::BoundaryConditions> bcs;
  std::unique_ptr<fem::StaticSolver> solver;
  std::unique_ptr<fem::Compliance> compliance;
  std::vector<int> surface, top;  // surface nodes; plate-top nodes (z > 9 mm), free end first
  double mesh_seconds = 0.0, deflection = 0.0;
  int fixed_nodes = 0;
};

Platform& GetPlatform(int order, int resolution_um) {
  static std::map<std::pair<int, int>, std::unique_ptr<Platform>> cache;
  auto& slot = cache[{order, resolution_um}];
  if (slot) return *slot;
  slot = std::make_unique<Platform>();
  Platform& p = *slot;
  const auto t0 = std::chrono::steady_clock::now();
  const double resolution = resolution_um * 1e-6;
  const app::SceneSolidGrid grid = app::PrepareSceneSolid(ScenePath(), "platform", resolution);
  modeling::SurfaceMeshSettings ss;
  ss.bounds = grid.bounds;
  ss.cell_size = grid.cell;
  const modeling::TriangleMesh surface = modeling::MeshSurface(grid.compiled, ss);
  modeling::TetMeshSettings ts;
  ts.max_radius_edge = 2.0;
  p.mesh = app::ToFemMesh(modeling::TetrahedralizeSurface(surface, ts));
  if (order == 2) p.mesh = fem::MakeQuadratic(p.mesh);
  p.mesh_seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();

  p.bcs = std::make_unique<fem::BoundaryConditions>(p.mesh.num_nodes());
  const double min_x = p.mesh.nodes.col(0).minCoeff(), max_x = p.mesh.nodes.col(0).maxCoeff();
  // The wall face: surface meshing places its vertices within a fraction of a cell of x = 0.
  p.fixed_nodes = fem::FixNodesInBox(p.mesh, Eigen::Vector3d(-1, -1, -1),
                                     Eigen::Vector3d(min_x + 0.25 * grid.cell, 1, 1), p.bcs.get());
  if (std::getenv("SPIDARCAD_BENCH_VERBOSE"))
    std::fprintf(stderr, "platform: min x %.3g m, cell %.3g m, %d nodes fixed\n", min_x, grid.cell,
                 p.fixed_nodes);
  const auto end =
      fem::NodesInBox(p.mesh, Eigen::Vector3d(max_x - 0.004, -1, -1), Eigen::Vector3d(1, 1, 1));
  for (int v : end) p.bcs->AddPointLoad(v, Eigen::Vector3d(0, 0, -kLoad / end.size()));
  p.solver = std::make_unique<fem::StaticSolver>(p.mesh, p.materials, *p.bcs);
  const fem::StaticSolution sol = p.solver->Solve();
  for (int v : end) p.deflection += -sol.displacement(3 * v + 2) / end.size();

  p.surface = fem::ExtractSurface(p.mesh).nodes;
  const Eigen::Vector3d tip(0.28, 0.0, 0.01);
  for (int v : p.surface)
    if (p.mesh.nodes(v, 2) > 0.009) p.top.push_back(v);
  std::sort(p.top.begin(), p.top.end(), [&](int a, int b) {
    return (p.mesh.nodes.row(a).transpose() - tip).norm() <
           (p.mesh.nodes.row(b).transpose() - tip).norm();
  });
  std::vector<int> condensed(p.top.begin(),
                             p.top.begin() + std::min<size_t>(kCondensed, p.top.size()));
  p.compliance = std::make_unique<fem::Compliance>(*p.solver, p.surface, condensed);
  return p;
}

struct Row {
  int tets = 0, dofs = 0, surface_nodes = 0;
  double mesh_s = 0, factor_s = 0, column_ms_per_node = 0, peak_mb = 0, g_mb_per_node = 0;
  double deflection_mm = 0;
  std::map<int, double> tick_us;
  double full_ms = -1, tick16_us = -1;
  double cache_columns_per_s = -1, full_surface_gb = -1;
};
std::map<std::pair<int, int>, Row>& Rows() {
  static std::map<std::pair<int, int>, Row> rows;
  return rows;
}

void BM_PlatformPrecompute(benchmark::State& state) {
  const int order = static_cast<int>(state.range(0)), res = static_cast<int>(state.range(1));
  Platform* p = nullptr;
  for (auto _ : state) p = &GetPlatform(order, res);
  const fem::FactorStats& st = p->solver->stats();
  Row& row = Rows()[{order, res}];
  row.tets = p->mesh.num_elements();
  row.dofs = st.num_free;
  row.surface_nodes = static_cast<int>(p->surface.size());
  row.mesh_s = p->mesh_seconds;
  row.factor_s = st.assembly_seconds + st.factor_seconds;
  row.column_ms_per_node =
      1e3 * p->compliance->compute_seconds() / p->compliance->condensed_nodes().size();
  row.peak_mb = st.factor_peak_bytes / 1e6;
  row.g_mb_per_node = 72.0 * p->surface.size() / 1e6;
  row.deflection_mm = 1e3 * p->deflection;
  state.counters["tets"] = row.tets;
  state.counters["dofs"] = row.dofs;
  state.counters["fixed_nodes"] = p->fixed_nodes;
  state.counters["mesh_s"] = row.mesh_s;
  state.counters["factor_s"] = row.factor_s;
  state.counters["column_ms_per_node"] = row.column_ms_per_node;
  state.counters["deflection_mm"] = row.deflection_mm;
}

std::vector<double> Targets(const fem::Compliance& c, const fem::ContactSolver& solver) {
  std::vector<double> t(3 * solver.num_contacts());
  for (int s = 0; s < solver.num_contacts(); ++s) {
    const int row = 3 * c.OutputIndexOfCondensed(solver.contact(s));
    for (int i = 0; i < 3; ++i) t[3 * s + i] = c.baseline()(row + i) - (i == 2 ? 1e-4 : 0.0);
  }
  return t;
}

void BM_PlatformTick(benchmark::State& state) {
  const int order = static_cast<int>(state.range(0)), res = static_cast<int>(state.range(1));
  const int k = static_cast<int>(state.range(2));
  const Platform& p = GetPlatform(order, res);
  fem::ContactSolver solver(*p.compliance, kCondensed);
  for (int b = 0;
       b < static_cast<int>(p.compliance->condensed_nodes().size()) && solver.num_contacts() < k;
       ++b)
    solver.Add(b);
  const auto target = Targets(*p.compliance, solver);
  std::vector<double> f(target.size());
  const double t0 = CpuSeconds();
  for (auto _ : state) {
    solver.Solve(target.data(), f.data());
    benchmark::DoNotOptimize(f.data());
  }
  const double us =
      1e6 * (CpuSeconds() - t0) / std::max<double>(1.0, static_cast<double>(state.iterations()));
  Rows()[{order, res}].tick_us[k] = us;
  state.counters["k"] = solver.num_contacts();
}

void BM_PlatformFullSolve(benchmark::State& state) {
  const int order = static_cast<int>(state.range(0)), res = static_cast<int>(state.range(1));
  const Platform& p = GetPlatform(order, res);
  fem::ContactSolver solver(*p.compliance, kCondensed);
  for (int b = 0; b < 16; ++b) solver.Add(b);
  const auto target = Targets(*p.compliance, solver);
  std::vector<double> f(target.size());
  const int reps = 2000;
  double t0 = CpuSeconds();
  for (int i = 0; i < reps; ++i) solver.Solve(target.data(), f.data());
  const double tick_s = (CpuSeconds() - t0) / reps;
  double max_rel = 0.0, full_s = 0.0;
  for (auto _ : state) {
    t0 = CpuSeconds();
    fem::BoundaryConditions bcs = *p.bcs;
    for (int s = 0; s < solver.num_contacts(); ++s)
      bcs.PrescribeNode(p.compliance->condensed_nodes()[solver.contact(s)],
                        Eigen::Vector3d(target[3 * s], target[3 * s + 1], target[3 * s + 2]));
    const fem::StaticSolver full(p.mesh, p.materials, bcs);
    const fem::StaticSolution sol = full.Solve();
    full_s = CpuSeconds() - t0;
    Eigen::VectorXd a(target.size()), b(target.size());
    for (int s = 0; s < solver.num_contacts(); ++s) {
      a.segment<3>(3 * s) =
          sol.reaction.segment<3>(3 * p.compliance->condensed_nodes()[solver.contact(s)]);
      b.segment<3>(3 * s) = Eigen::Vector3d(f[3 * s], f[3 * s + 1], f[3 * s + 2]);
    }
    max_rel = (a - b).norm() / a.norm();
  }
  Row& row = Rows()[{order, res}];
  row.full_ms = 1e3 * full_s;
  row.tick16_us = 1e6 * tick_s;
  state.counters["condensed_tick_us"] = 1e6 * tick_s;
  state.counters["full_ms"] = 1e3 * full_s;
  state.counters["full_over_tick"] = full_s / tick_s;
  state.counters["force_rel_diff"] = max_rel;
}

void BM_PlatformColumnCache(benchmark::State& state) {
  const int order = static_cast<int>(state.range(0)), res = static_cast<int>(state.range(1));
  const Platform& p = GetPlatform(order, res);
  const Eigen::Vector3d tip(0.28, 0.0, 0.01);
  std::vector<double> d;
  for (int v : p.top) d.push_back((p.mesh.nodes.row(v).transpose() - tip).norm());
  std::sort(d.begin(), d.end());
  const double radius = d[std::min<size_t>(d.size(), kCacheNodes) - 1] * (1 + 1e-9);
  double seconds = 0.0, per_node = 0.0;
  long nodes = 0;
  for (auto _ : state) {
    fem::ColumnCacheSettings settings;
    settings.memory_budget_bytes = 2.0e9;
    fem::ColumnCache cache(*p.solver, p.mesh.nodes, p.surface, p.top, settings);
    const double t0 = CpuSeconds();  // the worker's CPU: this thread only sleeps
    cache.RequestNear(tip, radius);
    cache.WaitUntilIdle(600.0);
    seconds = CpuSeconds() - t0;
    nodes = cache.stats().computed_nodes;
    per_node = cache.BytesPerNode();
  }
  Row& row = Rows()[{order, res}];
  row.cache_columns_per_s = 3.0 * nodes / seconds;
  row.full_surface_gb = per_node * p.surface.size() / 1e9;
  state.counters["nodes"] = static_cast<double>(nodes);
  state.counters["columns_per_cpu_s"] = row.cache_columns_per_s;
  state.counters["kB_per_node"] = per_node / 1e3;
  state.counters["full_surface_GB"] = row.full_surface_gb;
}

void PrintTable() {
  double reference = 0.0;
  int ref_res = 0;
  for (const auto& [key, row] : Rows())
    if (key.first == 2 && row.tets > 0 && (ref_res == 0 || key.second < ref_res)) {
      ref_res = key.second;
      reference = row.deflection_mm;
    }
  std::printf(
      "\nTick, full-solve and worker times are CPU time of this process (mesh, assembly and "
      "factor times are wall time).\n");
  std::printf(
      "\n### Speed against error: platform (steel, clamped at the wall, %.0f N on the free "
      "end)\n\n",
      kLoad);
  std::printf(
      "Deflection error against the finest quadratic mesh of this run (%.1f mm grid: %.4f mm).\n\n",
      ref_res * 1e-3, reference);
  std::printf(
      "| order | grid mm | tets | free dofs | mesh s | assembly+factor s | column ms/node | "
      "CHOLMOD peak MB | G MB/node | deflection mm | error %% | tick us k=1 | k=4 | k=16 | k=64 | "
      "full sparse solve ms (k=16) | full / tick | worker columns per CPU s | whole surface GB "
      "|\n");
  std::printf("|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|\n");
  for (const auto& [key, r] : Rows()) {
    if (r.tets == 0) continue;
    auto tick = [&](int k) {
      const auto it = r.tick_us.find(k);
      return it == r.tick_us.end() ? std::string("-") : std::to_string(it->second).substr(0, 6);
    };
    const double err =
        reference > 0 ? 100.0 * std::abs(r.deflection_mm - reference) / reference : 0.0;
    std::printf(
        "| %d | %.1f | %d | %d | %.2f | %.2f | %.2f | %.1f | %.3f | %.4f | %.2f | %s | %s | %s | "
        "%s | "
        "%.1f | %.0f | %.0f | %.2f |\n",
        key.first, key.second * 1e-3, r.tets, r.dofs, r.mesh_s, r.factor_s, r.column_ms_per_node,
        r.peak_mb, r.g_mb_per_node, r.deflection_mm, err, tick(1).c_str(), tick(4).c_str(),
        tick(16).c_str(), tick(64).c_str(), r.full_ms,
        r.full_ms > 0 ? 1e3 * r.full_ms / r.tick16_us : 0.0, r.cache_columns_per_s,
        r.full_surface_gb);
  }
}

// Grid cells (µm) for the linear and quadratic runs.
void Sizes(benchmark::internal::Benchmark* b) {
  for (int res : {12000, 10000, 8000, 6000}) b->Args({1, res});
  for (int res : {12000, 10000}) b->Args({2, res});
}
void TickSizes(benchmark::internal::Benchmark* b) {
  for (auto [order, res] : {std::pair{1, 10000}, std::pair{1, 6000}, std::pair{2, 10000}})
    for (int k : {1, 4, 16, 64}) b->Args({order, res, k});
}

BENCHMARK(BM_PlatformPrecompute)->Apply(Sizes)->Iterations(1)->Unit(benchmark::kSecond);
BENCHMARK(BM_PlatformTick)->Apply(TickSizes)->Unit(benchmark::kMicrosecond);
BENCHMARK(BM_PlatformFullSolve)->Apply(Sizes)->Iterations(1)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_PlatformColumnCache)
    ->Args({1, 6000})
    ->Args({2, 10000})
    ->Iterations(1)
    ->Unit(benchmark::kSecond);

}  // namespace
}  // namespace spidarcad

// What this program measures (its --help).
constexpr const char* kBenchDescription =
    "FE figures on the platform scene (assets/scenes/platform.json, the paper's Fig. 7: a\n"
    "0.3 × 0.2 × 0.01 m plate on a wall bracket with a gusset), meshed by modeling (MeshSurface "
    "on\n"
    "a grid of `resolution`, then TetGen), linear or quadratic (MakeQuadratic), steel, clamped\n"
    "at the wall face x = 0, 200 N down on the free end of the plate (x >= 0.296 m).\n"
    "  BM_PlatformPrecompute/order/res_um   meshing, assembly, factorisation, 64 compliance\n"
    "                                       nodes, memory; free-end deflection against the finest\n"
    "                                       quadratic mesh of the run (the reference).\n"
    "  BM_PlatformTick/order/res_um/k       one haptic tick, k pushed plate-top nodes.\n"
    "  BM_PlatformFullSolve/order/res_um    the same k = 16 contact as a full sparse solve.\n"
    "  BM_PlatformColumnCache/order/res_um  background worker: columns/s for the 48 top nodes\n"
    "                                       nearest the free end, memory per node (double).\n"
    "A markdown table is printed after the run. The scene is found at $SPIDARCAD_PLATFORM_SCENE,\n"
    "else <source>/assets/scenes/platform.json (from this file's path), else\n"
    "assets/scenes/platform.json in the working directory.\n"
    "Run: build/bench/app_fem_platform_bench";

// Tables printed after the benchmarks.
void PrintAfterRun() { spidarcad::PrintTable(); }

int main(int argc, char** argv) {
  return spidarcad::bench::RunBenchmarkMain(argc, argv, kBenchDescription, nullptr, PrintAfterRun);
}
