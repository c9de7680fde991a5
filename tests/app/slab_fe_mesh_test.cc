// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
// The platform meshed in slabs (scene/slab_fe_mesh.h), edited (its load holes widened, inside the
// last slab), re-meshed: only the edited slab goes through TetGen again, the others keep their
// tets bit for bit, the substructured solver refactors only that slab, and the felt patch's
// compliance equals a monolithic solve of the new mesh.
#include "scene/slab_fe_mesh.h"

#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <functional>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "scene/fe_model.h"
#include "scene/scene_solid.h"
#include "sculpt_stroke_support.h"
#include "spidarcad/fem/boundary.h"
#include "spidarcad/fem/static_solver.h"
#include "spidarcad/fem/substructure.h"
#include "spidarcad/modeling/feature_sharpening.h"
#include "spidarcad/modeling/implicit_evaluator.h"
#include "spidarcad/modeling/implicit_node.h"
#include "spidarcad/modeling/sculpt.h"
#include "spidarcad/modeling/surface_mesher.h"

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

// Factors `before` in slabs, then `after` (re-meshed in its last slab only) with the first as the
// reuse solver, at orders 1 and 2, the min-x face clamped: only the last slab is factored again,
// and the compliance of the plate-top nodes nearest the free corner equals a monolithic solve of
// the new mesh.
void ExpectOnlyTheLastSlabRefactoredAndExact(const SlabFeMesh& before, const SlabFeMesh& after) {
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
  const SlabFeMesh after = MeshSolidInSlabs(edited.compiled, before.grid_bounds, kCell,
                                            before.planes, Options(2.0, &before));
  EXPECT_EQ(after.num_remeshed(), 1);
  EXPECT_TRUE(after.remeshed.back());
  for (int k = 0; k + 1 < kSlabs; ++k) {
    ASSERT_EQ(after.slab_tets[k].tets.cols(), before.slab_tets[k].tets.cols());
    EXPECT_TRUE((after.slab_tets[k].nodes.array() == before.slab_tets[k].nodes.array()).all());
  }
  // The edit did change the part: the last slab lost volume.
  EXPECT_LT(modeling::TotalVolume(after.slab_tets.back()),
            modeling::TotalVolume(before.slab_tets.back()));

  ExpectOnlyTheLastSlabRefactoredAndExact(before, after);
}

// A wall about a cell thick (the platform's 10 mm plate at 13.5 mm cells, snapped as FE mode
// snaps) falls between the grid's planes on the first placement: MeshSolidInSlabs meshes the
// surface on a grid moved by a fraction of a cell, moves the slab planes with it, and keeps the
// solid's volume; meshed again on its grid and planes with it as the earlier mesh, every slab
// comes back as it was.
TEST(SlabFeMesh, MovesTheGridAndItsPlanesWhereAWallFallsBetweenGridPlanes) {
  const double cell = 0.0135;
  const SceneSolidGrid base = PrepareSceneSolid(PlatformScenePath(), "platform", cell);
  SlabMeshOptions o;
  o.snap_cells = modeling::kProductSnapCells;
  const std::vector<double> planes = SlabPlanes(base.bounds, cell, kSlabs, o);
  const SlabFeMesh m = MeshSolidInSlabs(base.compiled, base.bounds, cell, planes, o);
  // The solid's volume sampled from its function, and the surface of the unmoved grid.
  const double solid =
      modeling::EstimateSolidVolume(base.compiled, base.bounds, modeling::kSharpVolumePoints);
  modeling::SurfaceMeshSettings ss;
  ss.bounds = base.bounds;
  ss.cell_size = cell;
  ss.snap_cells = o.snap_cells;
  EXPECT_LT(modeling::MeshVolume(modeling::MeshSurface(base.compiled, ss)),
            (1.0 - modeling::kSharpVolumeRetry) * solid)
      << "the first placement no longer loses the wall";
  EXPECT_GT(m.grid_placements, 1);
  ASSERT_NE(m.grid_shift_cells, 0.0);
  EXPECT_NEAR(m.solid_volume, solid, 1e-15);
  EXPECT_LT(std::abs(modeling::TotalVolume(*m.volume) / solid - 1.0), modeling::kSharpVolumeRetry);
  EXPECT_TRUE(
      m.grid_bounds.isApprox(modeling::SharpGridPlacement(ss, m.grid_shift_cells).bounds, 0.0));
  ASSERT_EQ(m.planes.size(), planes.size());
  for (std::size_t k = 0; k < planes.size(); ++k)
    EXPECT_DOUBLE_EQ(m.planes[k], planes[k] + m.grid_shift_cells * cell) << k;
  ASSERT_NO_THROW(m.mesh.Validate());

  o.previous = &m;
  const SlabFeMesh again = MeshSolidInSlabs(base.compiled, m.grid_bounds, cell, m.planes, o);
  EXPECT_EQ(again.grid_placements, 1);
  EXPECT_EQ(again.grid_shift_cells, 0.0);
  EXPECT_EQ(again.planes, m.planes);
  EXPECT_EQ(again.num_remeshed(), 0);
}

