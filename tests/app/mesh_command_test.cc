// Tests of `spidarcad mesh`, run as a separate process on the built binary (SPIDARCAD_EXE): the
// platform scene to STL (read back with ReadTriangleMesh) and to VTU (parsed here: counts,
// indices and the enclosed volume against the platform's dimensions), bad scene files, bad
// options and unknown extensions exit with status 2 and a message that says where.
// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#include <gtest/gtest.h>
#include <sys/wait.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <map>
#include <regex>
#include <sstream>
#include <string>
#include <vector>

#include "spidarcad/modeling/triangle_mesh_io.h"
#include "spidarcad_runner.h"

namespace {

using spidarcad::test_support::CommandRun;
using spidarcad::test_support::ReadWholeFile;

using spidarcad::modeling::ReadTriangleMesh;
using spidarcad::modeling::TriangleMesh;

std::string OutputPath(const std::string& name) {
  return std::string(SPIDARCAD_TEST_OUTPUT_DIR) + "/mesh_cmd_" + name;
}

std::string Platform() {
  return std::string(SPIDARCAD_SOURCE_DIR) + "/assets/scenes/platform.json";
}

// Runs `spidarcad mesh ARGS` and captures stdout, stderr and the exit status.
CommandRun RunMesh(const std::string& args, const std::string& tag) {
  return spidarcad::test_support::RunSpidarcad("mesh " + args, "", "mesh_" + tag);
}

// The number printed before `word` (e.g. "123 triangles"), -1 if absent.
long PrintedCount(const std::string& text, const std::string& word) {
  std::smatch m;
  if (!std::regex_search(text, m, std::regex("([0-9]+) " + word))) return -1;
  return std::stol(m[1]);
}

// Volume of the platform from its dimensions (plate, bracket, gusset, minus six holes); the
// fillets and rounded edges change it by a few percent.
double PlatformVolume() {
  const double plate = 0.3 * 0.2 * 0.01, bracket = 0.01 * 0.2 * 0.16,
               gusset = 0.5 * 0.195 * 0.142 * 0.01;
  const double holes = 4 * M_PI * 0.0055 * 0.0055 * 0.01 + 2 * M_PI * 0.004 * 0.004 * 0.01;
  return plate + bracket + gusset - holes;
}

// Enclosed volume of a triangle mesh, computed here (divergence theorem).
double Volume(const TriangleMesh& mesh) {
  double v = 0.0;
  for (Eigen::Index t = 0; t < mesh.triangles.cols(); ++t) {
    const Eigen::Vector3d a = mesh.vertices.col(mesh.triangles(0, t));
    const Eigen::Vector3d b = mesh.vertices.col(mesh.triangles(1, t));
    const Eigen::Vector3d c = mesh.vertices.col(mesh.triangles(2, t));
    v += a.dot(b.cross(c)) / 6.0;
  }
  return v;
}

// The whitespace-separated numbers of the DataArray named `name` in VTU text.
std::vector<double> DataArray(const std::string& vtu, const std::string& name) {
  const auto at = vtu.find("Name=\"" + name + "\"");
  if (at == std::string::npos) return {};
  const auto begin = vtu.find('>', at) + 1;
  const auto end = vtu.find("</DataArray>", begin);
  std::stringstream s(vtu.substr(begin, end - begin));
  std::vector<double> values;
  double v;
  while (s >> v) values.push_back(v);
  return values;
}

// Closed and consistently oriented: every directed edge once, and its reverse.
void ExpectClosedAndOriented(const TriangleMesh& mesh) {
  std::map<std::pair<int, int>, int> directed;
  for (Eigen::Index t = 0; t < mesh.triangles.cols(); ++t) {
    for (int k = 0; k < 3; ++k) ++directed[{mesh.triangles(k, t), mesh.triangles((k + 1) % 3, t)}];
  }
  for (const auto& [edge, count] : directed) {
    ASSERT_EQ(count, 1);
    ASSERT_EQ(directed.count({edge.second, edge.first}), 1u) << "open edge";
  }
}

TEST(MeshCommand, WritesThePlatformSurfaceAsAClosedStl) {
  const std::string stl = OutputPath("platform.stl");
  std::remove(stl.c_str());
  const CommandRun run =
      RunMesh("'" + Platform() + "' --out '" + stl + "' --resolution 0.004", "stl");
  ASSERT_EQ(run.status, 0) << run.err;
  const TriangleMesh mesh = ReadTriangleMesh(stl);
  EXPECT_EQ(mesh.triangles.cols(), PrintedCount(run.out, "triangles")) << run.out;
  EXPECT_EQ(mesh.vertices.cols(), PrintedCount(run.out, "vertices")) << run.out;
  ExpectClosedAndOriented(mesh);
  EXPECT_NEAR(Volume(mesh), PlatformVolume(), 0.05 * PlatformVolume());
  EXPECT_NE(run.out.find("min triangle angle"), std::string::npos) << run.out;
  EXPECT_NE(run.out.find("error max"), std::string::npos) << run.out;
}

TEST(MeshCommand, WritesPlatformTetsAsVtuWithThePrintedCounts) {
  const std::string vtu_path = OutputPath("platform.vtu");
  std::remove(vtu_path.c_str());
  const CommandRun run = RunMesh(
      "'" + Platform() + "' --out '" + vtu_path + "' --resolution 0.005 --tets tetgen --quality 2",
      "vtu");
  ASSERT_EQ(run.status, 0) << run.err;
  const std::string vtu = ReadWholeFile(vtu_path);
  std::smatch m;
  ASSERT_TRUE(std::regex_search(
      vtu, m, std::regex("NumberOfPoints=\"([0-9]+)\" NumberOfCells=\"([0-9]+)\"")));
  const long points = std::stol(m[1]), cells = std::stol(m[2]);
  EXPECT_EQ(points, PrintedCount(run.out, "nodes")) << run.out;
  EXPECT_EQ(cells, PrintedCount(run.out, "tets")) << run.out;
  EXPECT_GT(cells, 1000);
  const std::vector<double> xyz = DataArray(vtu, "Points");
  const std::vector<double> connectivity = DataArray(vtu, "connectivity");
  ASSERT_EQ(static_cast<long>(xyz.size()), 3 * points);
  ASSERT_EQ(static_cast<long>(connectivity.size()), 4 * cells);
  // Every tet positively oriented; together they fill the platform's volume.
  double volume = 0.0;
  for (long t = 0; t < cells; ++t) {
    Eigen::Vector3d p[4];
    for (int k = 0; k < 4; ++k) {
      const long i = static_cast<long>(connectivity[4 * t + k]);
      ASSERT_GE(i, 0);
      ASSERT_LT(i, points);
      p[k] = Eigen::Vector3d(xyz[3 * i], xyz[3 * i + 1], xyz[3 * i + 2]);
    }
    const double v = (p[1] - p[0]).dot((p[2] - p[0]).cross(p[3] - p[0])) / 6.0;
    EXPECT_GT(v, 0.0) << "tet " << t;
    volume += v;
  }
  EXPECT_NEAR(volume, PlatformVolume(), 0.05 * PlatformVolume());
  EXPECT_NE(run.out.find("dihedral"), std::string::npos) << run.out;
}

// The smallest dihedral angle the command prints on its tet quality line.
double PrintedMinDihedral(const std::string& out) {
  std::smatch m;
  const std::regex line("tet quality: dihedral angles ([0-9.eE+-]+) \\.\\.");
  if (!std::regex_search(out, m, line)) return -1.0;
  return std::stod(m[1]);
}

// --smooth-tets moves TetGen's interior vertices: the same tets, a smallest dihedral angle no
// lower and fewer tets under the angle (the platform at 8 mm, with and without); bad values and
// a mesh without TetGen's tets exit 2 naming the option.
TEST(MeshCommand, SmoothTetsRaisesTheSmallestDihedralAngleAndRefusesBadValues) {
  const std::string base = "'" + Platform() + "' --resolution 0.008 --tets tetgen --out ";
  const CommandRun plain = RunMesh(base + OutputPath("unsmoothed.vtu"), "unsmoothed");
  ASSERT_EQ(plain.status, 0) << plain.all();
  const CommandRun smooth =
      RunMesh(base + OutputPath("smoothed.vtu") + " --smooth-tets 10", "smoothed");
  ASSERT_EQ(smooth.status, 0) << smooth.all();
  EXPECT_EQ(PrintedCount(smooth.out, "tets"), PrintedCount(plain.out, "tets")) << smooth.out;
  std::smatch m;
  ASSERT_TRUE(
      std::regex_search(smooth.out, m, std::regex("tets under 10 deg ([0-9]+) -> ([0-9]+)")))
      << smooth.out;
  EXPECT_LT(std::stol(m[2]), std::stol(m[1])) << smooth.out;
  EXPECT_GE(PrintedMinDihedral(smooth.out), PrintedMinDihedral(plain.out)) << smooth.out;
  EXPECT_GT(PrintedMinDihedral(plain.out), 0.0) << plain.out;
  for (const std::string& bad : {std::string("--tets tetgen --smooth-tets -1"),
                                 std::string("--tets tetgen --smooth-tets 60"),
                                 std::string("--tets cgal --smooth-tets 10")}) {
    const CommandRun run = RunMesh(
        "'" + Platform() + "' --resolution 0.008 --out " + OutputPath("bad.vtu") + " " + bad,
        "bad_smooth");
    EXPECT_EQ(run.status, 2) << bad << "\n" << run.all();
    EXPECT_NE(run.err.find("--smooth-tets"), std::string::npos) << bad << "\n" << run.all();
  }
}

TEST(MeshCommand, CgalWritesPositivePlatformTetsWithThePrintedCounts) {
  const std::string vtu_path = OutputPath("platform_cgal.vtu");
  std::remove(vtu_path.c_str());
  const CommandRun run = RunMesh(
      "'" + Platform() + "' --out '" + vtu_path + "' --resolution 0.006 --tets cgal", "cgal");
  ASSERT_EQ(run.status, 0) << run.err;
  const std::string vtu = ReadWholeFile(vtu_path);
  std::smatch m;
  ASSERT_TRUE(std::regex_search(
      vtu, m, std::regex("NumberOfPoints=\"([0-9]+)\" NumberOfCells=\"([0-9]+)\"")));
  const long points = std::stol(m[1]), cells = std::stol(m[2]);
  EXPECT_EQ(points, PrintedCount(run.out, "nodes")) << run.out;
  EXPECT_EQ(cells, PrintedCount(run.out, "tets")) << run.out;
  EXPECT_GT(cells, 1000);
  const std::vector<double> xyz = DataArray(vtu, "Points");
  const std::vector<double> connectivity = DataArray(vtu, "connectivity");
  ASSERT_EQ(static_cast<long>(xyz.size()), 3 * points);
  ASSERT_EQ(static_cast<long>(connectivity.size()), 4 * cells);
  double volume = 0.0;
  for (long t = 0; t < cells; ++t) {
    Eigen::Vector3d p[4];
    for (int k = 0; k < 4; ++k) {
      const long i = static_cast<long>(connectivity[4 * t + k]);
      ASSERT_GE(i, 0);
      ASSERT_LT(i, points);
      p[k] = Eigen::Vector3d(xyz[3 * i], xyz[3 * i + 1], xyz[3 * i + 2]);
    }
    const double v = (p[1] - p[0]).dot((p[2] - p[0]).cross(p[3] - p[0])) / 6.0;
    EXPECT_GT(v, 0.0) << "tet " << t;
    volume += v;
  }
  EXPECT_NEAR(volume, PlatformVolume(), 0.05 * PlatformVolume());
  EXPECT_NE(run.out.find("dihedral"), std::string::npos) << run.out;
  EXPECT_NE(run.out.find("error max"), std::string::npos) << run.out;
}

TEST(MeshCommand, WritesTetgenNodeAndEleFiles) {
  const std::string base = OutputPath("platform_tets");
  std::remove((base + ".node").c_str());
  std::remove((base + ".ele").c_str());
  const CommandRun run = RunMesh(
      "'" + Platform() + "' --out '" + base + ".node' --resolution 0.008 --tets tetgen --quality 0",
      "node");
  ASSERT_EQ(run.status, 0) << run.err;
  // First data line (after '#' comments) of .node: count, dimension 3; of .ele: count, 4
  // nodes per tet.
  auto header = [](const std::string& path) {
    std::ifstream in(path);
    std::string line;
    while (std::getline(in, line) && (line.empty() || line[0] == '#')) {
    }
    return std::stringstream(line);
  };
  long nodes = -1, dim = -1, tets = -1, per = -1;
  header(base + ".node") >> nodes >> dim;
  header(base + ".ele") >> tets >> per;
  EXPECT_EQ(nodes, PrintedCount(run.out, "nodes"));
  EXPECT_EQ(dim, 3);
  EXPECT_EQ(tets, PrintedCount(run.out, "tets"));
  EXPECT_EQ(per, 4);
}

TEST(MeshCommand, BadSceneFileExitsTwoNamingFileAndLine) {
  const std::string scene = OutputPath("bad_scene.json");
  // Line 7 holds a negative radius.
  std::ofstream(scene) << "{\n"
                          "  \"format\": \"spidarcad-scene\",\n"
                          "  \"version\": 1,\n"
                          "  \"units\": \"m\",\n"
                          "  \"solids\": [\n"
                          "    {\"name\": \"ball\", \"root\":\n"
                          "      {\"type\": \"sphere\", \"radius\": -0.1}}\n"
                          "  ]\n"
                          "}\n";
  const CommandRun run =
      RunMesh("'" + scene + "' --out '" + OutputPath("bad.stl") + "'", "bad_scene");
  EXPECT_EQ(run.status, 2);
  EXPECT_NE(run.err.find(scene + ":7:"), std::string::npos) << run.err;
  EXPECT_NE(run.err.find("radius"), std::string::npos) << run.err;

  const std::string syntax = OutputPath("syntax_scene.json");
  std::ofstream(syntax)
      << "{\n  \"format\": \"spidarcad-scene\",\n  \"version\": 1\n  \"units\": \"m\"\n}\n";
  const CommandRun run2 =
      RunMesh("'" + syntax + "' --out '" + OutputPath("bad.stl") + "'", "syntax_scene");
  EXPECT_EQ(run2.status, 2);
  EXPECT_NE(run2.err.find(syntax + ":4:"), std::string::npos) << run2.err;

  const CommandRun missing =
      RunMesh("'" + OutputPath("no_such_scene.json") + "' --out x.stl", "missing");
  EXPECT_EQ(missing.status, 2);
  EXPECT_NE(missing.err.find("no_such_scene.json"), std::string::npos) << missing.err;
}

TEST(MeshCommand, UnknownExtensionAndBadOptionsExitTwo) {
  const CommandRun ext =
      RunMesh("'" + Platform() + "' --out '" + OutputPath("platform.xyz") + "'", "ext");
  EXPECT_EQ(ext.status, 2);
  EXPECT_NE(ext.err.find(".xyz"), std::string::npos) << ext.err;

  const CommandRun tets =
      RunMesh("'" + Platform() + "' --out '" + OutputPath("c.vtu") + "' --tets netgen", "tets");
  EXPECT_EQ(tets.status, 2);
  EXPECT_NE(tets.err.find("netgen"), std::string::npos) << tets.err;
  EXPECT_NE(tets.err.find("tetgen or cgal"), std::string::npos) << tets.err;

  const CommandRun vtu_without_tets =
      RunMesh("'" + Platform() + "' --out '" + OutputPath("n.vtu") + "'", "notets");
  EXPECT_EQ(vtu_without_tets.status, 2);
  EXPECT_NE(vtu_without_tets.err.find("--tets"), std::string::npos) << vtu_without_tets.err;

  const CommandRun solid =
      RunMesh("'" + Platform() + "' --out '" + OutputPath("s.stl") + "' --solid nope", "solid");
  EXPECT_EQ(solid.status, 2);
  EXPECT_NE(solid.err.find("'platform'"), std::string::npos) << solid.err;

  const CommandRun resolution =
      RunMesh("'" + Platform() + "' --out '" + OutputPath("r.stl") + "' --resolution -1", "res");
  EXPECT_EQ(resolution.status, 2);
  EXPECT_NE(resolution.err.find("--resolution"), std::string::npos) << resolution.err;

  const CommandRun quality = RunMesh(
      "'" + Platform() + "' --out '" + OutputPath("q.vtu") + "' --tets tetgen --quality 0.5",
      "quality");
  EXPECT_EQ(quality.status, 2);
  EXPECT_NE(quality.err.find("--quality"), std::string::npos) << quality.err;

  const CommandRun unwritable =
      RunMesh("'" + Platform() + "' --out /nonexistent-dir/p.stl --resolution 0.008", "unwritable");
  EXPECT_EQ(unwritable.status, 2);
  EXPECT_NE(unwritable.err.find("/nonexistent-dir/p.stl"), std::string::npos) << unwritable.err;
}

TEST(MeshCommand, DocumentSolidIsMeshedByObjectNameAndOtherNamesAreRefused) {
  const std::string doc = std::string(SPIDARCAD_SOURCE_DIR) + "/assets/scenes/platform_fe.json";
  const std::string out = OutputPath("platform_fe.stl");
  const CommandRun run =
      RunMesh("'" + doc + "' --object platform --resolution 0.004 --out '" + out + "'", "doc");
  ASSERT_EQ(run.status, 0) << run.all();
  EXPECT_NE(run.out.find("solid 'platform'"), std::string::npos) << run.out;
  const TriangleMesh mesh = ReadTriangleMesh(out);
  // The same solid as platform.json: its volume from the drawing's dimensions within 5 %.
  EXPECT_NEAR(Volume(mesh), PlatformVolume(), 0.05 * PlatformVolume());

  const CommandRun unknown = RunMesh("'" + doc + "' --object nope --out x.stl", "doc_unknown");
  EXPECT_EQ(unknown.status, 2);
  EXPECT_NE(unknown.err.find("--object 'nope': no such solid in " + doc + " (it has 'platform')"),
            std::string::npos)
      << unknown.err;
  const CommandRun other = RunMesh("'" + doc + "' --object 'platform FE' --out x.stl", "doc_other");
  EXPECT_EQ(other.status, 2);
  EXPECT_NE(other.err.find("that is a fe_model object, not a solid (its solids: 'platform')"),
            std::string::npos)
      << other.err;
}

TEST(MeshCommand, HelpTeachesWithPlatformExamples) {
  const CommandRun run = RunMesh("--help", "help");
  EXPECT_EQ(run.status, 0);
  EXPECT_NE(run.out.find("assets/scenes/platform.json --out platform.vtu --tets tetgen"),
            std::string::npos)
      << run.out;
  EXPECT_NE(run.out.find("--tets cgal"), std::string::npos) << run.out;
}

}  // namespace

