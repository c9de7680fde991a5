// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
// What sculpt mode adds on the main thread by keeping the clay in the Document
// (scene/sculpt_document.h, gui/sculpt_mode.h), on a 163842-vertex clay (the icosphere with 7
// subdivisions, 0.1 m radius):
//  - BM_RecordStroke: a finished grab stroke (radius 20 mm, lifted 2 mm) recorded as one
//    SculptStroke command (MakeStrokeCommand + Document::Execute), at the stroke's end;
//  - BM_RecordRefinedStroke: the same for a stroke lifted 10 mm whose refinement split edges over
//    1.2 mm: the whole mesh recorded (ReplaceSculptMesh);
//  - BM_UndoInPlace: Ctrl+Z / Ctrl+Y of the mode's own last stroke as the user waits for it:
//    Document::Undo plus the session's inverse edit (SculptSession::Undo), alternating with redo;
//  - BM_UndoAndReload: the same when the session must reload the mesh from the Document instead
//    (an edit made elsewhere: SculptSession::SetMesh builds adjacency, normals and the grid).
#include <benchmark/benchmark.h>

#include <memory>
#include <numbers>
#include <utility>

#include "bench_cli.h"
#include "doc/command.h"
#include "doc/document.h"
#include "scene/sculpt_document.h"
#include "scene/sculpt_field.h"
#include "spidarcad/modeling/sculpt.h"

namespace {

using spidarcad::app::Document;
using spidarcad::app::ObjectId;
using spidarcad::app::SculptData;
using spidarcad::modeling::SculptMesh;
using spidarcad::modeling::TriangleMesh;

constexpr double kDeg = std::numbers::pi / 180.0;

const TriangleMesh& Clay() {
  static const TriangleMesh mesh = spidarcad::modeling::IcosphereMesh(0.1, 7);
  return mesh;
}

// A grab stroke at the sphere's north pole, lifted by `lift` m at full strength.
spidarcad::modeling::SculptEdit Pull(SculptMesh* mesh, double lift, double max_edge) {
  spidarcad::modeling::SculptToolSettings tool;
  tool.radius = 0.02;
  tool.max_edge_length = max_edge;
  Eigen::Isometry3d X = Eigen::Isometry3d::Identity();
  X.translation() = Eigen::Vector3d(0.0, 0.0, 0.1);
  mesh->BeginStroke(tool, X, 30.0 * kDeg);
  X.translation().z() += lift;
  mesh->UpdateStroke(X, 30.0 * kDeg);
  return mesh->EndStroke();
}

void RecordStrokes(benchmark::State& state, double lift, double max_edge) {
  Document doc;
  doc.Execute(spidarcad::app::edit::AddSculpt("clay", Clay()));
  const ObjectId id = doc.last_created().at(0);
  SculptMesh mesh(Clay(), 0.007);
  long moved = 0, splits = 0;
  for (auto _ : state) {
    state.PauseTiming();
    const auto edit = Pull(&mesh, lift, max_edge);
    moved = static_cast<long>(edit.moved.size());
    splits = edit.splits;
    state.ResumeTiming();
    doc.Execute(spidarcad::app::MakeStrokeCommand(
        id, "clay", spidarcad::modeling::SculptTool::kGrab, edit, mesh));
  }
  state.counters["moved_vertices"] = static_cast<double>(moved);
  state.counters["splits"] = static_cast<double>(splits);
  state.counters["vertices"] = mesh.vertex_count();
}

void BM_RecordStroke(benchmark::State& state) { RecordStrokes(state, 0.002, 0.0); }
BENCHMARK(BM_RecordStroke)->Unit(benchmark::kMillisecond)->Iterations(50);

void BM_RecordRefinedStroke(benchmark::State& state) { RecordStrokes(state, 0.01, 0.0012); }
BENCHMARK(BM_RecordRefinedStroke)->Unit(benchmark::kMillisecond)->Iterations(10);

void BM_UndoAndReload(benchmark::State& state) {
  Document doc;
  doc.Execute(spidarcad::app::edit::AddSculpt("clay", Clay()));
  const ObjectId id = doc.last_created().at(0);
  SculptMesh mesh(Clay(), 0.007);
  const auto edit = Pull(&mesh, 0.01, 0.0);
  doc.Execute(spidarcad::app::MakeStrokeCommand(id, "clay", spidarcad::modeling::SculptTool::kGrab,
                                                edit, mesh));
  spidarcad::app::SculptSession session;
  bool undo = true;
  for (auto _ : state) {
    if (undo) {
      doc.Undo();
    } else {
      doc.Redo();
    }
    undo = !undo;
    session.SetMesh(*std::get<SculptData>(doc.Get(id).data).mesh);
    benchmark::DoNotOptimize(session.mesh());
  }
  state.counters["vertices"] = session.mesh()->vertex_count();
}
BENCHMARK(BM_UndoAndReload)->Unit(benchmark::kMillisecond)->Iterations(20);

void BM_UndoInPlace(benchmark::State& state) {
  Document doc;
  doc.Execute(spidarcad::app::edit::AddSculpt("clay", Clay()));
  const ObjectId id = doc.last_created().at(0);
  spidarcad::app::SculptSession session;
  session.SetMesh(Clay(), 0.007);
  session.settings().tool.radius = 0.02;
  spidarcad::haptics::ToolKinematics tool;
  tool.p_WT = Eigen::Vector3d(0.0, 0.0, 0.1);
  tool.grasp = 30.0 * kDeg;
  session.Step(tool, false);
  tool.p_WT.z() += 0.01;
  session.Step(tool, false);
  tool.grasp = 90.0 * kDeg;
  session.Step(tool, false);
  doc.Execute(spidarcad::app::MakeStrokeCommand(id, "clay", spidarcad::modeling::SculptTool::kGrab,
                                                *session.last_edit(), *session.mesh()));
  const double moved = static_cast<double>(session.last_edit()->moved.size());
  bool undo = true;
  for (auto _ : state) {
    if (undo) {
      doc.Undo();
      session.Undo();
    } else {
      doc.Redo();
      session.Redo();
    }
    undo = !undo;
    benchmark::DoNotOptimize(session.mesh());
  }
  state.counters["moved_vertices"] = moved;
  state.counters["vertices"] = session.mesh()->vertex_count();
}
BENCHMARK(BM_UndoInPlace)->Unit(benchmark::kMillisecond)->Iterations(20);

}  // namespace

// What this program measures (its --help).
constexpr const char* kBenchDescription =
    "What sculpt mode adds on the main thread by keeping the clay in the Document, on a\n"
    "163842-vertex clay (icosphere, 7 subdivisions, 0.1 m): recording a finished grab stroke as\n"
    "one command (BM_RecordStroke: SculptStroke with the moved vertices; BM_RecordRefinedStroke:\n"
    "ReplaceSculptMesh after refinement), and Ctrl+Z / Ctrl+Y of a stroke: the session's inverse\n"
    "edit (BM_UndoInPlace) or, after edits made elsewhere, a reload of the mesh from the\n"
    "Document (BM_UndoAndReload).";

int main(int argc, char** argv) {
  return spidarcad::bench::RunBenchmarkMain(argc, argv, kBenchDescription);
}
