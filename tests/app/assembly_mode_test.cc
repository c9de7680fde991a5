// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
// Assembly mode in the window (issue 5): AssemblyMode places one actor per part at the pose the
// field publishes (checked against a transform computed here and against the closed-form box of
// the right arm), colours parts by state, shows the seat ghost, resets; the SceneView hides the
// part solids (which sit at their frame origins) so that nothing is drawn at the origin; the
// trajectory assets/trajectories/seat_right_leg.csv seats the right leg through the window's
// haptic runtime (virtual clock); and the window itself (xvfb) plays it, with --screenshot and
// with --frames, and prints "assembly: 1 of 5 parts seated (right_leg), carried: none". On a
// Document's rigid parts: a part let go is one command ("Move part", "Seat part ... on ..."),
// undo and redo move the field's part, an edit of a part's solid rebuilds the field with the new
// shape, the seating trajectory leaves exactly one command, and turning snap on or off rebuilds
// the field with its alignment snap on or off.
#include "gui/assembly_mode.h"

#include <gtest/gtest.h>
#include <vtkActor.h>
#include <vtkActorCollection.h>
#include <vtkImageData.h>
#include <vtkMapper.h>
#include <vtkMatrix4x4.h>
#include <vtkNew.h>
#include <vtkPNGReader.h>
#include <vtkPolyData.h>
#include <vtkProperty.h>
#include <vtkRenderer.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <memory>
#include <numbers>
#include <string>
#include <vector>

#include "doc/command.h"
#include "doc/document.h"
#include "doc/job.h"
#include "gui/scene_view.h"
#include "scene/grip_control.h"
#include "scene/haptic_runtime.h"
#include "scene/scene_model.h"
#include "scene/shared_field.h"
#include "spidarcad/haptics/trajectory.h"
#include "spidarcad/modeling/scene_io.h"
#include "spidarcad_runner.h"
#include "window_test_support.h"