namespace {

// Distance from each corner of the box [−h, h]³ to the nearest mesh vertex, worst over the corners.
double WorstCornerGap(const TriangleMesh& mesh, const Eigen::Vector3d& h) {
  double worst = 0.0;
  for (int c = 0; c < 8; ++c) {
    const Eigen::Vector3d corner((c & 1) ? h.x() : -h.x(), (c & 2) ? h.y() : -h.y(),
                                 (c & 4) ? h.z() : -h.z());
    double best = 1e9;
    for (Eigen::Index v = 0; v < mesh.vertices.cols(); ++v)
      best = std::min(best, (mesh.vertices.col(v) - corner).norm());
    worst = std::max(worst, best);
  }
  return worst;
}

double SmallestAngleDeg(const spidarcad::modeling::TriangleMesh& mesh);  // below

TEST(MeshCommand, PutsBoxCornersBackWhenSharpIsGiven) {
  // A box off the grid: plain marching tetrahedra cuts its corners; --sharp restores them.
  const std::string scene = OutputPath("sharp_box.json");
  std::ofstream(scene) << R"({"format": "spidarcad-scene", "version": 1, "solids": [
    {"name": "block", "root": {"type": "box", "size": [0.0413, 0.0291, 0.0187]}}]})";
  const Eigen::Vector3d h(0.0413 / 2, 0.0291 / 2, 0.0187 / 2);
  const CommandRun plain =
      RunMesh(scene + " --resolution 0.004 --out " + OutputPath("plain_box.stl"), "plain_box");
  ASSERT_EQ(plain.status, 0) << plain.all();
  const CommandRun sharp = RunMesh(
      scene + " --resolution 0.004 --sharp --out " + OutputPath("sharp_box.stl"), "sharp_box");
  ASSERT_EQ(sharp.status, 0) << sharp.all();
  EXPECT_NE(sharp.out.find("sharpen: "), std::string::npos) << sharp.out;
  const double plain_gap = WorstCornerGap(ReadTriangleMesh(OutputPath("plain_box.stl")), h);
  const double sharp_gap = WorstCornerGap(ReadTriangleMesh(OutputPath("sharp_box.stl")), h);
  EXPECT_GT(plain_gap, 4e-4);  // a tenth of a cell: the chamfer is there without --sharp
  EXPECT_LT(sharp_gap, 4e-6);  // a thousandth of a cell (STL stores float)
  // The lattice's surface, sharpened: its vertices lie too far from the corners to move there,
  // so each corner gets a new vertex.
  const CommandRun lattice = RunMesh(
      scene + " --resolution 0.004 --mesher lattice --sharp --out " + OutputPath("lattice_box.stl"),
      "lattice_box");
  ASSERT_EQ(lattice.status, 0) << lattice.all();
  EXPECT_NE(lattice.out.find("(lattice)"), std::string::npos) << lattice.out;
  EXPECT_NE(lattice.out.find("corners inserted"), std::string::npos) << lattice.out;
  const TriangleMesh lattice_mesh = ReadTriangleMesh(OutputPath("lattice_box.stl"));
  EXPECT_LT(WorstCornerGap(lattice_mesh, h), 4e-6);
  EXPECT_GE(SmallestAngleDeg(lattice_mesh), 10.0 - 1e-3);  // STL stores float
  const CommandRun bad =
      RunMesh(scene + " --sharp --raw-surface --out " + OutputPath("bad.stl"), "sharp_raw");
  EXPECT_EQ(bad.status, 2);
  EXPECT_NE(bad.err.find("--sharp"), std::string::npos) << bad.all();
}