// A sculpt of the platform (its snapped grid surface, as a sculpt made from the solid holds it)
// in slabs spaced by SurfaceSlabSpacing, on planes moved off its triangles (SurfaceSlabPlanes): a
// push/pull stroke that raises a 6 mm bump on the plate near the free end moves vertices in the
// last slab alone; meshed again with the first mesh as the earlier one, only that slab goes
// through TetGen, the others keep their tets bit for bit, and the FE model refactors that slab
// alone and solves exactly.
TEST(SlabFeMesh, SculptStrokeInTheLastSlabRemeshesAndRefactorsOnlyThatSlab) {
  const modeling::TriangleMesh surface = test_support::PlatformGridSurface(kCell);
  const double spacing = SurfaceSlabSpacing(surface);
  EXPECT_GT(spacing, 0.2 * kCell);
  EXPECT_LT(spacing, 2.0 * kCell);
  Eigen::AlignedBox3d box(surface.vertices.rowwise().minCoeff(),
                          surface.vertices.rowwise().maxCoeff());
  box.min().array() -= 2.0 * spacing;
  box.max().array() += 2.0 * spacing;
  const std::vector<double> planes = SurfaceSlabPlanes(surface, box, spacing, kSlabs);
  const SlabFeMesh before = MeshSurfaceInSlabs(surface, box, spacing, planes);
  EXPECT_EQ(before.num_remeshed(), kSlabs);
  ASSERT_NO_THROW(before.mesh.Validate());

  modeling::SculptMesh clay(surface);
  test_support::Stroke(&clay, modeling::SculptTool::kPushPull, Eigen::Vector3d(0.275, 0.0, 0.01),
                       Eigen::Vector3d(0.0, 0.0, 0.006));
  const modeling::TriangleMesh stroked = clay.ToTriangleMesh();

  const SlabFeMesh after = MeshSurfaceInSlabs(stroked, box, spacing, planes, Options(2.0, &before));
  EXPECT_EQ(after.num_remeshed(), 1);
  EXPECT_TRUE(after.remeshed.back());
  for (int k = 0; k + 1 < kSlabs; ++k) {
    ASSERT_EQ(after.slab_tets[k].tets.cols(), before.slab_tets[k].tets.cols());
    EXPECT_TRUE((after.slab_tets[k].nodes.array() == before.slab_tets[k].nodes.array()).all());
  }
  // The bump added volume to the last slab.
  EXPECT_GT(modeling::TotalVolume(after.slab_tets.back()),
            modeling::TotalVolume(before.slab_tets.back()));
  ExpectOnlyTheLastSlabRefactoredAndExact(before, after);
}

