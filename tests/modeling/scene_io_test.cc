// Tests of the JSON scene format: the shipped scenes load, save/load round trips, and bad files
// give errors naming file, line, column and field.
// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#include "spidarcad/modeling/scene_io.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <sys/stat.h>

#include <filesystem>
#include <fstream>
#include <random>

#include "spidarcad/modeling/implicit_evaluator.h"

namespace spidarcad::modeling {
namespace {

using ::testing::HasSubstr;

const std::string kScenes = std::string(SPIDARCAD_SOURCE_DIR) + "/assets/scenes/";
const std::string kOut = std::string(SPIDARCAD_TEST_OUTPUT_DIR) + "/";

// Writes text to a file in the test output directory and returns its path.
std::string WriteFile(const std::string& name, const std::string& text) {
  const std::string path = kOut + name;
  std::ofstream(path) << text;
  return path;
}

// Loads path and returns the SceneError (fails the test when there is none).
SceneError LoadError(const std::string& path) {
  try {
    LoadScene(path);
  } catch (const SceneError& e) {
    return e;
  }
  ADD_FAILURE() << "no SceneError for " << path;
  return SceneError("", 0, 0, "", "");
}

const Solid& FindSolid(const Scene& scene, const std::string& name) {
  for (const Solid& s : scene.solids) {
    if (s.name == name) return s;
  }
  throw std::runtime_error("no solid " + name);
}

TEST(SceneIo, PlatformLoadsWithTheFig7Parts) {
  const Scene scene = LoadScene(kScenes + "platform.json");
  ASSERT_EQ(scene.solids.size(), 2u);
  const CompiledSolid platform = CompiledSolid::Compile(FindSolid(scene, "platform").root);
  const CompiledSolid wall = CompiledSolid::Compile(FindSolid(scene, "wall").root);
  // Plate 0.3 x 0.2 x 0.01 m: inside at mid-thickness, 5 mm half-thickness.
  EXPECT_NEAR(platform.Value(Eigen::Vector3d(0.15, 0.0, 0.005)), -0.005, 1e-9);
  EXPECT_GT(platform.Value(Eigen::Vector3d(0.15, 0.0, 0.02)), 0.0);
  EXPECT_GT(platform.Value(Eigen::Vector3d(0.31, 0.0, 0.005)), 0.0);
  EXPECT_LT(platform.Value(Eigen::Vector3d(0.29, 0.09, 0.005)), 0.0);
  // Bracket against the wall face x = 0, reaching down to z = -0.15.
  EXPECT_LT(platform.Value(Eigen::Vector3d(0.005, 0.0, -0.14)), 0.0);
  EXPECT_GT(platform.Value(Eigen::Vector3d(0.005, 0.0, -0.16)), 0.0);
  // Gusset under the plate in the plane y = 0.
  EXPECT_LT(platform.Value(Eigen::Vector3d(0.05, 0.0, -0.03)), 0.0);
  EXPECT_GT(platform.Value(Eigen::Vector3d(0.05, 0.02, -0.03)), 0.0);
  // Four bolt holes through the bracket, mirrored in y, and two load holes in the plate.
  for (double y : {-0.065, 0.065}) {
    for (double z : {-0.035, -0.115})
      EXPECT_GT(platform.Value(Eigen::Vector3d(0.005, y, z)), 0.0) << y << " " << z;
    EXPECT_GT(platform.Value(Eigen::Vector3d(0.27, y > 0 ? 0.06 : -0.06, 0.005)), 0.0);
  }
  EXPECT_LT(platform.Value(Eigen::Vector3d(0.005, 0.0, -0.035)), 0.0);
  // The wall's face is the plane x = 0.
  EXPECT_NEAR(wall.Value(Eigen::Vector3d(0.0, 0.0, 0.0)), 0.0, 1e-12);
  EXPECT_LT(wall.Value(Eigen::Vector3d(-0.01, 0.0, 0.0)), 0.0);
}

TEST(SceneIo, ClayLoadsAsOneBlob) {
  const Scene scene = LoadScene(kScenes + "clay.json");
  ASSERT_EQ(scene.solids.size(), 1u);
  const CompiledSolid clay = CompiledSolid::Compile(scene.solids[0].root);
  EXPECT_LT(clay.Value(Eigen::Vector3d::Zero()), -0.05);
  EXPECT_GT(clay.Value(Eigen::Vector3d(0.3, 0, 0)), 0.0);
}

TEST(SceneIo, SaveThenLoadRestoresTheScene) {
  for (const char* name : {"platform.json", "clay.json"}) {
    const Scene scene = LoadScene(kScenes + name);
    const std::string path = kOut + "round_trip_" + name;
    SaveScene(scene, path);
    const Scene again = LoadScene(path);
    EXPECT_EQ(SceneToJson(again), SceneToJson(scene));
    EXPECT_EQ(again.description, scene.description);
    ASSERT_EQ(again.solids.size(), scene.solids.size());
    std::mt19937 rng(21);
    std::uniform_real_distribution<double> u(-0.2, 0.35);
    for (size_t s = 0; s < scene.solids.size(); ++s) {
      EXPECT_EQ(again.solids[s].name, scene.solids[s].name);
      for (int i = 0; i < 200; ++i) {
        const Eigen::Vector3d p(u(rng), u(rng), u(rng));
        // Bit-identical: numbers are written in shortest round-trip form.
        ASSERT_EQ(EvaluateTree(again.solids[s].root, p), EvaluateTree(scene.solids[s].root, p));
      }
    }
    EXPECT_FALSE(std::filesystem::exists(path + ".tmp"));
  }
}

TEST(SceneIo, EveryNodeTypeRoundTrips) {
  // One node of each type, with non-default values in every field.
  ExtrusionParams extrusion;
  extrusion.profile = {{0, 0}, {0.1, 0.01}, {0.02, 0.07}};
  extrusion.height = 0.021;
  MirrorParams mirror;
  mirror.normal = Eigen::Vector3d(0.1, 0.2, 0.3);
  mirror.offset = 0.01;
  mirror.keep_original = true;
  LinearArrayParams line;
  line.step = Eigen::Vector3d(0.01, 0.02, 0.03);
  line.count = 3;
  PolarArrayParams ring;
  ring.axis = Eigen::Vector3d(1, 1, 0);
  ring.count = 5;
  ring.step_angle = 0.3;
  const ImplicitNode s(SphereParams{0.1 / 3});
  std::vector<ImplicitNode> all = {
      s,
      ImplicitNode(BoxParams{Eigen::Vector3d(0.1, 0.2, 0.3)}),
      ImplicitNode(RoundedBoxParams{Eigen::Vector3d(0.1, 0.2, 0.3), 0.01}),
      ImplicitNode(CylinderParams{0.01, 0.02}),
      ImplicitNode(CapsuleParams{Eigen::Vector3d(1, 2, 3), Eigen::Vector3d(4, 5, 6), 0.5}),
      ImplicitNode(ConeParams{0.1, 0.2, 0.3}),
      ImplicitNode(TorusParams{0.2, 0.1}),
      ImplicitNode(HalfSpaceParams{Eigen::Vector3d(0, 1, 1), 0.2}),
      ImplicitNode(extrusion),
      ImplicitNode(UnionParams{}, {s}),
      ImplicitNode(IntersectionParams{}, {s}),
      ImplicitNode(DifferenceParams{}, {s, s}),
      ImplicitNode(SmoothUnionParams{0.01}, {s}),
      ImplicitNode(SmoothIntersectionParams{0.02}, {s}),
      ImplicitNode(SmoothDifferenceParams{0.03}, {s, s}),
      ImplicitNode(OffsetParams{-0.01}, {s}),
      ImplicitNode(ShellParams{0.002}, {s}),
      ImplicitNode(TranslateParams{Eigen::Vector3d(1, 2, 3)}, {s}),
      ImplicitNode(RotateParams{Eigen::Vector3d(0, 1, 0), 0.7}, {s}),
      ImplicitNode(ScaleParams{Eigen::Vector3d(1, 2, 3)}, {s}),
      ImplicitNode(mirror, {s}),
      ImplicitNode(line, {s}),
      ImplicitNode(ring, {s})};
  ASSERT_EQ(all.size(), std::variant_size_v<NodeParams>);
  ImplicitNode root(UnionParams{}, all, "root");
  root.name = "All \"types\"";
  const ImplicitNode again = NodeFromJson(NodeToJson(root));
  EXPECT_EQ(NodeToJson(again), NodeToJson(root));
  for (size_t i = 0; i < all.size(); ++i) {
    EXPECT_EQ(again.children[i].params.index(), all[i].params.index());
    EXPECT_EQ(NodeToJson(again.children[i]), NodeToJson(all[i])) << NodeTypeName(all[i].params);
  }
  EXPECT_EQ(again.name, root.name);
  EXPECT_EQ(std::get<PolarArrayParams>(again.children[22].params).step_angle, 0.3);
  EXPECT_TRUE(std::get<MirrorParams>(again.children[20].params).keep_original);
}

TEST(SceneIo, OptionalFieldsTakeTheirDefaults) {
  const Scene scene =
      ParseScene(R"({"format": "spidarcad-scene", "version": 1, "solids": [{"name": "a", "root":
      {"type": "polar_array", "count": 8, "children": [{"type": "scale", "factors": 2,
        "children": [{"type": "half_space", "normal": [0, 0, 1]}]}]}}]})");
  const auto& ring = std::get<PolarArrayParams>(scene.solids[0].root.params);
  EXPECT_EQ(ring.axis, Eigen::Vector3d(0, 0, 1));
  EXPECT_DOUBLE_EQ(ring.step_angle, 2 * M_PI / 8);
  EXPECT_EQ(std::get<ScaleParams>(scene.solids[0].root.children[0].params).factors,
            Eigen::Vector3d::Constant(2));
  EXPECT_EQ(std::get<HalfSpaceParams>(scene.solids[0].root.children[0].children[0].params).offset,
            0.0);
}