// The smallest triangle angle of a mesh, degrees, computed here from the corners.
double SmallestAngleDeg(const spidarcad::modeling::TriangleMesh& mesh) {
  double least = 180.0;
  for (Eigen::Index t = 0; t < mesh.triangles.cols(); ++t)
    for (int k = 0; k < 3; ++k) {
      const Eigen::Vector3d a = mesh.vertices.col(mesh.triangles(k, t));
      const Eigen::Vector3d b = mesh.vertices.col(mesh.triangles((k + 1) % 3, t));
      const Eigen::Vector3d c = mesh.vertices.col(mesh.triangles((k + 2) % 3, t));
      const double cosine = (b - a).normalized().dot((c - a).normalized());
      least = std::min(least, std::acos(std::clamp(cosine, -1.0, 1.0)) * 180.0 / M_PI);
    }
  return least;
}

// --sharp repairs the slivers it leaves along the creases by default (--sliver-angle 10): the
// 40 mm cube of assets/scenes/snap_box.json at 4 mm has a worst triangle of 3.7 degrees without
// the repair and none under 10 with it, its corners in place both ways.
TEST(MeshCommand, SharpRepairsSliversAlongCreasesUnlessTurnedOff) {
  const std::string cube = std::string(SPIDARCAD_SOURCE_DIR) + "/assets/scenes/snap_box.json";
  const Eigen::Vector3d h(0.02, 0.02, 0.02);
  const CommandRun repaired = RunMesh(
      "'" + cube + "' --resolution 0.004 --sharp --out " + OutputPath("sliver_on.stl"), "on");
  ASSERT_EQ(repaired.status, 0) << repaired.all();
  EXPECT_NE(repaired.out.find("slivers under 10 deg: "), std::string::npos) << repaired.out;
  // The quality line counts what is left under 10 degrees (nothing) and under 5.
  EXPECT_NE(repaired.out.find(", 0 triangles under 10 deg, 0 under 5 deg"), std::string::npos)
      << repaired.out;
  const CommandRun off =
      RunMesh("'" + cube + "' --resolution 0.004 --sharp --sliver-angle 0 --out " +
                  OutputPath("sliver_off.stl"),
              "off");
  ASSERT_EQ(off.status, 0) << off.all();
  EXPECT_EQ(off.out.find("slivers under"), std::string::npos) << off.out;
  EXPECT_EQ(off.out.find(", 0 triangles under 10 deg"), std::string::npos) << off.out;
  // The cube is centred at z = -0.04 m; WorstCornerGap takes it at the origin.
  auto centred = [](TriangleMesh mesh) {
    mesh.vertices.row(2).array() += 0.04;
    return mesh;
  };
  const TriangleMesh on_mesh = centred(ReadTriangleMesh(OutputPath("sliver_on.stl")));
  const TriangleMesh off_mesh = centred(ReadTriangleMesh(OutputPath("sliver_off.stl")));
  EXPECT_LT(SmallestAngleDeg(off_mesh), 5.0);
  EXPECT_GE(SmallestAngleDeg(on_mesh), 10.0 - 1e-3);  // STL stores float
  EXPECT_LT(WorstCornerGap(on_mesh, h), 4e-6);
  EXPECT_LT(WorstCornerGap(off_mesh, h), 4e-6);
  for (const std::string& bad :
       {std::string("--sliver-angle 10"), std::string("--sharp --sliver-angle 60"),
        std::string("--sharp --sliver-angle -1")}) {
    const CommandRun run =
        RunMesh("'" + cube + "' " + bad + " --out " + OutputPath("sliver_bad.stl"), "bad");
    EXPECT_EQ(run.status, 2) << bad << "\n" << run.all();
    EXPECT_NE(run.err.find("--sliver-angle"), std::string::npos) << bad << "\n" << run.all();
  }
}