// A bar with a step at x = 0 (a face across the axis) and a plane SlabPlanes puts on that face:
// the cut refuses it, SurfaceSlabPlanes moves it off by a tenth to four tenths of the spacing,
// and the bar is then meshed in slabs.
TEST(SlabFeMesh, SurfacePlanesMoveOffAFaceAcrossTheAxis) {
  modeling::ImplicitNode bar(modeling::UnionParams{});
  for (const auto& [x, height] : {std::pair{-0.06, 0.04}, std::pair{0.06, 0.02}}) {
    modeling::ImplicitNode block(modeling::TranslateParams{Eigen::Vector3d(x, 0, 0)});
    block.children.push_back(
        modeling::ImplicitNode(modeling::BoxParams{Eigen::Vector3d(0.12, 0.04, height)}));
    bar.children.push_back(std::move(block));
  }
  modeling::SurfaceMeshSettings ss;
  ss.bounds =
      Eigen::AlignedBox3d(Eigen::Vector3d(-0.13, -0.03, -0.03), Eigen::Vector3d(0.13, 0.03, 0.03));
  ss.cell_size = 0.005;
  const modeling::TriangleMesh surface =
      modeling::MeshSurface(modeling::CompiledSolid::Compile(bar), ss);
  constexpr double kSpacing = 0.01;
  // SlabPlanes on this box puts the one plane of two slabs at x = 0, on the step.
  const Eigen::AlignedBox3d box(Eigen::Vector3d(-0.125, -0.03, -0.03),
                                Eigen::Vector3d(0.125, 0.03, 0.03));
  const std::vector<double> on_face = SlabPlanes(box, kSpacing, 2);
  ASSERT_EQ(on_face.size(), 1u);
  ASSERT_NEAR(on_face[0], 0.0, 1e-12);
  EXPECT_THROW(MeshSurfaceInSlabs(surface, box, kSpacing, on_face), std::invalid_argument);
  const std::vector<double> moved = SurfaceSlabPlanes(surface, box, kSpacing, 2);
  ASSERT_EQ(moved.size(), 1u);
  EXPECT_GE(std::abs(moved[0]), 0.1 * kSpacing - 1e-12);
  EXPECT_LE(std::abs(moved[0]), 0.4 * kSpacing + 1e-12);
  const SlabFeMesh slabs = MeshSurfaceInSlabs(surface, box, kSpacing, moved);
  EXPECT_EQ(slabs.num_remeshed(), 2);
  EXPECT_NEAR(modeling::TotalVolume(*slabs.volume), modeling::MeshVolume(surface),
              1e-2 * modeling::MeshVolume(surface));
}

