// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
// FE mode without a window: FeModel (build, cancel, stress, disk cache) and FeTouchField (the
// force felt when pushing the platform), checked against full sparse solves of the same
// prescribed displacements.
#include "gui/fe_mode.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <memory>
#include <sstream>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

#include "doc/assets.h"
#include "doc/command.h"
#include "doc/job.h"
#include "gui/app_window.h"
#include "gui/modes.h"
#include "gui/tree_panel.h"
#include "gui/workbench_panels.h"
#include "scene/fe_model.h"
#include "scene/fe_setup.h"
#include "scene/fe_touch_field.h"
#include "scene/grip_control.h"
#include "scene/haptic_runtime.h"
#include "scene/scene_model.h"
#include "scene/sculpt_document.h"
#include "scene/shared_field.h"
#include "sculpt_stroke_support.h"
#include "spidarcad/fem/static_solver.h"
#include "spidarcad/fem/stiffness.h"
#include "spidarcad/haptics/haptic_loop.h"
#include "spidarcad/haptics/simulated_hand.h"
#include "spidarcad/modeling/cgal_mesher.h"
#include "spidarcad/modeling/sculpt.h"
#include "spidarcad/modeling/surface_mesher.h"
#include "spidarcad/modeling/tet_mesh.h"
#include "support/malloc_counter.h"
#include "support/scoped_env.h"
#include "support/scripted_window.h"