// The clean-up snaps by default (--snap-cells 0.2): the smooth clay blob of
// assets/scenes/clay.json at its default cell (2.3 mm) has no triangle under 10 degrees, measured
// here from the written STL; --snap-cells 0 gives the mesh of before (worst 0.056 degrees, 80048
// triangles against 64194, measured 2026-12-05). Values outside [0, 0.25] are refused before
// the scene is read.
// The default surface is the lattice route's; the marching-tetrahedra route keeps its clean-up's
// snapping (--snap-cells 0.2) by default. Both leave no angle under 10° on the clay, which
// unsnapped marching tetrahedra does not, and all three enclose the same volume.
TEST(MeshCommand, SnapsSmoothSurfacesToTenDegreesUnlessTurnedOff) {
  const std::string clay = std::string(SPIDARCAD_SOURCE_DIR) + "/assets/scenes/clay.json";
  const CommandRun lattice =
      RunMesh("'" + clay + "' --out " + OutputPath("lattice.stl"), "lattice");
  ASSERT_EQ(lattice.status, 0) << lattice.all();
  EXPECT_NE(lattice.out.find("(lattice)"), std::string::npos) << lattice.out;
  EXPECT_NE(lattice.out.find("lattice vertices snapped onto the surface (within 0.35"),
            std::string::npos)
      << lattice.out;
  const CommandRun snapped =
      RunMesh("'" + clay + "' --mesher tetrahedra --out " + OutputPath("snap_on.stl"), "snap_on");
  ASSERT_EQ(snapped.status, 0) << snapped.all();
  EXPECT_NE(snapped.out.find("snap 0.2 cells"), std::string::npos) << snapped.out;
  const CommandRun plain =
      RunMesh("'" + clay + "' --snap-cells 0 --out " + OutputPath("snap_off.stl"), "snap_off");
  ASSERT_EQ(plain.status, 0) << plain.all();
  EXPECT_NE(plain.out.find("(marching tetrahedra)"), std::string::npos) << plain.out;
  const TriangleMesh lattice_mesh = ReadTriangleMesh(OutputPath("lattice.stl"));
  const TriangleMesh on_mesh = ReadTriangleMesh(OutputPath("snap_on.stl"));
  const TriangleMesh off_mesh = ReadTriangleMesh(OutputPath("snap_off.stl"));
  EXPECT_GE(SmallestAngleDeg(lattice_mesh), 10.0);
  EXPECT_GE(SmallestAngleDeg(on_mesh), 10.0);
  EXPECT_LT(SmallestAngleDeg(off_mesh), 1.0);
  EXPECT_LT(on_mesh.triangles.cols(), off_mesh.triangles.cols());
  // All closed and consistently oriented, enclosing the same volume within 0.1 %.
  ExpectClosedAndOriented(lattice_mesh);
  ExpectClosedAndOriented(on_mesh);
  ExpectClosedAndOriented(off_mesh);
  EXPECT_NEAR(Volume(on_mesh), Volume(off_mesh), 1e-3 * Volume(off_mesh));
  EXPECT_NEAR(Volume(lattice_mesh), Volume(off_mesh), 1e-3 * Volume(off_mesh));
  for (const std::string& bad :
       {std::string("--snap-cells 0.3"), std::string("--snap-cells -0.1"),
        std::string("--snap-cells nan"), std::string("--mesher cubes"),
        std::string("--mesher lattice --snap-cells 0.1"), std::string("--lattice-snap 0.5"),
        std::string("--lattice-snap 0.2 --mesher tetrahedra"),
        std::string("--lattice-snap 0.2 --sharp")}) {
    const CommandRun run = RunMesh("'" + OutputPath("no_such_scene.json") + "' " + bad + " --out " +
                                       OutputPath("snap_bad.stl"),
                                   "snap_bad");
    EXPECT_EQ(run.status, 2) << bad << "\n" << run.all();
    const std::string option = bad.substr(0, bad.find(' '));
    EXPECT_NE(run.err.find(option), std::string::npos) << bad << "\n" << run.all();
    EXPECT_EQ(run.err.find("no_such_scene"), std::string::npos) << bad << "\n" << run.all();
  }
  const CommandRun raw = RunMesh(
      "'" + clay + "' --snap-cells 0.1 --raw-surface --out " + OutputPath("snap_raw.stl"), "raw");
  EXPECT_EQ(raw.status, 2) << raw.all();
  EXPECT_NE(raw.err.find("--snap-cells"), std::string::npos) << raw.all();
}

