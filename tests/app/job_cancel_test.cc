// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
// Issue 15: every long job the window starts can be cancelled within 0.5 s and leaves the
// document as it was. One test per job kind starts a long instance (several seconds) the way the
// window does, waits until the worker is in the phase under test, calls Job::Cancel and measures
// the wall time until the job has ended as kCancelled; the document's JSON (with revisions), its
// revision and its undo history are compared before and after. The measured latencies are
// printed ("cancel latency: ...") and tabulated in docs/limits.md.
//
// The latency is recorded (test property "cancel_latency_s"), not asserted: the project's tests
// assert no wall times. What is asserted is that Cancel works at all: the job must end as
// kCancelled (a job that ignored its flag would end as kSucceeded, or still be running when the
// 300 s watchdog, which is about hanging, not speed, gives up) and leave the document as it was.
// The 0.5 s bound is checked by bench/app_worker_cancel_bench.cc and tabulated in
// docs/limits.md; the typical latencies are tens of milliseconds. TetGen runs in a
// child process that Cancel kills (scene/worker_process.h; the tests set the worker program to the
// built spidarcad, as main() sets /proc/self/exe); after such a cancel a second TetGen job and
// an FE factorisation must work in the same process (an earlier abandoned-thread attempt crashed
// there). CGAL Mesh_3 runs in such a child too. Not covered: the CHOLMOD factorisation, which
// cannot be interrupted and ends only when the library call returns (docs/limits.md).
#include <gtest/gtest.h>
#include <vtkNew.h>
#include <vtkRenderer.h>

#include <chrono>
#include <cstdio>
#include <functional>
#include <memory>
#include <string>
#include <thread>

#include "doc/command.h"
#include "doc/document.h"
#include "doc/job.h"
#include "gui/fe_mode.h"
#include "gui/mode.h"
#include "gui/sculpt_mode.h"
#include "scene/fe_model.h"
#include "scene/fe_setup.h"
#include "scene/scene_model.h"
#include "scene/scene_solid.h"
#include "scene/slab_fe_mesh.h"
#include "scene/vtu_io.h"
#include "scene/worker_process.h"
#include "spidarcad/fem/mesh.h"
#include "spidarcad/modeling/implicit_node.h"
#include "spidarcad/modeling/sculpt.h"

