// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
// The platform meshed in slabs (scene/slab_fe_mesh.h), edited (its load holes widened, inside the
// last slab), re-meshed: only the edited slab goes through TetGen again, the others keep their
// tets bit for bit, the substructured solver refactors only that slab, and the felt patch's
// compliance equals a monolithic solve of the new mesh.
#include "scene/slab_fe_mesh.h"

#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <algorithm>
#include <filesystem>
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

// MeshSolidInSlabs's options: TetGen's bound, the earlier mesh and the cache directory.
SlabMeshOptions Options(double max_radius_edge, const SlabFeMesh* previous,
                        const std::filesystem::path& dir = {}) {
  SlabMeshOptions o;
  o.max_radius_edge = max_radius_edge;
  o.previous = previous;
  o.cache_directory = dir;
  return o;
}

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
  const SlabFeMesh after =
      MeshSolidInSlabs(edited.compiled, grid, kCell, planes, Options(2.0, &before));
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

// The cache directory keeps slab meshes between runs: a mesh made with no earlier mesh in memory
// reads every slab from it, bit for bit; after the edit it reads the three slabs the edit left
// alone and meshes the last; a damaged file is refused with a note naming it and re-meshed.
TEST(SlabFeMesh, CacheDirectoryKeepsSlabMeshesBetweenRuns) {
  const std::filesystem::path dir =
      std::filesystem::path(SPIDARCAD_TEST_OUTPUT_DIR) / "slab_fe_mesh_cache";
  std::filesystem::remove_all(dir);
  const SceneSolidGrid base = PrepareSceneSolid(PlatformScenePath(), "platform", kCell);
  const Eigen::AlignedBox3d grid = base.bounds;
  const std::vector<double> planes = SlabPlanes(grid, kCell, kSlabs);
  const SlabFeMesh first =
      MeshSolidInSlabs(base.compiled, grid, kCell, planes, Options(2.0, nullptr, dir));
  EXPECT_EQ(first.num_remeshed(), kSlabs);
  EXPECT_TRUE(first.cache_notes.empty());
  const SlabFeMesh second =
      MeshSolidInSlabs(base.compiled, grid, kCell, planes, Options(2.0, nullptr, dir));
  EXPECT_EQ(second.num_remeshed(), 0);
  EXPECT_EQ(std::count(second.loaded.begin(), second.loaded.end(), 1), kSlabs);
  EXPECT_TRUE((second.mesh.nodes.array() == first.mesh.nodes.array()).all());
  EXPECT_TRUE((second.mesh.elements.array() == first.mesh.elements.array()).all());
  EXPECT_TRUE((second.slab.array() == first.slab.array()).all());
  // Another TetGen bound is another key: nothing read.
  const SlabFeMesh other =
      MeshSolidInSlabs(base.compiled, grid, kCell, planes, Options(1.8, nullptr, dir));
  EXPECT_EQ(other.num_remeshed(), kSlabs);

  const SceneSolidGrid edited = PrepareSceneSolid(
      EditedPlatform("load_hole", "radius", 0.0045, "slab_fe_mesh_cache_hole"), "platform", kCell);
  const SlabFeMesh after =
      MeshSolidInSlabs(edited.compiled, grid, kCell, planes, Options(2.0, nullptr, dir));
  EXPECT_EQ(after.num_remeshed(), 1);
  EXPECT_TRUE(after.remeshed.back());
  EXPECT_EQ(std::count(after.loaded.begin(), after.loaded.end(), 1), kSlabs - 1);

  // Damage every file of the first mesh's slabs (a byte flipped in the middle).
  int damaged = 0;
  for (const auto& entry : std::filesystem::directory_iterator(dir)) {
    if (entry.path().extension() != ".slab") continue;
    std::fstream f(entry.path(), std::ios::in | std::ios::out | std::ios::binary);
    f.seekg(static_cast<std::streamoff>(entry.file_size() / 2));
    const char c = static_cast<char>(f.get());
    f.seekp(static_cast<std::streamoff>(entry.file_size() / 2));
    f.put(static_cast<char>(c ^ 0x40));
    ++damaged;
  }
  EXPECT_GE(damaged, kSlabs + 1);
  const SlabFeMesh refused =
      MeshSolidInSlabs(base.compiled, grid, kCell, planes, Options(2.0, nullptr, dir));
  EXPECT_EQ(refused.num_remeshed(), kSlabs);
  ASSERT_EQ(refused.cache_notes.size(), static_cast<std::size_t>(kSlabs));
  EXPECT_NE(refused.cache_notes[0].find("slab 0: refused " + dir.string()), std::string::npos)
      << refused.cache_notes[0];
  EXPECT_NE(refused.cache_notes[0].find("checksum"), std::string::npos) << refused.cache_notes[0];
  EXPECT_TRUE((refused.mesh.nodes.array() == first.mesh.nodes.array()).all());
  std::filesystem::remove_all(dir);
}

}  // namespace
}  // namespace spidarcad::app
