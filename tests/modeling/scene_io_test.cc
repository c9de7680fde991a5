// Tests of the JSON scene format: the shipped scenes load, save/load round trips, and bad files
// give errors naming file, line, column and field.
// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#include "spidarcad/modeling/scene_io.h"

#include <filesystem>
#include <fstream>
#include <random>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

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
    for (double z : {-0.035, -0.115}) EXPECT_GT(platform.Value(Eigen::Vector3d(0.005, y, z)), 0.0) << y << " " << z;
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
      s, ImplicitNode(BoxParams{Eigen::Vector3d(0.1, 0.2, 0.3)}),
      ImplicitNode(RoundedBoxParams{Eigen::Vector3d(0.1, 0.2, 0.3), 0.01}), ImplicitNode(CylinderParams{0.01, 0.02}),
      ImplicitNode(CapsuleParams{Eigen::Vector3d(1, 2, 3), Eigen::Vector3d(4, 5, 6), 0.5}),
      ImplicitNode(ConeParams{0.1, 0.2, 0.3}), ImplicitNode(TorusParams{0.2, 0.1}),
      ImplicitNode(HalfSpaceParams{Eigen::Vector3d(0, 1, 1), 0.2}), ImplicitNode(extrusion),
      ImplicitNode(UnionParams{}, {s}), ImplicitNode(IntersectionParams{}, {s}), ImplicitNode(DifferenceParams{}, {s, s}),
      ImplicitNode(SmoothUnionParams{0.01}, {s}), ImplicitNode(SmoothIntersectionParams{0.02}, {s}),
      ImplicitNode(SmoothDifferenceParams{0.03}, {s, s}), ImplicitNode(OffsetParams{-0.01}, {s}),
      ImplicitNode(ShellParams{0.002}, {s}), ImplicitNode(TranslateParams{Eigen::Vector3d(1, 2, 3)}, {s}),
      ImplicitNode(RotateParams{Eigen::Vector3d(0, 1, 0), 0.7}, {s}),
      ImplicitNode(ScaleParams{Eigen::Vector3d(1, 2, 3)}, {s}), ImplicitNode(mirror, {s}), ImplicitNode(line, {s}),
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
  const Scene scene = ParseScene(R"({"format": "spidarcad-scene", "version": 1, "solids": [{"name": "a", "root":
      {"type": "polar_array", "count": 8, "children": [{"type": "scale", "factors": 2,
        "children": [{"type": "half_space", "normal": [0, 0, 1]}]}]}}]})");
  const auto& ring = std::get<PolarArrayParams>(scene.solids[0].root.params);
  EXPECT_EQ(ring.axis, Eigen::Vector3d(0, 0, 1));
  EXPECT_DOUBLE_EQ(ring.step_angle, 2 * M_PI / 8);
  EXPECT_EQ(std::get<ScaleParams>(scene.solids[0].root.children[0].params).factors, Eigen::Vector3d::Constant(2));
  EXPECT_EQ(std::get<HalfSpaceParams>(scene.solids[0].root.children[0].children[0].params).offset, 0.0);
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
  const std::string path = WriteFile("truncated.json", "{\n  \"format\": \"spidarcad-scene\",\n  \"solids\": [\n");
  const SceneError e = LoadError(path);
  EXPECT_EQ(e.line(), 4);
}

const char* kHeader = "{\n  \"format\": \"spidarcad-scene\",\n  \"version\": 1,\n  \"solids\": [\n";

TEST(SceneIo, NegativeRadiusNamesLineAndField) {
  const std::string path = WriteFile("negative.json", std::string(kHeader) +
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
  const std::string path = WriteFile("typo.json", std::string(kHeader) +
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
    const std::string path = WriteFile("wrong_type.json", std::string(kHeader) +
                                                              "    {\"name\": \"s\", \"root\": {\"type\": \"cylinder\", "
                                                              "\"radius\": \"big\", \"height\": 0.1}}\n  ]\n}\n");
    const SceneError e = LoadError(path);
    EXPECT_EQ(e.pointer(), "/solids/0/root/radius");
    EXPECT_EQ(e.line(), 5);
    EXPECT_THAT(e.what(), HasSubstr("must be a number"));
  }
  {
    const std::string path = WriteFile("missing.json", std::string(kHeader) +
                                                           "    {\"name\": \"s\",\n     \"root\": {\"type\": \"cylinder\", "
                                                           "\"radius\": 0.1}}\n  ]\n}\n");
    const SceneError e = LoadError(path);
    EXPECT_EQ(e.pointer(), "/solids/0/root");
    EXPECT_EQ(e.line(), 6);
    EXPECT_EQ(e.column(), 14);
    EXPECT_THAT(e.what(), HasSubstr("missing field 'height'"));
  }
  {
    const std::string path = WriteFile("bad_type.json", std::string(kHeader) +
                                                            "    {\"name\": \"s\", \"root\": {\"type\": \"blob\"}}\n  ]\n}\n");
    const SceneError e = LoadError(path);
    EXPECT_EQ(e.pointer(), "/solids/0/root/type");
    EXPECT_THAT(e.what(), HasSubstr("unknown node type 'blob'"));
  }
}

TEST(SceneIo, WrongHeaderIsRejected) {
  const SceneError format = LoadError(WriteFile("format.json", R"({"format": "other", "version": 1, "solids": []})"));
  EXPECT_EQ(format.pointer(), "/format");
  const SceneError version = LoadError(WriteFile("version.json", R"({"format": "spidarcad-scene", "version": 2, "solids": []})"));
  EXPECT_EQ(version.pointer(), "/version");
  EXPECT_THAT(version.what(), HasSubstr("unsupported scene version 2"));
  const SceneError units = LoadError(WriteFile("units.json", R"({"format": "spidarcad-scene", "version": 1, "units": "mm", "solids": []})"));
  EXPECT_EQ(units.pointer(), "/units");
  const SceneError array = LoadError(WriteFile("array.json", "[1, 2]"));
  EXPECT_THAT(array.what(), HasSubstr("must be a JSON object"));
}

TEST(SceneIo, MissingFileIsNamed) {
  const SceneError e = LoadError(kOut + "does_not_exist.json");
  EXPECT_EQ(e.file(), kOut + "does_not_exist.json");
  EXPECT_THAT(e.what(), HasSubstr("cannot open"));
}

}  // namespace
}  // namespace spidarcad::modeling