namespace spidarcad::app {
namespace {

namespace fs = std::filesystem;

constexpr double kCoarse = 0.012;  // m: platform grid cell (about 12k tets)

fs::path ScratchDir(const std::string& name) {
  const fs::path dir = fs::path(SPIDARCAD_TEST_OUTPUT_DIR) / ("fe_mode_" + name);
  fs::remove_all(dir);
  fs::create_directories(dir);
  return dir;
}

// The coarse platform mesh, made once for the whole file.
const fem::TetMesh& PlatformMesh() {
  static const fem::TetMesh mesh = MeshSceneSolidForFe(PlatformScenePath(), "platform", kCoarse);
  return mesh;
}

FeModelSettings SteelSettings() {
  FeModelSettings s;
  s.material = kMaterialPresets[0].material;
  s.use_disk_cache = false;
  return s;
}

std::shared_ptr<FeModel> PlatformModel() {
  static std::shared_ptr<FeModel> model = FeModel::Build(PlatformMesh(), SteelSettings());
  return model;
}

// Tool state with the tool origin at p.
haptics::ToolKinematics ToolAt(const Eigen::Vector3d& p) {
  haptics::ToolKinematics t;
  t.p_WT = p;
  return t;
}

// Full sparse solve with the model's clamps and the state's contact nodes prescribed to their
// targets.
fem::StaticSolution FullSolve(const FeModel& model, const FeContactState& st) {
  fem::BoundaryConditions bcs = model.bcs();
  for (int s = 0; s < st.num_contacts; ++s)
    bcs.PrescribeNode(
        model.cache().candidate_node(st.candidate[s]),
        Eigen::Vector3d(st.target[3 * s], st.target[3 * s + 1], st.target[3 * s + 2]));
  const fem::MaterialTable materials(model.material());
  const fem::StaticSolver solver(model.mesh(), materials, bcs);
  EXPECT_TRUE(solver.factor_status().converged);
  return solver.Solve();
}

// Pushes the plate top near its free end with columns ready; returns the field's state.
FeContactState PushPlate(FeModel* model, FeTouchField* field, double depth_fraction,
                         double x = 0.25) {
  const double r = field->settings().tool_radius;
  const Eigen::Vector3d p(x, 0.01, 0.010 + r * (1.0 - depth_fraction));
  field->Evaluate(ToolAt(p));  // sets the focus
  model->cache().Start();
  EXPECT_TRUE(model->cache().WaitUntilIdle(300.0));
  model->cache().Stop();  // the full solves below must not share CHOLMOD with the worker
  field->Evaluate(ToolAt(p));
  return field->last_state();
}

TEST(FeModel, ClampsTheWallFaceAndFindsTheSurface) {
  const auto model = PlatformModel();
  EXPECT_GT(model->num_fixed_nodes(), 10);
  // The minimum-x face layer, 1 % of the part's largest side thick (kMinXFaceLayer).
  const Eigen::MatrixX3d& nodes = model->mesh().nodes;
  const double min_x = nodes.col(0).minCoeff();
  const double side = (nodes.colwise().maxCoeff() - nodes.colwise().minCoeff()).maxCoeff();
  for (int v = 0; v < model->mesh().num_nodes(); ++v) {
    const bool fixed = model->bcs().prescribed().count(3 * v) > 0;
    const bool on_wall = nodes(v, 0) <= min_x + 0.01 * side;
    ASSERT_EQ(fixed, on_wall) << "node " << v;
  }
  EXPECT_GT(model->mean_edge_length(), 0.3 * kCoarse);
  EXPECT_LT(model->mean_edge_length(), 3.0 * kCoarse);
  // Normals of the plate-top nodes point up.
  int top = 0;
  for (int b = 0; b < model->cache().num_candidates(); ++b) {
    const int v = model->cache().candidate_node(b);
    const Eigen::Vector3d x = model->mesh().nodes.row(v);
    if (x.z() > 0.0099 && x.x() > 0.05 && x.x() < 0.28 && std::abs(x.y()) < 0.08) {
      ++top;
      EXPECT_GT(model->candidate_normals()(b, 2), 0.9) << "node " << v;
    }
  }
  EXPECT_GT(top, 10);
}

TEST(FeTouchField, PushGivesForceOppositeToPushEqualToFullSolve) {
  const auto model = PlatformModel();
  FeTouchSettings ts;
  ts.tool_radius = 3.0 * model->mean_edge_length();
  auto channel = std::make_shared<FeContactChannel>();
  FeTouchField field(model, ts, channel);
  const FeContactState st = PushPlate(model.get(), &field, 0.4, 0.1);
  ASSERT_GE(st.num_contacts, 2);
  EXPECT_EQ(st.num_substituted, 0);
  // Frictionless: each contact force lies along its node's normal, pushing into the body.
  for (int s = 0; s < st.num_contacts; ++s) {
    const Eigen::Vector3d n = model->candidate_normals().row(st.candidate[s]).transpose();
    const Eigen::Vector3d f(st.force[3 * s], st.force[3 * s + 1], st.force[3 * s + 2]);
    EXPECT_LT((f - n * n.dot(f)).norm(), 1e-8 * f.norm()) << "slot " << s;
    EXPECT_LT(n.dot(f), 0.0) << "slot " << s;
  }
  // Pushed down: the part pushes the tool up.
  EXPECT_GT(st.f_tool_W.z(), 0.0);
  EXPECT_GT(st.f_tool_W.z(), 3.0 * std::hypot(st.f_tool_W.x(), st.f_tool_W.y()));

  const fem::StaticSolution full = FullSolve(*model, st);
  ASSERT_TRUE(full.status.converged);
  Eigen::Vector3d sum = Eigen::Vector3d::Zero();
  double fmax = 0.0;
  for (int s = 0; s < st.num_contacts; ++s)
    fmax = std::max(
        fmax, Eigen::Vector3d(st.force[3 * s], st.force[3 * s + 1], st.force[3 * s + 2]).norm());
  for (int s = 0; s < st.num_contacts; ++s) {
    const int v = model->cache().candidate_node(st.candidate[s]);
    const Eigen::Vector3d reaction = full.reaction.segment<3>(3 * v);
    const Eigen::Vector3d f(st.force[3 * s], st.force[3 * s + 1], st.force[3 * s + 2]);
    EXPECT_LT((f - reaction).norm(), 1e-6 * fmax) << "slot " << s;
    sum += reaction;
  }
  EXPECT_LT((st.f_tool_W + sum).norm(), 1e-6 * sum.norm());
  // The main thread got the same state.
  EXPECT_TRUE(channel->buffer.Update());
  EXPECT_EQ(channel->buffer.Read().num_contacts, st.num_contacts);
  EXPECT_EQ(channel->buffer.Read().f_tool_W, st.f_tool_W);
  // Felt force: scaled, bounded.
  FeTouchSettings soft = ts;
  soft.force_scale = 1e-6;
  soft.max_force = 1e9;
  FeTouchField scaled(model, soft, nullptr);
  const haptics::ToolWrench w = scaled.Evaluate(ToolAt(st.p_WT));
  EXPECT_NEAR((w.f_T_W - 1e-6 * st.f_tool_W).norm(), 0.0, 1e-9 * st.f_tool_W.norm());
  soft.max_force = 0.5;
  FeTouchField bounded(model, soft, nullptr);
  EXPECT_NEAR(bounded.Evaluate(ToolAt(st.p_WT)).f_T_W.norm(),
              std::min(0.5, 1e-6 * st.f_tool_W.norm()), 1e-12);
}

TEST(FeTouchField, DeformedSurfaceAndStressMatchFullSolveWhenSticking) {
  const auto model = PlatformModel();
  FeTouchSettings ts;
  ts.tool_radius = 3.0 * model->mean_edge_length();
  ts.frictionless = false;
  FeTouchField field(model, ts, nullptr);
  const FeContactState st = PushPlate(model.get(), &field, 0.4, 0.1);
  ASSERT_GE(st.num_contacts, 2);
  // Sticking: contact nodes move straight down (no tangential displacement).
  for (int s = 0; s < st.num_contacts; ++s)
    EXPECT_LT(std::hypot(st.target[3 * s], st.target[3 * s + 1]), 1e-12) << "slot " << s;
  Eigen::VectorXd u_out;
  EXPECT_EQ(ContactDisplacement(&model->cache(), st, &u_out), 0);
  const fem::StaticSolution full = FullSolve(*model, st);
  const Eigen::MatrixX3d u = model->FullDisplacement(u_out);
  double umax = 0.0, err = 0.0;
  for (int v = 0; v < model->mesh().num_nodes(); ++v) {
    if (model->OutputIndexOfNode(v) < 0) continue;
    umax = std::max(umax, full.displacement.segment<3>(3 * v).norm());
    err = std::max(err, (u.row(v).transpose() - full.displacement.segment<3>(3 * v)).norm());
  }
  EXPECT_GT(umax, 0.1 * ts.tool_radius * 0.5);
  EXPECT_LT(err, 1e-6 * umax);
  // Von Mises of the surface elements against fem's own stress recovery on the full solution.
  const Eigen::VectorXd vm = model->SurfaceElementVonMises(u_out);
  const Eigen::VectorXd vm_full =
      fem::ElementVonMises(model->mesh(), fem::MaterialTable(model->material()), full.displacement);
  double vmax = 0.0, verr = 0.0;
  for (std::size_t i = 0; i < model->surface_elements().size(); ++i) {
    const double ref = vm_full(model->surface_elements()[i]);
    vmax = std::max(vmax, ref);
    verr = std::max(verr, std::abs(vm(static_cast<Eigen::Index>(i)) - ref));
  }
  EXPECT_GT(vmax, 1e6);  // steel pushed by millimetres: MPa at least
  EXPECT_LT(verr, 1e-6 * vmax);
}

TEST(FeTouchField, ZeroForceOutOfContact) {
  const auto model = PlatformModel();
  FeTouchSettings ts;
  ts.tool_radius = model->mean_edge_length();
  FeTouchField field(model, ts, nullptr);
  const Eigen::Vector3d above(0.25, 0.01, 0.010 + 1.5 * ts.tool_radius);
  haptics::ToolWrench w = field.Evaluate(ToolAt(above));
  EXPECT_EQ(field.last_state().num_contacts, 0);
  EXPECT_EQ(w.f_T_W, Eigen::Vector3d::Zero());
  // In, then out again.
  PushPlate(model.get(), &field, 0.3);
  ASSERT_GT(field.last_state().num_contacts, 0);
  w = field.Evaluate(ToolAt(above));
  EXPECT_EQ(field.last_state().num_contacts, 0);
  EXPECT_EQ(w.f_T_W, Eigen::Vector3d::Zero());
  EXPECT_EQ(w.m_T_W, Eigen::Vector3d::Zero());
  // NaN tool: zero.
  w = field.Evaluate(ToolAt(Eigen::Vector3d::Constant(std::nan(""))));
  EXPECT_EQ(w.f_T_W, Eigen::Vector3d::Zero());
}

// DefaultTouch is defined further down (FE mode's defaults); declared here for the allocation test.
FeTouchSettings DefaultTouch(const FeModel& model);

TEST(FeTouchField, EvaluateAllocatesNothing) {
  ASSERT_TRUE(test_support::MallocCounterActive());
  const auto model = PlatformModel();
  FeTouchSettings ts;
  ts.tool_radius = model->mean_edge_length();
  auto channel = std::make_shared<FeContactChannel>();
  FeTouchField field(model, ts, channel);
  FeTouchSettings gs = ts;
  gs.grasp = true;
  gs.pole_length = 0.03;
  FeTouchField grasp(model, gs, channel);
  FeTouchField coupled(model, DefaultTouch(*model), channel);  // FE mode's virtual coupling
  PushPlate(model.get(), &field, 0.3);                         // some columns ready; worker stopped
  int max_k = 0, max_k_coupled = 0;
  long allocations = 0;
  {
    test_support::MallocCounter counter;
    for (int i = 0; i < 400; ++i) {  // slide across the plate, in and out of contact
      const double s = i / 400.0;
      const Eigen::Vector3d p(0.1 + 0.18 * s, -0.05 + 0.1 * s,
                              0.010 + ts.tool_radius * (0.5 + std::sin(20 * s)));
      field.Evaluate(ToolAt(p));
      max_k = std::max(max_k, field.last_state().num_contacts);
      grasp.Evaluate(ToolAt(p));
      coupled.Evaluate(ToolAt(p));
      max_k_coupled = std::max(max_k_coupled, coupled.last_state().num_contacts);
    }
    allocations = counter.count();
  }
  EXPECT_EQ(allocations, 0);
  EXPECT_GT(max_k, 1);
  EXPECT_GT(max_k_coupled, 0);  // the coupled path's contact solve and stiffness probe ran
}

TEST(FeTouchField, GraspSqueezePushesThePolesApart) {
  const auto model = PlatformModel();
  FeTouchSettings gs;
  gs.tool_radius = model->mean_edge_length();
  gs.grasp = true;
  gs.pole_length = 0.03;
  gs.max_force = 1e15;  // felt = FE wrench
  FeTouchField field(model, gs, nullptr);
  // Tool frame turned so that the tips straddle the plate (10 mm thick) vertically: the poles
  // lie in the T x-y plane; put T's (x − y) axis along W z, (x + y) along W x.
  haptics::ToolKinematics t;
  Eigen::Matrix3d R;
  const Eigen::Vector3d b_W(1, 0, 0), a_W(0, 0, 1);  // images of b_T, a_T
  R.col(0) = (b_W + a_W) / std::sqrt(2.0);
  R.col(1) = (b_W - a_W) / std::sqrt(2.0);
  R.col(2) = R.col(0).cross(R.col(1));
  t.R_WT = R;
  // Tips at x = p.x + d cos(θ/2), z = p.z ∓ d sin(θ/2); choose θ so the tips are 10 mm + 2r − 2δ
  // apart.
  const double r = gs.tool_radius, gap = 0.010 + 2.0 * r - 0.6 * r;
  t.grasp = 2.0 * std::asin(0.5 * gap / gs.pole_length);
  t.p_WT = Eigen::Vector3d(0.25 - gs.pole_length * std::cos(0.5 * t.grasp), 0.01, 0.005);
  EXPECT_LT((field.PoleTip(t, 0) - Eigen::Vector3d(0.25, 0.01, 0.005 - 0.5 * gap)).norm(), 1e-12);
  EXPECT_LT((field.PoleTip(t, 1) - Eigen::Vector3d(0.25, 0.01, 0.005 + 0.5 * gap)).norm(), 1e-12);
  field.Evaluate(t);
  model->cache().Start();
  ASSERT_TRUE(model->cache().WaitUntilIdle(300.0));
  model->cache().Stop();
  const haptics::ToolWrench w = field.Evaluate(t);
  const FeContactState& st = field.last_state();
  ASSERT_GT(st.num_contacts, 1);
  // Pushed apart: g < 0; the net force is much smaller than either tip's.
  EXPECT_LT(w.g, 0.0);
  double tip = 0.0;
  for (int s = 0; s < st.num_contacts; ++s) tip = std::max(tip, std::abs(st.force[3 * s + 2]));
  // Work check: g equals −F·∂tip/∂θ by finite differences of the tip positions.
  const double h = 1e-6;
  haptics::ToolKinematics tp = t, tm = t;
  tp.grasp += h;
  tm.grasp -= h;
  Eigen::Vector3d f_lo = Eigen::Vector3d::Zero(), f_hi = Eigen::Vector3d::Zero();
  for (int s = 0; s < st.num_contacts; ++s) {
    const Eigen::Vector3d x =
        model->mesh().nodes.row(model->cache().candidate_node(st.candidate[s])).transpose();
    const Eigen::Vector3d f(-st.force[3 * s], -st.force[3 * s + 1], -st.force[3 * s + 2]);
    ((x - field.PoleTip(t, 0)).norm() < (x - field.PoleTip(t, 1)).norm() ? f_lo : f_hi) += f;
  }
  const double g_fd = -(f_lo.dot(field.PoleTip(tp, 0) - field.PoleTip(tm, 0)) +
                        f_hi.dot(field.PoleTip(tp, 1) - field.PoleTip(tm, 1))) /
                      (2 * h);
  EXPECT_NEAR(w.g, g_fd, 1e-6 * std::abs(g_fd));
  EXPECT_GT(f_hi.z(), 0.0);  // the upper tip is pushed up
  EXPECT_LT(f_lo.z(), 0.0);  // the lower tip down
  EXPECT_GT(tip, 0.0);
}

TEST(FeModel, CancelledBuildReturnsNothingAndWritesNothing) {
  const fs::path dir = ScratchDir("cancel");
  for (double at : {0.05, 0.1, 0.7, 0.8}) {
    std::atomic<bool> cancel{false};
    FeModelSettings s = SteelSettings();
    s.use_disk_cache = true;
    s.cache_directory = dir;
    s.cancel = &cancel;
    double last = -1.0;
    s.progress = [&](double f) {
      last = f;
      if (f >= at) cancel = true;
    };
    std::unique_ptr<FeModel> model;
    EXPECT_THROW(model = FeModel::Build(PlatformMesh(), s), FeModelCancelled) << "at " << at;
    EXPECT_EQ(model, nullptr);
    EXPECT_LT(last, 1.0);
  }
  EXPECT_TRUE(fs::is_empty(dir));
}

TEST(FeModel, BadInputSaysWhat) {
  FeModelSettings s = SteelSettings();
  s.fixed_boxes.push_back(Eigen::AlignedBox3d(Eigen::Vector3d(5, 5, 5), Eigen::Vector3d(6, 6, 6)));
  try {
    FeModel::Build(PlatformMesh(), s);
    FAIL() << "no throw";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("fixed region"), std::string::npos) << e.what();
  }
  s = SteelSettings();
  s.material.poisson_ratio = 0.5;
  EXPECT_THROW(FeModel::Build(PlatformMesh(), s), std::invalid_argument);
  s = SteelSettings();
  s.order = 3;
  try {
    FeModel::Build(PlatformMesh(), s);
    FAIL() << "no throw";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("order"), std::string::npos) << e.what();
  }
}

