// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
// Tests of the tree panel's controller (gui/tree_panel.h) on the window's SceneModel, without a
// window: edits recompile the solid (values checked against closed-form signed distances),
// previews re-mesh coarse then fine, undo and redo restore exact values, copy/paste gives fresh
// ids, failing edits change nothing, save writes a scene that reads back. Plus a screenshot of
// the window with a node selected (under Xvfb).
#include <sys/wait.h>

#include <Eigen/Geometry>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <numbers>
#include <set>
#include <string>
#define GLFW_INCLUDE_NONE
#include <GLFW/glfw3.h>
#include <gtest/gtest.h>
#include <imgui.h>
#include <vtkImageData.h>
#include <vtkNew.h>
#include <vtkPNGReader.h>

#include "doc/command.h"
#include "doc/job.h"
#include "gui/panels.h"
#include "gui/tree_panel.h"
#include "scene/scene_fields.h"
#include "scene/scene_model.h"
#include "spidarcad/modeling/scene_io.h"
#include "spidarcad/modeling/sculpt.h"
#include "spidarcad/modeling/surface_mesher.h"
#include "window_test_support.h"

namespace spidarcad::app {
namespace {

using window_test::ReadPng;

constexpr double kPi = std::numbers::pi;
// Demo scene (scene_model.cc): knob = sphere r 35 mm at (80, 30, −85) mm; bracket = rounded box
// 140 x 100 x 50 mm minus a cylinder r 22 mm, both at (−40, 0, −90) mm.
const Eigen::Vector3d kKnobCentre(0.08, 0.03, -0.085);
const Eigen::Vector3d kBracketOrigin(-0.04, 0.0, -0.09);

// Runs preview passes until none is left to start (each pass: start, wait, land).
void SettlePreviews(SceneModel* model, JobQueue* jobs, int max_passes = 6) {
  for (int pass = 0; pass < max_passes; ++pass) {
    model->UpdatePreviews(jobs);
    if (jobs->jobs().empty()) return;
    for (const auto& job : jobs->jobs()) job->Wait();
    jobs->Poll();
    jobs->Prune();
  }
}

// One preview pass: start what is needed, wait for it, land it.
void OnePreviewPass(SceneModel* model, JobQueue* jobs) {
  model->UpdatePreviews(jobs);
  for (const auto& job : jobs->jobs()) job->Wait();
  jobs->Poll();
  jobs->Prune();
}

// The demo field switched off: the haptic scene then holds one field per solid.
DemoFieldSettings NoSprings() {
  DemoFieldSettings field;
  field.enabled = false;
  return field;
}

struct Demo {
  SceneModel model;
  JobQueue jobs;
  TreeController tree{&model};
  Demo() { model.Load(kDemoSceneName, Eigen::Vector3d::Constant(0.19)); }
  ObjectId Id(const std::string& name) const { return model.document().FindByName(name)->id; }
  const SceneObject& Object(const std::string& name) const {
    return model.objects()[model.IndexOf(Id(name))];
  }
  double SphereRadius() const {
    return std::get<modeling::SphereParams>(model.document().Node(Id("knob"), {0}).params).radius;
  }
};

TEST(TreeController, EditingTheRadiusRecompilesRemeshesAndUndoRestoresTheExactValue) {
  Demo d;
  const DeviceToWorld x_wd = d.model.device_to_world();
  SettlePreviews(&d.model, &d.jobs);
  ASSERT_TRUE(d.tree.SelectByName("knob/0"));
  ASSERT_NE(d.tree.SelectedNode(), nullptr);
  ASSERT_TRUE(std::holds_alternative<modeling::SphereParams>(d.tree.SelectedNode()->params));
  const Eigen::Vector3d p = kKnobCentre + Eigen::Vector3d(0.03, -0.04, 0.0);  // 50 mm out
  const double before = d.Object("knob").solid->Value(p);
  EXPECT_NEAR(before, 0.05 - 0.035, 1e-12);
  const int display_revision = d.Object("knob").revision;
  const auto bracket_solid = d.Object("bracket").solid;
  EXPECT_EQ(d.Object("knob").preview_cells_across, SceneModel::kFineCellsAcross);

  ASSERT_TRUE(d.tree.SetField("radius", 0.045)) << d.tree.error();
  EXPECT_TRUE(d.model.Refresh());
  EXPECT_FALSE(d.model.Refresh());  // nothing new
  EXPECT_NEAR(d.Object("knob").solid->Value(p), 0.05 - 0.045, 1e-12);
  EXPECT_NEAR(d.Object("knob").solid->Value(kKnobCentre), -0.045, 1e-12);
  EXPECT_EQ(d.Object("bracket").solid, bracket_solid);  // only the edited solid is recompiled
  // Live preview: a coarse pass first, from the current revision.
  OnePreviewPass(&d.model, &d.jobs);
  const SceneObject& coarse = d.Object("knob");
  EXPECT_GT(coarse.revision, display_revision);
  EXPECT_EQ(coarse.preview_revision, coarse.source_revision);
  EXPECT_EQ(coarse.preview_cells_across, SceneModel::kCoarseCellsAcross);
  // Then the fine pass; its volume is the new sphere's.
  SettlePreviews(&d.model, &d.jobs);
  const SceneObject& fine = d.Object("knob");
  EXPECT_EQ(fine.preview_cells_across, SceneModel::kFineCellsAcross);
  const double r = 0.045, exact = 4.0 / 3.0 * kPi * r * r * r;
  EXPECT_NEAR(modeling::MeshVolume(fine.preview), exact, 0.03 * exact);
  EXPECT_NEAR(fine.bounds_W.sizes().maxCoeff(), 2 * r, 0.004);

  // Undo: the exact old value; redo: the new one again. X_WD never moves.
  ASSERT_TRUE(d.tree.Undo());
  EXPECT_TRUE(d.model.Refresh());
  EXPECT_EQ(d.Object("knob").solid->Value(p), before);
  EXPECT_EQ(d.SphereRadius(), 0.035);
  ASSERT_TRUE(d.tree.Redo());
  EXPECT_TRUE(d.model.Refresh());
  EXPECT_NEAR(d.Object("knob").solid->Value(p), 0.05 - 0.045, 1e-12);
  EXPECT_EQ(d.model.device_to_world().world_scale, x_wd.world_scale);
  EXPECT_EQ(d.model.device_to_world().p_WDo, x_wd.p_WDo);
  // The haptic scene still has both solids.
  EXPECT_EQ(d.model.BuildHapticScene(NoSprings())->size(), 2);
  EXPECT_FALSE(d.tree.Undo() && d.tree.Undo());  // one step only, then nothing
}

TEST(TreeController, LivePreviewOfTheBracketBoreFollowsTheEditCoarseThenFine) {
  Demo d;
  SettlePreviews(&d.model, &d.jobs);
  // The bore: cylinder r 22 mm, 80 mm tall, through the 50 mm block (difference child 1).
  ASSERT_TRUE(d.tree.SelectByName("bracket/0/1"));
  const Eigen::Vector3d q = kBracketOrigin + Eigen::Vector3d(0.025, 0.0, 0.0);  // 3 mm outside
  EXPECT_NEAR(d.Object("bracket").solid->Value(q), -(0.025 - 0.022), 1e-9);
  const auto t0 = std::chrono::steady_clock::now();
  ASSERT_TRUE(d.tree.SetField("radius", 0.03, true));
  ASSERT_TRUE(d.model.Refresh());
  const auto t1 = std::chrono::steady_clock::now();
  // Now inside the bore: max(box, −cylinder) = 0.03 − 0.025.
  EXPECT_NEAR(d.Object("bracket").solid->Value(q), 0.005, 1e-9);
  OnePreviewPass(&d.model, &d.jobs);
  const auto t2 = std::chrono::steady_clock::now();
  const SceneObject& coarse = d.Object("bracket");
  EXPECT_EQ(coarse.preview_cells_across, SceneModel::kCoarseCellsAcross);
  EXPECT_EQ(coarse.preview_revision, coarse.source_revision);
  const double volume_coarse = modeling::MeshVolume(coarse.preview);
  OnePreviewPass(&d.model, &d.jobs);
  const auto t3 = std::chrono::steady_clock::now();
  const SceneObject& fine = d.Object("bracket");
  EXPECT_EQ(fine.preview_cells_across, SceneModel::kFineCellsAcross);
  // Block minus the bore (the rounded edges take away 4 (1 − π/4) r² per unit length of edge).
  const double r = 0.006, edges = 4 * (0.14 + 0.10 + 0.05);
  const double exact =
      0.14 * 0.10 * 0.05 - kPi * 0.03 * 0.03 * 0.05 - (1 - kPi / 4) * r * r * edges;
  EXPECT_NEAR(modeling::MeshVolume(fine.preview), exact, 0.02 * exact);
  EXPECT_NEAR(volume_coarse, exact, 0.10 * exact);
  // Figures for the README (printed, not asserted).
  const auto ms = [](auto a, auto b) {
    return std::chrono::duration<double, std::milli>(b - a).count();
  };
  std::printf(
      "[ figures  ] bracket edit: recompile %.2f ms, coarse preview (%g cells) %.1f ms, "
      "fine preview (%g cells) %.1f ms\n",
      ms(t0, t1), SceneModel::kCoarseCellsAcross, ms(t1, t2), SceneModel::kFineCellsAcross,
      ms(t2, t3));
}

TEST(TreeController, ADragIsOneUndoStepAndUndoRestoresTheValueBeforeIt) {
  Demo d;
  ASSERT_TRUE(d.tree.SelectByName("knob/0"));
  const size_t steps = d.model.document().history().undo_size();
  for (double r : {0.036, 0.038, 0.041, 0.040}) ASSERT_TRUE(d.tree.SetField("radius", r, true));
  d.tree.EndDrag();
  EXPECT_EQ(d.model.document().history().undo_size(), steps + 1);
  EXPECT_EQ(d.SphereRadius(), 0.040);
  // After EndDrag the next drag is its own step.
  ASSERT_TRUE(d.tree.SetField("radius", 0.030, true));
  d.tree.EndDrag();
  EXPECT_EQ(d.model.document().history().undo_size(), steps + 2);
  ASSERT_TRUE(d.tree.Undo());
  EXPECT_EQ(d.SphereRadius(), 0.040);
  ASSERT_TRUE(d.tree.Undo());
  EXPECT_EQ(d.SphereRadius(), 0.035);
  d.model.Refresh();
  EXPECT_NEAR(d.Object("knob").solid->Value(kKnobCentre), -0.035, 1e-15);
}

// While the history hold names a reason (the window's active mode holds a gesture: a carried
// part, a sculpt stroke), undo and redo change nothing and say why; once it is released they run.
TEST(TreeController, UndoAndRedoWaitWhileTheHistoryIsHeld) {
  Demo d;
  ASSERT_TRUE(d.tree.SelectByName("knob/0"));
  ASSERT_TRUE(d.tree.SetField("radius", 0.030));
  Document& doc = d.model.document();
  const std::size_t steps = doc.history().undo_size();
  std::string hold = "let go of part 'peg' first";
  d.tree.set_history_hold([&hold] { return hold; });
  const nlohmann::json before = doc.ToJson(true);
  const std::uint64_t revision = doc.revision();
  EXPECT_FALSE(d.tree.Undo());
  EXPECT_EQ(d.tree.error(), "Undo: let go of part 'peg' first");
  EXPECT_EQ(doc.ToJson(true), before);
  EXPECT_EQ(doc.revision(), revision);
  EXPECT_EQ(doc.history().undo_size(), steps);
  EXPECT_EQ(d.SphereRadius(), 0.030);
  // Released: the undo runs; held again: the redo waits.
  hold.clear();
  ASSERT_TRUE(d.tree.Undo()) << d.tree.error();
  EXPECT_EQ(d.SphereRadius(), 0.035);
  hold = "finish the sculpt stroke first";
  EXPECT_FALSE(d.tree.Redo());
  EXPECT_EQ(d.tree.error(), "Redo: finish the sculpt stroke first");
  EXPECT_EQ(d.SphereRadius(), 0.035);
  EXPECT_EQ(doc.history().redo_size(), 1u);
  hold.clear();
  ASSERT_TRUE(d.tree.Redo()) << d.tree.error();
  EXPECT_EQ(d.SphereRadius(), 0.030);
}

TEST(TreeController, ARefusedEditLeavesTheDocumentAndTheSolidUnchanged) {
  Demo d;
  ASSERT_TRUE(d.tree.SelectByName("knob/0"));
  const nlohmann::json before = d.model.document().ToJson(true);
  const auto revision = d.model.document().revision();
  const size_t steps = d.model.document().history().undo_size();
  // Negative radius mid-drag: the Document's validation refuses it.
  EXPECT_FALSE(d.tree.SetField("radius", -0.01, true));
  EXPECT_NE(d.tree.error().find("radius"), std::string::npos) << d.tree.error();
  ASSERT_TRUE(d.tree.error_at().has_value());
  EXPECT_EQ(*d.tree.error_at(), *d.tree.selection());  // shown next to the sphere
  EXPECT_EQ(d.model.document().ToJson(true), before);
  EXPECT_EQ(d.model.document().revision(), revision);
  EXPECT_EQ(d.model.document().history().undo_size(), steps);
  EXPECT_FALSE(d.model.Refresh());
  EXPECT_NEAR(d.Object("knob").solid->Value(kKnobCentre), -0.035, 1e-15);
  // Other refusals: a child for a primitive, deleting with nothing selected, a bad field.
  EXPECT_FALSE(d.tree.AddPrimitive("box", false));
  EXPECT_NE(d.tree.error().find("takes no children"), std::string::npos) << d.tree.error();
  EXPECT_FALSE(d.tree.SetField("children", nlohmann::json::array()));
  d.tree.ClearSelection();
  EXPECT_FALSE(d.tree.DeleteSelected());
  EXPECT_FALSE(d.tree.Copy());
  EXPECT_EQ(d.model.document().ToJson(true), before);
  // A good edit clears the error.
  ASSERT_TRUE(d.tree.SelectByName("knob/0"));
  ASSERT_TRUE(d.tree.SetField("radius", 0.03));
  EXPECT_TRUE(d.tree.error().empty());
}

TEST(TreeController, ASolidThatDoesNotCompileKeepsItsLastGoodShapeAndSaysWhy) {
  Demo d;
  SettlePreviews(&d.model, &d.jobs);
  ASSERT_TRUE(d.tree.SelectByName("knob/0"));
  ASSERT_TRUE(d.tree.Wrap("linear_array"));
  ASSERT_TRUE(d.model.Refresh());
  const Eigen::Vector3d p = kKnobCentre + Eigen::Vector3d(0.0, 0.0, 0.05);
  const double good = d.Object("knob").solid->Value(p);
  EXPECT_NEAR(good, 0.05 - 0.035, 1e-12);  // two copies 100 mm apart along x: the first is nearest
  const int preview_revision = d.Object("knob").revision;
  SettlePreviews(&d.model, &d.jobs);
  const auto landed = d.Object("knob").preview_revision;
  // Unions nested 80 deep on their second child: a valid tree whose value stack is deeper than
  // CompiledSolid::kMaxStackDepth, so compiling fails (checked here first).
  modeling::ImplicitNode deep = DefaultNode("sphere");
  for (int k = 0; k < 80; ++k) {
    deep =
        modeling::ImplicitNode(modeling::UnionParams{}, {DefaultNode("sphere"), std::move(deep)});
  }
  modeling::ImplicitNode root = d.model.document().Node(d.Id("knob"), {});
  root.children = {std::move(deep)};
  ASSERT_NO_THROW(modeling::ValidateTree(root));
  ASSERT_THROW(modeling::CompiledSolid::Compile(root), modeling::ModelError);
  d.model.document().Execute(edit::ReplaceTree(d.Id("knob"), std::move(root)));
  EXPECT_FALSE(d.model.Refresh());  // the haptic scene keeps the last good solid
  const SceneObject& knob = d.Object("knob");
  EXPECT_FALSE(knob.error.empty());
  EXPECT_EQ(knob.solid->Value(p), good);
  SettlePreviews(&d.model, &d.jobs);
  EXPECT_EQ(d.Object("knob").preview_revision, landed);  // no preview of the bad revision
  EXPECT_GE(d.Object("knob").revision, preview_revision);
  // Undo clears the error.
  ASSERT_TRUE(d.tree.Undo());
  d.model.Refresh();
  EXPECT_TRUE(d.Object("knob").error.empty());
  EXPECT_EQ(d.Object("knob").solid->Value(p), good);
}

TEST(TreeController, PastedSubtreesGetFreshIdsAndPastedSolidsBecomeNewObjects) {
  Demo d;
  ASSERT_TRUE(d.tree.SelectByName("knob/0"));
  ASSERT_TRUE(d.tree.SetField("id", "ball"));
  ASSERT_TRUE(d.tree.Copy());
  // Into the bracket's difference: the sphere (r 35 mm at the bracket's local origin) is cut out.
  ASSERT_TRUE(d.tree.SelectByName("bracket/0"));
  const Eigen::Vector3d q = kBracketOrigin + Eigen::Vector3d(0.0, 0.03, 0.0);
  d.model.Refresh();
  // Before: max(box −0.02, −cylinder −0.008) = −0.008.
  EXPECT_NEAR(d.Object("bracket").solid->Value(q), -0.008, 1e-9);
  ASSERT_TRUE(d.tree.Paste()) << d.tree.error();
  ASSERT_NE(d.tree.SelectedNode(), nullptr);
  const modeling::ImplicitNode* pasted = d.tree.SelectedNode();
  const std::string pasted_id = pasted->id;
  EXPECT_EQ(d.tree.selection()->path, (NodePath{0, 2}));
  EXPECT_FALSE(pasted->id.empty());
  EXPECT_NE(pasted->id, "ball");
  const auto where = d.model.document().FindNodeById(pasted->id);
  ASSERT_TRUE(where.has_value());
  EXPECT_EQ(where->first, d.Id("bracket"));
  EXPECT_EQ(d.model.document().FindNodeById("ball")->first, d.Id("knob"));
  EXPECT_TRUE(d.model.Refresh());
  // After: max(−0.02, −0.008, 0.035 − 0.03) = 0.005.
  EXPECT_NEAR(d.Object("bracket").solid->Value(q), 0.005, 1e-9);
  // A second paste gets yet another id.
  ASSERT_TRUE(d.tree.SelectByName("bracket/0"));
  ASSERT_TRUE(d.tree.Paste());
  EXPECT_NE(d.tree.SelectedNode()->id, pasted_id);
  EXPECT_NE(d.tree.SelectedNode()->id, "ball");

  // A whole solid: a new object with its own id, the same shape.
  ASSERT_TRUE(d.tree.SelectByName("knob"));
  ASSERT_TRUE(d.tree.Copy());
  ASSERT_TRUE(d.tree.Paste());
  const ObjectId copy = d.tree.selection()->object;
  EXPECT_NE(copy, d.Id("knob"));
  EXPECT_EQ(d.model.document().Get(copy).name, "knob copy");
  EXPECT_TRUE(d.model.Refresh());
  ASSERT_EQ(d.model.objects().size(), 3u);
  const Eigen::Vector3d p = kKnobCentre + Eigen::Vector3d(0.01, 0.0, 0.0);
  EXPECT_EQ(d.model.objects()[d.model.IndexOf(copy)].solid->Value(p),
            d.Object("knob").solid->Value(p));
  EXPECT_EQ(d.model.BuildHapticScene(NoSprings())->size(), 3);
  // Undo the paste: two objects again, and the selection let go of the deleted one.
  ASSERT_TRUE(d.tree.Undo());
  EXPECT_TRUE(d.model.Refresh());
  EXPECT_EQ(d.model.objects().size(), 2u);
  EXPECT_FALSE(d.tree.selection().has_value());
}

TEST(TreeController, AddWrapRenameDuplicateDeleteAllUndoBackToTheLoadedScene) {
  Demo d;
  const nlohmann::json loaded = d.model.document().ToJson();
  // A new box solid, wrapped in a translate and moved by 100 mm along x.
  ASSERT_TRUE(d.tree.AddPrimitive("box", true));
  const ObjectId box = d.tree.selection()->object;
  EXPECT_TRUE(d.tree.selection()->path.empty());
  ASSERT_TRUE(d.tree.Wrap("translate"));
  ASSERT_TRUE(d.tree.SetField("translation", {0.1, 0.0, 0.0}));
  ASSERT_TRUE(d.model.Refresh());
  const auto& solid = *d.model.objects()[d.model.IndexOf(box)].solid;
  EXPECT_NEAR(solid.Value({0.1, 0.0, 0.0}), -0.05, 1e-12);  // default box 100 mm: 50 mm deep
  EXPECT_NEAR(solid.Value({0.1, 0.0, 0.08}), 0.03, 1e-12);
  // Add a sphere child to the translate: union of box and sphere (r 50 mm) at the same place.
  ASSERT_TRUE(d.tree.AddPrimitive("sphere", false));
  EXPECT_EQ(d.tree.selection()->path, (NodePath{1}));
  ASSERT_TRUE(d.tree.RenameSelected("ball"));
  EXPECT_EQ(d.model.document().Node(box, {1}).name, "ball");
  ASSERT_TRUE(d.model.Refresh());
  EXPECT_NEAR(d.model.objects()[d.model.IndexOf(box)].solid->Value({0.1, 0.0, 0.08}), 0.03, 1e-12);
  // Wrap the box in a difference: the box minus a default sphere (r 50 mm): one undo step.
  d.tree.Select(box, {0});
  const size_t steps = d.model.document().history().undo_size();
  ASSERT_TRUE(d.tree.Wrap("difference")) << d.tree.error();
  EXPECT_EQ(d.model.document().history().undo_size(), steps + 1);
  EXPECT_TRUE(
      std::holds_alternative<modeling::DifferenceParams>(d.model.document().Node(box, {0}).params));
  // Rename and duplicate the object; delete a node; delete the duplicate.
  d.tree.Select(box);
  ASSERT_TRUE(d.tree.RenameSelected("block"));
  ASSERT_TRUE(d.tree.DuplicateSelected());
  EXPECT_EQ(d.model.document().Get(d.tree.selection()->object).name, "block copy");
  ASSERT_TRUE(d.tree.DeleteSelected());
  EXPECT_FALSE(d.tree.selection().has_value());
  d.tree.Select(box, {1});
  ASSERT_TRUE(d.tree.DeleteSelected());
  EXPECT_EQ(d.tree.selection()->path, NodePath{});  // the parent
  ASSERT_TRUE(d.model.Refresh());
  EXPECT_EQ(d.model.objects().size(), 3u);
  // Every step undone: the document is the loaded one again, and clean.
  while (d.tree.Undo()) {
  }
  EXPECT_EQ(d.model.document().ToJson(), loaded);
  EXPECT_FALSE(d.model.document().dirty());
  EXPECT_TRUE(d.model.Refresh());
  EXPECT_EQ(d.model.objects().size(), 2u);
  // ... and redone.
  while (d.tree.Redo()) {
  }
  d.model.Refresh();
  EXPECT_EQ(d.model.objects().size(), 3u);
  EXPECT_EQ(d.model.document().Get(box).name, "block");
}

TEST(TreeController, SaveWritesTheEditedSceneAndTheTitleShowsUnsavedEdits) {
  Demo d;
  EXPECT_EQ(d.tree.Title().rfind("*", 0), std::string::npos) << d.tree.Title();
  EXPECT_FALSE(d.tree.Save());  // the demo has no file
  EXPECT_NE(d.tree.error().find("Save As"), std::string::npos) << d.tree.error();
  ASSERT_TRUE(d.tree.SelectByName("knob/0"));
  ASSERT_TRUE(d.tree.SetField("radius", 0.02));
  EXPECT_EQ(d.tree.Title().rfind("*", 0), 0u) << d.tree.Title();
  const std::string dir = std::string(SPIDARCAD_TEST_OUTPUT_DIR) + "/tree_panel";
  std::filesystem::create_directories(dir);
  const std::string path = dir + "/edited.json";
  std::filesystem::remove(path);
  ASSERT_TRUE(d.tree.Save(path)) << d.tree.error();
  EXPECT_EQ(d.tree.Title(), "spidarcad — edited.json");
  EXPECT_FALSE(d.model.SourceChanged());  // our own write is not an outside change
  EXPECT_EQ(d.model.source(), path);
  const modeling::Scene back = modeling::LoadScene(path);
  ASSERT_EQ(back.solids.size(), 2u);
  EXPECT_EQ(back.solids[1].name, "knob");
  EXPECT_EQ(std::get<modeling::SphereParams>(back.solids[1].root.children[0].params).radius, 0.02);
  ASSERT_TRUE(d.tree.Save());  // now to the same file
  EXPECT_FALSE(d.tree.Save("/nonexistent/dir/x.json"));
  EXPECT_NE(d.tree.error().find("/nonexistent/dir/x.json"), std::string::npos) << d.tree.error();
  // The saved file loads into a new model with the edited sphere.
  SceneModel again;
  again.Load(path, Eigen::Vector3d::Constant(0.19));
  EXPECT_NEAR(again.objects()[1].solid->Value(kKnobCentre), -0.02, 1e-12);
}

// An object without a node tree (here a sculpt) stays selected as a whole across Revalidate, so
// that the modes can act on it; node edits refuse it, and its deletion clears the selection.
TEST(TreeController, AnObjectWithoutATreeStaysSelectedAsAWholeUntilItIsGone) {
  Demo d;
  Document& doc = d.model.document();
  doc.Execute(edit::AddSculpt("clay", modeling::IcosphereMesh(0.02, 1)));
  const ObjectId clay = doc.last_created().at(0);
  d.tree.Select(clay, {0, 1});  // a path it cannot have
  d.tree.Revalidate();
  ASSERT_TRUE(d.tree.selection().has_value());
  EXPECT_EQ(d.tree.selection()->object, clay);
  EXPECT_TRUE(d.tree.selection()->path.empty());
  EXPECT_EQ(d.tree.SelectedNode(), nullptr);
  const std::string before = doc.ToJson().dump();
  EXPECT_FALSE(d.tree.SetField("radius", 0.01));
  EXPECT_EQ(doc.ToJson().dump(), before);
  doc.Execute(edit::DeleteObject(clay));
  d.tree.Revalidate();
  EXPECT_FALSE(d.tree.selection().has_value());
}

// A mesh made from a solid, and an FE model on it, are stale once the solid is edited (and again
// up to date after undo); Refresh is asked for on either and names the mesh; a sculpt copy, an
// imported mesh and the solid itself are never stale; a mesh whose solid was deleted is stale
// but cannot be refreshed; Delete removes a mesh object (with its FE model) as one step.
TEST(TreeController, MeshesOfAnEditedSolidAreStaleAndRefreshIsAskedForOnThem) {
  Demo d;
  Document& doc = d.model.document();
  const ObjectId knob = d.Id("knob");
  const std::uint64_t knob_revision = doc.Get(knob).revision;
  auto surface = std::make_shared<const modeling::TriangleMesh>(modeling::IcosphereMesh(0.035, 1));
  doc.Execute(edit::AddMesh("knob surface", knob, knob_revision, surface, nullptr));
  const ObjectId mesh = doc.last_created().at(0);
  doc.Execute(edit::AddMesh("wedge", 0, 0, surface, nullptr));
  const ObjectId imported = doc.last_created().at(0);
  doc.Execute(edit::AddSculpt("knob sculpt", modeling::IcosphereMesh(0.035, 1)));
  const ObjectId clay = doc.last_created().at(0);
  for (ObjectId id : {knob, mesh, imported, clay}) EXPECT_EQ(StaleReason(doc, id), "") << id;
  EXPECT_EQ(RefreshableMesh(doc, mesh), mesh);
  EXPECT_EQ(RefreshableMesh(doc, imported), 0u);
  EXPECT_EQ(RefreshableMesh(doc, clay), 0u);
  EXPECT_EQ(RefreshableMesh(doc, knob), 0u);

  ASSERT_TRUE(d.tree.SelectByName("knob/0"));
  ASSERT_TRUE(d.tree.SetField("radius", 0.04));
  EXPECT_EQ(StaleReason(doc, mesh), "'knob' changed since this mesh was made");
  EXPECT_EQ(StaleReason(doc, clay), "") << "a sculpt is an edited copy";
  EXPECT_EQ(StaleReason(doc, imported), "");
  ASSERT_TRUE(d.tree.SelectByName("knob surface")) << "an object without a tree, by name";
  EXPECT_EQ(d.tree.selection()->object, mesh);
  ASSERT_TRUE(d.tree.RequestRefresh()) << d.tree.error();
  EXPECT_EQ(d.tree.TakeRefreshRequest(), mesh);
  EXPECT_EQ(d.tree.TakeRefreshRequest(), 0u) << "taken once";
  d.tree.Select(imported);
  EXPECT_FALSE(d.tree.RequestRefresh());
  EXPECT_NE(d.tree.error().find("was not meshed from another object"), std::string::npos)
      << d.tree.error();
  EXPECT_EQ(d.tree.TakeRefreshRequest(), 0u);
  ASSERT_TRUE(d.tree.Undo());
  EXPECT_EQ(StaleReason(doc, mesh), "") << "the solid is back at the revision that was meshed";
  ASSERT_TRUE(d.tree.Redo());

  // An FE model can only sit on tetrahedra: a tet mesh of the knob with an FE model on it.
  modeling::TetMesh tet;
  tet.nodes = Eigen::Matrix3Xd::Zero(3, 4);
  tet.nodes.col(1) << 0.01, 0, 0;
  tet.nodes.col(2) << 0, 0.01, 0;
  tet.nodes.col(3) << 0, 0, 0.01;
  tet.tets.resize(4, 1);
  tet.tets << 0, 1, 2, 3;
  tet.regions = Eigen::VectorXi::Zero(1);
  doc.Execute(edit::AddMesh("knob tets", knob, knob_revision, nullptr,
                            std::make_shared<const modeling::TetMesh>(tet)));
  const ObjectId tets = doc.last_created().at(0);
  doc.Execute(edit::AddFeModel("knob FE", tets, fem::Material{200e9, 0.3}, {}));
  const ObjectId fe = doc.last_created().at(0);
  EXPECT_EQ(StaleReason(doc, fe),
            "its mesh 'knob tets' is stale: 'knob' changed since this mesh was made");
  EXPECT_EQ(RefreshableMesh(doc, fe), tets);
  d.tree.Select(fe);
  ASSERT_TRUE(d.tree.RequestRefresh()) << d.tree.error();
  EXPECT_EQ(d.tree.TakeRefreshRequest(), fe);

  // The solid deleted: stale, nothing to refresh from.
  doc.Execute(edit::DeleteObject(knob));
  EXPECT_EQ(StaleReason(doc, mesh), "its source (object " + std::to_string(knob) + ") was deleted");
  EXPECT_EQ(RefreshableMesh(doc, mesh), 0u);
  d.tree.Select(mesh);
  EXPECT_FALSE(d.tree.RequestRefresh());
  EXPECT_NE(d.tree.error().find("was deleted"), std::string::npos) << d.tree.error();

  // Delete on a selected object without a tree: the mesh and the FE model on it, one step.
  const std::size_t steps = doc.history().undo_size();
  d.tree.Select(tets);
  ASSERT_TRUE(d.tree.DeleteSelected()) << d.tree.error();
  EXPECT_EQ(doc.Find(tets), nullptr);
  EXPECT_EQ(doc.Find(fe), nullptr);
  EXPECT_EQ(doc.history().undo_size(), steps + 1);
}

TEST(TreeController, NamesUnitsAndDefaultNodesCoverEveryType) {
  EXPECT_EQ(UnitOfField("radius"), FieldUnit::kLength);
  EXPECT_EQ(UnitOfField("translation"), FieldUnit::kLength);
  EXPECT_EQ(UnitOfField("angle"), FieldUnit::kAngle);
  EXPECT_EQ(UnitOfField("count"), FieldUnit::kCount);
  EXPECT_EQ(UnitOfField("axis"), FieldUnit::kPlain);
  EXPECT_DOUBLE_EQ(DisplayScale(FieldUnit::kAngle) * kPi, 180.0);
  EXPECT_DOUBLE_EQ(DisplayScale(FieldUnit::kLength), 1000.0);
  EXPECT_EQ(PrimitiveTypeNames().size() + OperationTypeNames().size(),
            std::variant_size_v<modeling::NodeParams>);
  // Every primitive's default node is a valid solid on its own; every operation around one.
  for (const std::string& t : PrimitiveTypeNames()) {
    const modeling::ImplicitNode n = DefaultNode(t);
    EXPECT_EQ(modeling::NodeTypeName(n.params), t);
    if (t == "half_space") continue;  // valid but unbounded
    EXPECT_NO_THROW(modeling::ValidateTree(n)) << t;
  }
  EXPECT_THROW(DefaultNode("teapot"), std::invalid_argument);
  // Every field the scene format writes for every type has a unit the panel knows (no field
  // name falls through to "length" by accident except the length ones).
  for (const std::string& t : OperationTypeNames()) {
    modeling::ImplicitNode n = DefaultNode(t);
    n.children = {DefaultNode("sphere"), DefaultNode("box")};
    const nlohmann::json j = modeling::NodeToJson(n);
    for (auto it = j.begin(); it != j.end(); ++it) {
      if (it.value().is_number() || it.value().is_array()) {
        if (it.key() == "children") continue;
        const FieldUnit u = UnitOfField(it.key());
        if (it.value().is_number_integer() && it.key() != "count") {
          ADD_FAILURE() << t << "." << it.key() << " is an integer but not a count";
        }
        if (u == FieldUnit::kLength) {
          static const std::set<std::string> lengths = {"radius",      "distance", "thickness",
                                                        "translation", "offset",   "step"};
          EXPECT_TRUE(lengths.count(it.key())) << t << "." << it.key() << " shown as mm";
        }
      }
    }
  }
  modeling::ImplicitNode named = DefaultNode("sphere");
  EXPECT_EQ(NodeLabel(named), "sphere");
  named.id = "ball";
  EXPECT_EQ(NodeLabel(named), "ball (sphere)");
  named.name = "Ball";
  EXPECT_EQ(NodeLabel(named), "Ball (sphere)");
}

// ---- the ImGui side, headless (no window: ImGui draws into lists nobody renders) ----

// An ImGui context with a font atlas and a display, for drawing panels without a window.
struct HeadlessImGui {
  HeadlessImGui() {
    ImGui::CreateContext();
    ImGuiIO& io = ImGui::GetIO();
    io.IniFilename = nullptr;
    io.DisplaySize = ImVec2(1280.0f, 800.0f);
    io.DeltaTime = 1.0f / 60.0f;
    unsigned char* pixels = nullptr;
    int w = 0, h = 0;
    io.Fonts->GetTexDataAsRGBA32(&pixels, &w, &h);
  }
  ~HeadlessImGui() { ImGui::DestroyContext(); }
  // One frame of the scene panel's tree with `keys` (GLFW codes) held and Ctrl/Shift as given.
  void Frame(TreeController* tree, TreePanelState* state, std::initializer_list<int> keys = {},
             bool ctrl = false, bool shift = false) {
    ImGuiIO& io = ImGui::GetIO();
    for (bool& down : io.KeysDown) down = false;
    for (int k : keys) io.KeysDown[k] = true;
    io.KeyCtrl = ctrl;
    io.KeyShift = shift;
    ImGui::NewFrame();
    ImGui::SetNextWindowSize(ImVec2(330.0f, 700.0f));
    ImGui::Begin("Scene");
    DrawTreePanel(tree, state, 300.0f);
    ImGui::End();
    HandleTreeShortcuts(tree, state);
    ImGui::Render();
  }
};

TEST(TreeController, PanelDrawsEveryNodeAndItsShortcutsAndMenuActionsEditTheDocument) {
  Demo d;
  HeadlessImGui imgui;
  TreePanelState state;
  // Every node of both solids selected and drawn with its parameters.
  for (const char* name :
       {"bracket", "bracket/0", "bracket/0/0", "bracket/0/1", "knob", "knob/0"}) {
    ASSERT_TRUE(d.tree.SelectByName(name)) << name;
    imgui.Frame(&d.tree, &state);
    EXPECT_EQ(*state.drawn_selection, *d.tree.selection()) << name;
  }
  // The rename field was filled for the selection.
  EXPECT_EQ(std::string(state.rename), "");  // the sphere has no name
  ASSERT_TRUE(d.tree.SelectByName("knob"));
  imgui.Frame(&d.tree, &state);
  EXPECT_EQ(std::string(state.rename), "knob");

  // A drag edit, then a frame with no widget held: the drag is closed, so the next drag edit is
  // a step of its own.
  ASSERT_TRUE(d.tree.SelectByName("knob/0"));
  const size_t steps = d.model.document().history().undo_size();
  ASSERT_TRUE(d.tree.SetField("radius", 0.04, true));
  imgui.Frame(&d.tree, &state);
  ASSERT_TRUE(d.tree.SetField("radius", 0.045, true));
  EXPECT_EQ(d.model.document().history().undo_size(), steps + 2);

  // Ctrl+Z undoes, Ctrl+Y and Ctrl+Shift+Z redo (one frame with the key down, one without).
  imgui.Frame(&d.tree, &state, {GLFW_KEY_Z}, true);
  imgui.Frame(&d.tree, &state);
  EXPECT_EQ(d.SphereRadius(), 0.04);
  imgui.Frame(&d.tree, &state, {GLFW_KEY_Y}, true);
  imgui.Frame(&d.tree, &state);
  EXPECT_EQ(d.SphereRadius(), 0.045);
  imgui.Frame(&d.tree, &state, {GLFW_KEY_Z}, true);
  imgui.Frame(&d.tree, &state);
  imgui.Frame(&d.tree, &state, {GLFW_KEY_Z}, true, true);
  imgui.Frame(&d.tree, &state);
  EXPECT_EQ(d.SphereRadius(), 0.045);
  // Ctrl+C on the knob's root, Ctrl+V: a new solid through ImGui's clipboard text.
  ASSERT_TRUE(d.tree.SelectByName("knob"));
  imgui.Frame(&d.tree, &state, {GLFW_KEY_C}, true);
  imgui.Frame(&d.tree, &state);
  EXPECT_NE(std::string(ImGui::GetClipboardText()).find("spidarcad-clipboard"), std::string::npos);
  imgui.Frame(&d.tree, &state, {GLFW_KEY_V}, true);
  imgui.Frame(&d.tree, &state);
  ASSERT_EQ(d.model.document().objects().size(), 3u);
  EXPECT_EQ(d.model.document().objects()[2].name, "knob copy");
  // Delete (no Ctrl) deletes the selection: the pasted copy.
  imgui.Frame(&d.tree, &state, {GLFW_KEY_DELETE});
  imgui.Frame(&d.tree, &state);
  EXPECT_EQ(d.model.document().objects().size(), 2u);

  // A context-menu action is queued while the tree is drawn and runs after it.
  ASSERT_TRUE(d.tree.SelectByName("knob/0"));
  state.pending = [](TreeController* c) { c->Wrap("translate"); };
  imgui.Frame(&d.tree, &state);
  EXPECT_FALSE(state.pending);
  EXPECT_TRUE(std::holds_alternative<modeling::TranslateParams>(
      d.model.document().Node(d.Id("knob"), {0}).params));
  // A refused edit's error is drawn next to its node without trouble.
  ASSERT_TRUE(d.tree.SelectByName("knob/0/0"));
  EXPECT_FALSE(d.tree.SetField("radius", -1.0));
  imgui.Frame(&d.tree, &state);
  EXPECT_FALSE(d.tree.error().empty());
}

// ---- the window ----

int RunCommand(const std::string& command, std::string* output) {
  FILE* pipe = popen(command.c_str(), "r");
  if (pipe == nullptr) return -1;
  char buffer[512];
  while (std::fgets(buffer, sizeof(buffer), pipe) != nullptr) *output += buffer;
  const int status = pclose(pipe);
  return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
}

TEST(TreeControllerWindow, ScreenshotShowsTheTreeWithTheSelectedNodeHighlighted) {
  const char* display = std::getenv("DISPLAY");
  if (display == nullptr || display[0] == '\0') {
    GTEST_SKIP() << "no X display: run under xvfb-run to include the window tests";
  }
  const std::string png = std::string(SPIDARCAD_TEST_OUTPUT_DIR) + "/tree_panel.png";
  std::filesystem::remove(png);
  std::string output;
  const int status =
      RunCommand(std::string("'") + SPIDARCAD_EXE + "' demo --select knob/0 --screenshot '" + png +
                     "' --size 1280x800 --device ideal 2>&1",
                 &output);
  ASSERT_EQ(status, 0) << output;
  const vtkSmartPointer<vtkImageData> image = ReadPng(png);
  int dims[3];
  image->GetDimensions(dims);
  ASSERT_EQ(dims[0], 1280);
  ASSERT_EQ(dims[1], 800);
  const int comps = image->GetNumberOfScalarComponents();
  const auto* px = static_cast<const unsigned char*>(image->GetScalarPointer());
  // The selected row: ImGui's header colour (0.80, 0.85, 0.93) in the document panel (docked
  // on the left, kPanelWidth wide).
  const int x1 = static_cast<int>(kPanelWidth);
  int highlighted = 0, dark = 0;
  for (int j = 0; j < dims[1]; ++j) {
    for (int i = 0; i < x1; ++i) {
      const unsigned char* p = px + (static_cast<size_t>(j) * dims[0] + i) * comps;
      if (std::abs(p[0] - 204) <= 2 && std::abs(p[1] - 217) <= 2 && std::abs(p[2] - 237) <= 2) {
        ++highlighted;
      }
      if (p[0] + p[1] + p[2] < 200) ++dark;
    }
  }
  EXPECT_GT(highlighted, 1000) << "no selected row in the tree";
  EXPECT_GT(dark, 3000) << "too little text in the scene panel";
  // A name that is not in the scene is bad input.
  output.clear();
  EXPECT_EQ(RunCommand(std::string("'") + SPIDARCAD_EXE + "' demo --select teapot --frames 1 2>&1",
                       &output),
            2)
      << output;
  EXPECT_NE(output.find("nothing named 'teapot' in the document: give a solid's name"),
            std::string::npos)
      << output;
}

}  // namespace
}  // namespace spidarcad::app
