// Issue 15 ("Trust"), its list of inputs a new user tried, one TEST per bullet, run against the
// real `spidarcad` executable as a child process (and, for the last test, the window in this
// process). Each hostile input must end with exit status 2 and a message naming the file and its
// line (or byte offset) and field, or the option; no crash (a signal), no exit status 1, no
// output file. Inputs that are large but legitimate get an estimate before the long work, a
// refusal past the budget naming the option that raises it, and stop on Ctrl+C. Big inputs are
// generated here, not committed. Where an existing test already asserts a case, its name is
// given in a comment and the case is not repeated.
// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later

#include <gtest/gtest.h>
#include <sys/stat.h>

#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <random>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include "doc/assets.h"
#include "doc/document.h"
#include "doc/recent_files.h"
#include "gui/app_window.h"
#include "gui/workbench_panels.h"
#include "scene/scene_model.h"
#include "spidarcad/fem/mesh.h"
#include "spidarcad/modeling/tet_mesh.h"
#include "spidarcad_runner.h"
#include "support/byte_mutator.h"
#include "support/scripted_window.h"
#include "vtk_writer_support.h"

namespace spidarcad::app {
namespace {

using test_support::CommandRun;
using test_support::RunSpidarcad;

std::string OutputPath(const std::string& name) { return test_support::TestOutputPath(name); }

bool FileExists(const std::string& path) { return std::filesystem::exists(path); }

std::string Repeat(const std::string& s, int times) {
  std::string out;
  out.reserve(s.size() * static_cast<size_t>(times));
  for (int i = 0; i < times; ++i) out += s;
  return out;
}

// A scene file (version 1) whose one solid's root is `root`, on line 6; returns its path.
std::string WriteScene(const std::string& name, const std::string& root) {
  const std::string path = OutputPath("hostile_" + name);
  std::ofstream(path) << "{\n  \"format\": \"spidarcad-scene\",\n  \"version\": 1,\n"
                         "  \"solids\": [\n    {\"name\": \"s\", \"root\":\n"
                      << root << "}\n  ]\n}\n";
  return path;
}

// The same solid in a version 2 document (objects), its root on line 6.
std::string WriteDocument(const std::string& name, const std::string& root) {
  const std::string path = OutputPath("hostile_" + name);
  std::ofstream(path) << "{\n  \"format\": \"spidarcad-scene\",\n  \"version\": 2,\n"
                         "  \"objects\": [\n    {\"name\": \"s\", \"kind\": \"solid\", \"root\":\n"
                      << root << "}\n  ]\n}\n";
  return path;
}

// The hostile scene roots of the issue (bullets 1 and 5, §2).
std::string ChainRoot(int depth) {
  return Repeat(R"({"type": "translate", "translation": [0, 0, 0], "children": [)", depth - 1) +
         R"({"type": "sphere", "radius": 0.01})" + Repeat("]}", depth - 1);
}
std::string NestedArrayRoot(int depth) {
  return R"({"type": "sphere", "radius": )" + Repeat("[", depth) + Repeat("]", depth) + "}";
}
const char* kHugeNumberRoot = R"({"type": "sphere", "radius": 1e999})";
const char* kStolKeyRoot =
    R"({"type": "sphere", "radius": 0.1, "children/99999999999999999999": 1})";
const char* kBillionCopiesRoot =
    R"({"type": "polar_array", "count": 1000000000, "children": [{"type": "sphere", "radius": 0.01}]})";

// A union of n spheres of radius 2 mm on a cubic lattice of pitch 5 mm (each under a translate).
std::string UnionRoot(int n) {
  const int side = static_cast<int>(std::ceil(std::cbrt(static_cast<double>(n)) - 1e-9));
  std::string out = R"({"type": "union", "children": [)";
  char item[160];
  for (int i = 0; i < n; ++i) {
    std::snprintf(item, sizeof item,
                  R"(%s{"type": "translate", "translation": [%g, %g, %g], "children": )"
                  R"([{"type": "sphere", "radius": 0.002}]})",
                  i == 0 ? "" : ", ", 0.005 * (i % side), 0.005 * (i / side % side),
                  0.005 * (i / side / side));
    out += item;
  }
  return out + "]}";
}

// A star-shaped extrusion of an n-point profile (radius 5 cm ± 10 %, 2 cm high).
std::string ExtrusionRoot(int n) {
  std::string out = R"({"type": "extrusion", "height": 0.02, "profile": [)";
  char item[96];
  for (int k = 0; k < n; ++k) {
    const double a = 2 * M_PI * k / n, r = 0.05 * (1 + 0.1 * std::cos(7 * a));
    std::snprintf(item, sizeof item, "%s[%.17g, %.17g]", k == 0 ? "" : ", ", r * std::cos(a),
                  r * std::sin(a));
    out += item;
  }
  return out + "]}";
}

// The platform of assets/scenes/platform.json with its bracket's bolt holes (the mirror node
// `bolt_holes`) repeated `count` times about the x axis by a polar_array.
std::string PolarBoltHolesScene(int count) {
  std::ifstream in(std::string(SPIDARCAD_SOURCE_DIR) + "/assets/scenes/platform.json");
  std::stringstream text;
  text << in.rdbuf();
  std::string s = text.str();
  const std::string begin = R"({
            "type": "mirror", "id": "bolt_holes")";
  const size_t at = s.find(begin);
  EXPECT_NE(at, std::string::npos);
  if (at == std::string::npos) return "";
  // The mirror node's closing brace: the first line after it indented as its opening.
  const std::string close = "\n          },\n";
  const size_t end = s.find(close, at);
  EXPECT_NE(end, std::string::npos);
  s.insert(end + 12, "]}");
  s.insert(at, R"({"type": "polar_array", "axis": [1, 0, 0], "count": )" + std::to_string(count) +
                   R"(, "children": [)");
  const std::string path = OutputPath("hostile_polar_bolts_" + std::to_string(count) + ".json");
  std::ofstream(path) << s;
  return path;
}

// Expects exit status 2, every part in stderr, nothing on stdout that claims a result and no
// file at `out`.
void ExpectRefused(const CommandRun& run, const std::string& what,
                   const std::vector<std::string>& parts, const std::string& out = "") {
  EXPECT_EQ(run.status, 2) << what << "\n" << run.all().substr(0, 3000);
  for (const std::string& part : parts) {
    EXPECT_NE(run.err.find(part), std::string::npos)
        << what << ": '" << part << "' not in: " << run.err.substr(0, 3000);
  }
  if (!out.empty()) {
    EXPECT_FALSE(FileExists(out)) << what << ": " << out << " was written";
  }
}

// A mistyped subcommand used to be taken for the window's scene: `spidarcad tune --help`
// printed the main help with status 0, and without --help the window opened to say no document
// file 'tune' exists. It exits 2 naming the word, the subcommands and the nearest one; a scene
// file, 'demo', 'none' and the subcommands themselves are taken as before.
TEST(HostileInput, AMistypedSubcommandExitsTwoNamingTheNearestOne) {
  for (const std::string& args : {std::string("mesj --help"), std::string("mesj x --out y")}) {
    const CommandRun run = RunSpidarcad(args, "", "typo");
    EXPECT_EQ(run.status, 2) << args << "\n" << run.all();
    EXPECT_NE(run.err.find("'mesj' is not a subcommand"), std::string::npos) << run.err;
    EXPECT_NE(run.err.find("did you mean 'mesh'?"), std::string::npos) << run.err;
    EXPECT_NE(run.err.find("fk, ik, tension"), std::string::npos) << run.err;
  }
  const CommandRun far = RunSpidarcad("xyzzyplugh", "", "far");
  EXPECT_EQ(far.status, 2) << far.all();
  EXPECT_EQ(far.err.find("did you mean"), std::string::npos) << far.err;
  for (const std::string& args :
       {std::string("--help"), std::string("demo --help"), std::string("none --help"),
        std::string("mesh --help"),
        "'" + std::string(SPIDARCAD_SOURCE_DIR) + "/assets/scenes/platform.json' --help"}) {
    const CommandRun run = RunSpidarcad(args, "", "known");
    EXPECT_EQ(run.status, 0) << args << "\n" << run.all();
    EXPECT_EQ(run.err.find("is not a subcommand"), std::string::npos) << args << "\n" << run.err;
  }
}

// Bullet 1: "a scene whose tree is a chain of 10,000 nested translate nodes, or whose JSON nests
// an array 100,000 deep, kills `spidarcad mesh` with a segmentation fault". Both files through
// `mesh` are MeshCommand.HostileScenesExitTwoNamingFileLineAndField (status 2, file:line, no
// output). Here: the same files through every other command that reads scenes and documents
// (fem, info, run; as version 1 scenes and version 2 documents) and §2's "a JSON nested ten
// thousand deep" and "a tree of a million nodes".
TEST(HostileInput, DeepTreesAndDeepJsonExitTwoNamingFileLineAndFieldInEveryCommand) {
  struct File {
    std::string path, expected;
  };
  const std::vector<File> files = {
      {WriteScene("chain.json", ChainRoot(10000)), ":6:"},
      {WriteScene("nested100k.json", NestedArrayRoot(100000)), ":6:1026: field /solids/0/root"},
      {WriteScene("nested10k.json", NestedArrayRoot(10000)), ":6:1026: field /solids/0/root"},
      {WriteDocument("chain_v2.json", ChainRoot(10000)), ":6:"},
      {WriteDocument("nested_v2.json", NestedArrayRoot(100000)), ":6:1026: field /objects/0/root"},
  };
  const std::string out = OutputPath("hostile_deep_out.vtu");
  std::remove(out.c_str());
  const std::string trajectory = OutputPath("hostile_deep_press.csv");
  std::ofstream(trajectory) << "0,0.05,0,0,1,0,0,0,1.5\n0.01,0.05,0,0,1,0,0,0,1.5\n";
  for (const File& f : files) {
    for (const std::string& command :
         {"fem '" + f.path + "' --fix=-1,-1,-1,1,1,1 --out '" + out + "'", "info '" + f.path + "'",
          "run '" + f.path + "' --trajectory '" + trajectory + "' --out '" + out + "'"}) {
      const CommandRun run = RunSpidarcad(command, "", "deep");
      ExpectRefused(run, command.substr(0, 200),
                    {f.path + f.expected, "deeper than", "docs/limits.md"}, out);
    }
  }
  // A million nodes (a union of a million spheres, 32 MB): refused at the 500,001st, by name.
  const std::string million =
      WriteScene("million.json", R"({"type": "union", "children": [)" +
                                     Repeat(R"({"type": "sphere", "radius": 0.01}, )", 999999) +
                                     R"({"type": "sphere", "radius": 0.01}]})");
  const std::string mesh_out = OutputPath("hostile_million.stl");
  const CommandRun run = RunSpidarcad("mesh '" + million + "' --out '" + mesh_out + "'", "", "m");
  ExpectRefused(run, "a million nodes",
                {million + ":6:", "field /solids/0/root/children/499999", "more than 500000 nodes"},
                mesh_out);
}

// Bullet 2: "a .vtu whose connectivity names point 1,000,000,000 of 8 kills `spidarcad fem`
// ...; VTK 9.1's XML reader itself crashes on small malformed files (a negative NumberOfCells, a
// cell-data array shorter than the cell count, corrupted binary data): about 3 % of mutated .vtu
// files crash fem." Point 1e9 through `fem` is HardFemInput.HostileInputExitsWithStatusTwoAnd
// NothingWritten; the three malformed files and 540 mutants read in process are
// HardVtu.HostileFilesAreRefusedNamingByteFieldAndValue and HardVtuMutation.ReaderReadsOrRefuses
// EveryMutatedVtkFile. Here the executable itself: the three files through `fem` (status 2,
// file, byte offset, field), then 60 mutants of VTK-written files (seed 15), each of which must
// be solved (status 0, output written) or refused (status 2 naming the file, nothing written).
TEST(HostileInput, MalformedAndMutatedVtuFilesNeverCrashFem) {
  fem::BoxMeshSettings box;
  box.upper = Eigen::Vector3d(0.3, 0.1, 0.05);
  box.nx = 3;
  box.ny = 2;
  box.nz = 1;
  const fem::TetMesh mesh = fem::MakeBoxMesh(box);
  const std::string out = OutputPath("hostile_vtu_out.vtu");
  const std::string solve = " --fix=-1,-1,-1,1e-9,1,1 --load 0.3,0.05,0.05 --force 0,0,-10";
  // A negative cell count, a short cell array, corrupted zlib data.
  modeling::VtuGrid g;
  g.points = mesh.nodes.transpose();
  g.cells = mesh.elements.transpose();
  g.regions = Eigen::VectorXi::Zero(mesh.num_elements());
  Eigen::MatrixXd value = Eigen::MatrixXd::Ones(1, mesh.num_elements());
  g.cell_data["value"] = value;
  const std::string ascii_path = OutputPath("hostile_vtu_ascii.vtu");
  modeling::WriteVtuGrid(g, ascii_path, modeling::VtuEncoding::kAscii);
  std::stringstream text;
  text << std::ifstream(ascii_path).rdbuf();
  const std::string ascii = text.str();
  const std::string zlib =
      WriteWithVtk(mesh, {1, false, true, false, false}, OutputPath("hostile_vtu_zlib.vtu"));
  struct Case {
    std::string name, bytes;
    std::vector<std::string> expected;
  };
  auto replaced = [](std::string s, const std::string& from, const std::string& to) {
    const size_t at = s.find(from);
    EXPECT_NE(at, std::string::npos) << from;
    if (at != std::string::npos) s.replace(at, from.size(), to);
    return s;
  };
  const std::string cells = "NumberOfCells=\"" + std::to_string(mesh.num_elements()) + "\"";
  std::string corrupt = zlib;
  const size_t payload = corrupt.find('>', corrupt.find("format=\"binary\"")) + 30;
  corrupt[payload] = corrupt[payload] == 'A' ? 'B' : 'A';
  std::string short_array = ascii;
  {
    // Drop the last value of the "value" cell array.
    const size_t name = short_array.find("Name=\"value\"");
    const size_t close = short_array.find("</DataArray>", name);
    const size_t last = short_array.rfind(" 1", close);
    short_array.erase(last, 2);
  }
  const std::vector<Case> cases = {
      {"negative_cells",
       replaced(ascii, cells, "NumberOfCells=\"-1\""),
       {"byte ", "NumberOfCells", "-1"}},
      {"short_cell_array", short_array, {"byte ", "Name=\"value\"", "values, expected"}},
      {"corrupt_zlib", corrupt, {"byte "}},
  };
  for (const Case& c : cases) {
    const std::string path = OutputPath("hostile_vtu_" + c.name + ".vtu");
    std::ofstream(path, std::ios::binary) << c.bytes;
    std::remove(out.c_str());
    std::vector<std::string> parts = c.expected;
    parts.push_back(path);
    ExpectRefused(RunSpidarcad("fem '" + path + "'" + solve + " --out '" + out + "'", "", c.name),
                  c.name, parts, out);
  }
  // Mutants of three VTK encodings (ascii, inline base64 with zlib, appended raw).
  std::vector<std::string> seeds = {
      WriteWithVtk(mesh, {0, false, false, false, false}, OutputPath("hostile_seed_ascii.vtu")),
      zlib,
      WriteWithVtk(mesh, {2, false, false, true, false}, OutputPath("hostile_seed_appended.vtu"))};
  std::mt19937 rng(15);
  int solved = 0, refused = 0, other = 0;
  for (int m = 0; m < 60; ++m) {
    const std::string path = OutputPath("hostile_mutant.vtu");
    std::ofstream(path, std::ios::binary)
        << test_support::MutateBytes(seeds[m % seeds.size()], rng, 3, 16);
    std::remove(out.c_str());
    const CommandRun run =
        RunSpidarcad("fem '" + path + "'" + solve + " --out '" + out + "'", "", "mutant");
    if (run.status == 0 && FileExists(out)) {
      ++solved;
    } else if (run.status == 2 && run.err.find(path) != std::string::npos && !FileExists(out)) {
      ++refused;
    } else {
      ++other;
      ADD_FAILURE() << "mutant " << m << ": status " << run.status << "\n"
                    << run.err.substr(0, 2000);
    }
  }
  std::printf("60 mutated .vtu files through spidarcad fem: %d solved, %d refused, %d other\n",
              solved, refused, other);
  EXPECT_EQ(other, 0);
  EXPECT_GT(refused, 0);
  RecordProperty("figure", std::to_string(solved) + " solved, " + std::to_string(refused) +
                               " refused (status 2), " + std::to_string(other) +
                               " crashes of 60 mutants");
}

// Bullet 3: "a --fix box that clamps every node crashes the solver, and --resolution 5e-324
// recurses until the stack overflows". --fix over a whole .vtu is HardFemInput.HostileInput
// ExitsWithStatusTwoAndNothingWritten; --resolution 5e-324 and 1e-6 through `mesh` are
// MeshCommand.AbsurdResolutionsAreRefusedWithTheGridEstimate. Here `fem` on a scene: both
// resolutions, and a --fix box around the whole meshed solid.
TEST(HostileInput, ClampingEveryNodeOrAnAbsurdResolutionExitsTwo) {
  const std::string platform = std::string(SPIDARCAD_SOURCE_DIR) + "/assets/scenes/platform.json";
  const std::string out = OutputPath("hostile_fem_scene.vtu");
  std::remove(out.c_str());
  const std::string push = " --fix=-1,-1,-1,0.0005,1,1 --push 0.29,0,0.01 --disp 0,0,-0.001";
  for (const char* resolution : {"5e-324", "1e-06"}) {
    const CommandRun run = RunSpidarcad(
        "fem '" + platform + "' --resolution " + resolution + push + " --out '" + out + "'", "",
        "resolution");
    ExpectRefused(run, resolution,
                  {std::string("--resolution ") + resolution, platform, "grid cells",
                   "use a coarser --resolution"},
                  out);
  }
  const CommandRun all = RunSpidarcad(
      "fem '" + platform + "' --resolution 0.02 --fix=-1,-1,-1,1,1,1 --out '" + out + "'", "",
      "clamp_all");
  ExpectRefused(all, "--fix around everything", {"--fix", "clamp all"}, out);
}

// Bullet 4: "some bad input is accepted silently: a connectivity index of 2^32+4 is truncated
// to 4 and solved; a region of nan is cast to an integer; --disp 0,0,-1e300 reports "converged":
// true with every result null; a trajectory from 0 to 1e300 s reports -9223372036854775807
// ticks". The first three through `fem` are HardFemInput.HostileInputExitsWithStatusTwoAnd
// NothingWritten, the trajectory through `run` is RunCommand.TrajectoryLongerThanTheLimitExits
// TwoNamingLineAndField and through the window SpidarcadWindow.RefusesATrajectoryItCouldNotPlay
// WithStatusTwo. Here the same kinds of number where other inputs take them: a load of 1e300 N,
// an index of 2^32+4 in TetGen's .ele (import), a trajectory time of 1e999 and of nan, and a
// trajectory from 0 to 1e300 s asked of `trajectory`-made runs through --max-duration.
TEST(HostileInput, ValuesOnceAcceptedSilentlyAreRefusedWhereverTheyAreRead) {
  const std::string out = OutputPath("hostile_values_out.vtu");
  std::remove(out.c_str());
  fem::BoxMeshSettings box;
  box.upper = Eigen::Vector3d(0.3, 0.1, 0.05);
  const std::string beam = OutputPath("hostile_values_beam.vtu");
  modeling::VtuGrid g;
  const fem::TetMesh mesh = fem::MakeBoxMesh(box);
  g.points = mesh.nodes.transpose();
  g.cells = mesh.elements.transpose();
  modeling::WriteVtuGrid(g, beam);
  const CommandRun force = RunSpidarcad(
      "fem '" + beam + "' --fix=-1,-1,-1,1e-9,1,1 --load 0.3,0.05,0.05 --force 0,0,1e300 --out '" +
          out + "'",
      "", "force");
  ExpectRefused(force, "--force 1e300", {"--force #1 '0,0,1e300'", "not finite"}, out);

  const std::string node = OutputPath("hostile_wrap.node"), ele = OutputPath("hostile_wrap.ele");
  std::ofstream(node) << "5 3 0 0\n0 0 0 0\n1 1 0 0\n2 0 1 0\n3 0 0 1\n4 1 1 1\n";
  std::ofstream(ele) << "1 4 0\n0 0 1 2 4294967300\n";
  const std::string doc = OutputPath("hostile_wrap_doc.json");
  std::remove(doc.c_str());
  const CommandRun wrap =
      RunSpidarcad("import '" + node + "' --into '" + doc + "'", "", "import_wrap");
  ExpectRefused(wrap, ".ele index 2^32+4", {"hostile_wrap.ele:2", "4294967300"}, doc);

  const std::string result = OutputPath("hostile_values_run.csv");
  std::remove(result.c_str());
  for (const char* t : {"1e999", "nan"}) {
    const std::string path = OutputPath(std::string("hostile_t_") + t + ".csv");
    std::ofstream(path) << "0,0.05,0,0,1,0,0,0,1.5\n" << t << ",0.05,0,0,1,0,0,0,1.5\n";
    const CommandRun run =
        RunSpidarcad("run demo --trajectory '" + path + "' --out '" + result + "'", "", "time");
    ExpectRefused(run, t, {path + ":2", "'t'", t}, result);
  }
}

// Bullet 5: "a number like 1e999 gives `spidarcad: error: [json.exception.out_of_range.406]
// number overflow parsing '1e999'` with exit status 1 and no file, line or field; a key like
// "children/99999999999999999999" gives `spidarcad: error: stol`, status 1; reading /dev/zero as
// a scene, `calibrate --simulated --poses 2000000000` and `device selftest --ticks 2000000000`
// end in a bare std::bad_alloc, status 1". `mesh` on the two scenes and on /dev/zero is
// MeshCommand.HostileScenesExitTwoNamingFileLineAndField and MeshCommand.DeviceOrDirectoryAs
// TheSceneIsRefusedBeforeReading; --poses is CalibrateCommand.BadInputExitsWithStatus2, --ticks
// DeviceCommand.SelftestRefusesMoreTicksThanItsLimitNamingTheRange. Here every other reader:
// `info` and `fem` on scenes and version 2 documents, a calibration file with 1e999, and
// /dev/zero or a pipe wherever a file is read (info, run, fem, --calibration, import).
TEST(HostileInput, LibraryErrorsBecomeMessagesNamingFileLineAndFieldInEveryReader) {
  const std::string out = OutputPath("hostile_library_out.vtu");
  std::remove(out.c_str());
  struct File {
    std::string path, expected;
  };
  const std::vector<File> files = {
      {WriteScene("huge.json", kHugeNumberRoot), ":6:30: field /solids/0/root/radius: "},
      {WriteScene("stol.json", kStolKeyRoot),
       ":6:68: field /solids/0/root/children~199999999999999999999"},
      {WriteDocument("huge_v2.json", kHugeNumberRoot), ":6:30: field /objects/0/root/radius: "},
      {WriteDocument("stol_v2.json", kStolKeyRoot),
       ":6:68: field /objects/0/root/children~199999999999999999999"},
      {WriteDocument("billion_v2.json", kBillionCopiesRoot), ":6:34: field /objects/0/root/count"},
  };
  for (const File& f : files) {
    for (const std::string& command :
         {"info '" + f.path + "'", "fem '" + f.path + "' --fix=-1,-1,-1,1,1,1 --out '" + out + "'",
          "mesh '" + f.path + "' --tets tetgen --out '" + out + "'"}) {
      ExpectRefused(RunSpidarcad(command, "", "library"), command, {f.path + f.expected}, out);
    }
  }
  // A calibration file with a number beyond a double.
  const std::string calibration = OutputPath("hostile_calibration.json");
  std::ofstream(calibration) << "{\"format\": \"spidarcad-calibration\", \"version\": 1e999}\n";
  const std::string trajectory = OutputPath("hostile_library_press.csv");
  std::ofstream(trajectory) << "0,0.05,0,0,1,0,0,0,1.5\n0.01,0.05,0,0,1,0,0,0,1.5\n";
  const std::string csv = OutputPath("hostile_library_run.csv");
  std::remove(csv.c_str());
  ExpectRefused(RunSpidarcad("run demo --calibration '" + calibration + "' --trajectory '" +
                                 trajectory + "' --out '" + csv + "'",
                             "", "calibration"),
                "calibration 1e999", {calibration + ":1:", "field /version", "1e999"}, csv);
  // Devices and pipes, each refused before a byte is read (they could be read forever).
  const std::string fifo = OutputPath("hostile_fifo.json");
  std::remove(fifo.c_str());
  ASSERT_EQ(mkfifo(fifo.c_str(), 0600), 0);
  for (const std::string& path : {std::string("/dev/zero"), fifo}) {
    for (const std::string& command :
         {"info '" + path + "'",
          "run '" + path + "' --trajectory '" + trajectory + "' --out '" + csv + "'",
          "run demo --calibration '" + path + "' --trajectory '" + trajectory + "' --out '" + csv +
              "'"}) {
      // `timeout`: a reader that blocks on the pipe would otherwise hang the test.
      ExpectRefused(RunSpidarcad(command, "", "device", "timeout 60"), command,
                    {path, "not a regular file"}, csv);
    }
  }
  std::remove(fifo.c_str());
}

// Bullet 6: "`spidarcad ik --batch` given a line with inf coordinates prints inf lengths instead
// of refusing the line as it refuses other bad lines." That is IkCommand.RefusesInfiniteAndNan
// CoordinatesLikeOtherBadLines. Here the two other batch commands given the same kind of line:
// `fk --batch` and `tension --batch` answer it with nan and name its line and column on stderr,
// as ik does, and go on with the next line.
TEST(HostileInput, EveryBatchCommandRefusesAnInfiniteLineNamingItAndGoesOn) {
  const std::string rest =
      "0.3939543,0.3939543,0.3939543,0.3939543,0.3939543,0.3939543,"
      "0.3939543,0.3939543";
  const CommandRun fk = RunSpidarcad(
      "fk --batch --no-header",
      rest + "\ninf,0.3939543,0.3939543,0.3939543,0.3939543,0.3939543,0.3939543,0.3939543\n" +
          "0.3939543,-inf,0.3939543,0.3939543,0.3939543,0.3939543,0.3939543,0.3939543\n" + rest +
          "\n",
      "fk");
  EXPECT_EQ(fk.status, 0) << fk.all();
  EXPECT_NE(fk.err.find("<stdin>:2: column 1 (l1): inf"), std::string::npos) << fk.err;
  EXPECT_NE(fk.err.find("<stdin>:3: column 2 (l2): -inf"), std::string::npos) << fk.err;
  EXPECT_EQ(fk.err.find("<stdin>:1:"), std::string::npos) << fk.err;
  std::vector<std::string> rows;
  std::istringstream lines(fk.out);
  for (std::string line; std::getline(lines, line);) rows.push_back(line);
  ASSERT_EQ(rows.size(), 4u) << fk.out;
  EXPECT_EQ(rows[0], rows[3]);
  for (int k : {1, 2})
    EXPECT_EQ(rows[k], "nan,nan,nan,nan,nan,nan,nan,nan,nan,nan,nan,invalid_input") << k;

  const std::string pose = "0,0,0,0,0.04,0,0.04,0,0,";
  const CommandRun tension = RunSpidarcad(
      "tension --batch",
      pose + "0,0,0,0,0,0,0\n" + pose + "inf,0,0,0,0,0,0\n" + pose + "0,0,0,0,0,0,0\n", "tension");
  EXPECT_EQ(tension.status, 0) << tension.all();
  EXPECT_NE(tension.err.find("<stdin>:2: column 10: inf is not finite"), std::string::npos)
      << tension.err;
  std::vector<std::string> t;
  std::istringstream tlines(tension.out);
  for (std::string line; std::getline(tlines, line);)
    if (!line.empty() && line[0] != '#') t.push_back(line);
  ASSERT_EQ(t.size(), 3u) << tension.out;
  EXPECT_EQ(t[0], t[2]);
  EXPECT_EQ(t[1], "nan,nan,nan,nan,nan,nan,nan,nan,nan");
}

// Bullet 7: "`spidarcad mesh assets/scenes/platform.json --resolution 1e-6` runs on with no
// estimate; unions of 10,000 to 100,000 primitives, a polar_array of 1,000 copies of the bolt
// holes, and extrusions with 10,000-point profiles each take longer than 20 s with no estimate,
// no progress and no way to stop but killing the process." --resolution 1e-6 is MeshCommand.
// AbsurdResolutionsAreRefusedWithTheGridEstimate. Here the four large solids: each gets its
// estimate (its work counting the cost of one evaluation: 10,000 for the profile's points), a
// refusal past a budget that names the estimate and the option that raises it, and, meshed,
// stops on the first Ctrl+C with status 130 and no output once the surface stage has begun.
// How long each takes in full is measured in docs/limits.md.
TEST(HostileInput, LargeSolidsGetAnEstimateFirstARefusalPastTheBudgetAndStopOnCtrlC) {
  struct Case {
    std::string name, path, cost;
  };
  const std::vector<Case> cases = {
      {"union 10,000", WriteScene("union10k.json", UnionRoot(10000)), "tape 19999 instructions"},
      {"union 100,000", WriteScene("union100k.json", UnionRoot(100000)),
       "tape 199999 instructions"},
      {"polar_array of 1,000 bolt hole sets", PolarBoltHolesScene(1000), "tape 8009 instructions"},
      {"extrusion of 10,000 points", WriteScene("extrusion10k.json", ExtrusionRoot(10000)),
       "tape 1 instructions (cost 1e+04 each)"},
  };
  const std::string out = OutputPath("hostile_large.stl");
  for (const Case& c : cases) {
    std::remove(out.c_str());
    const CommandRun budget =
        RunSpidarcad("mesh '" + c.path + "' --out '" + out + "' --max-work 1000", "", "budget");
    ExpectRefused(budget, c.name,
                  {"estimated work", "is over --max-work 1000", "estimate: grid ", c.cost,
                   "raise the limit with --max-work"},
                  out);
    const CommandRun run = test_support::InterruptOnceShown(
        "'" + std::string(SPIDARCAD_EXE) + "' mesh '" + c.path + "' --out '" + out + "' --progress",
        OutputPath("hostile_ctrl_c.err"), "mesh: surface", OutputPath("hostile_ctrl_c_run"));
    const std::string& err = run.err;
    EXPECT_NE(run.out.find("status=130"), std::string::npos) << c.name << "\n" << run.all() << err;
    EXPECT_NE(err.find("spidarcad mesh: estimate: grid "), std::string::npos) << c.name << err;
    EXPECT_LT(err.find("estimate: grid "), err.find("mesh: surface")) << c.name << err;
    EXPECT_NE(err.find(c.cost), std::string::npos) << c.name << err;
    EXPECT_NE(err.find("interrupted (Ctrl+C): stopped, nothing written"), std::string::npos)
        << c.name << err;
    EXPECT_FALSE(FileExists(out)) << c.name;
  }
  // A Ctrl+C during the box search before the estimate (about 6 s for the union of 100,000
  // spheres) ends the run there: no estimate is printed, nothing is written.
  const CommandRun box = test_support::InterruptOnceShown(
      "'" + std::string(SPIDARCAD_EXE) + "' mesh '" + cases[1].path + "' --out '" + out +
          "' --progress",
      OutputPath("hostile_ctrl_c.err"), "box: finding where", OutputPath("hostile_ctrl_c_box"));
  EXPECT_NE(box.out.find("status=130"), std::string::npos) << box.all() << box.err;
  EXPECT_NE(box.err.find("interrupted (Ctrl+C): stopped, nothing written"), std::string::npos)
      << box.err;
  EXPECT_EQ(box.err.find("estimate:"), std::string::npos) << box.err;
  EXPECT_FALSE(FileExists(out));
}

// The window: opening each hostile file of the issue (File > Open, drop, the recent list all
// call OpenDocument) shows the error naming the file, the line and the field and leaves the open
// document as it was; so does /dev/zero (which the window used to read forever) and a pipe.
TEST(HostileInputWindow, OpeningAHostileFileShowsTheErrorAndKeepsTheDocument) {
  if (!test_support::HaveDisplay()) GTEST_SKIP() << "no X display: run under xvfb-run";
  const test_support::WindowScratch scratch("hostile_window");
  const std::string fifo = (scratch.dir / "pipe.json").string();
  ASSERT_EQ(mkfifo(fifo.c_str(), 0600), 0);
  struct File {
    std::string path;
    std::vector<std::string> expected;
  };
  const std::vector<File> files = {
      {WriteScene("w_chain.json", ChainRoot(10000)), {":6:", "field /solids/0/root", "deeper"}},
      {WriteScene("w_nested.json", NestedArrayRoot(100000)), {":6:1026: field /solids/0/root"}},
      {WriteScene("w_huge.json", kHugeNumberRoot), {":6:30: field /solids/0/root/radius"}},
      {WriteScene("w_stol.json", kStolKeyRoot), {":6:68: field /solids/0/root/children~1"}},
      {WriteScene("w_billion.json", kBillionCopiesRoot), {":6:34: field /solids/0/root/count"}},
      {WriteDocument("w_huge_v2.json", kHugeNumberRoot), {":6:30: field /objects/0/root/radius"}},
      {"/dev/zero", {"not a regular file"}},
      {fifo, {"not a regular file"}},
  };
  AppWindow window(test_support::ScriptedWindowOptions(kDemoSceneName));
  window.Frame();
  const nlohmann::json before = window.model().document().ToJson();
  for (const File& f : files) {
    EXPECT_FALSE(window.OpenDocument(f.path)) << f.path;
    EXPECT_NE(window.file_error().find(f.path), std::string::npos) << window.file_error();
    for (const std::string& part : f.expected) {
      EXPECT_NE(window.file_error().find(part), std::string::npos)
          << "'" << part << "' not in: " << window.file_error().substr(0, 2000);
    }
    EXPECT_EQ(window.model().document().ToJson(), before) << f.path;
    EXPECT_EQ(window.model().source(), kDemoSceneName);
    for (int k = 0; k < 2; ++k) window.Frame();  // the error is drawn; the window goes on
  }
  EXPECT_TRUE(window.recent().paths().empty());
}

// Opening the union of 100,000 spheres reads the 11 MB file (twice: once for its parts), compiles
// the tree and searches for its box: 5 s or more on two cores. The window reads it on a thread
// of its own and draws frames meanwhile; its Cancel (here CancelOpen, which the button, Esc and
// the close button also raise, called from another thread while OpenDocument runs) returns at
// once, and the reading thread ends on its own at its next look at the flag (joined when the
// window goes). The open document, its source and the recent list are as they were, no error is
// shown, the status says the open was cancelled, and the next open is not cancelled. How long
// OpenDocument took to return after the cancel is recorded (property "cancel_seconds"); the
// issue's 0.5 s is not asserted (timing).
TEST(HostileInputWindow, OpeningAHugeUnionCanBeCancelledAndKeepsTheDocument) {
  using namespace std::chrono_literals;
  if (!test_support::HaveDisplay()) GTEST_SKIP() << "no X display: run under xvfb-run";
  const test_support::WindowScratch scratch("hostile_window_cancel");
  const std::string path = WriteScene("w_union100k.json", UnionRoot(100000));
  AppWindow window(test_support::ScriptedWindowOptions(kDemoSceneName));
  window.Frame();
  const nlohmann::json before = window.model().document().ToJson();
  std::atomic<bool> stop{false};
  std::atomic<long long> cancelled_at{0};
  std::thread canceller([&] {
    // Wait until the open is under way and past the file's reading (1.5 s), then cancel.
    while (!stop.load() && !window.opening()) std::this_thread::sleep_for(1ms);
    std::this_thread::sleep_for(1500ms);
    cancelled_at.store(std::chrono::steady_clock::now().time_since_epoch().count());
    window.CancelOpen();
  });
  const bool opened = window.OpenDocument(path);
  const auto returned = std::chrono::steady_clock::now().time_since_epoch().count();
  stop.store(true);
  canceller.join();
  const double cancel_seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::duration(returned - cancelled_at))
          .count();
  RecordProperty("cancel_seconds", std::to_string(cancel_seconds));
  EXPECT_FALSE(opened) << "the open ran to its end: it was not cancelled";
  EXPECT_EQ(window.file_error(), "");
  EXPECT_NE(window.workbench().status.find("cancelled (the document is unchanged)"),
            std::string::npos)
      << window.workbench().status;
  EXPECT_EQ(window.model().document().ToJson(), before);
  EXPECT_EQ(window.model().source(), kDemoSceneName);
  EXPECT_TRUE(window.recent().paths().empty());
  for (int k = 0; k < 2; ++k) EXPECT_TRUE(window.Frame());  // the window goes on
  // The next open is not cancelled by the last one's flag.
  EXPECT_TRUE(window.OpenDocument(AssetPath("scenes/platform.json"))) << window.file_error();
}