TEST(FeModel, SavedColumnsComeBackFromTheDiskCache) {
  const fs::path dir = ScratchDir("disk");
  FeModelSettings s = SteelSettings();
  s.use_disk_cache = true;
  s.cache_directory = dir;
  s.cache.start_worker = false;
  auto first = FeModel::Build(PlatformMesh(), s);
  EXPECT_EQ(first->imported_nodes(), 0);
  std::vector<int> some;
  for (int b = 0; b < first->cache().num_candidates() && some.size() < 5; ++b)
    if (!first->cache().IsFixed(b)) some.push_back(b);
  ASSERT_EQ(first->cache().ComputeNodes(some), 5);
  std::string error;
  ASSERT_TRUE(first->SaveColumns(&error)) << error;
  auto second = FeModel::Build(PlatformMesh(), s);
  EXPECT_EQ(second->imported_nodes(), 5);
  EXPECT_EQ(second->cache_key(), first->cache_key());
  for (int b : some) {
    ASSERT_TRUE(second->cache().IsReady(b));
    ASSERT_TRUE(first->cache().Pin(b));
    ASSERT_TRUE(second->cache().Pin(b));
    EXPECT_EQ(first->cache().Block(5, b), second->cache().Block(5, b));
    first->cache().Unpin(b);
    second->cache().Unpin(b);
  }
  // Another material: another key, nothing imported.
  s.material = kMaterialPresets[1].material;
  EXPECT_EQ(FeModel::Build(PlatformMesh(), s)->imported_nodes(), 0);
}

TEST(FeTouchField, BorrowsTheNearestReadyColumnUntilItsOwnIsReady) {
  FeModelSettings s = SteelSettings();
  s.cache.start_worker = false;
  std::shared_ptr<FeModel> model = FeModel::Build(PlatformMesh(), s);
  FeTouchSettings ts;
  ts.tool_radius = 3.0 * model->mean_edge_length();
  FeTouchField field(model, ts, nullptr);
  haptics::ToolKinematics tool = ToolAt(Eigen::Vector3d(0.1, 0.01, 0.010 + 0.6 * ts.tool_radius));
  haptics::ToolWrench w = field.Evaluate(tool);
  EXPECT_TRUE(field.last_state().waiting_for_columns);
  EXPECT_EQ(field.last_state().num_contacts, 0);
  EXPECT_EQ(w.f_T_W, Eigen::Vector3d::Zero());
  // One column far from the tool (a plate-top node near the free end) is ready: borrowed.
  int far = -1;
  for (int b = 0; b < model->cache().num_candidates() && far < 0; ++b) {
    const Eigen::Vector3d x = model->mesh().nodes.row(model->cache().candidate_node(b));
    if (x.z() > 0.0099 && x.x() > 0.2 && std::abs(x.y()) < 0.05) far = b;
  }
  ASSERT_GE(far, 0);
  ASSERT_EQ(model->cache().ComputeNodes({far}), 1);
  field.Evaluate(tool);
  const FeContactState st = field.last_state();
  ASSERT_GT(st.num_contacts, 0);
  EXPECT_EQ(st.num_substituted, st.num_contacts);
  EXPECT_FALSE(st.waiting_for_columns);
  EXPECT_GT(st.f_tool_W.z(), 0.0);  // still pushes back, with the borrowed compliance
}

TEST(FeMode, PrecomputesInAJobThenPublishesAFieldAndShowsStress) {
  JobQueue jobs;
  FeMode mode(nullptr, &jobs);  // no renderer: VTK data only
  EXPECT_EQ(mode.TakeField(), nullptr);
  mode.SetMesh(PlatformMesh(), "platform");
  mode.model_settings().use_disk_cache = false;
  mode.Precompute();
  for (int i = 0; i < 6000 && jobs.busy(); ++i)
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  ASSERT_FALSE(jobs.busy());
  EXPECT_EQ(jobs.Poll(), 1);
  ASSERT_NE(mode.model(), nullptr);
  EXPECT_EQ(mode.TakeField(), nullptr);  // inactive: nothing published
  mode.SetActive(true);
  std::unique_ptr<haptics::ForceField> field = mode.TakeField();
  ASSERT_NE(field, nullptr);
  EXPECT_EQ(mode.TakeField(), nullptr);  // once
  // Push as the haptic thread would, then a frame on the main thread: the tool (FE mode's
  // patch of radius r) half its radius into the plate top.
  const double r = mode.touch_settings().tool_radius;
  haptics::ToolState tool;
  tool.tool_W.p_WT = Eigen::Vector3d(0.1, 0.01, 0.010 + 0.5 * r);
  field->Evaluate(tool.tool_W);
  ASSERT_TRUE(mode.model()->cache().WaitUntilIdle(300.0));
  const haptics::ToolWrench w = field->Evaluate(tool.tool_W);
  mode.OnFrame(tool);
  EXPECT_GT(mode.figures().contacts, 0);
  EXPECT_GT(mode.figures().f_tool_W.z(), 0.0);
  EXPECT_GT(mode.figures().max_displacement, 0.1 * 0.5 * r);
  EXPECT_GT(mode.figures().max_von_mises, 1e6);
  // Felt force: the mode's default scale and bound.
  EXPECT_LE(w.f_T_W.norm(), mode.touch_settings().max_force * (1 + 1e-12));
  EXPECT_GT(w.f_T_W.z(), 0.0);
  mode.SetActive(false);
  EXPECT_EQ(mode.TakeField(), nullptr);
  for (int i = 0; i < 3000 && jobs.busy(); ++i)
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  jobs.Poll();
}

}  // namespace
}  // namespace spidarcad::app

