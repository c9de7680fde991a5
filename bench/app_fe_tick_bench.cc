// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
//
// Haptic tick of FE mode: FeTouchField::Evaluate (contact search, contact set update, active
// set, frictionless solve on the lazy columns, triple-buffer publish) without the HapticLoop,
// on assets/scenes/platform.json meshed by TetGen (linear tets, steel, clamped at the wall),
// at k = 1, 4, 16 contact nodes (max_contacts = k, the tool pushed until k nodes carry load).
//   BM_FeTick/cell_mm/k/frictionless   per-call thread CPU time over 2000 calls of a tool held
//   still
//                                      in contact (columns ready), as p50 / p99 / max in µs,
//                                      the mean k reached, tets.
//   BM_FeGrabTick/n   FeGrabField::Evaluate holding an n-node patch (4, 16, 64), p50 / p99.9 / max
//                     µs over 20000 ticks, and the grab tick's factorisation, ms.
// A markdown table is printed after the run. Scene: $SPIDARCAD_PLATFORM_SCENE, else the source
// tree's assets/scenes/platform.json.
// Run: build/bench/app_fe_tick_bench
#include <benchmark/benchmark.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <ctime>
#include <map>
#include <memory>
#include <tuple>
#include <vector>

#include "bench_cli.h"
#include "scene/fe_grab_field.h"
#include "scene/fe_model.h"
#include "scene/fe_part.h"
#include "scene/fe_touch_field.h"

namespace spidarcad::app {
namespace {

// CPU time of this thread, s (the machine is shared: wall time would count others' work).
double ThreadCpuSeconds() {
  timespec ts{};
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
  return ts.tv_sec + 1e-9 * ts.tv_nsec;
}

struct Part {
  std::shared_ptr<FeModel> model;
  double mesh_seconds = 0.0;
};

Part& GetPart(int cell_mm) {
  static std::map<int, std::unique_ptr<Part>> parts;
  auto& slot = parts[cell_mm];
  if (slot) return *slot;
  slot = std::make_unique<Part>();
  const auto t0 = std::chrono::steady_clock::now();
  fem::TetMesh mesh = MeshSceneSolidForFe(PlatformScenePath(), "platform", 1e-3 * cell_mm);
  slot->mesh_seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  FeModelSettings s;
  s.use_disk_cache = false;
  slot->model = FeModel::Build(std::move(mesh), s);
  return *slot;
}

struct Row {
  int tets = 0;
  double mean_k = 0, p50 = 0, p99 = 0, max = 0, build_s = 0;
};
std::map<std::tuple<int, int, int>, Row>& Rows() {
  static std::map<std::tuple<int, int, int>, Row> rows;
  return rows;
}

void BM_FeTick(benchmark::State& state) {
  const int cell_mm = static_cast<int>(state.range(0)), k = static_cast<int>(state.range(1));
  const bool frictionless = state.range(2) != 0;
  Part& part = GetPart(cell_mm);
  FeModel& model = *part.model;
  FeTouchSettings ts;
  ts.tool_radius = 3.0 * model.mean_edge_length();
  ts.max_contacts = k;
  ts.frictionless = frictionless;
  ts.focus_radius = 1.2 * ts.tool_radius;
  FeTouchField field(part.model, ts, std::make_shared<FeContactChannel>());
  // Push the plate top near the wall deeper until k nodes carry load.
  haptics::ToolKinematics tool;
  const double r = ts.tool_radius;
  for (double depth = 0.05; depth < 0.95; depth += 0.05) {
    tool.p_WT = Eigen::Vector3d(0.05, 0.01, 0.010 + r * (1.0 - depth));
    field.Evaluate(tool);
    model.cache().WaitUntilIdle(120.0);
    field.Evaluate(tool);
    if (field.last_state().num_contacts >= k) break;
  }
  std::vector<double> us;
  us.reserve(2000);
  long k_sum = 0;
  for (auto _ : state) {
    us.clear();
    k_sum = 0;
    for (int i = 0; i < 2000; ++i) {
      tool.time = 1e-3 * i;
      const double t0 = ThreadCpuSeconds();
      const haptics::ToolWrench w = field.Evaluate(tool);
      us.push_back(1e6 * (ThreadCpuSeconds() - t0));
      benchmark::DoNotOptimize(w);
      k_sum += field.last_state().num_contacts;
    }
  }
  std::sort(us.begin(), us.end());
  Row& row = Rows()[{cell_mm, k, frictionless ? 1 : 0}];
  row.tets = model.mesh().num_elements();
  row.mean_k = k_sum / 2000.0;
  row.p50 = us[us.size() / 2];
  row.p99 = us[us.size() * 99 / 100];
  row.max = us.back();
  row.build_s = part.mesh_seconds + model.build_seconds();
  state.counters["tets"] = row.tets;
  state.counters["mean_k"] = row.mean_k;
  state.counters["p50_us"] = row.p50;
  state.counters["p99_us"] = row.p99;
  state.counters["max_us"] = row.max;
}

void Args(benchmark::internal::Benchmark* b) {
  for (int cell : {12, 6}) {
    for (int k : {1, 4, 16}) b->Args({cell, k, 1});
    b->Args({cell, 16, 0});
  }
}
BENCHMARK(BM_FeTick)->Apply(Args)->Iterations(1)->Unit(benchmark::kMillisecond);

struct GrabRow {
  int tets = 0, nodes = 0;
  double factor_ms = 0, p50 = 0, p999 = 0, max = 0;
};
std::map<int, GrabRow>& GrabRows() {
  static std::map<int, GrabRow> rows;
  return rows;
}

// FeGrabField's held tick: the platform's free end grabbed (n nodes, FE mode's default grab
// settings: coupled, felt at 1e-4), the grip moving and twisting every tick.
void BM_FeGrabTick(benchmark::State& state) {
  const int n = static_cast<int>(state.range(0));
  Part& part = GetPart(12);
  FeModel& model = *part.model;
  FeGrabSettings gs = ResolvedGrabSettings(model, DefaultFeGrabSettings(), 1.0);
  gs.tool_radius = 0.06;  // wide enough for 64 surface nodes; max_patch picks the n nearest
  gs.max_patch = n;
  gs.worker = false;  // the grab tick factors (timed apart: the window's worker does it)
  FeGrabField field(part.model, gs, std::make_shared<FeGrabChannel>());
  const Eigen::Vector3d p0(0.29, 0.0, 0.005);
  model.cache().RequestNear(p0, gs.tool_radius);
  model.cache().WaitUntilIdle(300.0);
  haptics::ToolKinematics tool;
  tool.p_WT = p0;
  field.Evaluate(tool);
  tool.grasp = 1.0;
  tool.time = 1e-3;
  const double f0 = ThreadCpuSeconds();
  field.Evaluate(tool);  // the grab: factor Ĝ_gg and the coupling
  const double factor_s = ThreadCpuSeconds() - f0;
  constexpr int kTicks = 20000;
  std::vector<double> us;
  us.reserve(kTicks);
  for (auto _ : state) {
    us.clear();
    for (int i = 0; i < kTicks; ++i) {
      const double a = 1e-3 * i;
      tool.time = 2e-3 + a;
      tool.p_WT = p0 + 1e-3 * Eigen::Vector3d(std::sin(a), std::cos(3 * a) - 1.0, std::sin(2 * a));
      tool.R_WT = Eigen::AngleAxisd(0.2 * std::sin(a), Eigen::Vector3d::UnitX()).toRotationMatrix();
      const double t0 = ThreadCpuSeconds();
      const haptics::ToolWrench w = field.Evaluate(tool);
      us.push_back(1e6 * (ThreadCpuSeconds() - t0));
      benchmark::DoNotOptimize(w);
    }
  }
  std::sort(us.begin(), us.end());
  GrabRow& row = GrabRows()[n];
  row.tets = model.mesh().num_elements();
  row.nodes = field.last_state().ready ? field.last_state().num_nodes : 0;
  row.factor_ms = 1e3 * factor_s;
  row.p50 = us[us.size() / 2];
  row.p999 = us[us.size() * 999 / 1000];
  row.max = us.back();
  state.counters["nodes"] = row.nodes;
  state.counters["factor_ms"] = row.factor_ms;
  state.counters["p50_us"] = row.p50;
  state.counters["p999_us"] = row.p999;
  state.counters["max_us"] = row.max;
}
BENCHMARK(BM_FeGrabTick)->Arg(4)->Arg(16)->Arg(64)->Iterations(1)->Unit(benchmark::kMillisecond);

void PrintTable() {
  std::printf(
      "\n| cell | tets | contact | k asked | mean k | p50 µs | p99 µs | max µs | mesh + precompute "
      "s |\n");
  std::printf("|---|---|---|---|---|---|---|---|---|\n");
  for (const auto& [key, row] : Rows())
    std::printf("| %d mm | %d | %s | %d | %.1f | %.1f | %.1f | %.1f | %.1f |\n", std::get<0>(key),
                row.tets, std::get<2>(key) ? "frictionless" : "sticking", std::get<1>(key),
                row.mean_k, row.p50, row.p99, row.max, row.build_s);
  if (GrabRows().empty()) return;
  std::printf("\n| grab | tets | nodes | factor (grab tick) ms | p50 µs | p99.9 µs | max µs |\n");
  std::printf("|---|---|---|---|---|---|---|\n");
  for (const auto& [n, row] : GrabRows())
    std::printf("| %d asked | %d | %d | %.2f | %.1f | %.1f | %.1f |\n", n, row.tets, row.nodes,
                row.factor_ms, row.p50, row.p999, row.max);
}

}  // namespace
}  // namespace spidarcad::app

