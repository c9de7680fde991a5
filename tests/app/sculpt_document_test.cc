// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
// Sculpt strokes as Document commands (scene/sculpt_document.h): a stroke made on a SculptMesh
// and recorded on a sculpt object leaves the Document's mesh equal to the sculpted one, vertex
// for vertex; undo gives the original back exactly, redo the sculpted one; a stroke whose
// refinement split edges is recorded whole. Closed surfaces are told from open, unoriented and
// non-manifold ones.
#include "scene/sculpt_document.h"

#include <gtest/gtest.h>

#include <memory>
#include <numbers>
#include <string>
#include <vector>

#include "doc/command.h"
#include "doc/document.h"
#include "spidarcad/modeling/sculpt.h"

namespace spidarcad::app {
namespace {

constexpr double kDeg = std::numbers::pi / 180.0;

// True when a and b have the same vertices (bitwise) and triangles.
bool SameMesh(const modeling::TriangleMesh& a, const modeling::TriangleMesh& b) {
  return a.vertices.cols() == b.vertices.cols() && a.triangles.cols() == b.triangles.cols() &&
         a.vertices == b.vertices && a.triangles == b.triangles;
}

// The sculpt mesh of object id.
const SculptMesh& MeshOf(const Document& doc, ObjectId id) {
  return *std::get<SculptData>(doc.Get(id).data).mesh;
}

// Index of the vertex with the largest z.
int TopVertex(const modeling::SculptMesh& mesh) {
  int best = 0;
  for (int v = 0; v < mesh.vertex_count(); ++v) {
    if (mesh.positions()[v].z() > mesh.positions()[best].z()) best = v;
  }
  return best;
}

// A grab stroke at the top vertex of `mesh`, pulled up by `lift` m at full strength.
modeling::SculptEdit PullTop(modeling::SculptMesh* mesh, double lift, double max_edge = 0.0) {
  modeling::SculptToolSettings tool;
  tool.tool = modeling::SculptTool::kGrab;
  tool.radius = 0.02;
  tool.max_edge_length = max_edge;
  Eigen::Isometry3d X = Eigen::Isometry3d::Identity();
  X.translation() = mesh->positions()[TopVertex(*mesh)];
  mesh->BeginStroke(tool, X, 30.0 * kDeg);
  X.translation().z() += lift;
  mesh->UpdateStroke(X, 30.0 * kDeg);
  return mesh->EndStroke();
}

// A document with a mesh object holding `mesh` as its surface; returns its id.
ObjectId AddSurface(Document* doc, const modeling::TriangleMesh& mesh) {
  doc->Execute(
      edit::AddMesh("m", 0, 0, std::make_shared<const modeling::TriangleMesh>(mesh), nullptr));
  return doc->last_created().at(0);
}

TEST(SculptableSurface, AcceptsAClosedMeshAndRejectsHolesFlipsAndDoubledTriangles) {
  const modeling::TriangleMesh sphere = modeling::IcosphereMesh(0.05, 2);
  Document doc;
  EXPECT_NE(SculptableSurface(doc.Get(AddSurface(&doc, sphere))), nullptr);
  modeling::TriangleMesh hole = sphere;
  hole.triangles.conservativeResize(3, hole.triangles.cols() - 1);  // one triangle gone
  EXPECT_EQ(SculptableSurface(doc.Get(AddSurface(&doc, hole))), nullptr);
  modeling::TriangleMesh flipped = sphere;
  std::swap(flipped.triangles(1, 7), flipped.triangles(2, 7));  // one triangle turned over
  EXPECT_EQ(SculptableSurface(doc.Get(AddSurface(&doc, flipped))), nullptr);
  modeling::TriangleMesh doubled = sphere;  // every triangle twice: each edge in 4 triangles
  doubled.triangles.conservativeResize(3, 2 * sphere.triangles.cols());
  doubled.triangles.rightCols(sphere.triangles.cols()) = sphere.triangles;
  EXPECT_EQ(SculptableSurface(doc.Get(AddSurface(&doc, doubled))), nullptr);
  // A mesh object without a surface (tetrahedra only) has none either.
  auto tets = std::make_shared<modeling::TetMesh>();
  tets->nodes = sphere.vertices.leftCols(4);
  tets->tets.resize(4, 1);
  tets->tets << 0, 1, 2, 3;
  tets->regions = Eigen::VectorXi::Zero(1);
  doc.Execute(edit::AddMesh("t", 0, 0, nullptr, tets));
  EXPECT_EQ(SculptableSurface(doc.Get(doc.last_created().at(0))), nullptr);
}

TEST(CanSculptCopyOf, SolidsAndClosedMeshesOnly) {
  Document doc;
  doc.Execute(edit::AddSolid("ball", modeling::ImplicitNode(modeling::SphereParams{0.03})));
  const ObjectId ball = doc.last_created().at(0);
  auto closed = std::make_shared<const modeling::TriangleMesh>(modeling::IcosphereMesh(0.05, 1));
  doc.Execute(edit::AddMesh("closed", 0, 0, closed, nullptr));
  const ObjectId closed_id = doc.last_created().at(0);
  modeling::TriangleMesh open_mesh = *closed;
  open_mesh.triangles.conservativeResize(3, open_mesh.triangles.cols() - 2);
  doc.Execute(edit::AddMesh("open", 0, 0, std::make_shared<const modeling::TriangleMesh>(open_mesh),
                            nullptr));
  const ObjectId open_id = doc.last_created().at(0);
  doc.Execute(edit::AddSculpt("clay", *closed));
  const ObjectId clay = doc.last_created().at(0);
  EXPECT_TRUE(CanSculptCopyOf(doc.Get(ball)));
  EXPECT_TRUE(CanSculptCopyOf(doc.Get(closed_id)));
  EXPECT_EQ(SculptableSurface(doc.Get(closed_id)).get(), closed.get());
  EXPECT_FALSE(CanSculptCopyOf(doc.Get(open_id)));
  EXPECT_EQ(SculptableSurface(doc.Get(open_id)), nullptr);
  EXPECT_FALSE(CanSculptCopyOf(doc.Get(clay)));          // sculpted directly, not copied
  EXPECT_EQ(SculptableSurface(doc.Get(ball)), nullptr);  // solids are meshed by a Job
}

TEST(SculptStrokeTitle, NamesToolAndObject) {
  EXPECT_EQ(SculptStrokeTitle(modeling::SculptTool::kGrab, "clay"), "Sculpt stroke (grab) on clay");
  EXPECT_EQ(SculptStrokeTitle(modeling::SculptTool::kPushPull, "lump 2"),
            "Sculpt stroke (push/pull) on lump 2");
}

TEST(MakeStrokeCommand, RecordsMovedVerticesAndUndoRedoRestoreExactly) {
  const modeling::TriangleMesh start = modeling::IcosphereMesh(0.05, 4);
  Document doc;
  doc.Execute(edit::AddSculpt("clay", start));
  const ObjectId clay = doc.last_created().at(0);
  modeling::SculptMesh mesh(start, 0.007);
  const modeling::SculptEdit edit = PullTop(&mesh, 0.01);
  const modeling::TriangleMesh sculpted = mesh.ToTriangleMesh();
  ASSERT_FALSE(SameMesh(sculpted, start));
  auto command = MakeStrokeCommand(clay, "clay", modeling::SculptTool::kGrab, edit, mesh);
  ASSERT_NE(command, nullptr);
  EXPECT_EQ(command->Description(), "Sculpt stroke (grab) on clay");
  const std::uint64_t before = doc.Get(clay).revision;
  doc.Execute(std::move(command));
  EXPECT_NE(doc.Get(clay).revision, before);
  EXPECT_EQ(doc.history().UndoDescription(), "Sculpt stroke (grab) on clay");
  EXPECT_TRUE(SameMesh(MeshOf(doc, clay), sculpted));
  ASSERT_TRUE(doc.Undo());
  EXPECT_TRUE(SameMesh(MeshOf(doc, clay), start));
  EXPECT_EQ(doc.Get(clay).revision, before);
  ASSERT_TRUE(doc.Redo());
  EXPECT_TRUE(SameMesh(MeshOf(doc, clay), sculpted));
}

TEST(MakeStrokeCommand, RefinedStrokeReplacesTheWholeMesh) {
  const modeling::TriangleMesh start = modeling::IcosphereMesh(0.05, 3);
  Document doc;
  doc.Execute(edit::AddSculpt("clay", start));
  const ObjectId clay = doc.last_created().at(0);
  modeling::SculptMesh mesh(start, 0.007);
  const modeling::SculptEdit edit = PullTop(&mesh, 0.02, 0.003);
  ASSERT_GT(mesh.vertex_count(), static_cast<int>(start.vertices.cols()));  // edges were split
  const modeling::TriangleMesh sculpted = mesh.ToTriangleMesh();
  auto command = MakeStrokeCommand(clay, "clay", modeling::SculptTool::kGrab, edit, mesh);
  ASSERT_NE(command, nullptr);
  doc.Execute(std::move(command));
  EXPECT_EQ(doc.history().UndoDescription(), "Sculpt stroke (grab) on clay");
  EXPECT_TRUE(SameMesh(MeshOf(doc, clay), sculpted));
  ASSERT_TRUE(doc.Undo());
  EXPECT_TRUE(SameMesh(MeshOf(doc, clay), start));
  ASSERT_TRUE(doc.Redo());
  EXPECT_TRUE(SameMesh(MeshOf(doc, clay), sculpted));
}

TEST(MakeStrokeCommand, StrokeThatMovedNothingRecordsNothing) {
  modeling::SculptMesh mesh(modeling::IcosphereMesh(0.05, 2), 0.007);
  const modeling::SculptEdit edit = PullTop(&mesh, 0.0);
  EXPECT_EQ(MakeStrokeCommand(1, "clay", modeling::SculptTool::kGrab, edit, mesh), nullptr);
}

}  // namespace
}  // namespace spidarcad::app