TEST(SceneIo, SyntaxErrorNamesFileLineAndColumn) {
  // Line 4 has a trailing comma; the parser fails at the '}' on line 5, column 3.
  const std::string path = WriteFile("syntax.json",
                                     "{\n"
                                     "  \"format\": \"spidarcad-scene\",\n"
                                     "  \"version\": 1,\n"
                                     "  \"solids\": [],\n"
                                     "  }\n");
  const SceneError e = LoadError(path);
  EXPECT_EQ(e.file(), path);
  EXPECT_EQ(e.line(), 5);
  EXPECT_EQ(e.column(), 3);
  EXPECT_THAT(e.what(), HasSubstr(path + ":5:3:"));
  EXPECT_THAT(e.what(), HasSubstr("syntax error"));
}

TEST(SceneIo, TruncatedFileNamesTheLastLine) {
  const std::string path =
      WriteFile("truncated.json", "{\n  \"format\": \"spidarcad-scene\",\n  \"solids\": [\n");
  const SceneError e = LoadError(path);
  EXPECT_EQ(e.line(), 4);
}

const char* kHeader = "{\n  \"format\": \"spidarcad-scene\",\n  \"version\": 1,\n  \"solids\": [\n";

TEST(SceneIo, NegativeRadiusNamesLineAndField) {
  const std::string path = WriteFile(
      "negative.json", std::string(kHeader) +
                           "    {\"name\": \"s\", \"root\": {\"type\": \"union\", \"children\": [\n"
                           "      {\"type\": \"box\", \"size\": [0.1, 0.1, 0.1]},\n"
                           "      {\"type\": \"sphere\", \"id\": \"knob\",\n"
                           "       \"radius\": -0.02}\n"
                           "    ]}}\n  ]\n}\n");
  const SceneError e = LoadError(path);
  EXPECT_EQ(e.pointer(), "/solids/0/root/children/1/radius");
  EXPECT_EQ(e.line(), 8);
  EXPECT_EQ(e.column(), 18);
  EXPECT_THAT(e.what(), HasSubstr(path + ":8:18:"));
  EXPECT_THAT(e.what(), HasSubstr("'knob'"));
  EXPECT_THAT(e.what(), HasSubstr("'radius'"));
  EXPECT_THAT(e.what(), HasSubstr("-0.02"));
}

