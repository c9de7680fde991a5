// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
// Sculpt mode without a window: scripted tool states drive strokes on a sphere of clay; undo and
// redo restore positions exactly; the sculpt tool field renders −k·s·Δp inside a stroke and zero
// outside, without allocating; the TetGen job changes nothing when it fails. With a Document (a
// SceneModel and a ModeContext, no window): a stroke is one command, undo and redo in the
// Document reload the session exactly; sculpt copies of a solid (a Job) and of a closed mesh are
// one AddSculpt each, and a copy whose solid changed while it was meshed is dropped.
#include "gui/sculpt_mode.h"

#include <gtest/gtest.h>
#include <vtkActor.h>
#include <vtkActorCollection.h>
#include <vtkMapper.h>
#include <vtkNew.h>
#include <vtkPolyData.h>
#include <vtkRenderer.h>

#include <cmath>
#include <memory>
#include <numbers>
#include <vector>

#include "doc/command.h"
#include "doc/job.h"
#include "gui/mode.h"
#include "scene/scene_model.h"
#include "scene/sculpt_field.h"
#include "spidarcad/modeling/sculpt.h"
#include "support/malloc_counter.h"

namespace spidarcad::app {
namespace {

using modeling::SculptTool;

constexpr double kDeg = std::numbers::pi / 180.0;
constexpr double kRadius = 0.05;  // sphere of clay, m

haptics::ToolKinematics ToolAt(const Eigen::Vector3d& p, double grasp_deg) {
  haptics::ToolKinematics tool;
  tool.p_WT = p;
  tool.grasp = grasp_deg * kDeg;
  return tool;
}

// Index of the vertex with the largest z (the sphere's top).
int TopVertex(const modeling::SculptMesh& mesh) {
  int best = 0;
  for (int v = 0; v < mesh.vertex_count(); ++v) {
    if (mesh.positions()[v].z() > mesh.positions()[best].z()) best = v;
  }
  return best;
}

std::unique_ptr<SculptSession> MakeSession(SculptTool tool = SculptTool::kGrab,
                                           double max_edge = 0.0) {
  auto owner = std::make_unique<SculptSession>();
  SculptSession& session = *owner;
  session.settings().tool.tool = tool;
  session.settings().tool.radius = 0.02;
  session.settings().tool.stiffness = modeling::kReferenceSculptStiffness;  // falloff exponent 3
  session.settings().tool.grasp_closed_angle = 45.0 * kDeg;
  session.settings().tool.max_edge_length = max_edge;
  session.settings().stroke_begin_angle = 70.0 * kDeg;
  session.settings().stroke_end_angle = 80.0 * kDeg;
  session.SetMesh(modeling::IcosphereMesh(kRadius, 4));
  return owner;
}

TEST(SculptSession, GraspStrokeMovesGrabbedVertexByGripMotionAndUndoRestoresExactly) {
  auto owner = MakeSession();
  SculptSession& session = *owner;
  const modeling::SculptMesh& mesh = *session.mesh();
  const std::vector<Eigen::Vector3d> before = mesh.positions();
  const int top = TopVertex(mesh);
  const Eigen::Vector3d p0 = before[top];

  // Open grip at the surface: nothing happens.
  EXPECT_EQ(session.Step(ToolAt(p0, 90.0), false), SculptFrameEvent::kIdle);
  // Close fully (below the closed angle: strength 1): the stroke begins.
  EXPECT_EQ(session.Step(ToolAt(p0, 30.0), false), SculptFrameEvent::kBegan);
  EXPECT_TRUE(session.stroke_active());
  // Move 1 cm up in ten frames.
  const Eigen::Vector3d delta(0.0, 0.0, 0.01);
  for (int i = 1; i <= 10; ++i) {
    EXPECT_EQ(session.Step(ToolAt(p0 + delta * (i / 10.0), 30.0), false),
              SculptFrameEvent::kUpdated);
  }
  // Open: the stroke ends.
  EXPECT_EQ(session.Step(ToolAt(p0 + delta, 90.0), false), SculptFrameEvent::kEnded);
  EXPECT_FALSE(session.stroke_active());
  ASSERT_EQ(session.undo_count(), 1);

  const std::vector<Eigen::Vector3d> after = mesh.positions();
  EXPECT_NEAR((after[top] - before[top]).norm(), 0.01, 1e-12);
  // Every other vertex: Δp scaled by the falloff (1 − (r/R)²)³, computed here from the start
  // positions (grab tool, no volume conservation, strength 1).
  int moved = 0;
  for (int v = 0; v < mesh.vertex_count(); ++v) {
    const double r = (before[v] - p0).norm();
    const double q = r / 0.02;
    const double w = q < 1.0 ? std::pow(1.0 - q * q, 3.0) : 0.0;
    ASSERT_LT((after[v] - (before[v] + w * delta)).norm(), 1e-12) << "vertex " << v;
    if (w > 0.0) ++moved;
  }
  EXPECT_GT(moved, 10);

  ASSERT_TRUE(session.Undo());
  for (int v = 0; v < mesh.vertex_count(); ++v)
    ASSERT_EQ(mesh.positions()[v], before[v]) << "vertex " << v;
  ASSERT_TRUE(session.Redo());
  for (int v = 0; v < mesh.vertex_count(); ++v)
    ASSERT_EQ(mesh.positions()[v], after[v]) << "vertex " << v;
}

TEST(SculptSession, RefinedStrokeUndoRestoresTopologyAndPositions) {
  auto owner = MakeSession(SculptTool::kGrab, 0.003);
  SculptSession& session = *owner;
  const modeling::SculptMesh& mesh = *session.mesh();
  const std::vector<Eigen::Vector3d> before = mesh.positions();
  const std::vector<Eigen::Vector3i> triangles = mesh.triangles();
  const Eigen::Vector3d p0 = before[TopVertex(mesh)];
  ASSERT_EQ(session.Step(ToolAt(p0, 30.0), false), SculptFrameEvent::kBegan);
  session.Step(ToolAt(p0 + Eigen::Vector3d(0, 0, 0.02), 30.0), false);
  ASSERT_EQ(session.Step(ToolAt(p0 + Eigen::Vector3d(0, 0, 0.02), 90.0), false),
            SculptFrameEvent::kEnded);
  EXPECT_GT(mesh.vertex_count(), static_cast<int>(before.size()));  // stretched edges were split
  const std::uint64_t revision = session.revision();
  ASSERT_TRUE(session.Undo());
  EXPECT_GT(session.revision(), revision);
  ASSERT_EQ(mesh.vertex_count(), static_cast<int>(before.size()));
  ASSERT_EQ(mesh.triangle_count(), static_cast<int>(triangles.size()));
  for (int v = 0; v < mesh.vertex_count(); ++v) ASSERT_EQ(mesh.positions()[v], before[v]);
  for (int t = 0; t < mesh.triangle_count(); ++t) ASSERT_EQ(mesh.triangles()[t], triangles[t]);
}

TEST(SculptSession, ClosingGraspAwayFromClayBeginsNoStroke) {
  auto owner = MakeSession();
  SculptSession& session = *owner;
  const Eigen::Vector3d far(0.0, 0.0, kRadius + 0.05);  // 5 cm above the top, radius 2 cm
  EXPECT_EQ(session.Step(ToolAt(far, 30.0), false), SculptFrameEvent::kNoClayInReach);
  EXPECT_FALSE(session.stroke_active());
  EXPECT_FALSE(session.published_model().active);
}

TEST(SculptSession, KeyHeldStrokeUsesFullStrengthAndEndsOnRelease) {
  auto owner = MakeSession();
  SculptSession& session = *owner;
  const modeling::SculptMesh& mesh = *session.mesh();
  const int top = TopVertex(mesh);
  const Eigen::Vector3d p0 = mesh.positions()[top];
  const Eigen::Vector3d start = p0;
  // Grasp at rest (strength 0 if the grasp controlled it), key held: full strength.
  ASSERT_EQ(session.Step(ToolAt(p0, 90.0), true), SculptFrameEvent::kBegan);
  EXPECT_EQ(session.Step(ToolAt(p0 + Eigen::Vector3d(0.005, 0, 0), 90.0), true),
            SculptFrameEvent::kUpdated);
  EXPECT_NEAR((mesh.positions()[top] - (start + Eigen::Vector3d(0.005, 0, 0))).norm(), 0.0, 1e-12);
  EXPECT_EQ(session.Step(ToolAt(p0, 90.0), false), SculptFrameEvent::kEnded);
}

TEST(SculptToolField, ZeroOutsideStrokeAndMinusKSDeltaPInside) {
  auto owner = MakeSession();
  SculptSession& session = *owner;
  auto field = session.MakeField();
  const int top = TopVertex(*session.mesh());
  // The grip 3 mm above the surface: the stroke snaps to the top vertex.
  const Eigen::Vector3d p_start = session.mesh()->positions()[top] + Eigen::Vector3d(0, 0, 0.003);
  const Eigen::Vector3d dp(0.004, -0.002, 0.01);

  haptics::ToolWrench w = field->Evaluate(ToolAt(p_start + dp, 60.0));
  EXPECT_EQ(w.f_T_W, Eigen::Vector3d::Zero());
  EXPECT_EQ(w.m_T_W, Eigen::Vector3d::Zero());
  EXPECT_EQ(w.g, 0.0);

  const double grasp_deg = 60.0;  // below the 70° trigger; strength (90 − 60) / (90 − 45) = 2/3
  ASSERT_EQ(session.Step(ToolAt(p_start, grasp_deg), false), SculptFrameEvent::kBegan);
  EXPECT_NEAR((session.snap_offset() - Eigen::Vector3d(0, 0, -0.003)).norm(), 0.0, 1e-15);
  const double k = modeling::kReferenceSculptStiffness;
  const double s = 2.0 / 3.0;
  w = field->Evaluate(ToolAt(p_start + dp, grasp_deg));
  EXPECT_LT((w.f_T_W - (-k * s * dp)).norm(), 1e-9) << w.f_T_W.transpose();
  EXPECT_LT(w.m_T_W.norm(), 1e-12);
  // At the start pose the spring is relaxed.
  w = field->Evaluate(ToolAt(p_start, grasp_deg));
  EXPECT_LT(w.f_T_W.norm(), 1e-12);
  // The mesh follows the same snapped motion: the grabbed vertex moved by s·Δp.
  const Eigen::Vector3d grabbed = session.mesh()->positions()[top];
  session.Step(ToolAt(p_start + dp, grasp_deg), false);
  EXPECT_LT((session.mesh()->positions()[top] - (grabbed + s * dp)).norm(), 1e-12);

  ASSERT_EQ(session.Step(ToolAt(p_start + dp, 90.0), false), SculptFrameEvent::kEnded);
  w = field->Evaluate(ToolAt(p_start + 2 * dp, grasp_deg));
  EXPECT_EQ(w.f_T_W, Eigen::Vector3d::Zero());
}

TEST(SculptToolField, EvaluateAllocatesNothing) {
  ASSERT_TRUE(test_support::MallocCounterActive());
  auto owner = MakeSession(SculptTool::kTwist);
  SculptSession& session = *owner;
  auto field = session.MakeField();
  const Eigen::Vector3d p0 = session.mesh()->positions()[TopVertex(*session.mesh())];
  field->Evaluate(ToolAt(p0, 30.0));  // reader side of the channel warmed up
  ASSERT_EQ(session.Step(ToolAt(p0, 30.0), false), SculptFrameEvent::kBegan);
  haptics::ToolKinematics tool = ToolAt(p0, 30.0);
  double sum = 0.0;
  long allocations = 0;
  {
    test_support::MallocCounter counter;
    for (int i = 0; i < 1000; ++i) {
      tool.R_WT = Eigen::AngleAxisd(1e-4 * i, Eigen::Vector3d::UnitZ()).toRotationMatrix();
      sum += field->Evaluate(tool).m_T_W.norm();
    }
    allocations = counter.count();
  }
  EXPECT_EQ(allocations, 0);
  EXPECT_GT(sum, 0.0);  // the twist resists: the loop did real work
}

// Two overlapping spheres as one mesh: closed and oriented, but self-intersecting.
modeling::TriangleMesh OverlappingSpheres() {
  const modeling::TriangleMesh a = modeling::IcosphereMesh(0.03, 2);
  modeling::TriangleMesh m;
  const long n = a.vertices.cols();
  m.vertices.resize(3, 2 * n);
  m.vertices.leftCols(n) = a.vertices;
  m.vertices.rightCols(n) = a.vertices.colwise() + Eigen::Vector3d(0.02, 0.0, 0.0);
  m.triangles.resize(3, 2 * a.triangles.cols());
  m.triangles.leftCols(a.triangles.cols()) = a.triangles;
  m.triangles.rightCols(a.triangles.cols()) = a.triangles.array() + static_cast<int>(n);
  return m;
}

void RunJobs(JobQueue* jobs) {
  for (const auto& job : jobs->jobs()) job->Wait();
  jobs->Poll();
}

TEST(SculptSession, TetrahedralizeFailureChangesNothingAndSuccessLands) {
  JobQueue jobs;
  SculptSession session;
  session.SetMesh(OverlappingSpheres(), 0.01);
  ASSERT_TRUE(session.StartTetrahedralize(&jobs));
  RunJobs(&jobs);
  EXPECT_EQ(jobs.jobs().back()->state(), Job::State::kFailed);
  EXPECT_EQ(session.tet_mesh(), nullptr);
  EXPECT_EQ(session.job_message().rfind("Tetrahedralize failed: ", 0), 0u) << session.job_message();

  session.SetMesh(modeling::IcosphereMesh(0.03, 2), 0.01);
  ASSERT_TRUE(session.StartTetrahedralize(&jobs));
  RunJobs(&jobs);
  EXPECT_EQ(jobs.jobs().back()->state(), Job::State::kSucceeded) << jobs.jobs().back()->error();
  ASSERT_NE(session.tet_mesh(), nullptr);
  EXPECT_GE(session.tet_mesh()->nodes.cols(), 162);  // the surface's vertices come first
  EXPECT_GT(session.tet_mesh()->tets.cols(), 0);
  const auto tets = session.tet_mesh();
  // A later failure leaves the last good tet mesh in place.
  session.SetMesh(OverlappingSpheres(), 0.01);
  EXPECT_EQ(session.tet_mesh(), nullptr);  // a new clay drops the old tets
  ASSERT_TRUE(session.StartTetrahedralize(&jobs));
  RunJobs(&jobs);
  EXPECT_EQ(session.tet_mesh(), nullptr);
}

TEST(SculptSession, MeshSceneJobLoadsClayScene) {
  JobQueue jobs;
  SculptSession session;
  session.StartMeshScene(&jobs, std::string(SPIDARCAD_SOURCE_DIR) + "/assets/scenes/clay.json",
                         0.006);
  RunJobs(&jobs);
  ASSERT_EQ(jobs.jobs().back()->state(), Job::State::kSucceeded) << jobs.jobs().back()->error();
  ASSERT_TRUE(session.has_mesh());
  // The blob is about 0.2 m across: its volume lies between the largest lobe's sphere and a
  // 0.2 m cube.
  const double v = session.mesh()->ComputeVolume();
  EXPECT_GT(v, 4.0 / 3.0 * std::numbers::pi * std::pow(0.06, 3));
  EXPECT_LT(v, 0.2 * 0.2 * 0.2);
  // A missing file fails and leaves the clay.
  const int vertices = session.mesh()->vertex_count();
  session.StartMeshScene(&jobs, "/nonexistent/clay.json", 0.006);
  RunJobs(&jobs);
  EXPECT_EQ(jobs.jobs().back()->state(), Job::State::kFailed);
  EXPECT_EQ(session.mesh()->vertex_count(), vertices);
  EXPECT_FALSE(session.job_message().empty());
}

// The thin VTK layer without a window: a stroke frame writes the touched points into the
// actor's polydata in place; undo rebuilds it. No ImGui context: the G key reads as up.
TEST(SculptMode, StrokeFrameUpdatesActorPointsInPlaceAndUndoRebuilds) {
  vtkNew<vtkRenderer> renderer;
  JobQueue jobs;
  SculptMode mode(renderer, &jobs);
  mode.session().settings().tool.radius = 0.02;
  mode.LoadMesh(modeling::IcosphereMesh(kRadius, 3));
  mode.SetActive(true);
  ASSERT_NE(mode.TakeField(), nullptr);
  EXPECT_EQ(mode.TakeField(), nullptr);  // once per activation
  // The clay actor is the one whose input has the mesh's vertex count.
  vtkPolyData* poly = nullptr;
  vtkActorCollection* actors = renderer->GetActors();
  actors->InitTraversal();
  for (vtkActor* a = actors->GetNextActor(); a; a = actors->GetNextActor()) {
    auto* data = vtkPolyData::SafeDownCast(a->GetMapper()->GetInput());
    if (data && data->GetNumberOfPoints() == mode.session().mesh()->vertex_count()) poly = data;
  }
  ASSERT_NE(poly, nullptr);
  const int top = TopVertex(*mode.session().mesh());
  const Eigen::Vector3d p0 = mode.session().mesh()->positions()[top];
  vtkPoints* points = poly->GetPoints();
  haptics::ToolState state;
  state.tool_W = ToolAt(p0, 30.0);
  mode.OnFrame(state);
  ASSERT_TRUE(mode.session().stroke_active());
  const vtkMTimeType stamp = points->GetMTime();
  state.tool_W = ToolAt(p0 + Eigen::Vector3d(0, 0, 0.01), 30.0);
  mode.OnFrame(state);
  EXPECT_EQ(poly->GetPoints(), points);  // same array, modified in place
  EXPECT_GT(points->GetMTime(), stamp);
  double xyz[3];
  points->GetPoint(top, xyz);
  EXPECT_NEAR(xyz[2], p0.z() + 0.01, 1e-6);  // float storage
  state.tool_W = ToolAt(p0 + Eigen::Vector3d(0, 0, 0.01), 90.0);
  mode.OnFrame(state);
  ASSERT_TRUE(mode.session().Undo());
  mode.OnFrame(state);
  poly->GetPoints()->GetPoint(top, xyz);
  EXPECT_NEAR(xyz[2], p0.z(), 1e-6);
  mode.SetActive(false);
  EXPECT_FALSE(mode.session().published_model().active);
}

// ---- with a Document ----

// The sculpt mesh of object id in the model's Document.
const SculptMesh& DocMesh(const SceneModel& model, ObjectId id) {
  return *std::get<SculptData>(model.document().Get(id).data).mesh;
}

// True when the session's clay has exactly the vertices and triangles of `mesh`.
bool SessionHolds(SculptMode& mode, const modeling::TriangleMesh& mesh) {
  const modeling::SculptMesh* clay = mode.session().mesh();
  if (clay == nullptr || clay->vertex_count() != mesh.vertices.cols() ||
      clay->triangle_count() != mesh.triangles.cols())
    return false;
  for (int v = 0; v < clay->vertex_count(); ++v) {
    if (clay->positions()[v] != Eigen::Vector3d(mesh.vertices.col(v))) return false;
  }
  for (int t = 0; t < clay->triangle_count(); ++t) {
    if (clay->triangles()[t] != Eigen::Vector3i(mesh.triangles.col(t))) return false;
  }
  return true;
}

bool SameMesh(const modeling::TriangleMesh& a, const modeling::TriangleMesh& b) {
  return a.vertices.cols() == b.vertices.cols() && a.triangles.cols() == b.triangles.cols() &&
         a.vertices == b.vertices && a.triangles == b.triangles;
}

// A sculpt mode on an empty SceneModel's Document, without a window.
struct DocumentRig {
  vtkNew<vtkRenderer> renderer;
  JobQueue jobs;
  SceneModel model;
  SculptMode mode{renderer, &jobs};
  ModeContext context;
  DocumentRig() {
    model.Load(kNoSceneName, Eigen::Vector3d::Constant(0.1));
    context.model = &model;
    context.jobs = &jobs;
    mode.session().settings().tool.radius = 0.02;
  }
  void Frame(const haptics::ToolKinematics& tool) {
    haptics::ToolState state;
    state.tool_W = tool;
    mode.Update(state, context);
  }
  void FinishJobs() {
    for (const auto& job : jobs.jobs()) job->Wait();
    jobs.Poll();
    model.Refresh();
  }
};

TEST(SculptModeDocument, StrokeIsOneCommandAndUndoRedoReloadTheSessionExactly) {
  DocumentRig rig;
  const modeling::TriangleMesh start = modeling::IcosphereMesh(kRadius, 4);
  rig.model.document().Execute(edit::AddSculpt("clay", start));
  const ObjectId clay = rig.model.document().last_created().at(0);
  const std::size_t steps = rig.model.document().history().undo_size();
  rig.mode.SetActive(true);
  ASSERT_NE(rig.mode.TakeField(), nullptr);
  const Eigen::Vector3d away(0.0, 0.0, 1.0);
  rig.Frame(ToolAt(away, 90.0));  // the first Update takes the Document's only sculpt object
  EXPECT_EQ(rig.mode.target(), clay);
  ASSERT_TRUE(SessionHolds(rig.mode, start));

  // A grasp stroke at the top: pulled up 1 cm over five frames, then released.
  const Eigen::Vector3d p0 =
      rig.mode.session().mesh()->positions()[TopVertex(*rig.mode.session().mesh())];
  rig.Frame(ToolAt(p0, 30.0));
  ASSERT_TRUE(rig.mode.session().stroke_active());
  for (int i = 1; i <= 5; ++i) rig.Frame(ToolAt(p0 + Eigen::Vector3d(0, 0, 0.002 * i), 30.0));
  EXPECT_EQ(rig.model.document().history().undo_size(), steps) << "nothing before the stroke ends";
  rig.Frame(ToolAt(p0 + Eigen::Vector3d(0, 0, 0.01), 90.0));
  ASSERT_FALSE(rig.mode.session().stroke_active());
  ASSERT_EQ(rig.model.document().history().undo_size(), steps + 1);
  EXPECT_EQ(rig.model.document().history().UndoDescription(), "Sculpt stroke (grab) on clay");
  const modeling::TriangleMesh sculpted = DocMesh(rig.model, clay);
  EXPECT_FALSE(SameMesh(sculpted, start));
  EXPECT_TRUE(SessionHolds(rig.mode, sculpted));
  EXPECT_EQ(rig.mode.session().undo_count(), 1) << "the session keeps the stroke's edit";
  // The grabbed vertex went up by the grip's motion (grab tool, strength 1).
  EXPECT_NEAR(sculpted.vertices.col(TopVertex(*rig.mode.session().mesh())).z(), p0.z() + 0.01,
              1e-12);

  // Undo in the Document: the next Update brings the session to the original exactly (the
  // session's own inverse edit) and republishes; redo likewise.
  ASSERT_TRUE(rig.model.document().Undo());
  rig.Frame(ToolAt(away, 90.0));
  EXPECT_TRUE(SameMesh(DocMesh(rig.model, clay), start));
  EXPECT_TRUE(SessionHolds(rig.mode, start));
  EXPECT_EQ(rig.mode.session().redo_count(), 1) << "undone in place, not reloaded";
  EXPECT_NE(rig.mode.TakeField(), nullptr) << "an undo republishes the field";
  ASSERT_TRUE(rig.model.document().Redo());
  rig.Frame(ToolAt(away, 90.0));
  EXPECT_TRUE(SessionHolds(rig.mode, sculpted));
  // An edit made elsewhere (a whole new mesh) is reloaded; undoing it reloads the sculpted one.
  const modeling::TriangleMesh other = modeling::IcosphereMesh(0.03, 2);
  rig.model.document().Execute(edit::ReplaceSculptMesh(clay, other));
  rig.Frame(ToolAt(away, 90.0));
  EXPECT_TRUE(SessionHolds(rig.mode, other));
  EXPECT_EQ(rig.mode.session().undo_count(), 0) << "reloaded";
  ASSERT_TRUE(rig.model.document().Undo());
  rig.Frame(ToolAt(away, 90.0));
  EXPECT_TRUE(SessionHolds(rig.mode, sculpted));
  // Undo of the stroke after that reload, then of the object's addition: nothing to sculpt;
  // redo brings it back.
  ASSERT_TRUE(rig.model.document().Undo());
  rig.Frame(ToolAt(away, 90.0));
  EXPECT_TRUE(SessionHolds(rig.mode, start));
  ASSERT_TRUE(rig.model.document().Undo());
  rig.Frame(ToolAt(away, 90.0));
  EXPECT_FALSE(rig.mode.session().has_mesh());
  ASSERT_TRUE(rig.model.document().Redo());
  rig.Frame(ToolAt(away, 90.0));
  EXPECT_TRUE(SessionHolds(rig.mode, start));
}

// Two strokes, one with refinement (new vertices and triangles): undoing both and redoing both
// in the Document leaves the session equal to the Document at every step.
TEST(SculptModeDocument, UndoAndRedoOfRefinedStrokesKeepTheSessionEqualToTheDocument) {
  DocumentRig rig;
  const modeling::TriangleMesh start = modeling::IcosphereMesh(kRadius, 3);
  rig.model.document().Execute(edit::AddSculpt("clay", start));
  const ObjectId clay = rig.model.document().last_created().at(0);
  rig.mode.SetActive(true);
  const Eigen::Vector3d away(0.0, 0.0, 1.0);
  rig.Frame(ToolAt(away, 90.0));
  std::vector<modeling::TriangleMesh> states = {start};
  for (double max_edge : {0.0, 0.003}) {
    rig.mode.session().settings().tool.max_edge_length = max_edge;
    const modeling::SculptMesh& mesh = *rig.mode.session().mesh();
    const Eigen::Vector3d p0 = mesh.positions()[TopVertex(mesh)];
    rig.Frame(ToolAt(p0, 30.0));
    rig.Frame(ToolAt(p0 + Eigen::Vector3d(0, 0, 0.01), 30.0));
    rig.Frame(ToolAt(p0 + Eigen::Vector3d(0, 0, 0.01), 90.0));
    states.push_back(DocMesh(rig.model, clay));
    ASSERT_TRUE(SessionHolds(rig.mode, states.back()));
  }
  ASSERT_GT(states[2].vertices.cols(), states[1].vertices.cols()) << "the second stroke refined";
  for (int k = 1; k >= 0; --k) {
    ASSERT_TRUE(rig.model.document().Undo());
    rig.Frame(ToolAt(away, 90.0));
    EXPECT_TRUE(SameMesh(DocMesh(rig.model, clay), states[k]));
    EXPECT_TRUE(SessionHolds(rig.mode, states[k])) << "after undo to state " << k;
  }
  for (int k = 1; k <= 2; ++k) {
    ASSERT_TRUE(rig.model.document().Redo());
    rig.Frame(ToolAt(away, 90.0));
    EXPECT_TRUE(SessionHolds(rig.mode, states[k])) << "after redo to state " << k;
  }
}

TEST(SculptModeDocument, CopyOfASolidIsMeshedByAJobAndAddedAsOneStep) {
  DocumentRig rig;
  const double r = 0.03;
  rig.model.document().Execute(
      edit::AddSolid("ball", modeling::ImplicitNode(modeling::SphereParams{r})));
  const ObjectId ball = rig.model.document().last_created().at(0);
  rig.model.Refresh();
  rig.mode.set_mesh_cell(0.003);
  rig.mode.SetActive(true);
  const Eigen::Vector3d away(0.0, 0.0, 1.0);
  rig.Frame(ToolAt(away, 90.0));
  EXPECT_EQ(rig.mode.target(), 0u) << "no sculpt object yet";
  const std::size_t steps = rig.model.document().history().undo_size();
  const std::size_t objects = rig.model.document().objects().size();
  rig.mode.RequestCopy(ball);
  rig.Frame(ToolAt(away, 90.0));
  EXPECT_TRUE(rig.mode.copy_pending());
  EXPECT_EQ(rig.model.document().objects().size(), objects) << "nothing until the job lands";
  rig.FinishJobs();
  EXPECT_FALSE(rig.mode.copy_pending());
  ASSERT_EQ(rig.model.document().objects().size(), objects + 1) << rig.mode.message();
  EXPECT_EQ(rig.model.document().history().undo_size(), steps + 1);
  EXPECT_EQ(rig.model.document().history().UndoDescription(), "Add sculpt ball sculpt");
  const DocObject& copy = rig.model.document().objects().back();
  EXPECT_EQ(copy.name, "ball sculpt");
  EXPECT_EQ(rig.mode.target(), copy.id);
  const modeling::TriangleMesh surface = DocMesh(rig.model, copy.id);
  EXPECT_TRUE(SessionHolds(rig.mode, surface));
  // The surface lies on the sphere (within a fraction of the 3 mm cell) and encloses about its
  // volume 4/3 π r³.
  for (Eigen::Index v = 0; v < surface.vertices.cols(); ++v)
    ASSERT_NEAR(surface.vertices.col(v).norm(), r, 0.3 * 0.003) << "vertex " << v;
  const double volume = modeling::MeshVolume(surface);
  EXPECT_NEAR(volume, 4.0 / 3.0 * std::numbers::pi * r * r * r, 0.03 * volume);
  // Undo removes the copy (one step).
  ASSERT_TRUE(rig.model.document().Undo());
  EXPECT_EQ(rig.model.document().objects().size(), objects);
}

TEST(SculptModeDocument, CopyIsDroppedWhenTheSolidChangedWhileMeshing) {
  DocumentRig rig;
  rig.model.document().Execute(
      edit::AddSolid("ball", modeling::ImplicitNode(modeling::SphereParams{0.03})));
  const ObjectId ball = rig.model.document().last_created().at(0);
  rig.model.Refresh();
  rig.mode.set_mesh_cell(0.004);
  rig.mode.SetActive(true);
  rig.Frame(ToolAt(Eigen::Vector3d(0, 0, 1), 90.0));
  rig.mode.RequestCopy(ball);
  rig.Frame(ToolAt(Eigen::Vector3d(0, 0, 1), 90.0));
  ASSERT_TRUE(rig.mode.copy_pending());
  rig.model.document().Execute(edit::SetNodeField(ball, {}, "radius", 0.035));
  const std::string before = rig.model.document().ToJson().dump();
  rig.FinishJobs();
  EXPECT_EQ(rig.model.document().ToJson().dump(), before) << "the result was dropped";
  EXPECT_NE(rig.mode.message().find("changed while it was meshed"), std::string::npos)
      << rig.mode.message();
  EXPECT_EQ(rig.mode.target(), 0u);
}

TEST(SculptModeDocument, CopyOfAClosedMeshIsAddedAtOnceAndAnOpenOneIsRefused) {
  DocumentRig rig;
  Document& doc = rig.model.document();
  const modeling::TriangleMesh sphere = modeling::IcosphereMesh(0.04, 3);
  doc.Execute(edit::AddMesh("shell", 0, 0, std::make_shared<const modeling::TriangleMesh>(sphere),
                            nullptr));
  const ObjectId shell = doc.last_created().at(0);
  modeling::TriangleMesh open_mesh = sphere;
  open_mesh.triangles.conservativeResize(3, open_mesh.triangles.cols() - 1);
  doc.Execute(edit::AddMesh("cup", 0, 0, std::make_shared<const modeling::TriangleMesh>(open_mesh),
                            nullptr));
  const ObjectId cup = doc.last_created().at(0);
  rig.mode.SetActive(true);
  rig.Frame(ToolAt(Eigen::Vector3d(0, 0, 1), 90.0));
  const std::string before = doc.ToJson().dump();
  EXPECT_FALSE(rig.mode.StartCopy(rig.context, cup));
  EXPECT_NE(rig.mode.message().find("'cup'"), std::string::npos) << rig.mode.message();
  EXPECT_EQ(doc.ToJson().dump(), before);
  const std::size_t steps = doc.history().undo_size();
  ASSERT_TRUE(rig.mode.StartCopy(rig.context, shell)) << rig.mode.message();
  EXPECT_EQ(doc.history().undo_size(), steps + 1);
  const ObjectId copy = doc.last_created().at(0);
  EXPECT_EQ(doc.Get(copy).name, "shell sculpt");
  EXPECT_TRUE(SameMesh(DocMesh(rig.model, copy), sphere));
  rig.Frame(ToolAt(Eigen::Vector3d(0, 0, 1), 90.0));
  EXPECT_EQ(rig.mode.target(), copy);
  EXPECT_TRUE(SessionHolds(rig.mode, sphere));
}

}  // namespace
}  // namespace spidarcad::app