namespace spidarcad::app {
namespace {

// FE mode's default touch settings on `model`: tool radius = mean edge, felt force scale
// kDefaultFeForceScale, coupling kDefaultFeCoupling, at most 8 N.
FeTouchSettings DefaultTouch(const FeModel& model) {
  FeTouchSettings ts;
  ts.tool_radius = model.mean_edge_length();
  ts.force_scale = kDefaultFeForceScale;
  ts.coupling_stiffness = kDefaultFeCoupling;
  ts.max_force = 8.0;
  return ts;
}

// Where a tool sphere of radius r aimed 5 mm into the plate top (z = 0.01 m) at (0.1, 0.01) has
// its centre; the field is evaluated there once (the column focus) and the columns computed.
Eigen::Vector3d FocusFiveMillimetresIntoThePlate(FeModel* model, FeTouchField* field) {
  const Eigen::Vector3d press(0.1, 0.01, 0.010 + field->settings().tool_radius - 0.005);
  field->Evaluate(ToolAt(press));
  model->cache().Start();
  EXPECT_TRUE(model->cache().WaitUntilIdle(300.0));
  return press;
}

// The simulated hand (haptics::SimulatedHand: 0.3 kg, 300 N/m, 20 N·s/m) pushes the steel platform
// through FeTouchField at FE mode's defaults (force scale kDefaultFeForceScale, coupling
// kDefaultFeCoupling, at most 8 N, tool radius = mean edge), stepped at 1 kHz with no device
// damping: the grip must come to rest against the plate, not chatter on it. Without the coupling,
// a force scale of 1e-3 chatters (measured: force 0 .. 8 N, the grip moving 0.25 mm in the last
// second).
TEST(FeTouchField, HandPushingThePlateComesToRestWithoutChatter) {
  const auto model = PlatformModel();
  FeTouchField field(model, DefaultTouch(*model), nullptr);
  const Eigen::Vector3d target = FocusFiveMillimetresIntoThePlate(model.get(), &field);
  haptics::TrajectorySample start;
  start.p_DT = target + Eigen::Vector3d(0, 0, 0.01);  // 5 mm clear of the plate
  haptics::SimulatedHand hand(haptics::HandSettings{}, start, 0.04);
  haptics::TrajectorySample aim = start;
  aim.p_DT = target;
  const double dt = 1e-3;
  std::vector<double> z, fz;
  for (int tick = 0; tick < 3000; ++tick) {
    haptics::ToolKinematics tool = ToolAt(hand.position());
    tool.v_WT = hand.velocity();
    const haptics::ToolWrench w = field.Evaluate(tool);
    Eigen::Matrix<double, 7, 1> q;
    q << w.f_T_W, w.m_T_W, w.g;
    hand.Step(aim, q, dt);
    z.push_back(hand.position().z());
    fz.push_back(w.f_T_W.z());
  }
  model->cache().Stop();
  // Last second: at rest against the plate (force up, equal to the hand spring's pull).
  double z_min = 1e9, z_max = -1e9, f_min = 1e9, f_max = -1e9;
  for (int i = 2000; i < 3000; ++i) {
    z_min = std::min(z_min, z[i]);
    z_max = std::max(z_max, z[i]);
    f_min = std::min(f_min, fz[i]);
    f_max = std::max(f_max, fz[i]);
  }
  const double spring = 300.0 * (hand.position().z() - target.z());  // hand pull, N
  EXPECT_GT(f_min, 0.5) << "contact lost in the last second (chatter): force " << f_min << " .. "
                        << f_max;
  EXPECT_LT(z_max - z_min, 1e-4) << "grip still moving: z " << z_min << " .. " << z_max;
  EXPECT_NEAR(0.5 * (f_min + f_max), spring, 0.05 * std::abs(spring) + 0.05);
}

// The window's path: FE mode's field, wrapped as the window wraps it (SharedField), published to
// the HapticRuntime (ideal device, simulated hand, HapticLoop), ticked on a virtual clock. The
// hand comes down onto the plate; the loop must command an upward force while it presses.
TEST(FeTouchField, WindowRuntimeFeelsThePlateWhenTheHandPressesIt) {
  const auto model = PlatformModel();
  auto field = std::make_shared<FeTouchField>(model, DefaultTouch(*model), nullptr);
  const Eigen::Vector3d press = FocusFiveMillimetresIntoThePlate(model.get(), field.get());
  model->cache().Stop();

  RuntimeSettings settings;
  settings.device = RuntimeDevice::kIdeal;  // X_WD identity: W = D
  const haptics::SpidarGeometry g;
  const Eigen::Vector3d above = press + Eigen::Vector3d(0, 0, 0.01);
  HapticRuntime runtime(
      settings, haptics::GripPose::FromFrame(above, Eigen::Matrix3d::Identity(), M_PI / 2, g.d));
  auto scene = std::make_unique<haptics::HapticScene>();
  scene->Add(std::make_unique<SharedField>(field));
  runtime.Publish(std::move(scene));
  haptics::TickTiming timing;
  for (int k = 0; k < 3000; ++k) {
    if (k == 700)
      runtime.SetTarget(
          haptics::GripPose::FromFrame(press, Eigen::Matrix3d::Identity(), M_PI / 2, g.d));
    timing.tick = static_cast<std::uint64_t>(k);
    timing.elapsed = timing.period;
    runtime.Tick(timing);
  }
  const haptics::ToolState& tool = runtime.Latest().tool;
  EXPECT_GT(tool.wrench_D(2), 0.5)
      << "pressing 5 mm into the plate, the loop commands " << tool.wrench_D.head<3>().transpose()
      << " N; grip at " << tool.tool_W.p_WT.transpose() << ", events " << tool.events;
  EXPECT_FALSE(haptics::IsZeroForceEvent(tool.events));
}

// The plate-top surface node (z = 0.01 m, normal up) nearest to (x, y).
Eigen::Vector3d TopNodeNear(const FeModel& model, const Eigen::Vector2d& xy) {
  Eigen::Vector3d best = Eigen::Vector3d::Constant(1e9);
  for (int b = 0; b < model.cache().num_candidates(); ++b) {
    const Eigen::Vector3d x = model.mesh().nodes.row(model.cache().candidate_node(b)).transpose();
    if (std::abs(x.z() - 0.01) > 1e-6 || model.candidate_normals()(b, 2) < 0.99) continue;
    if ((x.head<2>() - xy).norm() < (best.head<2>() - xy).norm()) best = x;
  }
  return best;
}

// The virtual coupling (FE mode's defaults: σ = kDefaultFeForceScale, k_c = kDefaultFeCoupling)
// with the tool held still past the plate top: the coupled sphere must settle within a few
// hundred ticks at the quasi-static equilibrium k_c (x_c − x_t) = σF(x_c), and the felt
// stiffness (force change over 1 mm more depth) must stay below k_c and be lower at the plate's
// free corner than over the gusset near the wall (what FE mode is for: feeling where a design is
// compliant). The plate's bending at the corner is about 4e5 N/m in W, i.e. σK ≈ 400 N/m.
TEST(FeTouchField, CouplingSettlesAtTheSeriesEquilibriumAndTheFreeCornerFeelsSofter) {
  const auto model = PlatformModel();
  const FeTouchSettings ts = DefaultTouch(*model);
  const double r = ts.tool_radius;
  double felt_stiffness[2] = {0, 0};
  const Eigen::Vector2d spots[2] = {{0.28, 0.08}, {0.05, 0.0}};
  for (int i = 0; i < 2; ++i) {
    SCOPED_TRACE("spot " + std::to_string(i));
    double felt[2] = {0, 0};
    for (int j = 0; j < 2; ++j) {
      const double depth = 0.003 + 0.001 * j;
      FeTouchField field(model, ts, nullptr);
      const Eigen::Vector3d top = TopNodeNear(*model, spots[i]);
      const Eigen::Vector3d tool = top + Eigen::Vector3d(0, 0, r - depth);
      field.Evaluate(ToolAt(tool));
      model->cache().Start();
      ASSERT_TRUE(model->cache().WaitUntilIdle(300.0));
      haptics::ToolWrench w, previous;
      for (int tick = 0; tick < 400; ++tick) {
        previous = w;
        w = field.Evaluate(ToolAt(tool));
      }
      const FeContactState& st = field.last_state();
      ASSERT_GT(st.num_contacts, 0);
      EXPECT_EQ(st.num_substituted, 0);
      EXPECT_LT((w.f_T_W - previous.f_T_W).norm(), 1e-6 * w.f_T_W.norm()) << "still moving";
      const Eigen::Vector3d spring = ts.coupling_stiffness * (st.p_WC - tool);
      const Eigen::Vector3d fe = ts.force_scale * st.f_tool_W;
      EXPECT_LT((spring - fe).norm(), 0.01 * fe.norm())
          << "coupling " << spring.transpose() << " N, FE " << fe.transpose() << " N";
      EXPECT_GT(w.f_T_W.z(), 0.0);
      felt[j] = w.f_T_W.z();
    }
    felt_stiffness[i] = (felt[1] - felt[0]) / 0.001;
    EXPECT_GT(felt_stiffness[i], 0.0);
    EXPECT_LT(felt_stiffness[i], ts.coupling_stiffness * 1.001);
  }
  model->cache().Stop();
  std::printf(
      "felt stiffness: free corner %.0f N/m, over the gusset %.0f N/m (coupling %.0f N/m)\n",
      felt_stiffness[0], felt_stiffness[1], ts.coupling_stiffness);
  EXPECT_LT(felt_stiffness[0], 0.6 * felt_stiffness[1])
      << "free corner " << felt_stiffness[0] << " N/m, over the gusset " << felt_stiffness[1]
      << " N/m";
}

// FE mode as the window drives it (FeMode: precompute Job, TakeField, SharedField, the
// HapticRuntime on the simulated device held by the simulated hand), with the part drawn at world
// scale s (X_WD: p_W = s·p_D + p_WDo; the window puts the platform scene at s ≈ 4.6). The hand
// aims 5 mm (in D) past the plate top. At every s the grip must come to rest on the plate and feel
// the hand's pull (its spring times the gap), not chatter: at s = 4.6 with the force scale not
// divided by s the felt stiffness is 4.6 times higher and the hand bounced on the plate (measured).
// The tool's radius is a size on the part (W, kDefaultFeToolRadius at every s): its patch at rest
// holds every node under it, none refused (until 2026-12-04 the radius was scaled with s, 46 mm
// on the part at s = 4.6, and the patch was truncated at kMaxFeContacts).
TEST(FeMode, HandComesToRestOnThePlateAtAnyWorldScale) {
  JobQueue jobs;
  FeMode mode(nullptr, &jobs);
  mode.model_settings() = SteelSettings();
  mode.SetMesh(PlatformMesh(), "platform");
  mode.SetActive(true);
  mode.Precompute();
  while (jobs.busy()) {
    jobs.Poll();
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
  }
  jobs.Poll();
  ASSERT_TRUE(mode.model()) << mode.status();
  const double r = kDefaultFeToolRadius;         // the tool radius FE mode uses, on the part (W)
  const Eigen::Vector3d top_W(0.1, 0.01, 0.01);  // a point of the plate top (z = 0.01 m)
  const haptics::SpidarGeometry g;
  for (const double s : {1.0, 4.6}) {
    SCOPED_TRACE("world scale " + std::to_string(s));
    const Eigen::Vector3d p_WDo = top_W - s * Eigen::Vector3d(0, 0, -0.03);  // top_W at z_D = −3 cm
    mode.SetWorldToView({s, p_WDo});
    std::shared_ptr<haptics::ForceField> field(mode.TakeField());
    ASSERT_TRUE(field);
    auto* fe = dynamic_cast<FeTouchField*>(field.get());
    ASSERT_NE(fe, nullptr);
    EXPECT_DOUBLE_EQ(fe->settings().force_scale, kDefaultFeForceScale / s);
    EXPECT_DOUBLE_EQ(fe->settings().coupling_stiffness, kDefaultFeCoupling / s);
    EXPECT_DOUBLE_EQ(fe->settings().tool_radius, r);  // a size on the part: not scaled
    // Tool centre in D when the tool just touches the top, then where the hand aims.
    const Eigen::Vector3d touch_D(0, 0, -0.03 + r / s);
    const Eigen::Vector3d aim_D = touch_D - Eigen::Vector3d(0, 0, 0.005);
    fe->Evaluate(ToolAt(s * aim_D + p_WDo));  // column focus, then wait for the columns
    ASSERT_TRUE(mode.model()->cache().WaitUntilIdle(300.0));

    RuntimeSettings settings;
    settings.device = RuntimeDevice::kSimulated;
    settings.loop.X_WD.world_scale = s;
    settings.loop.X_WD.p_WDo = p_WDo;
    HapticRuntime runtime(settings,
                          haptics::GripPose::FromFrame(touch_D + Eigen::Vector3d(0, 0, 0.005),
                                                       Eigen::Matrix3d::Identity(), M_PI / 2, g.d));
    auto scene = std::make_unique<haptics::HapticScene>();
    scene->Add(std::make_unique<SharedField>(field));
    runtime.Publish(std::move(scene));
    haptics::TickTiming timing;
    double z_min = 1e9, z_max = -1e9, f_min = 1e9, f_max = -1e9;
    for (int k = 0; k < 4000; ++k) {
      if (k == 700)
        runtime.SetTarget(
            haptics::GripPose::FromFrame(aim_D, Eigen::Matrix3d::Identity(), M_PI / 2, g.d));
      timing.tick = static_cast<std::uint64_t>(k);
      timing.elapsed = timing.period;
      runtime.Tick(timing);
      if (k >= 3000) {
        const RuntimeFrame& frame = runtime.Latest();
        z_min = std::min(z_min, frame.hand_pose.p0.z());
        z_max = std::max(z_max, frame.hand_pose.p0.z());
        f_min = std::min(f_min, frame.tool.wrench_D(2));
        f_max = std::max(f_max, frame.tool.wrench_D(2));
      }
    }
    // The hand's spring pulls 300 N/m times the gap between aim and grip; the plate holds it.
    const double pull = settings.hand.stiffness * (0.5 * (z_min + z_max) - aim_D.z());
    EXPECT_GT(f_min, 0.3) << "contact lost in the last second: force " << f_min << " .. " << f_max
                          << " N";
    EXPECT_LT(z_max - z_min, 1e-4) << "grip still moving: z_D " << z_min << " .. " << z_max;
    EXPECT_NEAR(0.5 * (f_min + f_max), pull, 0.1 * std::abs(pull) + 0.05);
    const FeContactState& st = fe->last_state();
    std::printf("s = %.1f: %d patch nodes, %d refused, depth %.3f mm\n", s, st.num_contacts,
                st.refused, 1e3 * st.depth);
    EXPECT_GT(st.num_contacts, 0);
    EXPECT_EQ(st.refused, 0) << "tool patch truncated";
  }
  mode.SetActive(false);
  jobs.CancelAll();
  while (jobs.busy()) std::this_thread::sleep_for(std::chrono::milliseconds(5));
}

}  // namespace
}  // namespace spidarcad::app