TEST(SceneIo, UnknownFieldIsRejectedWithItsPosition) {
  const std::string path =
      WriteFile("typo.json", std::string(kHeader) +
                                 "    {\"name\": \"s\", \"root\":\n"
                                 "      {\"type\": \"sphere\", \"raduis\": 0.1}}\n  ]\n}\n");
  const SceneError e = LoadError(path);
  EXPECT_EQ(e.pointer(), "/solids/0/root/raduis");
  EXPECT_EQ(e.line(), 6);
  EXPECT_EQ(e.column(), 36);
  EXPECT_THAT(e.what(), HasSubstr("unknown field 'raduis'"));
}

TEST(SceneIo, WrongTypeAndMissingFieldAreNamed) {
  {
    const std::string path =
        WriteFile("wrong_type.json", std::string(kHeader) +
                                         "    {\"name\": \"s\", \"root\": {\"type\": \"cylinder\", "
                                         "\"radius\": \"big\", \"height\": 0.1}}\n  ]\n}\n");
    const SceneError e = LoadError(path);
    EXPECT_EQ(e.pointer(), "/solids/0/root/radius");
    EXPECT_EQ(e.line(), 5);
    EXPECT_THAT(e.what(), HasSubstr("must be a number"));
  }
  {
    const std::string path = WriteFile(
        "missing.json", std::string(kHeader) +
                            "    {\"name\": \"s\",\n     \"root\": {\"type\": \"cylinder\", "
                            "\"radius\": 0.1}}\n  ]\n}\n");
    const SceneError e = LoadError(path);
    EXPECT_EQ(e.pointer(), "/solids/0/root");
    EXPECT_EQ(e.line(), 6);
    EXPECT_EQ(e.column(), 14);
    EXPECT_THAT(e.what(), HasSubstr("missing field 'height'"));
  }
  {
    const std::string path = WriteFile(
        "bad_type.json",
        std::string(kHeader) + "    {\"name\": \"s\", \"root\": {\"type\": \"blob\"}}\n  ]\n}\n");
    const SceneError e = LoadError(path);
    EXPECT_EQ(e.pointer(), "/solids/0/root/type");
    EXPECT_THAT(e.what(), HasSubstr("unknown node type 'blob'"));
  }
}

