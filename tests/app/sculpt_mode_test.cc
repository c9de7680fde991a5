// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
// Sculpt mode without a window: scripted tool states drive strokes on a sphere of clay; undo and
// redo restore positions exactly; the sculpt tool field renders −k·s·Δp inside a stroke and zero
// outside, without allocating; the TetGen job changes nothing when it fails.
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

#include "doc/job.h"
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

}  // namespace
}  // namespace spidarcad::app