// ---- FE mode on the window's document (a window of their own per test; need an X display) ----

namespace spidarcad::app {
namespace {

namespace fs = std::filesystem;

using test_support::HaveDisplay;

// The first differences between two JSON documents (a short message instead of both in full).
std::string Differences(const nlohmann::json& a, const nlohmann::json& b) {
  return nlohmann::json::diff(a, b).dump().substr(0, 1500);
}

// Frames until `done` holds (true) or `seconds` of wall time have passed (false).
template <class Pred>
bool FramesUntil(AppWindow& window, Pred done, double seconds = 180.0) {
  const auto give_up = std::chrono::steady_clock::now() + std::chrono::duration<double>(seconds);
  while (!done()) {
    if (std::chrono::steady_clock::now() > give_up) return false;
    window.Frame();
  }
  return true;
}

// The document as JSON with each mesh's source revision (a counter of the session) replaced by
// whether the mesh is out of date.
nlohmann::json Comparable(const Document& doc) {
  nlohmann::json j = doc.ToJson();
  for (size_t i = 0; i < doc.objects().size(); ++i) {
    if (!std::holds_alternative<MeshData>(doc.objects()[i].data)) continue;
    j["objects"][i].erase("source_revision");
    j["objects"][i]["out_of_date"] = doc.IsMeshOutOfDate(doc.objects()[i].id);
  }
  return j;
}

const FeModelData& FeDataOf(const Document& doc, ObjectId id) {
  return std::get<FeModelData>(doc.Get(id).data);
}

// Switches `window` to FE mode and draws `frames` frames; its FeMode.
FeMode& EnterFeMode(AppWindow& window, int frames = 3) {
  auto* fe_mode = dynamic_cast<FeWindowMode*>(window.FindMode("fe"));
  if (fe_mode == nullptr) throw std::runtime_error("the window has no FE mode");
  window.SwitchMode(fe_mode);
  for (int k = 0; k < frames; ++k) window.Frame();
  return fe_mode->fe();
}

// Opens the shipped platform scene, chooses its solid in FE mode, sets it up (one undo step),
// precomputes, changes the material (the model is made again), undoes and redoes (the kept
// models come back), saves, and compares the saved file with the same edits made by commands
// directly, and with what a fresh window's FE mode binds to.
TEST(FeModeWindow, SetsUpASolidPrecomputesEditsUndoesRedoesAndSaves) {
  if (!HaveDisplay()) GTEST_SKIP() << "no X display: run under xvfb-run";
  const test_support::WindowScratch scratch("fe_window_setup");
  const fs::path& dir = scratch.dir;
  test_support::ScopedEnv cache("SPIDARCAD_CACHE_DIR", (dir / "cache").string().c_str());
  const std::string shipped = AssetPath("scenes/platform.json");
  const std::string saved = (dir / "platform_fe.json").string();
  const fem::Material steel = kMaterialPresets[0].material;
  const fem::Material aluminium = kMaterialPresets[1].material;
  nlohmann::json window_json;
  {
    AppWindow window(test_support::ScriptedWindowOptions(kNoSceneName));
    window.Frame();
    ASSERT_TRUE(window.OpenDocument(shipped)) << window.file_error();
    SceneModel& model = window.model();
    const Document& doc = model.document();
    const ObjectId platform = doc.FindByName("platform")->id;
    ASSERT_TRUE(window.tree().SelectByName("platform"));
    FeMode& fe = EnterFeMode(window);
    EXPECT_EQ(fe.chosen_object(), platform) << "the tree's selection is preselected";
    EXPECT_EQ(fe.bound_object(), 0u) << "no FE model yet";
    EXPECT_EQ(doc.history().undo_size(), 0u) << "entering the mode changes nothing";
    const std::size_t solids = doc.objects().size();  // the platform and the wall

    fe.mesh_settings().cell_size = 0.012;
    ASSERT_TRUE(fe.StartSetUp(&model, platform)) << fe.status();
    ASSERT_TRUE(FramesUntil(window, [&] { return fe.bound_object() != 0; })) << fe.status();
    ASSERT_EQ(doc.objects().size(), solids + 2);
    EXPECT_EQ(doc.history().undo_size(), 1u);
    EXPECT_EQ(doc.history().UndoDescription(), "Set up FE for platform");
    const ObjectId fe_id = fe.bound_object();
    EXPECT_EQ(doc.Get(fe_id).name, "platform FE");

    fe.RequestModel();
    ASSERT_TRUE(FramesUntil(window, [&] { return fe.model() != nullptr; })) << fe.status();
    EXPECT_EQ(fe.model()->material().youngs_modulus, steel.youngs_modulus);
    const FeModel* steel_model = fe.model().get();

    ASSERT_TRUE(fe.EditMaterial(&model, aluminium)) << fe.status();
    EXPECT_EQ(doc.history().UndoDescription(), "Set material");
    window.Frame();
    EXPECT_EQ(fe.model_settings().material.youngs_modulus, aluminium.youngs_modulus);
    ASSERT_TRUE(FramesUntil(
        window,
        [&] { return fe.model() != nullptr && fe.model()->material().youngs_modulus == 70e9; }))
        << "the mode precomputes the changed model again: " << fe.status();
    const FeModel* aluminium_model = fe.model().get();

    // Ctrl+Z: the document's material goes back and the mode shows the steel model again.
    ASSERT_TRUE(window.tree().Undo());
    window.Frame();
    EXPECT_EQ(FeDataOf(doc, fe_id).material.youngs_modulus, steel.youngs_modulus);
    EXPECT_EQ(fe.model().get(), steel_model) << "the model made before comes back at once";
    ASSERT_TRUE(window.tree().Redo());
    window.Frame();
    EXPECT_EQ(FeDataOf(doc, fe_id).material.youngs_modulus, aluminium.youngs_modulus);
    EXPECT_EQ(fe.model().get(), aluminium_model);

    // Undo the set-up itself: the FE model and its mesh are gone, and so is the mode's model.
    ASSERT_TRUE(window.tree().Undo());
    ASSERT_TRUE(window.tree().Undo());
    window.Frame();
    EXPECT_EQ(doc.objects().size(), solids);
    EXPECT_EQ(fe.bound_object(), 0u);
    EXPECT_EQ(fe.model(), nullptr);
    ASSERT_TRUE(window.tree().Redo());
    ASSERT_TRUE(window.tree().Redo());
    window.Frame();
    EXPECT_EQ(fe.bound_object(), fe_id) << "redo brings the same object back";
    EXPECT_EQ(fe.model().get(), aluminium_model);

    ASSERT_TRUE(window.tree().Save(saved)) << window.tree().error();
    window.Frame();
    window_json = Comparable(doc);
  }
  Document reread;
  reread.Load(saved);
  EXPECT_TRUE(Comparable(reread) == window_json) << Differences(Comparable(reread), window_json);
  // Independently: the shipped scene with the same edits made by commands.
  Document expected;
  expected.Load(shipped);
  MeshSettings settings;
  settings.cell_size = 0.012;
  settings.mesher = "tetgen";
  FeMeshInput input = PrepareFeMesh(expected, expected.FindByName("platform")->id, settings);
  input.slabs = kFeSlabs;  // as FE mode meshes a solid (FeMode::mesh_in_slabs, mesh_strips)
  input.strips = kFeStrips;
  expected.Execute(SetUpFe(input, MeshFeSource(input)));
  expected.Execute(edit::SetFeMaterial(expected.last_created()[1], aluminium));
  EXPECT_TRUE(Comparable(reread) == Comparable(expected))
      << Differences(Comparable(reread), Comparable(expected));
  // A fresh window on the saved file: FE mode binds to the saved FE model with its material.
  AppWindow again(test_support::ScriptedWindowOptions(saved));
  FeMode& again_fe = EnterFeMode(again);
  ASSERT_NE(again_fe.bound_object(), 0u);
  EXPECT_EQ(again.model().document().Get(again_fe.bound_object()).name, "platform FE");
  EXPECT_EQ(again_fe.model_settings().material.youngs_modulus, aluminium.youngs_modulus);
  EXPECT_FALSE(again.model().document().dirty());
  // The saved mesh says where its slabs are: the reopened model is factored slab by slab, and
  // every slab's factor and interface plane is read from the disk cache the first window wrote.
  again_fe.RequestModel();
  ASSERT_TRUE(FramesUntil(again, [&] { return again_fe.model() != nullptr; })) << again_fe.status();
  const fem::SubstructuredSolver* reopened = again_fe.model()->substructured();
  ASSERT_NE(reopened, nullptr);
  EXPECT_EQ(reopened->num_blocks(), kFeSlabs);
  EXPECT_EQ(reopened->stats().loaded_blocks, kFeSlabs);
  EXPECT_EQ(reopened->stats().factored_blocks, 0);
  EXPECT_EQ(reopened->stats().loaded_interface_groups, kFeSlabs - 1);
  EXPECT_NE(again_fe.status().find("0 of 4 pieces factored, 0 kept, 4 from the disk cache"),
            std::string::npos)
      << again_fe.status();
}

// The workbench's FE model is made from the platform solid: editing the solid makes it stale in
// FE mode; Refresh meshes it again with the stored settings in one undo step that keeps the FE
// model's settings; undo makes it stale again.
TEST(FeModeWindow, EditedSourceMakesTheMeshStaleAndRefreshMeshesItAgain) {
  if (!HaveDisplay()) GTEST_SKIP() << "no X display: run under xvfb-run";
  const test_support::WindowScratch scratch("fe_window_stale");
  AppWindow window(test_support::ScriptedWindowOptions(AssetPath("scenes/workbench.json")));
  SceneModel& model = window.model();
  const Document& doc = model.document();
  FeMode& fe = EnterFeMode(window);
  const ObjectId fe_id = doc.FindByName("platform FE")->id;
  const ObjectId mesh_id = doc.FindByName("platform tets")->id;
  const ObjectId platform = doc.FindByName("platform")->id;
  ASSERT_EQ(fe.bound_object(), fe_id);
  EXPECT_FALSE(fe.stale());
  const nlohmann::json fe_before = doc.ToJson()["objects"][doc.IndexOf(fe_id)];
  const auto old_volume = std::get<MeshData>(doc.Get(mesh_id).data).volume;

  ASSERT_TRUE(window.tree().SelectByName("plate"));
  ASSERT_TRUE(window.tree().SetField("radius", 0.0045)) << window.tree().error();
  window.Frame();
  EXPECT_EQ(fe.bound_object(), fe_id) << "the platform's FE model stays chosen";
  EXPECT_TRUE(fe.stale());
  const std::size_t steps = doc.history().undo_size();
  ASSERT_TRUE(fe.StartRefresh(&model)) << fe.status();
  ASSERT_TRUE(FramesUntil(window, [&] { return !fe.stale(); })) << fe.status();
  EXPECT_EQ(doc.history().undo_size(), steps + 1);
  EXPECT_EQ(doc.history().UndoDescription(), "Refresh platform mesh");
  const auto& mesh = std::get<MeshData>(doc.Get(mesh_id).data);
  EXPECT_NE(mesh.volume, old_volume);
  EXPECT_EQ(mesh.source_revision, doc.Get(platform).revision);
  EXPECT_EQ(mesh.settings.cell_size, 0.01) << "the stored settings";
  EXPECT_EQ(mesh.settings.max_radius_edge, 2.0);
  EXPECT_EQ(doc.ToJson()["objects"][doc.IndexOf(fe_id)], fe_before)
      << "the FE model keeps its material, clamp and loads";

  ASSERT_TRUE(window.tree().Undo());
  window.Frame();
  EXPECT_TRUE(fe.stale());
  EXPECT_EQ(std::get<MeshData>(doc.Get(mesh_id).data).volume, old_volume);
  ASSERT_TRUE(window.tree().Undo());  // the radius edit
  window.Frame();
  EXPECT_FALSE(fe.stale()) << "the solid is as it was meshed again";
}

// Quadratic elements chosen before set-up: the FE model has them and the solid's flat faces are
// meshed coarser (kQuadraticFlatCells). Switching the model to linear elements meshes it again
// with the flat faces fine (a second undo step, about twice the tets); undoing that refresh
// leaves a mesh that does not fit the order, and the panel's button meshes it again.
TEST(FeModeWindow, QuadraticSetUpCoarsensFlatFacesAndTheOrderSwitchMeshesAgain) {
  if (!HaveDisplay()) GTEST_SKIP() << "no X display: run under xvfb-run";
  const test_support::WindowScratch scratch("fe_window_order");
  test_support::ScopedEnv cache("SPIDARCAD_CACHE_DIR", (scratch.dir / "cache").string().c_str());
  AppWindow window(test_support::ScriptedWindowOptions(AssetPath("scenes/platform.json")));
  SceneModel& model = window.model();
  const Document& doc = model.document();
  FeMode& fe = EnterFeMode(window);
  const ObjectId platform = doc.FindByName("platform")->id;
  fe.mesh_settings().cell_size = 0.01;
  fe.model_settings().order = 2;
  const std::size_t steps = doc.history().undo_size();
  ASSERT_TRUE(fe.StartSetUp(&model, platform, false, false)) << fe.status();
  ASSERT_TRUE(FramesUntil(window, [&] { return fe.bound_object() != 0; })) << fe.status();
  EXPECT_EQ(doc.history().undo_size(), steps + 1);
  EXPECT_EQ(FeDataOf(doc, fe.bound_object()).element_order, 2);
  const ObjectId mesh_id = FeDataOf(doc, fe.bound_object()).tet_mesh;
  auto mesh = [&]() -> const MeshData& { return std::get<MeshData>(doc.Get(mesh_id).data); };
  EXPECT_EQ(mesh().settings.flat_cells, kQuadraticFlatCells);
  EXPECT_EQ(mesh().settings.slab_planes.size(), static_cast<std::size_t>(kFeSlabs - 1));
  EXPECT_TRUE(fe.MeshFitsOrder(doc));
  const long quadratic_tets = static_cast<long>(mesh().volume->tets.cols());

  ASSERT_TRUE(fe.EditElementOrder(&model, 1)) << fe.status();
  EXPECT_FALSE(fe.MeshFitsOrder(doc)) << "until the refresh lands";
  EXPECT_EQ(fe.status(), "re-meshing for linear elements (flat faces finer)...");
  window.Frame();  // the order's command rebinds the model: the re-mesh's status stays
  if (!fe.MeshFitsOrder(doc)) {  // (the re-mesh takes tenths of a second; a frame much less)
    EXPECT_EQ(fe.status(), "re-meshing for linear elements (flat faces finer)...");
  }
  ASSERT_TRUE(FramesUntil(window, [&] { return mesh().settings.flat_cells == 0.0; }))
      << fe.status();
  EXPECT_EQ(doc.history().undo_size(), steps + 3) << "the order and the refresh";
  EXPECT_EQ(doc.history().UndoDescription(), "Refresh platform mesh");
  EXPECT_EQ(FeDataOf(doc, fe.bound_object()).element_order, 1);
  EXPECT_TRUE(fe.MeshFitsOrder(doc));
  const long linear_tets = static_cast<long>(mesh().volume->tets.cols());
  std::printf("platform at 10 mm in slabs: %ld tets for quadratic elements, %ld for linear\n",
              quadratic_tets, linear_tets);
  EXPECT_GT(linear_tets, 3 * quadratic_tets / 2);

  ASSERT_TRUE(window.tree().Undo());  // the refresh
  for (int k = 0; k < 5; ++k) window.Frame();
  EXPECT_EQ(mesh().settings.flat_cells, kQuadraticFlatCells);
  EXPECT_FALSE(fe.MeshFitsOrder(doc));
  EXPECT_EQ(doc.history().redo_size(), 1u) << "not meshed again by itself";
  ASSERT_TRUE(fe.StartRefresh(&model)) << fe.status();  // the panel's "Re-mesh for this order"
  ASSERT_TRUE(FramesUntil(window, [&] { return fe.MeshFitsOrder(doc); })) << fe.status();
  EXPECT_EQ(static_cast<long>(mesh().volume->tets.cols()), linear_tets);
}

// The response of a model in slabs to unit forces at the three surface nodes nearest the
// platform's free corner equals that of a one-piece factorisation of the same mesh.
void ExpectFreeCornerSolvedAsOnePiece(const FeModel& after) {
  ASSERT_NE(after.substructured(), nullptr);
  const fem::StaticSolver one_piece(after.mesh(), after.materials(), after.bcs());
  std::vector<int> near = after.surface().nodes;
  const Eigen::Vector3d corner(0.3, 0.1, 0.01);
  std::partial_sort(near.begin(), near.begin() + 3, near.end(), [&](int a, int b) {
    return (after.mesh().nodes.row(a).transpose() - corner).norm() <
           (after.mesh().nodes.row(b).transpose() - corner).norm();
  });
  Eigen::MatrixXd rhs = Eigen::MatrixXd::Zero(one_piece.num_free(), 9);
  for (int c = 0; c < 3; ++c)
    for (int j = 0; j < 3; ++j) rhs(one_piece.FreeIndex(3 * near[c] + j), 3 * c + j) = 1.0;
  Eigen::MatrixXd x_slabs, x_whole;
  ASSERT_TRUE(after.substructured()->SolveFree(rhs, &x_slabs).converged);
  ASSERT_TRUE(one_piece.SolveFree(rhs, &x_whole).converged);
  EXPECT_LT((x_slabs - x_whole).norm(), 1e-9 * x_whole.norm());
}

// A solid set up in FE mode is meshed in slabs and factored by slab. With the model felt, an edit
// of the solid refreshes it by itself: only the slab the edit reached is re-meshed and refactored,
// and the new model solves as a one-piece factorisation of the new mesh does. The undo of that
// refresh is not refreshed again (the redo history stays).
TEST(FeModeWindow, EditOfAFeltSolidRefreshesItselfInTheSlabsItReached) {
  if (!HaveDisplay()) GTEST_SKIP() << "no X display: run under xvfb-run";
  const test_support::WindowScratch scratch("fe_window_slabs");
  test_support::ScopedEnv cache("SPIDARCAD_CACHE_DIR", (scratch.dir / "cache").string().c_str());
  AppWindow window(test_support::ScriptedWindowOptions(AssetPath("scenes/platform.json")));
  SceneModel& model = window.model();
  const Document& doc = model.document();
  FeMode& fe = EnterFeMode(window);
  EXPECT_TRUE(fe.mesh_in_slabs()) << "the default";
  EXPECT_TRUE(fe.refresh_on_edit()) << "the default";
  const ObjectId platform = doc.FindByName("platform")->id;
  fe.mesh_settings().cell_size = 0.012;
  ASSERT_TRUE(fe.StartSetUp(&model, platform, false, true)) << fe.status();
  ASSERT_TRUE(FramesUntil(window, [&] { return fe.model() != nullptr; })) << fe.status();
  const ObjectId mesh_id = FeDataOf(doc, fe.bound_object()).tet_mesh;
  const std::shared_ptr<const SlabFeMesh> first = fe.SlabsOf(doc, mesh_id);
  ASSERT_NE(first, nullptr) << "set up in slabs";
  EXPECT_EQ(first->num_remeshed(), kFeSlabs);
  const std::shared_ptr<FeModel> before = fe.model();
  ASSERT_NE(before->substructured(), nullptr);
  EXPECT_EQ(before->substructured()->num_blocks(), kFeSlabs);
  EXPECT_EQ(before->substructured()->stats().factored_blocks, kFeSlabs);
  const std::size_t steps = doc.history().undo_size();

  // The load holes (the last slab) from 4 to 4.5 mm radius.
  ASSERT_TRUE(window.tree().SelectByName("load_hole")) << window.tree().error();
  ASSERT_TRUE(window.tree().SetField("radius", 0.0045)) << window.tree().error();
  ASSERT_TRUE(FramesUntil(window, [&] { return fe.model() != nullptr && fe.model() != before; }))
      << fe.status();
  EXPECT_FALSE(fe.stale());
  EXPECT_EQ(doc.history().undo_size(), steps + 2) << "the edit and the refresh";
  EXPECT_EQ(doc.history().UndoDescription(), "Refresh platform mesh");
  const std::shared_ptr<const SlabFeMesh> second = fe.SlabsOf(doc, mesh_id);
  ASSERT_NE(second, nullptr);
  EXPECT_EQ(second->num_remeshed(), 1);
  EXPECT_TRUE(second->remeshed.back());
  const FeModel& after = *fe.model();
  ASSERT_NE(after.substructured(), nullptr);
  EXPECT_EQ(after.substructured()->stats().factored_blocks, 1) << fe.status();
  EXPECT_EQ(after.substructured()->stats().reused_blocks, kFeSlabs - 1);
  EXPECT_NE(fe.status().find("1 of 4 pieces factored, 3 kept"), std::string::npos) << fe.status();
  EXPECT_TRUE(before->cache().paused()) << "the replaced model computes no more columns";
  EXPECT_FALSE(after.cache().paused());
  // The disk cache (on by default) keeps the slab meshes of both: the first mesh's four and the
  // slab the edit changed (a reopened document's refresh reads the slabs it shares from there).
  int slab_files = 0;
  for (const auto& entry : fs::directory_iterator(scratch.dir / "cache"))
    slab_files += entry.path().extension() == ".slab";
  EXPECT_EQ(slab_files, kFeSlabs + 1);

  ExpectFreeCornerSolvedAsOnePiece(after);

  // Once its columns are ready (or it has gone untouched for a while), the model's interface
  // factor is completed from both ends in the background, so that an edit at the clamped end
  // (the bolt holes, the first slab) refactors that slab and only the one plane it touches.
  ASSERT_TRUE(FramesUntil(window, [&] { return after.reuse_preparation_started(); }));
  const std::shared_ptr<FeModel> second_model = fe.model();
  ASSERT_TRUE(window.tree().SelectByName("bolt_hole")) << window.tree().error();
  ASSERT_TRUE(window.tree().SetField("radius", 0.006)) << window.tree().error();
  ASSERT_TRUE(FramesUntil(window, [&] {
    return fe.model() != nullptr && fe.model() != second_model;
  })) << fe.status();
  const fem::SubstructuredSolver& third = *fe.model()->substructured();
  EXPECT_EQ(third.stats().factored_blocks, 1) << fe.status();
  EXPECT_EQ(third.stats().factored_interface_groups, 1);
  EXPECT_EQ(third.stats().reused_trailing_interface_groups, kFeSlabs - 2);
  EXPECT_EQ(third.stats().interface_twist, 0);
  ExpectFreeCornerSolvedAsOnePiece(*fe.model());

  // Undo the refresh: stale again, and left so (Refresh is the user's call now).
  ASSERT_TRUE(window.tree().Undo());
  for (int k = 0; k < 5; ++k) window.Frame();
  EXPECT_TRUE(fe.stale());
  EXPECT_EQ(doc.history().redo_size(), 1u);
}

// A sculpt set up in FE mode (here the platform's grid surface, as a sculpt made from the solid
// holds it) is meshed in slabs (spaced by SurfaceSlabSpacing). With the model felt, a stroke near
// the free end, committed as sculpt mode commits it, refreshes the model by itself: only the last
// slab is re-meshed and refactored, and the new model solves as a one-piece factorisation does.
TEST(FeModeWindow, StrokeOnAFeltSculptRefreshesItselfInTheSlabItReached) {
  if (!HaveDisplay()) GTEST_SKIP() << "no X display: run under xvfb-run";
  const test_support::WindowScratch scratch("fe_window_sculpt_slabs");
  test_support::ScopedEnv cache("SPIDARCAD_CACHE_DIR", (scratch.dir / "cache").string().c_str());
  AppWindow window(test_support::ScriptedWindowOptions(AssetPath("scenes/platform.json")));
  SceneModel& model = window.model();
  const Document& doc = model.document();
  model.document().Execute(
      edit::AddSculpt("platform clay", test_support::PlatformGridSurface(0.012)));
  const ObjectId clay = doc.last_created().front();
  FeMode& fe = EnterFeMode(window);
  ASSERT_TRUE(fe.StartSetUp(&model, clay, false, true)) << fe.status();
  ASSERT_TRUE(FramesUntil(window, [&] { return fe.model() != nullptr; })) << fe.status();
  const ObjectId mesh_id = FeDataOf(doc, fe.bound_object()).tet_mesh;
  const std::shared_ptr<const SlabFeMesh> first = fe.SlabsOf(doc, mesh_id);
  ASSERT_NE(first, nullptr) << "set up in slabs";
  EXPECT_EQ(first->num_remeshed(), kFeSlabs);
  const std::shared_ptr<FeModel> before = fe.model();
  ASSERT_NE(before->substructured(), nullptr);
  EXPECT_EQ(before->substructured()->num_blocks(), kFeSlabs);

  // A push/pull stroke raising a 3 mm bump on the plate near the free end (the last slab).
  modeling::SculptMesh stroked(*std::get<SculptData>(doc.Get(clay).data).mesh);
  const modeling::SculptEdit edit =
      test_support::Stroke(&stroked, modeling::SculptTool::kPushPull,
                           Eigen::Vector3d(0.275, 0.0, 0.01), Eigen::Vector3d(0.0, 0.0, 0.003));
  std::unique_ptr<Command> stroke =
      MakeStrokeCommand(clay, "platform clay", modeling::SculptTool::kPushPull, edit, stroked);
  ASSERT_NE(stroke, nullptr);
  model.document().Execute(std::move(stroke));
  ASSERT_TRUE(FramesUntil(window, [&] { return fe.model() != nullptr && fe.model() != before; }))
      << fe.status();
  EXPECT_FALSE(fe.stale());
  const std::shared_ptr<const SlabFeMesh> second = fe.SlabsOf(doc, mesh_id);
  ASSERT_NE(second, nullptr);
  EXPECT_EQ(second->planes, first->planes);
  EXPECT_EQ(second->num_remeshed(), 1);
  EXPECT_TRUE(second->remeshed.back());
  const FeModel& after = *fe.model();
  ASSERT_NE(after.substructured(), nullptr);
  EXPECT_EQ(after.substructured()->stats().factored_blocks, 1) << fe.status();
  EXPECT_EQ(after.substructured()->stats().reused_blocks, kFeSlabs - 1);
  ExpectFreeCornerSolvedAsOnePiece(after);
}

// A sculpt object selected in the tree (as sculpt mode's Send to FE does) is chosen in FE mode and
// set up in one call: its closed mesh filled by TetGen, the mesh object made from it.
TEST(FeModeWindow, SelectedSculptIsChosenAndSetUpInOneStep) {
  if (!HaveDisplay()) GTEST_SKIP() << "no X display: run under xvfb-run";
  const test_support::WindowScratch scratch("fe_window_sculpt");
  test_support::ScopedEnv cache("SPIDARCAD_CACHE_DIR", (scratch.dir / "cache").string().c_str());
  AppWindow window(test_support::ScriptedWindowOptions(AssetPath("scenes/workbench.json")));
  SceneModel& model = window.model();
  const Document& doc = model.document();
  const ObjectId clay = doc.FindByName("clay")->id;
  window.tree().Select(clay);
  FeMode& fe = EnterFeMode(window);
  EXPECT_EQ(fe.chosen_object(), clay);
  EXPECT_EQ(fe.bound_object(), 0u) << "the clay has no FE model yet";
  ASSERT_TRUE(fe.StartSetUp(&model, fe.chosen_object())) << fe.status();
  ASSERT_TRUE(FramesUntil(window, [&] { return fe.bound_object() != 0; })) << fe.status();
  EXPECT_EQ(doc.history().UndoDescription(), "Set up FE for clay");
  const auto& fe_data = FeDataOf(doc, fe.bound_object());
  const auto& mesh = std::get<MeshData>(doc.Get(fe_data.tet_mesh).data);
  EXPECT_EQ(mesh.source, clay);
  EXPECT_FALSE(doc.IsMeshOutOfDate(fe_data.tet_mesh));
  ASSERT_TRUE(mesh.volume);
  // Meshed in slabs (FeMode::mesh_in_slabs, the default): the cut moved the clay's vertices
  // within a tenth of the spacing of a plane onto it, so the tets fill the clay's surface (its
  // divergence-theorem volume) to the little volume those moves sweep, and their own boundary
  // exactly. In one piece they fill it exactly
  // (FeSetUp.SculptAndClosedSurfaceMeshAreTetrahedralizedAsTheyAre).
  const std::shared_ptr<const SlabFeMesh> slabs = fe.SlabsOf(doc, fe_data.tet_mesh);
  ASSERT_NE(slabs, nullptr);
  EXPECT_EQ(slabs->num_remeshed(), kFeSlabs);
  const auto& sculpt = *std::get<SculptData>(doc.Get(clay).data).mesh;
  const double volume = modeling::MeshVolume(sculpt);
  double tets = 0.0;
  for (Eigen::Index t = 0; t < mesh.volume->tets.cols(); ++t)
    tets += std::abs(modeling::TetVolume(*mesh.volume, t));
  EXPECT_NEAR(tets, volume, 1e-3 * volume);
  EXPECT_NEAR(tets, modeling::MeshVolume(modeling::BoundarySurface(*mesh.volume)), 1e-9 * volume);
}

// A set-up whose source is edited while the Job meshes it lands nothing: the document keeps the
// edit and gets no mesh of the old shape.
TEST(FeModeWindow, SetUpWhoseSourceChangesMeanwhileIsDropped) {
  if (!HaveDisplay()) GTEST_SKIP() << "no X display: run under xvfb-run";
  const test_support::WindowScratch scratch("fe_window_dropped");
  AppWindow window(test_support::ScriptedWindowOptions(AssetPath("scenes/platform.json")));
  SceneModel& model = window.model();
  const Document& doc = model.document();
  FeMode& fe = EnterFeMode(window, 1);
  const std::size_t objects = doc.objects().size();
  fe.mesh_settings().cell_size = 0.012;
  ASSERT_TRUE(fe.StartSetUp(&model, doc.FindByName("platform")->id)) << fe.status();
  ASSERT_TRUE(window.tree().SelectByName("plate"));
  ASSERT_TRUE(window.tree().SetField("radius", 0.0045)) << window.tree().error();
  ASSERT_TRUE(FramesUntil(window, [&] {
    return fe.status().find("changed while it was meshed") != std::string::npos;
  })) << fe.status();
  EXPECT_EQ(doc.objects().size(), objects);
  EXPECT_EQ(doc.history().undo_size(), 1u) << "the radius edit only";
  EXPECT_EQ(fe.bound_object(), 0u);
}

// A solid whose surface mesh would be past `spidarcad mesh`'s budget is not meshed until the
// question is answered; Cancel leaves the document as it was. The estimate (its box search)
// runs in a Job, not on the window's thread: the question is there only once the Job has landed.
TEST(FeModeWindow, LargeMeshAsksFirstAndCancelChangesNothing) {
  if (!HaveDisplay()) GTEST_SKIP() << "no X display: run under xvfb-run";
  const test_support::WindowScratch scratch("fe_window_budget");
  AppWindow window(test_support::ScriptedWindowOptions(AssetPath("scenes/platform.json")));
  SceneModel& model = window.model();
  FeMode& fe = EnterFeMode(window, 1);
  const std::string before = model.document().ToJson().dump();
  fe.mesh_settings().cell_size = 1e-4;  // the platform's box over 0.1 mm cells: far past 2^27
  ASSERT_TRUE(fe.StartSetUp(&model, model.document().FindByName("platform")->id)) << fe.status();
  EXPECT_TRUE(fe.pending_setup().empty()) << "estimated on the window's thread";
  bool estimating = false;
  for (const auto& job : window.jobs().jobs())
    estimating = estimating || job->title() == "Estimate the mesh of platform";
  EXPECT_TRUE(estimating);
  ASSERT_TRUE(FramesUntil(window, [&] { return !fe.pending_setup().empty(); })) << fe.status();
  EXPECT_NE(fe.pending_setup().find("grid cells"), std::string::npos) << fe.pending_setup();
  for (int k = 0; k < 3; ++k) window.Frame();  // the question is drawn
  EXPECT_EQ(model.document().ToJson().dump(), before) << "nothing is meshed while it asks";
  fe.ConfirmSetUp(&model, false);
  EXPECT_TRUE(fe.pending_setup().empty());
  for (int k = 0; k < 3; ++k) window.Frame();
  EXPECT_EQ(model.document().ToJson().dump(), before);
  EXPECT_EQ(model.document().history().undo_size(), 0u);
  EXPECT_EQ(fe.bound_object(), 0u);
  // The estimate cancelled while it runs: no question, nothing meshed, the status says so.
  ASSERT_TRUE(fe.StartSetUp(&model, model.document().FindByName("platform")->id)) << fe.status();
  for (const auto& job : window.jobs().jobs())
    if (job->title() == "Estimate the mesh of platform") job->Cancel();
  ASSERT_TRUE(FramesUntil(window, [&] { return !window.jobs().pending(); })) << fe.status();
  for (int k = 0; k < 3; ++k) window.Frame();
  if (fe.pending_setup().empty()) {  // (it may have landed before the cancel)
    EXPECT_NE(fe.status().find("nothing changed"), std::string::npos) << fe.status();
    EXPECT_NE(window.workbench().status.find("Estimate the mesh of platform: cancelled"),
              std::string::npos)
        << window.workbench().status;
  } else {
    fe.ConfirmSetUp(&model, false);
  }
  EXPECT_EQ(model.document().ToJson().dump(), before);
  EXPECT_EQ(fe.bound_object(), 0u);
}

// FE mode's "grasp grabs" in the window, with the scripted grip: the grip comes down onto the
// free end of the platform's FE model (assets/scenes/platform_fe.json), closes (grab), twists by
// 0.3 rad about +x and sees the FE moment and the felt moment resist the twist; opening lets go.
TEST(FeModeWindow, GraspGrabsTheFreeEndAndTheTwistIsResisted) {
  if (!HaveDisplay()) GTEST_SKIP() << "no X display: run under xvfb-run";
  const test_support::WindowScratch scratch("fe_window_grab");
  test_support::ScopedEnv cache("SPIDARCAD_CACHE_DIR", (scratch.dir / "cache").string().c_str());
  AppWindow window(test_support::ScriptedWindowOptions(kNoSceneName));
  window.Frame();
  ASSERT_TRUE(window.OpenDocument(AssetPath("scenes/platform_fe.json"))) << window.file_error();
  auto* fe_mode = dynamic_cast<FeWindowMode*>(window.FindMode("fe"));
  ASSERT_NE(fe_mode, nullptr);
  FeMode& fe = fe_mode->fe();
  fe.grab() = true;
  window.SwitchMode(fe_mode);
  for (int k = 0; k < 3; ++k) window.Frame();
  if (fe.model() == nullptr) fe.RequestModel();
  ASSERT_TRUE(FramesUntil(window, [&] { return fe.model() != nullptr; })) << fe.status();
  const DeviceToWorld& x = window.model().device_to_world();
  const auto to_D = [&](const Eigen::Vector3d& p_W) -> Eigen::Vector3d {
    return (p_W - x.p_WDo) / x.world_scale;
  };
  // Onto the plate top near the free end (pushed: the grip rests on it), then close the grasp.
  const Eigen::Vector3d on_top_D = to_D(Eigen::Vector3d(0.28, 0.0, 0.012));
  const double open = M_PI / 2, closed = 57.0 * M_PI / 180.0;
  window.grip().SetPose(on_top_D, Eigen::Matrix3d::Identity(), open);
  FramesUntil(
      window,
      [&] {
        const Eigen::Vector3d d = window.runtime().Latest().tool.pose_D.p0 - on_top_D;
        return d.head<2>().norm() < 5e-4 && fe.figures().contacts > 0;
      },
      60.0);
  window.grip().SetPose(on_top_D, Eigen::Matrix3d::Identity(), closed);
  ASSERT_TRUE(FramesUntil(
      window, [&] { return fe.figures().grabbed > 0; }, 120.0))
      << "not grabbed: " << fe.status();
  // Twist about +x: the part resists (FE moment and felt moment about x negative).
  const Eigen::Matrix3d twist = Eigen::AngleAxisd(0.3, Eigen::Vector3d::UnitX()).toRotationMatrix();
  window.grip().SetPose(on_top_D, twist, closed);
  FramesUntil(
      window,
      [&] {
        return fe.figures().m_tool_W.x() < 0.0 &&
               window.runtime().Latest().tool.wrench_D(3) < -0.05;
      },
      60.0);
  EXPECT_GT(fe.figures().grabbed, 0);
  EXPECT_LT(fe.figures().m_tool_W.x(), 0.0) << fe.figures().m_tool_W.transpose();
  EXPECT_LT(window.runtime().Latest().tool.wrench_D(3), -0.01)
      << window.runtime().Latest().tool.wrench_D.transpose();
  EXPECT_GT(fe.figures().max_displacement, 0.0);
  // Open: let go.
  window.grip().SetPose(on_top_D, twist, open);
  EXPECT_TRUE(FramesUntil(
      window, [&] { return fe.figures().grabbed == 0; }, 60.0));
}

}  // namespace
}  // namespace spidarcad::app
