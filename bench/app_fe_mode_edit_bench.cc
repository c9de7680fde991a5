// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
//
// Edit to first correct felt force in FE mode, through the window's own route: FeMode (headless:
// no renderer, no ImGui) on a SceneModel of the platform, driven as the window drives it (one
// SyncDocument, one JobQueue::Poll and one OnFrame per 1 ms "frame"). The part is set up from the
// solid (meshed in slabs or in one piece), precomputed, and felt near its free corner: the tool's
// focus (ColumnCache::RequestNear) sits on the 8 plate-top nodes nearest (0.29, 0.09, 0.01) m.
// Then the solid is edited by a document command, and the mode refreshes by itself (refresh on
// edit): the mesh Job, the command that lands it, the precompute Job (FeModel::Build on the
// slabs the edit left, or from scratch in one piece), and the patch's compliance columns. The
// clock runs from the edit's command to the frame at which the patch's 24 x 24 compliance block
// of the new model can be read: in slabs the columns publish the rows of the focus's slabs
// first (ColumnCacheSettings::near_rows_first), in one piece whole. At that frame a
// fem::CachedContactSolver puts the 8 patch nodes in contact on their own columns (as the touch
// field does; a refused node would be counted), and the block read then is checked against a
// one-piece fem::StaticSolver factorisation of the new mesh. The time at which the patch's
// columns are whole (every surface row, which the display waits for) is given too.
//   edits   load holes r 4 -> 4.5 mm (last slab), bolt holes r 5.5 -> 6 mm (first slab)
// The element order is chosen before set-up, as the panel offers it: the P2 cases' solid is
// meshed with its flat faces coarsened (MeshSettings::flat_cells = kQuadraticFlatCells, as FE
// mode meshes a solid for quadratic elements). P2 10 mm in slabs also runs with the panel's
// "lattice" box ticked (the surface by the lattice route, MeshSettings::surface_mesher =
// "lattice"; no flat-face coarsening).
// The sculpt cases (names ending "_sculpt") set up FE on a sculpt of the platform instead: its
// grid surface at the cell size, snapped as the product meshes (what a sculpt made from the solid
// holds), meshed in slabs spaced by app::SurfaceSlabSpacing (FeMeshInput::slabs). Their edits are
// sculpt strokes, committed as the sculpt mode commits them (MakeStrokeCommand): a push/pull
// raising a 3 mm bump of 15 mm radius on the plate near the free end (x = 0.275 m, last slab), and
// one on the bracket's face between the bolt holes (first slab). Each edit comes once the old
// model's column worker is idle (the columns within 10 mm of the tool done) and the old model's
// interface factor has been completed from both ends (FeModel::PrepareReuseInBackground, which
// FE mode starts when the worker goes idle; 0.4-1 s at P2 10 mm): an edit made while it
// solves a block shares the cores with that block until it ends (a full block of 16 nodes takes
// about a second at P2 10 mm), after which the refresh pauses it (ColumnCache::SetPaused). Times
// are wall seconds (steady clock) on whatever else the machine runs; the jobs use every core
// (CHOLMOD, OpenBLAS). Run: build/bench/app_fe_mode_edit_bench
//      build/bench/app_fe_mode_edit_bench --benchmark_filter=P2
//      SPIDARCAD_BENCH_CACHE_DIR=/tmp/c build/bench/app_fe_mode_edit_bench  (the disk cache on)
#include <benchmark/benchmark.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <functional>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

#include "bench_cli.h"
#include "bench_paths.h"
#include "doc/command.h"
#include "doc/job.h"
#include "gui/fe_mode.h"
#include "scene/fe_model.h"
#include "scene/fe_setup.h"
#include "scene/scene_model.h"
#include "scene/scene_solid.h"
#include "scene/sculpt_document.h"
#include "spidarcad/fem/column_cache.h"
#include "spidarcad/fem/static_solver.h"
#include "spidarcad/modeling/sculpt.h"
#include "spidarcad/modeling/surface_mesher.h"