TEST(SceneIo, WrongHeaderIsRejected) {
  const SceneError format =
      LoadError(WriteFile("format.json", R"({"format": "other", "version": 1, "solids": []})"));
  EXPECT_EQ(format.pointer(), "/format");
  const SceneError version = LoadError(
      WriteFile("version.json", R"({"format": "spidarcad-scene", "version": 2, "solids": []})"));
  EXPECT_EQ(version.pointer(), "/version");
  EXPECT_THAT(version.what(), HasSubstr("unsupported scene version 2"));
  const SceneError units = LoadError(WriteFile(
      "units.json", R"({"format": "spidarcad-scene", "version": 1, "units": "mm", "solids": []})"));
  EXPECT_EQ(units.pointer(), "/units");
  const SceneError array = LoadError(WriteFile("array.json", "[1, 2]"));
  EXPECT_THAT(array.what(), HasSubstr("must be a JSON object"));
}

TEST(SceneIo, MissingFileIsNamed) {
  const SceneError e = LoadError(kOut + "does_not_exist.json");
  EXPECT_EQ(e.file(), kOut + "does_not_exist.json");
  EXPECT_THAT(e.what(), HasSubstr("cannot open"));
}

// Assembly parts (the optional "parts" array).

// Scene text whose one solid's root is `root` (a JSON node), on line 5.
std::string SceneWithRoot(const std::string& root) {
  return std::string(kHeader) + "    {\"name\": \"s\", \"root\":\n" + root + "}\n  ]\n}\n";
}

// A node chain in JSON: `levels` - 1 translate nodes around a sphere.
std::string JsonTranslateChain(int levels) {
  std::string text;
  for (int i = 1; i < levels; ++i)
    text += R"({"type": "translate", "translation": [0, 0, 0], "children": [)";
  text += R"({"type": "sphere", "radius": 0.01})";
  for (int i = 1; i < levels; ++i) text += "]}";
  return text;
}

std::string Repeat(const std::string& s, int times) {
  std::string out;
  for (int i = 0; i < times; ++i) out += s;
  return out;
}

TEST(SceneIo, TreeDeeperThanTheLimitIsRefusedWithTheNodePath) {
  // 300 levels nest JSON about 600 deep (under kMaxJsonDepth): the tree limit speaks.
  const std::string path = WriteFile("deep_tree.json", SceneWithRoot(JsonTranslateChain(300)));
  const SceneError e = LoadError(path);
  EXPECT_EQ(e.pointer(), "/solids/0/root" + Repeat("/children/0", kMaxTreeDepth));
  EXPECT_EQ(e.line(), 6);
  EXPECT_GT(e.column(), 1);
  EXPECT_THAT(e.what(), HasSubstr(path + ":6:"));
  EXPECT_THAT(e.what(), HasSubstr("deeper than 256 levels"));
}

TEST(SceneIo, TenThousandNestedTranslatesAreRefusedBeforeTheDocumentIsBuilt) {
  const std::string path = WriteFile("chain_10000.json", SceneWithRoot(JsonTranslateChain(10000)));
  const SceneError e = LoadError(path);
  EXPECT_EQ(e.line(), 6);
  // Level kMaxJsonDepth + 1 opens inside the chain: its pointer runs down the children.
  EXPECT_EQ(e.pointer().rfind("/solids/0/root/children/0/children/0", 0), 0u) << e.pointer();
  EXPECT_THAT(e.what(), HasSubstr("nest deeper than 1000 levels"));
}