// The start-up document is read as File → Open reads one: on a thread of its own while the
// window draws the "Opening" box. The union of 100,000 spheres (seconds to read, compile and
// box) is cancelled 1.5 s after the window began (GuiOptions::cancel_open, what the box's
// Cancel, Esc and the close button raise): the window starts on an empty document, the status
// says so, and the next open works once the flag is down. Without the off-thread read the
// constructor would run the whole read and open the union. The time from the cancel until the
// constructor returned is recorded (property "cancel_seconds"), not asserted.
TEST(HostileInputWindow, AHugeStartUpDocumentCanBeCancelledForAnEmptyOne) {
  using namespace std::chrono_literals;
  if (!test_support::HaveDisplay()) GTEST_SKIP() << "no X display: run under xvfb-run";
  const test_support::WindowScratch scratch("hostile_window_startup_cancel");
  const std::string path = WriteScene("w_startup100k.json", UnionRoot(100000));
  std::atomic<bool> cancel{false};
  std::atomic<long long> cancelled_at{0};
  std::atomic<bool> stop{false};
  std::thread canceller([&] {
    for (int k = 0; k < 1500 && !stop.load(); ++k) std::this_thread::sleep_for(1ms);
    cancelled_at.store(std::chrono::steady_clock::now().time_since_epoch().count());
    cancel.store(true);
  });
  app::GuiOptions options = test_support::ScriptedWindowOptions(path);
  options.cancel_open = &cancel;
  AppWindow window(options);
  const auto returned = std::chrono::steady_clock::now().time_since_epoch().count();
  stop.store(true);
  canceller.join();
  ASSERT_TRUE(cancel.load());
  RecordProperty("cancel_seconds",
                 std::to_string(std::chrono::duration<double>(
                                    std::chrono::steady_clock::duration(returned - cancelled_at))
                                    .count()));
  EXPECT_EQ(window.model().source(), kNoSceneName) << "the union was opened: not cancelled";
  EXPECT_TRUE(window.model().objects().empty());
  EXPECT_NE(window.workbench().status.find("cancelled (an empty document instead)"),
            std::string::npos)
      << window.workbench().status;
  EXPECT_EQ(window.file_error(), "");
  for (int k = 0; k < 2; ++k) EXPECT_TRUE(window.Frame());  // the window goes on
  cancel.store(false);
  EXPECT_TRUE(window.OpenDocument(AssetPath("scenes/platform.json"))) << window.file_error();
}