// --flat-cells 0.5 coarsens the flat fans of the marching-tetrahedra surface: the platform's
// plate faces are cut by the 10 mm grid without needles, so the clean-up finds nothing to
// collapse there, and its surface had 15,120 triangles against 6,388 coarsened (2026-12-06).
// The coarsened surface is closed, encloses the same volume and has no sharper triangle; the
// option belongs to the marching-tetrahedra route and its clean-up, and is refused elsewhere and
// outside [0, 1] before the scene is read.
TEST(MeshCommand, FlatCellsCoarsensFlatFacesOnTheTetrahedraRoute) {
  const std::string platform = std::string(SPIDARCAD_SOURCE_DIR) + "/assets/scenes/platform.json";
  const std::string common = "'" + platform + "' --mesher tetrahedra --resolution 0.01 --out ";
  const CommandRun plain = RunMesh(common + OutputPath("flat_off.stl"), "flat_off");
  ASSERT_EQ(plain.status, 0) << plain.all();
  EXPECT_EQ(plain.out.find("flat fans"), std::string::npos) << plain.out;
  const CommandRun flat =
      RunMesh(common + OutputPath("flat_on.stl") + " --flat-cells 0.5", "flat_on");
  ASSERT_EQ(flat.status, 0) << flat.all();
  EXPECT_NE(flat.out.find("collapses in flat fans (edges under 0.5 cells)"), std::string::npos)
      << flat.out;
  const TriangleMesh off_mesh = ReadTriangleMesh(OutputPath("flat_off.stl"));
  const TriangleMesh on_mesh = ReadTriangleMesh(OutputPath("flat_on.stl"));
  ExpectClosedAndOriented(on_mesh);
  EXPECT_LT(on_mesh.triangles.cols(), off_mesh.triangles.cols() / 2);
  EXPECT_NEAR(Volume(on_mesh), Volume(off_mesh), 1e-4 * Volume(off_mesh));
  EXPECT_GE(SmallestAngleDeg(on_mesh), std::min(SmallestAngleDeg(off_mesh), 15.0) - 1e-6);
  for (const std::string& bad :
       {std::string("--flat-cells 1.5"), std::string("--flat-cells -0.1"),
        std::string("--flat-cells nan"), std::string("--mesher lattice --flat-cells 0.5"),
        std::string("--flat-cells 0.5 --raw-surface"),
        std::string("--flat-cells 0.5 --tets cgal")}) {
    const std::string out =
        bad.find("--tets") != std::string::npos ? "flat_bad.vtu" : "flat_bad.stl";
    const CommandRun run =
        RunMesh("'" + OutputPath("no_such_scene.json") + "' " + bad + " --out " + OutputPath(out),
                "flat_bad");
    EXPECT_EQ(run.status, 2) << bad << "\n" << run.all();
    const std::string option = bad.substr(0, bad.find(' '));
    EXPECT_NE(run.err.find(option), std::string::npos) << bad << "\n" << run.all();
    EXPECT_EQ(run.err.find("no_such_scene"), std::string::npos) << bad << "\n" << run.all();
  }
}