TEST(SceneIo, ArrayNestedHundredThousandDeepIsRefusedWithItsPosition) {
  const std::string root =
      R"({"type": "sphere", "radius": )" + Repeat("[", 100000) + Repeat("]", 100000) + "}";
  const std::string path = WriteFile("nested_array.json", SceneWithRoot(root));
  const SceneError e = LoadError(path);
  // The document, solids, solid and root make four levels: level 1001 is the 997th '[', element
  // 0 of the 996th.
  EXPECT_EQ(e.line(), 6);
  EXPECT_EQ(e.column(), static_cast<int>(root.find('[')) + 997);
  EXPECT_EQ(e.pointer(), "/solids/0/root/radius" + Repeat("/0", 996));
  EXPECT_THAT(e.what(), HasSubstr("nest deeper than 1000 levels"));
}

TEST(SceneIo, NumberBeyondADoubleNamesLineColumnAndField) {
  const std::string path =
      WriteFile("huge_number.json", SceneWithRoot(R"(      {"type": "sphere", "radius": 1e999})"));
  const SceneError e = LoadError(path);
  EXPECT_EQ(e.file(), path);
  EXPECT_EQ(e.line(), 6);
  EXPECT_EQ(e.column(), 36);  // the '1' of 1e999
  EXPECT_EQ(e.pointer(), "/solids/0/root/radius");
  EXPECT_THAT(e.what(), HasSubstr(path + ":6:36: field /solids/0/root/radius: "));
  EXPECT_THAT(e.what(), HasSubstr("1e999 is out of range"));
  EXPECT_THAT(e.what(), HasSubstr("write a finite number"));
  // In an array too: the element's index is named.
  const std::string in_array = WriteFile(
      "huge_in_array.json", SceneWithRoot(R"(      {"type": "box", "size": [0.1, -1e400, 0.1]})"));
  EXPECT_EQ(LoadError(in_array).pointer(), "/solids/0/root/size/1");
}

TEST(SceneIo, KeyWithASlashAndAHugeIndexIsAnUnknownFieldAtItsPosition) {
  const std::string path = WriteFile(
      "slash_key.json",
      SceneWithRoot(
          R"(      {"type": "sphere", "radius": 0.1, "children/99999999999999999999": 1})"));
  const SceneError e = LoadError(path);
  // The key is one pointer token, its '/' escaped as ~1 (RFC 6901).
  EXPECT_EQ(e.pointer(), "/solids/0/root/children~199999999999999999999");
  EXPECT_EQ(e.line(), 6);
  EXPECT_EQ(e.column(), 74);  // its value
  EXPECT_THAT(e.what(), HasSubstr("unknown field 'children/99999999999999999999'"));
}

TEST(SceneIo, DeviceAndDirectoryAreRefusedBeforeReading) {
  const SceneError zero = LoadError("/dev/zero");
  EXPECT_EQ(zero.file(), "/dev/zero");
  EXPECT_THAT(zero.what(), HasSubstr("not a regular file"));
  const SceneError directory = LoadError(kOut);
  EXPECT_THAT(directory.what(), HasSubstr("not a regular file"));
}

TEST(SceneIo, FileOverTheSizeCapIsRefusedBeforeReading) {
  const std::string path = kOut + "oversized.json";
  { std::ofstream(path) << "{"; }
  std::filesystem::resize_file(path, kMaxSceneFileBytes + 1);  // sparse: costs no disk
  const SceneError e = LoadError(path);
  EXPECT_THAT(e.what(), HasSubstr("67108865 bytes"));
  EXPECT_THAT(e.what(), HasSubstr("64 MiB"));
  std::filesystem::remove(path);
}

TEST(SceneIo, ArrayCountOfABillionIsRefusedNamingTheField) {
  const std::string path = WriteFile(
      "billion.json",
      SceneWithRoot(
          R"(      {"type": "polar_array", "count": 1000000000, "children": [{"type": "sphere", "radius": 0.01}]})"));
  const SceneError e = LoadError(path);
  EXPECT_EQ(e.pointer(), "/solids/0/root/count");
  EXPECT_EQ(e.line(), 6);
  EXPECT_THAT(e.what(), HasSubstr("[1, 1000]"));
}

TEST(SceneIo, AssemblyLoadsWithTheFig9Parts) {
  const Scene scene = LoadScene(kScenes + "assembly.json");
  ASSERT_EQ(scene.parts.size(), 6u);
  int fixed = 0, seats = 0;
  for (const ScenePart& p : scene.parts) {
    fixed += p.fixed;
    seats += static_cast<int>(p.seats.size());
    EXPECT_NO_THROW(FindSolid(scene, p.solid)) << p.name;
    EXPECT_NEAR(p.rotation.norm(), 1.0, 1e-15);
    for (const SceneSeat& s : p.seats) EXPECT_EQ(s.on, "body");
  }
  EXPECT_EQ(fixed, 1);
  EXPECT_TRUE(scene.parts[0].fixed);
  EXPECT_EQ(seats, 5);
  // The right arm's axis-angle (y, π/2) is a quaternion (cos π/4, 0, sin π/4, 0).
  const ScenePart& arm = scene.parts[2];
  EXPECT_EQ(arm.name, "right_arm");
  EXPECT_NEAR(arm.rotation.w(), std::sqrt(0.5), 1e-15);
  EXPECT_NEAR(arm.rotation.y(), std::sqrt(0.5), 1e-15);
  EXPECT_NEAR(arm.seats[0].rotation.angularDistance(arm.rotation), 0.0, 1e-12);
}