// The cache directory keeps slab meshes between runs: a mesh made with no earlier mesh in memory
// reads every slab from it, bit for bit; after the edit it reads the three slabs the edit left
// alone and meshes the last; a damaged file is refused with a note naming it and re-meshed.
// The bracket slab (the first, about half of the part's triangles) cut into three strips across
// y: widening the four bolt holes (y = ±65 mm) re-meshes and refactors the two outer strips
// only, the other pieces keep their tets bit for bit, and the solve, whose interface now has
// nodes shared by three pieces (where a strip plane ends on the first slab plane) and is factored
// by CHOLMOD, equals a monolithic solve of the new mesh.
TEST(SlabFeMesh, BoltHoleEditInBracketStripsRemeshesOnlyTheOuterStrips) {
  const double cell = 0.0075;
  const SceneSolidGrid base = PrepareSceneSolid(PlatformScenePath(), "platform", cell);
  const Eigen::AlignedBox3d grid = base.bounds;
  const std::vector<double> planes = SlabPlanes(grid, cell, kSlabs);
  SlabMeshOptions o;
  o.strips = 3;
  o.strip_min_triangles = 0;  // the bracket slab at 7.5 mm is smaller than FE mode strips
  o.snap_cells = modeling::kProductSnapCells;
  const SlabFeMesh before = MeshSolidInSlabs(base.compiled, grid, cell, planes, o);
  ASSERT_EQ(before.strip_axis, 1);
  ASSERT_EQ(before.strip_planes.size(), static_cast<std::size_t>(kSlabs));
  EXPECT_EQ(before.strip_planes[0].size(), 2u);
  for (int k = 1; k < kSlabs; ++k) EXPECT_TRUE(before.strip_planes[k].empty()) << k;
  ASSERT_EQ(before.slab_tets.size(), kSlabs + 2u);
  const SceneSolidGrid edited = PrepareSceneSolid(
      EditedPlatform("bolt_hole", "radius", 0.006, "slab_fe_mesh_bolt"), "platform", cell);
  o.previous = &before;
  const SlabFeMesh after =
      MeshSolidInSlabs(edited.compiled, before.grid_bounds, cell, before.planes, o);
  EXPECT_EQ(after.strip_planes, before.strip_planes);
  for (std::size_t k = 0; k < after.slab_tets.size(); ++k) {
    SCOPED_TRACE("piece " + std::to_string(k));
    const bool outer = k == 0 || k == 2;
    EXPECT_EQ(after.remeshed[k], outer ? 1 : 0);
    if (!outer) {
      ASSERT_EQ(after.slab_tets[k].tets.cols(), before.slab_tets[k].tets.cols());
      EXPECT_TRUE((after.slab_tets[k].nodes.array() == before.slab_tets[k].nodes.array()).all());
    }
  }
  ASSERT_NO_THROW(after.mesh.Validate());

  const fem::MaterialTable steel(fem::Material{2.0e11, 0.3});
  auto conditions = [](const fem::TetMesh& mesh) {
    fem::BoundaryConditions bcs(mesh.num_nodes());
    bcs.FixNodes(MinXFaceNodes(mesh));
    return bcs;
  };
  // The strips share their slab's place in the interface chain: the strip planes join the first
  // slab plane's group, so S stays a chain of three groups, and the edit refactors the first one
  // alone. Without places S is no chain and CHOLMOD factors all of it.
  EXPECT_EQ(after.piece_slab, (std::vector<int>{0, 0, 0, 1, 2, 3}));
  // The labels follow from the planes and strips alone (a mesh read back from a document).
  std::vector<int> place;
  EXPECT_EQ(SlabPieceLabels(after.mesh, after.planes, after.strip_axis, after.strip_planes, &place),
            after.slab);
  EXPECT_EQ(place, after.piece_slab);
  // FE mode's bound leaves this slab whole.
  o.strip_min_triangles = kStripMinTriangles;
  o.previous = nullptr;
  EXPECT_TRUE(MeshSolidInSlabs(edited.compiled, grid, cell, planes, o).strip_planes.empty());
  const fem::BoundaryConditions bcs0 = conditions(before.mesh), bcs1 = conditions(after.mesh);
  const fem::StaticSolver mono(after.mesh, steel, bcs1);
  for (const bool places : {true, false}) {
    SCOPED_TRACE(places ? "strips in their slab's place" : "no places");
    const std::vector<int> p0 = places ? before.piece_slab : std::vector<int>{};
    const std::vector<int> p1 = places ? after.piece_slab : std::vector<int>{};
    const fem::SubstructuredSolver s0(before.mesh, steel, bcs0, before.slab, nullptr, {}, nullptr,
                                      p0);
    const fem::SubstructuredSolver s1(after.mesh, steel, bcs1, after.slab, &s0, {}, nullptr, p1);
    ASSERT_TRUE(s1.factor_status().converged) << s1.factor_status().message;
    EXPECT_EQ(s1.stats().factored_blocks, 2);
    if (places) {
      EXPECT_EQ(s1.stats().interface_groups, 3);
      EXPECT_EQ(s1.stats().factored_interface_groups, 1);
      EXPECT_EQ(s1.stats().reused_trailing_interface_groups, 2);
    } else {
      EXPECT_EQ(s1.stats().interface_groups, 0);  // CHOLMOD
    }
    // A load on the plate's free corner.
    Eigen::MatrixXd rhs = Eigen::MatrixXd::Zero(s1.num_free(), 1);
    for (int v = 0; v < after.mesh.num_nodes(); ++v)
      if (after.mesh.nodes(v, 0) > 0.28 && after.mesh.nodes(v, 2) > 0.0099)
        rhs(s1.FreeIndex(3 * v + 2), 0) = -1.0;
    Eigen::MatrixXd x_sub, x_mono;
    ASSERT_TRUE(s1.SolveFree(rhs, &x_sub).converged);
    ASSERT_TRUE(mono.SolveFree(rhs, &x_mono).converged);
    EXPECT_LT((x_sub - x_mono).norm(), 1e-9 * x_mono.norm());
  }
}

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
