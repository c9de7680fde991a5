// Sculpting speed on a ~200k-vertex mesh (the clay blob of assets/scenes/clay.json meshed at a
// fine cell): one stroke step (UpdateStroke) per tool at radius 1 cm and 3 cm with volume
// conservation off and on (time, vertices touched, volume error), a 60-step stroke end to end
// (begin, 60 updates, end with refinement; undone outside the timing), and building the
// SculptMesh. A display at 60 Hz leaves 16.7 ms per frame for everything. BM_SphereGrab: the
// report's workload, a grab on a 163842-vertex icosphere, with and without the self-intersection
// check (args: radius mm, check 0/1).
// Run: build/bench/modeling_sculpt_bench  (SPIDARCAD_SCULPT_CELL=0.00104 sets the cell, m)
// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#include <benchmark/benchmark.h>

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <memory>
#include <numbers>
#include <string>

#include "bench_cli.h"
#include "bench_paths.h"
#include "spidarcad/modeling/implicit_evaluator.h"
#include "spidarcad/modeling/scene_io.h"
#include "spidarcad/modeling/sculpt.h"
#include "spidarcad/modeling/surface_mesher.h"
#include "spidarcad/workloads/sculpt.h"

namespace spidarcad::modeling {
namespace {

// The clay blob meshed once (cell from SPIDARCAD_SCULPT_CELL, default 1.04 mm: about 200k
// vertices).
const TriangleMesh& Blob() {
  static const TriangleMesh mesh = [] {
    const char* cell_env = std::getenv("SPIDARCAD_SCULPT_CELL");
    const double cell = cell_env != nullptr ? std::atof(cell_env) : 0.00104;
    const std::string path = spidarcad::bench::RepoPath("assets/scenes/clay.json");
    const Scene scene = LoadScene(path);
    const CompiledSolid solid = CompiledSolid::Compile(scene.solids.at(0).root);
    SurfaceMeshSettings settings;
    settings.bounds =
        Eigen::AlignedBox3d(Eigen::Vector3d::Constant(-0.15), Eigen::Vector3d::Constant(0.15));
    settings.cell_size = cell;
    SurfaceMeshStats stats;
    TriangleMesh result = MeshSurface(solid, settings, &stats);
    std::fprintf(stderr,
                 "clay blob at cell %.4f m: %ld vertices, %ld triangles (meshed in %.1f s)\n", cell,
                 static_cast<long>(result.vertices.cols()),
                 static_cast<long>(result.triangles.cols()), stats.seconds);
    return result;
  }();
  return mesh;
}

SculptMesh& Sculpt() {
  static SculptMesh sculpt(Blob(), 0.005);
  return sculpt;
}

// The grab point: the vertex with the largest z (top of the blob), and a grip frame with z
// along its normal.
Eigen::Isometry3d StartPose(const SculptMesh& sculpt) {
  int top = 0;
  for (int v = 0; v < sculpt.vertex_count(); ++v) {
    if (sculpt.positions()[v].z() > sculpt.positions()[top].z()) top = v;
  }
  Eigen::Isometry3d X = Eigen::Isometry3d::Identity();
  X.linear() = Eigen::Quaterniond::FromTwoVectors(Eigen::Vector3d::UnitZ(), sculpt.normals()[top])
                   .toRotationMatrix();
  X.translation() = sculpt.positions()[top];
  return X;
}

SculptToolSettings Settings(SculptTool tool, double radius, bool conserve, bool check = true) {
  SculptToolSettings s;
  s.tool = tool;
  s.radius = radius;
  s.grasp_controls_strength = false;
  s.conserve_volume = conserve;
  s.prevent_self_intersection = check;
  return s;
}

// One UpdateStroke; args: tool, radius (mm), conserve (0/1), self-intersection check (0/1).
void BM_StrokeStep(benchmark::State& state) {
  const auto tool = static_cast<SculptTool>(state.range(0));
  const double radius = state.range(1) * 1e-3;
  const bool conserve = state.range(2) != 0;
  const bool check = state.range(3) != 0;
  SculptMesh& sculpt = Sculpt();
  const Eigen::Isometry3d X0 = StartPose(sculpt);
  const Eigen::Isometry3d full = workloads::SculptTargetPose(tool, X0, radius, 1.0),
                          half = workloads::SculptTargetPose(tool, X0, radius, 0.5);
  sculpt.BeginStroke(Settings(tool, radius, conserve, check), X0, 0.0);
  long i = 0;
  for (auto _ : state) {
    sculpt.UpdateStroke((i++ & 1) ? half : full, 0.0);
    benchmark::ClobberMemory();
  }
  sculpt.UpdateStroke(full, 0.0);
  const StrokeStats stats = sculpt.stroke_stats();
  state.counters["touched"] = stats.affected_vertices;
  state.counters["normals"] = stats.normal_updates;
  state.counters["vol_err_pct"] =
      100.0 * std::abs(sculpt.ComputeVolume() / stats.start_volume - 1.0);
  state.counters["newton"] = stats.volume_iterations;
  state.counters["limit"] = stats.limit;
  state.counters["checks"] = stats.intersection_checks;
  state.SetLabel(std::string(SculptToolName(tool)) + (conserve ? " conserve" : "") +
                 (check ? " checked" : ""));
  sculpt.CancelStroke();
}

void StepArgs(benchmark::internal::Benchmark* b) {
  for (int tool = 0; tool < 5; ++tool) {
    for (int radius : {10, 30}) {
      for (int conserve : {0, 1}) {
        for (int check : {0, 1}) b->Args({tool, radius, conserve, check});
      }
    }
  }
}
BENCHMARK(BM_StrokeStep)->Apply(StepArgs)->Unit(benchmark::kMicrosecond);

// The report's sculpting workload (app/src/cli/report_sculpt.cc): a grab at the top of an
// icosphere of radius 10 cm with 7 subdivisions (163842 vertices), one UpdateStroke alternating
// between half and full stroke. args: radius (mm), self-intersection check (0/1).
void BM_SphereGrab(benchmark::State& state) {
  static SculptMesh sculpt(IcosphereMesh(0.1, 7), 0.005);
  const double radius = state.range(0) * 1e-3;
  const bool check = state.range(1) != 0;
  const Eigen::Isometry3d X0 = StartPose(sculpt);
  const Eigen::Isometry3d full = workloads::SculptTargetPose(SculptTool::kGrab, X0, radius, 1.0),
                          half = workloads::SculptTargetPose(SculptTool::kGrab, X0, radius, 0.5);
  sculpt.BeginStroke(Settings(SculptTool::kGrab, radius, false, check), X0, 0.0);
  long i = 0;
  for (auto _ : state) {
    sculpt.UpdateStroke((i++ & 1) ? half : full, 0.0);
    benchmark::ClobberMemory();
  }
  const StrokeStats stats = sculpt.stroke_stats();
  state.counters["touched"] = stats.affected_vertices;
  state.counters["limit"] = stats.limit;
  state.SetLabel(check ? "grab checked" : "grab");
  sculpt.CancelStroke();
}
BENCHMARK(BM_SphereGrab)->ArgsProduct({{5, 10, 20, 60}, {0, 1}})->Unit(benchmark::kMicrosecond);

// A 60-step stroke end to end: BeginStroke, 60 UpdateStroke along the path, EndStroke with
// refinement (edges above 2 mm split). Undo runs outside the timing. args: tool, radius (mm).
void BM_Stroke60(benchmark::State& state) {
  const auto tool = static_cast<SculptTool>(state.range(0));
  const double radius = state.range(1) * 1e-3;
  SculptMesh& sculpt = Sculpt();
  const Eigen::Isometry3d X0 = StartPose(sculpt);
  SculptToolSettings settings = Settings(tool, radius, true);
  settings.max_edge_length = 0.002;
  long splits = 0;
  for (auto _ : state) {
    sculpt.BeginStroke(settings, X0, 0.0);
    for (int step = 1; step <= 60; ++step)
      sculpt.UpdateStroke(workloads::SculptTargetPose(tool, X0, radius, step / 60.0), 0.0);
    const SculptEdit edit = sculpt.EndStroke();
    state.PauseTiming();
    splits = edit.splits;
    sculpt.Undo(edit);
    state.ResumeTiming();
  }
  state.counters["splits"] = static_cast<double>(splits);
  state.SetLabel(SculptToolName(tool));
}
BENCHMARK(BM_Stroke60)->ArgsProduct({{0, 1, 2, 3, 4}, {10, 30}})->Unit(benchmark::kMillisecond);

// Building a SculptMesh (adjacency, closedness check, normals, grid) from the blob.
void BM_Build(benchmark::State& state) {
  const TriangleMesh& mesh = Blob();
  for (auto _ : state) {
    SculptMesh sculpt(mesh, 0.005);
    benchmark::DoNotOptimize(sculpt.volume());
  }
  state.counters["vertices"] = static_cast<double>(mesh.vertices.cols());
}
BENCHMARK(BM_Build)->Unit(benchmark::kMillisecond)->Iterations(3);

// Back to a TriangleMesh (for TetGen, saving, or the renderer's full upload).
void BM_ToTriangleMesh(benchmark::State& state) {
  for (auto _ : state) benchmark::DoNotOptimize(Sculpt().ToTriangleMesh().vertices.data());
}
BENCHMARK(BM_ToTriangleMesh)->Unit(benchmark::kMillisecond);

}  // namespace
}  // namespace spidarcad::modeling

// What this program measures (its --help).
constexpr const char* kBenchDescription =
    "Sculpting speed on a ~200k-vertex mesh (the clay blob of assets/scenes/clay.json meshed at a\n"
    "fine cell): one stroke step (UpdateStroke) per tool at radius 1 cm and 3 cm with volume\n"
    "conservation off and on (time, vertices touched, volume error), a 60-step stroke end to end\n"
    "(begin, 60 updates, end with refinement; undone outside the timing), and building the\n"
    "SculptMesh. A display at 60 Hz leaves 16.7 ms per frame for everything.\n"
    "BM_SphereGrab: the report's workload, a grab on a 163842-vertex icosphere, with and without\n"
    "the self-intersection check (args: radius mm, check 0/1).\n"
    "Run: build/bench/modeling_sculpt_bench  (SPIDARCAD_SCULPT_CELL=0.00104 sets the cell, m)";

int main(int argc, char** argv) {
  return spidarcad::bench::RunBenchmarkMain(argc, argv, kBenchDescription);
}
