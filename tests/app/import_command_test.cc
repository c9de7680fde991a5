// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
// Tests of `spidarcad import`, run as a separate process: a surface and a tetrahedral mesh land
// in a document as mesh objects (read back with the Document), `fem` solves the imported tets,
// and a bad file exits 2 naming file and line with the document untouched.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <string>
#include <variant>

#include "doc/document.h"
#include "spidarcad/fem/mesh.h"
#include "spidarcad/modeling/tet_mesh.h"
#include "spidarcad/modeling/triangle_mesh_io.h"
#include "spidarcad_runner.h"

namespace spidarcad::app {
namespace {

using spidarcad::test_support::CommandRun;
using spidarcad::test_support::ReadWholeFile;

std::string OutputPath(const std::string& name) {
  return std::string(SPIDARCAD_TEST_OUTPUT_DIR) + "/import_" + name;
}

CommandRun RunCli(const std::string& args, const std::string& tag) {
  return spidarcad::test_support::RunSpidarcad(args, "", "import_" + tag);
}

// The surface of a cube of side 0.02 m: 8 vertices, two triangles on each face.
modeling::TriangleMesh Cube() {
  modeling::TriangleMesh m;
  m.vertices.resize(3, 8);
  for (int i = 0; i < 8; ++i)
    m.vertices.col(i) = 0.02 * Eigen::Vector3d((i & 1) ? 1 : 0, (i & 2) ? 1 : 0, (i & 4) ? 1 : 0);
  m.triangles.resize(3, 12);
  m.triangles << 0, 0, 4, 4, 0, 0, 2, 2, 0, 0, 1, 1,  //
      2, 3, 5, 7, 1, 5, 3, 7, 4, 6, 3, 7,             //
      3, 1, 7, 6, 5, 4, 7, 6, 6, 2, 7, 5;
  return m;
}

// A 0.2 x 0.02 x 0.02 m beam of linear tetrahedra in modeling's layout.
modeling::TetMesh Beam() {
  fem::BoxMeshSettings s;
  s.upper = Eigen::Vector3d(0.2, 0.02, 0.02);
  s.nx = 10;
  s.ny = 1;
  s.nz = 1;
  const fem::TetMesh f = fem::MakeBoxMesh(s);
  modeling::TetMesh m;
  m.nodes = f.nodes.transpose();
  m.tets = f.elements.transpose();
  m.regions = f.regions;
  return m;
}

TEST(ImportCommand, SurfaceAndTetsLandAsMeshObjectsAndFemSolvesTheTets) {
  const std::string scene = std::string(SPIDARCAD_SOURCE_DIR) + "/assets/scenes/platform.json";
  const std::string obj = OutputPath("cube.obj");
  modeling::WriteTriangleMesh(Cube(), obj, modeling::MeshFileFormat::kObj);
  const std::string doc = OutputPath("design.json");
  std::filesystem::remove(doc);
  const CommandRun first =
      RunCli("import '" + obj + "' --into '" + scene + "' --out '" + doc + "'", "obj");
  ASSERT_EQ(first.status, 0) << first.all();
  EXPECT_NE(first.out.find("(obj: 8 vertices, 12 triangles) as mesh 'import_cube'"),
            std::string::npos)
      << first.out;
  const std::string base = OutputPath("beam");
  modeling::WriteTetgenFiles(Beam(), base);
  const CommandRun second =
      RunCli("import '" + base + ".node' --into '" + doc + "' --name bar", "node");
  ASSERT_EQ(second.status, 0) << second.all();
  EXPECT_NE(second.out.find("as tet_mesh 'bar'"), std::string::npos) << second.out;

  Document read;
  read.Load(doc);
  ASSERT_EQ(read.objects().size(), 4u);  // the platform and wall solids, the cube, the bar
  EXPECT_TRUE(std::holds_alternative<SolidData>(read.objects()[1].data));
  const auto& cube = std::get<MeshData>(read.objects()[2].data);
  EXPECT_EQ(read.objects()[2].name, "import_cube");  // the file name without extension
  EXPECT_EQ(cube.import_source, obj);
  ASSERT_TRUE(cube.surface);
  EXPECT_TRUE(cube.surface->vertices.isApprox(Cube().vertices, 1e-15));
  const auto& bar = std::get<MeshData>(read.objects()[3].data);
  ASSERT_TRUE(bar.volume);
  EXPECT_EQ(bar.volume->tets, Beam().tets);

  const CommandRun info = RunCli("info '" + doc + "'", "info");
  ASSERT_EQ(info.status, 0) << info.all();
  EXPECT_NE(
      info.out.find("mesh      'import_cube' nodes=8 triangles=12 imported_from='" + obj + "'"),
      std::string::npos)
      << info.out;

  // The imported tets are a part `fem` can solve: a 1 N tip load against the clamp.
  const CommandRun fem =
      RunCli("fem '" + doc + "' --object bar --fix=-1,-1,-1,1e-9,1,1 " +
                 "--load 0.2,0.01,0.01 --force 0,0,-1 --out '" + OutputPath("bar.vtu") + "'",
             "fem");
  ASSERT_EQ(fem.status, 0) << fem.all();
  const nlohmann::json report = nlohmann::json::parse(fem.out);
  EXPECT_EQ(report["object"]["kind"], "mesh");
  EXPECT_EQ(report["elements"].get<int>(), Beam().tets.cols());
  EXPECT_NEAR(report["fixed_reaction_force"][2].get<double>(), 1.0, 1e-9);
}

TEST(ImportCommand, BadFileExitsTwoNamingFileAndLineAndWritesNothing) {
  const std::string doc = OutputPath("keep.json");
  std::filesystem::copy_file(std::string(SPIDARCAD_SOURCE_DIR) + "/assets/scenes/platform.json",
                             doc, std::filesystem::copy_options::overwrite_existing);
  const std::string before = ReadWholeFile(doc);
  const std::string stl = OutputPath("bad.stl");
  std::ofstream(stl) << "solid x\n facet normal 0 0 1\n  outer loop\n   vertex 0 0 zero\n";
  const CommandRun run = RunCli("import '" + stl + "' --into '" + doc + "'", "bad");
  EXPECT_EQ(run.status, 2) << run.all();
  EXPECT_NE(run.err.find(stl + ":4"), std::string::npos) << run.err;
  EXPECT_EQ(ReadWholeFile(doc), before);

  const CommandRun bad_doc =
      RunCli("import '" + OutputPath("cube.obj") + "' --into '" + stl + "'", "bad_doc");
  EXPECT_EQ(bad_doc.status, 2) << bad_doc.all();
  EXPECT_NE(bad_doc.err.find(stl + ":1"), std::string::npos) << bad_doc.err;
}

}  // namespace
}  // namespace spidarcad::app
