// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
// The document file (doc/document_io.h, docs/scene-format.md version 2): every object kind
// survives save and open; undo and redo of each kind work across a save; version 1 scenes open
// as before; large arrays are stored as base64 raw bytes; bad files name file, line and field
// and leave the document unchanged; saving is atomic.
#include "doc/document_io.h"

#include <gtest/gtest.h>
#include <unistd.h>

#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <functional>
#include <memory>
#include <numbers>
#include <random>
#include <sstream>
#include <string>
#include <tuple>
#include <utility>
#include <vector>

#include "doc/command.h"
#include "doc/document.h"

namespace spidarcad::app {
namespace {

namespace fs = std::filesystem;
using modeling::ImplicitNode;
using nlohmann::json;

std::string OutDir(const std::string& name) {
  const fs::path dir = fs::path(SPIDARCAD_TEST_OUTPUT_DIR) / ("document_io_" + name);
  fs::remove_all(dir);
  fs::create_directories(dir);
  return dir.string();
}

std::string ReadText(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  std::ostringstream s;
  s << in.rdbuf();
  return s.str();
}

void WriteText(const std::string& path, const std::string& text) {
  std::ofstream out(path, std::ios::binary);
  out << text;
}

// The Document's own debug JSON (document.cc, not the file writer) with object ids replaced by
// positions, mesh revisions by "up to date", so that a reopened document compares equal.
json Canonical(const Document& doc) {
  json j = doc.ToJson(false);
  for (json& o : j["objects"]) {
    const ObjectId id = o["id"].get<ObjectId>();
    o["id"] = doc.IndexOf(id);
    if (o["kind"] == "mesh") {
      const ObjectId source = o["source"].get<ObjectId>();
      o["source"] = source != 0 ? doc.IndexOf(source) : -1;
      o["up_to_date"] = source != 0 && doc.Find(source) != nullptr && !doc.IsMeshOutOfDate(id);
      o.erase("source_revision");
    }
    if (o["kind"] == "fe_model") o["tet_mesh"] = doc.IndexOf(o["tet_mesh"].get<ObjectId>());
  }
  j["parts"] =
      modeling::SceneToJson({"", {}, doc.parts(), std::nullopt}).value("parts", json::array());
  return j;
}

ImplicitNode Sphere(double r, std::string id = {}) {
  return ImplicitNode(modeling::SphereParams{r}, {}, std::move(id));
}

modeling::TetMesh TwoTets() {
  modeling::TetMesh m;
  m.nodes.resize(3, 5);
  m.nodes << 0, 1, 0, 0, 1, 0, 0, 1, 0, 1, 0, 0, 0, 1, 1;
  m.tets.resize(4, 2);
  m.tets << 0, 1, 1, 2, 2, 3, 3, 4;
  m.regions.resize(2);
  m.regions << 1, 2;
  return m;
}

SculptMesh RandomMesh(int vertices, int triangles, unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(-0.1, 0.1);
  std::uniform_int_distribution<int> v(0, vertices - 1);
  SculptMesh m;
  m.vertices.resize(3, vertices);
  for (int i = 0; i < vertices; ++i) m.vertices.col(i) = Eigen::Vector3d(u(rng), u(rng), u(rng));
  m.triangles.resize(3, triangles);
  for (int t = 0; t < triangles; ++t) m.triangles.col(t) = Eigen::Vector3i(v(rng), v(rng), v(rng));
  return m;
}

Eigen::Isometry3d Pose(double angle, const Eigen::Vector3d& p) {
  Eigen::Isometry3d X = Eigen::Isometry3d::Identity();
  X.translate(p);
  X.rotate(Eigen::AngleAxisd(angle, Eigen::Vector3d(1, 2, 3).normalized()));
  return X;
}

// One object of every kind, each with its optional fields set, made through commands.
struct Fixture {
  Document doc;
  ObjectId solid = 0, mesh = 0, surface = 0, fe = 0, sculpt = 0, base = 0, lid = 0;
  Fixture() {
    doc.Execute(edit::AddSolid(
        "platform",
        ImplicitNode(modeling::UnionParams{}, {Sphere(0.05, "ball"), Sphere(0.02, "pip")}, "u")));
    solid = doc.last_created().at(0);
    MeshData m;
    m.source = solid;
    m.source_revision = doc.Get(solid).revision;
    m.volume = std::make_shared<const modeling::TetMesh>(TwoTets());
    m.surface = std::make_shared<const modeling::TriangleMesh>(RandomMesh(7, 5, 1));
    m.settings = {0.004, 1e-7, 1.5};
    doc.Execute(edit::AddObject("platform tets", m));
    mesh = doc.last_created().at(0);
    MeshData imported;
    imported.surface = std::make_shared<const modeling::TriangleMesh>(RandomMesh(9, 4, 2));
    imported.import_source = "/tmp/bunny.stl";
    doc.Execute(edit::AddObject("bunny", imported));
    surface = doc.last_created().at(0);
    doc.Execute(edit::AddFeModel(
        "platform fe", mesh, fem::Material{2e11, 0.3},
        {Eigen::AlignedBox3d(Eigen::Vector3d(-1, -1, -1), Eigen::Vector3d(0.001, 1, 1))}));
    fe = doc.last_created().at(0);
    doc.Execute(edit::SetFeLoads(
        fe, {{Eigen::AlignedBox3d(Eigen::Vector3d(0.9, -1, -1), Eigen::Vector3d(1, 1, 1)),
              Eigen::Vector3d(0, 0, -10.5)}}));
    doc.Execute(edit::SetRegionMaterials(fe, {{2, fem::Material{7e10, 0.33}}}));
    doc.Execute(edit::SetElementOrder(fe, 2));
    doc.Execute(edit::SetPrecomputeKey(fe, 0xfedcba9876543210ull));
    doc.Execute(edit::AddSculpt("clay", RandomMesh(50, 40, 3)));
    sculpt = doc.last_created().at(0);
    doc.Execute(edit::AddRigidPart("base", Sphere(0.03, "base_ball"),
                                   Pose(0.3, Eigen::Vector3d(0.1, 0.2, 0.3))));
    base = doc.last_created().at(0);
    doc.Execute(edit::SetRigidFixed(base, true));
    doc.Execute(edit::AddRigidPart("lid", Sphere(0.01, "lid_ball"),
                                   Pose(1.1, Eigen::Vector3d(-0.1, 0, 0.05))));
    lid = doc.last_created().at(0);
    modeling::SceneSeat seat;
    seat.on = "base";
    seat.position = Eigen::Vector3d(0, 0, 0.04);
    seat.rotation = Eigen::Quaterniond(Eigen::AngleAxisd(0.2, Eigen::Vector3d::UnitZ()));
    seat.position_tolerance = 0.003;
    doc.Execute(edit::SetRigidSeats(lid, {seat}));
    doc.Execute(edit::SetSnap(modeling::SceneSnap{2.0, 0.01, 0.006, 0.004}));
    doc.Execute(edit::SetDescription("every kind"));
    DocView view;
    view.position = Eigen::Vector3d(0.3, -0.7, 0.25);
    view.view_angle = 41.5;
    doc.set_view(view);
    haptics::SpidarGeometry frame;  // a scaled frame (the paper's Sec. 8)
    frame.a = 0.3;
    frame.b = 0.25;
    frame.c = 0.2;
    frame.d = 0.05;
    doc.set_device(frame);
  }
};

json SaveAndOpen(const Document& doc, const std::string& path, Document* into) {
  const_cast<Document&>(doc).Save(path);
  into->Load(path);
  return Canonical(*into);
}

TEST(DocumentIo, Base64MatchesRfc4648Vectors) {
  const std::pair<std::string, std::string> cases[] = {{"", ""},
                                                       {"f", "Zg=="},
                                                       {"fo", "Zm8="},
                                                       {"foo", "Zm9v"},
                                                       {"foob", "Zm9vYg=="},
                                                       {"fooba", "Zm9vYmE="},
                                                       {"foobar", "Zm9vYmFy"}};
  for (const auto& [plain, coded] : cases) {
    EXPECT_EQ(Base64Encode(plain.data(), plain.size()), coded);
    const std::vector<std::uint8_t> back = Base64Decode(coded);
    EXPECT_EQ(std::string(back.begin(), back.end()), plain);
  }
  EXPECT_THROW(Base64Decode("Zm9"), std::invalid_argument);
  EXPECT_THROW(Base64Decode("Zm!v"), std::invalid_argument);
  EXPECT_THROW(Base64Decode("Z=9v"), std::invalid_argument);
}

TEST(DocumentIo, EveryObjectKindSurvivesSaveAndOpen) {
  Fixture f;
  const std::string path = OutDir("every_kind") + "/doc.json";
  Document other;
  EXPECT_EQ(SaveAndOpen(f.doc, path, &other), Canonical(f.doc));
  EXPECT_FALSE(other.dirty());
  EXPECT_FALSE(f.doc.dirty());
  // The mesh made from the solid is still known to be up to date, the imported one has no source.
  EXPECT_FALSE(other.IsMeshOutOfDate(other.objects()[1].id));
  EXPECT_EQ(std::get<MeshData>(other.objects()[2].data).import_source, "/tmp/bunny.stl");
  const auto& fe = std::get<FeModelData>(other.objects()[3].data);
  EXPECT_EQ(fe.precompute_key, 0xfedcba9876543210ull);
  EXPECT_EQ(fe.element_order, 2);
  ASSERT_TRUE(other.view().has_value());
  EXPECT_EQ(other.view()->view_angle, 41.5);
  EXPECT_EQ(other.view()->position, Eigen::Vector3d(0.3, -0.7, 0.25));
  ASSERT_TRUE(other.device().has_value());
  EXPECT_EQ(other.device()->a, 0.3);
  EXPECT_EQ(other.device()->b, 0.25);
  EXPECT_EQ(other.device()->c, 0.2);
  EXPECT_EQ(other.device()->d, 0.05);
  // The pose comes back bit for bit.
  EXPECT_EQ(std::get<RigidPartData>(other.objects()[6].data).X_WP.matrix(),
            std::get<RigidPartData>(f.doc.Get(f.lid).data).X_WP.matrix());
  // Saving the reopened document gives the same bytes.
  const std::string again = OutDir("every_kind_again") + "/doc.json";
  other.Save(again);
  EXPECT_EQ(ReadText(again), ReadText(path));
}

TEST(DocumentIo, OutOfDateMeshStaysOutOfDateAfterOpen) {
  Fixture f;
  f.doc.Execute(edit::SetNodeField(f.solid, {0}, "radius", 0.06));
  ASSERT_TRUE(f.doc.IsMeshOutOfDate(f.mesh));
  Document other;
  SaveAndOpen(f.doc, OutDir("out_of_date") + "/doc.json", &other);
  EXPECT_TRUE(other.IsMeshOutOfDate(other.objects()[1].id));
}

// Undo and redo of an edit of each kind across a save: the history outlives the save, and what
// undo and redo give saves and reopens to the same content.
TEST(DocumentIo, UndoAndRedoOfEachKindWorkAcrossASave) {
  const std::vector<std::pair<std::string, std::function<std::unique_ptr<Command>(const Fixture&)>>>
      edits = {
          {"solid",
           [](const Fixture& f) { return edit::SetNodeField(f.solid, {1}, "radius", 0.025); }},
          {"add solid",
           [](const Fixture&) { return edit::AddSolid("extra", Sphere(0.2, "extra")); }},
          {"mesh",
           [](const Fixture& f) {
             MeshData m = std::get<MeshData>(f.doc.Get(f.mesh).data);
             m.settings.cell_size = 0.002;
             return edit::SetObjectData(f.mesh, m);
           }},
          {"delete mesh", [](const Fixture& f) { return edit::DeleteObject(f.mesh); }},
          {"fe material",
           [](const Fixture& f) {
             return edit::SetFeMaterial(f.fe, fem::Material{1e9, 0.4});
           }},
          {"fe loads", [](const Fixture& f) { return edit::SetFeLoads(f.fe, {}); }},
          {"fe order", [](const Fixture& f) { return edit::SetElementOrder(f.fe, 1); }},
          {"fe regions",
           [](const Fixture& f) {
             return edit::SetRegionMaterials(f.fe, {{1, fem::Material{3e9, 0.2}}});
           }},
          {"delete fe", [](const Fixture& f) { return edit::DeleteObject(f.fe); }},
          {"sculpt stroke",
           [](const Fixture& f) {
             Eigen::Matrix3Xd p(3, 2);
             p << 0.5, 0.6, 0.5, 0.6, 0.5, 0.6;
             return edit::SculptStroke(f.sculpt, {1, 3}, p);
           }},
          {"sculpt replace",
           [](const Fixture& f) {
             return edit::ReplaceSculptMesh(f.sculpt, RandomMesh(20, 10, 9));
           }},
          {"delete sculpt", [](const Fixture& f) { return edit::DeleteObject(f.sculpt); }},
          {"part pose",
           [](const Fixture& f) {
             return edit::SetRigidPose(f.lid, Pose(0.7, Eigen::Vector3d(0.01, 0.02, 0.03)));
           }},
          {"part fixed", [](const Fixture& f) { return edit::SetRigidFixed(f.lid, true); }},
          {"part seats", [](const Fixture& f) { return edit::SetRigidSeats(f.lid, {}); }},
          {"delete part", [](const Fixture& f) { return edit::DeleteObject(f.lid); }},
          {"snap", [](const Fixture&) { return edit::SetSnap(std::nullopt); }},
          {"duplicate sculpt", [](const Fixture& f) { return edit::DuplicateObject(f.sculpt); }},
          {"rename", [](const Fixture& f) { return edit::RenameObject(f.fe, "renamed"); }},
          {"move", [](const Fixture& f) { return edit::MoveObject(f.lid, 0); }},
      };
  for (std::size_t e = 0; e < edits.size(); ++e) {
    const auto& [name, make] = edits[e];
    SCOPED_TRACE(name);
    Fixture f;
    const json before = Canonical(f.doc);
    f.doc.Execute(make(f));
    const json after = Canonical(f.doc);
    ASSERT_NE(after, before);
    const std::string path = OutDir("undo_" + std::to_string(e)) + "/doc.json";
    Document reopened;
    EXPECT_EQ(SaveAndOpen(f.doc, path, &reopened), after);
    ASSERT_TRUE(f.doc.Undo());
    EXPECT_TRUE(f.doc.dirty());
    EXPECT_EQ(Canonical(f.doc), before);
    Document undone;
    EXPECT_EQ(SaveAndOpen(f.doc, path, &undone), before);
    ASSERT_TRUE(f.doc.Redo());
    EXPECT_EQ(Canonical(f.doc), after);
    Document redone;
    EXPECT_EQ(SaveAndOpen(f.doc, path, &redone), after);
    // The reopened copy is editable with the same commands: undo of a fresh edit restores it.
    const json reopened_state = Canonical(redone);
    redone.Execute(edit::SetDescription("edited after open"));
    ASSERT_TRUE(redone.Undo());
    EXPECT_EQ(Canonical(redone), reopened_state);
  }
}

// Every shipped version 1 scene opens as modeling's own reader reads it, and a document of
// solids only is saved as version 1 again (so that older readers still open it).
TEST(DocumentIo, Version1ScenesOpenUnchangedAndSaveAsVersion1) {
  for (const char* name : {"platform", "clay", "assembly"}) {
    SCOPED_TRACE(name);
    const std::string source =
        std::string(SPIDARCAD_SOURCE_DIR) + "/assets/scenes/" + name + ".json";
    const modeling::Scene expected = modeling::LoadScene(source);
    Document doc;
    EXPECT_EQ(doc.Load(source), 1);
    EXPECT_EQ(modeling::SceneToJson(doc.ToScene()), modeling::SceneToJson(expected));
    const std::string path = OutDir(std::string("v1_") + name) + "/scene.json";
    doc.Save(path);
    const json written = json::parse(ReadText(path));
    EXPECT_EQ(written.at("version"), 1);
    EXPECT_EQ(modeling::SceneToJson(modeling::LoadScene(path)), modeling::SceneToJson(expected));
  }
}

// A bad version 1 scene (the document reader parses its text once and hands that JSON to the
// scene reader) fails with exactly the error modeling's own reader gives for the same file:
// file, line, column, JSON pointer and message, for a semantic error deep in a part's seat, a
// bad field of a solid, a number beyond a double and a syntax error.
TEST(DocumentIo, BadVersion1SceneGivesTheSceneReadersOwnError) {
  const std::string head =
      "{\n  \"format\": \"spidarcad-scene\",\n  \"version\": 1,\n  \"solids\": [\n"
      "    {\"name\": \"a\", \"root\": {\"type\": \"sphere\", \"radius\": 0.1}},\n"
      "    {\"name\": \"b\", \"root\": {\"type\": \"sphere\", \"radius\": 0.05}}\n  ]";
  const std::vector<std::string> bodies = {
      ",\n  \"parts\": [{\"name\": \"p\", \"solid\": \"a\"},\n"
      "    {\"name\": \"q\", \"solid\": \"b\", \"seats\": [{\"on\": \"ghost\"}]}]\n}\n",
      ",\n  \"parts\": [{\"name\": \"p\", \"solid\": \"nothing\"}]\n}\n",
      ",\n  \"snap\": {\"max_force\": 1e999}\n}\n",
      ",\n  \"snap\": {\"max_force\": -1}\n}\n",
      ",\n  \"parts\": [,]\n}\n",
  };
  const std::string path = OutDir("bad_v1") + "/scene.json";
  for (const std::string& body : bodies) {
    SCOPED_TRACE(body);
    WriteText(path, head + body);
    std::string expected;
    try {
      modeling::LoadScene(path);
      ADD_FAILURE() << "the scene reader took it";
    } catch (const modeling::SceneError& e) {
      expected = e.what();
      EXPECT_GT(e.line(), 0) << e.what();
    }
    Document doc;
    try {
      doc.Load(path);
      ADD_FAILURE() << "no error";
    } catch (const modeling::SceneError& e) {
      EXPECT_EQ(std::string(e.what()), expected);
    }
  }
}

// Mesh arrays are stored as base64 of the raw little-endian doubles and int32s, not as JSON
// numbers: decoding the text gives the vertex coordinates back exactly.
TEST(DocumentIo, LargeArraysAreStoredAsRawBytes) {
  Document doc;
  const SculptMesh mesh = RandomMesh(1000, 1500, 4);
  doc.Execute(edit::AddSculpt("clay", mesh));
  const std::string path = OutDir("raw") + "/doc.json";
  doc.Save(path);
  const json j = json::parse(ReadText(path));
  const json& vertices = j.at("objects").at(0).at("mesh").at("vertices");
  EXPECT_EQ(vertices.at("dtype"), "f64");
  EXPECT_EQ(vertices.at("shape"), json::array({1000, 3}));
  const std::string text = vertices.at("base64").get<std::string>();
  EXPECT_EQ(text.size(), (1000u * 3 * 8 + 2) / 3 * 4);
  const std::vector<std::uint8_t> bytes = Base64Decode(text);
  ASSERT_EQ(bytes.size(), 1000u * 3 * 8);
  for (int v = 0; v < 1000; v += 97) {
    for (int r = 0; r < 3; ++r) {
      double x;
      std::memcpy(&x, bytes.data() + 8 * (3 * v + r), 8);
      EXPECT_EQ(x, mesh.vertices(r, v));
    }
  }
  const json& triangles = j.at("objects").at(0).at("mesh").at("triangles");
  EXPECT_EQ(triangles.at("dtype"), "i32");
  EXPECT_EQ(triangles.at("shape"), json::array({1500, 3}));
  // The file is about the size of the raw arrays (4/3 for base64), not of decimal numbers.
  const double raw = 1000.0 * 3 * 8 + 1500.0 * 3 * 4;
  EXPECT_LT(static_cast<double>(fs::file_size(path)), raw * 4 / 3 + 2000);
}

// Hand-written files may list small arrays as JSON numbers; a sculpt or a mesh can be generated
// at open time from a solid (the shipped examples do).
TEST(DocumentIo, GeneratedMeshesMatchTheirSolid) {
  const std::string path = OutDir("generate") + "/doc.json";
  const double r = 0.05, h = 0.005;
  WriteText(
      path,
      json{{"format", "spidarcad-scene"},
           {"version", 2},
           {"objects",
            {{{"kind", "solid"}, {"name", "ball"}, {"root", {{"type", "sphere"}, {"radius", r}}}},
             {{"kind", "mesh"},
              {"name", "ball tets"},
              {"source", 0},
              {"generate", "volume"},
              {"settings", {{"cell_size", h}}}},
             {{"kind", "sculpt"},
              {"name", "clay"},
              {"generate_from", {{"root", {{"type", "sphere"}, {"radius", r}}}, {"cell_size", h}}}},
             {{"kind", "sculpt"},
              {"name", "tri"},
              {"mesh",
               {{"vertices", {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}}}, {"triangles", {{0, 1, 2}}}}}}}}}
          .dump(1));
  Document doc;
  doc.Load(path);
  ASSERT_EQ(doc.objects().size(), 4u);
  const auto& mesh = std::get<MeshData>(doc.objects()[1].data);
  ASSERT_TRUE(mesh.volume && mesh.surface);
  EXPECT_FALSE(doc.IsMeshOutOfDate(doc.objects()[1].id));
  const double volume = modeling::TotalVolume(*mesh.volume);
  EXPECT_NEAR(volume, 4.0 / 3.0 * std::numbers::pi * r * r * r,
              0.05 * 4.0 / 3.0 * std::numbers::pi * r * r * r);
  const SculptMesh& clay = *std::get<SculptData>(doc.objects()[2].data).mesh;
  ASSERT_GT(clay.vertices.cols(), 100);
  for (Eigen::Index v = 0; v < clay.vertices.cols(); ++v)
    EXPECT_NEAR(clay.vertices.col(v).norm(), r, 0.2 * h);
  const SculptMesh& tri = *std::get<SculptData>(doc.objects()[3].data).mesh;
  EXPECT_EQ(tri.vertices.col(1), Eigen::Vector3d(1, 0, 0));
  EXPECT_EQ(tri.triangles.col(0), Eigen::Vector3i(0, 1, 2));
}

// A mesh or sculpt the file asks to be made at open time, too large to make there (a sphere
// 2 m across at 2 mm cells: millions of triangles, minutes with TetGen): refused from the
// estimate, naming its cell size, and nothing is loaded. (The libFuzzer document harness found a
// smooth union whose 5 m blend radius made the platform's FE mesh as large: tests/fuzz/
// regressions/document/.)
TEST(DocumentIo, GeneratedMeshTooLargeToMakeAtOpenIsRefused) {
  const std::string path = OutDir("generate_large") + "/doc.json";
  const json ball = {{"type", "sphere"}, {"radius", 1.0}};
  const json solid = {{"kind", "solid"}, {"name", "ball"}, {"root", ball}};
  const json mesh = {{"kind", "mesh"},
                     {"name", "ball tets"},
                     {"source", 0},
                     {"generate", "volume"},
                     {"settings", {{"cell_size", 0.002}}}};
  const json sculpt = {{"kind", "sculpt"},
                       {"name", "clay"},
                       {"generate_from", {{"root", ball}, {"cell_size", 0.002}}}};
  for (const auto& [objects, pointer] :
       {std::pair{json::array({solid, mesh}), "/objects/1/settings/cell_size"},
        std::pair{json::array({sculpt}), "/objects/0/generate_from/cell_size"}}) {
    SCOPED_TRACE(pointer);
    WriteText(path,
              json{{"format", "spidarcad-scene"}, {"version", 2}, {"objects", objects}}.dump(1));
    Document doc;
    try {
      doc.Load(path);
      ADD_FAILURE() << "loaded";
    } catch (const modeling::SceneError& e) {
      EXPECT_EQ(e.pointer(), pointer) << e.what();
      const std::string what = e.what();
      EXPECT_NE(what.find("meshing at open time would make about"), std::string::npos) << what;
      EXPECT_NE(what.find("raise the cell size"), std::string::npos) << what;
    }
    EXPECT_TRUE(doc.objects().empty());
  }
}

struct BadCase {
  const char* name;
  std::string text;
  int line;
  const char* pointer;
  const char* message;  // a part of the message
};

// Each bad file: SceneError with the file, the line of the field and its JSON pointer; the
// document keeps its content.
TEST(DocumentIo, BadFileNamesLineAndFieldAndLeavesDocumentUnchanged) {
  const std::string header =
      "{\n\"format\": \"spidarcad-scene\",\n\"version\": 2,\n\"objects\": [\n";
  const std::string solid =
      "{\"kind\": \"solid\", \"name\": \"s\", \"root\": {\"type\": \"sphere\", \"id\": \"a\", "
      "\"radius\": 0.1}}";
  const std::string tets =
      "{\"kind\": \"mesh\", \"name\": \"m\", \"volume\": {\"nodes\": "
      "[[0,0,0],[1,0,0],[0,1,0],[0,0,1]], \"tets\": [[0,1,2,3]]}}";
  const std::vector<BadCase> cases = {
      {"unknown kind", "{\"kind\": \"teapot\", \"name\": \"x\"}", 5, "/objects/0/kind",
       "unknown kind"},
      {"bad radius",
       "{\"kind\": \"solid\", \"name\": \"s\", \"root\": {\"type\": \"sphere\", \"radius\": -1}}",
       5, "/objects/0/root/radius", "radius"},
      {"tet index",
       "{\"kind\": \"mesh\", \"name\": \"m\", \"volume\": {\"nodes\": [[0,0,0]], \"tets\": "
       "[[0,1,2,3]]}}",
       5, "/objects/0/volume/tets", "outside"},
      {"bad base64",
       "{\"kind\": \"sculpt\", \"name\": \"c\", \"mesh\": {\"vertices\": {\"dtype\": \"f64\", "
       "\"shape\": [1, 3], "
       "\"base64\": \"AAAA\"}, \"triangles\": []}}",
       5, "/objects/0/mesh/vertices/base64", "bytes"},
      {"fe without tets",
       "{\"kind\": \"fe_model\", \"name\": \"f\", \"tet_mesh\": 7, \"material\": "
       "{\"youngs_modulus\": 1e9, "
       "\"poisson_ratio\": 0.3}}",
       5, "/objects/0/tet_mesh", "index"},
      {"fe material",
       (tets + ",\n{\"kind\": \"fe_model\", \"name\": \"f\", \"tet_mesh\": 0, \"material\": "
               "{\"youngs_modulus\": "
               "1e9, \"poisson_ratio\": 0.7}}"),
       6, "/objects/1/material", "0.7"},
      {"repeated node id", solid + ",\n" + solid, 6, "/objects/1/root/id", "already used"},
      {"seat on nothing",
       "{\"kind\": \"rigid_part\", \"name\": \"p\", \"root\": {\"type\": \"sphere\", \"radius\": "
       "0.1}, "
       "\"position\": [0,0,0], \"seats\": [{\"on\": \"ghost\", \"position\": [0,0,0]}]}",
       5, "/objects/0/seats/0/on", "ghost"},
  };
  for (const BadCase& c : cases) {
    SCOPED_TRACE(c.name);
    const std::string path = OutDir("bad") + "/bad.json";
    WriteText(path, header + c.text + "\n]\n}\n");
    Fixture f;
    const json before = f.doc.ToJson(true);
    const std::uint64_t revision = f.doc.revision();
    try {
      f.doc.Load(path);
      ADD_FAILURE() << "no error";
    } catch (const modeling::SceneError& e) {
      EXPECT_EQ(e.file(), path);
      EXPECT_EQ(e.line(), c.line) << e.what();
      EXPECT_EQ(e.pointer(), c.pointer) << e.what();
      EXPECT_NE(std::string(e.what()).find(c.message), std::string::npos) << e.what();
    }
    EXPECT_EQ(f.doc.ToJson(true), before);
    EXPECT_EQ(f.doc.revision(), revision);
    EXPECT_TRUE(f.doc.history().CanUndo());
  }
}

TEST(DocumentIo, DeviceFrameTheGripCannotFitInIsRefusedNamingTheLineAndField) {
  // A pole half-length of 0.3 m does not fit a frame of half-side 0.2 m (d < min(a, b, c)).
  const std::string path = OutDir("bad_device") + "/bad.json";
  WriteText(path,
            "{\n\"format\": \"spidarcad-scene\",\n\"version\": 2,\n\"device\": {\"frame\": "
            "[0.3, 0.3, 0.2],\n  \"pole\": 0.3},\n\"objects\": []\n}\n");
  Fixture f;
  const json before = f.doc.ToJson(true);
  try {
    f.doc.Load(path);
    ADD_FAILURE() << "no error";
  } catch (const modeling::SceneError& e) {
    EXPECT_EQ(e.file(), path);
    EXPECT_EQ(e.pointer(), "/device") << e.what();
    EXPECT_EQ(e.line(), 4) << e.what();
    EXPECT_NE(std::string(e.what()).find("pole"), std::string::npos) << e.what();
  }
  EXPECT_EQ(f.doc.ToJson(true), before);
}

TEST(DocumentIo, NewerVersionAndSyntaxErrorsNameTheLine) {
  const std::string path = OutDir("version") + "/doc.json";
  WriteText(path,
            "{\n  \"format\": \"spidarcad-scene\",\n  \"version\": 3,\n  \"objects\": []\n}\n");
  Document doc;
  try {
    doc.Load(path);
    ADD_FAILURE() << "no error";
  } catch (const modeling::SceneError& e) {
    EXPECT_EQ(e.line(), 3);
    EXPECT_EQ(e.pointer(), "/version");
  }
  WriteText(path,
            "{\n  \"format\": \"spidarcad-scene\",\n  \"version\": 2,\n  \"objects\": [,]\n}\n");
  try {
    doc.Load(path);
    ADD_FAILURE() << "no error";
  } catch (const modeling::SceneError& e) {
    EXPECT_EQ(e.line(), 4);
  }
}

// A failed save leaves the old file byte for byte and no temporary file; a successful one
// leaves only the file.
TEST(DocumentIo, SaveIsAtomic) {
  const std::string dir = OutDir("atomic");
  const std::string path = dir + "/doc.json";
  Fixture f;
  f.doc.Save(path);
  const std::string first = ReadText(path);
  EXPECT_EQ(std::distance(fs::directory_iterator(dir), fs::directory_iterator()), 1);
  EXPECT_THROW(f.doc.Save(dir + "/missing/doc.json"), modeling::SceneError);
  f.doc.Execute(edit::SetDescription("changed"));
  fs::permissions(dir, fs::perms::owner_read | fs::perms::owner_exec);
  const bool can_still_write = ::access(dir.c_str(), W_OK) == 0;  // root ignores permissions
  if (!can_still_write) {
    EXPECT_THROW(f.doc.Save(path), modeling::SceneError);
    EXPECT_TRUE(f.doc.dirty());
  }
  fs::permissions(dir, fs::perms::owner_all);
  EXPECT_EQ(ReadText(path), first);
  EXPECT_EQ(std::distance(fs::directory_iterator(dir), fs::directory_iterator()), 1);
}

TEST(DocumentIo, MeshSettingsKeepTheMesherSharpEdgesAndSlabPlanes) {
  const std::string dir = OutDir("mesher");
  Document doc;
  doc.Execute(edit::AddSolid("ball", ImplicitNode(modeling::SphereParams{0.05}, {}, "ball")));
  const ObjectId ball = doc.last_created().front();
  const auto tets = std::make_shared<modeling::TetMesh>();
  tets->nodes.resize(3, 4);
  tets->nodes << 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1;
  tets->tets.resize(4, 1);
  tets->tets << 0, 1, 2, 3;
  tets->regions = Eigen::VectorXi::Zero(1);
  for (const auto& [mesher, sharp, surface_mesher] :
       std::vector<std::tuple<std::string, bool, std::string>>{{"cgal", false, ""},
                                                               {"tetgen", true, ""},
                                                               {"", false, ""},
                                                               {"tetgen", true, "lattice"}}) {
    MeshData m;
    m.source = ball;
    m.source_revision = doc.Get(ball).revision;
    m.volume = tets;
    m.settings.cell_size = 0.01;
    m.settings.mesher = mesher;
    m.settings.sharp_edges = sharp;
    m.settings.surface_mesher = surface_mesher;
    if (mesher == "tetgen" && surface_mesher.empty()) {
      m.settings.slab_planes = {-0.0251, 0.0003, 0.025};
      m.settings.slab_strip_axis = 2;
      m.settings.slab_strips = {{-0.0333, 0.0341}, {}, {}, {0.0001}};
    }
    if (mesher.empty()) m.settings.flat_cells = 0.37;  // FE mode's quadratic elements
    doc.Execute(edit::AddObject("tets " + mesher + surface_mesher, m));
  }
  const std::string path = dir + "/doc.json";
  doc.Save(path);
  Document other;
  other.Load(path);
  ASSERT_EQ(other.objects().size(), 5u);
  const std::string expected_mesher[] = {"cgal", "tetgen", "", "tetgen"};
  const bool expected_sharp[] = {false, true, false, true};
  for (int i = 0; i < 4; ++i) {
    const auto& m = std::get<MeshData>(other.objects()[i + 1].data);
    EXPECT_EQ(m.settings.mesher, expected_mesher[i]) << i;
    EXPECT_EQ(m.settings.sharp_edges, expected_sharp[i]) << i;
    EXPECT_EQ(m.settings.surface_mesher, i == 3 ? "lattice" : "") << i;
    EXPECT_EQ(m.settings.cell_size, 0.01);
    EXPECT_EQ(m.settings.flat_cells, i == 2 ? 0.37 : 0.0) << i;
    EXPECT_EQ(m.settings.slab_planes,
              (i == 1 ? std::vector<double>{-0.0251, 0.0003, 0.025} : std::vector<double>{}))
        << i;  // bit for bit
    EXPECT_EQ(m.settings.slab_strips,
              (i == 1 ? std::vector<std::vector<double>>{{-0.0333, 0.0341}, {}, {}, {0.0001}}
                      : std::vector<std::vector<double>>{}))
        << i;
    if (i == 1) {
      EXPECT_EQ(m.settings.slab_strip_axis, 2);
    }
  }
  // Refused: an unknown mesher, and "generate" with what only the window's meshing does.
  const std::string solid =
      "{\"kind\": \"solid\", \"name\": \"s\", \"root\": {\"type\": \"sphere\", "
      "\"radius\": 0.05}}";
  const struct {
    std::string mesh;
    const char* pointer;
    const char* message;
  } bad[] = {
      {"{\"kind\": \"mesh\", \"name\": \"m\", \"source\": 0, \"generate\": \"volume\", "
       "\"settings\": {\"cell_size\": 0.01, \"mesher\": \"gmsh\"}}",
       "/objects/1/settings/mesher", "tetgen"},
      {"{\"kind\": \"mesh\", \"name\": \"m\", \"source\": 0, \"generate\": \"volume\", "
       "\"settings\": {\"cell_size\": 0.01, \"mesher\": \"cgal\"}}",
       "/objects/1/generate", "store the mesh"},
      {"{\"kind\": \"mesh\", \"name\": \"m\", \"source\": 0, \"generate\": \"volume\", "
       "\"settings\": {\"cell_size\": 0.01, \"slab_planes\": [0.01, 0.01]}}",
       "/objects/1/settings/slab_planes/1", "the planes must increase"},
      {"{\"kind\": \"mesh\", \"name\": \"m\", \"source\": 0, \"generate\": \"volume\", "
       "\"settings\": {\"cell_size\": 0.01, \"slab_planes\": 0.01}}",
       "/objects/1/settings/slab_planes", "expected an array"},
      {"{\"kind\": \"mesh\", \"name\": \"m\", \"source\": 0, \"generate\": \"volume\", "
       "\"settings\": {\"cell_size\": 0.01, \"slab_planes\": [\"x\"]}}",
       "/objects/1/settings/slab_planes/0", "expected a number"},
      {"{\"kind\": \"mesh\", \"name\": \"m\", \"source\": 0, \"generate\": \"volume\", "
       "\"settings\": {\"cell_size\": 0.01, \"slab_planes\": [0.01], \"slab_strips\": "
       "{\"axis\": \"x\", \"planes\": [[], []]}}}",
       "/objects/1/settings/slab_strips/axis", "expected \"y\" or \"z\""},
      {"{\"kind\": \"mesh\", \"name\": \"m\", \"source\": 0, \"generate\": \"volume\", "
       "\"settings\": {\"cell_size\": 0.01, \"slab_planes\": [0.01], \"slab_strips\": "
       "{\"axis\": \"y\", \"planes\": [[]]}}}",
       "/objects/1/settings/slab_strips/planes", "one list per slab (2"},
      {"{\"kind\": \"mesh\", \"name\": \"m\", \"source\": 0, \"generate\": \"volume\", "
       "\"settings\": {\"cell_size\": 0.01, \"slab_planes\": [0.01], \"slab_strips\": "
       "{\"axis\": \"y\", \"planes\": [[0.02, 0.01], []]}}}",
       "/objects/1/settings/slab_strips/planes/0/1", "the planes must increase"},
      {"{\"kind\": \"mesh\", \"name\": \"m\", \"source\": 0, \"generate\": \"volume\", "
       "\"settings\": {\"cell_size\": 0.01, \"surface_mesher\": \"dual\"}}",
       "/objects/1/settings/surface_mesher", "expected \"lattice\""},
      {"{\"kind\": \"mesh\", \"name\": \"m\", \"source\": 0, \"generate\": \"volume\", "
       "\"settings\": {\"cell_size\": 0.01, \"mesher\": \"cgal\", \"surface_mesher\": "
       "\"lattice\"}}",
       "/objects/1/settings/surface_mesher", "CGAL"},
      {"{\"kind\": \"mesh\", \"name\": \"m\", \"source\": 0, \"generate\": \"volume\", "
       "\"settings\": {\"cell_size\": 0.01, \"surface_mesher\": \"lattice\"}}",
       "/objects/1/generate", "store the mesh"},
      {"{\"kind\": \"mesh\", \"name\": \"m\", \"source\": 0, \"generate\": \"volume\", "
       "\"settings\": {\"cell_size\": 0.01, \"flat_cells\": 2}}",
       "/objects/1/settings/flat_cells", "in [0, 1]"},
      {"{\"kind\": \"mesh\", \"name\": \"m\", \"source\": 0, \"generate\": \"volume\", "
       "\"settings\": {\"cell_size\": 0.01, \"flat_cells\": \"half\"}}",
       "/objects/1/settings/flat_cells", "expected a number"},
      {"{\"kind\": \"mesh\", \"name\": \"m\", \"source\": 0, \"generate\": \"volume\", "
       "\"settings\": {\"cell_size\": 0.01, \"surface_mesher\": \"lattice\", "
       "\"flat_cells\": 0.5}}",
       "/objects/1/settings/flat_cells", "marching-tetrahedra surface"},
      {"{\"kind\": \"mesh\", \"name\": \"m\", \"source\": 0, \"generate\": \"volume\", "
       "\"settings\": {\"cell_size\": 0.01, \"flat_cells\": 0.5}}",
       "/objects/1/generate", "settings/flat_cells"},
  };
  for (const auto& c : bad) {
    WriteText(path, "{\n\"format\": \"spidarcad-scene\",\n\"version\": 2,\n\"objects\": [\n" +
                        solid + ",\n" + c.mesh + "\n]\n}\n");
    try {
      other.Load(path);
      ADD_FAILURE() << "no error for " << c.mesh;
    } catch (const modeling::SceneError& e) {
      EXPECT_EQ(e.pointer(), c.pointer) << e.what();
      EXPECT_NE(std::string(e.what()).find(c.message), std::string::npos) << e.what();
    }
  }
}

}  // namespace
}  // namespace spidarcad::app
