// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#include "cli/edit_to_force.h"

#include <Eigen/Dense>
#include <algorithm>
#include <atomic>
#include <chrono>
#include <cstdio>
#include <ctime>
#include <filesystem>
#include <fstream>
#include <functional>
#include <map>
#include <memory>
#include <nlohmann/json.hpp>
#include <sstream>
#include <thread>

#include "scene/fe_model.h"
#include "scene/scene_solid.h"
#include "scene/slab_fe_mesh.h"
#include "scene/vtu_io.h"
#include "spidarcad/fem/boundary.h"
#include "spidarcad/fem/column_cache.h"
#include "spidarcad/fem/static_solver.h"
#include "spidarcad/fem/substructure.h"
#include "spidarcad/haptics/loop_runner.h"
#include "spidarcad/modeling/cgal_mesher.h"
#include "spidarcad/modeling/surface_mesher.h"
#include "spidarcad/modeling/tetgen_mesher.h"

namespace spidarcad::app {
namespace {

const fem::Material kSteel{2.0e11, 0.3};
constexpr int kPatch = 8;

double CpuSeconds() {
  timespec ts{};
  clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &ts);
  return ts.tv_sec + 1e-9 * ts.tv_nsec;
}

struct Timer {
  std::chrono::steady_clock::time_point wall = std::chrono::steady_clock::now();
  double cpu = CpuSeconds();
  double Wall() const {
    return std::chrono::duration<double>(std::chrono::steady_clock::now() - wall).count();
  }
  double Cpu() const { return CpuSeconds() - cpu; }
};

// The platform scene with `field` of node `id` set to `value`, written to a temporary file.
std::string Edited(const std::string& scene_path, const std::string& id, const std::string& field,
                   const nlohmann::json& value, const std::string& name) {
  std::ifstream in(scene_path);
  nlohmann::json scene = nlohmann::json::parse(in);
  std::function<void(nlohmann::json&)> visit = [&](nlohmann::json& node) {
    if (node.is_object()) {
      if (node.contains("id") && node["id"] == id) node[field] = value;
      for (auto& [key, child] : node.items()) visit(child);
    } else if (node.is_array()) {
      for (auto& child : node) visit(child);
    }
  };
  visit(scene);
  const auto dir = std::filesystem::temp_directory_path() / "spidarcad-edit-bench";
  std::filesystem::create_directories(dir);
  const std::string path = (dir / (name + ".json")).string();
  std::ofstream(path) << scene.dump(1);
  return path;
}

struct Edit {
  const char* name;
  std::string path;
};
std::vector<Edit> Edits(const std::string& scene) {
  return {
      {"load holes r 4 -> 4.5 mm", Edited(scene, "load_hole", "radius", 0.0045, "load_hole")},
      {"bolt holes r 5.5 -> 6 mm", Edited(scene, "bolt_hole", "radius", 0.006, "bolt_hole")},
      {"gusset 0.2 -> 0.17 m long",
       Edited(scene, "gusset", "profile", {{0.005, 0.002}, {0.17, 0.002}, {0.005, -0.14}},
              "gusset")},
      {"plate 10 -> 11 mm thick", Edited(scene, "plate", "size", {0.3, 0.2, 0.011}, "plate")},
  };
}

fem::BoundaryConditions Conditions(const fem::TetMesh& mesh) {
  fem::BoundaryConditions bcs(mesh.num_nodes());
  bcs.FixNodes(MinXFaceNodes(mesh));
  return bcs;
}

std::vector<int> Patch(const fem::TetMesh& mesh, const fem::BoundaryConditions& bcs) {
  const Eigen::Vector3d corner(0.29, 0.09, 0.01);
  std::vector<int> top;
  for (int v = 0; v < mesh.num_nodes(); ++v)
    if (mesh.nodes(v, 2) > 0.0099 && !bcs.prescribed().count(3 * v)) top.push_back(v);
  std::sort(top.begin(), top.end(), [&](int a, int b) {
    return (mesh.nodes.row(a).transpose() - corner).norm() <
           (mesh.nodes.row(b).transpose() - corner).norm();
  });
  top.resize(std::min<std::size_t>(kPatch, top.size()));
  return top;
}

template <class Solver>
Eigen::MatrixXd PatchRhs(const Solver& solver, const std::vector<int>& patch) {
  Eigen::MatrixXd rhs = Eigen::MatrixXd::Zero(solver.num_free(), 3 * patch.size());
  for (std::size_t c = 0; c < patch.size(); ++c)
    for (int j = 0; j < 3; ++j) rhs(solver.FreeIndex(3 * patch[c] + j), 3 * c + j) = 1.0;
  return rhs;
}

template <class Solver>
Eigen::MatrixXd PatchBlock(const Solver& solver, const std::vector<int>& patch,
                           const Eigen::MatrixXd& x) {
  Eigen::MatrixXd g(3 * patch.size(), x.cols());
  for (std::size_t a = 0; a < patch.size(); ++a)
    for (int i = 0; i < 3; ++i) g.row(3 * a + i) = x.row(solver.FreeIndex(3 * patch[a] + i));
  return g;
}

// A 1 kHz contact tick on the old model while the update runs: 16 contacts of the patch on a
// ColumnCache of the old substructured solver (the columns made before the edit), one
// CachedContactSolver::Solve per tick, on a haptics::LoopRunner (SCHED_FIFO 80 when permitted,
// absolute sleeps, wake-up lateness histogram) as the window's haptic thread. Records each tick's
// thread CPU time too.
class TickProbe {
 public:
  TickProbe(fem::ColumnCache* cache, const std::vector<int>& candidates) : solver_(cache, 16) {
    for (int b : candidates)
      if (solver_.num_contacts() < 16) solver_.Add(b);
    target_.assign(3 * solver_.num_contacts(), 0.0);
    for (int s = 0; s < solver_.num_contacts(); ++s)
      target_[3 * s + 2] =
          cache->baseline()(3 * cache->OutputIndexOfCandidate(solver_.contact(s)) + 2) - 1e-5;
    force_.assign(target_.size(), 0.0);
  }
  void Start() {
    runner_.Start([this](const haptics::TickTiming&) {
      const double t0 = ThreadCpu();
      solver_.Solve(target_.data(), force_.data());
      cpu_.Add(ThreadCpu() - t0);
    });
  }
  void Stop() { runner_.Stop(); }
  const haptics::LoopRunner& runner() const { return runner_; }
  // Thread CPU time per tick, s.
  const haptics::LatencyHistogram& cpu() const { return cpu_; }

