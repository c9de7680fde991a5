// Tests of the one builder of FE parts (scene/fe_part.cc) shared by FE mode and `spidarcad run`:
// the part built from a document FE model, the candidates near a path (against a brute-force
// distance), and the deterministic column set a scripted run prepares.
// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#include "scene/fe_part.h"

#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <filesystem>
#include <memory>
#include <string>
#include <utility>
#include <variant>
#include <vector>

#include "doc/command.h"
#include "doc/document.h"
#include "spidarcad/fem/mesh.h"
#include "spidarcad/modeling/tet_mesh.h"

namespace spidarcad::app {
namespace {

// A 0.3 x 0.05 x 0.05 m beam of 6 x 2 x 2 boxes (W, m), linear tetrahedra.
fem::TetMesh Beam() {
  fem::BoxMeshSettings box;
  box.upper = Eigen::Vector3d(0.3, 0.05, 0.05);
  box.nx = 6;
  box.ny = 2;
  box.nz = 2;
  return fem::MakeBoxMesh(box);
}

// The beam as a modeling mesh, for a document.
std::shared_ptr<modeling::TetMesh> BeamForDocument() {
  const fem::TetMesh m = Beam();
  auto out = std::make_shared<modeling::TetMesh>();
  out->nodes = m.nodes.transpose();
  out->tets.resize(4, m.num_elements());
  for (int e = 0; e < m.num_elements(); ++e)
    for (int j = 0; j < 4; ++j) out->tets(j, e) = m.elements(e, j);
  out->regions = Eigen::VectorXi::Zero(m.num_elements());
  return out;
}

// Settings that keep the model on this thread and off the disk.
FeModelSettings Quiet() {
  FeModelSettings s;
  s.use_disk_cache = false;
  s.cache.start_worker = false;
  return s;
}

// A scratch directory of this test (emptied).
std::filesystem::path Scratch(const std::string& name) {
  const std::filesystem::path dir = std::filesystem::path(SPIDARCAD_TEST_OUTPUT_DIR) / name;
  std::filesystem::remove_all(dir);
  std::filesystem::create_directories(dir);
  return dir;
}

TEST(FePart, IsBuiltFromTheDocumentWithFeModesTouchSettings) {
  Document doc;
  doc.Execute(edit::AddMesh("beam tets", 0, 0, nullptr, BeamForDocument()));
  FeModelData data;
  data.tet_mesh = doc.last_created().front();
  data.material = {70e9, 0.33};
  doc.Execute(edit::AddObject("beam FE", data));
  const ObjectId fe = doc.last_created().front();
  ASSERT_EQ(FeModelsOf(doc), std::vector<ObjectId>{fe});
  EXPECT_EQ(FeModelSource(doc, fe), 0u);  // an imported mesh: no source

  FePartOptions options;
  options.world_scale = 2.0;
  options.model = Quiet();
  FePart part = BuildFePart(doc, fe, options);
  EXPECT_EQ(part.name, "beam FE");
  EXPECT_EQ(part.mesh, data.tet_mesh);
  ASSERT_TRUE(part.model && part.field && part.channel);
  EXPECT_EQ(part.model->material().youngs_modulus, 70e9);
  EXPECT_EQ(part.model->num_fixed_nodes(), 9);  // the minimum-x face: 3 x 3 nodes
  // FE mode's defaults, as felt at the grip, divided by the world scale for the field (W).
  const FeTouchSettings& ts = part.field->settings();
  // The tool has a physical size on the part: its radius is not scaled by the world scale.
  EXPECT_DOUBLE_EQ(ts.tool_radius, kDefaultFeToolRadius);
  EXPECT_TRUE(ts.patch_contact);
  EXPECT_DOUBLE_EQ(ts.force_scale, kDefaultFeForceScale / 2.0);
  EXPECT_DOUBLE_EQ(ts.coupling_stiffness, kDefaultFeCoupling / 2.0);
  EXPECT_EQ(ts.max_force, 8.0);
  EXPECT_FALSE(ts.frictionless);  // sticking, as `felt` defines the patch stiffness
  EXPECT_FALSE(ts.grasp);

  EXPECT_THROW(BuildFePart(doc, data.tet_mesh, options), DocumentError);  // not an FE model
}

// A mesh made from a solid has that solid as its design while it is up to date with it
// (FeDesignOf), and the part built from it takes the design's normals: the normalised gradient of
// the solid where it agrees with the mesh's normal (kDesignNormalAgreement), the mesh's elsewhere;
// on the beam's flat faces the face's normal. A mesh with no source, or made from a revision the
// solid no longer has, has no design: the mesh's normals.
TEST(FePart, DesignIsTheSourceSolidWhileTheMeshIsUpToDate) {
  Document doc;
  const modeling::ImplicitNode box(
      modeling::TranslateParams{Eigen::Vector3d(0.15, 0.025, 0.025)},
      {modeling::ImplicitNode(modeling::BoxParams{Eigen::Vector3d(0.3, 0.05, 0.05)})});
  doc.Execute(edit::AddSolid("beam", box));
  const ObjectId solid = doc.last_created().front();
  doc.Execute(
      edit::AddMesh("beam tets", solid, doc.Get(solid).revision, nullptr, BeamForDocument()));
  const ObjectId mesh = doc.last_created().front();
  doc.Execute(edit::AddMesh("imported tets", 0, 0, nullptr, BeamForDocument()));
  const ObjectId imported = doc.last_created().front();
  EXPECT_EQ(FeDesignOf(doc, imported), nullptr);
  const std::shared_ptr<const modeling::CompiledSolid> design = FeDesignOf(doc, mesh);
  ASSERT_NE(design, nullptr);
  EXPECT_NEAR(design->Value(Eigen::Vector3d(0.1, 0.02, 0.06)), 0.01, 1e-12);  // 1 cm above

  FeModelData data;
  data.tet_mesh = mesh;
  data.material = {70e9, 0.33};
  doc.Execute(edit::AddObject("beam FE", data));
  FePartOptions options;
  options.model = Quiet();
  const FePart part = BuildFePart(doc, doc.last_created().front(), options);
  const FeModel& model = *part.model;
  EXPECT_GT(model.num_design_normals(), 0);
  int face_interior = 0;
  for (int b = 0; b < model.cache().num_candidates(); ++b) {
    const Eigen::Vector3d x = model.mesh().nodes.row(model.cache().candidate_node(b)).transpose();
    const Eigen::Vector3d mesh_n = model.candidate_normals().row(b).transpose();
    const Eigen::Vector3d n = model.design_normals().row(b).transpose();
    Eigen::Vector3d gradient;
    design->ValueAndGradient(x, &gradient);
    const Eigen::Vector3d g = gradient.normalized();
    if (g.dot(mesh_n) >= kDesignNormalAgreement)
      EXPECT_NEAR((n - g).norm(), 0.0, 1e-12) << "node at " << x.transpose();
    else
      EXPECT_EQ(n, mesh_n) << "node at " << x.transpose();
    // A node inside the top face (z = 0.05 m, off its edges): the face's normal.
    if (std::abs(x.z() - 0.05) < 1e-12 && x.x() > 1e-6 && x.x() < 0.3 - 1e-6 && x.y() > 1e-6 &&
        x.y() < 0.05 - 1e-6) {
      ++face_interior;
      EXPECT_NEAR((n - Eigen::Vector3d::UnitZ()).norm(), 0.0, 1e-12);
    }
  }
  EXPECT_GT(face_interior, 0);

  // The solid edited: the mesh is out of date, no design.
  doc.Execute(edit::ReplaceTree(solid, modeling::ImplicitNode(modeling::BoxParams{})));
  EXPECT_EQ(FeDesignOf(doc, mesh), nullptr);
}

TEST(FePart, CandidatesNearPathAreTheSurfaceNodesWithinReachOfThePolyline) {
  const std::unique_ptr<FeModel> model = FeModel::Build(Beam(), Quiet());
  const std::vector<Eigen::Vector3d> path = {Eigen::Vector3d(0.1, 0.025, 0.12),
                                             Eigen::Vector3d(0.1, 0.025, 0.03),
                                             Eigen::Vector3d(0.26, -0.01, 0.06)};
  const double radius = 0.04;
  const std::vector<int> near = CandidatesNearPath(*model, path, radius);
  // Brute force: the distance to 20000 points along each segment (spacing under 10 µm).
  const fem::ColumnCache& cache = model->cache();
  int inside = 0;
  for (int b = 0; b < cache.num_candidates(); ++b) {
    const Eigen::Vector3d x = model->mesh().nodes.row(cache.candidate_node(b)).transpose();
    double d = 1e30;
    for (std::size_t i = 1; i < path.size(); ++i)
      for (int k = 0; k <= 20000; ++k)
        d = std::min(d, (x - (path[i - 1] + (path[i] - path[i - 1]) * (k / 20000.0))).norm());
    const bool listed = std::find(near.begin(), near.end(), b) != near.end();
    if (cache.IsFixed(b)) {
      EXPECT_FALSE(listed) << "clamped candidate " << b;
    } else if (d < radius - 1e-5) {
      EXPECT_TRUE(listed) << "candidate " << b << " at " << d << " m";
      ++inside;
    } else if (d > radius + 1e-5) {
      EXPECT_FALSE(listed) << "candidate " << b << " at " << d << " m";
    }
  }
  EXPECT_GT(inside, 5);
  // Nearest the path first: the brute-force distances of the list do not decrease.
  std::vector<double> distances;
  for (int b : near) {
    const Eigen::Vector3d x = model->mesh().nodes.row(cache.candidate_node(b)).transpose();
    double d = 1e30;
    for (std::size_t i = 1; i < path.size(); ++i)
      for (int k = 0; k <= 20000; ++k)
        d = std::min(d, (x - (path[i - 1] + (path[i] - path[i - 1]) * (k / 20000.0))).norm());
    distances.push_back(d);
  }
  for (std::size_t i = 1; i < distances.size(); ++i)
    EXPECT_LE(distances[i - 1], distances[i] + 1e-5) << "position " << i;
  // One point: a ball.
  const std::vector<int> ball = CandidatesNearPath(*model, {Eigen::Vector3d(0.3, 0, 0)}, 0.001);
  ASSERT_EQ(ball.size(), 1u);
  EXPECT_LT((model->mesh().nodes.row(cache.candidate_node(ball[0])) - Eigen::RowVector3d(0.3, 0, 0))
                .norm(),
            1e-12);
}

TEST(FePart, PreparedColumnsAreExactlyThoseAskedForWhateverTheDiskCacheHeld) {
  const std::filesystem::path dir = Scratch("fe_part_columns");
  FeModelSettings settings = Quiet();
  settings.use_disk_cache = true;
  settings.cache_directory = dir;
  const std::unique_ptr<FeModel> first = FeModel::Build(Beam(), settings);
  const int n = first->cache().num_candidates();
  std::vector<int> a, b;  // a: every third free candidate; b: every second one
  for (int c = 0; c < n; ++c) {
    if (first->cache().IsFixed(c)) continue;
    if (c % 3 == 0) a.push_back(c);
    if (c % 2 == 0) b.push_back(c);
  }
  const FeColumnPlan cold = PrepareColumns(first.get(), a, /*save=*/true, dir);
  EXPECT_EQ(cold.requested, static_cast<int>(a.size()));
  EXPECT_EQ(cold.from_disk, 0);
  EXPECT_EQ(cold.computed, static_cast<int>(a.size()));
  EXPECT_EQ(cold.ready, static_cast<int>(a.size()));
  EXPECT_TRUE(cold.saved);

  // Reopened: the disk gives a; b is asked for. Ready afterwards: b and nothing else.
  const std::unique_ptr<FeModel> second = FeModel::Build(Beam(), settings);
  EXPECT_EQ(second->imported_nodes(), static_cast<int>(a.size()));
  const FeColumnPlan warm = PrepareColumns(second.get(), b, /*save=*/true, dir);
  int shared = 0;
  for (int c : b) shared += std::binary_search(a.begin(), a.end(), c) ? 1 : 0;
  EXPECT_EQ(warm.from_disk, shared);
  EXPECT_EQ(warm.computed, static_cast<int>(b.size()) - shared);
  for (int c = 0; c < n; ++c)
    EXPECT_EQ(second->cache().IsReady(c), std::binary_search(b.begin(), b.end(), c)) << c;
  // The columns equal those of a model that computed them all afresh.
  const std::unique_ptr<FeModel> fresh = FeModel::Build(Beam(), Quiet());
  PrepareColumns(fresh.get(), b, /*save=*/false);
  double worst = 0.0, largest = 0.0;
  for (int c : b) {
    ASSERT_TRUE(second->cache().Pin(c) && fresh->cache().Pin(c));
    for (int j = 0; j < 3; ++j)
      for (int r = 0; r < 3 * fresh->cache().num_outputs(); ++r) {
        worst = std::max(worst,
                         std::abs(second->cache().Value(r, c, j) - fresh->cache().Value(r, c, j)));
        largest = std::max(largest, std::abs(fresh->cache().Value(r, c, j)));
      }
    second->cache().Unpin(c);
    fresh->cache().Unpin(c);
  }
  EXPECT_LE(worst, 1e-12 * largest);
  // The file now holds a and b: a third model imports both.
  const std::unique_ptr<FeModel> third = FeModel::Build(Beam(), settings);
  std::vector<int> both = a;
  both.insert(both.end(), b.begin(), b.end());
  std::sort(both.begin(), both.end());
  both.erase(std::unique(both.begin(), both.end()), both.end());
  EXPECT_EQ(third->imported_nodes(), static_cast<int>(both.size()));

  // A memory bound of one node's columns: the first candidate asked for is the one kept.
  FeModelSettings small = Quiet();
  small.cache.memory_budget_bytes = 1.0;
  const std::unique_ptr<FeModel> tight = FeModel::Build(Beam(), small);
  ASSERT_EQ(tight->cache().capacity_nodes(), 1);
  const FeColumnPlan bounded = PrepareColumns(tight.get(), {b[2], b[0], b[1]}, false);
  EXPECT_EQ(bounded.requested, 3);
  EXPECT_EQ(bounded.ready, 1);
  EXPECT_TRUE(tight->cache().IsReady(b[2]));

  // The worker must be stopped.
  FeModelSettings running = Quiet();
  running.cache.start_worker = true;
  const std::unique_ptr<FeModel> busy = FeModel::Build(Beam(), running);
  EXPECT_THROW(PrepareColumns(busy.get(), a, false), std::logic_error);
}

}  // namespace
}  // namespace spidarcad::app