// What this program measures (its --help).
constexpr const char* kBenchDescription =
    "Haptic tick of FE mode: FeTouchField::Evaluate (contact search, contact set update, active\n"
    "set, frictionless solve on the lazy columns, triple-buffer publish) without the HapticLoop,\n"
    "on assets/scenes/platform.json meshed by TetGen (linear tets, steel, clamped at the wall),\n"
    "at k = 1, 4, 16 contact nodes (max_contacts = k, the tool pushed until k nodes carry load).\n"
    "  BM_FeTick/cell_mm/k/frictionless   per-call thread CPU time over 2000 calls of a tool held "
    "still\n"
    "                                     in contact (columns ready), as p50 / p99 / max in µs,\n"
    "                                     the mean k reached, tets.\n"
    "  BM_FeGrabTick/n   FeGrabField::Evaluate holding an n-node patch of the plate's free end\n"
    "                    (n = 4, 16, 64; 12 mm cells; FE mode's coupled grab settings) while the\n"
    "                    grip moves and twists: thread CPU time over 20000 ticks as p50 / p99.9 /\n"
    "                    max in µs, and the grab tick's factorisation of the patch (ms; the\n"
    "                    window does it on the field's worker, off the tick).\n"
    "A markdown table is printed after the run. Scene: $SPIDARCAD_PLATFORM_SCENE, else the source\n"
    "tree's assets/scenes/platform.json.\n"
    "Run: build/bench/app_fe_tick_bench";

// Tables printed after the benchmarks.
void PrintAfterRun() { spidarcad::app::PrintTable(); }

int main(int argc, char** argv) {
  return spidarcad::bench::RunBenchmarkMain(argc, argv, kBenchDescription, nullptr, PrintAfterRun);
}