// Writes a scene file whose one solid's root is `root` (JSON text on line 6); returns its path.
std::string WriteScene(const std::string& name, const std::string& root) {
  const std::string path = OutputPath(name);
  std::ofstream(path)
      << "{\n  \"format\": \"spidarcad-scene\",\n  \"version\": 1,\n  \"solids\": [\n"
         "    {\"name\": \"s\", \"root\":\n"
      << root << "}\n  ]\n}\n";
  return path;
}

std::string Repeat(const std::string& s, int times) {
  std::string out;
  for (int i = 0; i < times; ++i) out += s;
  return out;
}

bool FileExists(const std::string& path) { return std::ifstream(path).good(); }

TEST(MeshCommand, HostileScenesExitTwoNamingFileLineAndField) {
  struct Case {
    std::string name, root, expected;
  };
  const Case cases[] = {
      // 10,000 nested translate nodes (used to overflow the stack: segmentation fault).
      {"chain.json",
       Repeat(R"({"type": "translate", "translation": [0, 0, 0], "children": [)", 9999) +
           R"({"type": "sphere", "radius": 0.01})" + Repeat("]}", 9999),
       ":6:"},
      // An array nested 100,000 deep.
      {"nested.json",
       R"({"type": "sphere", "radius": )" + Repeat("[", 100000) + Repeat("]", 100000) + "}", ":6:"},
      // A number beyond a double (used to exit 1 with nlohmann's out_of_range.406).
      {"huge.json", R"({"type": "sphere", "radius": 1e999})",
       ":6:30: field /solids/0/root/radius: "},
      // A key with a '/' and a 20-digit index (used to exit 1 with "stol").
      {"slash.json", R"({"type": "sphere", "radius": 0.1, "children/99999999999999999999": 1})",
       ":6:68: field /solids/0/root/children~199999999999999999999"},
      // A polar array of a billion copies.
      {"billion.json",
       R"({"type": "polar_array", "count": 1000000000, "children": [{"type": "sphere", "radius": 0.01}]})",
       ":6:34: field /solids/0/root/count"},
  };
  for (const Case& c : cases) {
    const std::string scene = WriteScene(c.name, c.root);
    const std::string out = OutputPath("hostile_" + c.name + ".stl");
    std::remove(out.c_str());
    const CommandRun run = RunMesh("'" + scene + "' --out '" + out + "'", "hostile");
    EXPECT_EQ(run.status, 2) << c.name << "\n" << run.err;
    EXPECT_NE(run.err.find(scene + c.expected), std::string::npos) << c.name << "\n"
                                                                   << run.err.substr(0, 2000);
    EXPECT_FALSE(FileExists(out)) << c.name;
  }
}

TEST(MeshCommand, DeviceOrDirectoryAsTheSceneIsRefusedBeforeReading) {
  // /dev/zero used to be read until std::bad_alloc (exit 1).
  const CommandRun zero = RunMesh("/dev/zero --out '" + OutputPath("zero.stl") + "'", "zero");
  EXPECT_EQ(zero.status, 2) << zero.all();
  EXPECT_NE(zero.err.find("/dev/zero: is not a regular file"), std::string::npos) << zero.err;
  const CommandRun directory = RunMesh(
      "'" + std::string(SPIDARCAD_SOURCE_DIR) + "' --out '" + OutputPath("dir.stl") + "'", "dir");
  EXPECT_EQ(directory.status, 2) << directory.all();
  EXPECT_NE(directory.err.find("not a regular file"), std::string::npos) << directory.err;
}

