// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
// Tests of modelling by touch's geometry (scene/touch_modelling.h) against closed forms: the size
// the grasp gives, the placed node's solid (the primitives' own distance functions at the pose),
// the pose command (one undo step; the solid moved rigidly, checked by evaluating the old tree at
// the moved points; undo and redo exact), and the alignment to a box's face and edge and a
// cylinder's axis (the aligned pose worked out by hand).
#include "scene/touch_modelling.h"

#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <cmath>
#include <numbers>
#include <random>
#include <stdexcept>
#include <string>

#include "doc/command.h"
#include "doc/document.h"
#include "spidarcad/modeling/implicit_node.h"

namespace spidarcad::app {
namespace {

using Eigen::Isometry3d;
using Eigen::Vector3d;
constexpr double kDeg = std::numbers::pi / 180.0;

Isometry3d Pose(const Vector3d& p, const Eigen::Matrix3d& R = Eigen::Matrix3d::Identity()) {
  Isometry3d X = Isometry3d::Identity();
  X.linear() = R;
  X.translation() = p;
  return X;
}

Eigen::Matrix3d Rot(double angle, const Vector3d& axis) {
  return Eigen::AngleAxisd(angle, axis.normalized()).toRotationMatrix();
}

// Exact signed distances of the primitives at their local origin (independent of the modeller).
double SphereDistance(const Vector3d& x, double r) { return x.norm() - r; }
double BoxDistance(const Vector3d& x, const Vector3d& h) {
  const Vector3d q = x.cwiseAbs() - h;
  return q.cwiseMax(0.0).norm() + std::min(q.maxCoeff(), 0.0);
}
double CylinderDistance(const Vector3d& x, double r, double half_height) {
  const Eigen::Vector2d q(std::hypot(x.x(), x.y()) - r, std::abs(x.z()) - half_height);
  return q.cwiseMax(0.0).norm() + std::min(q.maxCoeff(), 0.0);
}

TEST(PlaceSize, IsTheArcBetweenThePoleTipsLinearInTheGraspAndClamped) {
  const double d = 0.04;
  EXPECT_NEAR(PlaceSize(std::numbers::pi / 2, d, 1.0), d * std::numbers::pi / 2, 1e-15);
  EXPECT_NEAR(PlaceSize(60 * kDeg, d, 1.0), d * 60 * kDeg, 1e-15);
  // Linear: equal steps of θ give equal steps of size.
  EXPECT_NEAR(PlaceSize(100 * kDeg, d, 1.0) - PlaceSize(90 * kDeg, d, 1.0),
              PlaceSize(50 * kDeg, d, 1.0) - PlaceSize(40 * kDeg, d, 1.0), 1e-15);
  // Bounds: the hand's range, 20° to 160°.
  EXPECT_EQ(PlaceSize(5 * kDeg, d, 1.0), PlaceSize(20 * kDeg, d, 1.0));
  EXPECT_EQ(PlaceSize(175 * kDeg, d, 1.0), PlaceSize(160 * kDeg, d, 1.0));
  EXPECT_NEAR(PlaceSize(20 * kDeg, d, 1.0), 0.013963, 1e-6);
  EXPECT_NEAR(PlaceSize(160 * kDeg, d, 1.0), 0.111701, 1e-6);
  // The world scale multiplies it.
  EXPECT_NEAR(PlaceSize(1.0, d, 10.0), 10.0 * PlaceSize(1.0, d, 1.0), 1e-15);
  EXPECT_TRUE(std::isnan(PlaceSize(std::nan(""), d, 1.0)));
}

TEST(PlaceKind, ParsesTheThreeNamesAndRefusesOthersNamingTheChoices) {
  for (PlaceKind k : {PlaceKind::kSphere, PlaceKind::kBox, PlaceKind::kCylinder})
    EXPECT_EQ(ParsePlaceKind(PlaceKindName(k)), k);
  try {
    ParsePlaceKind("cone");
    FAIL() << "cone accepted";
  } catch (const std::invalid_argument& e) {
    EXPECT_EQ(std::string(e.what()),
              "'cone' is not a primitive the grip places: use sphere, box or cylinder");
  }
}

TEST(PlacedNode, IsThePrimitiveOfTheGivenSizeAtThePoseAndReadsBackItsPose) {
  const Isometry3d X_WN = Pose(Vector3d(0.03, -0.02, 0.05), Rot(0.7, Vector3d(1, 2, -0.5)));
  const double c = 0.03;
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> u(-0.04, 0.04);
  for (PlaceKind kind : {PlaceKind::kSphere, PlaceKind::kBox, PlaceKind::kCylinder}) {
    const modeling::ImplicitNode node = PlacedNode(kind, X_WN, c);
    modeling::ValidateTree(node);
    const NodePose pose = PoseOfNode(node);
    EXPECT_EQ(pose.depth, 2);
    EXPECT_LT((pose.X_AN.matrix() - X_WN.matrix()).norm(), 1e-12);
    for (int i = 0; i < 50; ++i) {
      const Vector3d x_N(u(rng), u(rng), u(rng));
      double expected = 0;
      switch (kind) {
        case PlaceKind::kSphere:
          expected = SphereDistance(x_N, c / 2);
          break;
        case PlaceKind::kBox:
          expected = BoxDistance(x_N, Vector3d::Constant(c / 2));
          break;
        case PlaceKind::kCylinder:
          expected = CylinderDistance(x_N, c / 2, c / 2);
          break;
      }
      EXPECT_NEAR(modeling::EvaluateTree(node, X_WN * x_N), expected, 1e-12) << PlaceKindName(kind);
    }
  }
  // The identity pose: no turn (angle 0 about z).
  const modeling::ImplicitNode still = PlacedNode(PlaceKind::kBox, Isometry3d::Identity(), c);
  const auto& r = std::get<modeling::RotateParams>(still.children.front().params);
  EXPECT_EQ(r.angle, 0.0);
  EXPECT_TRUE(r.axis == Vector3d::UnitZ());
}

// A solid: union{ translate{rotate{box "lid"}}, sphere "ball", translate{ rotate{ cylinder } } }.
modeling::ImplicitNode Assembly() {
  modeling::ImplicitNode lid(modeling::BoxParams{Vector3d(0.04, 0.02, 0.01)}, {}, "lid");
  modeling::ImplicitNode ball(modeling::SphereParams{0.01}, {}, "ball");
  modeling::ImplicitNode pin(modeling::CylinderParams{0.005, 0.03}, {}, "pin");
  modeling::ImplicitNode posed_lid = PlacedNode(PlaceKind::kBox, Isometry3d::Identity(), 1.0);
  posed_lid.children.front().children.front() = lid;
  posed_lid.children.front().params = modeling::RotateParams{Vector3d(0, 0, 1), 0.3};
  std::get<modeling::TranslateParams>(posed_lid.params).translation = Vector3d(0.01, 0, 0.02);
  modeling::ImplicitNode rotated_pin(modeling::RotateParams{Vector3d(1, 0, 0), 0.5}, {pin});
  modeling::ImplicitNode moved(modeling::TranslateParams{Vector3d(-0.03, 0.01, 0)}, {rotated_pin});
  return modeling::ImplicitNode(modeling::UnionParams{}, {posed_lid, ball, moved}, "whole");
}

TEST(FrameOfNode, IsTheProductOfTheTransformsAboveTheNode) {
  const modeling::ImplicitNode root = Assembly();
  // The pin at {2, 0, 0}: the translate then the rotate.
  const Eigen::Affine3d X = FrameOfNode(root, {2, 0, 0});
  const Eigen::Affine3d expected =
      Eigen::Translation3d(-0.03, 0.01, 0) * Eigen::AngleAxisd(0.5, Vector3d::UnitX());
  EXPECT_LT((X.matrix() - expected.matrix()).norm(), 1e-15);
  EXPECT_TRUE(IsRigid(X));
  // A scale above makes it non-rigid.
  modeling::ImplicitNode scaled(modeling::ScaleParams{Vector3d(1, 2, 1)}, {root});
  EXPECT_FALSE(IsRigid(FrameOfNode(scaled, {0, 1})));
  EXPECT_THROW(FrameOfNode(root, {3}), DocumentError);
}

// The tree value after the command, at points moved by the node's new pose, equals the old
// value of the moved node at the points before: checked on the node alone (the rest is apart).
void ExpectPosed(const Document& doc, ObjectId id, const NodePath& path, const Isometry3d& old_X,
                 const Isometry3d& new_X, const modeling::ImplicitNode& old_node) {
  const modeling::ImplicitNode& now = doc.Node(id, path);
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> u(-0.05, 0.05);
  for (int i = 0; i < 40; ++i) {
    const Vector3d x_A(u(rng), u(rng), u(rng));
    // x_A in the old node's place is new_X * old_X⁻¹ * x_A in the new one.
    EXPECT_NEAR(modeling::EvaluateTree(now, new_X * old_X.inverse() * x_A),
                modeling::EvaluateTree(old_node, x_A), 1e-12);
  }
}

TEST(PoseNodeCommand, MovesTheNodeRigidlyAsOneUndoStepThatUndoAndRedoRestoreExactly) {
  Document doc;
  doc.Execute(edit::AddSolid("part", Assembly()));
  const ObjectId id = doc.last_created().front();
  const std::size_t steps = doc.history().undo_size();
  const nlohmann::json before = doc.ToJson(true);
  const Isometry3d X_new = Pose(Vector3d(0.02, 0.01, -0.01), Rot(0.4, Vector3d(0.2, 1, 0.3)));
  // The lid (translate{rotate{box}} at {0}): both edited in place.
  const modeling::ImplicitNode lid_before = doc.Node(id, {0});
  const Isometry3d X_old = PoseOfNode(lid_before).X_AN;
  doc.Execute(PoseNodeCommand(doc, id, {0}, X_new));
  EXPECT_EQ(doc.history().undo_size(), steps + 1);
  EXPECT_EQ(doc.history().UndoDescription(), "Move part by touch");
  EXPECT_LT((PoseOfNode(doc.Node(id, {0})).X_AN.matrix() - X_new.matrix()).norm(), 1e-12);
  EXPECT_EQ(doc.Node(id, {0, 0, 0}).id, "lid");
  ExpectPosed(doc, id, {0}, X_old, X_new, lid_before);
  const nlohmann::json after = doc.ToJson(true);
  ASSERT_TRUE(doc.Undo());
  EXPECT_EQ(doc.ToJson(true), before);
  ASSERT_TRUE(doc.Redo());
  EXPECT_EQ(doc.ToJson(true), after);
  // The ball (a bare sphere at {1}): wrapped, keeping its id.
  const modeling::ImplicitNode ball_before = doc.Node(id, {1});
  doc.Execute(PoseNodeCommand(doc, id, {1}, X_new));
  EXPECT_EQ(doc.Node(id, {1, 0, 0}).id, "ball");
  ExpectPosed(doc, id, {1}, Isometry3d::Identity(), X_new, ball_before);
  // A translate over a rotate over the pin: edited.
  const modeling::ImplicitNode pin_before = doc.Node(id, {2});
  const Isometry3d X_pin = PoseOfNode(pin_before).X_AN;
  doc.Execute(PoseNodeCommand(doc, id, {2}, X_new));
  ExpectPosed(doc, id, {2}, X_pin, X_new, pin_before);
  EXPECT_EQ(doc.history().undo_size(), steps + 3);
  // The root (a union): wrapped.
  const modeling::ImplicitNode root_before = doc.Node(id, {});
  doc.Execute(PoseNodeCommand(doc, id, {}, X_new));
  ExpectPosed(doc, id, {}, Isometry3d::Identity(), X_new, root_before);
  EXPECT_EQ(doc.Node(id, {0, 0}).id, "whole");
}

TEST(PoseNodeCommand, RefusesABadPathANonRigidPoseAndAnObjectWithoutATree) {
  Document doc;
  doc.Execute(edit::AddSolid("part", Assembly()));
  const ObjectId id = doc.last_created().front();
  EXPECT_THROW(PoseNodeCommand(doc, id, {7}, Isometry3d::Identity()), DocumentError);
  Isometry3d skew = Isometry3d::Identity();
  skew.linear()(0, 1) = 0.1;
  try {
    PoseNodeCommand(doc, id, {1}, skew);
    FAIL();
  } catch (const DocumentError& e) {
    EXPECT_NE(std::string(e.what()).find("not a rigid motion"), std::string::npos) << e.what();
  }
  EXPECT_THROW(PoseNodeCommand(doc, 999, {}, Isometry3d::Identity()), DocumentError);
}

// A 40 mm cube at the origin and a cylinder (radius 10 mm, height 40 mm) along z at x = 100 mm.
modeling::Scene BoxAndCylinder() {
  modeling::Scene scene;
  scene.solids.push_back(
      {"cube", modeling::ImplicitNode(modeling::BoxParams{Vector3d::Constant(0.04)})});
  modeling::ImplicitNode cylinder(modeling::CylinderParams{0.01, 0.04});
  scene.solids.push_back(
      {"post", modeling::ImplicitNode(modeling::TranslateParams{Vector3d(0.1, 0, 0)}, {cylinder})});
  return scene;
}

TEST(ExtractTouchSnapFeatures, GivesOutwardFaceNormalsAndTheCylindersAxis) {
  const TouchSnapFeatures f = ExtractTouchSnapFeatures(BoxAndCylinder());
  ASSERT_EQ(f.face_normals_W.size(), f.features.faces_W.size());
  int cube_faces = 0;
  for (std::size_t i = 0; i < f.features.faces_W.size(); ++i) {
    Vector3d c = Vector3d::Zero();
    for (const Vector3d& p : f.features.faces_W[i].polygon_W) c += p;
    c /= static_cast<double>(f.features.faces_W[i].polygon_W.size());
    const Vector3d centre = c.x() > 0.05 ? Vector3d(0.1, 0, 0) : Vector3d::Zero();
    EXPECT_GT(f.face_normals_W[i].dot(c - centre), 0.0) << "face " << i << " points inward";
    EXPECT_NEAR(f.face_normals_W[i].norm(), 1.0, 1e-12);
    if (c.x() < 0.05) ++cube_faces;
  }
  EXPECT_EQ(cube_faces, 6);
  ASSERT_EQ(f.axes.size(), 1u);
  EXPECT_LT((f.axes[0].a_W - Vector3d(0.1, 0, -0.02)).norm(), 1e-15);
  EXPECT_LT((f.axes[0].b_W - Vector3d(0.1, 0, 0.02)).norm(), 1e-15);
}

TEST(AlignToFeatures, RestsACubeOnTheFaceBelowItSquaredToIt) {
  const TouchSnapFeatures f = ExtractTouchSnapFeatures(BoxAndCylinder());
  const TouchSnapSettings settings;  // faces 6 mm, lines 4 mm
  const double c = 0.02;             // a 20 mm cube: 10 mm below its centre
  const Eigen::AlignedBox3d box(Vector3d::Constant(-c / 2), Vector3d::Constant(c / 2));
  // 3 mm above resting on the top face (z = 20 mm), tilted 10° about x.
  const Isometry3d X =
      Pose(Vector3d(0.005, -0.003, 0.02 + c / 2 + 0.003), Rot(10 * kDeg, Vector3d::UnitX()));
  const Alignment a = AlignToFeatures(f, X, box, settings, 1.0);
  ASSERT_EQ(a.kind, AlignKind::kFace) << a.Text();
  EXPECT_LT((f.face_normals_W[a.index] - Vector3d::UnitZ()).norm(), 1e-12);
  EXPECT_LT((a.X_WN.translation() - Vector3d(0.005, -0.003, 0.03)).norm(), 1e-12);
  EXPECT_LT((a.X_WN.linear() - Eigen::Matrix3d::Identity()).norm(), 1e-12);
  // 7 mm above: beyond the 6 mm capture, unchanged.
  const Isometry3d far = Pose(Vector3d(0.005, -0.003, 0.02 + c / 2 + 0.007));
  const Alignment none = AlignToFeatures(f, far, box, settings, 1.0);
  EXPECT_EQ(none.kind, AlignKind::kNone);
  EXPECT_EQ(none.X_WN.matrix(), far.matrix());
  // At world scale 2 the capture is 12 mm: taken.
  EXPECT_EQ(AlignToFeatures(f, far, box, settings, 2.0).kind, AlignKind::kFace);
  // Off the face (its foot outside the square): not a face alignment.
  const Isometry3d beside = Pose(Vector3d(0.03, 0.0, 0.02 + c / 2 + 0.003));
  EXPECT_EQ(AlignToFeatures(f, beside, box, settings, 1.0).kind, AlignKind::kNone);
}

TEST(AlignToFeatures, PutsTheCentreOnANearEdgeWithTheNearestAxisAlongIt) {
  const TouchSnapFeatures f = ExtractTouchSnapFeatures(BoxAndCylinder());
  const Eigen::AlignedBox3d box(Vector3d::Constant(-0.005), Vector3d::Constant(0.005));
  // 2.1 mm from the top front edge (along x at y = −20 mm, z = 20 mm), turned 20° about z: its x
  // axis is the nearest to the edge's direction and turns onto it, so the pose squares up.
  const Isometry3d X = Pose(Vector3d(0.004, -0.0215, 0.0215), Rot(20 * kDeg, Vector3d::UnitZ()));
  const Alignment a = AlignToFeatures(f, X, box, TouchSnapSettings{}, 1.0);
  ASSERT_EQ(a.kind, AlignKind::kEdge) << a.Text();
  EXPECT_LT((a.X_WN.translation() - Vector3d(0.004, -0.02, 0.02)).norm(), 1e-12);
  EXPECT_LT((a.X_WN.linear() - Eigen::Matrix3d::Identity()).norm(), 1e-12);
}

TEST(AlignToFeatures, PutsTheCentreOnAnAxisAboveACylinderCoaxially) {
  const TouchSnapFeatures f = ExtractTouchSnapFeatures(BoxAndCylinder());
  const Eigen::AlignedBox3d box(Vector3d::Constant(-0.005), Vector3d::Constant(0.005));
  // 2.2 mm off the post's axis, 15 mm above its top (the axis extends 40 mm beyond it), tilted
  // 15° about y: its z axis turns onto the post's.
  const Isometry3d X = Pose(Vector3d(0.102, -0.001, 0.035), Rot(15 * kDeg, Vector3d::UnitY()));
  const Alignment a = AlignToFeatures(f, X, box, TouchSnapSettings{}, 1.0);
  ASSERT_EQ(a.kind, AlignKind::kAxis) << a.Text();
  EXPECT_EQ(a.Text(), "axis 0");
  EXPECT_LT((a.X_WN.translation() - Vector3d(0.1, 0, 0.035)).norm(), 1e-12);
  EXPECT_LT((a.X_WN.linear() - Eigen::Matrix3d::Identity()).norm(), 1e-12);
  // 70 mm above: past the extended axis, nothing.
  EXPECT_EQ(AlignToFeatures(f, Pose(Vector3d(0.101, 0, 0.07)), box, TouchSnapSettings{}, 1.0).kind,
            AlignKind::kNone);
}

TEST(AlignToFeatures, PutsTheCentreOnANearVertexKeepingItsOrientation) {
  const TouchSnapFeatures f = ExtractTouchSnapFeatures(BoxAndCylinder());
  const Eigen::AlignedBox3d box(Vector3d::Constant(-0.005), Vector3d::Constant(0.005));
  // The cube's corner (20, 20, 20) mm; a centre 3 mm out along the diagonal (inside the 5 mm
  // vertex capture, beyond the 4 mm edge capture's... nearer than it too: the vertex wins),
  // turned 20° about z: the centre goes onto the corner, the orientation stays.
  const Vector3d corner(0.02, 0.02, 0.02);
  const Vector3d out = Vector3d::Ones().normalized();
  const Eigen::Matrix3d R = Rot(20 * kDeg, Vector3d::UnitZ());
  const Alignment a = AlignToFeatures(f, Pose(corner + 0.003 * out, R), box, {}, 1.0);
  ASSERT_EQ(a.kind, AlignKind::kVertex) << a.Text();
  EXPECT_EQ(a.Text().rfind("vertex ", 0), 0u);
  EXPECT_LT((f.features.vertices_W[a.index] - corner).norm(), 1e-12);
  EXPECT_LT((a.X_WN.translation() - corner).norm(), 1e-12);
  EXPECT_LT((a.X_WN.linear() - R).norm(), 1e-15);
  // 6 mm out along the diagonal: past the vertex capture; 6 mm from the three edges' ends and
  // over no face: nothing.
  EXPECT_EQ(AlignToFeatures(f, Pose(corner + 0.006 * out, R), box, {}, 1.0).kind, AlignKind::kNone);
  // At world scale 2 the capture is 10 mm: taken.
  EXPECT_EQ(AlignToFeatures(f, Pose(corner + 0.006 * out, R), box, {}, 2.0).kind,
            AlignKind::kVertex);
  // 1 mm above the middle of the top front edge (far from any corner): the edge, as before.
  EXPECT_EQ(AlignToFeatures(f, Pose(Vector3d(0.0, -0.02, 0.021)), box, {}, 1.0).kind,
            AlignKind::kEdge);
}

TEST(FeltSnapFeatures, LiftsTheFacesByTheRestHeightAndAddsTheExtendedAxes) {
  const TouchSnapFeatures f = ExtractTouchSnapFeatures(BoxAndCylinder());
  const haptics::SnapFeatures felt = FeltSnapFeatures(f, 0.01);
  EXPECT_EQ(felt.vertices_W, f.features.vertices_W);  // the corners, where a centre goes
  ASSERT_EQ(felt.edges_W.size(), f.features.edges_W.size() + 1);
  EXPECT_LT((felt.edges_W.back().first - Vector3d(0.1, 0, -0.06)).norm(), 1e-15);
  EXPECT_LT((felt.edges_W.back().second - Vector3d(0.1, 0, 0.06)).norm(), 1e-15);
  ASSERT_EQ(felt.faces_W.size(), f.features.faces_W.size());
  for (std::size_t i = 0; i < felt.faces_W.size(); ++i) {
    for (std::size_t k = 0; k < felt.faces_W[i].polygon_W.size(); ++k) {
      EXPECT_LT((felt.faces_W[i].polygon_W[k] - f.features.faces_W[i].polygon_W[k] -
                 0.01 * f.face_normals_W[i])
                    .norm(),
                1e-15);
    }
  }
  // The settings refuse a zero capture.
  TouchSnapSettings bad;
  bad.face_capture = 0.0;
  EXPECT_THROW(bad.Validate(), std::invalid_argument);
}

TEST(GhostMesh, MeshesTheNodeInItsOwnFrame) {
  const modeling::TriangleMesh mesh =
      GhostMesh(modeling::ImplicitNode(modeling::SphereParams{0.02}), 24.0);
  ASSERT_GT(mesh.vertices.cols(), 100);
  for (int v = 0; v < mesh.vertices.cols(); ++v)
    EXPECT_NEAR(mesh.vertices.col(v).norm(), 0.02, 0.04 / 24.0);
  EXPECT_THROW(GhostMesh(modeling::ImplicitNode(modeling::HalfSpaceParams{})), std::runtime_error);
}

}  // namespace
}  // namespace spidarcad::app
