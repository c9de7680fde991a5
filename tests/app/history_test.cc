// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
// The undo history: drag merging, redo clearing, bounded depth, macros, descriptions.
#include <gtest/gtest.h>

#include <memory>
#include <string>
#include <vector>

#include "doc/command.h"
#include "doc/document.h"

namespace spidarcad::app {
namespace {

using modeling::ImplicitNode;

std::string SceneText(const Document& doc) { return modeling::SceneToJson(doc.ToScene()).dump(); }

// A document with one solid: union { sphere "s" r = 0.05, cylinder "c" r = 0.02 h = 0.04 }.
struct Fixture {
  Document doc;
  ObjectId solid = 0;
  Fixture() {
    modeling::Scene scene;
    ImplicitNode root(modeling::UnionParams{},
                      {ImplicitNode(modeling::SphereParams{0.05}, {}, "s"),
                       ImplicitNode(modeling::CylinderParams{0.02, 0.04}, {}, "c")},
                      "u");
    scene.solids.push_back({"part", root});
    doc.LoadScene(scene);
    solid = doc.objects()[0].id;
  }
  double Radius(const NodePath& path) const {
    const auto& p = doc.Node(solid, path).params;
    if (const auto* s = std::get_if<modeling::SphereParams>(&p)) return s->radius;
    return std::get<modeling::CylinderParams>(p).radius;
  }
  double Height() const {
    return std::get<modeling::CylinderParams>(doc.Node(solid, {1}).params).height;
  }
};

TEST(History, MergesDragEditsOfOneFieldIntoOneStep) {
  Fixture f;
  const std::string before = SceneText(f.doc);
  for (double r : {0.051, 0.052, 0.053, 0.054})
    f.doc.Execute(edit::SetNodeField(f.solid, {0}, "radius", r, true));
  EXPECT_EQ(f.Radius({0}), 0.054);
  EXPECT_EQ(f.doc.history().undo_size(), 1u);
  EXPECT_EQ(f.doc.history().UndoDescription(), "Set radius");
  const std::string after = SceneText(f.doc);
  f.doc.Undo();
  EXPECT_EQ(SceneText(f.doc), before);
  EXPECT_EQ(f.Radius({0}), 0.05);
  f.doc.Redo();
  EXPECT_EQ(SceneText(f.doc), after);
}

TEST(History, MergesTypedParamsDragAndKeepsFirstRevisionForUndo) {
  Fixture f;
  const std::uint64_t r0 = f.doc.Get(f.solid).revision;
  f.doc.Execute(
      edit::SetNodeParams(f.solid, {1}, modeling::CylinderParams{0.03, 0.04}, "radius", true));
  f.doc.Execute(
      edit::SetNodeParams(f.solid, {1}, modeling::CylinderParams{0.04, 0.04}, "radius", true));
  EXPECT_EQ(f.doc.history().undo_size(), 1u);
  f.doc.Undo();
  EXPECT_EQ(f.Radius({1}), 0.02);
  EXPECT_EQ(f.doc.Get(f.solid).revision, r0);
}

TEST(History, DoesNotMergeAcrossFieldsNodesOrAfterEndDrag) {
  Fixture f;
  f.doc.Execute(edit::SetNodeField(f.solid, {1}, "radius", 0.021, true));
  f.doc.Execute(edit::SetNodeField(f.solid, {1}, "radius", 0.022, true));
  f.doc.Execute(edit::SetNodeField(f.solid, {1}, "height", 0.05, true));  // other field
  EXPECT_EQ(f.doc.history().undo_size(), 2u);
  f.doc.Execute(edit::SetNodeField(f.solid, {0}, "radius", 0.06, true));  // other node
  EXPECT_EQ(f.doc.history().undo_size(), 3u);
  f.doc.EndDrag();
  f.doc.Execute(edit::SetNodeField(f.solid, {0}, "radius", 0.07, true));  // new drag
  EXPECT_EQ(f.doc.history().undo_size(), 4u);
  f.doc.Execute(edit::SetNodeField(f.solid, {0}, "radius", 0.08, false));  // not dragging
  f.doc.Execute(edit::SetNodeField(f.solid, {0}, "radius", 0.09, false));
  EXPECT_EQ(f.doc.history().undo_size(), 6u);
  // Back to the first field after another field was dragged: a new step.
  f.doc.Execute(edit::SetNodeField(f.solid, {1}, "height", 0.06, true));
  f.doc.Execute(edit::SetNodeField(f.solid, {1}, "radius", 0.023, true));
  EXPECT_EQ(f.doc.history().undo_size(), 8u);
  // Undo walks back step by step to the original values.
  f.doc.Undo();
  EXPECT_EQ(f.Radius({1}), 0.022);
  for (int i = 0; i < 7; ++i) f.doc.Undo();
  EXPECT_EQ(f.Radius({1}), 0.02);
  EXPECT_EQ(f.Height(), 0.04);
  EXPECT_EQ(f.Radius({0}), 0.05);
}

TEST(History, DoesNotMergeAfterUndoOrRedo) {
  Fixture f;
  f.doc.Execute(edit::SetNodeField(f.solid, {0}, "radius", 0.06, true));
  f.doc.Execute(edit::SetNodeField(f.solid, {0}, "radius", 0.07, true));
  f.doc.Undo();
  f.doc.Redo();
  f.doc.Execute(edit::SetNodeField(f.solid, {0}, "radius", 0.08, true));
  EXPECT_EQ(f.doc.history().undo_size(), 2u);
  f.doc.Undo();
  EXPECT_EQ(f.Radius({0}), 0.07);
}

TEST(History, InvalidDragEditIsNotMergedAndKeepsState) {
  Fixture f;
  f.doc.Execute(edit::SetNodeField(f.solid, {0}, "radius", 0.06, true));
  EXPECT_THROW(f.doc.Execute(edit::SetNodeField(f.solid, {0}, "radius", -0.01, true)),
               modeling::ModelError);
  EXPECT_EQ(f.Radius({0}), 0.06);
  f.doc.Execute(edit::SetNodeField(f.solid, {0}, "radius", 0.07, true));
  EXPECT_EQ(f.doc.history().undo_size(), 1u);
  f.doc.Undo();
  EXPECT_EQ(f.Radius({0}), 0.05);
}

TEST(History, NewCommandClearsRedoButFailedCommandKeepsIt) {
  Fixture f;
  f.doc.Execute(edit::SetNodeField(f.solid, {0}, "radius", 0.06));
  f.doc.Execute(edit::SetNodeField(f.solid, {0}, "radius", 0.07));
  f.doc.Undo();
  EXPECT_TRUE(f.doc.history().CanRedo());
  EXPECT_EQ(f.doc.history().RedoDescription(), "Set radius");
  EXPECT_THROW(f.doc.Execute(edit::SetNodeField(f.solid, {0}, "radius", 0.0)),
               modeling::ModelError);
  EXPECT_TRUE(f.doc.history().CanRedo());
  f.doc.Execute(edit::SetNodeField(f.solid, {1}, "height", 0.1));
  EXPECT_FALSE(f.doc.history().CanRedo());
  EXPECT_FALSE(f.doc.Redo());
  EXPECT_EQ(f.Radius({0}), 0.06);
}

TEST(History, DropsOldestStepsBeyondMaxDepth) {
  Fixture f;
  f.doc.history().set_max_depth(3);
  std::vector<std::string> states{SceneText(f.doc)};
  for (int i = 1; i <= 5; ++i) {
    f.doc.Execute(edit::SetNodeField(f.solid, {0}, "radius", 0.05 + 0.01 * i));
    states.push_back(SceneText(f.doc));
  }
  EXPECT_EQ(f.doc.history().undo_size(), 3u);
  while (f.doc.Undo()) {
  }
  EXPECT_EQ(SceneText(f.doc), states[2]);  // edits 3, 4, 5 undone; 1 and 2 are permanent
  EXPECT_EQ(f.doc.history().redo_size(), 3u);
  while (f.doc.Redo()) {
  }
  EXPECT_EQ(SceneText(f.doc), states[5]);
}

TEST(History, MacroIsOneStepAndUndoesInReverse) {
  Fixture f;
  const std::string before = SceneText(f.doc);
  std::vector<std::unique_ptr<Command>> steps;
  steps.push_back(
      edit::WrapNode(f.solid, {0}, modeling::TranslateParams{Eigen::Vector3d(1, 0, 0)}, "t"));
  steps.push_back(edit::SetNodeField(f.solid, {0, 0}, "radius", 0.01));  // the sphere, now inside t
  steps.push_back(edit::RenameObject(f.solid, "moved"));
  f.doc.Execute(std::make_unique<MacroCommand>("Move sphere", std::move(steps)));
  EXPECT_EQ(f.doc.history().undo_size(), 1u);
  EXPECT_EQ(f.doc.history().UndoDescription(), "Move sphere");
  EXPECT_EQ(f.doc.Node(f.solid, {0}).id, "t");
  EXPECT_EQ(f.Radius({0, 0}), 0.01);
  const std::string after = SceneText(f.doc);
  f.doc.Undo();
  EXPECT_EQ(SceneText(f.doc), before);
  f.doc.Redo();
  EXPECT_EQ(SceneText(f.doc), after);
}

TEST(History, ClearsOnLoad) {
  Fixture f;
  f.doc.Execute(edit::SetNodeField(f.solid, {0}, "radius", 0.06));
  EXPECT_TRUE(f.doc.history().CanUndo());
  f.doc.LoadScene(modeling::Scene{});
  EXPECT_FALSE(f.doc.history().CanUndo());
  EXPECT_FALSE(f.doc.Undo());
  EXPECT_TRUE(f.doc.objects().empty());
}

}  // namespace
}  // namespace spidarcad::app