TEST(SceneIo, PartsRoundTripThroughSaveAndLoad) {
  const Scene scene = ParseScene(R"({"format": "spidarcad-scene", "version": 1,
    "solids": [{"name": "a", "root": {"type": "sphere", "radius": 0.01}},
               {"name": "b", "root": {"type": "box", "size": [0.01, 0.02, 0.03]}}],
    "parts": [{"name": "base", "solid": "b", "kind": "fixed", "quaternion": [2, 0, 0, 0]},
              {"name": "ball", "solid": "a", "position": [0.1, -0.2, 0.3], "axis": [1, 1, 0], "angle": 0.7,
               "seats": [{"on": "base", "position": [0, 0, 0.02], "quaternion": [0.5, 0.5, 0.5, 0.5],
                          "position_tolerance": 0.001, "angle_tolerance": 0.05}]}]})");
  ASSERT_EQ(scene.parts.size(), 2u);
  EXPECT_TRUE(scene.parts[0].fixed);
  EXPECT_EQ(scene.parts[0].rotation.coeffs(),
            Eigen::Quaterniond::Identity().coeffs());  // normalised
  const ScenePart& ball = scene.parts[1];
  EXPECT_FALSE(ball.fixed);
  const Eigen::Quaterniond expected(Eigen::AngleAxisd(0.7, Eigen::Vector3d(1, 1, 0).normalized()));
  EXPECT_LT(ball.rotation.angularDistance(expected), 1e-14);
  EXPECT_EQ(ball.position, Eigen::Vector3d(0.1, -0.2, 0.3));
  ASSERT_EQ(ball.seats.size(), 1u);
  EXPECT_EQ(ball.seats[0].on, "base");
  EXPECT_EQ(ball.seats[0].position_tolerance, 0.001);
  EXPECT_EQ(ball.seats[0].angle_tolerance, 0.05);
  // Rotation about (1,1,1) by 2π/3 maps x to y.
  EXPECT_LT((ball.seats[0].rotation * Eigen::Vector3d::UnitX() - Eigen::Vector3d::UnitY()).norm(),
            1e-15);

  for (const Scene& original : {scene, LoadScene(kScenes + "assembly.json")}) {
    const std::string path = kOut + "round_trip_parts.json";
    SaveScene(original, path);
    const Scene again = LoadScene(path);
    EXPECT_EQ(SceneToJson(again), SceneToJson(original));
    ASSERT_EQ(again.parts.size(), original.parts.size());
    for (size_t i = 0; i < original.parts.size(); ++i) {
      const ScenePart& a = again.parts[i];
      const ScenePart& o = original.parts[i];
      EXPECT_EQ(a.name, o.name);
      EXPECT_EQ(a.solid, o.solid);
      EXPECT_EQ(a.fixed, o.fixed);
      EXPECT_EQ(a.position, o.position);
      EXPECT_EQ(a.rotation.coeffs(), o.rotation.coeffs());
      ASSERT_EQ(a.seats.size(), o.seats.size());
      for (size_t k = 0; k < o.seats.size(); ++k) {
        EXPECT_EQ(a.seats[k].on, o.seats[k].on);
        EXPECT_EQ(a.seats[k].position, o.seats[k].position);
        EXPECT_EQ(a.seats[k].rotation.coeffs(), o.seats[k].rotation.coeffs());
        EXPECT_EQ(a.seats[k].position_tolerance, o.seats[k].position_tolerance);
        EXPECT_EQ(a.seats[k].angle_tolerance, o.seats[k].angle_tolerance);
      }
    }
  }
}