namespace spidarcad::app {
namespace {

using Clock = std::chrono::steady_clock;

double Since(Clock::time_point t0) {
  return std::chrono::duration<double>(Clock::now() - t0).count();
}

// What must not change when a job is cancelled.
struct DocState {
  std::string json;
  std::uint64_t revision = 0;
  std::size_t undo = 0, redo = 0;
  explicit DocState(const Document& doc)
      : json(doc.ToJson(true).dump()),
        revision(doc.revision()),
        undo(doc.history().undo_size()),
        redo(doc.history().redo_size()) {}
  bool operator==(const DocState& o) const {
    return json == o.json && revision == o.revision && undo == o.undo && redo == o.redo;
  }
};

// Waits until `working()` holds (the job is in the phase under test), cancels the job and
// records the seconds from Cancel() until the job has ended (property "cancel_latency_s"); then
// polls the queue (no finisher runs for a cancelled job). Fails the test when the job ended
// before it could be cancelled, did not end as kCancelled, or was still running 300 s after.
void CancelWhen(JobQueue* jobs, Job& job, const std::function<bool()>& working, const char* kind) {
  const Clock::time_point limit = Clock::now() + std::chrono::seconds(300);
  while (job.state() == Job::State::kRunning && !working() && Clock::now() < limit)
    std::this_thread::sleep_for(std::chrono::microseconds(200));
  EXPECT_EQ(job.state(), Job::State::kRunning)
      << kind << ": the job ended (" << job.error() << ") before it could be cancelled";
  EXPECT_TRUE(working()) << kind << ": the job did not reach the phase under test";
  const Clock::time_point t0 = Clock::now();
  job.Cancel();
  while (job.state() == Job::State::kRunning && Since(t0) < 300.0)
    std::this_thread::sleep_for(std::chrono::microseconds(100));
  const double seconds = Since(t0);
  jobs->Poll();
  EXPECT_EQ(job.state(), Job::State::kCancelled) << kind << ": " << job.error();
  std::printf("cancel latency: %-40s %.4f s (phase '%s', progress %.2f)\n", kind, seconds,
              job.phase().c_str(), job.progress());
  ::testing::Test::RecordProperty("cancel_latency_s", std::to_string(seconds));
}

std::function<bool()> PhaseIs(const Job& job, const std::string& phase, double min_progress = 0.0) {
  return [&job, phase, min_progress] {
    return job.phase() == phase && job.progress() >= min_progress;
  };
}

// Model mode's mesh settings of a cell size (m).
MeshSettings CellOf(double cell) {
  MeshSettings settings;
  settings.cell_size = cell;
  return settings;
}

// True once the job's progress has been at least `min_progress` for `dwell` seconds (TetGen
// reports no progress while it runs).
std::function<bool(const Job&)> ProgressFor(double min_progress, double dwell) {
  auto entered = std::make_shared<Clock::time_point>();
  auto seen = std::make_shared<bool>(false);
  return [min_progress, dwell, entered, seen](const Job& job) {
    if (job.progress() < min_progress) return false;
    if (!*seen) {
      *seen = true;
      *entered = Clock::now();
    }
    return Since(*entered) >= dwell;
  };
}

std::function<bool()> ProgressFor(const Job& job, double min_progress, double dwell) {
  auto when = ProgressFor(min_progress, dwell);
  return [&job, when] { return when(job); };
}

// TetGen, CGAL and CHOLMOD run in a child process of the built spidarcad for the scope.
struct WorkerScope {
  WorkerScope() { SetWorkerProgram(SPIDARCAD_EXE); }
  ~WorkerScope() { SetWorkerProgram(""); }
};

// A SceneModel on an empty document with one solid, compiled and previewed (the preview gives
// the object's box, which the mesh jobs mesh).
struct SolidRig {
  SceneModel model;
  JobQueue jobs;
  ObjectId solid = 0;
  explicit SolidRig(const modeling::ImplicitNode& root) {
    model.Load(kNoSceneName, Eigen::Vector3d::Constant(0.2));
    model.document().Execute(edit::AddSolid("part", root));
    solid = model.document().last_created().at(0);
    model.Refresh();
    model.StartPreviewJobs(&jobs, 16.0);
    for (const auto& job : jobs.jobs()) job->Wait();
    jobs.Poll();
    jobs.Prune();
    EXPECT_FALSE(model.objects()[index()].bounds_W.isEmpty()) << model.objects()[index()].error;
  }
  int index() const { return model.IndexOf(solid); }
};

modeling::ImplicitNode Ball(double r) { return modeling::ImplicitNode(modeling::SphereParams{r}); }

// ---- model mode ----

TEST(JobCancel, PreviewEndsWithinHalfASecond) {
  SolidRig rig(Ball(0.05));
  const DocState before(rig.model.document());
  rig.model.StartPreviewJobs(&rig.jobs, 300.0);
  Job& job = *rig.jobs.jobs().back();
  CancelWhen(&rig.jobs, job, PhaseIs(job, "surface", 0.05), "preview (surface)");
  EXPECT_TRUE(DocState(rig.model.document()) == before);
}

TEST(JobCancel, SurfaceMeshEndsWithinHalfASecond) {
  SolidRig rig(Ball(0.05));
  const DocState before(rig.model.document());
  const std::uint64_t revision = rig.model.objects()[rig.index()].revision;
  Job& job = rig.model.StartMeshJob(&rig.jobs, rig.index(), MeshKind::kSurface, CellOf(0.0004));
  CancelWhen(&rig.jobs, job, PhaseIs(job, "surface", 0.05), "mesh surface");
  EXPECT_TRUE(DocState(rig.model.document()) == before);
  EXPECT_EQ(rig.model.objects()[rig.index()].revision, revision);
}

// After a cancel inside TetGen: another TetGen job in this process lands its mesh, and an FE
// model factorises on it (an abandoned TetGen/CHOLMOD thread made this crash before).
void ExpectMeshingStillWorks(SolidRig* rig) {
  const std::size_t objects = rig->model.document().objects().size();
  Job& again =
      rig->model.StartMeshJob(&rig->jobs, rig->index(), MeshKind::kTetrahedra, CellOf(0.01));
  again.Wait();
  rig->jobs.Poll();
  ASSERT_EQ(again.state(), Job::State::kSucceeded) << again.error();
  ASSERT_EQ(rig->model.document().objects().size(), objects + 1);
  const DocObject& mesh = rig->model.document().Get(rig->model.document().last_created().at(0));
  const auto& data = std::get<MeshData>(mesh.data);
  ASSERT_TRUE(data.volume);
  EXPECT_GT(data.volume->tets.cols(), 100);
  FeModelSettings fe;
  fe.use_disk_cache = false;
  fe.cache.start_worker = false;
  fe.fixed_boxes = {Eigen::AlignedBox3d(Eigen::Vector3d(-1, -1, -1), Eigen::Vector3d(-0.03, 1, 1))};
  const std::unique_ptr<FeModel> model = FeModel::Build(ToFemMesh(*data.volume), fe);
  EXPECT_TRUE(model != nullptr);
}

TEST(JobCancel, TetrahedraEndWithinHalfASecondInsideTetgen) {
  WorkerScope worker;
  SolidRig rig(Ball(0.05));
  const DocState before(rig.model.document());
  const std::uint64_t revision = rig.model.objects()[rig.index()].revision;
  Job& job = rig.model.StartMeshJob(&rig.jobs, rig.index(), MeshKind::kTetrahedra, CellOf(0.002));
  // 0.35 + 0.65 × 0.2 for 0.3 s: the surface is meshed and checked, TetGen runs (38 s).
  CancelWhen(&rig.jobs, job, ProgressFor(job, 0.479, 0.3), "mesh tetrahedra (TetGen)");
  EXPECT_TRUE(DocState(rig.model.document()) == before);
  EXPECT_EQ(rig.model.objects()[rig.index()].revision, revision);
  ExpectMeshingStillWorks(&rig);
}

// The job body of FeMode::StartMeshJob (FE mode's Set up FE).
Job& StartFeSetUp(JobQueue* jobs, const Document& doc, ObjectId solid, double cell) {
  const FeMeshInput input = PrepareFeMesh(doc, solid, CellOf(cell));
  return jobs->Start("Set up FE for part", [input](JobContext& ctx) -> Job::Finisher {
    ctx.SetPhase("surface and TetGen");
    const FeMeshResult result = MeshFeSource(input, ctx.cancel_flag(), ctx.ProgressRange(0.0, 1.0));
    (void)result;
    return [] { ADD_FAILURE() << "a cancelled job ran its finisher"; };
  });
}

TEST(JobCancel, FeSetUpEndsWithinHalfASecondInsideTetgen) {
  WorkerScope worker;
  SolidRig rig(Ball(0.05));
  const DocState before(rig.model.document());
  Job& job = StartFeSetUp(&rig.jobs, rig.model.document(), rig.solid, 0.002);
  CancelWhen(&rig.jobs, job, ProgressFor(job, 0.479, 0.3), "FE set-up (TetGen)");
  EXPECT_TRUE(DocState(rig.model.document()) == before);
  ExpectMeshingStillWorks(&rig);
}

// FE mode's Set up FE with CGAL Mesh_3 on the ball at `cell`, cancelled when `when` holds.
void CancelCgalSetUp(double cell, const std::function<bool(const Job&)>& when, const char* kind) {
  WorkerScope worker;
  SolidRig rig(Ball(0.05));
  const DocState before(rig.model.document());
  MeshSettings settings = CellOf(cell);
  settings.mesher = "cgal";
  const FeMeshInput input = PrepareFeMesh(rig.model.document(), rig.solid, settings);
  Job& job = rig.jobs.Start("Set up FE for part", [input](JobContext& ctx) -> Job::Finisher {
    ctx.SetPhase("CGAL Mesh_3");
    const FeMeshResult result = MeshFeSource(input, ctx.cancel_flag(), ctx.ProgressRange(0.0, 1.0));
    (void)result;
    return [] { ADD_FAILURE() << "a cancelled job ran its finisher"; };
  });
  CancelWhen(
      &rig.jobs, job, [&job, when] { return when(job); }, kind);
  EXPECT_TRUE(DocState(rig.model.document()) == before);
  ExpectMeshingStillWorks(&rig);
}

TEST(JobCancel, FeSetUpEndsWithinHalfASecondInCgalsStartUp) {
  // 0.3 s into the job (or at CGAL's first refinement report, 0.05, if that comes first): the
  // child starts up or seeds, which polls nothing (the printed progress says where it was).
  auto when = ProgressFor(0.0, 0.3);
  CancelCgalSetUp(
      0.0008, [when](const Job& job) { return when(job) || job.progress() >= 0.05; },
      "FE set-up (CGAL Mesh_3 start-up)");
}

TEST(JobCancel, FeSetUpEndsWithinHalfASecondInCgalsOptimisers) {
  // 0.2 s after refinement ended (0.7): perturbation and exudation, which poll nothing.
  CancelCgalSetUp(0.002, ProgressFor(0.7, 0.2), "FE set-up (CGAL Mesh_3 optimisers)");
}

// Model mode's Refresh of a tetrahedral mesh (SceneModel::StartRefreshJob): the mesh object of
// the ball was made at 1 cm but records 2 mm, so that the refresh's TetGen run takes tens of
// seconds.
TEST(JobCancel, RefreshEndsWithinHalfASecondInsideTetgen) {
  WorkerScope worker;
  SolidRig rig(Ball(0.05));
  const FeMeshInput coarse = PrepareSolidMesh(rig.model.document(), rig.solid, CellOf(0.01), true);
  FeMeshResult result = MeshFeSource(coarse, nullptr, {});
  result.settings.cell_size = 0.002;
  rig.model.document().Execute(AddMeshOf(coarse, result));
  const ObjectId mesh = rig.model.document().last_created().at(0);
  rig.model.Refresh();
  const DocState before(rig.model.document());
  Job& job = rig.model.StartRefreshJob(&rig.jobs, mesh);
  CancelWhen(&rig.jobs, job, ProgressFor(job, 0.479, 0.3), "refresh tetrahedra (TetGen)");
  EXPECT_TRUE(DocState(rig.model.document()) == before);
}

// ---- FE mode: the precompute (FeMode::Precompute: assembly, then CHOLMOD) ----

// True once the job has been in `phase` for `dwell` seconds.
std::function<bool()> PhaseFor(const Job& job, const std::string& phase, double dwell) {
  auto entered = std::make_shared<Clock::time_point>();
  auto seen = std::make_shared<bool>(false);
  return [&job, phase, dwell, entered, seen] {
    if (job.phase() != phase) return false;
    if (!*seen) {
      *seen = true;
      *entered = Clock::now();
    }
    return Since(*entered) >= dwell;
  };
}

TEST(JobCancel, FePrecomputeEndsWithinHalfASecondInsideCholmod) {
  WorkerScope worker;
  SceneModel scene;
  scene.Load(PlatformScenePath(), Eigen::Vector3d::Constant(0.2));
  // The precompute reads only the mode's mesh; the document is checked all the same.
  const DocState before(scene.document());
  JobQueue jobs;
  FeMode mode(nullptr, &jobs);  // no renderer: VTK data only
  // P2 on the platform at 8 mm: CHOLMOD factorises for seconds (docs/limits.md).
  mode.SetMesh(MeshSceneSolidForFe(PlatformScenePath(), "platform", 0.008), "platform");
  mode.model_settings().order = 2;
  mode.model_settings().use_disk_cache = false;
  mode.Precompute();
  ASSERT_FALSE(jobs.jobs().empty());
  Job& job = *jobs.jobs().back();
  CancelWhen(&jobs, job, PhaseFor(job, "factor", 0.3), "FE precompute (CHOLMOD)");
  EXPECT_EQ(mode.model(), nullptr);
  EXPECT_TRUE(DocState(scene.document()) == before);
  // Afterwards a precompute in this process lands its model (the child path again).
  jobs.Prune();
  mode.SetMesh(MeshSceneSolidForFe(PlatformScenePath(), "platform", 0.012), "platform");
  mode.Precompute();
  jobs.jobs().back()->Wait();
  jobs.Poll();
  ASSERT_NE(mode.model(), nullptr) << mode.status();
  EXPECT_TRUE(mode.model()->factor_status().converged);
}

// In slabs the factorisation runs in this process, slab by slab: a cancel ends it before the
// next slab (or the interface), and nothing is kept.
TEST(JobCancel, FePrecomputeInSlabsEndsBeforeTheNextSlab) {
  SceneModel scene;
  scene.Load(PlatformScenePath(), Eigen::Vector3d::Constant(0.2));
  const DocState before(scene.document());
  JobQueue jobs;
  FeMode mode(nullptr, &jobs);
  // P2 on the platform at 8 mm in four slabs: each slab's CHOLMOD factorisation takes a second
  // or more.
  const SceneSolidGrid grid = PrepareSceneSolid(PlatformScenePath(), "platform", 0.008);
  const SlabFeMesh slabs = MeshSolidInSlabs(grid.compiled, grid.bounds, grid.cell,
                                            SlabPlanes(grid.bounds, grid.cell, kFeSlabs));
  mode.SetMesh(slabs.mesh, "platform", slabs.slab);
  mode.model_settings().order = 2;
  mode.model_settings().use_disk_cache = false;
  mode.Precompute();
  ASSERT_FALSE(jobs.jobs().empty());
  Job& job = *jobs.jobs().back();
  CancelWhen(&jobs, job, PhaseFor(job, "factor slabs", 0.3), "FE precompute in slabs");
  EXPECT_EQ(mode.model(), nullptr);
  EXPECT_TRUE(DocState(scene.document()) == before);
}

// ---- sculpt mode: a sculpt copy of a solid (SculptMode::RequestCopy) ----

struct SculptRig {
  vtkNew<vtkRenderer> renderer;
  JobQueue jobs;
  SceneModel model;
  SculptMode mode{renderer, &jobs};
  ModeContext context;
  ObjectId solid = 0;
  SculptRig() {
    model.Load(kNoSceneName, Eigen::Vector3d::Constant(0.2));
    context.model = &model;
    context.jobs = &jobs;
    mode.session().settings().tool.radius = 0.002;
    model.document().Execute(edit::AddSolid("ball", Ball(0.05)));
    solid = model.document().last_created().at(0);
    model.Refresh();
    mode.SetActive(true);
    Frame();
  }
  void Frame() {
    haptics::ToolState state;
    state.tool_W.p_WT = Eigen::Vector3d(0, 0, 1);  // away from the clay, grasp open
    mode.Update(state, context);
  }
  Job& StartCopy(double cell) {
    mode.set_mesh_cell(cell);
    mode.RequestCopy(solid);
    Frame();
    EXPECT_TRUE(mode.copy_pending()) << mode.message();
    return *jobs.jobs().back();
  }
};

TEST(JobCancel, SculptCopyEndsWithinHalfASecondWhileMeshing) {
  SculptRig rig;
  const DocState before(rig.model.document());
  Job& job = rig.StartCopy(0.0004);
  CancelWhen(&rig.jobs, job, PhaseIs(job, "surface", 0.05), "sculpt copy (surface)");
  rig.Frame();
  EXPECT_TRUE(DocState(rig.model.document()) == before);
  EXPECT_EQ(rig.mode.target(), 0u);
}

// Sculpt mode's Tetrahedralize for FE (SculptSession::StartTetrahedralize) on a fine clay.
TEST(JobCancel, TetrahedralizeClayEndsWithinHalfASecondInsideTetgen) {
  WorkerScope worker;
  SculptRig rig;
  const DocState before(rig.model.document());
  rig.mode.session().SetMesh(modeling::IcosphereMesh(0.05, 6), 0.002);  // 81,920 triangles
  ASSERT_TRUE(rig.mode.session().StartTetrahedralize(&rig.jobs));
  Job& job = *rig.jobs.jobs().back();
  // 0.2 + 0.8 × 0.2: checked, inside TetGen.
  CancelWhen(&rig.jobs, job, ProgressFor(job, 0.36, 0.3), "tetrahedralize clay (TetGen)");
  EXPECT_EQ(rig.mode.session().tet_mesh(), nullptr);
  EXPECT_TRUE(DocState(rig.model.document()) == before);
}

}  // namespace
}  // namespace spidarcad::app
