// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
// `spidarcad info FILE` (cli/info_command.cc): one line per object on every shipped scene, with
// counts checked against the file's own JSON and against a Document loaded in process; a broken
// file exits 2 naming the file, the line and the field.
#include <gtest/gtest.h>

#include <fstream>
#include <nlohmann/json.hpp>
#include <sstream>
#include <string>
#include <vector>

#include "doc/document.h"
#include "spidarcad_runner.h"

namespace spidarcad::app {
namespace {

using test_support::RunSpidarcad;

std::vector<std::string> Lines(const std::string& text) {
  std::vector<std::string> lines;
  std::istringstream in(text);
  for (std::string line; std::getline(in, line);) lines.push_back(line);
  return lines;
}

std::string Scene(const std::string& name) {
  return std::string(SPIDARCAD_SOURCE_DIR) + "/assets/scenes/" + name + ".json";
}

nlohmann::json ReadJson(const std::string& path) {
  std::ifstream in(path);
  return nlohmann::json::parse(in);
}

// Every shipped scene: one line per entry of the file's "solids", "objects" and "parts", in order,
// each starting with the kind the file gives and the name.
TEST(InfoCommand, ListsEveryObjectOfEveryShippedScene) {
  for (const char* name :
       {"platform", "clay", "assembly", "platform_fe", "clay_sculpt", "workbench"}) {
    SCOPED_TRACE(name);
    const auto run = RunSpidarcad("info " + Scene(name), "", name);
    ASSERT_EQ(run.status, 0) << run.all();
    const nlohmann::json file = ReadJson(Scene(name));
    std::vector<std::pair<std::string, std::string>> expected;  // kind, name
    for (const auto& s : file.value("solids", nlohmann::json::array()))
      expected.emplace_back("solid", s["name"]);
    for (const auto& o : file.value("objects", nlohmann::json::array())) {
      std::string kind = o["kind"];
      if (kind == "mesh")
        kind = (o.contains("volume") || o.value("generate", "") == "volume") ? "tet_mesh" : "mesh";
      if (kind == "rigid_part") kind = "part";
      expected.emplace_back(kind, o["name"]);
    }
    for (const auto& p : file.value("parts", nlohmann::json::array()))
      expected.emplace_back("part", p["name"]);
    const std::vector<std::string> lines = Lines(run.out);
    ASSERT_EQ(lines.size(), expected.size()) << run.out;
    for (std::size_t i = 0; i < lines.size(); ++i) {
      EXPECT_EQ(lines[i].rfind(expected[i].first + " ", 0), 0u) << lines[i];
      EXPECT_NE(lines[i].find("'" + expected[i].second + "'"), std::string::npos) << lines[i];
    }
  }
}

// Counts on the workbench agree with the document loaded here; the seated cap and the steel
// material show.
TEST(InfoCommand, CountsAgreeWithTheLoadedDocument) {
  const auto run = RunSpidarcad("info " + Scene("workbench"));
  ASSERT_EQ(run.status, 0) << run.all();
  Document doc;
  doc.Load(Scene("workbench"));
  const auto& mesh = std::get<MeshData>(doc.objects()[1].data);
  const auto& clay = std::get<SculptData>(doc.objects()[3].data);
  const std::vector<std::string> lines = Lines(run.out);
  ASSERT_EQ(lines.size(), 6u) << run.out;
  EXPECT_NE(lines[1].find("nodes=" + std::to_string(mesh.volume->nodes.cols()) +
                          " tets=" + std::to_string(mesh.volume->tets.cols())),
            std::string::npos)
      << lines[1];
  EXPECT_NE(lines[2].find("material=E2e+11Pa,nu0.3"), std::string::npos) << lines[2];
  EXPECT_NE(lines[2].find("clamps=1 loads=1"), std::string::npos) << lines[2];
  EXPECT_NE(lines[3].find("nodes=" + std::to_string(clay.mesh->vertices.cols())), std::string::npos)
      << lines[3];
  EXPECT_NE(lines[4].find("fixed"), std::string::npos) << lines[4];
  EXPECT_NE(lines[5].find("seated on 'base'"), std::string::npos) << lines[5];
  // In the assembly scene every part is laid out beside the torso: none is seated yet.
  const auto assembly = RunSpidarcad("info " + Scene("assembly"), "", "assembly");
  ASSERT_EQ(assembly.status, 0);
  EXPECT_NE(assembly.out.find("part      'head' solid='head' not seated"), std::string::npos)
      << assembly.out;
}

TEST(InfoCommand, BrokenFileExitsTwoNamingFileLineAndField) {
  const std::string path = test_support::TestOutputPath("info_broken.json");
  {
    std::ofstream out(path);
    out << "{\n  \"format\": \"spidarcad-scene\",\n  \"version\": 2,\n  \"objects\": [\n"
           "    {\"kind\": \"sculpt\", \"name\": \"clay\",\n     \"mesh\": {\"vertices\": [[0, 0, "
           "\"x\"]], \"triangles\": []}}\n  ]\n}\n";
  }
  const auto run = RunSpidarcad("info " + path);
  EXPECT_EQ(run.status, 2) << run.all();
  EXPECT_NE(run.err.find(path + ":6:"), std::string::npos) << run.err;
  EXPECT_NE(run.err.find("/objects/0/mesh/vertices/0/2"), std::string::npos) << run.err;
  EXPECT_TRUE(run.out.empty()) << run.out;
  const auto missing = RunSpidarcad("info " + path + ".missing", "", "missing");
  EXPECT_EQ(missing.status, 2) << missing.all();
  EXPECT_NE(missing.err.find(path + ".missing"), std::string::npos) << missing.err;
}

// A document made for a scaled frame says so on a last "device" line.
TEST(InfoCommand, DocumentFramePrintsALastDeviceLine) {
  const std::string path = test_support::TestOutputPath("info_device.json");
  {
    std::ofstream out(path);
    out << "{\"format\": \"spidarcad-scene\", \"version\": 2,\n"
           " \"device\": {\"frame\": [0.3, 0.28, 0.26], \"pole\": 0.05},\n"
           " \"objects\": [{\"kind\": \"solid\", \"name\": \"ball\", \"root\": "
           "{\"type\": \"sphere\", \"radius\": 0.02}}]}\n";
  }
  const auto run = RunSpidarcad("info " + path);
  ASSERT_EQ(run.status, 0) << run.all();
  const std::vector<std::string> lines = Lines(run.out);
  ASSERT_EQ(lines.size(), 2u) << run.out;
  EXPECT_EQ(lines[0].rfind("solid", 0), 0u) << lines[0];
  EXPECT_EQ(lines[1], "device    frame=0.3,0.28,0.26 pole=0.05 (m)");
}

}  // namespace
}  // namespace spidarcad::app
