// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
// The platform meshed in slabs (scene/slab_fe_mesh.h), edited (its load holes widened, inside the
// last slab), re-meshed: only the edited slab goes through TetGen again, the others keep their
// tets bit for bit, the substructured solver refactors only that slab, and the felt patch's
// compliance equals a monolithic solve of the new mesh.
#include "scene/slab_fe_mesh.h"

#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <algorithm>
#include <fstream>
#include <functional>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "scene/fe_model.h"
#include "scene/scene_solid.h"
#include "spidarcad/fem/boundary.h"
#include "spidarcad/fem/static_solver.h"
#include "spidarcad/fem/substructure.h"

namespace spidarcad::app {
namespace {

constexpr double kCell = 0.0125;
constexpr int kSlabs =
    4;  // planes near x = 0.056, 0.146, 0.237 m: the holes (0.27 m) are 2 cells clear

// Sets `field` of the node with `id` in the platform scene to `value`; returns the new file.
std::string EditedPlatform(const std::string& id, const std::string& field,
                           const nlohmann::json& value, const std::string& name) {
  std::ifstream in(PlatformScenePath());
  nlohmann::json scene = nlohmann::json::parse(in);
  bool found = false;
  std::function<void(nlohmann::json&)> visit = [&](nlohmann::json& node) {
    if (node.is_object()) {
      if (node.contains("id") && node["id"] == id) {
        node[field] = value;
        found = true;
      }
      for (auto& [key, child] : node.items()) visit(child);
    } else if (node.is_array()) {
      for (auto& child : node) visit(child);
    }
  };
  visit(scene);
  EXPECT_TRUE(found) << id;
  const std::string path = std::string(SPIDARCAD_TEST_OUTPUT_DIR) + "/" + name + ".json";
  std::ofstream(path) << scene.dump(1);
  return path;
}

TEST(SlabFeMesh, EditInTheLastSlabRemeshesAndRefactorsOnlyThatSlab) {
  const SceneSolidGrid base = PrepareSceneSolid(PlatformScenePath(), "platform", kCell);
  // The grid of the first mesh is kept for the edit (the edit stays inside its box).
  const Eigen::AlignedBox3d grid = base.bounds;
  const std::vector<double> planes = SlabPlanes(grid, kCell, kSlabs);
  ASSERT_EQ(planes.size(), kSlabs - 1u);
  const SlabFeMesh before = MeshSolidInSlabs(base.compiled, grid, kCell, planes);
  EXPECT_EQ(before.num_remeshed(), kSlabs);
  ASSERT_NO_THROW(before.mesh.Validate());

  // The load holes (x = 0.27 m, last slab) from 4 to 4.5 mm radius.
  const SceneSolidGrid edited = PrepareSceneSolid(
      EditedPlatform("load_hole", "radius", 0.0045, "slab_fe_mesh_hole"), "platform", kCell);
  const SlabFeMesh after = MeshSolidInSlabs(edited.compiled, grid, kCell, planes, 2.0, &before);
  EXPECT_EQ(after.num_remeshed(), 1);
  EXPECT_TRUE(after.remeshed.back());
  for (int k = 0; k + 1 < kSlabs; ++k) {
    ASSERT_EQ(after.slab_tets[k].tets.cols(), before.slab_tets[k].tets.cols());
    EXPECT_TRUE((after.slab_tets[k].nodes.array() == before.slab_tets[k].nodes.array()).all());
  }
  // The edit did change the part: the last slab lost volume.
  EXPECT_LT(modeling::TotalVolume(after.slab_tets.back()),
            modeling::TotalVolume(before.slab_tets.back()));

  for (int order : {1, 2}) {
    SCOPED_TRACE("order " + std::to_string(order));
    const fem::TetMesh m0 = order == 2 ? fem::MakeQuadratic(before.mesh) : before.mesh;
    const fem::TetMesh m1 = order == 2 ? fem::MakeQuadratic(after.mesh) : after.mesh;
    const fem::MaterialTable steel(fem::Material{2.0e11, 0.3});
    auto conditions = [](const fem::TetMesh& mesh) {
      fem::BoundaryConditions bcs(mesh.num_nodes());
      bcs.FixNodes(MinXFaceNodes(mesh));
      return bcs;
    };
    const fem::SubstructuredSolver s0(m0, steel, conditions(m0), before.slab);
    const fem::BoundaryConditions bcs1 = conditions(m1);
    const fem::SubstructuredSolver s1(m1, steel, bcs1, after.slab, &s0);
    ASSERT_TRUE(s1.factor_status().converged) << s1.factor_status().message;
    EXPECT_EQ(s1.stats().factored_blocks, 1);
    EXPECT_FALSE(s1.block_stats(kSlabs - 1).reused);
    // The felt patch: the plate-top nodes nearest the free corner, their 3 × 3 blocks.
    const Eigen::Vector3d corner(0.29, 0.09, 0.01);
    std::vector<int> patch;
    for (int v = 0; v < m1.num_nodes(); ++v)
      if (m1.nodes(v, 2) > 0.0099 && s1.FreeIndex(3 * v) >= 0) patch.push_back(v);
    std::sort(patch.begin(), patch.end(), [&](int a, int b) {
      return (m1.nodes.row(a).transpose() - corner).norm() <
             (m1.nodes.row(b).transpose() - corner).norm();
    });
    patch.resize(6);
    Eigen::MatrixXd rhs = Eigen::MatrixXd::Zero(s1.num_free(), 3 * patch.size());
    for (std::size_t c = 0; c < patch.size(); ++c)
      for (int j = 0; j < 3; ++j) rhs(s1.FreeIndex(3 * patch[c] + j), 3 * c + j) = 1.0;
    Eigen::MatrixXd x_sub, x_mono;
    ASSERT_TRUE(s1.SolveFreeInBlocks(rhs, {kSlabs - 1}, &x_sub).converged);
    const fem::StaticSolver mono(m1, steel, bcs1);
    ASSERT_TRUE(mono.SolveFree(rhs, &x_mono).converged);
    Eigen::MatrixXd g_sub(rhs.cols(), rhs.cols()), g_mono(rhs.cols(), rhs.cols());
    for (std::size_t a = 0; a < patch.size(); ++a)
      for (int i = 0; i < 3; ++i) {
        g_sub.row(3 * a + i) = x_sub.row(s1.FreeIndex(3 * patch[a] + i));
        g_mono.row(3 * a + i) = x_mono.row(mono.FreeIndex(3 * patch[a] + i));
      }
    EXPECT_LT((g_sub - g_mono).norm(), 1e-9 * g_mono.norm());
  }
}

}  // namespace
}  // namespace spidarcad::app
