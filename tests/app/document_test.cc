// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
// The Document and its edit commands: every command's Do/Undo/Redo against scene serialisations,
// the strong guarantee of invalid edits, a randomized undo/redo property test, revisions, the
// dirty flag and Save/Load.
#include "doc/document.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <functional>
#include <random>
#include <set>
#include <string>
#include <vector>

#include "doc/clipboard.h"
#include "doc/command.h"
#include "doc/input_error.h"

namespace spidarcad::app {
namespace {

using modeling::ImplicitNode;
using nlohmann::json;

// Scene file text of the solids (modeling's serialiser, independent of the Document's ToJson).
std::string SceneText(const Document& doc) { return modeling::SceneToJson(doc.ToScene()).dump(); }
// Everything (all object kinds, with revisions).
std::string FullText(const Document& doc) { return doc.ToJson(true).dump() + SceneText(doc); }

ImplicitNode Sphere(double r, std::string id = {}) {
  return ImplicitNode(modeling::SphereParams{r}, {}, std::move(id));
}
ImplicitNode Box(std::string id = {}) {
  return ImplicitNode(modeling::BoxParams{}, {}, std::move(id));
}

// union u { sphere ball, translate t { box b }, sphere pip }
ImplicitNode PlatformTree() {
  ImplicitNode translate(modeling::TranslateParams{Eigen::Vector3d(0.1, 0, 0)}, {Box("b")}, "t");
  ImplicitNode root(modeling::UnionParams{}, {Sphere(0.05, "ball"), translate, Sphere(0.01, "pip")},
                    "u");
  root.children[0].name = "ball";
  return root;
}

modeling::TetMesh TinyTetMesh() {
  modeling::TetMesh m;
  m.nodes.resize(3, 4);
  m.nodes << 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1;
  m.tets.resize(4, 1);
  m.tets << 0, 1, 2, 3;
  m.regions = Eigen::VectorXi::Zero(1);
  return m;
}

SculptMesh TinyTriangleMesh() {
  SculptMesh m;
  m.vertices.resize(3, 4);
  m.vertices << 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1;
  m.triangles.resize(3, 4);
  m.triangles << 0, 0, 0, 1, 2, 1, 3, 2, 1, 3, 2, 3;
  return m;
}

// A document with one object of every kind.
struct Fixture {
  Document doc;
  ObjectId platform = 0, knob = 0, mesh = 0, fe = 0, clay = 0, part = 0;
  Fixture() {
    modeling::Scene scene;
    scene.description = "test scene";
    scene.solids.push_back({"platform", PlatformTree()});
    ImplicitNode cyl(modeling::CylinderParams{0.02, 0.04}, {}, "c");
    scene.solids.push_back({"knob", cyl});
    doc.LoadScene(scene);
    platform = doc.objects()[0].id;
    knob = doc.objects()[1].id;
    doc.Execute(edit::AddMesh("platform mesh", platform, doc.Get(platform).revision, nullptr,
                              std::make_shared<const modeling::TetMesh>(TinyTetMesh())));
    mesh = doc.last_created().at(0);
    doc.Execute(edit::AddFeModel("platform fe", mesh, fem::Material{2e9, 0.3}, {}));
    fe = doc.last_created().at(0);
    doc.Execute(edit::AddSculpt("clay", TinyTriangleMesh()));
    clay = doc.last_created().at(0);
    doc.Execute(edit::AddRigidPart(
        "lid", ImplicitNode(modeling::UnionParams{}, {Sphere(0.03, "lid_ball")}, "lid"),
        Eigen::Isometry3d::Identity()));
    part = doc.last_created().at(0);
    doc.history().Clear();
  }
};

struct NamedEdit {
  std::string name;
  std::function<std::unique_ptr<Command>(const Fixture&)> make;
};

std::vector<NamedEdit> EveryEdit() {
  Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();
  pose.translate(Eigen::Vector3d(0.1, 0.2, 0.3));
  pose.rotate(Eigen::AngleAxisd(0.5, Eigen::Vector3d::UnitZ()));
  return {
      {"AddSolid", [](const Fixture&) { return edit::AddSolid("new", Sphere(0.1), 1); }},
      {"DeleteSolid", [](const Fixture& f) { return edit::DeleteObject(f.platform); }},
      {"DeleteMeshCascades", [](const Fixture& f) { return edit::DeleteObject(f.mesh); }},
      {"RenameObject", [](const Fixture& f) { return edit::RenameObject(f.knob, "handle"); }},
      {"MoveObject", [](const Fixture& f) { return edit::MoveObject(f.knob, 0); }},
      {"DuplicateSolid", [](const Fixture& f) { return edit::DuplicateObject(f.platform); }},
      {"DuplicateSculpt", [](const Fixture& f) { return edit::DuplicateObject(f.clay); }},
      {"SetDescription", [](const Fixture&) { return edit::SetDescription("new text"); }},
      {"AddNode",
       [](const Fixture& f) { return edit::AddNode(f.platform, {1}, 0, Sphere(0.02, "s2")); }},
      {"WrapNode",
       [](const Fixture& f) {
         return edit::WrapNode(f.platform, {0}, modeling::TranslateParams{}, "w");
       }},
      {"WrapRoot",
       [](const Fixture& f) { return edit::WrapNode(f.knob, {}, modeling::OffsetParams{0.001}); }},
      {"DeleteNode", [](const Fixture& f) { return edit::DeleteNode(f.platform, {1}); }},
      {"SetNodeParams",
       [](const Fixture& f) {
         return edit::SetNodeParams(f.platform, {0}, modeling::SphereParams{0.07}, "radius");
       }},
      {"SetNodeField",
       [](const Fixture& f) {
         return edit::SetNodeField(f.platform, {1, 0}, "size", json::array({0.1, 0.2, 0.3}));
       }},
      {"SetNodeId",
       [](const Fixture& f) { return edit::SetNodeField(f.platform, {2}, "id", "pip2"); }},
      {"SetNodeName", [](const Fixture& f) { return edit::SetNodeName(f.platform, {2}, "pip"); }},
      {"MoveNodeSameTree",
       [](const Fixture& f) { return edit::MoveNode(f.platform, {0}, f.platform, {1}, 1); }},
      {"MoveNodeAcrossTrees",
       [](const Fixture& f) { return edit::MoveNode(f.platform, {2}, f.part, {}, -1); }},
      {"ReorderNode", [](const Fixture& f) { return edit::ReorderNode(f.platform, {2}, 0); }},
      {"ReplaceTree", [](const Fixture& f) { return edit::ReplaceTree(f.knob, Box("kb")); }},
      {"AddMesh",
       [](const Fixture& f) {
         return edit::AddMesh("surf", f.knob, 1,
                              std::make_shared<const modeling::TriangleMesh>(TinyTriangleMesh()),
                              nullptr);
       }},
      {"AddFeModel",
       [](const Fixture& f) { return edit::AddFeModel("fe2", f.mesh, fem::Material{}, {}); }},
      {"SetFeMaterial",
       [](const Fixture& f) {
         return edit::SetFeMaterial(f.fe, fem::Material{7e10, 0.33});
       }},
      {"SetFixedBoxes",
       [](const Fixture& f) {
         return edit::SetFixedBoxes(
             f.fe, {Eigen::AlignedBox3d(Eigen::Vector3d(-1, -1, -1), Eigen::Vector3d(1, 1, 0.1))});
       }},
      {"AddSculpt", [](const Fixture&) { return edit::AddSculpt("clay2", TinyTriangleMesh()); }},
      {"ReplaceSculptMesh",
       [](const Fixture& f) {
         SculptMesh m = TinyTriangleMesh();
         m.vertices *= 2.0;
         return edit::ReplaceSculptMesh(f.clay, m);
       }},
      {"SculptStroke",
       [](const Fixture& f) {
         Eigen::Matrix3Xd p(3, 2);
         p << 0.5, 0.6, 0.5, 0.6, 0.5, 0.6;
         return edit::SculptStroke(f.clay, {1, 3}, p);
       }},
      {"AddRigidPart",
       [pose](const Fixture&) { return edit::AddRigidPart("part2", Box("pb"), pose); }},
      {"SetRigidPose", [pose](const Fixture& f) { return edit::SetRigidPose(f.part, pose); }},
      {"SetRigidFixed", [](const Fixture& f) { return edit::SetRigidFixed(f.part, true); }},
      {"SetRigidSeats",
       [](const Fixture& f) {
         modeling::SceneSeat seat;
         seat.on = "base";
         seat.position = Eigen::Vector3d(0, 0, 0.01);
         return edit::SetRigidSeats(f.part, {seat});
       }},
      {"SetFeLoads",
       [](const Fixture& f) {
         return edit::SetFeLoads(
             f.fe, {{Eigen::AlignedBox3d(Eigen::Vector3d::Zero(), Eigen::Vector3d::Ones()),
                     Eigen::Vector3d(0, 0, -1)}});
       }},
      {"SetRegionMaterials",
       [](const Fixture& f) {
         return edit::SetRegionMaterials(f.fe, {{0, fem::Material{7e10, 0.33}}});
       }},
      {"SetElementOrder", [](const Fixture& f) { return edit::SetElementOrder(f.fe, 2); }},
      {"SetPrecomputeKey", [](const Fixture& f) { return edit::SetPrecomputeKey(f.fe, 42); }},
      {"SetSnap", [](const Fixture&) { return edit::SetSnap(modeling::SceneSnap{}); }},
      {"AddObjectSculpt",
       [](const Fixture&) {
         return edit::AddObject("clay3",
                                SculptData{std::make_shared<SculptMesh>(TinyTriangleMesh())});
       }},
      {"SetObjectDataMesh",
       [](const Fixture& f) {
         MeshData m = std::get<MeshData>(f.doc.Get(f.mesh).data);
         m.import_source = "part.vtu";
         return edit::SetObjectData(f.mesh, m);
       }},
      {"PasteAsSolid",
       [](const Fixture& f) {
         Clipboard c;
         c.CopySolid(f.doc, f.platform);
         return PasteAsSolid(c.text());
       }},
      {"PasteAsChild",
       [](const Fixture& f) {
         Clipboard c;
         c.CopyNode(f.doc, f.platform, {1});
         return PasteAsChild(c.text(), f.platform, {}, 1);
       }},
      {"Macro",
       [](const Fixture& f) {
         std::vector<std::unique_ptr<Command>> steps;
         steps.push_back(edit::RenameObject(f.knob, "k2"));
         steps.push_back(edit::SetNodeField(f.knob, {}, "radius", 0.03));
         return std::make_unique<MacroCommand>("Two edits", std::move(steps));
       }},
  };
}

TEST(Document, EveryCommandUndoRestoresJsonAndRedoRepeatsDo) {
  for (const NamedEdit& e : EveryEdit()) {
    SCOPED_TRACE(e.name);
    Fixture f;
    const std::string before = FullText(f.doc);
    const std::uint64_t doc_revision = f.doc.revision();
    f.doc.Execute(e.make(f));
    const std::string after = FullText(f.doc);
    EXPECT_NE(before, after);
    EXPECT_GT(f.doc.revision(), doc_revision);
    EXPECT_EQ(f.doc.history().undo_size(), 1u);
    ASSERT_TRUE(f.doc.Undo());
    EXPECT_EQ(FullText(f.doc), before);
    ASSERT_TRUE(f.doc.Redo());
    EXPECT_EQ(FullText(f.doc), after);
    ASSERT_TRUE(f.doc.Undo());
    EXPECT_EQ(FullText(f.doc), before);
  }
}

TEST(Document, EditsGiveTheExpectedTreesWhenApplied) {
  Fixture f;
  f.doc.Execute(edit::SetNodeField(f.platform, {0}, "radius", 0.02));
  EXPECT_EQ(modeling::NodeToJson(f.doc.Node(f.platform, {0})),
            json::parse(R"({"type": "sphere", "id": "ball", "name": "ball", "radius": 0.02})"));
  f.doc.Execute(
      edit::WrapNode(f.platform, {0}, modeling::TranslateParams{Eigen::Vector3d(0, 0, 1)}, "w"));
  EXPECT_EQ(modeling::NodeToJson(f.doc.Node(f.platform, {0})),
            json::parse(R"({"type": "translate", "id": "w", "translation": [0.0, 0.0, 1.0],
                            "children": [{"type": "sphere", "id": "ball", "name": "ball", "radius": 0.02}]})"));
  // Root children are now w, t, pip. Moving w to index 2 (counted before the move) puts it before
  // pip.
  f.doc.Execute(edit::MoveNode(f.platform, {0}, f.platform, {}, 2));
  auto ids = [&] {
    std::vector<std::string> out;
    for (const ImplicitNode& c : f.doc.Node(f.platform, {}).children) out.push_back(c.id);
    return out;
  };
  EXPECT_EQ(ids(), (std::vector<std::string>{"t", "w", "pip"}));
  // Move pip into t (t is before pip, so its path does not shift).
  f.doc.Execute(edit::MoveNode(f.platform, {2}, f.platform, {0}, 0));
  EXPECT_EQ(ids(), (std::vector<std::string>{"t", "w"}));
  EXPECT_EQ(f.doc.Node(f.platform, {0, 0}).id, "pip");
  // Move w (a later sibling of t) under... t's first child position, and t from before into w:
  // moving t (index 0) into w (index 1) must find w at index 0 after t is removed.
  f.doc.Execute(edit::MoveNode(f.platform, {0}, f.platform, {1}, -1));
  ASSERT_EQ(f.doc.Node(f.platform, {}).children.size(), 1u);
  EXPECT_EQ(f.doc.Node(f.platform, {0}).id, "w");
  EXPECT_EQ(f.doc.Node(f.platform, {0, 1}).id, "t");
  EXPECT_EQ(f.doc.Node(f.platform, {0, 1, 0}).id, "pip");
  f.doc.Execute(edit::ReorderNode(f.platform, {0, 1}, 0));
  EXPECT_EQ(f.doc.Node(f.platform, {0, 0}).id, "t");
  EXPECT_EQ(f.doc.history().UndoDescription(), "Reorder node");
}

// Asserts that making and executing the command throws E, and the document is unchanged.
template <class E>
void ExpectRejected(Fixture& f, const std::function<std::unique_ptr<Command>()>& make,
                    const std::string& fragment, bool same_revision = true) {
  const std::string before = FullText(f.doc);
  const std::uint64_t revision = f.doc.revision();
  const size_t steps = f.doc.history().undo_size();
  try {
    f.doc.Execute(make());
    ADD_FAILURE() << "no exception; expected one containing '" << fragment << "'";
  } catch (const E& e) {
    EXPECT_NE(std::string(e.what()).find(fragment), std::string::npos) << e.what();
  }
  EXPECT_EQ(FullText(f.doc), before);
  // A failed macro undoes its done steps, which counts as changes for revision() (content is
  // equal).
  if (same_revision) {
    EXPECT_EQ(f.doc.revision(), revision);
  }
  EXPECT_EQ(f.doc.history().undo_size(), steps);
}

TEST(Document, InvalidEditThrowsAndLeavesDocumentUnchanged) {
  Fixture f;
  f.doc.Execute(edit::RenameObject(f.knob, "k"));  // something to undo, to see the stack unchanged
  ExpectRejected<modeling::ModelError>(
      f, [&] { return edit::SetNodeField(f.platform, {0}, "radius", -0.02); }, "ball");
  ExpectRejected<modeling::ModelError>(
      f,
      [&] {
        return edit::SetNodeParams(f.knob, {}, modeling::CylinderParams{0.01, -1});
      },
      "height");
  ExpectRejected<modeling::ModelError>(
      f, [&] { return edit::AddNode(f.platform, {0}, 0, Sphere(0.01)); }, "children");
  ExpectRejected<modeling::ModelError>(
      f, [&] { return edit::AddNode(f.platform, {}, 0, Sphere(0.01, "c")); }, "'c'");
  ExpectRejected<modeling::ModelError>(
      f, [&] { return edit::SetNodeField(f.platform, {0}, "id", "lid_ball"); }, "lid_ball");
  ExpectRejected<modeling::ModelError>(
      f,
      [&] {
        return edit::DeleteNode(f.platform, {1, 0});
      },
      "children");
  ExpectRejected<modeling::SceneError>(
      f, [&] { return edit::SetNodeField(f.platform, {0}, "raduis", 0.1); }, "raduis");
  ExpectRejected<DocumentError>(
      f, [&] { return edit::SetNodeField(f.platform, {7}, "radius", 0.1); }, "/children/7");
  ExpectRejected<DocumentError>(
      f, [&] { return edit::SetNodeField(f.platform, {}, "children", json::array()); }, "children");
  ExpectRejected<DocumentError>(
      f, [&] { return edit::DeleteNode(f.platform, {}); }, "root");
  ExpectRejected<DocumentError>(
      f,
      [&] {
        return edit::MoveNode(f.platform, {1}, f.platform, {1, 0}, 0);
      },
      "own subtree");
  ExpectRejected<DocumentError>(
      f, [&] { return edit::AddNode(f.platform, {}, 9, Sphere(0.01)); }, "index 9");
  ExpectRejected<DocumentError>(
      f,
      [&] {
        return edit::SetFeMaterial(f.fe, fem::Material{2e9, 0.5});
      },
      "material");
  ExpectRejected<DocumentError>(
      f, [&] { return edit::SetFeMaterial(f.platform, fem::Material{}); }, "not an FE model");
  ExpectRejected<DocumentError>(
      f, [&] { return edit::AddFeModel("x", f.platform, fem::Material{}, {}); }, "tet_mesh");
  ExpectRejected<DocumentError>(
      f,
      [&] {
        return edit::SetFixedBoxes(
            f.fe, {Eigen::AlignedBox3d(Eigen::Vector3d(1, 0, 0), Eigen::Vector3d(0, 1, 1))});
      },
      "fixed_boxes/0");
  ExpectRejected<DocumentError>(
      f, [&] { return edit::RenameObject(f.knob, ""); }, "name");
  ExpectRejected<DocumentError>(
      f, [&] { return edit::SculptStroke(f.clay, {9}, Eigen::Matrix3Xd::Zero(3, 1)); }, "vertex 9");
  ExpectRejected<DocumentError>(
      f, [&] { return edit::DeleteObject(12345); }, "12345");
  Eigen::Isometry3d skew = Eigen::Isometry3d::Identity();
  skew.linear()(0, 1) = 0.5;
  ExpectRejected<DocumentError>(
      f, [&] { return edit::SetRigidPose(f.part, skew); }, "X_WP");
  ExpectRejected<DocumentError>(
      f, [&] { return edit::SetElementOrder(f.fe, 3); }, "element_order");
  ExpectRejected<DocumentError>(
      f,
      [&] {
        return edit::SetRegionMaterials(f.fe, {{1, fem::Material{}}, {1, fem::Material{2e9, 0.2}}});
      },
      "listed twice");
  ExpectRejected<DocumentError>(
      f,
      [&] {
        return edit::SetFeLoads(
            f.fe, {{Eigen::AlignedBox3d(Eigen::Vector3d::Zero(), Eigen::Vector3d::Ones()),
                    Eigen::Vector3d(0, std::nan(""), 0)}});
      },
      "loads/0");
  ExpectRejected<DocumentError>(
      f, [&] { return edit::SetRigidSeats(f.part, {modeling::SceneSeat{}}); }, "seats/0");
  ExpectRejected<DocumentError>(
      f,
      [&] {
        return edit::SetSnap(modeling::SceneSnap{0.0, 1, 1, 1});
      },
      "snap");
  ExpectRejected<DocumentError>(
      f, [&] { return edit::SetObjectData(f.clay, SolidData{Sphere(0.1)}); }, "does not match");
  // A macro whose second step fails undoes its first.
  ExpectRejected<modeling::ModelError>(
      f,
      [&] {
        std::vector<std::unique_ptr<Command>> steps;
        steps.push_back(edit::RenameObject(f.knob, "k3"));
        steps.push_back(edit::SetNodeField(f.knob, {}, "radius", -1.0));
        return std::make_unique<MacroCommand>("Two edits", std::move(steps));
      },
      "radius", false);
  EXPECT_EQ(f.doc.history().UndoDescription(), "Rename to k");
}

// All paths of a tree.
void CollectPaths(const ImplicitNode& node, NodePath* path, std::vector<NodePath>* out) {
  out->push_back(*path);
  for (int i = 0; i < static_cast<int>(node.children.size()); ++i) {
    path->push_back(i);
    CollectPaths(node.children[i], path, out);
    path->pop_back();
  }
}

TEST(Document, RandomEditsUndoToInitialAndRedoToFinalJson) {
  Fixture f;
  std::mt19937 rng(12345);
  auto uniform = [&](int n) { return std::uniform_int_distribution<int>(0, n - 1)(rng); };
  auto real = [&](double a, double b) { return std::uniform_real_distribution<double>(a, b)(rng); };
  std::vector<std::string> states{FullText(f.doc)};
  int valid = 0, invalid = 0, fresh = 0;
  for (int step = 0; step < 200; ++step) {
    // Pick a tree-bearing object and a node in it.
    std::vector<ObjectId> trees;
    for (const DocObject& o : f.doc.objects()) {
      if (TreeOf(o)) trees.push_back(o.id);
    }
    ASSERT_FALSE(trees.empty());
    const ObjectId id = trees[uniform(static_cast<int>(trees.size()))];
    std::vector<NodePath> paths;
    NodePath scratch;
    CollectPaths(*TreeOf(f.doc.Get(id)), &scratch, &paths);
    const NodePath path = paths[uniform(static_cast<int>(paths.size()))];
    const ImplicitNode& node = f.doc.Node(id, path);
    std::unique_ptr<Command> command;
    switch (uniform(12)) {
      case 0:  // radius of a sphere, sometimes negative; other nodes reject the field
        command = edit::SetNodeField(id, path, "radius", real(-0.01, 0.05));
        break;
      case 1:
        command = edit::AddNode(
            id, path, uniform(3) - 1,
            Sphere(real(0.001, 0.02), uniform(2) ? "n" + std::to_string(fresh++) : ""));
        break;
      case 2:
        command =
            edit::WrapNode(id, path, modeling::TranslateParams{Eigen::Vector3d(real(-1, 1), 0, 0)});
        break;
      case 3:
        command = edit::DeleteNode(id, path);
        break;
      case 4: {
        const ObjectId dst = trees[uniform(static_cast<int>(trees.size()))];
        std::vector<NodePath> dst_paths;
        NodePath s2;
        CollectPaths(*TreeOf(f.doc.Get(dst)), &s2, &dst_paths);
        command = edit::MoveNode(
            id, path, dst, dst_paths[uniform(static_cast<int>(dst_paths.size()))], uniform(3) - 1);
        break;
      }
      case 5:
        command = edit::ReorderNode(id, path, uniform(3));
        break;
      case 6:
        command = edit::SetNodeName(id, path, "name" + std::to_string(step));
        break;
      case 7:
        command = edit::RenameObject(id, uniform(4) ? "obj" + std::to_string(step) : "");
        break;
      case 8:
        command = edit::AddSolid("s" + std::to_string(step), Sphere(real(-0.01, 0.05)));
        break;
      case 9:
        if (trees.size() <= 2) {
          command = edit::AddSolid("r" + std::to_string(step), Box());
          break;
        }
        command = edit::DeleteObject(
            f.doc.objects()[uniform(static_cast<int>(f.doc.objects().size()))].id);
        break;
      case 10:
        // Keep trees small: copies double them.
        command = modeling::CountNodes(*TreeOf(f.doc.Get(id))) > 20
                      ? edit::SetNodeName(id, path, "big")
                      : edit::DuplicateObject(id);
        break;
      case 11: {
        if (modeling::CountNodes(node) > 10) {
          command = edit::SetNodeName(id, path, "big");
          break;
        }
        Clipboard c;
        c.CopyNode(f.doc, id, path);
        command = PasteAsChild(c.text(), trees[uniform(static_cast<int>(trees.size()))], {}, -1);
        break;
      }
    }
    (void)node;
    const std::string before = FullText(f.doc);
    const size_t depth = f.doc.history().undo_size();
    try {
      f.doc.Execute(std::move(command));
      ++valid;
      states.push_back(FullText(f.doc));
      ASSERT_EQ(f.doc.history().undo_size(), depth + 1);
    } catch (const std::invalid_argument&) {  // ModelError, SceneError's base is runtime_error
      ++invalid;
      ASSERT_EQ(FullText(f.doc), before);
      ASSERT_EQ(f.doc.history().undo_size(), depth);
    } catch (const modeling::SceneError&) {
      ++invalid;
      ASSERT_EQ(FullText(f.doc), before);
      ASSERT_EQ(f.doc.history().undo_size(), depth);
    }
    // The document never holds a repeated node id.
    std::set<std::string> ids;
    for (const DocObject& o : f.doc.objects()) {
      if (!TreeOf(o)) continue;
      std::vector<NodePath> all;
      NodePath s3;
      CollectPaths(*TreeOf(o), &s3, &all);
      for (const NodePath& p : all) {
        const std::string& nid = f.doc.Node(o.id, p).id;
        if (!nid.empty()) {
          ASSERT_TRUE(ids.insert(nid).second) << "repeated id " << nid;
        }
      }
    }
  }
  RecordProperty("valid_edits", valid);
  RecordProperty("invalid_edits", invalid);
  std::printf("random edits: %d valid, %d invalid\n", valid, invalid);
  EXPECT_GT(valid, 60);
  EXPECT_GT(invalid, 20);
  ASSERT_EQ(f.doc.history().undo_size(), static_cast<size_t>(valid));
  const std::string final_state = states.back();
  for (int k = valid; k > 0; --k) {
    ASSERT_TRUE(f.doc.Undo());
    ASSERT_EQ(FullText(f.doc), states[k - 1]) << "after undoing step " << k;
  }
  EXPECT_FALSE(f.doc.Undo());
  EXPECT_EQ(FullText(f.doc), states.front());
  for (int k = 1; k <= valid; ++k) {
    ASSERT_TRUE(f.doc.Redo());
    ASSERT_EQ(FullText(f.doc), states[k]) << "after redoing step " << k;
  }
  EXPECT_FALSE(f.doc.Redo());
  EXPECT_EQ(FullText(f.doc), final_state);
}

TEST(Document, PathStaysValidThroughUndoAndRedo) {
  Fixture f;
  const NodePath box_path{1, 0};
  ASSERT_EQ(f.doc.Node(f.platform, box_path).id, "b");
  f.doc.Execute(edit::DeleteNode(f.platform, {0}));  // shifts t to index 0
  EXPECT_EQ(f.doc.Node(f.platform, {0, 0}).id, "b");
  f.doc.Undo();
  EXPECT_EQ(f.doc.Node(f.platform, box_path).id, "b");
  f.doc.Redo();
  f.doc.Undo();
  EXPECT_EQ(f.doc.Node(f.platform, box_path).id, "b");
  const auto found = f.doc.FindNodeById("b");
  ASSERT_TRUE(found.has_value());
  EXPECT_EQ(found->first, f.platform);
  EXPECT_EQ(found->second, box_path);
  EXPECT_FALSE(f.doc.FindNodeById("nope").has_value());
}

TEST(Document, ObjectIdsAreNeverReusedAndRedoKeepsThem) {
  Fixture f;
  f.doc.Execute(edit::AddSolid("a", Sphere(0.1)));
  const ObjectId a = f.doc.last_created().at(0);
  f.doc.Undo();
  EXPECT_EQ(f.doc.Find(a), nullptr);
  f.doc.Redo();
  ASSERT_NE(f.doc.Find(a), nullptr);
  EXPECT_EQ(f.doc.last_created(), std::vector<ObjectId>{a});
  f.doc.Undo();
  f.doc.Execute(edit::AddSolid("b", Sphere(0.1)));
  const ObjectId b = f.doc.last_created().at(0);
  for (const DocObject& o : f.doc.objects()) {
    if (o.id != b) {
      EXPECT_LT(o.id, b);
    }
  }
  EXPECT_GT(b, a);
}

TEST(Document, RevisionsTagContentAndMeshKnowsWhenOutOfDate) {
  Fixture f;
  const std::uint64_t r0 = f.doc.Get(f.platform).revision;
  const std::uint64_t knob_revision = f.doc.Get(f.knob).revision;
  EXPECT_FALSE(f.doc.IsMeshOutOfDate(f.mesh));
  f.doc.Execute(edit::SetNodeField(f.platform, {0}, "radius", 0.06));
  const std::uint64_t r1 = f.doc.Get(f.platform).revision;
  EXPECT_NE(r1, r0);
  EXPECT_TRUE(f.doc.IsMeshOutOfDate(f.mesh));
  EXPECT_EQ(f.doc.Get(f.knob).revision, knob_revision);  // other objects keep theirs
  f.doc.Undo();
  EXPECT_EQ(f.doc.Get(f.platform).revision, r0);
  EXPECT_FALSE(f.doc.IsMeshOutOfDate(f.mesh));
  f.doc.Redo();
  EXPECT_EQ(f.doc.Get(f.platform).revision, r1);
  // A new, different edit after undo gets a revision never seen before.
  f.doc.Undo();
  f.doc.Execute(edit::SetNodeField(f.platform, {0}, "radius", 0.07));
  EXPECT_NE(f.doc.Get(f.platform).revision, r1);
  EXPECT_NE(f.doc.Get(f.platform).revision, r0);
  f.doc.Execute(edit::DeleteObject(f.platform));
  EXPECT_TRUE(f.doc.IsMeshOutOfDate(f.mesh));
}

TEST(Document, FePrecomputationIsValidOnlyForItsRevision) {
  Fixture f;
  EXPECT_FALSE(f.doc.FePrecomputation(f.fe).has_value());
  f.doc.SetFePrecomputation(f.fe, std::make_shared<const int>(42));
  ASSERT_TRUE(f.doc.FePrecomputation(f.fe).has_value());
  EXPECT_EQ(*std::any_cast<std::shared_ptr<const int>>(f.doc.FePrecomputation(f.fe)), 42);
  f.doc.Execute(edit::SetFeMaterial(f.fe, fem::Material{1e9, 0.2}));
  EXPECT_FALSE(f.doc.FePrecomputation(f.fe).has_value());
  f.doc.Undo();
  EXPECT_TRUE(f.doc.FePrecomputation(f.fe).has_value());
  EXPECT_THROW(f.doc.SetFePrecomputation(f.platform, 1), DocumentError);
}

TEST(Document, DeletingMeshDeletesItsFeModelsInOneStep) {
  Fixture f;
  const std::string before = FullText(f.doc);
  f.doc.Execute(edit::DeleteObject(f.mesh));
  EXPECT_EQ(f.doc.Find(f.mesh), nullptr);
  EXPECT_EQ(f.doc.Find(f.fe), nullptr);
  EXPECT_EQ(f.doc.history().undo_size(), 1u);
  EXPECT_EQ(f.doc.history().UndoDescription(), "Delete platform mesh");
  f.doc.Undo();
  EXPECT_EQ(FullText(f.doc), before);
  EXPECT_EQ(f.doc.IndexOf(f.mesh) + 1, f.doc.IndexOf(f.fe));
}

TEST(Document, StrokeOnSharedSculptMeshLeavesOtherCopyAlone) {
  Fixture f;
  f.doc.Execute(edit::DuplicateObject(f.clay));
  const ObjectId copy = f.doc.last_created().at(0);
  EXPECT_EQ(f.doc.Get(copy).name, "clay copy");
  const std::string copy_json = f.doc.ToJson()["objects"][f.doc.IndexOf(copy)].dump();
  Eigen::Matrix3Xd p(3, 1);
  p << 9, 9, 9;
  f.doc.Execute(edit::SculptStroke(f.clay, {2}, p));
  EXPECT_EQ(SculptVertex(*std::get<SculptData>(f.doc.Get(f.clay).data).mesh, 2),
            Eigen::Vector3d(9, 9, 9));
  EXPECT_EQ(f.doc.ToJson()["objects"][f.doc.IndexOf(copy)].dump(), copy_json);
  f.doc.Undo();
  EXPECT_EQ(SculptVertex(*std::get<SculptData>(f.doc.Get(f.clay).data).mesh, 2),
            Eigen::Vector3d(0, 1, 0));
}

TEST(Document, DirtyFlagFollowsEditsUndoAndSave) {
  Fixture f;
  const std::string path = std::string(SPIDARCAD_TEST_OUTPUT_DIR) + "/document_dirty.json";
  EXPECT_TRUE(f.doc.dirty());  // objects were added after LoadScene
  f.doc.Save(path);
  EXPECT_FALSE(f.doc.dirty());
  f.doc.Execute(edit::RenameObject(f.knob, "k"));
  EXPECT_TRUE(f.doc.dirty());
  f.doc.Undo();
  EXPECT_FALSE(f.doc.dirty());
  f.doc.Redo();
  EXPECT_TRUE(f.doc.dirty());
  f.doc.Save(path);
  EXPECT_FALSE(f.doc.dirty());
  EXPECT_EQ(f.doc.file_path(), path);
  f.doc.Undo();
  EXPECT_TRUE(f.doc.dirty());
  f.doc.Redo();
  EXPECT_FALSE(f.doc.dirty());
  // An edit that changes nothing (the name is already "k") still sets the flag: the flag tracks
  // revisions, which a new edit always changes.
  f.doc.Execute(edit::RenameObject(f.knob, "k"));
  EXPECT_TRUE(f.doc.dirty());
  std::remove(path.c_str());
}

// A document of solids only is written as a version 1 scene that modeling's reader reads; one
// with other kinds as version 2, which keeps every object (doc/document_io.h).
TEST(Document, SaveWritesFileThatLoadReadsBack) {
  Fixture f;
  f.doc.Execute(edit::SetNodeField(f.platform, {0}, "radius", 0.1 + 0.2));  // not exactly 0.3
  f.doc.Execute(edit::SetDescription("saved"));
  const std::string solids_only =
      std::string(SPIDARCAD_TEST_OUTPUT_DIR) + "/document_save_solids.json";
  {
    Document solids;
    solids.LoadScene(f.doc.ToScene());
    solids.Save(solids_only);
    const modeling::Scene read = modeling::LoadScene(solids_only);
    EXPECT_EQ(modeling::SceneToJson(read), modeling::SceneToJson(f.doc.ToScene()));
    EXPECT_EQ(read.solids.size(), 2u);
    EXPECT_EQ(read.description, "saved");
    std::remove(solids_only.c_str());
  }
  const std::string path = std::string(SPIDARCAD_TEST_OUTPUT_DIR) + "/document_save.json";
  f.doc.Save(path);
  EXPECT_THROW(modeling::LoadScene(path),
               modeling::SceneError);  // version 2: not a version 1 reader's
  Document other;
  other.Load(path);
  EXPECT_EQ(SceneText(other), SceneText(f.doc));
  ASSERT_EQ(other.objects().size(), f.doc.objects().size());  // every kind is saved
  for (std::size_t i = 0; i < other.objects().size(); ++i) {
    EXPECT_EQ(other.objects()[i].name, f.doc.objects()[i].name);
    EXPECT_EQ(other.objects()[i].data.index(), f.doc.objects()[i].data.index());
  }
  EXPECT_FALSE(other.dirty());
  EXPECT_FALSE(other.history().CanUndo());
  std::remove(path.c_str());
}

// Assembly parts survive Load -> Save -> Load unchanged (seats included, compared as JSON by
// modeling's serialiser); a part whose solid was renamed away stops the save, names the part and
// leaves the file as it was.
TEST(Document, SaveKeepsAssemblyPartsAndRefusesAPartWithoutItsSolid) {
  const std::string source = std::string(SPIDARCAD_SOURCE_DIR) + "/assets/scenes/assembly.json";
  const modeling::Scene original = modeling::LoadScene(source);
  ASSERT_EQ(original.parts.size(), 6u);
  Document doc;
  doc.Load(source);
  ASSERT_EQ(doc.parts().size(), 6u);
  const std::string path = std::string(SPIDARCAD_TEST_OUTPUT_DIR) + "/document_assembly.json";
  doc.Save(path);
  const modeling::Scene read = modeling::LoadScene(path);
  EXPECT_EQ(modeling::SceneToJson(read)["parts"], modeling::SceneToJson(original)["parts"]);
  EXPECT_EQ(read.parts.size(), 6u);

  const DocObject* head = doc.FindByName(original.parts[1].solid);
  ASSERT_NE(head, nullptr);
  doc.Execute(edit::RenameObject(head->id, "renamed"));
  try {
    doc.Save(path);
    ADD_FAILURE() << "saved a part without its solid";
  } catch (const modeling::SceneError& e) {
    EXPECT_EQ(e.pointer(), "/parts/1/solid");
    EXPECT_NE(std::string(e.what()).find("'" + original.parts[1].name + "'"), std::string::npos)
        << e.what();
    EXPECT_NE(std::string(e.what()).find("rename a solid back"), std::string::npos) << e.what();
  }
  EXPECT_EQ(modeling::SceneToJson(modeling::LoadScene(path)), modeling::SceneToJson(read));
  EXPECT_TRUE(doc.dirty());
  doc.Undo();
  doc.Save(path);
  EXPECT_EQ(modeling::LoadScene(path).parts.size(), 6u);
  std::remove(path.c_str());
}

TEST(Document, LoadRejectsIdsRepeatedAcrossSolidsAndKeepsContent) {
  Fixture f;
  const std::string before = FullText(f.doc);
  modeling::Scene scene;
  scene.solids.push_back({"a", Sphere(0.1, "x")});
  scene.solids.push_back({"b", Sphere(0.1, "x")});
  try {
    f.doc.LoadScene(scene, "dup.json");
    ADD_FAILURE() << "no exception";
  } catch (const modeling::SceneError& e) {
    EXPECT_EQ(e.pointer(), "/solids/1/root/id");
    EXPECT_NE(std::string(e.what()).find("'x'"), std::string::npos) << e.what();
  }
  EXPECT_EQ(FullText(f.doc), before);
  const std::string missing = std::string(SPIDARCAD_TEST_OUTPUT_DIR) + "/no_such_scene.json";
  EXPECT_THROW(f.doc.Load(missing), modeling::SceneError);
  EXPECT_EQ(FullText(f.doc), before);
}

}  // namespace
}  // namespace spidarcad::app

