// Speed of the compiled implicit evaluator: point queries with gradient (the haptic proxy's
// per-tick cost), batch throughput, interval bounds per box, octree culling, and the platform
// scene. Run from anywhere: build-dir/bench/implicit_bench (bench_paths.h finds the scene).
// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#include <benchmark/benchmark.h>

#include <cmath>
#include <memory>
#include <random>
#include <string>
#include <vector>

#include "bench_cli.h"
#include "bench_paths.h"
#include "spidarcad/modeling/cell_specialized_solid.h"
#include "spidarcad/modeling/implicit_evaluator.h"
#include "spidarcad/modeling/scene_io.h"
#include "spidarcad/modeling/surface_mesher.h"

namespace {

using namespace spidarcad::modeling;

// A 50-node part: a smoothly blended cluster of 10 rotated primitives of every kind, minus 6
// holes, offset, mirrored, with a rounded base. Deterministic.
ImplicitNode FiftyNodeTree() {
  std::mt19937 rng(42);
  std::uniform_real_distribution<double> u(-0.05, 0.05);
  auto at = [&](ImplicitNode child) {
    return ImplicitNode(TranslateParams{Eigen::Vector3d(u(rng), u(rng), u(rng))},
                        {std::move(child)});
  };
  ExtrusionParams hexagon;
  for (int i = 0; i < 6; ++i)
    hexagon.profile.emplace_back(0.02 * std::cos(i * M_PI / 3), 0.02 * std::sin(i * M_PI / 3));
  hexagon.height = 0.03;
  const std::vector<NodeParams> lumps = {
      SphereParams{0.03},
      BoxParams{Eigen::Vector3d(0.04, 0.03, 0.02)},
      RoundedBoxParams{Eigen::Vector3d(0.05, 0.03, 0.03), 0.005},
      CylinderParams{0.015, 0.06},
      CapsuleParams{Eigen::Vector3d(0, 0, -0.02), Eigen::Vector3d(0.02, 0, 0.02), 0.01},
      ConeParams{0.025, 0.01, 0.04},
      TorusParams{0.025, 0.008},
      hexagon,
      SphereParams{0.025},
      BoxParams{Eigen::Vector3d(0.02, 0.05, 0.02)}};
  ImplicitNode cluster(SmoothUnionParams{0.01});
  for (const NodeParams& p : lumps) {
    cluster.children.push_back(at(ImplicitNode(
        RotateParams{Eigen::Vector3d(u(rng), u(rng), 1.0), u(rng) * 30}, {ImplicitNode(p)})));
  }
  ImplicitNode holes(UnionParams{});
  for (int i = 0; i < 6; ++i)
    holes.children.push_back(at(ImplicitNode(CylinderParams{0.006, 0.2})));
  ImplicitNode part(DifferenceParams{}, {cluster, holes});
  ImplicitNode base(TranslateParams{Eigen::Vector3d(0, 0, -0.06)},
                    {ImplicitNode(RoundedBoxParams{Eigen::Vector3d(0.15, 0.15, 0.02), 0.005})});
  ImplicitNode with_base(UnionParams{}, {part, base});
  ImplicitNode offset(OffsetParams{0.001}, {with_base});
  MirrorParams mirror;
  mirror.normal = Eigen::Vector3d(1, 0, 0);
  mirror.offset = 0.06;
  mirror.keep_original = true;
  return ImplicitNode(mirror, {offset});
}

std::vector<Eigen::Vector3d> RandomPoints(int n, const Eigen::Vector3d& lo,
                                          const Eigen::Vector3d& hi) {
  std::mt19937 rng(7);
  std::vector<Eigen::Vector3d> points;
  for (int i = 0; i < n; ++i) {
    Eigen::Vector3d p;
    for (int k = 0; k < 3; ++k) p[k] = std::uniform_real_distribution<double>(lo[k], hi[k])(rng);
    points.push_back(p);
  }
  return points;
}

const Eigen::Vector3d kLo(-0.1, -0.1, -0.1), kHi(0.2, 0.1, 0.1);

void BM_PointValueAndGradient_50Nodes(benchmark::State& state) {
  const ImplicitNode tree = FiftyNodeTree();
  const CompiledSolid solid = CompiledSolid::Compile(tree);
  const auto points = RandomPoints(1024, kLo, kHi);
  size_t i = 0;
  Eigen::Vector3d g;
  for (auto _ : state) {
    benchmark::DoNotOptimize(solid.ValueAndGradient(points[i++ & 1023], &g));
    benchmark::DoNotOptimize(g);
  }
  state.counters["nodes"] = CountNodes(tree);
  state.counters["primitives"] = solid.primitive_count();
  state.counters["instructions"] = solid.instruction_count();
  state.counters["queries_per_1ms_tick"] =
      benchmark::Counter(1e-3, benchmark::Counter::kIsIterationInvariantRate);
}
BENCHMARK(BM_PointValueAndGradient_50Nodes);

void BM_PointValue_50Nodes(benchmark::State& state) {
  const CompiledSolid solid = CompiledSolid::Compile(FiftyNodeTree());
  const auto points = RandomPoints(1024, kLo, kHi);
  size_t i = 0;
  for (auto _ : state) benchmark::DoNotOptimize(solid.Value(points[i++ & 1023]));
}
BENCHMARK(BM_PointValue_50Nodes);

// The recursive reference evaluator on the same tree, for comparison.
void BM_PointValueTreeWalk_50Nodes(benchmark::State& state) {
  const ImplicitNode tree = FiftyNodeTree();
  const auto points = RandomPoints(1024, kLo, kHi);
  size_t i = 0;
  for (auto _ : state) benchmark::DoNotOptimize(EvaluateTree(tree, points[i++ & 1023]));
}
BENCHMARK(BM_PointValueTreeWalk_50Nodes);

void BM_BatchValues_50Nodes(benchmark::State& state) {
  const CompiledSolid solid = CompiledSolid::Compile(FiftyNodeTree());
  const int n = static_cast<int>(state.range(0));
  const auto pts = RandomPoints(n, kLo, kHi);
  Eigen::Matrix3Xd points(3, n);
  for (int i = 0; i < n; ++i) points.col(i) = pts[i];
  Eigen::VectorXd values(n);
  for (auto _ : state) {
    solid.Values(points, values);
    benchmark::DoNotOptimize(values.data());
  }
  state.SetItemsProcessed(state.iterations() * n);
}
BENCHMARK(BM_BatchValues_50Nodes)->Arg(4096);

void BM_BatchValuesAndGradients_50Nodes(benchmark::State& state) {
  const CompiledSolid solid = CompiledSolid::Compile(FiftyNodeTree());
  const int n = static_cast<int>(state.range(0));
  const auto pts = RandomPoints(n, kLo, kHi);
  Eigen::Matrix3Xd points(3, n), gradients(3, n);
  for (int i = 0; i < n; ++i) points.col(i) = pts[i];
  Eigen::VectorXd values(n);
  for (auto _ : state) {
    solid.ValuesAndGradients(points, values, gradients);
    benchmark::DoNotOptimize(values.data());
  }
  state.SetItemsProcessed(state.iterations() * n);
}
BENCHMARK(BM_BatchValuesAndGradients_50Nodes)->Arg(4096);

// Interval bounds over boxes of edge state.range(0) mm.
void BM_IntervalBounds_50Nodes(benchmark::State& state) {
  const CompiledSolid solid = CompiledSolid::Compile(FiftyNodeTree());
  const auto points = RandomPoints(1024, kLo, kHi);
  const double edge = state.range(0) * 1e-3;
  size_t i = 0;
  for (auto _ : state) {
    const Eigen::Vector3d& p = points[i++ & 1023];
    benchmark::DoNotOptimize(
        solid.Bounds(Eigen::AlignedBox3d(p, p + Eigen::Vector3d::Constant(edge))));
  }
}
BENCHMARK(BM_IntervalBounds_50Nodes)->Arg(2)->Arg(20);

void BM_Compile_50Nodes(benchmark::State& state) {
  const ImplicitNode tree = FiftyNodeTree();
  for (auto _ : state) benchmark::DoNotOptimize(CompiledSolid::Compile(tree));
}
BENCHMARK(BM_Compile_50Nodes);

ImplicitNode PlatformTree() {
  const Scene scene = LoadScene(spidarcad::bench::RepoPath("assets/scenes/platform.json"));
  return scene.solids.at(0).root;
}
const Eigen::Vector3d kPlatformLo(-0.01, -0.11, -0.16), kPlatformHi(0.31, 0.11, 0.02);

void BM_PlatformValueAndGradient(benchmark::State& state) {
  const ImplicitNode tree = PlatformTree();
  const CompiledSolid solid = CompiledSolid::Compile(tree);
  const auto points = RandomPoints(1024, kPlatformLo, kPlatformHi);
  size_t i = 0;
  Eigen::Vector3d g;
  for (auto _ : state) {
    benchmark::DoNotOptimize(solid.ValueAndGradient(points[i++ & 1023], &g));
    benchmark::DoNotOptimize(g);
  }
  state.counters["nodes"] = CountNodes(tree);
  state.counters["primitives"] = solid.primitive_count();
}
BENCHMARK(BM_PlatformValueAndGradient);

// Counts the cells of edge <= `leaf` that an octree descent over box must evaluate: boxes the
// interval bounds classify as inside or outside are skipped whole.
void Descend(const CompiledSolid& solid, const Eigen::AlignedBox3d& box, double leaf,
             long* ambiguous_leaves, double* skipped_volume) {
  if (solid.Classify(box) != BoxClass::kAmbiguous) {
    *skipped_volume += box.volume();
    return;
  }
  if (box.sizes().maxCoeff() <= leaf * (1 + 1e-9)) {
    ++*ambiguous_leaves;
    return;
  }
  const Eigen::Vector3d c = box.center();
  for (int k = 0; k < 8; ++k) {
    const Eigen::Vector3d corner = box.corner(static_cast<Eigen::AlignedBox3d::CornerType>(k));
    Descend(solid, Eigen::AlignedBox3d(c.cwiseMin(corner), c.cwiseMax(corner)), leaf,
            ambiguous_leaves, skipped_volume);
  }
}

// Octree culling of the platform's bounding box down to 2.5 mm cells (128³ grid).
void BM_PlatformOctreeCulling(benchmark::State& state) {
  const CompiledSolid solid = CompiledSolid::Compile(PlatformTree());
  const Eigen::Vector3d lo(-0.01, -0.12, -0.17);
  const double edge = 0.32;
  const Eigen::AlignedBox3d box(lo, lo + Eigen::Vector3d::Constant(edge));
  const double leaf = edge / 128;
  long ambiguous = 0;
  double skipped = 0;
  for (auto _ : state) {
    ambiguous = 0;
    skipped = 0;
    Descend(solid, box, leaf, &ambiguous, &skipped);
  }
  state.counters["grid_cells"] = 128.0 * 128 * 128;
  state.counters["ambiguous_cells"] = ambiguous;
  state.counters["volume_skipped_pct"] = 100.0 * skipped / box.volume();
}
BENCHMARK(BM_PlatformOctreeCulling)->Unit(benchmark::kMillisecond);

// Surface meshing of the platform at cell size state.range(0) / 10 mm: time, size, and the
// sampled mesh-to-surface error (|value| at vertices, edge midpoints, centroids).
void BM_MeshPlatform(benchmark::State& state) {
  const CompiledSolid solid = CompiledSolid::Compile(PlatformTree());
  SurfaceMeshSettings settings;
  settings.bounds =
      Eigen::AlignedBox3d(Eigen::Vector3d(-0.01, -0.11, -0.16), Eigen::Vector3d(0.31, 0.11, 0.02));
  settings.cell_size = state.range(0) * 1e-4;
  TriangleMesh mesh;
  SurfaceMeshStats stats;
  for (auto _ : state) mesh = MeshSurface(solid, settings, &stats);
  const SurfaceError error = MeasureSurfaceError(solid, mesh);
  state.counters["cell_mm"] = settings.cell_size * 1e3;
  state.counters["triangles"] = static_cast<double>(mesh.triangles.cols());
  state.counters["evaluated_cells_pct"] = 100.0 * stats.evaluated_cells / stats.grid_cells;
  state.counters["err_max_mm"] = error.max * 1e3;
  state.counters["err_rms_mm"] = error.rms * 1e3;
}
BENCHMARK(BM_MeshPlatform)->Arg(40)->Arg(20)->Arg(10)->Unit(benchmark::kMillisecond);

// A 5 cm sphere meshed at cell size r / state.range(0): error against the exact surface.
void BM_MeshSphere(benchmark::State& state) {
  const double r = 0.05;
  const CompiledSolid solid = CompiledSolid::Compile(ImplicitNode(SphereParams{r}));
  SurfaceMeshSettings settings;
  settings.bounds =
      Eigen::AlignedBox3d(Eigen::Vector3d::Constant(-0.06), Eigen::Vector3d::Constant(0.06));
  settings.cell_size = r / state.range(0);
  TriangleMesh mesh;
  for (auto _ : state) mesh = MeshSurface(solid, settings);
  const SurfaceError error = MeasureSurfaceError(solid, mesh);
  const double exact = 4.0 / 3.0 * M_PI * r * r * r;
  state.counters["triangles"] = static_cast<double>(mesh.triangles.cols());
  state.counters["err_max_mm"] = error.max * 1e3;
  state.counters["volume_err_pct"] = 100.0 * (MeshVolume(mesh) - exact) / exact;
}
BENCHMARK(BM_MeshSphere)->Arg(10)->Arg(20)->Arg(40)->Unit(benchmark::kMillisecond);

// Per-cell pruned tapes (CompiledSolid::Specialize, CellSpecializedSolid) on the assembly's
// torso, "a box less five cylinders" (assets/scenes/assembly.json, solid "body", frame of the
// part): value and gradient at points around the bottom right hole where a leg's peg sits.
// Arg 0: the full tape; 1: the grid of 5 mm cells; 2: one tape specialized for the whole query box.
std::shared_ptr<const CompiledSolid> TorsoSolid() {
  const Scene scene = LoadScene(spidarcad::bench::RepoPath("assets/scenes/assembly.json"));
  for (const Solid& s : scene.solids) {
    if (s.name == "body")
      return std::make_shared<const CompiledSolid>(CompiledSolid::Compile(s.root));
  }
  return nullptr;
}
const Eigen::AlignedBox3d kTorsoGrid(Eigen::Vector3d(-0.045, -0.035, -0.05),
                                     Eigen::Vector3d(0.045, 0.035, 0.05));
const Eigen::Vector3d kHoleLo(0.006, -0.006, -0.045), kHoleHi(0.018, 0.006, -0.022);

void BM_TorsoHoleValueAndGradient(benchmark::State& state) {
  const auto torso = TorsoSolid();
  CellSpecializationSettings settings;
  settings.cell_size = 0.005;
  const CellSpecializedSolid cells(torso, kTorsoGrid, settings);
  const CompiledSolid one = torso->Specialize(Eigen::AlignedBox3d(kHoleLo, kHoleHi));
  const auto points = RandomPoints(1024, kHoleLo, kHoleHi);
  size_t i = 0;
  Eigen::Vector3d g;
  const int mode = static_cast<int>(state.range(0));
  for (auto _ : state) {
    const Eigen::Vector3d& p = points[i++ & 1023];
    if (mode == 0) {
      benchmark::DoNotOptimize(torso->ValueAndGradient(p, &g));
    } else if (mode == 1) {
      benchmark::DoNotOptimize(cells.ValueAndGradient(p, &g));
    } else {
      benchmark::DoNotOptimize(one.ValueAndGradient(p, &g));
    }
    benchmark::DoNotOptimize(g);
  }
  double instructions = 0;
  for (const Eigen::Vector3d& p : points) {
    instructions += mode == 0   ? torso->instruction_count()
                    : mode == 1 ? cells.TapeAt(p).instruction_count()
                                : one.instruction_count();
  }
  state.counters["mean_instructions"] = instructions / points.size();
}
BENCHMARK(BM_TorsoHoleValueAndGradient)->Arg(0)->Arg(1)->Arg(2);

// Build time of the torso's grid (state.range(0) / 10 mm cells) and its figures.
void BM_TorsoCellBuild(benchmark::State& state) {
  const auto torso = TorsoSolid();
  CellSpecializationSettings settings;
  settings.cell_size = state.range(0) * 1e-4;
  CellSpecializationStats stats;
  for (auto _ : state) stats = CellSpecializedSolid(torso, kTorsoGrid, settings).stats();
  state.counters["cells"] = stats.cells;
  state.counters["specialized_cells"] = stats.specialized_cells;
  state.counters["distinct_tapes"] = stats.distinct_tapes;
  state.counters["mean_instructions"] = stats.mean_instructions;
  state.counters["full_instructions"] = stats.full_instructions;
}
BENCHMARK(BM_TorsoCellBuild)->Arg(100)->Arg(50)->Arg(25)->Unit(benchmark::kMillisecond);

// The platform through a grid of 20, 10 or 5 mm cells over its bounds: build time, and value and
// gradient at random points of the box as BM_PlatformValueAndGradient.
void BM_PlatformCellsValueAndGradient(benchmark::State& state) {
  const auto solid = std::make_shared<const CompiledSolid>(CompiledSolid::Compile(PlatformTree()));
  CellSpecializationSettings settings;
  settings.cell_size = state.range(0) * 1e-4;  // arg: cell edge in 0.1 mm
  const CellSpecializedSolid cells(solid, Eigen::AlignedBox3d(kPlatformLo, kPlatformHi), settings);
  const auto points = RandomPoints(1024, kPlatformLo, kPlatformHi);
  size_t i = 0;
  Eigen::Vector3d g;
  for (auto _ : state) {
    benchmark::DoNotOptimize(cells.ValueAndGradient(points[i++ & 1023], &g));
    benchmark::DoNotOptimize(g);
  }
  state.counters["build_ms"] = cells.stats().build_seconds * 1e3;
  state.counters["cells"] = cells.stats().cells;
  state.counters["mean_instructions"] = cells.stats().mean_instructions;
  state.counters["full_instructions"] = cells.stats().full_instructions;
}
BENCHMARK(BM_PlatformCellsValueAndGradient)->Arg(200)->Arg(100)->Arg(50);

// n points (as many as a six-DOF shell has: 196 or 2004) in a 10 cm cube on the platform's plate,
// value and gradient of each per iteration: arg 0 the mode (0 point by point on the full tape,
// 1 ValuesAndGradients on the full tape (several points per pass), 2 point by point through
// 10 mm cells, 3 ValueAndGradientBatch through the cells), arg 1 n. items_per_second: points per
// second.
void BM_PlatformShellPoints(benchmark::State& state) {
  const auto solid = std::make_shared<const CompiledSolid>(CompiledSolid::Compile(PlatformTree()));
  CellSpecializationSettings settings;
  settings.cell_size = 0.01;
  const CellSpecializedSolid cells(solid, Eigen::AlignedBox3d(kPlatformLo, kPlatformHi), settings);
  const int mode = static_cast<int>(state.range(0)), n = static_cast<int>(state.range(1));
  const auto points =
      RandomPoints(n, Eigen::Vector3d(0.1, -0.05, -0.04), Eigen::Vector3d(0.2, 0.05, 0.06));
  std::vector<double> x(n), y(n), z(n), v(n), gx(n), gy(n), gz(n);
  Eigen::Matrix3Xd matrix(3, n), gradients(3, n);
  Eigen::VectorXd values(n);
  for (int i = 0; i < n; ++i) {
    matrix.col(i) = points[i];
    x[i] = points[i].x();
    y[i] = points[i].y();
    z[i] = points[i].z();
  }
  for (auto _ : state) {
    if (mode == 0 || mode == 2) {
      Eigen::Vector3d g;
      for (int i = 0; i < n; ++i) {
        v[i] = mode == 0 ? solid->ValueAndGradient(points[i], &g)
                         : cells.ValueAndGradient(points[i], &g);
        gx[i] = g.x();
        gy[i] = g.y();
        gz[i] = g.z();
      }
    } else if (mode == 1) {
      solid->ValuesAndGradients(matrix, values, gradients);
    } else {
      cells.ValueAndGradientBatch(x.data(), y.data(), z.data(), n, v.data(), gx.data(), gy.data(),
                                  gz.data());
    }
    benchmark::DoNotOptimize(v.data());
    benchmark::DoNotOptimize(gx.data());
    benchmark::ClobberMemory();
  }
  state.SetItemsProcessed(state.iterations() * n);  // points per second
}
BENCHMARK(BM_PlatformShellPoints)
    ->ArgsProduct({{0, 1, 2, 3}, {196, 2004}})
    ->Unit(benchmark::kMicrosecond);

}  // namespace

// What this program measures (its --help).
constexpr const char* kBenchDescription =
    "Speed of the compiled implicit evaluator: point queries with gradient (the haptic proxy's\n"
    "per-tick cost), batch throughput, interval bounds per box, octree culling, and the platform\n"
    "scene. Run from anywhere: build-dir/bench/implicit_bench (bench_paths.h finds the scene).";

int main(int argc, char** argv) {
  return spidarcad::bench::RunBenchmarkMain(argc, argv, kBenchDescription);
}
