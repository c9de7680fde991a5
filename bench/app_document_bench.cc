// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
// Save and open times of a document file (doc/document_io.h) holding a 200k-vertex sculpt and a
// 100k-tet FE model (with its tet mesh), plus a solid. Counters: file size (MB).
//   build/bench/app_document_bench
#include <benchmark/benchmark.h>

#include <cmath>
#include <filesystem>
#include <numbers>
#include <string>

#include "bench_cli.h"
#include "doc/command.h"
#include "doc/document.h"

namespace spidarcad::app {
namespace {

namespace fs = std::filesystem;

// A UV sphere of radius 0.1 m with rings x segments vertices (no poles: an open tube closed enough
// for timing).
SculptMesh UvSphere(int rings, int segments) {
  SculptMesh m;
  m.vertices.resize(3, rings * segments);
  for (int r = 0; r < rings; ++r) {
    const double theta = std::numbers::pi * (r + 0.5) / rings;
    for (int s = 0; s < segments; ++s) {
      const double phi = 2 * std::numbers::pi * s / segments;
      m.vertices.col(r * segments + s) =
          0.1 * Eigen::Vector3d(std::sin(theta) * std::cos(phi), std::sin(theta) * std::sin(phi),
                                std::cos(theta));
    }
  }
  m.triangles.resize(3, 2 * (rings - 1) * segments);
  int t = 0;
  for (int r = 0; r + 1 < rings; ++r) {
    for (int s = 0; s < segments; ++s) {
      const int a = r * segments + s, b = r * segments + (s + 1) % segments;
      const int c = a + segments, d = b + segments;
      m.triangles.col(t++) = Eigen::Vector3i(a, c, b);
      m.triangles.col(t++) = Eigen::Vector3i(b, c, d);
    }
  }
  return m;
}

// n^3 cubes of a 0.3 m block, six tets each.
modeling::TetMesh GridTets(int n) {
  modeling::TetMesh m;
  const int p = n + 1;
  m.nodes.resize(3, p * p * p);
  auto id = [p](int i, int j, int k) { return (k * p + j) * p + i; };
  for (int k = 0; k < p; ++k)
    for (int j = 0; j < p; ++j)
      for (int i = 0; i < p; ++i) m.nodes.col(id(i, j, k)) = 0.3 / n * Eigen::Vector3d(i, j, k);
  m.tets.resize(4, 6 * n * n * n);
  int t = 0;
  for (int k = 0; k < n; ++k)
    for (int j = 0; j < n; ++j)
      for (int i = 0; i < n; ++i) {
        const int v0 = id(i, j, k), v1 = id(i + 1, j, k), v2 = id(i, j + 1, k),
                  v3 = id(i + 1, j + 1, k);
        const int v4 = id(i, j, k + 1), v5 = id(i + 1, j, k + 1), v6 = id(i, j + 1, k + 1),
                  v7 = id(i + 1, j + 1, k + 1);
        // Kuhn subdivision along the diagonal v0-v7.
        const int tets[6][4] = {{v0, v1, v3, v7}, {v0, v3, v2, v7}, {v0, v2, v6, v7},
                                {v0, v6, v4, v7}, {v0, v4, v5, v7}, {v0, v5, v1, v7}};
        for (const auto& q : tets) m.tets.col(t++) = Eigen::Vector4i(q[0], q[1], q[2], q[3]);
      }
  m.regions = Eigen::VectorXi::Zero(m.tets.cols());
  return m;
}

void Fill(Document* doc) {
  doc->Execute(
      edit::AddSolid("ball", modeling::ImplicitNode(modeling::SphereParams{0.05}, {}, "ball")));
  doc->Execute(edit::AddSculpt("clay", UvSphere(400, 500)));  // 200k vertices, 399k triangles
  MeshData mesh;
  mesh.volume =
      std::make_shared<const modeling::TetMesh>(GridTets(26));  // 105 456 tets, 19 683 nodes
  doc->Execute(edit::AddObject("block tets", mesh));
  const ObjectId tets = doc->last_created().at(0);
  doc->Execute(edit::AddFeModel(
      "block FE", tets, fem::Material{2e11, 0.3},
      {Eigen::AlignedBox3d(Eigen::Vector3d::Constant(-1), Eigen::Vector3d(1e-4, 1, 1))}));
}

std::string BenchPath() {
  return (fs::temp_directory_path() / "spidarcad_app_document_bench.json").string();
}

void BM_SaveDocument(benchmark::State& state) {
  Document doc;
  Fill(&doc);
  const std::string path = BenchPath();
  for (auto _ : state) doc.Save(path);
  state.counters["file_MB"] = static_cast<double>(fs::file_size(path)) / 1e6;
}
BENCHMARK(BM_SaveDocument)->Unit(benchmark::kMillisecond)->UseRealTime();

void BM_OpenDocument(benchmark::State& state) {
  {
    Document doc;
    Fill(&doc);
    doc.Save(BenchPath());
  }
  for (auto _ : state) {
    Document doc;
    doc.Load(BenchPath());
    benchmark::DoNotOptimize(doc.objects().size());
  }
  state.counters["file_MB"] = static_cast<double>(fs::file_size(BenchPath())) / 1e6;
}
BENCHMARK(BM_OpenDocument)->Unit(benchmark::kMillisecond)->UseRealTime();

}  // namespace
}  // namespace spidarcad::app

int main(int argc, char** argv) {
  return spidarcad::bench::RunBenchmarkMain(argc, argv,
                                            "app_document_bench: save and open times of a document "
                                            "file (docs/scene-format.md, version 2) holding a\n"
                                            "200k-vertex sculpt, a 105k-tet mesh with its FE model "
                                            "and a solid; file_MB is the file size.");
}
