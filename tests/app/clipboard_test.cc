// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
// Copy and paste of solids and subtrees: fresh unique ids, " copy" names, independence of the
// copy, undo, and malformed clipboard text.
#include "doc/clipboard.h"

#include <gtest/gtest.h>

#include <set>
#include <string>

namespace spidarcad::app {
namespace {

using modeling::ImplicitNode;

std::string SceneText(const Document& doc) { return modeling::SceneToJson(doc.ToScene()).dump(); }

void CollectIds(const ImplicitNode& node, std::multiset<std::string>* ids) {
  if (!node.id.empty()) ids->insert(node.id);
  for (const ImplicitNode& c : node.children) CollectIds(c, ids);
}

std::multiset<std::string> AllIds(const Document& doc) {
  std::multiset<std::string> ids;
  for (const DocObject& o : doc.objects()) {
    if (TreeOf(o)) CollectIds(*TreeOf(o), &ids);
  }
  return ids;
}

// platform: difference "d" { box "plate", translate "t" "hole" { cylinder "bore" } }
struct Fixture {
  Document doc;
  ObjectId platform = 0;
  Fixture() {
    ImplicitNode bore(modeling::CylinderParams{0.005, 0.03}, {}, "bore");
    ImplicitNode t(modeling::TranslateParams{Eigen::Vector3d(0.02, 0, 0)}, {bore}, "t");
    t.name = "hole";
    ImplicitNode root(modeling::DifferenceParams{},
                      {ImplicitNode(modeling::BoxParams{}, {}, "plate"), t}, "d");
    modeling::Scene scene;
    scene.solids.push_back({"platform", root});
    doc.LoadScene(scene);
    platform = doc.objects()[0].id;
  }
};

TEST(Clipboard, PastedSubtreeGetsFreshUniqueIdsAndCopyNames) {
  Fixture f;
  Clipboard clip;
  clip.CopyNode(f.doc, f.platform, {1});
  EXPECT_FALSE(clip.empty());
  f.doc.Execute(PasteAsChild(clip.text(), f.platform, {}, -1));
  const ImplicitNode& root = f.doc.Node(f.platform, {});
  ASSERT_EQ(root.children.size(), 3u);
  const ImplicitNode& copy = root.children[2];
  EXPECT_EQ(copy.id, "t_2");
  EXPECT_EQ(copy.name, "hole copy");
  ASSERT_EQ(copy.children.size(), 1u);
  EXPECT_EQ(copy.children[0].id, "bore_2");
  // Same content apart from ids and names.
  ImplicitNode stripped = copy;
  stripped.id = "t";
  stripped.name = "hole";
  stripped.children[0].id = "bore";
  EXPECT_EQ(modeling::NodeToJson(stripped), modeling::NodeToJson(root.children[1]));
  const std::multiset<std::string> ids = AllIds(f.doc);
  for (const std::string& id : ids) EXPECT_EQ(ids.count(id), 1u) << id;
  EXPECT_EQ(ids.size(), 6u);
  // A second paste finds the next free id and name.
  f.doc.Execute(PasteAsChild(clip.text(), f.platform, {}, 1));
  EXPECT_EQ(f.doc.Node(f.platform, {1}).id, "t_3");
  EXPECT_EQ(f.doc.Node(f.platform, {1}).name, "hole copy 2");
}

TEST(Clipboard, EditingTheCopyLeavesTheOriginal) {
  Fixture f;
  Clipboard clip;
  clip.CopyNode(f.doc, f.platform, {1});
  const nlohmann::json original = modeling::NodeToJson(f.doc.Node(f.platform, {1}));
  f.doc.Execute(PasteAsChild(clip.text(), f.platform, {}, -1));
  f.doc.Execute(edit::SetNodeField(f.platform, {2, 0}, "radius", 0.008));
  f.doc.Execute(edit::SetNodeField(f.platform, {2}, "translation", {-0.02, 0.0, 0.0}));
  EXPECT_EQ(modeling::NodeToJson(f.doc.Node(f.platform, {1})), original);
  EXPECT_EQ(std::get<modeling::CylinderParams>(f.doc.Node(f.platform, {2, 0}).params).radius,
            0.008);
}

TEST(Clipboard, PasteAsSolidThenUndoRemovesIt) {
  Fixture f;
  Clipboard clip;
  clip.CopySolid(f.doc, f.platform);
  const std::string before = SceneText(f.doc);
  const std::string full_before = f.doc.ToJson(true).dump();
  f.doc.Execute(PasteAsSolid(clip.text()));
  ASSERT_EQ(f.doc.objects().size(), 2u);
  const ObjectId pasted = f.doc.last_created().at(0);
  EXPECT_EQ(f.doc.Get(pasted).name, "platform copy");
  EXPECT_EQ(f.doc.history().UndoDescription(), "Paste platform");
  EXPECT_EQ(f.doc.Node(pasted, {}).id, "d_2");
  const std::string after = SceneText(f.doc);
  f.doc.Undo();
  EXPECT_EQ(SceneText(f.doc), before);
  EXPECT_EQ(f.doc.ToJson(true).dump(), full_before);
  f.doc.Redo();
  EXPECT_EQ(SceneText(f.doc), after);
  f.doc.Execute(PasteAsSolid(clip.text()));
  EXPECT_EQ(f.doc.Get(f.doc.last_created().at(0)).name, "platform copy 2");
}

TEST(Clipboard, PasteIntoAnotherDocumentKeepsFreeIds) {
  Fixture f;
  Clipboard clip;
  clip.CopySolid(f.doc, f.platform);
  Document other;
  other.Execute(PasteAsSolid(clip.text()));
  EXPECT_EQ(SceneText(other), SceneText(f.doc));
}

TEST(Clipboard, SubtreePastedAsSolidIsNamedAfterItsNode) {
  Fixture f;
  Clipboard clip;
  clip.CopyNode(f.doc, f.platform, {0});
  f.doc.Execute(PasteAsSolid(clip.text()));
  EXPECT_EQ(f.doc.Get(f.doc.last_created().at(0)).name, "box");
  // Bare node text, as a user might paste from elsewhere.
  f.doc.Execute(PasteAsChild(R"({"type": "sphere", "radius": 0.01})", f.platform, {1}, 0));
  EXPECT_EQ(std::get<modeling::SphereParams>(f.doc.Node(f.platform, {1, 0}).params).radius, 0.01);
}

TEST(Clipboard, MalformedTextIsAnErrorNamingTheProblemAndChangesNothing) {
  Fixture f;
  const std::string before = f.doc.ToJson(true).dump();
  const struct {
    const char* text;
    const char* fragment;
  } cases[] = {
      {"", "empty"},
      {"{\"type\": \"sphere\",\n \"radius\": }", "line 2"},
      {"[1, 2]", "object"},
      {R"({"format": "spidarcad-clipboard", "version": 2, "node": {"type": "sphere"}})", "version"},
      {R"({"format": "other", "version": 1})", "/format"},
      {R"({"format": "spidarcad-clipboard", "version": 1})", "exactly one"},
      {R"({"format": "spidarcad-clipboard", "version": 1, "node": {"type": "sphere", "radius": -1}})",
       "radius"},
      {R"({"format": "spidarcad-clipboard", "version": 1, "node": {"type": "sphere", "raduis": 1}})",
       "raduis"},
      {R"({"format": "spidarcad-clipboard", "version": 1, "solid": {"root": {"type": "box"}}})",
       "name"},
      {R"({"type": "blob"})", "blob"},
      {R"({"hello": 1})", "not a spidarcad"},
  };
  for (const auto& c : cases) {
    SCOPED_TRACE(c.text);
    try {
      f.doc.Execute(PasteAsSolid(c.text));
      ADD_FAILURE() << "no exception";
    } catch (const ClipboardError& e) {
      EXPECT_NE(std::string(e.what()).find(c.fragment), std::string::npos) << e.what();
    }
    EXPECT_THROW(f.doc.Execute(PasteAsChild(c.text, f.platform, {}, -1)), ClipboardError);
    EXPECT_EQ(f.doc.ToJson(true).dump(), before);
    EXPECT_FALSE(f.doc.history().CanUndo());
  }
  // Well-formed text pasted where it does not fit (under a primitive) is refused by validation.
  Clipboard clip;
  clip.CopyNode(f.doc, f.platform, {1});
  EXPECT_THROW(f.doc.Execute(PasteAsChild(clip.text(), f.platform, {0}, -1)), modeling::ModelError);
  EXPECT_EQ(f.doc.ToJson(true).dump(), before);
}

TEST(Clipboard, TextIsVersionedJsonOfTheNode) {
  Fixture f;
  Clipboard clip;
  clip.CopyNode(f.doc, f.platform, {1, 0});
  const nlohmann::json j = nlohmann::json::parse(clip.text());
  EXPECT_EQ(j["format"], "spidarcad-clipboard");
  EXPECT_EQ(j["version"], 1);
  EXPECT_EQ(j["node"],
            nlohmann::json::parse(
                R"({"type": "cylinder", "id": "bore", "radius": 0.005, "height": 0.03})"));
  EXPECT_THROW(clip.CopyNode(f.doc, f.platform, {5}), DocumentError);
}

}  // namespace
}  // namespace spidarcad::app