// A scene file changed on disk is read again as File → Open reads one (off the main thread,
// cancellable). Here the change is a union of 10,000 spheres (about 2 s to read and box) and
// the reload is cancelled: the window keeps the old scene and does not read the file again
// until it changes again; the next change, with the flag down, is reloaded and adopted.
TEST(HostileInputWindow, AReloadAfterAnOutsideChangeCanBeCancelledAndWaitsForTheNextChange) {
  if (!test_support::HaveDisplay()) GTEST_SKIP() << "no X display: run under xvfb-run";
  const test_support::WindowScratch scratch("hostile_window_reload");
  const std::string path = WriteScene("w_reload.json", UnionRoot(2));
  std::atomic<bool> cancel{false};
  app::GuiOptions options = test_support::ScriptedWindowOptions(path);
  options.cancel_open = &cancel;
  AppWindow window(options);
  window.Frame();
  const nlohmann::json before = window.model().document().ToJson();
  // Rewrites the file with `root`, its modification time moved on by `seconds`.
  const auto rewrite = [&path](const std::string& root, int seconds) {
    const auto mtime = std::filesystem::last_write_time(path);
    WriteScene("w_reload.json", root);
    std::filesystem::last_write_time(path, mtime + std::chrono::seconds(seconds));
  };
  // Frames past two of the window's checks of the file (every 30 frames).
  const auto frames = [&window] {
    for (int k = 0; k < 61; ++k) ASSERT_TRUE(window.Frame());
  };
  cancel.store(true);
  rewrite(UnionRoot(10000), 5);
  frames();
  EXPECT_EQ(window.model().document().ToJson(), before) << "the cancelled reload was adopted";
  cancel.store(false);
  frames();  // not read again: the file has not changed since
  EXPECT_EQ(window.model().document().ToJson(), before) << "read again without a change";
  rewrite(UnionRoot(3), 10);
  frames();
  EXPECT_NE(window.model().document().ToJson(), before) << window.workbench().status;
  EXPECT_EQ(window.model().source(), path);
}

}  // namespace
}  // namespace spidarcad::app
