// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
// Tests of the scene view's imported meshes (no display needed: actors are not rendered here):
// the surface drawn for a mesh object (its surface, else the boundary of its tetrahedra, checked
// against the faces of two tets sharing one face, counted by hand), and SceneView::Sync giving
// an imported mesh object an actor with the mesh's bounds in D, none to a mesh made from a solid,
// and dropping the actor when the import is undone.
#include "gui/scene_view.h"

#include <gtest/gtest.h>
#include <vtkActor.h>
#include <vtkNew.h>
#include <vtkRenderer.h>

#include <memory>

#include "doc/command.h"
#include "scene/grip_control.h"

namespace spidarcad::app {
namespace {

// Two positively oriented tets sharing the face (1, 2, 3): 6 boundary faces over 5 nodes.
modeling::TetMesh TwoTets() {
  modeling::TetMesh m;
  m.nodes.resize(3, 5);
  m.nodes << 0, 1, 0, 0, 1, 0, 0, 1, 0, 1, 0, 0, 0, 1, 1;
  m.tets.resize(4, 2);
  m.tets.col(0) << 0, 1, 2, 3;
  m.tets.col(1) << 4, 2, 1, 3;
  m.regions = Eigen::VectorXi::Zero(2);
  return m;
}

TEST(DrawnSurface, IsTheBoundaryOfTheTetrahedraWhenThereIsNoSurface) {
  const modeling::TetMesh tets = TwoTets();
  ASSERT_GT(modeling::TetVolume(tets, 0), 0.0);
  ASSERT_GT(modeling::TetVolume(tets, 1), 0.0);
  MeshData data;
  data.volume = std::make_shared<modeling::TetMesh>(tets);
  const modeling::TriangleMesh boundary = DrawnSurface(data);
  EXPECT_EQ(boundary.triangles.cols(), 6);  // 2 × 4 faces, less the shared one twice
  EXPECT_EQ(boundary.vertices.cols(), 5);
  // The shared face (1, 2, 3) is not drawn: no triangle has exactly those corners.
  for (Eigen::Index t = 0; t < boundary.triangles.cols(); ++t) {
    Eigen::Vector3d sum = Eigen::Vector3d::Zero();
    for (int k = 0; k < 3; ++k) sum += boundary.vertices.col(boundary.triangles(k, t));
    EXPECT_FALSE(sum.isApprox(Eigen::Vector3d(1, 1, 1))) << "the shared face, triangle " << t;
  }
  // With a surface, the surface itself.
  modeling::TriangleMesh surface;
  surface.vertices = Eigen::Matrix3Xd::Identity(3, 3);
  surface.triangles.resize(3, 1);
  surface.triangles << 0, 1, 2;
  data.surface = std::make_shared<modeling::TriangleMesh>(surface);
  EXPECT_EQ(DrawnSurface(data).triangles.cols(), 1);
  EXPECT_EQ(DrawnSurface(MeshData{}).triangles.cols(), 0);
}

TEST(SceneView, DrawsImportedMeshesAtTheirBoundsAndNotMeshesOfASolid) {
  SceneModel model;
  model.Load(kDemoSceneName, GripControl(haptics::SpidarGeometry{}).limits());
  const DeviceToWorld x = model.device_to_world();
  ASSERT_GT(x.world_scale, 0.0);
  Document& doc = model.document();
  auto tets = std::make_shared<modeling::TetMesh>(TwoTets());
  tets->nodes *= 0.05;  // a 5 cm pair of tets
  doc.Execute(std::make_unique<ImportMeshCommand>("pair", "pair.vtu", nullptr, tets));
  const ObjectId imported = doc.last_created().at(0);
  // A mesh of the bracket (a solid): drawn by the solid's actor, not again.
  doc.Execute(
      edit::AddMesh("bracket tets", doc.objects()[0].id, doc.objects()[0].revision, nullptr, tets));
  const ObjectId generated = doc.last_created().at(0);
  model.Refresh();
  vtkNew<vtkRenderer> renderer;
  SceneView view(renderer);
  view.Sync(model);
  vtkActor* actor = view.ActorOf(imported);
  ASSERT_NE(actor, nullptr);
  EXPECT_TRUE(actor->GetVisibility());
  EXPECT_EQ(view.ActorOf(generated), nullptr);
  // Its bounds in D: p_D = (p_W − p_WDo) / s of the nodes' box [0, 0.05]³ (vtkPoints hold
  // floats: 0.05 to 7.5e-10).
  double b[6];
  actor->GetBounds(b);
  for (int k = 0; k < 3; ++k) {
    EXPECT_NEAR(b[2 * k], (0.0 - x.p_WDo[k]) / x.world_scale, 1e-8) << k;
    EXPECT_NEAR(b[2 * k + 1], (0.05 - x.p_WDo[k]) / x.world_scale, 1e-8) << k;
  }
  doc.Undo();
  doc.Undo();
  model.Refresh();
  view.Sync(model);
  EXPECT_EQ(view.ActorOf(imported), nullptr);
}

}  // namespace
}  // namespace spidarcad::app