TEST(MeshCommand, AbsurdResolutionsAreRefusedWithTheGridEstimate) {
  struct Case {
    std::string resolution, cells;
  };
  // The platform's box is about 0.30 x 0.20 x 0.17 m (plus the coarse search's slack).
  const Case cases[] = {{"5e-324", "inf grid cells"}, {"1e-06", "e+16 grid cells"}};
  for (const Case& c : cases) {
    const std::string out = OutputPath("absurd.stl");
    std::remove(out.c_str());
    const CommandRun run =
        RunMesh("'" + Platform() + "' --out '" + out + "' --resolution " + c.resolution, "absurd");
    EXPECT_EQ(run.status, 2) << c.resolution << "\n" << run.all();
    EXPECT_NE(run.err.find("--resolution " + c.resolution), std::string::npos) << run.err;
    EXPECT_NE(run.err.find(c.cells), std::string::npos) << run.err;
    EXPECT_NE(run.err.find("raise the limit with --max-cells"), std::string::npos) << run.err;
    EXPECT_FALSE(FileExists(out));
  }
}

TEST(MeshCommand, BudgetRefusesWithTheEstimateAndTheOptionThatRaisesIt) {
  struct Case {
    std::string options, option;
  };
  const Case cases[] = {
      {"--max-cells 1000", "--max-cells"},
      {"--max-memory 1000", "--max-memory"},
      {"--max-work 1000", "--max-work"},
  };
  for (const Case& c : cases) {
    const std::string out = OutputPath("budget.stl");
    std::remove(out.c_str());
    const CommandRun run =
        RunMesh("'" + Platform() + "' --out '" + out + "' " + c.options, "budget");
    EXPECT_EQ(run.status, 2) << c.options << "\n" << run.all();
    EXPECT_NE(run.err.find("raise the limit with " + c.option), std::string::npos) << run.err;
    EXPECT_FALSE(FileExists(out));
  }
  // The estimate's figures are in the refusal.
  const CommandRun memory = RunMesh(
      "'" + Platform() + "' --out '" + OutputPath("budget.stl") + "' --max-memory 1000", "memory");
  EXPECT_NE(memory.err.find("estimate: grid "), std::string::npos) << memory.err;
  EXPECT_NE(memory.err.find(" triangles"), std::string::npos) << memory.err;
  EXPECT_NE(memory.err.find(" MiB"), std::string::npos) << memory.err;
  // Out of range limits name the option.
  const std::vector<std::string> bad_limits = {"--max-cells 0", "--max-cells 2e9",
                                               "--max-memory -1", "--max-work nan"};
  for (const std::string& bad : bad_limits) {
    const CommandRun run = RunMesh(
        "'" + Platform() + "' --out '" + OutputPath("budget.stl") + "' " + bad, "bad_budget");
    EXPECT_EQ(run.status, 2) << bad << "\n" << run.all();
    EXPECT_NE(run.err.find(bad.substr(0, bad.find(' '))), std::string::npos) << run.err;
  }
}

TEST(MeshCommand, ProgressGoesToStderrWithTheFlag) {
  const std::string out = OutputPath("progress.stl");
  const CommandRun run =
      RunMesh("'" + Platform() + "' --out '" + out + "' --resolution 0.008 --progress", "progress");
  EXPECT_EQ(run.status, 0) << run.all();
  EXPECT_LT(run.err.find("spidarcad mesh: box: finding where the solid lies"),
            run.err.find("spidarcad mesh: estimate: grid "))
      << run.err;
  EXPECT_NE(run.err.find("spidarcad mesh: estimate: grid "), std::string::npos) << run.err;
  EXPECT_NE(run.err.find("spidarcad mesh: surface 100.0 %"), std::string::npos) << run.err;
  EXPECT_EQ(run.out.find("estimate"), std::string::npos);  // stdout keeps its figures only
  // Without the flag (stderr is a file here, not a terminal): nothing on stderr.
  const CommandRun quiet =
      RunMesh("'" + Platform() + "' --out '" + out + "' --resolution 0.008", "quiet");
  EXPECT_EQ(quiet.status, 0) << quiet.all();
  EXPECT_EQ(quiet.err, "");
}

TEST(MeshCommand, CtrlCStopsWithStatus130AndWritesNothing) {
  // A sphere of 10 cm at 0.3 mm (3.2e8 grid cells, inside --max-cells 1e9): a long run, so it is
  // still meshing when the signal comes (sent once the progress line shows the surface stage has
  // begun).
  const std::string scene = WriteScene("ctrl_c.json", R"({"type": "sphere", "radius": 0.1})");
  const std::string out = OutputPath("ctrl_c.stl");
  const std::string err = OutputPath("ctrl_c.err");
  std::remove(out.c_str());
  const CommandRun run = spidarcad::test_support::InterruptOnceShown(
      "'" + std::string(SPIDARCAD_EXE) + "' mesh '" + scene + "' --out '" + out +
          "' --resolution 0.0003 --max-cells 1e9 --max-memory 1e11 --max-work 1e15 --progress",
      err, "surface", OutputPath("ctrl_c_run"), 60, 60);
  const std::string& stderr_text = run.err;
  EXPECT_NE(run.out.find("status=130"), std::string::npos) << run.all() << stderr_text;
  EXPECT_NE(stderr_text.find("interrupted (Ctrl+C): stopped, nothing written"), std::string::npos)
      << stderr_text;
  EXPECT_FALSE(FileExists(out));
  // No temporary left beside it either.
  const std::string listing =
      spidarcad::test_support::RunCommand("ls -a '" + std::string(SPIDARCAD_TEST_OUTPUT_DIR) + "'",
                                          "", OutputPath("ctrl_c_ls"))
          .out;
  EXPECT_EQ(listing.find(".ctrl_c.partial-"), std::string::npos) << listing;
}

// An axis-aligned box [0, 1]^3 as 12 outward triangles over 8 vertices.
TriangleMesh UnitBox() {
  TriangleMesh m;
  m.vertices.resize(3, 8);
  for (int i = 0; i < 8; ++i) m.vertices.col(i) << (i & 1), (i & 2) / 2, (i & 4) / 4;
  m.triangles.resize(3, 12);
  m.triangles << 0, 1, 4, 5, 0, 1, 2, 3, 0, 2, 1, 3,  //
      2, 2, 5, 7, 1, 5, 6, 6, 4, 4, 3, 7,             //
      1, 3, 6, 6, 4, 4, 3, 7, 2, 6, 5, 5;
  return m;
}

