// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
// Per-frame cost of sculpt mode's display update on a ~200k-vertex clay: one stroke step
// (SculptSession::Step -> UpdateStroke) plus copying the touched vertices' positions and normals
// into the VTK arrays (what SculptMode::OnFrame does), against the alternatives: rebuilding the
// whole polydata (what happens once at the stroke's end) and running vtkPolyDataNormals over the
// whole mesh. Rendering itself is not included (it needs a display).
//
// Clay: the icosphere with 7 subdivisions scaled to 0.1 m radius (163842 vertices), or, with the
// environment variable SCULPT_BENCH_CLAY=<path of assets/scenes/clay.json>, that scene meshed at
// 0.85 mm.
#include <benchmark/benchmark.h>
#include <vtkCellArray.h>
#include <vtkFloatArray.h>
#include <vtkNew.h>
#include <vtkPointData.h>
#include <vtkPoints.h>
#include <vtkPolyData.h>
#include <vtkPolyDataNormals.h>

#include <cmath>
#include <cstdlib>
#include <memory>
#include <numbers>

#include "bench_cli.h"
#include "scene/scene_solid.h"
#include "scene/sculpt_field.h"
#include "spidarcad/modeling/sculpt.h"

namespace {

using spidarcad::app::SculptSession;
using spidarcad::modeling::TriangleMesh;

const TriangleMesh& Clay() {
  static const TriangleMesh mesh = [] {
    const char* env = std::getenv("SCULPT_BENCH_CLAY");
    if (env && env[0] != '\0') {
      auto grid = spidarcad::app::PrepareSceneSolid(env, "", 0.00085);
      spidarcad::modeling::SurfaceMeshSettings s;
      s.bounds = grid.bounds;
      s.cell_size = grid.cell;
      return spidarcad::modeling::MeshSurface(grid.compiled, s);
    }
    return spidarcad::modeling::IcosphereMesh(0.1, 7);
  }();
  return mesh;
}

// The VTK side of the clay, as SculptMode builds it.
struct VtkClay {
  vtkNew<vtkPoints> points;
  vtkNew<vtkFloatArray> normals;
  vtkNew<vtkCellArray> cells;
  vtkNew<vtkPolyData> poly;
  void Rebuild(const spidarcad::modeling::SculptMesh& mesh) {
    points->SetDataTypeToFloat();
    normals->SetNumberOfComponents(3);
    const int n = mesh.vertex_count();
    points->SetNumberOfPoints(n);
    normals->SetNumberOfTuples(n);
    float* xyz = static_cast<float*>(points->GetData()->GetVoidPointer(0));
    float* nxyz = normals->GetPointer(0);
    for (int i = 0; i < n; ++i) {
      for (int k = 0; k < 3; ++k) {
        xyz[3 * i + k] = static_cast<float>(mesh.positions()[i][k]);
        nxyz[3 * i + k] = static_cast<float>(mesh.normals()[i][k]);
      }
    }
    cells->Reset();
    cells->AllocateExact(mesh.triangle_count(), 3 * mesh.triangle_count());
    for (const Eigen::Vector3i& t : mesh.triangles()) {
      const vtkIdType ids[3] = {t[0], t[1], t[2]};
      cells->InsertNextCell(3, ids);
    }
    poly->SetPoints(points);
    poly->SetPolys(cells);
    poly->GetPointData()->SetNormals(normals);
    poly->Modified();
  }
};

int TopVertex(const spidarcad::modeling::SculptMesh& mesh) {
  int best = 0;
  for (int v = 0; v < mesh.vertex_count(); ++v) {
    if (mesh.positions()[v].z() > mesh.positions()[best].z()) best = v;
  }
  return best;
}

spidarcad::haptics::ToolKinematics Tool(const Eigen::Vector3d& p) {
  spidarcad::haptics::ToolKinematics tool;
  tool.p_WT = p;
  tool.grasp = 0.5;  // closed: full strength
  return tool;
}

// One frame during a stroke: Step (UpdateStroke) + copy of the touched vertices into VTK arrays.
// Arg 0: tool radius (mm); arg 1: tool (0 grab, 4 smooth); arg 2: conserve volume.
void BM_StrokeFrame(benchmark::State& state) {
  SculptSession session;
  session.settings().tool.radius = state.range(0) * 1e-3;
  session.settings().tool.tool = static_cast<spidarcad::modeling::SculptTool>(state.range(1));
  session.settings().tool.conserve_volume = state.range(2) != 0;
  session.SetMesh(Clay(), 0.01);
  VtkClay vtk;
  vtk.Rebuild(*session.mesh());
  const Eigen::Vector3d p0 = session.mesh()->positions()[TopVertex(*session.mesh())];
  session.Step(Tool(p0), false);
  long i = 0;
  for (auto _ : state) {
    const double t = 0.01 * static_cast<double>(i++ % 100);
    const Eigen::Vector3d p =
        p0 + 0.01 * Eigen::Vector3d(std::sin(t), 0.5 * std::cos(t), std::sin(2 * t));
    session.Step(Tool(p), false);
    spidarcad::app::CopyVerticesToFloat(
        *session.mesh(), session.display_vertices(),
        static_cast<float*>(vtk.points->GetData()->GetVoidPointer(0)), vtk.normals->GetPointer(0));
    vtk.points->Modified();
    vtk.normals->Modified();
    vtk.poly->Modified();
    benchmark::DoNotOptimize(vtk.poly.GetPointer());
  }
  state.counters["vertices"] = session.mesh()->vertex_count();
  state.counters["moved"] = session.mesh()->stroke_stats().affected_vertices;
  state.counters["copied"] = static_cast<double>(session.display_vertices().size());
}
BENCHMARK(BM_StrokeFrame)
    ->Args({10, 0, 0})
    ->Args({20, 0, 0})
    ->Args({50, 0, 0})
    ->Args({20, 0, 1})
    ->Args({20, 4, 0})
    ->Unit(benchmark::kMillisecond);

// Stroke end on the display side: the whole polydata rebuilt (positions, normals, triangles).
void BM_FullRebuild(benchmark::State& state) {
  SculptSession session;
  session.SetMesh(Clay(), 0.01);
  VtkClay vtk;
  for (auto _ : state) {
    vtk.Rebuild(*session.mesh());
    benchmark::DoNotOptimize(vtk.poly.GetPointer());
  }
  state.counters["vertices"] = session.mesh()->vertex_count();
}
BENCHMARK(BM_FullRebuild)->Unit(benchmark::kMillisecond);

// The alternative to the sculpt mesh's own normals: vtkPolyDataNormals over the whole clay.
void BM_VtkPolyDataNormals(benchmark::State& state) {
  SculptSession session;
  session.SetMesh(Clay(), 0.01);
  VtkClay vtk;
  vtk.Rebuild(*session.mesh());
  vtk.poly->GetPointData()->SetNormals(nullptr);
  for (auto _ : state) {
    vtkNew<vtkPolyDataNormals> normals;
    normals->SetInputData(vtk.poly);
    normals->ComputePointNormalsOn();
    normals->SplittingOff();
    normals->ConsistencyOff();
    normals->Update();
    benchmark::DoNotOptimize(normals->GetOutput());
  }
}
BENCHMARK(BM_VtkPolyDataNormals)->Unit(benchmark::kMillisecond);

// A stroke's end on the sculpt side: EndStroke (refinement of edges over 2 mm) for a 2 cm grab
// pulled 2 cm, then Undo to restore the clay for the next iteration.
void BM_EndStrokeWithRefinement(benchmark::State& state) {
  SculptSession session;
  session.settings().tool.radius = 0.02;
  session.settings().tool.max_edge_length = 0.002;
  session.SetMesh(Clay(), 0.01);
  const Eigen::Vector3d p0 = session.mesh()->positions()[TopVertex(*session.mesh())];
  for (auto _ : state) {
    state.PauseTiming();
    session.Step(Tool(p0), false);
    session.Step(Tool(p0 + Eigen::Vector3d(0, 0, 0.02)), false);
    state.ResumeTiming();
    spidarcad::haptics::ToolKinematics open = Tool(p0 + Eigen::Vector3d(0, 0, 0.02));
    open.grasp = std::numbers::pi / 2;
    session.Step(open, false);
    state.PauseTiming();
    state.counters["splits"] = static_cast<double>(session.last_edit()->splits);
    session.Undo();
    state.ResumeTiming();
  }
}
BENCHMARK(BM_EndStrokeWithRefinement)->Unit(benchmark::kMillisecond)->Iterations(5);

}  // namespace

// What this program measures (its --help).
constexpr const char* kBenchDescription =
    "Per-frame cost of sculpt mode's display update on a ~200k-vertex clay: one stroke step\n"
    "(SculptSession::Step -> UpdateStroke) plus copying the touched vertices' positions and "
    "normals\n"
    "into the VTK arrays (what SculptMode::OnFrame does), against the alternatives: rebuilding "
    "the\n"
    "whole polydata (what happens once at the stroke's end) and running vtkPolyDataNormals over "
    "the\n"
    "whole mesh. Rendering itself is not included (it needs a display).\n"
    "\n"
    "Clay: the icosphere with 7 subdivisions scaled to 0.1 m radius (163842 vertices), or, with "
    "the\n"
    "environment variable SCULPT_BENCH_CLAY=<path of assets/scenes/clay.json>, that scene meshed "
    "at 0.85 mm.";

int main(int argc, char** argv) {
  return spidarcad::bench::RunBenchmarkMain(argc, argv, kBenchDescription);
}
