// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
// FeTouchField's tool patch (scene/fe_touch_field.h, FeTouchSettings::patch_contact): the patch a
// tool of physical radius R covers is pushed rigidly by its depth, its forces equal a full sparse
// solve, a patch over kMaxFeContacts degrades to the nearest nodes and says so, and no tick
// allocates. The node-to-sphere model's tests are in fe_mode_test.cc; the patch's felt stiffness
// against `felt`'s converged value is in felt_stiffness_test.cc.
#include "scene/fe_touch_field.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <memory>
#include <vector>

#include "scene/fe_model.h"
#include "scene/fe_part.h"
#include "scene/felt_stiffness.h"
#include "spidarcad/fem/static_solver.h"
#include "spidarcad/fem/stiffness.h"
#include "support/malloc_counter.h"

namespace spidarcad::app {
namespace {

// The steel platform, linear tetrahedra of 12 mm cells, clamped at its wall face; columns are
// computed on demand (no worker), built once for the file.
std::shared_ptr<FeModel> Platform() {
  static const std::shared_ptr<FeModel> model = [] {
    FeModelSettings ms;
    ms.use_disk_cache = false;
    ms.cache.start_worker = false;
    return std::shared_ptr<FeModel>(
        FeModel::Build(MeshSceneSolidForFe(PlatformScenePath(), "platform", 0.012), ms));
  }();
  return model;
}

// The tool patch of radius r, no coupling (the ball on the tool), no force bound.
FeTouchSettings PatchSettings(double r, bool frictionless) {
  FeTouchSettings ts;
  ts.patch_contact = true;
  ts.tool_radius = r;
  ts.frictionless = frictionless;
  ts.force_scale = 1.0;
  ts.max_force = 1e12;
  return ts;
}

haptics::ToolKinematics ToolAt(const Eigen::Vector3d& p) {
  haptics::ToolKinematics t;
  t.p_WT = p;
  return t;
}

// Makes the columns of the free surface nodes within `reach` of p ready.
void ColumnsNear(FeModel* model, const Eigen::Vector3d& p, double reach) {
  model->cache().ComputeNodes(CandidatesNearPath(*model, {p}, reach));
}

// Reactions of a full sparse solve with the state's contact nodes prescribed to their targets.
Eigen::VectorXd FullReactions(const FeModel& model, const FeContactState& st) {
  fem::BoundaryConditions bcs = model.bcs();
  for (int s = 0; s < st.num_contacts; ++s)
    bcs.PrescribeNode(
        model.cache().candidate_node(st.candidate[s]),
        Eigen::Vector3d(st.target[3 * s], st.target[3 * s + 1], st.target[3 * s + 2]));
  const fem::StaticSolver solver(model.mesh(), model.materials(), bcs);
  EXPECT_TRUE(solver.factor_status().converged);
  const fem::StaticSolution full = solver.Solve();
  EXPECT_TRUE(full.status.converged);
  return full.reaction;
}

// The contact set as ascending mesh nodes.
std::vector<int> ContactNodes(const FeModel& model, const FeContactState& st) {
  std::vector<int> nodes;
  for (int s = 0; s < st.num_contacts; ++s)
    nodes.push_back(model.cache().candidate_node(st.candidate[s]));
  std::sort(nodes.begin(), nodes.end());
  return nodes;
}

// Pressed 1.5 mm into the plate top (z = 0.01 m) at two spots, sticking and frictionless: the
// contact set is the tool's patch at the touch point (ToolPatchNodes), every node is moved by the
// same depth along −n (sticking: by exactly −δ n on top of the loads' displacement), the forces on
// the body equal a full sparse solve's reactions to 1e-9, the force on the tool is their negated
// sum, and, sticking, its component along n is the patch stiffness (ReferencePatchStiffness, a
// SolveGrab) times the depth.
TEST(FeTouchFieldPatch, PushedPatchForcesEqualAFullSparseSolve) {
  const std::shared_ptr<FeModel> model = Platform();
  const double r = 0.01;
  for (bool frictionless : {false, true}) {
    for (const Eigen::Vector2d& spot :
         {Eigen::Vector2d(0.25, 0.02), Eigen::Vector2d(0.12, -0.03)}) {
      SCOPED_TRACE(std::string(frictionless ? "frictionless" : "sticking") +
                   " at x = " + std::to_string(spot.x()));
      const Eigen::Vector3d tool(spot.x(), spot.y(), 0.010 + r - 0.0015);
      ColumnsNear(model.get(), tool, 2.0 * r);
      FeTouchField field(model, PatchSettings(r, frictionless), nullptr);
      field.Evaluate(ToolAt(tool));
      const FeContactState& st = field.last_state();
      ASSERT_GT(st.num_contacts, 1);
      EXPECT_EQ(st.num_substituted, 0);
      EXPECT_EQ(st.refused, 0);
      EXPECT_NEAR(st.normal.z(), 1.0, 1e-6);  // the flat top
      EXPECT_NEAR(st.depth, 0.0015, 1e-9);
      const Eigen::Vector3d touch = st.p_WC - (r - st.depth) * st.normal;
      EXPECT_EQ(ContactNodes(*model, st), ToolPatchNodes(*model, touch, r, -st.normal));

      const Eigen::VectorXd reaction = FullReactions(*model, st);
      double fmax = 0.0;
      Eigen::Vector3d sum = Eigen::Vector3d::Zero();
      for (int s = 0; s < st.num_contacts; ++s) {
        const Eigen::Vector3d f(st.force[3 * s], st.force[3 * s + 1], st.force[3 * s + 2]);
        fmax = std::max(fmax, f.norm());
        sum += f;
      }
      for (int s = 0; s < st.num_contacts; ++s) {
        const int b = st.candidate[s];
        const int v = model->cache().candidate_node(b);
        const Eigen::Vector3d f(st.force[3 * s], st.force[3 * s + 1], st.force[3 * s + 2]);
        EXPECT_LT((f - reaction.segment<3>(3 * v)).norm(), 1e-9 * fmax) << "slot " << s;
        const Eigen::Vector3d u(st.target[3 * s], st.target[3 * s + 1], st.target[3 * s + 2]);
        const Eigen::Vector3d u0 =
            model->cache().baseline().segment<3>(3 * model->cache().OutputIndexOfCandidate(b));
        if (frictionless) {
          EXPECT_NEAR(st.normal.dot(u - u0), -st.depth, 1e-12) << "slot " << s;
          EXPECT_LT((f - st.normal * st.normal.dot(f)).norm(), 1e-9 * fmax) << "slot " << s;
        } else {
          EXPECT_LT((u - u0 + st.depth * st.normal).norm(), 1e-15) << "slot " << s;
        }
      }
      EXPECT_LT((st.f_tool_W + sum).norm(), 1e-12 * sum.norm());
      EXPECT_GT(st.f_tool_W.z(), 0.0);
      if (!frictionless) {
        const double k = ReferencePatchStiffness(*model, ContactNodes(*model, st), -st.normal);
        EXPECT_NEAR(st.f_tool_W.dot(st.normal), k * st.depth, 1e-9 * k * st.depth);
      }
    }
  }
}

// Out of contact (the ball above the plane fitted to the surface) nothing is felt, and a coupled
// tool coming down onto the plate in one long step is stopped where the ball meets the surface's
// plane: contact begins at a depth of at most 1e-3 R, wherever the nodes lie under it.
TEST(FeTouchFieldPatch, ZeroForceAboveAndCoupledContactBeginsAtAVanishingDepth) {
  const std::shared_ptr<FeModel> model = Platform();
  FeTouchSettings ts = ResolvedFieldSettings(*model, DefaultFeTouchSettings(), 1.0);
  const double r = ts.tool_radius;
  for (double x : {0.20, 0.2037, 0.2071}) {
    SCOPED_TRACE("x = " + std::to_string(x));
    const Eigen::Vector3d above(x, 0.013, 0.010 + r + 0.004);
    ColumnsNear(model.get(), above, 2.0 * r);
    FeTouchField field(model, ts, nullptr);
    haptics::ToolWrench w = field.Evaluate(ToolAt(above));
    EXPECT_EQ(field.last_state().num_contacts, 0);
    EXPECT_EQ(w.f_T_W.norm(), 0.0);
    const Eigen::Vector3d below = above - Eigen::Vector3d(0, 0, 0.006);  // 2 mm past the top
    field.Evaluate(ToolAt(below));                                       // moves the coupled point
    w = field.Evaluate(ToolAt(below));
    const FeContactState& st = field.last_state();
    ASSERT_GT(st.num_contacts, 0);
    EXPECT_GT(st.depth, 0.0);
    EXPECT_LE(st.depth, 1.001e-3 * r);
    // Then it settles with the tool pushed back up, never more than the coupling's spring.
    for (int tick = 0; tick < 200; ++tick) w = field.Evaluate(ToolAt(below));
    EXPECT_GT(w.f_T_W.z(), 0.0);
    EXPECT_LE(w.f_T_W.z(), ts.coupling_stiffness * 0.002 * (1.0 + 1e-9));
  }
}

// A tool whose patch holds more nodes than kMaxFeContacts keeps the nearest kMaxFeContacts to its
// touch point (a smaller punch, still pushed rigidly and still exact), counts the rest in
// `refused` (FE mode's panel and `run` say so), and feels a force no larger than the whole patch
// would give.
TEST(FeTouchFieldPatch, APatchOverTheContactLimitKeepsTheNearestNodesAndSaysSo) {
  const std::shared_ptr<FeModel> model = Platform();
  const double r = 0.07;
  const Eigen::Vector3d tool(0.2, 0.0, 0.010 + r - 0.001);
  ColumnsNear(model.get(), tool, 2.0 * r);
  FeTouchField field(model, PatchSettings(r, false), nullptr);
  field.Evaluate(ToolAt(tool));
  const FeContactState& st = field.last_state();
  const Eigen::Vector3d touch = st.p_WC - (r - st.depth) * st.normal;
  const std::vector<int> whole = ToolPatchNodes(*model, touch, r, -st.normal);
  std::printf(
      "patch of radius %.3f m: %d contacts, %d refused, depth %.6f m, normal %.3f %.3f %.3f\n", r,
      st.num_contacts, st.refused, st.depth, st.normal.x(), st.normal.y(), st.normal.z());
  ASSERT_GT(static_cast<int>(whole.size()), kMaxFeContacts);
  EXPECT_EQ(st.num_contacts, kMaxFeContacts);
  EXPECT_EQ(st.refused, static_cast<int>(whole.size()) - kMaxFeContacts);
  // The kept nodes are the nearest to the touch point.
  double farthest_kept = 0.0, nearest_left = 1e9;
  const std::vector<int> kept = ContactNodes(*model, st);
  for (int v : whole) {
    const double d = (model->mesh().nodes.row(v).transpose() - touch).norm();
    if (std::binary_search(kept.begin(), kept.end(), v))
      farthest_kept = std::max(farthest_kept, d);
    else
      nearest_left = std::min(nearest_left, d);
  }
  EXPECT_LE(farthest_kept, nearest_left);
  const double k_kept = ReferencePatchStiffness(*model, kept, -st.normal);
  const double k_whole = ReferencePatchStiffness(*model, whole, -st.normal);
  EXPECT_NEAR(st.f_tool_W.dot(st.normal), k_kept * st.depth, 1e-9 * k_kept * st.depth);
  EXPECT_LE(k_kept, k_whole);
  EXPECT_TRUE(st.f_tool_W.allFinite());
}

// No tick of the tool patch allocates: pushing (coupled, as FE mode), pushing without coupling,
// and squeezing between the pole tips, sliding across the plate in and out of contact.
TEST(FeTouchFieldPatch, EvaluateAllocatesNothing) {
  ASSERT_TRUE(test_support::MallocCounterActive());
  const std::shared_ptr<FeModel> model = Platform();
  const FeTouchSettings coupled_settings =
      ResolvedFieldSettings(*model, DefaultFeTouchSettings(), 1.0);
  const double r = coupled_settings.tool_radius;
  std::vector<Eigen::Vector3d> path;
  for (int i = 0; i < 400; ++i) {
    const double s = i / 400.0;
    path.emplace_back(0.1 + 0.18 * s, -0.05 + 0.1 * s, 0.010 + r * (0.8 + 0.5 * std::sin(20 * s)));
  }
  model->cache().ComputeNodes(CandidatesNearPath(*model, path, 2.0 * r + 0.03));
  FeTouchField coupled(model, coupled_settings, nullptr);
  FeTouchField bare(model, PatchSettings(r, false), nullptr);
  FeTouchSettings gs = PatchSettings(0.004, true);
  gs.grasp = true;
  gs.pole_length = 0.03;
  FeTouchField grasp(model, gs, nullptr);
  int max_k = 0, max_k_coupled = 0;
  long allocations = 0;
  {
    test_support::MallocCounter counter;
    for (const Eigen::Vector3d& p : path) {
      bare.Evaluate(ToolAt(p));
      max_k = std::max(max_k, bare.last_state().num_contacts);
      coupled.Evaluate(ToolAt(p));
      max_k_coupled = std::max(max_k_coupled, coupled.last_state().num_contacts);
      grasp.Evaluate(ToolAt(p));
    }
    allocations = counter.count();
  }
  EXPECT_EQ(allocations, 0);
  EXPECT_GT(max_k, 1);
  EXPECT_GT(max_k_coupled, 1);  // the coupled path's patch solve and stiffness probe ran
}

}  // namespace
}  // namespace spidarcad::app