TEST(MeshCommand, RepairsAMeshFileReportingEachChangeAndTetrahedralizesIt) {
  // The box inside out, with one triangle repeated: OBJ keeps both (STL readers weld only).
  TriangleMesh box = UnitBox();
  box.triangles.row(1).swap(box.triangles.row(2));
  box.triangles.conservativeResize(3, 13);
  box.triangles.col(12) = box.triangles.col(4);
  const std::string in = OutputPath("repair_in.obj"), out = OutputPath("repair_out.stl");
  spidarcad::modeling::WriteTriangleMesh(box, in);
  const CommandRun run = RunMesh("'" + in + "' --out '" + out + "'", "repair");
  ASSERT_EQ(run.status, 0) << run.all();
  EXPECT_NE(run.out.find("mesh file " + in + ": 8 vertices, 13 triangles"), std::string::npos)
      << run.out;
  EXPECT_NE(run.out.find("repair: 1 repeated triangles dropped"), std::string::npos) << run.out;
  EXPECT_NE(run.out.find("repair: 12 triangles turned over"), std::string::npos) << run.out;
  const TriangleMesh fixed = ReadTriangleMesh(out);
  EXPECT_EQ(fixed.triangles.cols(), 12);
  EXPECT_NEAR(Volume(fixed), 1.0, 1e-6);  // outward again (this file's own volume formula)

  const std::string vtu = OutputPath("repair_out.vtu");
  const CommandRun tets = RunMesh("'" + in + "' --out '" + vtu + "' --tets tetgen", "repair_tets");
  ASSERT_EQ(tets.status, 0) << tets.all();
  EXPECT_GT(PrintedCount(tets.out, "tets"), 0) << tets.out;
  // Options of scene meshing make no sense for a mesh file.
  const CommandRun cgal = RunMesh("'" + in + "' --out '" + vtu + "' --tets cgal", "repair_cgal");
  EXPECT_EQ(cgal.status, 2);
  EXPECT_NE(cgal.err.find("--tets tetgen"), std::string::npos) << cgal.err;
}

TEST(MeshCommand, RefusesAnOpenMeshFileNamingTheFileTheEdgeAndTheTriangle) {
  TriangleMesh box = UnitBox();
  box.triangles.conservativeResize(3, 11);  // the last triangle gone: a hole
  const std::string in = OutputPath("open_in.stl"), out = OutputPath("open_out.vtu");
  spidarcad::modeling::WriteTriangleMesh(box, in);
  std::remove(out.c_str());
  const CommandRun run = RunMesh("'" + in + "' --out '" + out + "' --tets tetgen", "open");
  EXPECT_EQ(run.status, 2) << run.all();
  EXPECT_NE(run.err.find(in + ": the surface is open: 3 edges have one triangle only"),
            std::string::npos)
      << run.err;
  EXPECT_NE(run.err.find("of triangle "), std::string::npos) << run.err;
  EXPECT_NE(run.err.find("Close the holes"), std::string::npos) << run.err;
  EXPECT_FALSE(std::ifstream(out).good());
}

}  // namespace

// The platform's 10 mm plate at 13.5 mm cells on the marching-tetrahedra route: the grid's planes
// leave no value inside most of it, and the surface keeps about a fifth of the solid's volume
// (measured 2026-12-07: -79 %, sharpened -80 %). The command meshes it again on the grid moved by
// a fraction of a cell (the `grid placement` line) and keeps the volume, with or without --sharp.
// At 20 mm cells the lattice loses about a fifth on every placement tried (measured 2026-12-07:
// -18.8 %): the command keeps the first and says so on stderr, with the way out. At the default
// cell nothing is said.
TEST(MeshCommand, VolumeLostBetweenGridPlanesMovesTheGridOrIsWarned) {
  const std::string out = OutputPath("volume_lost.stl");
  // The surface's volume against the solid's, as the command prints it (percent).
  auto percent_off = [](const std::string& printed) {
    const std::size_t end = printed.find(" % from the solid's, sampled");
    const std::size_t begin = printed.rfind('(', end);
    return end == std::string::npos || begin == std::string::npos
               ? 1e9
               : std::stod(printed.substr(begin + 1, end - begin - 1));
  };
  for (const char* route : {"--mesher tetrahedra", "--sharp"}) {
    const CommandRun moved = RunMesh(
        "'" + Platform() + "' --out '" + out + "' " + route + " --resolution 0.0135", "moved");
    EXPECT_EQ(moved.status, 0) << moved.all();
    EXPECT_NE(moved.out.find("grid placement: the first"), std::string::npos) << moved.out;
    // The first placement's volume, as the line prints it.
    const std::size_t first = moved.out.find(" volume ", moved.out.find("grid placement: "));
    ASSERT_NE(first, std::string::npos) << moved.out;
    EXPECT_LT(std::stod(moved.out.substr(first + 8)), -50.0) << moved.out;
    EXPECT_LT(std::abs(percent_off(moved.out)), 5.0) << moved.out;
    EXPECT_EQ(moved.err.find("warning"), std::string::npos) << moved.err;
  }
  const CommandRun lost =
      RunMesh("'" + Platform() + "' --out '" + out + "' --resolution 0.02", "lost");
  EXPECT_EQ(lost.status, 0) << lost.all();
  EXPECT_NE(lost.out.find("4 placements meshed, kept the first"), std::string::npos) << lost.out;
  EXPECT_LT(percent_off(lost.out), -5.0) << lost.out;
  EXPECT_NE(lost.err.find("warning: the mesh holds "), std::string::npos) << lost.err;
  EXPECT_NE(lost.err.find("less volume than the solid"), std::string::npos) << lost.err;
  EXPECT_NE(lost.err.find("no grid placement tried keeps it; a finer --resolution"),
            std::string::npos)
      << lost.err;
  const CommandRun fine = RunMesh("'" + Platform() + "' --out '" + out + "'", "fine");
  EXPECT_EQ(fine.status, 0) << fine.all();
  EXPECT_EQ(fine.out.find("grid placement"), std::string::npos) << fine.out;
  EXPECT_EQ(fine.err, "");
}