 private:
  static double ThreadCpu() {
    timespec ts{};
    clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
    return ts.tv_sec + 1e-9 * ts.tv_nsec;
  }
  fem::CachedContactSolver solver_;
  std::vector<double> target_, force_;
  haptics::LatencyHistogram cpu_;
  haptics::LoopRunner runner_;
};

EditToForceCase::Quality Measure(const modeling::CompiledSolid& solid,
                                 const modeling::TetMesh& mesh) {
  EditToForceCase::Quality out;
  out.tets = static_cast<int>(mesh.tets.cols());
  out.q = modeling::MeasureTetQuality(mesh);
  out.hausdorff = modeling::MeasureSurfaceError(solid, modeling::BoundarySurface(mesh)).max;
  return out;
}

// printf into a string.
template <class... Args>
std::string Format(const char* format, Args... args) {
  char buffer[512];
  std::snprintf(buffer, sizeof buffer, format, args...);
  return buffer;
}

}  // namespace

EditToForceCase MeasureEditToForce(const std::string& scene_path, int order, double cell,
                                   int num_slabs, int num_edits,
                                   const EditToForceMeshing& meshing) {
  const bool lattice = meshing.lattice;
  const double flat_cells = meshing.flat_cells, snap_cells = meshing.snap_cells;
  const int strips = meshing.strips;
  EditToForceCase row;
  row.name =
      Format("P%d %g mm, %d slabs%s", order, cell * 1000.0, num_slabs, lattice ? ", lattice" : "");
  if (strips > 1) row.name += Format(", %d strips", strips);
  if (snap_cells > 0.0) row.name += Format(", snap %g", snap_cells);
  if (flat_cells > 0.0) row.name += Format(", flat %g", flat_cells);
  row.order = order;
  row.cell = cell;
  row.num_slabs = num_slabs;
  row.lattice = lattice;
  row.flat_cells = flat_cells;
  row.strips = strips;
  row.snap_cells = snap_cells;
  const SceneSolidGrid base = PrepareSceneSolid(scene_path, "platform", cell);
  const fem::MaterialTable steel(kSteel);
  // Today: the whole part meshed in one piece, factored, the patch's columns.
  {
    Timer t;
    modeling::SurfaceMeshSettings ss;
    ss.bounds = base.bounds;
    ss.cell_size = cell;
    ss.flat_coarsen_cells = flat_cells;
    ss.snap_cells = snap_cells;
    if (lattice) ss.mesher = modeling::SurfaceMesher::kLattice;
    const modeling::TriangleMesh surface = modeling::MeshSurface(base.compiled, ss);
    modeling::TetMeshSettings ts;
    ts.max_radius_edge = 2.0;
    const modeling::TetMesh one_piece = modeling::TetrahedralizeSurface(surface, ts);
    fem::TetMesh mesh = ToFemMesh(one_piece);
    mesh.regions.setZero();
    if (order == 2) mesh = fem::MakeQuadratic(mesh);
    row.full_mesh = t.Wall();
    Timer tf;
    const fem::BoundaryConditions bcs = Conditions(mesh);
    const fem::StaticSolver full(mesh, steel, bcs);
    row.full_factor = tf.Wall();
    Timer tp;
    Eigen::MatrixXd x;
    full.SolveFree(PatchRhs(full, Patch(mesh, bcs)), &x);
    row.full_patch = tp.Wall();
    row.full_cpu = t.Cpu();
    row.one_piece = Measure(base.compiled, one_piece);
  }
  // The slab route, fresh.
  const Eigen::AlignedBox3d grid = base.bounds;  // the edits mesh on slab_mesh's grid
  SlabMeshOptions fresh_options;
  fresh_options.lattice = lattice;
  fresh_options.flat_coarsen_cells = flat_cells;
  fresh_options.strips = strips;
  fresh_options.snap_cells = snap_cells;
  const std::vector<double> planes = SlabPlanes(grid, cell, num_slabs, fresh_options);
  Timer tf;
  const SlabFeMesh slab_mesh = MeshSolidInSlabs(base.compiled, grid, cell, planes, fresh_options);
  const fem::TetMesh mesh0 = order == 2 ? fem::MakeQuadratic(slab_mesh.mesh) : slab_mesh.mesh;
  const fem::SubstructuredSolver fresh(mesh0, steel, Conditions(mesh0), slab_mesh.slab, nullptr, {},
                                       nullptr, slab_mesh.piece_slab);
  row.slab_fresh_wall = tf.Wall();
  row.slab_fresh_cpu = tf.Cpu();
  row.free = fresh.num_free();
  row.interface = fresh.stats().num_interface_dofs;
  row.slabs = Measure(base.compiled, *slab_mesh.volume);  // the joined mesh it already holds
  // The old model as FE mode holds it: lazy columns of its surface, the patch's made ready.
  const fem::Surface surface0 = fem::ExtractSurface(mesh0);
  fem::ColumnCacheSettings cs;
  cs.start_worker = false;
  fem::ColumnCache cache0(fresh, mesh0.nodes, surface0.nodes, surface0.nodes, cs);
  std::vector<int> patch0;
  for (int v : Patch(mesh0, Conditions(mesh0))) patch0.push_back(cache0.CandidateOfNode(v));
  cache0.ComputeNodes(patch0);
  // Then both ends of its interface factor, as FE mode does in the background once the model is
  // ready: an edit keeps the planes on either side of it.
  row.prepare_reuse = fresh.PrepareReuse().seconds;
  const std::vector<Edit> edits = Edits(scene_path);
  for (int k = 0; k < num_edits && k < static_cast<int>(edits.size()); ++k) {
    const Edit& edit = edits[k];
    EditToForceRow e;
    TickProbe probe(&cache0, patch0);
    probe.Start();
    e.edit = edit.name;
    e.slabs = static_cast<int>(slab_mesh.slab_tets.size());  // slabs, or pieces with strips
    Timer t;
    const SceneSolidGrid changed = PrepareSceneSolid(edit.path, "platform", cell);
    SlabMeshOptions reuse;
    reuse.previous = &slab_mesh;
    reuse.lattice = lattice;
    reuse.flat_coarsen_cells = flat_cells;
    reuse.strips = strips;
    reuse.snap_cells = snap_cells;
    // On the first mesh's grid and planes (moved with its grid when that kept a wall), as FE
    // mode meshes an edit.
    const SlabFeMesh m =
        MeshSolidInSlabs(changed.compiled, slab_mesh.grid_bounds, cell, slab_mesh.planes, reuse);
    const fem::TetMesh mesh1 = order == 2 ? fem::MakeQuadratic(m.mesh) : m.mesh;
    const fem::BoundaryConditions bcs1 = Conditions(mesh1);
    Timer ts;
    const fem::SubstructuredSolver after(mesh1, steel, bcs1, m.slab, &fresh, {}, nullptr,
                                         m.piece_slab);
    e.blocks = after.stats().block_assembly_seconds + after.stats().block_factor_seconds +
               after.stats().block_schur_seconds;
    e.interface = after.stats().interface_seconds;
    const std::vector<int> patch = Patch(mesh1, bcs1);
    Timer tp;
    Eigen::MatrixXd x;
    std::vector<int> patch_blocks;  // the blocks of the patch's nodes (the last slab's)
    for (int v : patch) {
      const int b = after.BlockOfNode(v);
      if (b >= 0 && std::find(patch_blocks.begin(), patch_blocks.end(), b) == patch_blocks.end())
        patch_blocks.push_back(b);
    }
    after.SolveFreeInBlocks(PatchRhs(after, patch), patch_blocks, &x);
    const Eigen::MatrixXd g = PatchBlock(after, patch, x);
    e.patch = tp.Wall();
    e.total_wall = t.Wall();
    e.total_cpu = t.Cpu();
    probe.Stop();
    e.ticks = static_cast<int>(probe.runner().ticks());
    e.scheduling = haptics::RealtimeStatusName(probe.runner().realtime_status());
    e.tick_cpu_p999 = 1e6 * probe.cpu().Percentile(0.999);
    e.tick_cpu_max = 1e6 * probe.cpu().max();
    e.tick_late_p999 = 1e6 * probe.runner().lateness().Percentile(0.999);
    e.surface = m.surface_seconds;
    e.cut = m.cut_seconds;
    e.tetgen = m.tetgen_seconds;
    e.join = m.join_seconds;
    e.remeshed = m.num_remeshed();
    for (std::size_t s = 0; s < m.slab_tets.size(); ++s)
      if (m.remeshed[s]) e.remeshed_tets += m.slab_tets[s].tets.cols();
    e.refactored = after.stats().factored_blocks;
    e.planes = after.stats().interface_groups;
    e.planes_refactored = after.stats().factored_interface_groups;
    // Check against a monolithic solve of the same new mesh.
    const fem::StaticSolver mono(mesh1, steel, bcs1);
    Eigen::MatrixXd xm;
    mono.SolveFree(PatchRhs(mono, patch), &xm);
    const Eigen::MatrixXd gm = PatchBlock(mono, patch, xm);
    e.error = (g - gm).norm() / gm.norm();
    row.edits.push_back(e);
  }
  return row;
}