namespace spidarcad::app {
namespace {

// ImportMesh: a file written here as text (an ASCII STL of two triangles, a TetGen pair with one
// negatively numbered tet) lands as one mesh object holding exactly the file's geometry, undo
// removes it, redo brings it back; a bad file throws naming it and makes no command.
TEST(Document, ImportMeshAddsTheFileAsAMeshObjectAndUndoRemovesIt) {
  const std::filesystem::path dir = std::filesystem::path(SPIDARCAD_TEST_OUTPUT_DIR) / "import";
  std::filesystem::create_directories(dir);
  const std::string stl = (dir / "quad.stl").string();
  {
    std::FILE* f = std::fopen(stl.c_str(), "w");
    ASSERT_NE(f, nullptr);
    std::fputs(
        "solid quad\n"
        " facet normal 0 0 1\n  outer loop\n   vertex 0 0 0\n   vertex 0.1 0 0\n"
        "   vertex 0.1 0.2 0\n  endloop\n endfacet\n"
        " facet normal 0 0 1\n  outer loop\n   vertex 0 0 0\n   vertex 0.1 0.2 0\n"
        "   vertex 0 0.2 0\n  endloop\n endfacet\nendsolid quad\n",
        f);
    std::fclose(f);
  }
  Document doc;
  doc.Execute(edit::AddSolid("ball", Sphere(0.01)));
  const std::string before = FullText(doc);
  doc.Execute(edit::ImportMesh(stl));
  ASSERT_EQ(doc.objects().size(), 2u);
  const DocObject& o = doc.objects().back();
  EXPECT_EQ(o.name, "quad");
  const auto* mesh = std::get_if<MeshData>(&o.data);
  ASSERT_NE(mesh, nullptr);
  EXPECT_EQ(mesh->import_source, stl);
  EXPECT_EQ(mesh->source, 0u);
  ASSERT_TRUE(mesh->surface);
  EXPECT_FALSE(mesh->volume);
  EXPECT_EQ(mesh->surface->triangles.cols(), 2);
  // The surface's area is the rectangle's, 0.1 × 0.2 m², whatever the vertex order.
  double area = 0.0;
  for (int t = 0; t < 2; ++t) {
    const Eigen::Vector3d a = mesh->surface->vertices.col(mesh->surface->triangles(0, t));
    const Eigen::Vector3d b = mesh->surface->vertices.col(mesh->surface->triangles(1, t));
    const Eigen::Vector3d c = mesh->surface->vertices.col(mesh->surface->triangles(2, t));
    area += 0.5 * (b - a).cross(c - a).norm();
  }
  EXPECT_NEAR(area, 0.02, 1e-12);
  EXPECT_EQ(doc.history().UndoDescription(), "Import mesh quad");
  ASSERT_TRUE(doc.Undo());
  EXPECT_EQ(FullText(doc), before);
  ASSERT_TRUE(doc.Redo());
  EXPECT_EQ(doc.objects().size(), 2u);

  // TetGen files, numbered from 1, the tet given with negative orientation: flipped, the unit
  // corner tet's volume 1/6 m³; the region attribute kept.
  std::FILE* node = std::fopen((dir / "tet.node").c_str(), "w");
  ASSERT_NE(node, nullptr);
  std::fputs("# corner tet\n4 3 0 0\n1 0 0 0\n2 1 0 0\n3 0 1 0\n4 0 0 1\n", node);
  std::fclose(node);
  std::FILE* ele = std::fopen((dir / "tet.ele").c_str(), "w");
  ASSERT_NE(ele, nullptr);
  std::fputs("1 4 1\n1 1 3 2 4 7\n", ele);
  std::fclose(ele);
  doc.Execute(edit::ImportMesh((dir / "tet.node").string(), "corner"));
  const auto* tets = std::get_if<MeshData>(&doc.objects().back().data);
  ASSERT_NE(tets, nullptr);
  ASSERT_TRUE(tets->volume);
  EXPECT_EQ(doc.objects().back().name, "corner");
  EXPECT_EQ(tets->volume->tets.cols(), 1);
  EXPECT_NEAR(modeling::TetVolume(*tets->volume, 0), 1.0 / 6.0, 1e-15);
  EXPECT_EQ(tets->volume->regions(0), 7);

  // A bad file: InputError naming the file and line; no command, the document as it was.
  const std::string bad = (dir / "bad.node").string();
  std::FILE* b = std::fopen(bad.c_str(), "w");
  ASSERT_NE(b, nullptr);
  std::fputs("2 3 0 0\n0 0 0 0\n1 0 zero 0\n", b);
  std::fclose(b);
  std::FILE* be = std::fopen((dir / "bad.ele").c_str(), "w");
  ASSERT_NE(be, nullptr);
  std::fputs("0 4 0\n", be);
  std::fclose(be);
  const std::string kept = FullText(doc);
  try {
    doc.Execute(edit::ImportMesh(bad));
    FAIL() << "imported a bad file";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find(bad + ":3: y is not a finite number: 'zero'"),
              std::string::npos)
        << e.what();
  }
  EXPECT_EQ(FullText(doc), kept);
  EXPECT_THROW(edit::ImportMesh((dir / "missing.stl").string()), InputError);
  EXPECT_THROW(edit::ImportMesh((dir / "quad.txt").string()), InputError);
}

}  // namespace
}  // namespace spidarcad::app