TEST(SceneIo, BadPartsAreNamedWithLineAndField) {
  const std::string head =
      "{\n  \"format\": \"spidarcad-scene\", \"version\": 1,\n"
      "  \"solids\": [{\"name\": \"a\", \"root\": {\"type\": \"sphere\", \"radius\": 0.01}}],\n"
      "  \"parts\": [\n";
  struct Case {
    const char* parts;
    const char* pointer;
    int line;
    const char* text;
  };
  const Case cases[] = {
      {"    {\"name\": \"p\", \"solid\": \"a\"},\n    {\"name\": \"q\", \"solid\": \"nope\"}\n",
       "/parts/1/solid", 6, "no solid named 'nope'"},
      {"    {\"name\": \"p\", \"solid\": \"a\", \"seats\": [{\"on\": \"bdy\"}]}\n",
       "/parts/0/seats/0/on", 5, "no part named 'bdy'"},
      {"    {\"name\": \"p\", \"solid\": \"a\", \"kind\": \"glued\"}\n", "/parts/0/kind", 5,
       "\"fixed\" or \"graspable\""},
      {"    {\"name\": \"p\", \"solid\": \"a\"},\n    {\"name\": \"p\", \"solid\": \"a\"}\n",
       "/parts/1/name", 6, "duplicate part name 'p'"},
      {"    {\"name\": \"p\", \"solid\": \"a\", \"positon\": [0, 0, 0]}\n", "/parts/0/positon", 5,
       "unknown field 'positon'"},
      {"    {\"name\": \"p\", \"solid\": \"a\", \"quaternion\": [0, 0, 0, 0]}\n",
       "/parts/0/quaternion", 5, "non-zero"},
      {"    {\"name\": \"p\", \"solid\": \"a\", \"seats\": [{\"on\": \"p\"}]}\n",
       "/parts/0/seats/0/on", 5, "cannot sit on itself"},
      {"    {\"name\": \"p\", \"solid\": \"a\", \"seats\": [{\"on\": \"q\", \"angle_tolerance\": "
       "-1}]},\n"
       "    {\"name\": \"q\", \"solid\": \"a\"}\n",
       "/parts/0/seats/0/angle_tolerance", 5, ">= 0"},
  };
  int index = 0;
  for (const Case& c : cases) {
    const std::string path =
        WriteFile("bad_parts_" + std::to_string(index++) + ".json", head + c.parts + "  ]\n}\n");
    const SceneError e = LoadError(path);
    EXPECT_EQ(e.pointer(), c.pointer) << c.parts;
    EXPECT_EQ(e.line(), c.line) << c.parts;
    EXPECT_THAT(e.what(), HasSubstr(path + ":" + std::to_string(c.line) + ":")) << c.parts;
    EXPECT_THAT(e.what(), HasSubstr(c.text)) << c.parts;
  }
}

TEST(SceneIo, SnapIsOptionalTakesDefaultsAndRoundTrips) {
  const std::string solids =
      "\"solids\": [{\"name\": \"a\", \"root\": {\"type\": \"box\", \"size\": [0.02, 0.02, "
      "0.02]}}]";
  // Absent: no snap (old files load as before).
  const Scene plain =
      ParseScene("{\"format\": \"spidarcad-scene\", \"version\": 1, " + solids + "}");
  EXPECT_FALSE(plain.snap.has_value());
  EXPECT_EQ(SceneToJson(plain).count("snap"), 0u);
  EXPECT_FALSE(LoadScene(kScenes + "platform.json").snap.has_value());
  // Empty object: every default (the documented values).
  const Scene defaults =
      ParseScene("{\"format\": \"spidarcad-scene\", \"version\": 1, \"snap\": {}, " + solids + "}");
  ASSERT_TRUE(defaults.snap.has_value());
  EXPECT_EQ(defaults.snap->max_force, 1.0);
  EXPECT_EQ(defaults.snap->vertex_radius, 0.008);
  EXPECT_EQ(defaults.snap->edge_radius, 0.005);
  EXPECT_EQ(defaults.snap->face_radius, 0.003);
  // Given values survive save and load bit for bit.
  const Scene given = ParseScene(
      "{\"format\": \"spidarcad-scene\", \"version\": 1, \"snap\": "
      "{\"max_force\": 0.7, \"vertex_radius\": 0.011, \"edge_radius\": 0.0061, "
      "\"face_radius\": 0.0023}, " +
      solids + "}");
  const std::string path = kOut + "snap_round_trip.json";
  SaveScene(given, path);
  const Scene back = LoadScene(path);
  ASSERT_TRUE(back.snap.has_value());
  EXPECT_EQ(back.snap->max_force, 0.7);
  EXPECT_EQ(back.snap->vertex_radius, 0.011);
  EXPECT_EQ(back.snap->edge_radius, 0.0061);
  EXPECT_EQ(back.snap->face_radius, 0.0023);
}

