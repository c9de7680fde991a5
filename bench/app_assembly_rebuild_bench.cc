// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
// What assembly mode pays on the main thread when the document's rigid parts change
// (AssemblyMode::SyncDocument -> BuildAssemblyField): the toy robot of assets/scenes/assembly.json
// as rigid parts (6 parts, 4 distinct trees), built
//   BM_AssemblyFullBuild       from nothing (open, or a cache miss on every tree),
//   BM_AssemblyPoseRebuild     after an undo of a move: every tree from the geometry cache,
//   BM_AssemblyOneTreeEdited   after an edit of the head's peg radius: one tree compiled and
//                              sampled again, three from the cache.
// Display meshing (MeshPartSolid, once per new tree) is not included.
#include <benchmark/benchmark.h>

#include <variant>

#include "bench_cli.h"
#include "bench_paths.h"
#include "doc/command.h"
#include "doc/document.h"
#include "scene/assembly_scene.h"

namespace {

using spidarcad::app::AssemblyGeometryCache;
using spidarcad::app::AssemblySceneSettings;
using spidarcad::app::Document;

void LoadRobot(Document* doc) {
  doc->Load(spidarcad::bench::RepoPath("assets/scenes/assembly.json"));
  spidarcad::app::AdoptScenePartsAsRigidParts(doc);
}

void BM_AssemblyFullBuild(benchmark::State& state) {
  Document doc;
  LoadRobot(&doc);
  for (auto _ : state) {
    AssemblyGeometryCache cache;
    benchmark::DoNotOptimize(spidarcad::app::BuildAssemblyField(
        spidarcad::app::RigidPartInputs(doc, nullptr), AssemblySceneSettings{}, &cache));
  }
}
BENCHMARK(BM_AssemblyFullBuild)->Unit(benchmark::kMillisecond);

void BM_AssemblyPoseRebuild(benchmark::State& state) {
  Document doc;
  LoadRobot(&doc);
  AssemblyGeometryCache cache;
  spidarcad::app::BuildAssemblyField(spidarcad::app::RigidPartInputs(doc, nullptr),
                                     AssemblySceneSettings{}, &cache);
  for (auto _ : state) {
    benchmark::DoNotOptimize(spidarcad::app::BuildAssemblyField(
        spidarcad::app::RigidPartInputs(doc, nullptr), AssemblySceneSettings{}, &cache));
  }
  state.counters["compiled"] = cache.compiled_last();
}
BENCHMARK(BM_AssemblyPoseRebuild)->Unit(benchmark::kMillisecond);

void BM_AssemblyOneTreeEdited(benchmark::State& state) {
  Document doc;
  LoadRobot(&doc);
  const spidarcad::app::ObjectId head = doc.objects()[1].id;
  AssemblyGeometryCache cache;
  spidarcad::app::BuildAssemblyField(spidarcad::app::RigidPartInputs(doc, nullptr),
                                     AssemblySceneSettings{}, &cache);
  int k = 0;
  for (auto _ : state) {
    state.PauseTiming();
    // Alternating radii, each new to the cache (it keeps the trees of the latest build only).
    doc.Execute(
        spidarcad::app::edit::SetNodeField(head, {1, 0}, "radius", (k++ % 2) ? 0.0040 : 0.0035));
    state.ResumeTiming();
    benchmark::DoNotOptimize(spidarcad::app::BuildAssemblyField(
        spidarcad::app::RigidPartInputs(doc, nullptr), AssemblySceneSettings{}, &cache));
  }
  state.counters["compiled"] = cache.compiled_last();
}
BENCHMARK(BM_AssemblyOneTreeEdited)->Unit(benchmark::kMillisecond);

constexpr char kBenchDescription[] =
    "Assembly mode's field rebuild on the main thread for the toy robot (6 rigid parts, 4 trees):\n"
    "from nothing, after a pose change (every tree cached) and after an edit of one tree.";

}  // namespace

int main(int argc, char** argv) {
  return spidarcad::bench::RunBenchmarkMain(argc, argv, kBenchDescription);
}