std::string EditToForceTables(const std::vector<EditToForceCase>& cases) {
  std::string s =
      "| case | free dofs | interface dofs | full: mesh | factor | patch | total (cpu) | "
      "slabs fresh (cpu) | S from both ends |\n|---|---|---|---|---|---|---|---|---|\n";
  for (const EditToForceCase& r : cases)
    s += Format("| %s | %d | %d | %.2f | %.2f | %.3f | %.2f (%.2f) | %.2f (%.2f) | %.2f |\n",
                r.name.c_str(), r.free, r.interface, r.full_mesh, r.full_factor, r.full_patch,
                r.full_wall(), r.full_cpu, r.slab_fresh_wall, r.slab_fresh_cpu, r.prepare_reuse);
  s += "\n| case | edit | slabs re-meshed / refactored | tets re-meshed | planes of S refactored | "
       "surface | cut | TetGen | join | blocks | S | patch | edit -> force (cpu) | rel. diff "
       "|\n|---|---|---|---|---|---|---|---|---|---|---|---|---|---|\n";
  for (const EditToForceCase& r : cases)
    for (const EditToForceRow& e : r.edits)
      s += Format(
          "| %s | %s | %d / %d of %d | %lld | %d of %d | %.2f | %.2f | %.2f | %.2f | %.2f | %.2f "
          "| %.3f | %.2f (%.2f) | %.1e |\n",
          r.name.c_str(), e.edit.c_str(), e.remeshed, e.refactored, e.slabs, e.remeshed_tets,
          e.planes_refactored, e.planes, e.surface, e.cut, e.tetgen, e.join, e.blocks, e.interface,
          e.patch, e.total_wall, e.total_cpu, e.error);
  s += "\n1 kHz contact tick (16 contacts, old model) during each update: thread CPU per tick and "
       "lateness of its wake-up, µs\n\n| case | edit | probe thread | ticks | tick CPU p99.9 | max "
       "| wake-up lateness p99.9 |\n|---|---|---|---|---|---|---|\n";
  for (const EditToForceCase& r : cases)
    for (const EditToForceRow& e : r.edits)
      s += Format("| %s | %s | %s | %d | %.1f | %.1f | %.0f |\n", r.name.c_str(), e.edit.c_str(),
                  e.scheduling.c_str(), e.ticks, e.tick_cpu_p999, e.tick_cpu_max, e.tick_late_p999);
  s += "\n| case | mesh | tets | min dihedral deg | max radius-edge | volume cm^3 | surface "
       "Hausdorff mm |\n|---|---|---|---|---|---|---|\n";
  for (const EditToForceCase& r : cases)
    for (const auto& [label, q] :
         {std::make_pair("one piece", r.one_piece), std::make_pair("slabs", r.slabs)})
      s += Format("| %s | %s | %d | %.2f | %.2f | %.2f | %.3f |\n", r.name.c_str(), label, q.tets,
                  q.q.min_dihedral_deg, q.q.max_radius_edge, 1e6 * q.q.total_volume,
                  1e3 * q.hausdorff);
  return s;
}

}  // namespace spidarcad::app
