// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
// FeGrabField: grabbing the platform's free end with the grip, checked against fem::SolveGrab (a
// full sparse solve with the patch prescribed), plus the grip's hysteresis, the worker's
// hand-over and its ramp, and that Evaluate allocates nothing.
#include "scene/fe_grab_field.h"

#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <chrono>
#include <cmath>
#include <memory>
#include <string>
#include <thread>
#include <vector>

#include "doc/job.h"
#include "gui/fe_mode.h"
#include "scene/fe_model.h"
#include "scene/fe_part.h"
#include "spidarcad/fem/grab.h"
#include "support/malloc_counter.h"

namespace spidarcad::app {
namespace {

constexpr double kCoarse = 0.012;  // m: platform grid cell
constexpr double kOpen = 1.5707963267948966;
constexpr double kClosed = 1.0;  // rad, below the default close angle (70°)

const fem::TetMesh& PlatformMesh() {
  static const fem::TetMesh mesh = MeshSceneSolidForFe(PlatformScenePath(), "platform", kCoarse);
  return mesh;
}

// The coarse platform, clamped at the wall, columns prepared around its free end (x = 0.3).
std::shared_ptr<FeModel> PlatformModel() {
  static std::shared_ptr<FeModel> model = [] {
    FeModelSettings s;
    s.use_disk_cache = false;
    s.cache.start_worker = false;
    auto m = FeModel::Build(PlatformMesh(), s);
    PrepareColumns(m.get(), CandidatesNearPath(*m, {Eigen::Vector3d(0.29, 0.0, 0.005)}, 0.05),
                   false);
    return m;
  }();
  return model;
}

const Eigen::Vector3d kGrabPoint(0.29, 0.0, 0.005);

haptics::ToolKinematics Tool(double time, const Eigen::Vector3d& p, const Eigen::Matrix3d& R,
                             double grasp) {
  haptics::ToolKinematics t;
  t.time = time;
  t.p_WT = p;
  t.R_WT = R;
  t.grasp = grasp;
  return t;
}

FeGrabSettings SyncSettings() {
  FeGrabSettings s;
  s.tool_radius = 0.02;
  s.worker = false;
  s.ramp_seconds = 0.0;
  return s;
}

// The grip motion of the tests: 1 mm along x, 0.5 mm along y, 2 mm up and 0.02 rad about an
// axis mostly along x (a twist of the plate's free end).
Eigen::Matrix3d Twist(double angle) {
  return Eigen::AngleAxisd(angle, Eigen::Vector3d(1.0, 0.2, -0.1).normalized()).toRotationMatrix();
}
const Eigen::Vector3d kMove(0.001, 0.0005, 0.002);

TEST(FeGrabField, HeldWrenchEqualsTheFullSparseGrabSolve) {
  const auto model = PlatformModel();
  FeGrabField field(model, SyncSettings(), nullptr);
  const Eigen::Matrix3d R0 = Eigen::AngleAxisd(0.3, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  haptics::ToolWrench w = field.Evaluate(Tool(0.0, kGrabPoint, R0, kOpen));
  EXPECT_EQ(w.f_T_W.norm(), 0.0);
  EXPECT_FALSE(field.last_state().held);
  w = field.Evaluate(Tool(0.001, kGrabPoint, R0, kClosed));
  ASSERT_TRUE(field.last_state().ready);
  EXPECT_LT(w.f_T_W.norm(), 1e-6);  // grabbed where it is: no force yet
  const int n = field.last_state().num_nodes;
  EXPECT_GT(n, 4);
  EXPECT_LE(n, kMaxFeGrabNodes);
  EXPECT_EQ(field.last_state().num_substituted, 0);

  const Eigen::Matrix3d R = Twist(0.02) * R0;
  w = field.Evaluate(Tool(0.002, kGrabPoint + kMove, R, kClosed));
  const FeGrabState& st = field.last_state();
  ASSERT_TRUE(st.ready);

  // Reference: the same patch moved by (t, r) about its centroid, solved in full.
  std::vector<int> nodes;
  for (int i = 0; i < n; ++i) nodes.push_back(model->cache().candidate_node(st.candidate[i]));
  const fem::GrabPatch patch(model->mesh().nodes, nodes);
  EXPECT_LT((patch.centroid() - st.centroid).norm(), 1e-12);
  // The grip's rigid motion about p_0 is the patch's about c: the same node displacements.
  std::vector<double> u(3 * n);
  patch.Displacements(st.t, st.r, u.data());
  for (int i = 0; i < 3 * n; ++i) EXPECT_NEAR(u[i], st.target[i], 1e-15) << i;
  const fem::GrabSolution ref =
      fem::SolveGrab(model->mesh(), model->materials(), model->bcs(), patch, st.t, st.r);
  ASSERT_TRUE(ref.status.converged) << ref.status.message;
  const double fscale = ref.wrench.force.norm(), mscale = ref.wrench.moment.norm();
  ASSERT_GT(fscale, 1.0);
  ASSERT_GT(mscale, 1e-3);
  EXPECT_LT((st.force_body - ref.wrench.force).norm(), 1e-9 * fscale)
      << st.force_body.transpose() << " vs " << ref.wrench.force.transpose();
  EXPECT_LT((st.moment_body - ref.wrench.moment).norm(), 1e-9 * mscale)
      << st.moment_body.transpose() << " vs " << ref.wrench.moment.transpose();
  double fmax = 0.0, ferr = 0.0;
  for (int i = 0; i < n; ++i) {
    const Eigen::Vector3d f_ref = ref.reaction.segment<3>(3 * nodes[i]);
    const Eigen::Vector3d f(st.force[3 * i], st.force[3 * i + 1], st.force[3 * i + 2]);
    fmax = std::max(fmax, f_ref.norm());
    ferr = std::max(ferr, (f - f_ref).norm());
  }
  EXPECT_LT(ferr, 1e-9 * fmax);

  // The tool feels the reaction: −F, and the moment about p_WT of −f at the held positions.
  EXPECT_LT((st.f_tool_W + ref.wrench.force).norm(), 1e-9 * fscale);
  const Eigen::Vector3d p = kGrabPoint + kMove;
  // −Σ (x_v + u_v − p) × f_v = −M − (c − p) × F − Σ u_v × f_v.
  Eigen::Vector3d m_tool = -ref.wrench.moment - (patch.centroid() - p).cross(ref.wrench.force);
  for (int i = 0; i < n; ++i)
    m_tool -= Eigen::Vector3d(u[3 * i], u[3 * i + 1], u[3 * i + 2])
                  .cross(ref.reaction.segment<3>(3 * nodes[i]));
  EXPECT_LT((st.m_tool_W - m_tool).norm(), 1e-9 * mscale);
  // Unit force scale, clamps far away: felt = FE reaction (clamped magnitudes only).
  EXPECT_LT((w.f_T_W - SyncSettings().max_force * st.f_tool_W.normalized()).norm(), 1e-9);

  // The held state solved in full (run --export): the same displacement field as SolveGrab.
  const FeSolvedState solved = SolveFeGrabState(*model, st);
  EXPECT_LT((solved.displacement - ref.displacement).norm(), 1e-9 * ref.displacement.norm());

  // Opening the grip lets go.
  w = field.Evaluate(Tool(0.003, p, R, kOpen));
  EXPECT_EQ(w.f_T_W.norm(), 0.0);
  EXPECT_EQ(w.m_T_W.norm(), 0.0);
  EXPECT_FALSE(field.last_state().held);
}

TEST(FeGrabField, TwistIsResistedAndTheGripHysteresisHolds) {
  const auto model = PlatformModel();
  FeGrabSettings s = SyncSettings();
  s.force_scale = 1e-4;
  s.max_torque = 100.0;
  s.max_force = 100.0;
  FeGrabField field(model, s, nullptr);
  const Eigen::Matrix3d I = Eigen::Matrix3d::Identity();
  field.Evaluate(Tool(0.0, kGrabPoint, I, kOpen));
  field.Evaluate(Tool(0.001, kGrabPoint, I, kClosed));
  // Twist about the plate's long axis (+x): the felt moment opposes it.
  const Eigen::Matrix3d R = Eigen::AngleAxisd(0.01, Eigen::Vector3d::UnitX()).toRotationMatrix();
  haptics::ToolWrench w = field.Evaluate(Tool(0.002, kGrabPoint, R, kClosed));
  EXPECT_LT(w.m_T_W.x(), 0.0);
  EXPECT_GT(std::abs(w.m_T_W.x()), 0.9 * w.m_T_W.norm());
  // Pull up: the felt force points down.
  w = field.Evaluate(Tool(0.003, kGrabPoint + Eigen::Vector3d(0, 0, 0.001), I, kClosed));
  EXPECT_LT(w.f_T_W.z(), 0.0);
  EXPECT_GT(std::abs(w.f_T_W.z()), 0.7 * w.f_T_W.norm());
  // Between the close and open angles the grip stays closed (75°).
  w = field.Evaluate(Tool(0.004, kGrabPoint + Eigen::Vector3d(0, 0, 0.001), I, 75.0 * M_PI / 180));
  EXPECT_TRUE(field.last_state().held);
  EXPECT_LT(w.f_T_W.z(), 0.0);
  // Open (85°): let go; closing again away from the part grabs nothing.
  w = field.Evaluate(Tool(0.005, kGrabPoint, I, 85.0 * M_PI / 180));
  EXPECT_FALSE(field.last_state().held);
  w = field.Evaluate(Tool(0.006, Eigen::Vector3d(0.29, 0.0, 0.1), I, kClosed));
  EXPECT_FALSE(field.last_state().held);
  EXPECT_EQ(w.f_T_W.norm(), 0.0);
  // ... and moving onto the part while closed does not grab either: the grip must close there.
  w = field.Evaluate(Tool(0.007, kGrabPoint, I, kClosed));
  EXPECT_FALSE(field.last_state().held);
}

TEST(FeGrabField, CouplingHoldsThePatchAtTheSeriesEquilibrium) {
  const auto model = PlatformModel();
  FeGrabSettings s = SyncSettings();
  s.force_scale = 1e-4;
  s.coupling_stiffness = 1500.0;
  s.coupling_rot_stiffness = 2.0;
  s.max_force = 1e6;
  s.max_torque = 1e6;
  FeGrabField field(model, s, nullptr);
  const Eigen::Matrix3d I = Eigen::Matrix3d::Identity();
  field.Evaluate(Tool(0.0, kGrabPoint, I, kOpen));
  field.Evaluate(Tool(0.001, kGrabPoint, I, kClosed));
  // A pure pull first (the coupled motion still turns a little: K₆ couples them), then a twist.
  haptics::ToolWrench w = field.Evaluate(Tool(0.002, kGrabPoint + kMove, I, kClosed));
  const FeGrabState& st = field.last_state();
  ASSERT_TRUE(st.ready);
  // Never stiffer than the coupling: |felt| <= k_c |t_grip|.
  EXPECT_LE(w.f_T_W.norm(), 1500.0 * st.t_grip.norm());
  EXPECT_GT(w.f_T_W.norm(), 0.1 * 1500.0 * st.t_grip.norm());
  // Equilibrium of the springs with the FE reaction at the coupled motion, exact for the
  // linearised kinematics u = t + r × (x − c): σ F = −k_c (t_grip − t), σ M = −k_r (r_grip − r).
  // The field moves the patch by R(r) (Rodrigues): the second order of the coupled rotation
  // (½|r|²|x − c| ~ 4e-7 m at |r| ~ 0.009 rad) against the patch's ~1e9 N/m, felt at 1e-4, is
  // what separates them (a few hundredths of a newton of 2 N).
  const auto check = [&](double tol) {
    const Eigen::Vector3d f_spring = -1500.0 * (st.t_grip - st.t);
    const Eigen::Vector3d m_spring = -2.0 * (st.r_grip - st.r);
    EXPECT_LT((1e-4 * st.f_tool_W - f_spring).norm(), tol * f_spring.norm())
        << (1e-4 * st.f_tool_W).transpose() << " vs " << f_spring.transpose();
    EXPECT_LT((-1e-4 * st.moment_body - m_spring).norm(), tol * m_spring.norm())
        << (-1e-4 * st.moment_body).transpose() << " vs " << m_spring.transpose();
  };
  check(0.03);
  // Twisted by 0.05 rad.
  w = field.Evaluate(Tool(0.003, kGrabPoint + kMove, Twist(0.05), kClosed));
  EXPECT_LE(w.f_T_W.norm(), 1500.0 * st.t_grip.norm());
  EXPECT_LE(w.m_T_W.norm(), 2.0 * st.r_grip.norm() + 1500.0 * st.t_grip.norm() * 0.03);
  check(0.03);
  // The FE state is the grab of (t, r): fem::SolveGrab agrees.
  std::vector<int> nodes;
  for (int i = 0; i < st.num_nodes; ++i)
    nodes.push_back(model->cache().candidate_node(st.candidate[i]));
  const fem::GrabPatch patch(model->mesh().nodes, nodes);
  const fem::GrabSolution ref =
      fem::SolveGrab(model->mesh(), model->materials(), model->bcs(), patch, st.t, st.r);
  EXPECT_LT((st.force_body - ref.wrench.force).norm(), 1e-9 * ref.wrench.force.norm());
  EXPECT_LT((st.moment_body - ref.wrench.moment).norm(), 1e-9 * ref.wrench.moment.norm());
}

TEST(FeGrabField, WorkerFactorsOffTheTickAndTheForceRampsIn) {
  const auto model = PlatformModel();
  FeGrabSettings s = SyncSettings();
  s.max_force = 1e12;  // no clamping: the ramp alone
  s.max_torque = 1e12;
  FeGrabField sync(model, s, nullptr);
  s.worker = true;
  s.ramp_seconds = 0.005;
  auto channel = std::make_shared<FeGrabChannel>();
  FeGrabField field(model, s, channel);
  const Eigen::Matrix3d I = Eigen::Matrix3d::Identity();
  const Eigen::Vector3d p = kGrabPoint + kMove;
  sync.Evaluate(Tool(0.0, kGrabPoint, I, kOpen));
  sync.Evaluate(Tool(0.001, kGrabPoint, I, kClosed));
  const haptics::ToolWrench full = sync.Evaluate(Tool(0.002, p, Twist(0.01), kClosed));
  ASSERT_GT(full.f_T_W.norm(), 1.0);

  field.Evaluate(Tool(0.0, kGrabPoint, I, kOpen));
  haptics::ToolWrench w = field.Evaluate(Tool(0.001, kGrabPoint, I, kClosed));
  EXPECT_TRUE(field.last_state().held);
  // Hold the twisted pose until the worker has handed the patch over (zero force meanwhile).
  double t = 0.002;
  int waited = 0;
  for (; waited < 20000; ++waited, t += 0.001) {
    w = field.Evaluate(Tool(t, p, Twist(0.01), kClosed));
    if (field.last_state().ready) break;
    EXPECT_EQ(w.f_T_W.norm(), 0.0);
    std::this_thread::sleep_for(std::chrono::microseconds(200));
  }
  ASSERT_TRUE(field.last_state().ready);
  // Ramp: 0 on the hand-over tick, then linear steps of a fifth up to the full wrench.
  for (int k = 0; k <= 6; ++k) {
    const double ramp = std::min(1.0, k / 5.0);
    EXPECT_NEAR(field.last_state().ramp, ramp, 1e-9) << k;
    EXPECT_LT((w.f_T_W - ramp * full.f_T_W).norm(), 1e-9 * full.f_T_W.norm()) << k;
    EXPECT_LT((w.m_T_W - ramp * full.m_T_W).norm(), 1e-9 * full.m_T_W.norm()) << k;
    t += 0.001;
    w = field.Evaluate(Tool(t, p, Twist(0.01), kClosed));
  }
  // The channel carries the state; the drawn displacement moves the patch to its targets.
  const FeGrabState drawn = channel->buffer.Latest();
  EXPECT_TRUE(drawn.ready);
  Eigen::VectorXd u;
  EXPECT_EQ(GrabDisplacement(&model->cache(), drawn, &u), 0);
  const fem::ColumnCache& cache = model->cache();
  for (int i = 0; i < drawn.num_nodes; ++i) {
    const int row = 3 * cache.OutputIndexOfCandidate(drawn.candidate[i]);
    for (int j = 0; j < 3; ++j) EXPECT_NEAR(u(row + j), drawn.target[3 * i + j], 1e-12);
  }
}

TEST(FeGrabField, EvaluateAllocatesNothing) {
  ASSERT_TRUE(test_support::MallocCounterActive());
  const auto model = PlatformModel();
  FeGrabSettings s = SyncSettings();
  auto channel = std::make_shared<FeGrabChannel>();
  FeGrabField sync(model, s, channel);
  s.grasp = true;
  s.tool_radius = 0.012;
  FeGrabField poles(model, s, channel);
  s.grasp = false;
  s.worker = true;
  s.tool_radius = 0.02;
  FeGrabField worker(model, s, channel);
  int max_n = 0;
  bool worker_ready = false;
  long allocations = 0;
  {
    // The ticks run on this thread; the third field's patch worker allocates on its own thread,
    // as it may, and under AddressSanitizer, whose hook sees every thread, allocations were
    // counted here (docs/sanitizers.md): only this thread's allocations count.
    test_support::MallocCounter counter(test_support::MallocCounter::Threads::kThisThread);
    for (int i = 0; i < 600; ++i) {  // grab, twist and pull, let go, three times over
      const double phase = (i % 200) / 200.0;
      const double grasp = phase < 0.1 || phase > 0.8 ? kOpen : kClosed;
      const Eigen::Vector3d p = kGrabPoint + phase * kMove;
      const Eigen::Matrix3d R = Twist(0.05 * phase);
      const haptics::ToolKinematics tool = Tool(0.001 * i, p, R, grasp);
      sync.Evaluate(tool);
      max_n = std::max(max_n, sync.last_state().num_nodes);
      poles.Evaluate(tool);
      worker.Evaluate(tool);
      worker_ready = worker_ready || worker.last_state().ready;
      std::this_thread::sleep_for(std::chrono::microseconds(100));
    }
    allocations = counter.count();
  }
  EXPECT_EQ(allocations, 0);
  EXPECT_GT(max_n, 4);
  EXPECT_TRUE(worker_ready);
}

// FE mode with "grasp grabs": the field it publishes pushes while open and grabs when the grip
// closes on the part (patch factored on the grab field's worker, columns from the mode's column
// worker); a frame then draws the held, twisted part and shows the moment.
TEST(FeMode, GraspGrabsTwistsAndDrawsThePartThenLetsGo) {
  JobQueue jobs;
  FeMode mode(nullptr, &jobs);  // no renderer: VTK data only
  mode.model_settings().use_disk_cache = false;
  mode.grab() = true;
  mode.SetMesh(PlatformMesh(), "platform");
  mode.SetActive(true);
  mode.Precompute();
  for (int i = 0; i < 6000 && jobs.busy(); ++i)
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  jobs.Poll();
  ASSERT_NE(mode.model(), nullptr) << mode.status();
  std::unique_ptr<haptics::ForceField> field = mode.TakeField();
  ASSERT_NE(field, nullptr);
  auto* push_grab = dynamic_cast<FePushGrabField*>(field.get());
  ASSERT_NE(push_grab, nullptr);
  haptics::ToolState tool;
  tool.tool_W = Tool(0.0, kGrabPoint, Eigen::Matrix3d::Identity(), kOpen);
  field->Evaluate(tool.tool_W);
  tool.tool_W = Tool(0.001, kGrabPoint, Eigen::Matrix3d::Identity(), kClosed);
  field->Evaluate(tool.tool_W);
  EXPECT_TRUE(push_grab->grab().last_state().held);
  // Twist by 0.1 rad about +x and hold until the patch is handed over and ramped in.
  haptics::ToolWrench w;
  double t = 0.002;
  for (int i = 0; i < 20000 && push_grab->grab().last_state().ramp < 1.0; ++i, t += 0.001) {
    tool.tool_W =
        Tool(t, kGrabPoint, Eigen::AngleAxisd(0.1, Eigen::Vector3d::UnitX()).toRotationMatrix(),
             kClosed);
    w = field->Evaluate(tool.tool_W);
    std::this_thread::sleep_for(std::chrono::microseconds(500));
  }
  ASSERT_EQ(push_grab->grab().last_state().ramp, 1.0);
  EXPECT_EQ(push_grab->grab().last_state().num_substituted, 0);
  EXPECT_LT(w.m_T_W.x(), -0.05);  // felt: resists the twist (coupling 2 N·m/rad in series)
  EXPECT_LE(w.m_T_W.norm(), 0.1 * kDefaultFeGrabRotCoupling + 1e-9);
  mode.OnFrame(tool);
  EXPECT_GT(mode.figures().grabbed, 4);
  EXPECT_LT(mode.figures().m_tool_W.x(), 0.0);
  EXPECT_GT(mode.figures().max_displacement, 1e-6);
  EXPECT_GT(mode.figures().max_von_mises, 1e5);
  // Open: let go; the frame shows the push again (nothing touched at the grab point's sphere).
  tool.tool_W.grasp = kOpen;
  tool.tool_W.time = t;
  w = field->Evaluate(tool.tool_W);
  EXPECT_FALSE(push_grab->grab().last_state().held);
  mode.OnFrame(tool);
  EXPECT_EQ(mode.figures().grabbed, 0);
  mode.SetActive(false);
  for (int i = 0; i < 3000 && jobs.busy(); ++i)
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  jobs.Poll();
}

TEST(FeGrabField, BadSettingsAreNamed) {
  const auto model = PlatformModel();
  const auto expect_named = [&](FeGrabSettings s, const std::string& name) {
    try {
      FeGrabField field(model, s, nullptr);
      ADD_FAILURE() << name << " accepted";
    } catch (const std::invalid_argument& e) {
      EXPECT_NE(std::string(e.what()).find(name), std::string::npos) << e.what();
    }
  };
  FeGrabSettings s;
  s.tool_radius = 0.0;
  expect_named(s, "tool_radius");
  s = {};
  s.max_patch = 65;
  expect_named(s, "max_patch");
  s = {};
  s.open_angle = 0.5;
  expect_named(s, "open_angle");
  s = {};
  s.max_torque = 0.0;
  expect_named(s, "max_torque");
}

}  // namespace
}  // namespace spidarcad::app
