// Tests of FE set-up from document objects (scene/fe_setup.cc): which objects can become an FE
// model, meshing a solid (TetGen, CGAL), a sculpt or a closed surface, the one-step set-up and
// refresh commands, and the cost estimate. Volumes are checked against closed forms (the sphere)
// or the divergence-theorem volume of the surface that was tetrahedralized.
// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#include "scene/fe_setup.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <memory>
#include <string>
#include <tuple>
#include <utility>
#include <variant>
#include <vector>

#include "doc/assets.h"
#include "doc/command.h"
#include "doc/document.h"
#include "scene/fe_model.h"
#include "sculpt_stroke_support.h"
#include "spidarcad/modeling/implicit_evaluator.h"
#include "spidarcad/modeling/sculpt.h"
#include "spidarcad/modeling/surface_mesher.h"

namespace spidarcad::app {
namespace {

constexpr double kPi = 3.14159265358979323846;

modeling::ImplicitNode Sphere(double r) {
  return modeling::ImplicitNode(modeling::SphereParams{r}, {}, "ball");
}

// Total volume of a tet mesh, m³ (each tet |det| / 6).
double TetVolume(const modeling::TetMesh& mesh) {
  double v = 0.0;
  for (Eigen::Index t = 0; t < mesh.tets.cols(); ++t) {
    const Eigen::Vector3d a = mesh.nodes.col(mesh.tets(0, t));
    Eigen::Matrix3d m;
    for (int k = 0; k < 3; ++k) m.col(k) = mesh.nodes.col(mesh.tets(k + 1, t)) - a;
    v += std::abs(m.determinant()) / 6.0;
  }
  return v;
}

// A document holding the solid "ball" (a sphere of radius r at the origin).
struct BallDoc {
  Document doc;
  ObjectId ball = 0;
  explicit BallDoc(double r = 0.05) {
    doc.Execute(edit::AddSolid("ball", Sphere(r)));
    ball = doc.last_created().front();
    doc.history().Clear();
  }
};

MeshSettings Cell(double h, std::string mesher = "tetgen") {
  MeshSettings s;
  s.cell_size = h;
  s.mesher = std::move(mesher);
  return s;
}

// A closed surface of a sphere (the grid mesher), for sculpt and surface-mesh sources.
modeling::TriangleMesh SphereSurface(double r, double h) {
  const modeling::CompiledSolid solid = modeling::CompiledSolid::Compile(Sphere(r));
  modeling::SurfaceMeshSettings s;
  s.bounds = Eigen::AlignedBox3d(Eigen::Vector3d::Constant(-r - 2 * h),
                                 Eigen::Vector3d::Constant(r + 2 * h));
  s.cell_size = h;
  return modeling::MeshSurface(solid, s);
}

TEST(FeSetUp, SolidBecomesMeshAndFeModelInOneUndoStep) {
  constexpr double kR = 0.05;
  BallDoc f(kR);
  const std::string before = f.doc.ToJson(true).dump();
  const FeMeshInput input = PrepareFeMesh(f.doc, f.ball, Cell(0.005));
  EXPECT_EQ(input.kind, FeSourceKind::kSolid);
  const FeMeshResult mesh = MeshFeSource(input);
  ASSERT_TRUE(mesh.volume);
  // The sphere's volume (closed form) within 3 % at 20 cells across.
  const double exact = 4.0 / 3.0 * kPi * kR * kR * kR;
  EXPECT_NEAR(TetVolume(*mesh.volume), exact, 0.03 * exact);
  f.doc.Execute(SetUpFe(input, mesh));
  ASSERT_EQ(f.doc.objects().size(), 3u);
  ASSERT_EQ(f.doc.last_created().size(), 2u);
  const ObjectId mesh_id = f.doc.last_created()[0], fe_id = f.doc.last_created()[1];
  const auto& md = std::get<MeshData>(f.doc.Get(mesh_id).data);
  EXPECT_EQ(f.doc.Get(mesh_id).name, "ball tets");
  EXPECT_EQ(md.source, f.ball);
  EXPECT_EQ(md.source_revision, f.doc.Get(f.ball).revision);
  EXPECT_EQ(md.settings.cell_size, 0.005);
  EXPECT_EQ(md.settings.mesher, "tetgen");
  EXPECT_EQ(md.volume, mesh.volume);
  EXPECT_FALSE(f.doc.IsMeshOutOfDate(mesh_id));
  const auto& fe = std::get<FeModelData>(f.doc.Get(fe_id).data);
  EXPECT_EQ(f.doc.Get(fe_id).name, "ball FE");
  EXPECT_EQ(fe.tet_mesh, mesh_id);
  EXPECT_EQ(fe.material.youngs_modulus, 200e9);
  EXPECT_EQ(fe.material.poisson_ratio, 0.3);
  EXPECT_TRUE(fe.fixed_boxes.empty()) << "the minimum-x face clamp";
  EXPECT_EQ(fe.element_order, 1);
  EXPECT_EQ(FeModelFor(f.doc, f.ball), fe_id);
  EXPECT_EQ(FeModelFor(f.doc, mesh_id), fe_id);
  ASSERT_EQ(f.doc.history().undo_size(), 1u);
  EXPECT_EQ(f.doc.history().UndoDescription(), "Set up FE for ball");
  const std::string after = f.doc.ToJson(true).dump();
  ASSERT_TRUE(f.doc.Undo());
  EXPECT_EQ(f.doc.ToJson(true).dump(), before);
  ASSERT_TRUE(f.doc.Redo());
  EXPECT_EQ(f.doc.ToJson(true).dump(), after) << "redo brings back the same ids and content";
}

// In slabs: the joined slab mesh is the result's volume; meshed again with the first as the
// previous mesh, every slab comes back as it was. A solid that a plane misses (two blocks with a
// gap) is meshed in one piece, and the result says why.
TEST(FeSetUp, SolidInSlabsReusesUnchangedSlabsAndFallsBackToOnePieceWhereAPlaneMisses) {
  constexpr double kR = 0.05;
  BallDoc f(kR);
  FeMeshInput input = PrepareFeMesh(f.doc, f.ball, Cell(0.008));
  input.slabs = kFeSlabs;
  const FeMeshResult first = MeshFeSource(input);
  ASSERT_NE(first.slabs, nullptr) << first.slab_note;
  EXPECT_TRUE(first.slab_note.empty());
  EXPECT_EQ(first.volume, first.slabs->volume);
  EXPECT_EQ(first.slabs->slab_tets.size(), static_cast<std::size_t>(kFeSlabs));
  EXPECT_EQ(first.slabs->num_remeshed(), kFeSlabs);
  EXPECT_TRUE(IsClosedSurface(*first.surface));
  const double exact = 4.0 / 3.0 * kPi * kR * kR * kR;
  EXPECT_NEAR(TetVolume(*first.volume), exact, 0.03 * exact);
  input.previous_slabs = first.slabs;
  const FeMeshResult again = MeshFeSource(input);
  ASSERT_NE(again.slabs, nullptr);
  EXPECT_EQ(again.slabs->num_remeshed(), 0);
  EXPECT_TRUE((again.volume->tets.array() == first.volume->tets.array()).all());

  Document gap;
  modeling::ImplicitNode blocks(modeling::UnionParams{});
  for (double x : {0.0, 0.2}) {
    modeling::ImplicitNode block(modeling::TranslateParams{Eigen::Vector3d(x, 0, 0)});
    block.children.push_back(
        modeling::ImplicitNode(modeling::BoxParams{Eigen::Vector3d(0.02, 0.05, 0.05)}));
    blocks.children.push_back(std::move(block));
  }
  gap.Execute(edit::AddSolid("blocks", std::move(blocks)));
  FeMeshInput two = PrepareFeMesh(gap, gap.last_created().front(), Cell(0.01));
  two.slabs = kFeSlabs;
  const FeMeshResult one_piece = MeshFeSource(two);
  EXPECT_EQ(one_piece.slabs, nullptr);
  ASSERT_TRUE(one_piece.volume);
  EXPECT_GT(one_piece.volume->tets.cols(), 0);
  EXPECT_NE(one_piece.slab_note.find("meshed in one piece: in 4 slabs it failed"),
            std::string::npos)
      << one_piece.slab_note;
  EXPECT_NE(one_piece.slab_note.find("cross-section"), std::string::npos) << one_piece.slab_note;
}

// The window's "lattice" (settings.surface_mesher): the surface by the lattice route, as
// `spidarcad mesh` makes it, then TetGen, in one piece or cut into slabs on planes a quarter
// cell past the grid planes (a slab the edit did not reach kept); sharpened with corners
// inserted. Refused for CGAL, for a surface source and under an unknown name.
TEST(FeSetUp, LatticeSurfaceIsTheLatticeRoutesInOnePieceOrInSlabs) {
  constexpr double kR = 0.05;
  BallDoc f(kR);
  MeshSettings settings = Cell(0.008);
  const FeMeshResult grid = MeshFeSource(PrepareFeMesh(f.doc, f.ball, settings));
  settings.surface_mesher = "lattice";
  FeMeshInput input = PrepareFeMesh(f.doc, f.ball, settings);
  const FeMeshResult mesh = MeshFeSource(input);
  ASSERT_TRUE(mesh.volume && mesh.surface && grid.surface);
  EXPECT_EQ(mesh.slabs, nullptr);
  EXPECT_TRUE(IsClosedSurface(*mesh.surface));
  const double exact = 4.0 / 3.0 * kPi * kR * kR * kR;
  EXPECT_NEAR(TetVolume(*mesh.volume), exact, 0.03 * exact);
  // The lattice route's surface on the FE box, bit for bit; the grid surface is another one.
  double cell = 0.008;
  modeling::CompiledSolid compiled;
  modeling::SurfaceMeshSettings direct;
  direct.bounds = FeSolidBounds(Sphere(kR), "ball", &cell, &compiled);
  direct.cell_size = cell;
  direct.mesher = modeling::SurfaceMesher::kLattice;
  const modeling::TriangleMesh expected = modeling::MeshSurface(compiled, direct);
  EXPECT_EQ(mesh.surface->vertices, expected.vertices);
  EXPECT_EQ(mesh.surface->triangles, expected.triangles);
  EXPECT_NE(grid.surface->triangles.cols(), expected.triangles.cols());
  std::printf("sphere at 8 mm: lattice %ld triangles, min angle %.2f deg; grid %ld, %.2f deg\n",
              static_cast<long>(mesh.surface->triangles.cols()),
              modeling::MeasureTriangleAngles(*mesh.surface).min_angle_deg,
              static_cast<long>(grid.surface->triangles.cols()),
              modeling::MeasureTriangleAngles(*grid.surface).min_angle_deg);
  // In slabs: the lattice surface of the slab grid cut on planes a quarter cell past its grid
  // planes (which hold no lattice vertex or edge); meshed again from the first, every slab is
  // kept.
  input.slabs = kFeSlabs;
  const FeMeshResult slabs = MeshFeSource(input);
  ASSERT_NE(slabs.slabs, nullptr) << slabs.slab_note;
  EXPECT_EQ(slabs.slabs->slab_tets.size(), static_cast<std::size_t>(kFeSlabs));
  const Eigen::AlignedBox3d& grid_box = slabs.slabs->grid_bounds;
  const double h = slabs.slabs->cell;
  const double origin =
      grid_box.center().x() - 0.5 * h * std::ceil(grid_box.sizes().x() / h - 1e-9);
  for (double x : slabs.slabs->planes) {
    const double cells = (x - origin) / h;
    EXPECT_NEAR(cells - std::floor(cells), 0.25, 1e-9) << x;
  }
  EXPECT_NEAR(TetVolume(*slabs.volume), exact, 0.03 * exact);
  input.previous_slabs = slabs.slabs;
  const FeMeshResult again = MeshFeSource(input);
  ASSERT_NE(again.slabs, nullptr);
  EXPECT_EQ(again.slabs->num_remeshed(), 0);
  EXPECT_TRUE((again.volume->tets.array() == slabs.volume->tets.array()).all());
  f.doc.Execute(SetUpFe(input, slabs));
  const auto& md = std::get<MeshData>(f.doc.Get(f.doc.last_created()[0]).data);
  EXPECT_EQ(md.settings.surface_mesher, "lattice");
  EXPECT_EQ(md.settings.slab_planes, slabs.slabs->planes);

  // A box off the grid, sharpened on the lattice: a vertex on each corner.
  Document boxes;
  modeling::ImplicitNode box(modeling::TranslateParams{Eigen::Vector3d(0.0013, -0.0021, 0.0007)});
  box.children.push_back(
      modeling::ImplicitNode(modeling::BoxParams{Eigen::Vector3d(0.1, 0.08, 0.06)}));
  boxes.Execute(edit::AddSolid("block", std::move(box)));
  MeshSettings sharp = Cell(0.006);
  sharp.surface_mesher = "lattice";
  sharp.sharp_edges = true;
  FeMeshInput block = PrepareFeMesh(boxes, boxes.last_created().front(), sharp);
  block.volume = false;
  const FeMeshResult sharpened = MeshFeSource(block);
  ASSERT_TRUE(sharpened.surface);
  double worst = 0.0;
  for (int k = 0; k < 8; ++k) {
    const Eigen::Vector3d corner =
        Eigen::Vector3d(0.0013, -0.0021, 0.0007) +
        Eigen::Vector3d(k & 1 ? 0.05 : -0.05, k & 2 ? 0.04 : -0.04, k & 4 ? 0.03 : -0.03);
    double nearest = 1.0;
    for (Eigen::Index v = 0; v < sharpened.surface->vertices.cols(); ++v)
      nearest = std::min(nearest, (sharpened.surface->vertices.col(v) - corner).norm());
    worst = std::max(worst, nearest);
  }
  EXPECT_LT(worst, 1e-9);

  for (const auto& [mesher, surface_mesher, needle] :
       std::vector<std::tuple<std::string, std::string, std::string>>{
           {"cgal", "lattice", "CGAL does not use a surface"},
           {"tetgen", "dual", "surface mesher 'dual'"}}) {
    MeshSettings bad = Cell(0.008, mesher);
    bad.surface_mesher = surface_mesher;
    try {
      PrepareFeMesh(f.doc, f.ball, bad);
      ADD_FAILURE() << surface_mesher << " with " << mesher << " accepted";
    } catch (const DocumentError& e) {
      EXPECT_NE(std::string(e.what()).find(needle), std::string::npos) << e.what();
    }
  }
  f.doc.Execute(edit::AddSculpt("shell", SphereSurface(0.04, 0.01)));
  MeshSettings on_surface = Cell(0.008);
  on_surface.surface_mesher = "lattice";
  try {
    PrepareFeMesh(f.doc, f.doc.last_created().front(), on_surface);
    ADD_FAILURE() << "the lattice accepted for a sculpt";
  } catch (const DocumentError& e) {
    EXPECT_NE(std::string(e.what()).find("this source is a surface already"), std::string::npos)
        << e.what();
  }
}

// MeshSettings::flat_cells (FE mode's quadratic elements): the marching-tetrahedra surface with
// its flat fans coarsened, as MeshSurface makes it with flat_coarsen_cells, in one piece or in
// slabs; fewer triangles and tets on a box off the grid, the same volume. FlatCellsForOrder picks
// it for quadratic elements on a solid's plain TetGen surface only; PrepareFeMesh refuses it
// elsewhere and out of range.
TEST(FeSetUp, FlatCellsCoarsenASolidsFlatFacesForQuadraticElements) {
  Document doc;
  modeling::ImplicitNode box(modeling::TranslateParams{Eigen::Vector3d(0.0013, -0.0021, 0.0007)});
  box.children.push_back(
      modeling::ImplicitNode(modeling::BoxParams{Eigen::Vector3d(0.1, 0.08, 0.06)}));
  doc.Execute(edit::AddSolid("block", box));
  const ObjectId block = doc.last_created().front();
  const MeshSettings plain = Cell(0.007);
  EXPECT_EQ(FlatCellsForOrder(FeSourceKind::kSolid, plain, 2), kQuadraticFlatCells);
  EXPECT_EQ(FlatCellsForOrder(FeSourceKind::kSolid, plain, 1), 0.0);
  EXPECT_EQ(FlatCellsForOrder(FeSourceKind::kSculpt, plain, 2), 0.0);
  EXPECT_EQ(FlatCellsForOrder(FeSourceKind::kSurfaceMesh, plain, 2), 0.0);
  for (const auto& [mesher, sharp, surface_mesher] :
       std::vector<std::tuple<std::string, bool, std::string>>{
           {"cgal", false, ""}, {"tetgen", true, ""}, {"tetgen", false, "lattice"}}) {
    MeshSettings other = Cell(0.007, mesher);
    other.sharp_edges = sharp;
    other.surface_mesher = surface_mesher;
    EXPECT_EQ(FlatCellsForOrder(FeSourceKind::kSolid, other, 2), 0.0) << mesher << surface_mesher;
  }

  MeshSettings flat = plain;
  flat.flat_cells = kQuadraticFlatCells;
  const FeMeshResult fine = MeshFeSource(PrepareFeMesh(doc, block, plain));
  FeMeshInput input = PrepareFeMesh(doc, block, flat);
  const FeMeshResult coarse = MeshFeSource(input);
  ASSERT_TRUE(fine.volume && coarse.volume && coarse.surface);
  EXPECT_EQ(coarse.settings.flat_cells, kQuadraticFlatCells);
  // The surface MeshSurface makes with the coarsening, on the FE box, snapped as FE mode snaps.
  double cell = 0.007;
  modeling::CompiledSolid compiled;
  modeling::SurfaceMeshSettings direct;
  direct.bounds = FeSolidBounds(box, "block", &cell, &compiled);
  direct.cell_size = cell;
  direct.snap_cells = modeling::kProductSnapCells;
  direct.flat_coarsen_cells = kQuadraticFlatCells;
  const modeling::TriangleMesh expected = modeling::MeshSurface(compiled, direct);
  EXPECT_EQ(coarse.surface->vertices, expected.vertices);
  EXPECT_EQ(coarse.surface->triangles, expected.triangles);
  EXPECT_LT(coarse.surface->triangles.cols(), 0.8 * fine.surface->triangles.cols());
  EXPECT_LT(coarse.volume->tets.cols(), fine.volume->tets.cols());
  const double v_fine = TetVolume(*fine.volume);
  EXPECT_NEAR(TetVolume(*coarse.volume), v_fine, 1e-6 * v_fine);
  std::printf("block at 7 mm: %ld -> %ld triangles, %ld -> %ld tets with flat faces coarsened\n",
              static_cast<long>(fine.surface->triangles.cols()),
              static_cast<long>(coarse.surface->triangles.cols()),
              static_cast<long>(fine.volume->tets.cols()),
              static_cast<long>(coarse.volume->tets.cols()));

  // In slabs: the same coarsening; meshed again from the first, every slab is kept.
  input.slabs = kFeSlabs;
  const FeMeshResult slabs = MeshFeSource(input);
  ASSERT_NE(slabs.slabs, nullptr) << slabs.slab_note;
  EXPECT_NEAR(TetVolume(*slabs.volume), v_fine, 1e-6 * v_fine);
  FeMeshInput fine_slabs = PrepareFeMesh(doc, block, plain);
  fine_slabs.slabs = kFeSlabs;
  EXPECT_LT(slabs.volume->tets.cols(), MeshFeSource(fine_slabs).volume->tets.cols());
  input.previous_slabs = slabs.slabs;
  EXPECT_EQ(MeshFeSource(input).slabs->num_remeshed(), 0);
  // Set up with quadratic elements: the FE model has them, the mesh keeps the setting.
  input.element_order = 2;
  doc.Execute(SetUpFe(input, slabs));
  const auto& md = std::get<MeshData>(doc.Get(doc.last_created()[0]).data);
  EXPECT_EQ(md.settings.flat_cells, kQuadraticFlatCells);
  EXPECT_EQ(std::get<FeModelData>(doc.Get(doc.last_created()[1]).data).element_order, 2);
  const FeMeshInput again = PrepareFeRemesh(doc, doc.last_created()[0]);
  EXPECT_EQ(again.settings.flat_cells, kQuadraticFlatCells);

  // Refused: out of [0, 1], with the lattice or CGAL, for a surface source.
  doc.Execute(edit::AddSculpt("clay", SphereSurface(0.04, 0.01)));
  const ObjectId clay = doc.last_created().front();
  struct Bad {
    ObjectId source;
    double flat;
    std::string mesher, surface_mesher, needle;
  };
  for (const Bad& c : std::vector<Bad>{{block, 1.5, "tetgen", "", "expected [0, 1]"},
                                       {block, -0.1, "tetgen", "", "expected [0, 1]"},
                                       {block, 0.5, "tetgen", "lattice", "the lattice"},
                                       {block, 0.5, "cgal", "", "CGAL"},
                                       {clay, 0.5, "", "", "for a surface"}}) {
    MeshSettings bad = Cell(0.007, c.mesher);
    bad.surface_mesher = c.surface_mesher;
    bad.flat_cells = c.flat;
    try {
      PrepareFeMesh(doc, c.source, bad);
      ADD_FAILURE() << "flat cells " << c.flat << " accepted with " << c.mesher << " "
                    << c.surface_mesher;
    } catch (const DocumentError& e) {
      EXPECT_NE(std::string(e.what()).find(c.needle), std::string::npos) << e.what();
    }
  }
}

TEST(FeSetUp, CgalMeshesTheSolidFromItsFunction) {
  constexpr double kR = 0.05;
  BallDoc f(kR);
  const FeMeshInput input = PrepareFeMesh(f.doc, f.ball, Cell(0.01, "cgal"));
  const FeMeshResult mesh = MeshFeSource(input);
  ASSERT_TRUE(mesh.volume && mesh.surface);
  const double exact = 4.0 / 3.0 * kPi * kR * kR * kR;
  EXPECT_NEAR(TetVolume(*mesh.volume), exact, 0.05 * exact);
  EXPECT_TRUE(IsClosedSurface(*mesh.surface));
  f.doc.Execute(SetUpFe(input, mesh));
  const auto& md = std::get<MeshData>(f.doc.Get(f.doc.last_created()[0]).data);
  EXPECT_EQ(md.settings.mesher, "cgal");
}

TEST(FeSetUp, AutomaticCellIsTheSolidsSizeOverCellsAcross) {
  BallDoc f(0.05);
  const FeMeshResult mesh = MeshFeSource(PrepareFeMesh(f.doc, f.ball, Cell(0.0)));
  // The largest side of the box found by the 1 cm coarse search: the diameter, 0.1 m, plus at
  // most about one search cell per side.
  EXPECT_GE(mesh.settings.cell_size, 0.1 / kFeCellsAcross);
  EXPECT_LE(mesh.settings.cell_size, (0.1 + 2 * 0.01) / kFeCellsAcross);
}

TEST(FeSetUp, ResultIsRefusedWhenTheSourceChangedWhileMeshing) {
  BallDoc f;
  const FeMeshInput input = PrepareFeMesh(f.doc, f.ball, Cell(0.01));
  const FeMeshResult mesh = MeshFeSource(input);
  f.doc.Execute(edit::SetNodeField(f.ball, {}, "radius", 0.06));
  const std::string before = f.doc.ToJson(true).dump();
  const std::size_t steps = f.doc.history().undo_size();
  try {
    f.doc.Execute(SetUpFe(input, mesh));
    FAIL() << "a mesh of the old shape was added";
  } catch (const DocumentError& e) {
    EXPECT_NE(std::string(e.what()).find("'ball' changed while it was meshed"), std::string::npos)
        << e.what();
  }
  EXPECT_EQ(f.doc.ToJson(true).dump(), before);
  EXPECT_EQ(f.doc.history().undo_size(), steps);
}

TEST(FeSetUp, RefreshRemeshesWithTheStoredSettingsAndKeepsTheFeSettings) {
  BallDoc f(0.05);
  const FeMeshInput input = PrepareFeMesh(f.doc, f.ball, Cell(0.01));
  f.doc.Execute(SetUpFe(input, MeshFeSource(input)));
  const ObjectId mesh_id = f.doc.last_created()[0], fe_id = f.doc.last_created()[1];
  const auto old_volume = std::get<MeshData>(f.doc.Get(mesh_id).data).volume;
  f.doc.Execute(edit::SetFeMaterial(fe_id, kMaterialPresets[1].material));
  f.doc.Execute(edit::SetPrecomputeKey(fe_id, 42));
  f.doc.Execute(edit::SetNodeField(f.ball, {}, "radius", 0.06));
  ASSERT_TRUE(f.doc.IsMeshOutOfDate(mesh_id));
  const FeMeshInput again = PrepareFeRemesh(f.doc, mesh_id);
  EXPECT_EQ(again.source, f.ball);
  EXPECT_EQ(again.settings.cell_size, 0.01);
  EXPECT_EQ(again.settings.mesher, "tetgen");
  const std::size_t steps = f.doc.history().undo_size();
  f.doc.Execute(RefreshFeMesh(mesh_id, again, MeshFeSource(again)));
  EXPECT_EQ(f.doc.history().undo_size(), steps + 1);
  EXPECT_EQ(f.doc.history().UndoDescription(), "Refresh ball mesh");
  EXPECT_FALSE(f.doc.IsMeshOutOfDate(mesh_id));
  const auto& md = std::get<MeshData>(f.doc.Get(mesh_id).data);
  const double exact = 4.0 / 3.0 * kPi * 0.06 * 0.06 * 0.06;
  EXPECT_NEAR(TetVolume(*md.volume), exact, 0.05 * exact);
  const auto& fe = std::get<FeModelData>(f.doc.Get(fe_id).data);
  EXPECT_EQ(fe.material.youngs_modulus, kMaterialPresets[1].material.youngs_modulus);
  EXPECT_EQ(fe.tet_mesh, mesh_id);
  EXPECT_EQ(fe.precompute_key, 0u) << "the columns were of the old mesh";
  ASSERT_TRUE(f.doc.Undo());
  EXPECT_TRUE(f.doc.IsMeshOutOfDate(mesh_id));
  EXPECT_EQ(std::get<MeshData>(f.doc.Get(mesh_id).data).volume, old_volume);
  EXPECT_EQ(std::get<FeModelData>(f.doc.Get(fe_id).data).precompute_key, 42u);
}

TEST(FeSetUp, SculptAndClosedSurfaceMeshAreTetrahedralizedAsTheyAre) {
  Document doc;
  const modeling::TriangleMesh surface = SphereSurface(0.04, 0.008);
  ASSERT_TRUE(IsClosedSurface(surface));
  doc.Execute(edit::AddSculpt("clay", surface));
  const ObjectId clay = doc.last_created().front();
  doc.Execute(
      edit::AddMesh("shell", 0, 0, std::make_shared<modeling::TriangleMesh>(surface), nullptr));
  const ObjectId shell = doc.last_created().front();
  EXPECT_EQ(ClassifyFeSource(doc, clay), FeSourceKind::kSculpt);
  EXPECT_EQ(ClassifyFeSource(doc, shell), FeSourceKind::kSurfaceMesh);
  for (ObjectId id : {clay, shell}) {
    const FeMeshInput input = PrepareFeMesh(doc, id, MeshSettings{});
    const FeMeshResult mesh = MeshFeSource(input);
    ASSERT_TRUE(mesh.volume);
    // The tets fill the surface they were made from (its divergence-theorem volume).
    EXPECT_NEAR(TetVolume(*mesh.volume), modeling::MeshVolume(surface),
                1e-6 * modeling::MeshVolume(surface));
    doc.Execute(SetUpFe(input, mesh));
    EXPECT_EQ(FeModelFor(doc, id), doc.last_created()[1]);
  }
  // CGAL and sharp edges need a solid's function.
  MeshSettings cgal;
  cgal.mesher = "cgal";
  EXPECT_THROW(PrepareFeMesh(doc, clay, cgal), DocumentError);
}

// `surface` after one stroke (test_support::Stroke).
modeling::TriangleMesh Stroked(const modeling::TriangleMesh& surface, modeling::SculptTool tool,
                               const Eigen::Vector3d& at, const Eigen::Vector3d& move) {
  modeling::SculptMesh clay(surface);
  test_support::Stroke(&clay, tool, at, move);
  return clay.ToTriangleMesh();
}

// In slabs, a sculpt is cut on planes spaced by SurfaceSlabSpacing. A stroke at one end re-meshes
// that end's slab alone, on the same planes; a stroke that takes the surface out of the first
// mesh's box starts again on planes of the new box.
TEST(FeSetUp, SculptInSlabsRemeshesOnlyTheSlabAStrokeReached) {
  const modeling::CompiledSolid bar = modeling::CompiledSolid::Compile(
      modeling::ImplicitNode(modeling::BoxParams{Eigen::Vector3d(0.24, 0.04, 0.04)}));
  modeling::SurfaceMeshSettings ss;
  ss.bounds =
      Eigen::AlignedBox3d(Eigen::Vector3d(-0.14, -0.04, -0.04), Eigen::Vector3d(0.14, 0.04, 0.04));
  ss.cell_size = 0.008;
  ss.snap_cells = modeling::kProductSnapCells;
  const modeling::TriangleMesh surface = modeling::MeshSurface(bar, ss);
  Document doc;
  doc.Execute(edit::AddSculpt("bar", surface));
  FeMeshInput input = PrepareFeMesh(doc, doc.last_created().front(), MeshSettings{});
  ASSERT_EQ(input.kind, FeSourceKind::kSculpt);
  input.slabs = kFeSlabs;
  const FeMeshResult first = MeshFeSource(input);
  ASSERT_NE(first.slabs, nullptr) << first.slab_note;
  EXPECT_EQ(first.volume, first.slabs->volume);
  EXPECT_EQ(first.settings.slab_planes.size(), kFeSlabs - 1u);
  EXPECT_EQ(first.slabs->num_remeshed(), kFeSlabs);
  EXPECT_TRUE(IsClosedSurface(*first.surface));
  const double volume = modeling::MeshVolume(surface);
  EXPECT_NEAR(TetVolume(*first.volume), volume, 1e-2 * volume);

  // A bump raised on the top near the +x end (the last slab: planes near x = -0.06, 0, 0.06).
  input.surface = std::make_shared<const modeling::TriangleMesh>(
      Stroked(surface, modeling::SculptTool::kPushPull, Eigen::Vector3d(0.1, 0.0, 0.02),
              Eigen::Vector3d(0.0, 0.0, 0.004)));
  input.previous_slabs = first.slabs;
  const FeMeshResult second = MeshFeSource(input);
  ASSERT_NE(second.slabs, nullptr) << second.slab_note;
  EXPECT_EQ(second.settings.slab_planes, first.settings.slab_planes);
  EXPECT_EQ(second.slabs->num_remeshed(), 1);
  EXPECT_TRUE(second.slabs->remeshed.back());
  EXPECT_GT(TetVolume(*second.volume), TetVolume(*first.volume));

  // The +x end pulled out by 3 cm, past the first mesh's box: new planes, every slab meshed.
  input.surface = std::make_shared<const modeling::TriangleMesh>(
      Stroked(surface, modeling::SculptTool::kGrab, Eigen::Vector3d(0.12, 0.0, 0.0),
              Eigen::Vector3d(0.03, 0.0, 0.0)));
  ASSERT_GT(input.surface->vertices.row(0).maxCoeff(), first.slabs->grid_bounds.max().x());
  const FeMeshResult third = MeshFeSource(input);
  ASSERT_NE(third.slabs, nullptr) << third.slab_note;
  EXPECT_NE(third.settings.slab_planes, first.settings.slab_planes);
  EXPECT_EQ(third.slabs->num_remeshed(), kFeSlabs);
}

TEST(FeSetUp, OpenSurfacesAndOtherKindsAreRefusedNamingTheObject) {
  Document doc;
  modeling::TriangleMesh open = SphereSurface(0.04, 0.01);
  open.triangles.conservativeResize(3, open.triangles.cols() - 1);
  EXPECT_FALSE(IsClosedSurface(open));
  doc.Execute(edit::AddSculpt("torn", open));
  const ObjectId torn = doc.last_created().front();
  EXPECT_EQ(ClassifyFeSource(doc, torn), FeSourceKind::kNone);
  try {
    PrepareFeMesh(doc, torn, MeshSettings{});
    FAIL();
  } catch (const DocumentError& e) {
    EXPECT_NE(std::string(e.what()).find("sculpt 'torn'"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("not a closed surface"), std::string::npos) << e.what();
  }
  doc.Execute(edit::AddRigidPart("base", Sphere(0.01), Eigen::Isometry3d::Identity()));
  EXPECT_EQ(ClassifyFeSource(doc, doc.last_created().front()), FeSourceKind::kNone);
  EXPECT_EQ(ClassifyFeSource(doc, 999), FeSourceKind::kNone);
  EXPECT_THROW(PrepareFeMesh(doc, 999, MeshSettings{}), DocumentError);
}

TEST(FeSetUp, IsClosedSurfaceNeedsEveryEdgeTwiceInOppositeDirections) {
  modeling::TriangleMesh tet;  // a tetrahedron's four faces, outward
  tet.vertices.resize(3, 4);
  tet.vertices << 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1;
  tet.triangles.resize(3, 4);
  tet.triangles << 0, 0, 0, 1, 2, 1, 3, 2, 1, 3, 2, 3;
  EXPECT_TRUE(IsClosedSurface(tet));
  modeling::TriangleMesh flipped = tet;
  std::swap(flipped.triangles(1, 0), flipped.triangles(2, 0));
  EXPECT_FALSE(IsClosedSurface(flipped));
  modeling::TriangleMesh missing = tet;
  missing.triangles.conservativeResize(3, 3);
  EXPECT_FALSE(IsClosedSurface(missing));
  EXPECT_FALSE(IsClosedSurface(modeling::TriangleMesh{}));
}

TEST(FeSetUp, VolumeMeshGetsAnFeModelWithoutMeshing) {
  Document doc;
  modeling::TetMesh tets;
  tets.nodes.resize(3, 4);
  tets.nodes << 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1;
  tets.tets.resize(4, 1);
  tets.tets << 0, 1, 2, 3;
  tets.regions = Eigen::VectorXi::Zero(1);
  doc.Execute(edit::AddMesh("block", 0, 0, nullptr, std::make_shared<modeling::TetMesh>(tets)));
  const ObjectId block = doc.last_created().front();
  EXPECT_EQ(ClassifyFeSource(doc, block), FeSourceKind::kVolumeMesh);
  EXPECT_EQ(FeModelFor(doc, block), 0u);
  doc.Execute(SetUpFeOnMesh(doc, block));
  EXPECT_EQ(doc.history().UndoDescription(), "Set up FE for block");
  const ObjectId fe = doc.last_created().front();
  EXPECT_EQ(std::get<FeModelData>(doc.Get(fe).data).tet_mesh, block);
  EXPECT_EQ(FeModelFor(doc, block), fe);
  EXPECT_EQ(ClassifyFeSource(doc, fe), FeSourceKind::kFeModel);
}

TEST(FeSetUp, FindsTheFeModelOfTheShippedWorkbench) {
  Document doc;
  doc.Load(AssetPath("scenes/workbench.json"));
  const ObjectId platform = doc.FindByName("platform")->id;
  const ObjectId tets = doc.FindByName("platform tets")->id;
  const ObjectId fe = doc.FindByName("platform FE")->id;
  EXPECT_EQ(FeModelFor(doc, platform), fe);
  EXPECT_EQ(FeModelFor(doc, tets), fe);
  EXPECT_EQ(FeModelFor(doc, fe), fe);
  EXPECT_EQ(FeModelFor(doc, doc.FindByName("clay")->id), 0u);
  EXPECT_EQ(ClassifyFeSource(doc, doc.FindByName("base")->id), FeSourceKind::kNone);
}

TEST(FeSetUp, EstimateFlagsAMeshPastTheCliBudget) {
  BallDoc f(0.05);
  // 1e-4 m cells over a ~0.1 m box: about (0.1 / 1e-4)^3 = 1e9 grid cells, past 2^27.
  const auto fine = EstimateFeMesh(PrepareFeMesh(f.doc, f.ball, Cell(1e-4)));
  ASSERT_TRUE(fine.has_value());
  EXPECT_GT(fine->grid_cells, 0.9e9);
  EXPECT_NE(FeMeshOverBudget(*fine).find("grid cells"), std::string::npos);
  const auto coarse = EstimateFeMesh(PrepareFeMesh(f.doc, f.ball, Cell(0.005)));
  ASSERT_TRUE(coarse.has_value());
  EXPECT_EQ(FeMeshOverBudget(*coarse), "");
  EXPECT_FALSE(EstimateFeMesh(PrepareFeMesh(f.doc, f.ball, Cell(0.005, "cgal"))).has_value());
}

}  // namespace
}  // namespace spidarcad::app
