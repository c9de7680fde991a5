// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
// The loader of the headless commands (scene/document_file.cc): version 1 scenes read exactly as
// modeling::LoadScene reads them, version 2 documents with every object kind.
#include "scene/document_file.h"

#include <gtest/gtest.h>

#include <fstream>
#include <string>
#include <variant>

#include "doc/input_error.h"

namespace spidarcad::app {
namespace {

std::string Asset(const std::string& name) {
  return std::string(SPIDARCAD_SOURCE_DIR) + "/assets/scenes/" + name;
}

std::string OutputPath(const std::string& name) {
  return std::string(SPIDARCAD_TEST_OUTPUT_DIR) + "/document_file_" + name;
}

TEST(DocumentFile, VersionIsReadFromTheTopLevelOnly) {
  EXPECT_EQ(DocumentFileVersion(Asset("platform.json")), 1);
  EXPECT_EQ(DocumentFileVersion(Asset("workbench.json")), 2);
  EXPECT_EQ(DocumentFileVersion(Asset("no_such_file.json")), 1);
  const std::string nested = OutputPath("nested.json");
  std::ofstream(nested) << R"({"solids": [{"version": 2}], "format": "spidarcad-scene",
                              "version": 1})";
  EXPECT_EQ(DocumentFileVersion(nested), 1);
  const std::string late = OutputPath("late.json");
  std::ofstream(late) << R"({"objects": [{"kind": "x", "version": 1}], "version": 2})";
  EXPECT_EQ(DocumentFileVersion(late), 2);
  const std::string broken = OutputPath("broken.json");
  std::ofstream(broken) << "{\"version\": ";
  EXPECT_EQ(DocumentFileVersion(broken), 1);
}

TEST(DocumentFile, Version1SceneGivesTheSolidsModelingReads) {
  const OpenedDocument opened = OpenDocumentFile(Asset("assembly.json"));
  EXPECT_EQ(opened.version, 1);
  const modeling::Scene expected = modeling::LoadScene(Asset("assembly.json"));
  const modeling::Scene got = opened.doc->ToScene();
  EXPECT_EQ(modeling::SceneToJson(got).dump(), modeling::SceneToJson(expected).dump());
  ASSERT_GE(opened.doc->objects().size(), 2u);
  EXPECT_EQ(ObjectPointer(opened, opened.doc->objects()[1].id), "/solids/1");
}

TEST(DocumentFile, Version2DocumentGivesEveryObjectKind) {
  const OpenedDocument opened = OpenDocumentFile(Asset("platform_fe.json"));
  EXPECT_EQ(opened.version, 2);
  const Document& doc = *opened.doc;
  ASSERT_EQ(doc.objects().size(), 3u);
  EXPECT_TRUE(std::holds_alternative<SolidData>(doc.objects()[0].data));
  const auto& mesh = std::get<MeshData>(doc.objects()[1].data);
  ASSERT_TRUE(mesh.volume);  // generated when the file is opened
  EXPECT_GT(mesh.volume->tets.cols(), 100);
  const auto& fe = std::get<FeModelData>(doc.objects()[2].data);
  EXPECT_EQ(fe.tet_mesh, doc.objects()[1].id);
  ASSERT_EQ(fe.loads.size(), 1u);
  EXPECT_EQ(fe.loads[0].force.z(), -50.0);
  EXPECT_EQ(ObjectPointer(opened, doc.objects()[2].id), "/objects/2");
  EXPECT_EQ(ObjectNames(doc, {"solid", "fe_model"}), "'platform', 'platform FE'");
  EXPECT_EQ(ObjectNames(doc, {"sculpt"}), "none");
}

TEST(DocumentFile, BadFilesThrowInputErrorNamingFileLineAndField) {
  const std::string bad = OutputPath("bad.json");
  std::ofstream(bad) << "{\n  \"format\": \"spidarcad-scene\",\n  \"version\": 2,\n"
                        "  \"objects\": [\n    {\"kind\": \"solid\", \"name\": \"s\", \"root\":\n"
                        "      {\"type\": \"sphere\", \"radius\": -1}}\n  ]\n}\n";
  try {
    OpenDocumentFile(bad);
    FAIL() << "a negative radius was accepted";
  } catch (const InputError& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find(bad + ":6:"), std::string::npos) << what;
    EXPECT_NE(what.find("/objects/0/root/radius"), std::string::npos) << what;
  }
  try {
    OpenDocumentFile(OutputPath("missing.json"));
    FAIL() << "a missing file was accepted";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("missing.json"), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace spidarcad::app