namespace spidarcad::app {
namespace {

using window_test::ReadPng;

constexpr double kPi = std::numbers::pi;
const std::string kScene = std::string(SPIDARCAD_SOURCE_DIR) + "/assets/scenes/assembly.json";
const std::string kSeatTrajectory =
    std::string(SPIDARCAD_SOURCE_DIR) + "/assets/trajectories/seat_right_leg.csv";
constexpr int kRightArm = 2;  // index of right_arm in assembly.json's parts
constexpr int kRightLeg = 4;  // and of right_leg

Eigen::Isometry3d Pose(const Eigen::Vector3d& p, const Eigen::Vector3d& axis, double angle) {
  Eigen::Isometry3d X = Eigen::Isometry3d::Identity();
  X.linear() = Eigen::AngleAxisd(angle, axis.normalized()).toRotationMatrix();
  X.translation() = p;
  return X;
}

// The 4×4 matrix of a vtkActor (position, orientation, scale and user matrix combined).
Eigen::Matrix4d ActorMatrix(vtkActor* actor) {
  Eigen::Matrix4d M;
  vtkMatrix4x4* m = actor->GetMatrix();
  for (int r = 0; r < 4; ++r) {
    for (int c = 0; c < 4; ++c) M(r, c) = m->GetElement(r, c);
  }
  return M;
}

// True when the actor's colour is `rgb` (to float precision).
bool HasColour(vtkActor* actor, const std::array<double, 3>& rgb) {
  double c[3];
  actor->GetProperty()->GetColor(c);
  return std::abs(c[0] - rgb[0]) < 1e-6 && std::abs(c[1] - rgb[1]) < 1e-6 &&
         std::abs(c[2] - rgb[2]) < 1e-6;
}

// The polydata a part actor draws (its normals filter's output, brought up to date).
vtkPolyData* ActorData(vtkActor* actor) {
  actor->GetMapper()->Update();
  return vtkPolyData::SafeDownCast(actor->GetMapper()->GetInput());
}

TEST(AssemblyMode, LoadsTheRobotsPartsAndTheSolidsTheyUse) {
  vtkNew<vtkRenderer> renderer;
  AssemblyMode mode(renderer);
  EXPECT_FALSE(mode.has_parts());
  mode.Load(modeling::LoadScene(kScene));
  ASSERT_TRUE(mode.has_parts());
  ASSERT_EQ(mode.size(), 6);
  EXPECT_EQ(mode.graspable_count(), 5);
  EXPECT_EQ(mode.part_name(kRightArm), "right_arm");
  EXPECT_TRUE(mode.part_fixed(0));
  EXPECT_TRUE(mode.TakeFieldChanged());
  EXPECT_FALSE(mode.TakeFieldChanged());
  std::vector<std::string> solids = mode.part_solids();
  std::sort(solids.begin(), solids.end());
  EXPECT_EQ(solids, (std::vector<std::string>{"arm", "body", "head", "leg"}));
  // Before the field's first tick the initial poses are shown; nothing seated or carried.
  EXPECT_EQ(mode.state().count, 6);
  EXPECT_EQ(mode.seated_count(), 0);
  EXPECT_EQ(FormatAssemblySummary(mode), "assembly: 0 of 5 parts seated, carried: none\n");
  // The two arms share one mesh (same solid), in P: the same polydata bounds.
  double a[6], b[6];
  ASSERT_GT(ActorData(mode.actor(2))->GetNumberOfPoints(), 100);
  ActorData(mode.actor(2))->GetBounds(a);
  ActorData(mode.actor(3))->GetBounds(b);
  for (int k = 0; k < 6; ++k) EXPECT_EQ(a[k], b[k]);
  // A scene without parts empties the mode.
  modeling::Scene plain = modeling::LoadScene(kScene);
  plain.parts.clear();
  mode.Load(plain);
  EXPECT_FALSE(mode.has_parts());
  EXPECT_EQ(mode.size(), 0);
  EXPECT_EQ(mode.field(), nullptr);
}

TEST(AssemblyMode, RefusesAPartOfAnUnknownSolidAndStaysAsItWas) {
  AssemblyMode mode(nullptr);
  mode.Load(modeling::LoadScene(kScene));
  modeling::Scene bad = modeling::LoadScene(kScene);
  bad.parts[3].solid = "no_such_solid";
  try {
    mode.Load(bad);
    FAIL() << "accepted a part of an unknown solid";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("left_arm"), std::string::npos) << e.what();
  }
  EXPECT_EQ(mode.size(), 6);
  EXPECT_NE(mode.field(), nullptr);
}

// Each actor sits at X_DW · X_WP of the shown state: every mesh point r_P of part i lands at
// p_D = (R_WP r_P + p_WP − p_WDo) / s, computed here point by point.
TEST(AssemblyMode, PlacesEveryPartAtItsPublishedPoseInTheViewFrame) {
  vtkNew<vtkRenderer> renderer;
  AssemblyMode mode(renderer);
  mode.Load(modeling::LoadScene(kScene));
  const double s = 2.5;
  const Eigen::Vector3d p_WDo(0.1, -0.2, 0.3);
  mode.SetWorldToView({s, p_WDo});
  haptics::AssemblyState state;
  state.count = mode.size();
  for (int i = 0; i < mode.size(); ++i) {
    state.X_WP[i] = Pose(Eigen::Vector3d(0.01 * i, -0.02 + 0.003 * i, 0.05 - 0.01 * i),
                         Eigen::Vector3d(1.0, 0.3 * i, -0.5), 0.4 + 0.3 * i);
  }
  mode.Show(state);
  for (int i = 0; i < mode.size(); ++i) {
    vtkActor* actor = mode.actor(i);
    ASSERT_NE(actor, nullptr);
    const Eigen::Matrix4d M = ActorMatrix(actor);
    vtkPolyData* poly = ActorData(actor);
    ASSERT_NE(poly, nullptr);
    ASSERT_GT(poly->GetNumberOfPoints(), 100);
    const Eigen::Matrix3d R = state.X_WP[i].linear();
    const Eigen::Vector3d t = state.X_WP[i].translation();
    double worst = 0.0;
    for (vtkIdType k = 0; k < poly->GetNumberOfPoints(); k += 7) {
      double r[3];
      poly->GetPoint(k, r);
      const Eigen::Vector3d r_P(r[0], r[1], r[2]);
      const Eigen::Vector3d expected = (R * r_P + t - p_WDo) / s;
      const Eigen::Vector4d got = M * Eigen::Vector4d(r[0], r[1], r[2], 1.0);
      worst = std::max(worst, (got.head<3>() - expected).norm());
    }
    EXPECT_LT(worst, 1e-12) << mode.part_name(i);
  }
}

// The right arm at its starting pose, X_WD = identity: its box in W from the scene's numbers.
// In P the arm is x, y in ±6 mm, z from −8 mm (peg end) to 35 mm (top of the bulk); turned +90°
// about y (x_W = z_P, z_W = −x_P) and moved to (0.04, 0.06, 0.0065).
TEST(AssemblyMode, RightArmActorCoversItsClosedFormBoxAtTheStartPose) {
  vtkNew<vtkRenderer> renderer;
  AssemblyMode mode(renderer);
  mode.Load(modeling::LoadScene(kScene));
  mode.OnFrame();  // no tick yet: the initial poses
  double bounds[6];
  mode.actor(kRightArm)->GetBounds(bounds);
  const double expected[6] = {0.032, 0.075, 0.054, 0.066, 0.0005, 0.0125};
  for (int k = 0; k < 6; ++k) EXPECT_NEAR(bounds[k], expected[k], 3e-4) << "bound " << k;
}

TEST(AssemblyMode, ColoursPartsByStateAndShowsTheCarriedPartsSeat) {
  vtkNew<vtkRenderer> renderer;
  AssemblyMode mode(renderer);
  mode.Load(modeling::LoadScene(kScene));
  const auto& field = mode.field();
  haptics::AssemblyState state;
  state.count = mode.size();
  for (int i = 0; i < mode.size(); ++i) state.X_WP[i] = field->part(i).X_WP;
  state.carried = kRightArm;
  state.X_WP[kRightArm].translation() += Eigen::Vector3d(0.01, -0.02, 0.05);
  state.seated[3] = true;  // left_arm
  state.X_WP[3] = field->X_WP(0) * field->part(3).seats[0].X_OS;
  mode.Show(state);
  EXPECT_TRUE(HasColour(mode.actor(0), kAssemblyFixedColour));
  EXPECT_TRUE(HasColour(mode.actor(1), kAssemblyFreeColour));
  EXPECT_TRUE(HasColour(mode.actor(kRightArm), kAssemblyCarriedColour));
  EXPECT_TRUE(HasColour(mode.actor(3), kAssemblySeatedColour));
  EXPECT_EQ(mode.part_state(kRightArm), AssemblyPartState::kCarried);
  EXPECT_EQ(mode.seated_count(), 1);
  EXPECT_EQ(FormatAssemblySummary(mode),
            "assembly: 1 of 5 parts seated (left_arm), carried: right_arm\n");
  // The ghost: the carried arm at its seat on the body, X_WS = X_W,body · X_OS (X_WD identity).
  ASSERT_TRUE(mode.ghost()->GetVisibility());
  const Eigen::Isometry3d X_WS = state.X_WP[0] * field->part(kRightArm).seats[0].X_OS;
  EXPECT_LT((ActorMatrix(mode.ghost()) - X_WS.matrix()).norm(), 1e-12);
  EXPECT_EQ(mode.ghost()->GetMapper()->GetInput(), mode.actor(kRightArm)->GetMapper()->GetInput());
  // Released: no ghost.
  state.carried = -1;
  mode.Show(state);
  EXPECT_FALSE(mode.ghost()->GetVisibility());
  EXPECT_TRUE(HasColour(mode.actor(kRightArm), kAssemblyFreeColour));
}

// Scripted grip on a field (the geometry of assembly_scene_test's scripted run): closes on part
// `part` from beside it, then each call of Lift moves the carried part up, Open opens the grasp
// until the part is let go.
class Grip {
 public:
  Grip(haptics::AssemblyField* field, int part) : field_(field) {
    tool_.R_WT << 0, 0, 1, 1, 0, 0, 0, 1, 0;
    const Eigen::Vector3d b_W = tool_.R_WT * Eigen::Vector3d(1, 1, 0).normalized();
    tool_.p_WT = field->X_WP(part) * Eigen::Vector3d(0, 0, 0.0175) - 0.02 * b_W;
    Tick();
    while (field->carried() < 0 && tool_.grasp > 0.3) {
      tool_.grasp -= 1e-3;
      tool_.grasp_rate = -1.0;
      Tick();
    }
    tool_.grasp_rate = 0.0;
  }
  void Lift(double dz) {
    for (int k = 1; k <= 400; ++k) {
      const Eigen::Vector3d next = tool_.p_WT + Eigen::Vector3d(0, 0, dz / 400);
      tool_.v_WT = (next - tool_.p_WT) / 1e-3;
      tool_.p_WT = next;
      Tick();
    }
    tool_.v_WT.setZero();
    for (int k = 0; k < 300; ++k) Tick();
  }
  void Open() {
    while (field_->carried() >= 0 && tool_.grasp < kPi / 2) {
      tool_.grasp += 1e-3;
      tool_.grasp_rate = 1.0;
      Tick();
    }
    tool_.grasp_rate = 0.0;
    for (int k = 0; k < 50; ++k) Tick();
  }

