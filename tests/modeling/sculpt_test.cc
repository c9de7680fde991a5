// Tests of freeform sculpting: each tool's field against closed forms, independence of the step
// count, volume conservation, refinement keeping the mesh closed and manifold, smoothing, undo
// and redo, a sculpted blob going through TetGen, and the haptic wrench (linear, allocation-free).
// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#include "spidarcad/modeling/sculpt.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <map>
#include <random>
#include <set>

#include "spidarcad/modeling/scene_io.h"
#include "spidarcad/modeling/tetgen_mesher.h"
#include "support/malloc_counter.h"

namespace spidarcad::modeling {
namespace {

constexpr double kPi = std::numbers::pi;

Eigen::Isometry3d Pose(const Eigen::Matrix3d& R, const Eigen::Vector3d& p) {
  Eigen::Isometry3d X = Eigen::Isometry3d::Identity();
  X.linear() = R;
  X.translation() = p;
  return X;
}

// A rotation whose z column is n (unit).
Eigen::Matrix3d FrameWithZ(const Eigen::Vector3d& n) {
  return Eigen::Quaterniond::FromTwoVectors(Eigen::Vector3d::UnitZ(), n).toRotationMatrix();
}

// Settings with strength 1 whatever the grasp.
SculptToolSettings Tool(SculptTool tool, double radius) {
  SculptToolSettings s;
  s.tool = tool;
  s.radius = radius;
  s.grasp_controls_strength = false;
  return s;
}

// Every directed edge exactly once and its reverse present (closed, consistently oriented, edge
// manifold), and the triangles around each vertex form a single fan. Returns V - E + F.
long CheckClosedManifold(const TriangleMesh& mesh) {
  std::map<std::pair<int, int>, int> next_in_fan;  // (v, a) -> b for triangle (v, a, b)
  std::set<std::pair<int, int>> directed;
  for (Eigen::Index t = 0; t < mesh.triangles.cols(); ++t) {
    for (int k = 0; k < 3; ++k) {
      const int v = mesh.triangles(k, t), a = mesh.triangles((k + 1) % 3, t),
                b = mesh.triangles((k + 2) % 3, t);
      EXPECT_TRUE(directed.insert({v, a}).second) << "directed edge " << v << "->" << a << " twice";
      next_in_fan[{v, a}] = b;
    }
  }
  for (const auto& [a, b] : directed)
    EXPECT_TRUE(directed.count({b, a})) << "open edge " << a << "-" << b;
  std::map<int, int> fan_size;
  for (const auto& [key, b] : next_in_fan) ++fan_size[key.first];
  for (const auto& [v, size] : fan_size) {
    const int start = next_in_fan.lower_bound({v, -1})->first.second;
    int at = start, steps = 0;
    do {
      at = next_in_fan[{v, at}];
      ++steps;
    } while (at != start && steps <= size);
    EXPECT_EQ(steps, size) << "vertex " << v << " is not manifold";
  }
  return static_cast<long>(mesh.vertices.cols()) - static_cast<long>(directed.size()) / 2 +
         mesh.triangles.cols();
}

double LongestEdge(const TriangleMesh& mesh) {
  double longest = 0.0;
  for (Eigen::Index t = 0; t < mesh.triangles.cols(); ++t) {
    for (int k = 0; k < 3; ++k) {
      longest = std::max(longest, (mesh.vertices.col(mesh.triangles(k, t)) -
                                   mesh.vertices.col(mesh.triangles((k + 1) % 3, t)))
                                      .norm());
    }
  }
  return longest;
}

TEST(SculptMesh, IcosphereIsClosedOutwardAndOnTheSphere) {
  const TriangleMesh mesh = IcosphereMesh(0.05, 3);
  EXPECT_EQ(mesh.vertices.cols(), 10 * 64 + 2);
  EXPECT_EQ(CheckClosedManifold(mesh), 2);
  for (Eigen::Index v = 0; v < mesh.vertices.cols(); ++v)
    EXPECT_NEAR(mesh.vertices.col(v).norm(), 0.05, 1e-15);
  // Inscribed polyhedron: a little below the ball's volume, converging to it.
  const double ball = 4.0 / 3.0 * kPi * std::pow(0.05, 3);
  EXPECT_LT(MeshVolume(mesh), ball);
  EXPECT_GT(MeshVolume(mesh), 0.97 * ball);
  const SculptMesh sculpt(mesh);
  EXPECT_NEAR(sculpt.volume(), MeshVolume(mesh), 1e-15);
  // Normals of a sphere point along the position.
  for (int v = 0; v < sculpt.vertex_count(); ++v)
    EXPECT_GT(sculpt.normals()[v].dot(sculpt.positions()[v].normalized()), 0.999);
}

TEST(SculptMesh, RejectsOpenAndBadMeshes) {
  TriangleMesh mesh = IcosphereMesh(0.05, 1);
  TriangleMesh open = mesh;
  open.triangles.conservativeResize(3, open.triangles.cols() - 1);
  EXPECT_THROW(SculptMesh{open}, std::invalid_argument);
  TriangleMesh bad_index = mesh;
  bad_index.triangles(1, 3) = 1000;
  EXPECT_THROW(SculptMesh{bad_index}, std::invalid_argument);
  TriangleMesh flipped = mesh;
  std::swap(flipped.triangles(1, 0), flipped.triangles(2, 0));
  EXPECT_THROW(SculptMesh{flipped}, std::invalid_argument);
  EXPECT_THROW(SculptMesh(mesh, 0.0), std::invalid_argument);
  SculptMesh sculpt(mesh);
  EXPECT_THROW(sculpt.UpdateStroke(Eigen::Isometry3d::Identity(), kPi / 4), std::logic_error);
  SculptToolSettings bad = Tool(SculptTool::kGrab, -0.01);
  EXPECT_THROW(sculpt.BeginStroke(bad, Eigen::Isometry3d::Identity(), kPi / 2),
               std::invalid_argument);
  bad = Tool(SculptTool::kGrab, 0.01);
  bad.grasp_closed_angle = 2.0;
  EXPECT_THROW(sculpt.BeginStroke(bad, Eigen::Isometry3d::Identity(), kPi / 2),
               std::invalid_argument);
}

TEST(SculptMesh, QueryBallMatchesBruteForce) {
  const SculptMesh sculpt(IcosphereMesh(0.05, 4), 0.004);
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> u(-0.06, 0.06);
  std::vector<int> found;
  for (int trial = 0; trial < 20; ++trial) {
    const Eigen::Vector3d c(u(rng), u(rng), u(rng));
    const double radius = 0.005 + 0.005 * (trial % 5);
    sculpt.QueryBall(c, radius, &found);
    std::vector<int> expected;
    for (int v = 0; v < sculpt.vertex_count(); ++v) {
      if ((sculpt.positions()[v] - c).norm() < radius) expected.push_back(v);
    }
    EXPECT_EQ(found, expected) << "trial " << trial;
  }
}

TEST(SculptGrab, MovesGrabbedVertexByFullTranslationAndNothingBeyondRadius) {
  const TriangleMesh start = IcosphereMesh(0.05, 4);
  SculptMesh sculpt(start);
  const int grabbed = 17;
  const Eigen::Vector3d c = start.vertices.col(grabbed);
  const double R = 0.02;
  const Eigen::Vector3d dp(0.01, 0.004, -0.003);
  sculpt.BeginStroke(Tool(SculptTool::kGrab, R), Pose(Eigen::Matrix3d::Identity(), c), kPi / 2);
  sculpt.UpdateStroke(Pose(Eigen::Matrix3d::Identity(), c + dp), kPi / 2);
  int inside = 0;
  for (int v = 0; v < sculpt.vertex_count(); ++v) {
    const Eigen::Vector3d p0 = start.vertices.col(v);
    const double r = (p0 - c).norm();
    const Eigen::Vector3d moved = sculpt.positions()[v] - p0;
    if (r >= R) {
      EXPECT_EQ(moved, Eigen::Vector3d::Zero()) << "vertex " << v << " beyond the radius moved";
    } else {
      ++inside;
      const double q = r / R;
      const double w = (1 - q * q) * (1 - q * q) * (1 - q * q);  // reference stiffness: exponent 3
      EXPECT_NEAR((moved - w * dp).norm(), 0.0, 1e-15) << "vertex " << v;
    }
  }
  EXPECT_NEAR((sculpt.positions()[grabbed] - (c + dp)).norm(), 0.0, 1e-16);
  EXPECT_GT(inside, 30);
  EXPECT_EQ(sculpt.stroke_stats().affected_vertices, inside);
}

TEST(SculptGrab, StrengthFollowsGraspAndStiffnessSharpensFalloff) {
  EXPECT_EQ(SculptGrabStrength(kPi / 2, kPi / 4), 0.0);
  EXPECT_EQ(SculptGrabStrength(2.0, kPi / 4), 0.0);
  EXPECT_DOUBLE_EQ(SculptGrabStrength(3 * kPi / 8, kPi / 4), 0.5);
  EXPECT_EQ(SculptGrabStrength(0.1, kPi / 4), 1.0);
  EXPECT_DOUBLE_EQ(SculptFalloffExponent(kReferenceSculptStiffness), 3.0);
  EXPECT_GT(SculptFalloffExponent(8 * kReferenceSculptStiffness), 5.9);
  EXPECT_LT(SculptFalloffWeight(0.01, 0.02, SculptFalloffExponent(2000.0)),
            SculptFalloffWeight(0.01, 0.02, 3.0));
  EXPECT_EQ(SculptFalloffWeight(0.02, 0.02, 3.0), 0.0);

  const TriangleMesh start = IcosphereMesh(0.05, 3);
  const Eigen::Vector3d c = start.vertices.col(5);
  const Eigen::Vector3d dp(0.0, 0.0, 0.01);
  SculptToolSettings settings = Tool(SculptTool::kGrab, 0.02);
  settings.grasp_controls_strength = true;
  SculptMesh sculpt(start);
  sculpt.BeginStroke(settings, Pose(Eigen::Matrix3d::Identity(), c), kPi / 2);
  sculpt.UpdateStroke(Pose(Eigen::Matrix3d::Identity(), c + dp),
                      kPi / 2);  // open grip: holds nothing
  EXPECT_EQ(sculpt.positions()[5], c);
  sculpt.UpdateStroke(Pose(Eigen::Matrix3d::Identity(), c + dp), 3 * kPi / 8);  // half closed
  EXPECT_NEAR((sculpt.positions()[5] - (c + 0.5 * dp)).norm(), 0.0, 1e-15);
  sculpt.UpdateStroke(Pose(Eigen::Matrix3d::Identity(), c + dp), 0.2);  // closed
  EXPECT_NEAR((sculpt.positions()[5] - (c + dp)).norm(), 0.0, 1e-15);
  sculpt.CancelStroke();
  EXPECT_EQ(sculpt.ToTriangleMesh().vertices, start.vertices);
}

TEST(SculptTwist, RotatesAboutGripAxisByAngleTimesWeight) {
  const TriangleMesh start = IcosphereMesh(0.05, 4);
  SculptMesh sculpt(start);
  const int grabbed = 40;
  const Eigen::Vector3d c = start.vertices.col(grabbed);
  const Eigen::Vector3d z = c.normalized();  // grip axis along the surface normal
  const Eigen::Matrix3d R0 = FrameWithZ(z);
  const double alpha = 0.7, R = 0.03;
  sculpt.BeginStroke(Tool(SculptTool::kTwist, R), Pose(R0, c), kPi / 2);
  // Twist about z, plus a translation the twist tool ignores.
  sculpt.UpdateStroke(Pose(Eigen::AngleAxisd(alpha, z) * R0, c + Eigen::Vector3d(0.003, 0, 0)),
                      kPi / 2);
  int checked = 0;
  for (int v = 0; v < sculpt.vertex_count(); ++v) {
    const Eigen::Vector3d r0 = start.vertices.col(v) - c;
    const Eigen::Vector3d r1 = sculpt.positions()[v] - c;
    EXPECT_NEAR(r1.norm(), r0.norm(), 1e-14);
    EXPECT_NEAR(r1.dot(z), r0.dot(z), 1e-14);
    const Eigen::Vector3d a = r0 - r0.dot(z) * z, b = r1 - r1.dot(z) * z;
    if (a.norm() < 1e-4) continue;
    const double angle = std::atan2(a.cross(b).dot(z), a.dot(b));
    const double q = r0.norm() / R;
    const double w = r0.norm() < R ? std::pow(1 - q * q, 3) : 0.0;
    EXPECT_NEAR(angle, alpha * w, 1e-12) << "vertex " << v;
    ++checked;
  }
  EXPECT_GT(checked, 2000);
}

TEST(SculptBend, BothSidesTurnTheSameWayAndDistancesToCentreAreKept) {
  // Bend a sphere about a point on its equator with the grip x axis along the tangent: the
  // vertices at +x and -x along the tangent both move inward (a U), by the same amount.
  const TriangleMesh start = IcosphereMesh(0.05, 4);
  SculptMesh sculpt(start);
  const Eigen::Vector3d c(0.05, 0, 0);  // grab at the vertex nearest to this equator point
  int nearest = 0;
  for (int v = 0; v < start.vertices.cols(); ++v) {
    if ((start.vertices.col(v) - c).norm() < (start.vertices.col(nearest) - c).norm()) nearest = v;
  }
  const Eigen::Vector3d centre = start.vertices.col(nearest);
  Eigen::Matrix3d R0;  // grip x along the tangent +y, y = -x (inward), z = x × y = +z
  R0.col(0) = Eigen::Vector3d::UnitY();
  R0.col(1) = -Eigen::Vector3d::UnitX();
  R0.col(2) = Eigen::Vector3d::UnitZ();
  const double R = 0.03, phi = 0.4;
  sculpt.BeginStroke(Tool(SculptTool::kBend, R), Pose(R0, centre), kPi / 2);
  sculpt.UpdateStroke(Pose(Eigen::AngleAxisd(phi, Eigen::Vector3d::UnitZ()) * R0, centre), kPi / 2);
  double plus = 0, minus = 0;
  for (int v = 0; v < sculpt.vertex_count(); ++v) {
    const Eigen::Vector3d r0 = start.vertices.col(v) - centre;
    const Eigen::Vector3d r1 = sculpt.positions()[v] - centre;
    EXPECT_NEAR(r1.norm(), r0.norm(), 1e-15);
    if (std::abs(r0.z()) > 0.003 || r0.norm() > R) continue;
    // Rotation about z through the centre: the x displacement of points at ±y.
    const double dx = r1.x() - r0.x();
    if (r0.y() > 0.008) plus += dx;
    if (r0.y() < -0.008) minus += dx;
  }
  EXPECT_LT(plus, -1e-4);
  EXPECT_LT(minus, -1e-4);
  EXPECT_NEAR(plus, minus, 0.35 * std::abs(plus));  // the icosphere is only nearly symmetric
}

TEST(SculptStroke, ResultIndependentOfStepCount) {
  const TriangleMesh start = IcosphereMesh(0.05, 4);
  const Eigen::Vector3d c = start.vertices.col(100);
  const Eigen::Matrix3d R0 = FrameWithZ(c.normalized());
  const Eigen::Isometry3d X_final =
      Pose(Eigen::AngleAxisd(0.5, Eigen::Vector3d(1, 2, 3).normalized()) * R0,
           c + Eigen::Vector3d(0.012, -0.004, 0.009) + 0.01 * c.normalized());
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  for (SculptTool tool : {SculptTool::kGrab, SculptTool::kTwist, SculptTool::kBend,
                          SculptTool::kPushPull, SculptTool::kSmooth}) {
    for (bool conserve : {false, true}) {
      SculptToolSettings settings = Tool(tool, 0.025);
      settings.conserve_volume = conserve;
      SculptMesh one(start), many(start);
      one.BeginStroke(settings, Pose(R0, c), 0.3);
      one.UpdateStroke(X_final, 0.3);
      many.BeginStroke(settings, Pose(R0, c), 0.3);
      for (int step = 0; step < 40; ++step) {  // a wandering path
        const Eigen::Isometry3d X = Pose(
            Eigen::AngleAxisd(0.8 * u(rng), Eigen::Vector3d(u(rng), u(rng), u(rng)).normalized()) *
                R0,
            c + 0.02 * Eigen::Vector3d(u(rng), u(rng), u(rng)));
        many.UpdateStroke(X, 0.3);
      }
      many.UpdateStroke(X_final, 0.3);
      double largest = 0.0, moved = 0.0;
      for (int v = 0; v < one.vertex_count(); ++v) {
        largest = std::max(largest, (one.positions()[v] - many.positions()[v]).norm());
        moved = std::max(moved, (one.positions()[v] - start.vertices.col(v)).norm());
      }
      EXPECT_LT(largest, 1e-15) << SculptToolName(tool) << " conserve " << conserve;
      EXPECT_GT(moved, 1e-4) << SculptToolName(tool) << " did nothing";
    }
  }
}

TEST(SculptStroke, ConservesVolumeWithinTolerancesWhenAsked) {
  const TriangleMesh start = IcosphereMesh(0.05, 4);
  const double v0 = MeshVolume(start);
  const Eigen::Vector3d c = start.vertices.col(200);
  const Eigen::Matrix3d R0 = FrameWithZ(c.normalized());
  struct Case {
    SculptTool tool;
    Eigen::Isometry3d X;
  };
  const std::vector<Case> cases = {
      {SculptTool::kPushPull, Pose(R0, c + 0.02 * c.normalized())},   // pull a bump out
      {SculptTool::kPushPull, Pose(R0, c - 0.015 * c.normalized())},  // push a dent in
      {SculptTool::kGrab, Pose(R0, c + 0.025 * c.normalized())},
  };
  for (const Case& k : cases) {
    for (bool conserve : {false, true}) {
      SculptToolSettings settings = Tool(k.tool, 0.03);
      settings.conserve_volume = conserve;
      SculptMesh sculpt(start);
      sculpt.BeginStroke(settings, Pose(R0, c), kPi / 2);
      sculpt.UpdateStroke(k.X, kPi / 2);
      const double error = std::abs(MeshVolume(sculpt.ToTriangleMesh()) / v0 - 1.0);
      EXPECT_NEAR(sculpt.stroke_stats().volume, MeshVolume(sculpt.ToTriangleMesh()), 1e-15);
      if (conserve) {
        EXPECT_LT(error, 1e-6) << SculptToolName(k.tool);
        EXPECT_GT(sculpt.stroke_stats().volume_iterations, 0);
        // The correction leaves the grab centre alone: the grabbed vertex follows the grip exactly.
        if (k.tool == SculptTool::kGrab) {
          EXPECT_NEAR((sculpt.positions()[200] - k.X.translation()).norm(), 0.0, 1e-15);
        }
      } else {
        EXPECT_GT(error, 0.01) << SculptToolName(k.tool);
      }
      sculpt.EndStroke();
      EXPECT_NEAR(sculpt.volume(), sculpt.ComputeVolume(), 1e-15);
    }
  }
}

TEST(SculptRefine, SplitsStretchedEdgesKeepingTheMeshClosedAndUndoRestoresIt) {
  const TriangleMesh start = IcosphereMesh(0.05, 3);
  const double max_edge = 1.2 * LongestEdge(start);
  SculptMesh sculpt(start);
  const int grabbed = 30;
  const Eigen::Vector3d c = start.vertices.col(grabbed);
  SculptToolSettings settings = Tool(SculptTool::kGrab, 0.03);
  settings.max_edge_length = max_edge;
  sculpt.BeginStroke(settings, Pose(Eigen::Matrix3d::Identity(), c), kPi / 2);
  sculpt.UpdateStroke(Pose(Eigen::Matrix3d::Identity(), c + 0.04 * c.normalized()), kPi / 2);
  const TriangleMesh stretched = sculpt.ToTriangleMesh();
  ASSERT_GT(LongestEdge(stretched),
            1.5 * max_edge);  // the stroke stretched edges well beyond the limit
  const double volume_before_refine = MeshVolume(stretched);
  const SculptEdit edit = sculpt.EndStroke();
  const TriangleMesh refined = sculpt.ToTriangleMesh();
  EXPECT_GT(edit.splits, 20);
  EXPECT_EQ(refined.vertices.cols(), start.vertices.cols() + edit.splits);
  EXPECT_EQ(refined.triangles.cols(), start.triangles.cols() + 2 * edit.splits);
  EXPECT_LE(LongestEdge(refined), max_edge);
  EXPECT_EQ(CheckClosedManifold(refined), 2);
  EXPECT_NO_THROW(CheckSurface(refined));
  // Midpoint splits are planar: the volume is unchanged.
  EXPECT_NEAR(MeshVolume(refined), volume_before_refine, 1e-12 * volume_before_refine);
  EXPECT_NEAR(sculpt.volume(), MeshVolume(refined), 1e-12 * volume_before_refine);
  // The normals kept up to date through the stroke and the splits equal those of a mesh built
  // from scratch.
  const SculptMesh rebuilt(refined);
  for (int v = 0; v < sculpt.vertex_count(); ++v) {
    EXPECT_NEAR((sculpt.normals()[v] - rebuilt.normals()[v]).norm(), 0.0, 1e-12) << "vertex " << v;
  }

  sculpt.Undo(edit);
  const TriangleMesh undone = sculpt.ToTriangleMesh();
  EXPECT_EQ(undone.vertices, start.vertices);
  EXPECT_EQ(undone.triangles, start.triangles);
  const SculptMesh fresh(start);
  for (int v = 0; v < sculpt.vertex_count(); ++v) {
    EXPECT_NEAR((sculpt.normals()[v] - fresh.normals()[v]).norm(), 0.0, 1e-12);
    EXPECT_EQ(sculpt.VertexTriangles(v).size(), fresh.VertexTriangles(v).size());
  }
  sculpt.Redo(edit);
  const TriangleMesh redone = sculpt.ToTriangleMesh();
  EXPECT_EQ(redone.vertices, refined.vertices);
  EXPECT_EQ(redone.triangles, refined.triangles);
  // The grid follows: a query at the pulled tip finds the same vertices as brute force.
  std::vector<int> found, expected;
  const Eigen::Vector3d tip = sculpt.positions()[grabbed];
  sculpt.QueryBall(tip, 0.01, &found);
  for (int v = 0; v < sculpt.vertex_count(); ++v) {
    if ((sculpt.positions()[v] - tip).norm() < 0.01) expected.push_back(v);
  }
  EXPECT_EQ(found, expected);
  EXPECT_GT(found.size(), 3u);
}

TEST(SculptMesh, UndoesAndRedoesSeveralStrokesInOrder) {
  const TriangleMesh start = IcosphereMesh(0.05, 3);
  SculptMesh sculpt(start);
  const double max_edge = 1.2 * LongestEdge(start);
  std::vector<SculptEdit> edits;
  std::vector<TriangleMesh> states = {start};
  const SculptTool tools[] = {SculptTool::kGrab, SculptTool::kTwist, SculptTool::kPushPull,
                              SculptTool::kGrab};
  for (int i = 0; i < 4; ++i) {
    const Eigen::Vector3d c = sculpt.positions()[10 + 50 * i];
    const Eigen::Matrix3d R0 = FrameWithZ(sculpt.normals()[10 + 50 * i]);
    SculptToolSettings settings = Tool(tools[i], 0.03);
    settings.max_edge_length = max_edge;
    settings.conserve_volume = i % 2 == 1;
    sculpt.BeginStroke(settings, Pose(R0, c), kPi / 2);
    sculpt.UpdateStroke(Pose(Eigen::AngleAxisd(0.6, R0.col(2)) * R0, c + 0.03 * R0.col(2)),
                        kPi / 2);
    edits.push_back(sculpt.EndStroke());
    states.push_back(sculpt.ToTriangleMesh());
    EXPECT_NEAR(sculpt.volume(), MeshVolume(states.back()), 1e-15) << "stroke " << i;
  }
  EXPECT_GT(edits[0].splits + edits[2].splits + edits[3].splits, 0);
  EXPECT_THROW(sculpt.Undo(edits[1]), std::logic_error);  // not the last edit
  for (int i = 3; i >= 0; --i) {
    sculpt.Undo(edits[i]);
    const TriangleMesh now = sculpt.ToTriangleMesh();
    EXPECT_EQ(now.vertices, states[i].vertices) << "after undoing stroke " << i;
    EXPECT_EQ(now.triangles, states[i].triangles) << "after undoing stroke " << i;
    EXPECT_NEAR(sculpt.volume(), MeshVolume(now), 1e-15);
  }
  for (int i = 0; i < 4; ++i) sculpt.Redo(edits[i]);
  EXPECT_EQ(sculpt.ToTriangleMesh().vertices, states[4].vertices);
  EXPECT_EQ(sculpt.ToTriangleMesh().triangles, states[4].triangles);
  EXPECT_EQ(CheckClosedManifold(sculpt.ToTriangleMesh()), 2);
  const SculptMesh rebuilt(states[4]);
  for (int v = 0; v < sculpt.vertex_count(); ++v) {
    EXPECT_NEAR((sculpt.normals()[v] - rebuilt.normals()[v]).norm(), 0.0, 1e-12) << "vertex " << v;
  }
}

TEST(SculptSmooth, ReducesNoisySphereDeviation) {
  TriangleMesh noisy = IcosphereMesh(0.05, 4);
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> noise(-0.0006, 0.0006);
  for (Eigen::Index v = 0; v < noisy.vertices.cols(); ++v) {
    noisy.vertices.col(v) *= (0.05 + noise(rng)) / 0.05;
  }
  SculptMesh sculpt(noisy);
  const Eigen::Vector3d c = noisy.vertices.col(321);
  const double R = 0.025;
  auto Deviation =
      [&](const std::vector<Eigen::Vector3d>& points) {  // RMS of |p| - 0.05 within R/3
        double sum = 0.0;
        int n = 0;
        for (int v = 0; v < noisy.vertices.cols(); ++v) {
          if ((noisy.vertices.col(v) - c).norm() > R / 3) continue;
          sum += std::pow(points[v].norm() - 0.05, 2);
          ++n;
        }
        return std::sqrt(sum / n);
      };
  const double before = Deviation(sculpt.positions());
  sculpt.BeginStroke(Tool(SculptTool::kSmooth, R), Pose(Eigen::Matrix3d::Identity(), c), kPi / 2);
  sculpt.UpdateStroke(Pose(Eigen::Matrix3d::Identity(), c + Eigen::Vector3d(R, 0, 0)), kPi / 2);
  const double after = Deviation(sculpt.positions());
  EXPECT_GT(before, 2e-4);
  EXPECT_LT(after, 0.5 * before);
}

TEST(SculptMesh, SculptedBlobPassesCheckSurfaceAndTetrahedralizes) {
  const Scene scene = LoadScene(std::string(SPIDARCAD_SOURCE_DIR) + "/assets/scenes/clay.json");
  const CompiledSolid solid = CompiledSolid::Compile(scene.solids.at(0).root);
  SurfaceMeshSettings mesh_settings;
  mesh_settings.bounds =
      Eigen::AlignedBox3d(Eigen::Vector3d::Constant(-0.15), Eigen::Vector3d::Constant(0.15));
  mesh_settings.cell_size = 0.008;
  SculptMesh sculpt(MeshSurface(solid, mesh_settings));
  const double v0 = sculpt.volume();
  // The top-most vertex: pull it up, twist about the vertical, bend sideways.
  int top = 0;
  for (int v = 0; v < sculpt.vertex_count(); ++v) {
    if (sculpt.positions()[v].z() > sculpt.positions()[top].z()) top = v;
  }
  const Eigen::Vector3d c = sculpt.positions()[top];
  const Eigen::Matrix3d I = Eigen::Matrix3d::Identity();
  SculptToolSettings settings = Tool(SculptTool::kGrab, 0.04);
  settings.max_edge_length = 0.008;
  sculpt.BeginStroke(settings, Pose(I, c), kPi / 2);
  sculpt.UpdateStroke(Pose(I, c + Eigen::Vector3d(0.005, 0, 0.03)), kPi / 2);
  sculpt.EndStroke();
  const Eigen::Vector3d c2 = sculpt.positions()[top];
  settings.tool = SculptTool::kTwist;
  settings.conserve_volume = true;
  sculpt.BeginStroke(settings, Pose(I, c2), kPi / 2);
  sculpt.UpdateStroke(Pose(Eigen::AngleAxisd(0.8, Eigen::Vector3d::UnitZ()).toRotationMatrix(), c2),
                      kPi / 2);
  sculpt.EndStroke();
  settings.tool = SculptTool::kBend;
  sculpt.BeginStroke(settings, Pose(I, c2), kPi / 2);
  sculpt.UpdateStroke(Pose(Eigen::AngleAxisd(0.3, Eigen::Vector3d::UnitY()).toRotationMatrix(), c2),
                      kPi / 2);
  sculpt.EndStroke();
  const TriangleMesh sculpted = sculpt.ToTriangleMesh();
  EXPECT_GT(sculpted.vertices.cols(), 0);
  EXPECT_NEAR(sculpt.volume(), MeshVolume(sculpted), 1e-12);
  EXPECT_GT(sculpt.volume(), v0 * 1.01);  // the pull added material; twist and bend kept it
  EXPECT_NO_THROW(CheckSurface(sculpted));
  const TetMesh tets = TetrahedralizeSurface(sculpted);
  ASSERT_GT(tets.tets.cols(), 0);
  const TetQuality quality = MeasureTetQuality(tets);
  EXPECT_GT(quality.min_volume, 0.0);
  EXPECT_NEAR(quality.total_volume, MeshVolume(sculpted), 1e-6 * MeshVolume(sculpted));
}

TEST(StrokeWrench, ZeroAtStartLinearInDisplacementAndAllocationFree) {
  const TriangleMesh start = IcosphereMesh(0.05, 3);
  SculptMesh sculpt(start);
  const Eigen::Vector3d c = start.vertices.col(7);
  const Eigen::Matrix3d R0 = FrameWithZ(c.normalized());
  SculptToolSettings settings;
  settings.tool = SculptTool::kGrab;
  settings.radius = 0.02;
  settings.stiffness = 500.0;
  const double theta = 3 * kPi / 8;  // strength 0.5
  EXPECT_FALSE(
      ComputeStrokeWrench(sculpt.force_model(), Pose(R0, c + Eigen::Vector3d(0.1, 0, 0)), 0.0)
          .f_T_W.any());
  sculpt.BeginStroke(settings, Pose(R0, c), theta);
  const StrokeForceModel model = sculpt.force_model();
  ASSERT_TRUE(model.active);
  const SculptWrench at_start = ComputeStrokeWrench(model, Pose(R0, c), theta);
  EXPECT_EQ(at_start.f_T_W, Eigen::Vector3d::Zero());
  EXPECT_EQ(at_start.m_T_W, Eigen::Vector3d::Zero());
  const Eigen::Vector3d dp(0.004, -0.002, 0.003);
  const SculptWrench one = ComputeStrokeWrench(model, Pose(R0, c + dp), theta);
  const SculptWrench two = ComputeStrokeWrench(model, Pose(R0, c + 2 * dp), theta);
  EXPECT_NEAR((two.f_T_W - 2 * one.f_T_W).norm(), 0.0, 1e-12);
  EXPECT_NEAR((one.f_T_W + 500.0 * 0.5 * dp).norm(), 0.0, 1e-12);  // opposes the pull: -k s Δp
  // The force does the work the grabbed material stores: along the path it is -dE/dp with
  // E = k s |Δp|²/2 (finite differences).
  const double h = 1e-7;
  for (int i = 0; i < 3; ++i) {
    auto Energy = [&](const Eigen::Vector3d& p) {
      return 0.5 * 500.0 * 0.5 * (p - c).squaredNorm();
    };
    const Eigen::Vector3d e = h * Eigen::Vector3d::Unit(i);
    const double dE = (Energy(c + dp + e) - Energy(c + dp - e)) / (2 * h);
    EXPECT_NEAR(one.f_T_W[i], -dE, 1e-6);
  }
  sculpt.EndStroke();

  // Twist: moment about the grip axis, linear in small angles, stiffness × R² per rad.
  settings.tool = SculptTool::kTwist;
  sculpt.BeginStroke(settings, Pose(R0, c), 0.0);
  const StrokeForceModel twist = sculpt.force_model();
  const Eigen::Vector3d z = R0.col(2);
  const SculptWrench small =
      ComputeStrokeWrench(twist, Pose(Eigen::AngleAxisd(0.01, z) * R0, c), 0.0);
  const SculptWrench twice =
      ComputeStrokeWrench(twist, Pose(Eigen::AngleAxisd(0.02, z) * R0, c), 0.0);
  EXPECT_NEAR((small.m_T_W + 500.0 * 0.02 * 0.02 * 0.01 * z).norm(), 0.0, 1e-12);
  EXPECT_NEAR((twice.m_T_W - 2 * small.m_T_W).norm(), 0.0, 1e-12);
  EXPECT_EQ(small.f_T_W, Eigen::Vector3d::Zero());

  // Neither the wrench nor a stroke update allocates.
  ASSERT_TRUE(test_support::MallocCounterActive());
  double sum = 0.0;
  {
    test_support::MallocCounter counter;
    for (int i = 0; i < 1000; ++i) {
      const Eigen::Isometry3d X = Pose(Eigen::AngleAxisd(1e-4 * i, z) * R0, c + 1e-6 * i * dp);
      sum += ComputeStrokeWrench(twist, X, 0.1).m_T_W.norm() +
             ComputeStrokeWrench(model, X, 0.1).f_T_W.norm();
      sculpt.UpdateStroke(X, 0.1);
    }
    EXPECT_EQ(counter.count(), 0);
  }
  EXPECT_GT(sum, 0.0);
  sculpt.EndStroke();
  EXPECT_FALSE(sculpt.force_model().active);
}

// ---------------------------------------------------------------------------------------------
// Hard cases: strokes that would fold the surface through itself.

// A lens 10 cm across and 16 mm thick at its centre (an icosphere squashed along z).
TriangleMesh ThinLens() {
  TriangleMesh mesh = IcosphereMesh(0.05, 4);
  mesh.vertices.row(2) *= 0.16;
  return mesh;
}

// The independent check: CheckSurface's own grid and exact-sign triangle tests over the whole mesh.
std::string SurfaceDefect(const TriangleMesh& mesh) {
  try {
    CheckSurface(mesh);
  } catch (const std::exception& e) {
    return e.what();
  }
  return "";
}

// Runs one stroke on the lens from its top pole to `X_end` in `steps` updates; returns the mesh.
TriangleMesh StrokeOnLens(SculptToolSettings tool, const Eigen::Vector3d& drag, int steps,
                          bool prevent, StrokeStats* stats = nullptr) {
  SculptMesh mesh(ThinLens(), 0.005);
  tool.prevent_self_intersection = prevent;
  const Eigen::Vector3d top(0, 0, 0.008);
  mesh.BeginStroke(tool, Pose(Eigen::Matrix3d::Identity(), top), 0.0);
  for (int k = 1; k <= steps; ++k) {
    mesh.UpdateStroke(Pose(Eigen::Matrix3d::Identity(), top + drag * k / steps), 0.0);
  }
  if (stats != nullptr) *stats = mesh.stroke_stats();
  mesh.EndStroke();
  return mesh.ToTriangleMesh();
}

TEST(HardSculpt, GrabbingTheTopThroughTheBottomStopsBeforeTheSurfacesCross) {
  const SculptToolSettings grab = Tool(SculptTool::kGrab, 0.03);
  const Eigen::Vector3d drag(0, 0, -0.03);  // the top pole 3 cm down, through the 16 mm lens
  ASSERT_EQ(SurfaceDefect(ThinLens()), "");
  // Unchecked, the stroke folds the top through the bottom: the oracle sees it.
  const std::string folded = SurfaceDefect(StrokeOnLens(grab, drag, 1, false));
  EXPECT_NE(folded, "") << "the unchecked stroke should cross the bottom";
  // Checked: no crossing, and the stroke stops just short of where the poles meet. Closed form:
  // the top pole moves down by t·3 cm, the bottom pole (16 mm from the grab centre) by t·w·3 cm
  // with w = (1 − (16/30)²)³; they meet at t* = 16 mm / (30 mm (1 − w)) ≈ 0.842. The bisection
  // keeps the largest multiple of 1/256 below the first crossing.
  StrokeStats stats;
  const TriangleMesh kept = StrokeOnLens(grab, drag, 1, true, &stats);
  EXPECT_EQ(SurfaceDefect(kept), "");
  const double w = SculptFalloffWeight(0.016, 0.03, SculptFalloffExponent(grab.stiffness));
  const double t_meet = 0.016 / (0.03 * (1.0 - w));
  EXPECT_LT(stats.limit, t_meet);
  EXPECT_GE(stats.limit, t_meet - 1.0 / 256 - 0.01);  // 0.01: the meshes meet slightly earlier
  EXPECT_EQ(stats.intersection_checks, 9);
  // The result depends on the final pose only, not on the path (as every stroke).
  const TriangleMesh stepped = StrokeOnLens(grab, drag, 7, true);
  EXPECT_EQ((kept.vertices - stepped.vertices).cwiseAbs().maxCoeff(), 0.0);
  RecordProperty("figure", "share of the stroke applied " + std::to_string(stats.limit) +
                               "; unchecked: " + folded.substr(0, 80));
  RecordProperty("bar", "no self-intersection (CheckSurface); share within 1/256 + 0.01 below " +
                            std::to_string(t_meet) + " (the poles meet)");
}

TEST(HardSculpt, PushingBothFacesOfTheLensTogetherWithVolumeConservationStopsShort) {
  SculptToolSettings push = Tool(SculptTool::kPushPull, 0.035);
  push.conserve_volume = true;
  const Eigen::Vector3d drag(0, 0, -0.04);
  EXPECT_NE(SurfaceDefect(StrokeOnLens(push, drag, 1, false)), "");
  StrokeStats stats;
  const TriangleMesh kept = StrokeOnLens(push, drag, 3, true, &stats);
  EXPECT_EQ(SurfaceDefect(kept), "");
  EXPECT_GT(stats.limit, 0.0);
  EXPECT_LT(stats.limit, 1.0);
  // The volume is still conserved at the share applied.
  EXPECT_NEAR(stats.volume, stats.start_volume, 1e-9 * stats.start_volume);
  RecordProperty("figure", "share of the stroke applied " + std::to_string(stats.limit));
  RecordProperty("bar", "no self-intersection (CheckSurface); volume within 1e-9");
}

TEST(HardSculpt, AStrokeThatDoesNotFoldIsUnchangedByTheCheck) {
  const SculptToolSettings grab = Tool(SculptTool::kGrab, 0.03);
  const Eigen::Vector3d lift(0.01, 0, 0.02);  // pulling the top up and aside folds nothing
  StrokeStats stats;
  const TriangleMesh checked = StrokeOnLens(grab, lift, 1, true, &stats);
  const TriangleMesh unchecked = StrokeOnLens(grab, lift, 1, false);
  EXPECT_EQ(stats.limit, 1.0);
  EXPECT_EQ(stats.intersection_checks, 1);
  EXPECT_EQ((checked.vertices - unchecked.vertices).cwiseAbs().maxCoeff(), 0.0);
  EXPECT_EQ(SurfaceDefect(checked), "");
  RecordProperty("figure", "identical to the unchecked stroke");
  RecordProperty("bar", "bit-identical positions, one check");
}

TEST(HardSculpt, ARegionThatAlreadyIntersectsItselfIsNotFrozen) {
  // The folded lens from above, sculpted again near the fold: the check is skipped for this
  // stroke (it would stop every motion), so the stroke moves the material as asked.
  const TriangleMesh folded =
      StrokeOnLens(Tool(SculptTool::kGrab, 0.03), Eigen::Vector3d(0, 0, -0.03), 1, false);
  ASSERT_NE(SurfaceDefect(folded), "");
  SculptMesh mesh(folded, 0.005);
  const Eigen::Vector3d at(0, 0, -0.022);
  mesh.BeginStroke(Tool(SculptTool::kGrab, 0.01), Pose(Eigen::Matrix3d::Identity(), at), 0.0);
  mesh.UpdateStroke(Pose(Eigen::Matrix3d::Identity(), at + Eigen::Vector3d(0, 0, -0.002)), 0.0);
  EXPECT_EQ(mesh.stroke_stats().limit, 1.0);
  EXPECT_EQ(mesh.stroke_stats().intersection_checks, 0);
  RecordProperty("figure", "stroke applied in full, no check");
  RecordProperty("bar", "limit 1");
}

}  // namespace
}  // namespace spidarcad::modeling