namespace spidarcad {
namespace {

using Clock = std::chrono::steady_clock;

double Since(Clock::time_point t0) {
  return std::chrono::duration<double>(Clock::now() - t0).count();
}

std::string ScenePath() {
  if (const char* p = std::getenv("SPIDARCAD_PLATFORM_SCENE"); p && *p) return p;
  return bench::RepoPath("assets/scenes/platform.json");
}

// Path of the node whose id is `id` under `node` (false when there is none).
bool FindNode(const modeling::ImplicitNode& node, const std::string& id, app::NodePath* path) {
  if (node.id == id) return true;
  for (int i = 0; i < static_cast<int>(node.children.size()); ++i) {
    path->push_back(i);
    if (FindNode(node.children[i], id, path)) return true;
    path->pop_back();
  }
  return false;
}

struct Row {
  std::string name, edit;
  int tets = 0, order = 1;
  bool slabs = false;
  int strips = 0;  // a large slab's strips (FeMode::mesh_strips), when it had them
  double mesh = 0, model = 0, columns = 0, total = 0;  // s, from the edit's command
  double whole = 0;      // s, from the edit's command to every row of the patch's columns
  int own_contacts = 0;  // patch nodes a contact solver took on their own columns at `total`
  // Slab mesh stages of the refresh (s): grid surface, cut, TetGen, join.
  double surface = 0, cut = 0, tetgen = 0, join = 0;
  int factored = 0, blocks = 0, remeshed = 0;
  int interface = 0;                    // free interface dofs (the planes' sections), in slabs
  int planes = 0, planes_factored = 0;  // planes of the interface; their dense blocks factored
  double interface_seconds = 0.0;       // the interface's share of the model's factorisation, s
  // The factored blocks' assembly, CHOLMOD factorisation and Schur complements S_b (summed), s.
  double block_assembly = 0.0, block_factor = 0.0, block_schur = 0.0;
  double error = 0;  // patch block against a one-piece factorisation of the new mesh
};

std::vector<Row>& Rows() {
  static std::vector<Row> rows;
  return rows;
}

// The window's frame loop: until `done` or `seconds` pass.
void Frames(app::FeMode* mode, app::SceneModel* scene, app::JobQueue* jobs,
            const std::function<bool()>& done, double seconds = 600.0) {
  const auto give_up = Clock::now() + std::chrono::duration<double>(seconds);
  while (!done()) {
    if (Clock::now() > give_up) throw std::runtime_error("timed out: " + mode->status());
    mode->SyncDocument(scene, 0);
    jobs->Poll();
    mode->OnFrame(haptics::ToolState{});  // starts the precompute a landed refresh asked for
    std::this_thread::sleep_for(std::chrono::milliseconds(1));
  }
}

// The patch: the 8 plate-top surface nodes nearest the free corner, as candidates of `model`.
std::vector<int> Patch(const app::FeModel& model) {
  const Eigen::Vector3d corner(0.29, 0.09, 0.01);
  std::vector<int> top;
  const fem::ColumnCache& cache = model.cache();
  for (int b = 0; b < cache.num_candidates(); ++b)
    if (model.mesh().nodes(cache.candidate_node(b), 2) > 0.0099 && !cache.IsFixed(b))
      top.push_back(b);
  auto dist = [&](int b) {
    return (model.mesh().nodes.row(cache.candidate_node(b)).transpose() - corner).norm();
  };
  std::sort(top.begin(), top.end(), [&](int a, int b) { return dist(a) < dist(b); });
  top.resize(std::min<std::size_t>(8, top.size()));
  return top;
}

void Focus(app::FeModel* model) {
  model->cache().RequestNear(Eigen::Vector3d(0.29, 0.09, 0.01), 0.01);
}

bool PatchReady(const app::FeModel& model, const std::vector<int>& patch) {
  return std::all_of(patch.begin(), patch.end(), [&](int b) { return model.cache().IsReady(b); });
}

// True when every block of the patch's compliance can be read (rows computed).
bool PatchFelt(const app::FeModel& model, const std::vector<int>& patch) {
  const fem::ColumnCache& cache = model.cache();
  for (int b : patch) {
    if (!cache.HasColumn(b)) return false;
    for (int a : patch)
      if (!cache.RowReady(cache.OutputIndexOfCandidate(a), b)) return false;
  }
  return true;
}

// The patch's compliance block as read now (3n by 3n).
Eigen::MatrixXd PatchBlock(const app::FeModel& model, const std::vector<int>& patch) {
  const int n = static_cast<int>(patch.size());
  Eigen::MatrixXd got(3 * n, 3 * n);
  for (int a = 0; a < n; ++a)
    for (int b = 0; b < n; ++b)
      got.block<3, 3>(3 * a, 3 * b) =
          model.cache().Block(model.cache().OutputIndexOfCandidate(patch[a]), patch[b]);
  return got;
}

// Patch nodes a contact solver on the model's cache takes on their own columns now.
int OwnContacts(app::FeModel* model, const std::vector<int>& patch) {
  fem::CachedContactSolver contacts(&model->cache(), static_cast<int>(patch.size()));
  int own = 0;
  for (int b : patch) {
    const fem::CachedContactStatus status = contacts.Add(b);
    if (status == fem::CachedContactStatus::kOk)
      own += contacts.substitute(contacts.num_contacts() - 1) == b;
  }
  return own;
}

// Relative difference of a patch block `got` from a one-piece factorisation.
double PatchError(const app::FeModel& model, const std::vector<int>& patch,
                  const Eigen::MatrixXd& got) {
  const fem::StaticSolver whole(model.mesh(), model.materials(), model.bcs());
  const int n = static_cast<int>(patch.size());
  Eigen::MatrixXd rhs = Eigen::MatrixXd::Zero(whole.num_free(), 3 * n);
  for (int c = 0; c < n; ++c)
    for (int j = 0; j < 3; ++j)
      rhs(whole.FreeIndex(3 * model.cache().candidate_node(patch[c]) + j), 3 * c + j) = 1.0;
  Eigen::MatrixXd x;
  whole.SolveFree(rhs, &x);
  Eigen::MatrixXd expected(3 * n, 3 * n);
  for (int a = 0; a < n; ++a)
    for (int b = 0; b < n; ++b) {
      for (int i = 0; i < 3; ++i)
        for (int j = 0; j < 3; ++j)
          expected(3 * a + i, 3 * b + j) =
              x(whole.FreeIndex(3 * model.cache().candidate_node(patch[a]) + i), 3 * b + j);
    }
  return (got - expected).norm() / expected.norm();
}

// A sculpt of the platform: its grid surface at `cell`, snapped as the product meshes.
modeling::TriangleMesh PlatformSurface(double cell) {
  const app::SceneSolidGrid grid = app::PrepareSceneSolid(ScenePath(), "platform", cell);
  modeling::SurfaceMeshSettings ss;
  ss.bounds = grid.bounds;
  ss.cell_size = cell;
  ss.snap_cells = modeling::kProductSnapCells;
  return modeling::MeshSurface(grid.compiled, ss);
}

// The command of a push/pull stroke on sculpt `id` raising a bump of `height` m, radius 15 mm,
// centred on the surface vertex nearest `at`.
std::unique_ptr<app::Command> BumpStroke(const app::Document& doc, app::ObjectId id,
                                         const Eigen::Vector3d& at, double height) {
  modeling::SculptMesh clay(*std::get<app::SculptData>(doc.Get(id).data).mesh);
  int nearest = 0;
  for (int v = 0; v < clay.vertex_count(); ++v)
    if ((clay.positions()[v] - at).norm() < (clay.positions()[nearest] - at).norm()) nearest = v;
  modeling::SculptToolSettings tool;
  tool.tool = modeling::SculptTool::kPushPull;
  tool.radius = 0.015;
  tool.grasp_controls_strength = false;
  Eigen::Isometry3d X = Eigen::Isometry3d::Identity();
  X.translation() = clay.positions()[nearest];
  clay.BeginStroke(tool, X, 0.0);
  X.translation() += height * clay.normals()[nearest];
  clay.UpdateStroke(X, 0.0);
  const modeling::SculptEdit edit = clay.EndStroke();
  auto command = app::MakeStrokeCommand(id, "platform clay", tool.tool, edit, clay);
  if (!command) throw std::runtime_error("the stroke moved nothing");
  return command;
}

void BM_FeModeEdit(benchmark::State& state) {
  const int order = static_cast<int>(state.range(0));
  const double cell = state.range(1) * 1e-6;
  const bool slabs = state.range(2) != 0;
  // 1: FE mode's strips (kFeStrips, from kStripMinTriangles on); 10 + N: N strips, whatever the
  // slab's size (10: none).
  const int strips =
      state.range(2) >= 10 ? static_cast<int>(state.range(2)) - 10 : (slabs ? app::kFeStrips : 0);
  const bool sculpt = state.range(3) != 0;
  const bool lattice = state.range(4) != 0;
  for (auto _ : state) {
    app::SceneModel scene;
    scene.Load(ScenePath(), Eigen::Vector3d::Constant(0.2));
    if (sculpt) {
      scene.document().Execute(app::edit::AddSculpt("platform clay", PlatformSurface(cell)));
      scene.document().history().Clear();
    }
    app::JobQueue jobs;
    app::FeMode mode(nullptr, &jobs);
    mode.mesh_in_slabs() = slabs;
    mode.mesh_strips() = strips;
    if (state.range(2) >= 10) mode.mesh_strip_min_triangles() = 0;
    mode.mesh_settings().mesher = "tetgen";
    mode.mesh_settings().cell_size = cell;
    if (lattice) mode.mesh_settings().surface_mesher = "lattice";  // the panel's "lattice" box
    // The disk cache is off unless SPIDARCAD_BENCH_CACHE_DIR names a directory: then the
    // window's default (slab meshes, slab factors and planes written there by the jobs' own
    // threads while the columns are solved) is measured.
    const char* cache_dir = std::getenv("SPIDARCAD_BENCH_CACHE_DIR");
    mode.model_settings().use_disk_cache = cache_dir != nullptr && *cache_dir != '\0';
    if (mode.model_settings().use_disk_cache) mode.model_settings().cache_directory = cache_dir;
    const app::Document& doc = scene.document();
    const app::ObjectId platform = doc.FindByName(sculpt ? "platform clay" : "platform")->id;
    mode.SyncDocument(&scene, 0);
    // The order chosen before set-up, as the panel offers it: a solid's flat faces are meshed
    // for it (coarser for quadratic elements, FlatCellsForOrder).
    mode.model_settings().order = order;
    if (!mode.StartSetUp(&scene, platform, false, false)) throw std::runtime_error(mode.status());
    Frames(&mode, &scene, &jobs, [&] { return mode.bound_object() != 0; });
    mode.RequestModel();
    mode.SetActive(true);
    Frames(&mode, &scene, &jobs, [&] { return mode.model() != nullptr; });
    Focus(mode.model().get());
    {
      const std::vector<int> patch = Patch(*mode.model());
      Frames(&mode, &scene, &jobs, [&] { return PatchReady(*mode.model(), patch); });
    }
    struct Edit {
      const char* name;
      const char* counter;
      std::function<std::unique_ptr<app::Command>()> command;
    };
    // A solid's hole radius.
    auto radius = [&](const char* node, double r) {
      return [&doc, platform, node, r] {
        app::NodePath path;
        if (!FindNode(std::get<app::SolidData>(doc.Get(platform).data).root, node, &path))
          throw std::runtime_error(std::string("no node ") + node);
        return app::edit::SetNodeField(platform, path, "radius", r);
      };
    };
    const std::vector<Edit> edits =
        sculpt ? std::vector<Edit>{{"stroke: 3 mm bump near the free end", "free_end_bump",
                                    [&] {
                                      return BumpStroke(doc, platform,
                                                        Eigen::Vector3d(0.275, 0.0, 0.01), 0.003);
                                    }},
                                   {"stroke: 3 mm bump on the bracket", "bracket_bump",
                                    [&] {
                                      return BumpStroke(doc, platform,
                                                        Eigen::Vector3d(0.01, 0.05, -0.075), 0.003);
                                    }}}
               : std::vector<Edit>{
                     {"load holes r 4 -> 4.5 mm", "load_hole", radius("load_hole", 0.0045)},
                     {"bolt holes r 5.5 -> 6 mm", "bolt_hole", radius("bolt_hole", 0.006)}};
    for (const Edit& e : edits) {
      Row row;
      row.name = "P" + std::to_string(order) + " " + std::to_string(state.range(1) / 1000) + " mm" +
                 (sculpt ? " sculpt" : "") + (lattice ? ", lattice" : "");
      row.edit = e.name;
      row.order = order;
      row.slabs = slabs;
      const std::shared_ptr<app::FeModel> before = mode.model();
      // The edit comes after the tool has rested on the part: the columns around it are done
      // (an edit while the worker is in a block waits for that block: see the file comment).
      before->cache().WaitUntilIdle(600.0);
      // FE mode then completes the old model's interface factor from both ends, which the
      // edit's model reuses (a user's next edit comes seconds later).
      before->PrepareReuseInBackground();
      before->WaitReusePrepared();
      std::unique_ptr<app::Command> command = e.command();  // the stroke is made before the clock
      const auto t0 = Clock::now();
      scene.document().Execute(std::move(command));
      const std::uint64_t edited = doc.Get(platform).revision;
      Frames(&mode, &scene, &jobs, [&] {
        if (row.mesh == 0.0 && !mode.stale() && mode.bound_object() != 0) {
          const app::ObjectId mesh =
              std::get<app::FeModelData>(doc.Get(mode.bound_object()).data).tet_mesh;
          if (std::get<app::MeshData>(doc.Get(mesh).data).source_revision == edited)
            row.mesh = Since(t0);
        }
        return mode.model() != nullptr && mode.model() != before;
      });
      row.model = Since(t0);
      app::FeModel& model = *mode.model();
      Focus(&model);
      const std::vector<int> patch = Patch(model);
      Frames(&mode, &scene, &jobs, [&] { return PatchFelt(model, patch); });
      row.total = Since(t0);
      row.columns = row.total - row.model;
      row.own_contacts = OwnContacts(&model, patch);
      const Eigen::MatrixXd felt = PatchBlock(model, patch);
      Frames(&mode, &scene, &jobs, [&] { return PatchReady(model, patch); });
      row.whole = Since(t0);
      row.tets = model.mesh().num_elements();
      if (const fem::SubstructuredSolver* s = model.substructured()) {
        row.factored = s->stats().factored_blocks;
        row.blocks = s->num_blocks();
        row.interface = s->stats().num_interface_dofs;
        row.planes = s->stats().interface_groups;
        row.planes_factored = s->stats().factored_interface_groups;
        row.interface_seconds = s->stats().interface_seconds;
        row.block_assembly = s->stats().block_assembly_seconds;
        row.block_factor = s->stats().block_factor_seconds;
        row.block_schur = s->stats().block_schur_seconds;
      }
      const app::ObjectId mesh_id =
          std::get<app::FeModelData>(doc.Get(mode.bound_object()).data).tet_mesh;
      if (const auto slab_mesh = mode.SlabsOf(doc, mesh_id)) {
        row.remeshed = slab_mesh->num_remeshed();
        // The strips asked for, where a slab was large enough for them (kStripMinTriangles).
        row.strips = slab_mesh->strip_planes.empty() ? 0 : strips;
        row.surface = slab_mesh->surface_seconds;
        row.cut = slab_mesh->cut_seconds;
        row.tetgen = slab_mesh->tetgen_seconds;
        row.join = slab_mesh->join_seconds;
      }
      row.error = PatchError(model, patch, felt);
      if ((felt - PatchBlock(model, patch)).norm() != 0.0)
        throw std::runtime_error("the patch block changed when its columns were completed");
      Rows().push_back(row);
      state.counters[e.counter] = row.total;
    }
    mode.SetActive(false);  // saves columns only with SPIDARCAD_BENCH_CACHE_DIR
    Frames(&mode, &scene, &jobs, [&] { return !jobs.pending(); });
  }
}

void PrintTables() {
  bench::PrintLoadAverage();
  std::printf(" Wall seconds from the edit's command.\n\n");
  std::printf(
      "| case | mesh | tets | edit | slabs re-meshed / factored | refresh (mesh) | precompute | "
      "patch columns | **edit -> force** | own contacts | whole columns | vs one-piece factor "
      "|\n|---|---|---|---|---|---|---|---|---|---|---|---|\n");
  for (const Row& r : Rows()) {
    std::printf(
        "| %s | %s | %d | %s | %s | %.2f | %.2f | %.2f | **%.2f** | %d of 8 | %.2f | %.1e |\n",
        r.name.c_str(),
        r.strips ? ("4 slabs, " + std::to_string(r.strips) + " strips").c_str()
                 : (r.slabs ? "4 slabs" : "one piece"),
        r.tets, r.edit.c_str(),
        r.slabs ? (std::to_string(r.remeshed) + " / " + std::to_string(r.factored) + " of " +
                   std::to_string(r.blocks))
                      .c_str()
                : "all",
        r.mesh, r.model - r.mesh, r.columns, r.total, r.own_contacts, r.whole, r.error);
  }
  std::printf(
      "\nThe refresh's slab mesh, by stage (s): the grid surface of the whole solid, the cut by "
      "the planes, TetGen on the slabs that changed, the join; and the model's interface (free "
      "dofs on the planes, the planes whose dense blocks the new model factored: the others are "
      "kept from the old model's factor, completed from both ends, and the interface's time in "
      "s); and the blocks the new model factored: their assembly, CHOLMOD factorisations and "
      "Schur complements S_b, summed, s.\n\n| case | edit | surface | cut | TetGen | join | "
      "interface dofs | planes factored | interface | blocks: assembly | factor | S_b |\n"
      "|---|---|---|---|---|---|---|---|---|---|---|---|\n");
  for (const Row& r : Rows())
    if (r.slabs)
      std::printf(
          "| %s | %s | %.2f | %.2f | %.2f | %.2f | %d | %d of %d | %.2f | %.2f | %.2f | %.2f |\n",
          r.name.c_str(), r.edit.c_str(), r.surface, r.cut, r.tetgen, r.join, r.interface,
          r.planes_factored, r.planes, r.interface_seconds, r.block_assembly, r.block_factor,
          r.block_schur);
}

// Args: element order, cell (µm), in slabs as FE mode (1: a large slab in kFeStrips strips;
// 10 + N: a slab with over 1.5 times the mean share of triangles in N strips, however small,
// 10: none; FeMode::mesh_strips) or one piece (0), the solid (0) or a sculpt (1), the surface by
// marching tetrahedra (0, FE mode's default) or by the lattice (1).
BENCHMARK(BM_FeModeEdit)
    ->Name("P1_6mm")
    ->Args({1, 6000, 1, 0, 0})
    ->Args({1, 6000, 0, 0, 0})
    ->Iterations(1)
    ->Unit(benchmark::kSecond);
BENCHMARK(BM_FeModeEdit)
    ->Name("P2_10mm")
    ->Args({2, 10000, 1, 0, 0})
    ->Args({2, 10000, 0, 0, 0})
    ->Args({2, 10000, 1, 0, 1})
    ->Args({2, 10000, 13, 0, 0})
    ->Iterations(1)
    ->Unit(benchmark::kSecond);
BENCHMARK(BM_FeModeEdit)
    ->Name("P1_5mm")
    ->Args({1, 5000, 1, 0, 0})
    ->Args({1, 5000, 0, 0, 0})
    ->Args({1, 5000, 10, 0, 0})
    ->Args({1, 5000, 14, 0, 0})
    ->Iterations(1)
    ->Unit(benchmark::kSecond);
BENCHMARK(BM_FeModeEdit)
    ->Name("P2_10mm_sculpt")
    ->Args({2, 10000, 1, 1, 0})
    ->Args({2, 10000, 0, 1, 0})
    ->Iterations(1)
    ->Unit(benchmark::kSecond);
BENCHMARK(BM_FeModeEdit)
    ->Name("P1_5mm_sculpt")
    ->Args({1, 5000, 1, 1, 0})
    ->Args({1, 5000, 0, 1, 0})
    ->Iterations(1)
    ->Unit(benchmark::kSecond);

}  // namespace
}  // namespace spidarcad

int main(int argc, char** argv) {
  return spidarcad::bench::RunBenchmarkMain(
      argc, argv,
      "Edit to first correct felt force in FE mode (the window's route, headless): the platform "
      "set up in slabs or in one piece, edited, refreshed by the mode itself, the felt patch's "
      "columns ready.",
      nullptr, spidarcad::PrintTables);
}