TEST(SceneIo, BadSnapIsNamedWithLineAndField) {
  const std::string head =
      "{\n  \"format\": \"spidarcad-scene\", \"version\": 1,\n"
      "  \"solids\": [{\"name\": \"a\", \"root\": {\"type\": \"sphere\", \"radius\": 0.01}}],\n";
  struct Case {
    const char* snap;
    const char* pointer;
    const char* text;
  };
  const Case cases[] = {
      {"  \"snap\": {\"vertex_radius\": -0.01}\n", "/snap/vertex_radius",
       "must be finite and > 0, got -0.01"},
      {"  \"snap\": {\"max_force\": 0}\n", "/snap/max_force", "must be finite and > 0, got 0"},
      {"  \"snap\": {\"radius\": 0.01}\n", "/snap/radius", "unknown field 'radius'"},
      {"  \"snap\": {\"edge_radius\": \"big\"}\n", "/snap/edge_radius", "must be a number"},
      {"  \"snap\": true\n", "/snap", "must be a JSON object"},
  };
  int index = 0;
  for (const Case& c : cases) {
    const std::string path =
        WriteFile("bad_snap_" + std::to_string(index++) + ".json", head + c.snap + "}\n");
    const SceneError e = LoadError(path);
    EXPECT_EQ(e.pointer(), c.pointer) << c.snap;
    EXPECT_EQ(e.line(), 4) << c.snap;
    EXPECT_THAT(e.what(), HasSubstr(path + ":4:")) << c.snap;
    EXPECT_THAT(e.what(), HasSubstr(c.text)) << c.snap;
  }
}

// The bounded reader behind LoadScene, documents and calibration files: a missing file, a
// device, a directory, a pipe and a file over the limit are refused before reading, naming the
// path; a file within it is read exactly.
TEST(SceneIo, ReadBoundedFileRefusesDevicesPipesAndLargeFilesBeforeReading) {
  const std::string dir = std::string(SPIDARCAD_TEST_OUTPUT_DIR);
  const std::string small = dir + "/bounded_small.json";
  std::ofstream(small, std::ios::binary) << std::string("{\"a\": 1}\n\0x", 11);
  EXPECT_EQ(ReadBoundedFile(small, 11, "thing"), std::string("{\"a\": 1}\n\0x", 11));
  const std::string fifo = dir + "/bounded_fifo.json";
  std::filesystem::remove(fifo);
  ASSERT_EQ(mkfifo(fifo.c_str(), 0600), 0);
  struct Case {
    std::string path;
    long long limit;
    std::string expected;
  };
  const Case cases[] = {
      {dir + "/bounded_missing.json", 100, "cannot open the thing for reading (no such file)"},
      {"/dev/zero", 100, "is not a regular file (a directory, device or pipe)"},
      {dir, 100, "is not a regular file"},
      {fifo, 100, "is not a regular file"},
      {small, 10, "the file is 11 bytes, more than the 10 bytes a thing may have"},
  };
  for (const Case& c : cases) {
    try {
      ReadBoundedFile(c.path, c.limit, "thing");
      ADD_FAILURE() << c.path << ": nothing thrown";
    } catch (const SceneError& e) {
      EXPECT_EQ(e.file(), c.path);
      EXPECT_THAT(e.what(), HasSubstr(c.expected)) << c.path;
    }
  }
  std::filesystem::remove(fifo);
}

// ParseJsonText, the one JSON entry point of every reader: no nlohmann exception escapes; each
// failure names the line, column and (for numbers and nesting) the field.
TEST(SceneIo, ParseJsonTextNamesLineColumnAndFieldOfEveryFailure) {
  EXPECT_EQ(ParseJsonText("{\"a\": [1, 2.5]}", "t")["a"][1].get<double>(), 2.5);
  struct Case {
    std::string text, expected;
  };
  const Case cases[] = {
      {"{\n  \"a\": {\"b\": [0, 1e999]}}",
       "t:2:18: field /a/b/1: the number 1e999 is out of range"},
      {"{\"a\": -1e400}", "t:1:7: field /a: the number -1e400 is out of range"},
      {"{\n\"a\": " + std::string(2000, '[') + std::string(2000, ']') + "}",
       "t:2:1005: field /a/0/0"},
      {"{\"a\": }", "t:1:7: JSON syntax error"},
      {"", "t:1:1: JSON syntax error"},
  };
  for (const Case& c : cases) {
    try {
      ParseJsonText(c.text, "t");
      ADD_FAILURE() << c.expected << ": nothing thrown";
    } catch (const SceneError& e) {
      EXPECT_THAT(e.what(), HasSubstr(c.expected));
    }
  }
}

}  // namespace
}  // namespace spidarcad::modeling