 private:
  void Tick() {
    tool_.time += 1e-3;
    field_->Evaluate(tool_);
  }
  haptics::AssemblyField* field_;
  haptics::ToolKinematics tool_;
};

// assets/scenes/assembly.json as the window opens it: its parts as rigid parts.
void LoadRobot(Document* doc) {
  doc->Load(kScene);
  ASSERT_TRUE(AdoptScenePartsAsRigidParts(doc));
}

Eigen::Isometry3d DocPose(const Document& doc, ObjectId id) {
  return std::get<RigidPartData>(doc.Get(id).data).X_WP;
}

// The right arm picked up, lifted 2 cm and let go: one command "Move part right_arm" with the
// field's pose; nothing while it is carried, nothing more afterwards, no rebuild for the mode's
// own command. Undo puts the document's arm and a new field's arm (and its actor) back at the
// start, with every tree from the cache; redo moves them again; a saved and reopened document
// has the moved pose.
TEST(AssemblyModeDocument, LetGoPartIsOneCommandThatUndoAndRedoMoveInTheField) {
  Document doc;
  LoadRobot(&doc);
  vtkNew<vtkRenderer> renderer;
  AssemblyMode mode(renderer);
  mode.LoadDocument(doc);
  ASSERT_EQ(mode.size(), 6);
  EXPECT_TRUE(mode.TakeFieldChanged());
  const ObjectId arm = mode.part_id(kRightArm);
  ASSERT_EQ(doc.Get(arm).name, "right_arm");
  const Eigen::Isometry3d start = DocPose(doc, arm);
  mode.OnFrame();
  EXPECT_FALSE(mode.SyncDocument(&doc));
  const int rebuilds = mode.rebuilds();
  std::shared_ptr<haptics::AssemblyField> field = mode.field();
  Grip grip(field.get(), kRightArm);
  ASSERT_EQ(field->carried(), kRightArm);
  grip.Lift(0.02);
  mode.OnFrame();
  EXPECT_FALSE(mode.SyncDocument(&doc)) << "carried: nothing to commit yet";
  EXPECT_EQ(doc.history().undo_size(), 0u);
  grip.Open();
  ASSERT_EQ(field->carried(), -1);
  mode.OnFrame();
  EXPECT_TRUE(mode.SyncDocument(&doc));
  EXPECT_EQ(doc.history().undo_size(), 1u);
  EXPECT_EQ(doc.history().UndoDescription(), "Move part right_arm");
  const Eigen::Isometry3d moved = DocPose(doc, arm);
  EXPECT_LT((moved.matrix() - field->X_WP(kRightArm).matrix()).norm(), 1e-12);
  EXPECT_NEAR(moved.translation().z() - start.translation().z(), 0.02, 2e-3);
  for (int i = 0; i < mode.size(); ++i) {
    if (i == kRightArm) continue;
    EXPECT_EQ(DocPose(doc, mode.part_id(i)).matrix(), field->part(i).X_WP.matrix());
  }
  mode.OnFrame();
  EXPECT_FALSE(mode.SyncDocument(&doc));
  EXPECT_EQ(doc.history().undo_size(), 1u);
  EXPECT_EQ(mode.rebuilds(), rebuilds);
  EXPECT_EQ(mode.field(), field);
  EXPECT_EQ(mode.commits(), 1);
  // Undo: the arm back in the document and in a new field (no tick yet: its initial poses).
  mode.TakeFieldChanged();
  ASSERT_TRUE(doc.Undo());
  EXPECT_EQ(DocPose(doc, arm).matrix(), start.matrix());
  EXPECT_FALSE(mode.SyncDocument(&doc));
  EXPECT_TRUE(mode.TakeFieldChanged());
  EXPECT_NE(mode.field(), field);
  EXPECT_EQ(mode.compiled_last(), 0);
  EXPECT_EQ(mode.field()->part(kRightArm).X_WP.matrix(), start.matrix());
  mode.OnFrame();
  EXPECT_LT((ActorMatrix(mode.actor(kRightArm)) - start.matrix()).norm(), 1e-12);
  EXPECT_EQ(mode.part_state(kRightArm), AssemblyPartState::kFree);
  EXPECT_FALSE(mode.SyncDocument(&doc)) << "the rebuilt field agrees with the document";
  EXPECT_EQ(doc.history().redo_size(), 1u);
  // Redo.
  ASSERT_TRUE(doc.Redo());
  mode.SyncDocument(&doc);
  EXPECT_TRUE(mode.TakeFieldChanged());
  EXPECT_EQ(mode.field()->part(kRightArm).X_WP.matrix(), moved.matrix());
  mode.OnFrame();
  EXPECT_LT((ActorMatrix(mode.actor(kRightArm)) - moved.matrix()).norm(), 1e-12);
  // Saved and reopened.
  const std::string saved = test_support::TestOutputPath("assembly_moved_arm.json");
  doc.Save(saved);
  Document again;
  again.Load(saved);
  EXPECT_FALSE(AdoptScenePartsAsRigidParts(&again)) << "saved as rigid parts";
  const DocObject* reopened = again.FindByName("right_arm");
  ASSERT_NE(reopened, nullptr);
  EXPECT_LT((DocPose(again, reopened->id).matrix() - moved.matrix()).norm(), 1e-15);
  AssemblyMode reopened_mode(nullptr);
  reopened_mode.LoadDocument(again);
  EXPECT_LT((reopened_mode.field()->part(kRightArm).X_WP.matrix() - moved.matrix()).norm(), 1e-15);
}

// Reset parts on a document: the field goes back to the poses it was built with and the parts
// that had been moved since come back as one undoable command.
TEST(AssemblyModeDocument, ResetPutsMovedPartsBackAsOneCommand) {
  Document doc;
  LoadRobot(&doc);
  AssemblyMode mode(nullptr);
  mode.LoadDocument(doc);
  const ObjectId arm = mode.part_id(kRightArm);
  const Eigen::Isometry3d start = DocPose(doc, arm);
  Grip grip(mode.field().get(), kRightArm);
  grip.Lift(0.02);
  grip.Open();
  mode.OnFrame();
  ASSERT_TRUE(mode.SyncDocument(&doc));
  const Eigen::Isometry3d moved = DocPose(doc, arm);
  ASSERT_GT((moved.translation() - start.translation()).norm(), 0.01);
  mode.Reset();
  EXPECT_TRUE(mode.SyncDocument(&doc));
  EXPECT_EQ(doc.history().undo_size(), 2u);
  EXPECT_EQ(doc.history().UndoDescription(), "Move part right_arm");
  EXPECT_EQ(DocPose(doc, arm).matrix(), start.matrix());
  ASSERT_TRUE(doc.Undo());
  mode.SyncDocument(&doc);
  EXPECT_EQ(mode.field()->part(kRightArm).X_WP.matrix(), moved.matrix());
}

// An edit of a part's solid through a command (the head's peg radius 4 -> 3.5 mm) rebuilds the
// field at the next sync: beside the peg the field's distance is the edited solid's own, 0.5 mm
// more than before; only that tree is compiled again. Undo brings the old shape back.
TEST(AssemblyModeDocument, EditOfAPartsSolidRebuildsTheFieldWithTheNewShape) {
  Document doc;
  LoadRobot(&doc);
  AssemblyMode mode(nullptr);
  mode.LoadDocument(doc);
  mode.TakeFieldChanged();
  constexpr int kHead = 1;
  const ObjectId head = mode.part_id(kHead);
  const Eigen::Vector3d p_P(0.006, 0.0, -0.004);  // 2 mm beside the peg, mid-height
  const double before = mode.field()->part(kHead).field_P->Evaluate(p_P, nullptr);
  EXPECT_NEAR(before, 0.002, 1e-12);
  doc.Execute(edit::SetNodeField(head, {1, 0}, "radius", 0.0035));
  EXPECT_FALSE(mode.SyncDocument(&doc));
  EXPECT_TRUE(mode.TakeFieldChanged());
  EXPECT_EQ(mode.compiled_last(), 1);
  const double after = mode.field()->part(kHead).field_P->Evaluate(p_P, nullptr);
  const auto own =
      modeling::CompiledSolid::Compile(std::get<RigidPartData>(doc.Get(head).data).root);
  EXPECT_NEAR(after, own.Value(p_P), 1e-12);
  EXPECT_NEAR(after - before, 0.0005, 1e-12);
  ASSERT_TRUE(doc.Undo());
  mode.SyncDocument(&doc);
  EXPECT_TRUE(mode.TakeFieldChanged());
  EXPECT_NEAR(mode.field()->part(kHead).field_P->Evaluate(p_P, nullptr), before, 1e-15);
}

// A tree edit that breaks a part (a radius the field cannot sample: no surface) keeps the last
// good field and says why, without retrying every frame.
TEST(AssemblyModeDocument, FailedRebuildKeepsTheLastGoodField) {
  Document doc;
  LoadRobot(&doc);
  AssemblyMode mode(nullptr);
  mode.LoadDocument(doc);
  mode.TakeFieldChanged();
  const std::shared_ptr<haptics::AssemblyField> field = mode.field();
  // The head moved 2 m away: outside the 0.5 m search cube about its frame origin.
  const ObjectId head = mode.part_id(1);
  doc.Execute(edit::WrapNode(head, {}, modeling::TranslateParams{Eigen::Vector3d(2.0, 0, 0)}));
  mode.SyncDocument(&doc);
  EXPECT_FALSE(mode.TakeFieldChanged());
  EXPECT_EQ(mode.field(), field);
  EXPECT_NE(mode.message().find("head"), std::string::npos) << mode.message();
  const int rebuilds = mode.rebuilds();
  mode.SyncDocument(&doc);
  EXPECT_EQ(mode.rebuilds(), rebuilds);
}

// Snap under Haptics turns the alignment snap of a carried part on and off: the field is rebuilt
// with it (assembly_field.h), and undo brings the document's setting back.
TEST(AssemblyModeDocument, SnapToggleRebuildsTheFieldWithAlignmentSnap) {
  Document doc;
  LoadRobot(&doc);
  ASSERT_FALSE(doc.snap().has_value());
  AssemblyMode mode(nullptr);
  mode.LoadDocument(doc);
  mode.TakeFieldChanged();
  EXPECT_FALSE(mode.field()->settings().align.enabled);
  doc.Execute(edit::SetSnap(modeling::SceneSnap{}));
  mode.SyncDocument(&doc);
  EXPECT_TRUE(mode.TakeFieldChanged());
  EXPECT_TRUE(mode.field()->settings().align.enabled);
  mode.SyncDocument(&doc);
  EXPECT_FALSE(mode.TakeFieldChanged());  // nothing changed since
  doc.Undo();
  mode.SyncDocument(&doc);
  EXPECT_TRUE(mode.TakeFieldChanged());
  EXPECT_FALSE(mode.field()->settings().align.enabled);
}

// The field's own state reaches the actors through OnFrame: the grip closes on the right arm
// (the geometry of assembly_scene_test's scripted run), lifts it 2 cm; Reset puts it back.
TEST(AssemblyMode, OnFrameShowsTheFieldsStateAndResetRestoresTheStart) {
  vtkNew<vtkRenderer> renderer;
  AssemblyMode mode(renderer);
  mode.Load(modeling::LoadScene(kScene));
  std::shared_ptr<haptics::AssemblyField> field = mode.field();
  haptics::ToolKinematics tool;
  tool.R_WT << 0, 0, 1, 1, 0, 0, 0, 1, 0;
  const Eigen::Vector3d b_W = tool.R_WT * Eigen::Vector3d(1, 1, 0).normalized();
  const Eigen::Isometry3d start = field->X_WP(kRightArm);
  tool.p_WT = start * Eigen::Vector3d(0, 0, 0.0175) - 0.02 * b_W;
  auto tick = [&] {
    tool.time += 1e-3;
    field->Evaluate(tool);
  };
  tick();
  while (field->carried() < 0 && tool.grasp > 0.3) {
    tool.grasp -= 1e-3;
    tool.grasp_rate = -1.0;
    tick();
  }
  tool.grasp_rate = 0.0;
  ASSERT_EQ(field->carried(), kRightArm);
  for (int k = 1; k <= 400; ++k) {
    const Eigen::Vector3d next = tool.p_WT + Eigen::Vector3d(0, 0, 0.02 / 400);
    tool.v_WT = (next - tool.p_WT) / 1e-3;
    tool.p_WT = next;
    tick();
  }
  tool.v_WT.setZero();
  for (int k = 0; k < 300; ++k) tick();
  mode.OnFrame();
  EXPECT_EQ(mode.part_state(kRightArm), AssemblyPartState::kCarried);
  const Eigen::Matrix4d shown = ActorMatrix(mode.actor(kRightArm));
  EXPECT_LT((shown - field->X_WP(kRightArm).matrix()).norm(), 1e-12);
  EXPECT_NEAR(shown(2, 3) - start.translation().z(), 0.02, 2e-3);  // lifted 2 cm
  // Reset: a new field, every part back at its initial pose.
  EXPECT_TRUE(mode.TakeFieldChanged());
  mode.Reset();
  EXPECT_TRUE(mode.TakeFieldChanged());
  EXPECT_NE(mode.field(), field);
  EXPECT_EQ(mode.part_state(kRightArm), AssemblyPartState::kFree);
  EXPECT_LT((ActorMatrix(mode.actor(kRightArm)) - start.matrix()).norm(), 1e-12);
  mode.OnFrame();  // the new field has not ticked: still the initial poses
  EXPECT_LT((ActorMatrix(mode.actor(kRightArm)) - start.matrix()).norm(), 1e-12);
}

// Visible actors of a renderer.
std::vector<vtkActor*> VisibleActors(vtkRenderer* renderer) {
  std::vector<vtkActor*> out;
  vtkActorCollection* actors = renderer->GetActors();
  actors->InitTraversal();
  while (vtkActor* a = actors->GetNextActor()) {
    if (a->GetVisibility()) out.push_back(a);
  }
  return out;
}

bool ContainsOrigin(vtkActor* actor) {
  double b[6];
  actor->GetBounds(b);
  return b[0] <= 0 && b[1] >= 0 && b[2] <= 0 && b[3] >= 0 && b[4] <= 0 && b[5] >= 0;
}

// The window's scene objects for assembly.json are the part solids, each in its own frame (all
// four straddle the origin). With them hidden, the only visible actors are the six parts, and
// none covers the origin (every part is away from it at its starting pose).
TEST(AssemblyMode, PartSolidsAreNotDrawnAtTheOrigin) {
  SceneModel model;
  const DeviceToWorld identity;
  model.Load(kScene, GripControl(haptics::SpidarGeometry{}).limits(), &identity);
  ASSERT_EQ(model.objects().size(), 4u);
  JobQueue jobs;
  model.StartPreviewJobs(&jobs, 16.0);
  for (const auto& job : jobs.jobs()) job->Wait();
  jobs.Poll();
  vtkNew<vtkRenderer> renderer;
  SceneView scene_view(renderer);
  AssemblyMode mode(renderer);
  mode.Load(modeling::LoadScene(kScene));
  // Without hiding, the static solids pile up at the origin (what the window used to show).
  scene_view.Sync(model);
  int at_origin = 0;
  for (vtkActor* a : VisibleActors(renderer)) at_origin += ContainsOrigin(a);
  EXPECT_EQ(at_origin, 4);
  scene_view.SetHidden(mode.part_solids());
  scene_view.Sync(model);
  const std::vector<vtkActor*> visible = VisibleActors(renderer);
  EXPECT_EQ(visible.size(), 6u);
  for (int i = 0; i < mode.size(); ++i) {
    EXPECT_NE(std::find(visible.begin(), visible.end(), mode.actor(i)), visible.end())
        << mode.part_name(i);
  }
  for (vtkActor* a : visible) EXPECT_FALSE(ContainsOrigin(a));
}

// The trajectory file through the window's haptic runtime (simulated SPIDAR-G with line-fit
// calibration, simulated hand), X_WD identity, on a virtual clock: the target follows the
// trajectory, as the window's player thread does in wall-clock time. Returns the summary line.
// `update_ms`: the target changes every that many ticks (60: a slow window's frame rate);
// `late_tick` (>= 0): that tick starts 10 ms late, a missed deadline (zero force, then the
// 0.5 s force ramp again). With `doc` (the robot as rigid parts) the mode works on it and syncs
// at every target update, as the window does once per frame.
std::string PlaySeatTrajectory(std::uint64_t seed, int update_ms, long late_tick, bool* carried,
                               Document* doc = nullptr) {
  const haptics::Trajectory trajectory = haptics::Trajectory::Load(kSeatTrajectory);
  const haptics::SpidarGeometry g;
  AssemblyMode mode(nullptr);
  if (doc != nullptr) {
    mode.LoadDocument(*doc);
  } else {
    mode.Load(modeling::LoadScene(kScene));
  }
  RuntimeSettings settings;  // world scale 1, origin 0
  settings.seed = seed;
  auto target = [&](double t) {
    const haptics::TrajectorySample s = trajectory.Sample(t);
    return haptics::GripPose::FromFrame(s.p_DT, s.q_DT.toRotationMatrix(), s.grasp, g.d);
  };
  HapticRuntime runtime(settings, target(trajectory.start_time()));
  auto scene = std::make_unique<haptics::HapticScene>();
  scene->Add(std::make_unique<SharedField>(mode.field()));
  runtime.Publish(std::move(scene));
  haptics::TickTiming timing;
  const long ticks =
      static_cast<long>((trajectory.end_time() - trajectory.start_time()) / 1e-3) + 500;
  *carried = false;
  for (long k = 0; k < ticks; ++k) {
    if (k % update_ms == 0) {
      runtime.SetTarget(target(trajectory.start_time() + k * 1e-3));
      if (doc != nullptr) {
        mode.OnFrame();
        mode.SyncDocument(doc);
      }
    }
    timing.lateness = k == late_tick ? 0.01 : 0.0;
    runtime.Tick(timing);
    ++timing.tick;
    *carried = *carried || mode.field()->carried() == kRightLeg;
  }
  mode.OnFrame();
  return FormatAssemblySummary(mode);
}

TEST(SeatRightLegTrajectory, StartsAtTheWindowsDefaultGrip) {
  const haptics::Trajectory trajectory = haptics::Trajectory::Load(kSeatTrajectory);
  const haptics::TrajectorySample first = trajectory.Sample(trajectory.start_time());
  EXPECT_EQ(first.p_DT, Eigen::Vector3d::Zero());
  EXPECT_NEAR(first.q_DT.angularDistance(Eigen::Quaterniond::Identity()), 0.0, 1e-12);
  EXPECT_NEAR(first.grasp, kPi / 2, 1e-9);
}

TEST(SeatRightLegTrajectory, SeatsTheLegThroughTheWindowsRuntime) {
  bool carried = false;
  EXPECT_EQ(PlaySeatTrajectory(1, 1, -1, &carried),
            "assembly: 1 of 5 parts seated (right_leg), carried: none\n");
  EXPECT_TRUE(carried);
}

// On the document: the seated leg is one command named after the seat, the document's leg sits
// exactly at its seat X_W,body · X_OS, and the mode still shows it seated.
TEST(SeatRightLegTrajectory, LeavesOneSeatCommandInTheDocument) {
  Document doc;
  LoadRobot(&doc);
  bool carried = false;
  EXPECT_EQ(PlaySeatTrajectory(1, 16, -1, &carried, &doc),
            "assembly: 1 of 5 parts seated (right_leg), carried: none\n");
  EXPECT_TRUE(carried);
  EXPECT_EQ(doc.history().undo_size(), 1u);
  EXPECT_EQ(doc.history().UndoDescription(), "Seat part right_leg on body");
  const RigidPartData& leg = std::get<RigidPartData>(doc.FindByName("right_leg")->data);
  const RigidPartData& body = std::get<RigidPartData>(doc.FindByName("body")->data);
  ASSERT_EQ(leg.seats.size(), 1u);
  const Eigen::Isometry3d X_WS = body.X_WP * PartPose(leg.seats[0].position, leg.seats[0].rotation);
  EXPECT_LT((leg.X_WP.matrix() - X_WS.matrix()).norm(), 1e-12);
  // A mode built from the document shows the leg seated (it lies in its seat).
  AssemblyMode reopened(nullptr);
  reopened.LoadDocument(doc);
  EXPECT_EQ(reopened.part_state(kRightLeg), AssemblyPartState::kSeated);
  EXPECT_EQ(FormatAssemblySummary(reopened),
            "assembly: 1 of 5 parts seated (right_leg), carried: none\n");
}

// Robust to what a loaded machine does to the window: another device (seed 3: other encoder
// errors and calibration), targets updated at 16 Hz, a missed deadline while the leg is carried.
TEST(SeatRightLegTrajectory, SeatsTheLegWithOtherErrorsSlowTargetsAndAMissedDeadline) {
  bool carried = false;
  EXPECT_EQ(PlaySeatTrajectory(3, 60, -1, &carried),
            "assembly: 1 of 5 parts seated (right_leg), carried: none\n");
  EXPECT_EQ(PlaySeatTrajectory(2, 1, 9000, &carried),
            "assembly: 1 of 5 parts seated (right_leg), carried: none\n");
  EXPECT_TRUE(carried);
}

// The window end to end (needs an X display): assembly.json with the seating trajectory and a
// screenshot, which waits until the trajectory has ended. The exit summary names the outcome;
// the picture shows the seated arm in its colour.
TEST(SpidarcadWindow, AssemblySceneSeatsTheRightLegAlongTheTrajectory) {
  const char* display = std::getenv("DISPLAY");
  if (display == nullptr || display[0] == '\0') GTEST_SKIP() << "no X display";
  const std::string png = test_support::TestOutputPath("gui_assembly.png");
  std::filesystem::remove(png);
  const test_support::CommandRun r =
      test_support::RunSpidarcad("'" + kScene + "' --trajectory '" + kSeatTrajectory +
                                     "' --screenshot '" + png + "' --size 1100x760",
                                 "", "assembly");
  ASSERT_EQ(r.status, 0) << r.all();
  EXPECT_NE(r.out.find("assembly: 1 of 5 parts seated (right_leg), carried: none"),
            std::string::npos)
      << r.all();
  const vtkSmartPointer<vtkImageData> image = ReadPng(png);
  int dims[3];
  image->GetDimensions(dims);
  ASSERT_EQ(dims[0], 1100);
  // Pixels whose chromaticity is the seated green (shaded: compare ratios).
  const int green =
      window_test::CountChromaticity(image, 0, dims[0], 0, dims[1], kAssemblySeatedColour, 0.03);
  EXPECT_GT(green, 200) << "the seated arm is not drawn in the seated colour";
}

// --frames 3: the run lasts until the trajectory has ended (about 19 s), so the arm is seated.
TEST(SpidarcadWindow, FramesRunLastsUntilTheTrajectoryHasEnded) {
  const char* display = std::getenv("DISPLAY");
  if (display == nullptr || display[0] == '\0') GTEST_SKIP() << "no X display";
  const test_support::CommandRun r = test_support::RunSpidarcad(
      "'" + kScene + "' --trajectory '" + kSeatTrajectory + "' --frames 3 --size 800x600", "",
      "frames");
  ASSERT_EQ(r.status, 0) << r.all();
  EXPECT_NE(r.out.find("assembly: 1 of 5 parts seated (right_leg), carried: none"),
            std::string::npos)
      << r.all();
}

// A bad trajectory file fails before any window opens, naming the option and the line.
TEST(SpidarcadWindow, TrajectoryOptionRefusesABadFile) {
  const char* display = std::getenv("DISPLAY");
  if (display == nullptr || display[0] == '\0') GTEST_SKIP() << "no X display";
  const std::string bad = test_support::TestOutputPath("bad_trajectory.csv");
  {
    std::ofstream out(bad);
    out << "0,0,0,0,1,0,0,0,1.57\n0.5,0,zero,0,1,0,0,0,1.57\n";
  }
  const test_support::CommandRun r =
      test_support::RunSpidarcad("none --trajectory '" + bad + "' --frames 2", "", "bad");
  EXPECT_EQ(r.status, 2) << r.all();
  EXPECT_NE(r.err.find("--trajectory"), std::string::npos) << r.all();
  EXPECT_NE(r.err.find(":2:"), std::string::npos) << r.all();
}

}  // namespace
}  // namespace spidarcad::app
