// Tests of the assembly field: closing the poles on a graspable part grasps it (the same grasp
// torque as GraspField on that part), the part follows the grip, carrying it into the body gives
// a contact force opposing the penetration, releasing it aligned over its hole seats it exactly
// and it stays, releasing it elsewhere leaves it there, the tool's own shell touches the parts,
// and Evaluate allocates nothing. Alignment snap: near its seat a carried part is drawn toward the
// seat's axis (force perpendicular to the axis, toward it; torque turning the part's axis onto
// it), continuous at the capture boundary, zero beyond it and zero with snap off.
// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#include "spidarcad/haptics/assembly_field.h"

#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <stdexcept>

#include "spidarcad/haptics/grasp_field.h"
#include "support/malloc_counter.h"

namespace spidarcad::haptics {
namespace {

constexpr double kPi = 3.14159265358979323846;

// φ of a capped cylinder along z, radius r, from z0 to z1 (exact).
double CylinderPhi(const Eigen::Vector3d& p, double r, double z0, double z1) {
  const double zc = 0.5 * (z0 + z1), hz = 0.5 * (z1 - z0);
  const Eigen::Vector2d d(std::hypot(p.x(), p.y()) - r, std::abs(p.z() - zc) - hz);
  return std::min(std::max(d.x(), d.y()), 0.0) + d.cwiseMax(0.0).norm();
}

// Central-difference gradient of a scalar function.
template <class F>
Eigen::Vector3d Gradient(const F& f, const Eigen::Vector3d& p) {
  constexpr double h = 1e-6;
  Eigen::Vector3d g;
  for (int i = 0; i < 3; ++i) {
    Eigen::Vector3d e = Eigen::Vector3d::Zero();
    e(i) = h;
    g(i) = (f(p + e) - f(p - e)) / (2 * h);
  }
  return g;
}

// The body: a box of half sides (30, 30, 20) mm centred at the origin minus a vertical hole of
// radius 4.6 mm from z = 5 mm up through the top face (z = 20 mm).
constexpr double kHoleRadius = 4.6e-3;
constexpr double kTopZ = 0.02;
class BodyField final : public DistanceField {
 public:
  double Phi(const Eigen::Vector3d& p) const noexcept {
    return std::max(box_.Evaluate(p, nullptr), -CylinderPhi(p, kHoleRadius, 0.005, 0.04));
  }
  double Evaluate(const Eigen::Vector3d& p, Eigen::Vector3d* g) const noexcept override {
    if (g != nullptr) *g = Gradient([this](const Eigen::Vector3d& x) { return Phi(x); }, p);
    return Phi(p);
  }

 private:
  BoxDistanceField box_{Eigen::Vector3d(0.03, 0.03, 0.02)};
};

// The peg part, in its frame P: a handle cube of half side 8 mm centred at (0, 0, 8 mm) and a
// peg of radius 4 mm below it, from z = −12 mm to 1 mm.
constexpr double kPegRadius = 4e-3;
constexpr double kHandle = 0.008;
class PegField final : public DistanceField {
 public:
  double Phi(const Eigen::Vector3d& p) const noexcept {
    return std::min(box_.Evaluate(p - Eigen::Vector3d(0, 0, kHandle), nullptr),
                    CylinderPhi(p, kPegRadius, -0.012, 0.001));
  }
  double Evaluate(const Eigen::Vector3d& p, Eigen::Vector3d* g) const noexcept override {
    if (g != nullptr) *g = Gradient([this](const Eigen::Vector3d& x) { return Phi(x); }, p);
    return Phi(p);
  }

 private:
  BoxDistanceField box_{Eigen::Vector3d::Constant(kHandle)};
};

// The peg's point shell: the handle's faces (2 mm grid) and the peg's side and bottom.
PointShell PegShell() {
  PointShell handle = PointShell::Box(Eigen::Vector3d::Constant(kHandle), 0.002);
  std::vector<Eigen::Vector3d> points, normals;
  for (int i = 0; i < handle.size(); ++i) {
    const Eigen::Vector3d p = handle.points_T[i] + Eigen::Vector3d(0, 0, kHandle);
    if (p.z() < 1e-9 && std::hypot(p.x(), p.y()) < kPegRadius) continue;  // inside the peg's base
    points.push_back(p);
    normals.push_back(handle.normals_T[i]);
  }
  for (int ring = 0; ring <= 6; ++ring) {
    const double z = -0.012 + 0.002 * ring;
    for (int k = 0; k < 12; ++k) {
      const double a = 2 * kPi * k / 12;
      points.emplace_back(kPegRadius * std::cos(a), kPegRadius * std::sin(a), z);
      normals.emplace_back(-std::cos(a), -std::sin(a), 0);
    }
  }
  for (int k = 0; k < 6; ++k) {
    const double a = 2 * kPi * k / 6;
    points.emplace_back(0.5 * kPegRadius * std::cos(a), 0.5 * kPegRadius * std::sin(a), -0.012);
    normals.emplace_back(0, 0, 1);
  }
  points.emplace_back(0, 0, -0.012);
  normals.emplace_back(0, 0, 1);
  return PointShell::FromPoints(points, normals);
}

// The seated pose of the peg in the body frame: peg in the hole, handle 1 mm above the top.
const Eigen::Isometry3d kSeat_BP(Eigen::Translation3d(0, 0, kTopZ + 0.001));
// The peg's initial pose: beside the body.
const Eigen::Isometry3d kStart_WP(Eigen::Translation3d(0.07, 0, 0));
// The handle's centre lies at L along the grip bisector from the grip centre.
constexpr double kL = 0.02;
const Eigen::Vector3d kBisector = Eigen::Vector3d(1, 1, 0) / std::sqrt(2.0);

std::vector<AssemblyPart> Parts() {
  AssemblyPart body;
  body.name = "body";
  body.field_P = std::make_shared<BodyField>();
  body.fixed = true;
  AssemblyPart peg;
  peg.name = "peg";
  peg.field_P = std::make_shared<PegField>();
  peg.shell_P = PegShell();
  peg.X_WP = kStart_WP;
  AssemblySeat seat;
  seat.other = 0;
  seat.X_OS = kSeat_BP;
  seat.position_tolerance = 2e-3;
  seat.angle_tolerance = 0.1;
  peg.seats.push_back(seat);
  return {body, peg};
}

// Drives the field with a scripted grip at 1 kHz (velocities by finite differences).
struct Driver {
  AssemblyField& field;
  ToolKinematics tool;
  ToolWrench last;

  // When not null, every tick appends the wrench, the contacts, the candidates and every part's
  // pose.
  std::vector<std::vector<double>>* trace = nullptr;

  void Tick() {
    tool.time += 1e-3;
    last = field.Evaluate(tool);
    if (trace == nullptr) return;
    std::vector<double> row = {
        last.f_T_W.x(), last.f_T_W.y(),           last.f_T_W.z(),
        last.m_T_W.x(), last.m_T_W.y(),           last.m_T_W.z(),
        last.g,         double(field.contacts()), double(field.candidates())};
    for (int i = 0; i < field.size(); ++i) {
      const Eigen::Matrix4d X = field.X_WP(i).matrix();
      row.insert(row.end(), X.data(), X.data() + 16);
    }
    trace->push_back(std::move(row));
  }
  // Moves the grip centre linearly to p in `ticks` ticks.
  void MoveTo(const Eigen::Vector3d& p, int ticks) {
    const Eigen::Vector3d start = tool.p_WT;
    for (int k = 1; k <= ticks; ++k) {
      const Eigen::Vector3d next = start + (p - start) * (double(k) / ticks);
      tool.v_WT = (next - tool.p_WT) / 1e-3;
      tool.p_WT = next;
      Tick();
    }
    tool.v_WT.setZero();
  }
  void Hold(int ticks) {
    for (int k = 0; k < ticks; ++k) Tick();
  }
  // Closes the grip (rate rad/s < 0) until the field carries a part or the angle hits `limit`.
  void CloseUntilGrasped(double rate, double limit) {
    tool.grasp_rate = rate;
    while (field.carried() < 0 && tool.grasp > limit) {
      tool.grasp += rate * 1e-3;
      Tick();
    }
    tool.grasp_rate = 0;
  }
  // Opens the grip to π/2.
  void Open() {
    tool.grasp_rate = 2.0;
    while (tool.grasp < kPi / 2) {
      tool.grasp = std::min(kPi / 2, tool.grasp + 2e-3);
      Tick();
    }
    tool.grasp_rate = 0;
  }
};

// Grip centre that puts the handle's centre at L along the bisector (R_WT = I).
Eigen::Vector3d GripFor(const Eigen::Isometry3d& X_WP) {
  return X_WP * Eigen::Vector3d(0, 0, kHandle) - kL * kBisector;
}

// Picks the peg up at its start pose; returns the driver.
Driver PickUp(AssemblyField& field) {
  Driver d{field, ToolKinematics{}, ToolWrench{}};
  d.tool.p_WT = GripFor(kStart_WP);
  d.Hold(5);
  d.CloseUntilGrasped(-1.0, 0.2);
  return d;
}

TEST(AssemblyField, ClosingThePolesOnAPartGrabsItWithTheGraspFieldTorque) {
  AssemblyField field(Parts());
  // The same part alone in a GraspField gives the reference torque at each angle.
  GraspField reference(std::make_shared<PegField>(), kStart_WP);
  Driver d{field, ToolKinematics{}, ToolWrench{}};
  d.tool.p_WT = GripFor(kStart_WP);
  d.tool.grasp_rate = -1.0;
  bool touched = false;
  while (field.carried() < 0 && d.tool.grasp > 0.2) {
    d.tool.grasp -= 1e-3;
    const ToolWrench expected = reference.Evaluate(d.tool);
    d.Tick();
    EXPECT_NEAR(d.last.g, expected.g, 1e-9) << "at θ = " << d.tool.grasp;
    if (d.last.g != 0) {
      EXPECT_LT(d.last.g, 0.0);
      touched = true;
    }
  }
  EXPECT_TRUE(touched);
  ASSERT_EQ(field.carried(), 1);
  EXPECT_TRUE(reference.grasped());
  // The grab happens at the current pose: X_TP = X_WT⁻¹ X_WP with R_WT = I.
  EXPECT_TRUE(field.X_TP().isApprox(
      Eigen::Isometry3d(Eigen::Translation3d(kStart_WP.translation() - d.tool.p_WT)), 1e-12));
  EXPECT_GT(d.tool.grasp, 0.2);
}

TEST(AssemblyField, CarriedPartFollowsTheGrip) {
  AssemblyField field(Parts());
  Driver d = PickUp(field);
  ASSERT_EQ(field.carried(), 1);
  const Eigen::Isometry3d X_TP = field.X_TP();
  d.MoveTo(d.tool.p_WT + Eigen::Vector3d(-0.01, 0.02, 0.04), 300);
  d.Hold(500);
  Eigen::Isometry3d X_WT = Eigen::Isometry3d::Identity();
  X_WT.translation() = d.tool.p_WT;
  EXPECT_LT((field.X_WP(1).translation() - (X_WT * X_TP).translation()).norm(), 1e-5);
  EXPECT_TRUE(field.X_WP(1).linear().isApprox(Eigen::Matrix3d::Identity(), 1e-4));
  EXPECT_EQ(field.carried(), 1);
  // At rest in free space the user feels (almost) nothing but the grasp.
  EXPECT_LT(d.last.f_T_W.norm(), 1e-2);
  EXPECT_LT(d.last.g, 0.0);
  // The published state agrees.
  const AssemblyState& s = field.LatestState();
  EXPECT_EQ(s.count, 2);
  EXPECT_EQ(s.carried, 1);
  EXPECT_TRUE(s.X_WP[1].isApprox(field.X_WP(1)));
}

TEST(AssemblyField, CarryingThePartIntoTheBodyPushesBack) {
  AssemblyField field(Parts());
  Driver d = PickUp(field);
  ASSERT_EQ(field.carried(), 1);
  // Peg bottom 3 mm below the top face, away from the hole.
  Eigen::Isometry3d target(Eigen::Translation3d(0.015, -0.012, kTopZ + 0.012 - 0.003));
  Eigen::Isometry3d above = target;
  above.translation().z() += 0.03;
  d.MoveTo(GripFor(above), 400);
  d.Hold(300);
  EXPECT_LT(d.last.f_T_W.norm(), 1e-2);
  d.MoveTo(GripFor(target), 300);
  d.Hold(400);
  ASSERT_EQ(field.carried(), 1);
  // The user is pushed up, out of the body; the part stays above the target, less deep.
  EXPECT_GT(d.last.f_T_W.z(), 1.0);
  EXPECT_LT(std::abs(d.last.f_T_W.x()) + std::abs(d.last.f_T_W.y()), 0.1 * d.last.f_T_W.z());
  EXPECT_GT(field.X_WP(1).translation().z(), target.translation().z() + 1e-3);
  EXPECT_GT(field.contacts(), 0);
  // The part's lowest point is within 1 mm of the top face.
  EXPECT_GT(field.X_WP(1).translation().z() - 0.012, kTopZ - 1e-3);
  // Opening there releases it unseated.
  d.Open();
  EXPECT_EQ(field.carried(), -1);
  EXPECT_FALSE(field.seated(1));
}

// A part built within a seat's tolerance (a document saved with it seated) starts seated, at the
// pose it was given; one built beside it does not. The constructor's published state says so
// before the first tick (the window and `spidarcad run` read their summaries from it).
TEST(AssemblyField, APartBuiltInItsSeatStartsSeatedWhereItWasGiven) {
  std::vector<AssemblyPart> parts = Parts();
  Eigen::Isometry3d near = kSeat_BP;  // body at the origin
  near.translation() += Eigen::Vector3d(0.0003, -0.0002, 0.001);
  parts[1].X_WP = near;
  AssemblyField built_seated(parts);
  EXPECT_TRUE(built_seated.seated(1));
  EXPECT_FALSE(built_seated.seated(0)) << "a fixed part is never seated";
  EXPECT_EQ(built_seated.X_WP(1).matrix(), near.matrix());
  const AssemblyState& s = built_seated.LatestState();
  ASSERT_EQ(s.count, 2);
  EXPECT_TRUE(s.seated[1]);
  EXPECT_EQ(s.X_WP[1].matrix(), near.matrix());
  parts[1].X_WP.translation().z() += 0.003;  // 3 mm above: outside the 2 mm tolerance
  AssemblyField above(parts);
  EXPECT_FALSE(above.seated(1));
  AssemblyField apart(Parts());
  EXPECT_FALSE(apart.seated(1));
}

TEST(AssemblyField, ReleasingOverTheHoleSeatsThePartExactlyAndItStays) {
  AssemblyField field(Parts());
  Driver d = PickUp(field);
  ASSERT_EQ(field.carried(), 1);
  const Eigen::Isometry3d seat = kSeat_BP;  // body at the origin
  Eigen::Isometry3d above = seat;
  above.translation().z() += 0.03;
  d.MoveTo(GripFor(above), 400);
  d.Hold(200);
  // Down into the hole, stopping 1 mm short of the seat (within its 2 mm tolerance).
  Eigen::Isometry3d near = seat;
  near.translation() += Eigen::Vector3d(0.0003, -0.0002, 0.001);
  d.MoveTo(GripFor(near), 400);
  d.Hold(300);
  ASSERT_EQ(field.carried(), 1);
  EXPECT_LT((field.X_WP(1).translation() - near.translation()).norm(), 2e-4);
  d.Open();
  EXPECT_EQ(field.carried(), -1);
  EXPECT_TRUE(field.seated(1));
  EXPECT_EQ(field.X_WP(1).matrix(), seat.matrix());
  // It stays when the grip leaves.
  d.MoveTo(d.tool.p_WT + Eigen::Vector3d(0.05, -0.03, 0.05), 300);
  d.Hold(100);
  EXPECT_TRUE(field.seated(1));
  EXPECT_EQ(field.X_WP(1).matrix(), seat.matrix());
  const AssemblyState& s = field.LatestState();
  EXPECT_TRUE(s.seated[1]);
  EXPECT_FALSE(s.seated[0]);
  EXPECT_EQ(s.X_WP[1].matrix(), seat.matrix());
}

// The body field, counting its evaluations.
class CountingBodyField final : public DistanceField {
 public:
  double Evaluate(const Eigen::Vector3d& p, Eigen::Vector3d* g) const noexcept override {
    ++calls;
    return body_.Evaluate(p, g);
  }
  mutable long calls = 0;

 private:
  BodyField body_;
};

// Carries part 1 (picked up by both drivers) above the hole, then down and off-centre so the
// peg presses on the hole's wall, and releases it, ticking both fields alike: every tick must
// give the same wrench, pose, contacts and candidates, bit for bit, and the peg must touch.
void CarryIntoTheHoleInLockstep(AssemblyField& a, Driver& da, AssemblyField& b, Driver& db) {
  Eigen::Isometry3d above = kSeat_BP;
  above.translation().z() += 0.03;
  Eigen::Isometry3d in = kSeat_BP;
  in.translation() += Eigen::Vector3d(0.0012, -0.0008, 0.004);
  std::vector<Eigen::Vector3d> path;
  for (int k = 1; k <= 300; ++k)
    path.push_back(GripFor(kStart_WP) + (GripFor(above) - GripFor(kStart_WP)) * (k / 300.0));
  for (int k = 1; k <= 400; ++k)
    path.push_back(GripFor(above) + (GripFor(in) - GripFor(above)) * (k / 400.0));
  for (int k = 0; k < 200; ++k)
    path.push_back(GripFor(in) + Eigen::Vector3d(0.001 * std::sin(0.05 * k), 0, 0));
  int touching = 0;
  for (std::size_t t = 0; t < path.size(); ++t) {
    for (Driver* d : {&da, &db}) {
      d->tool.v_WT = (path[t] - d->tool.p_WT) / 1e-3;
      d->tool.p_WT = path[t];
      d->Tick();
    }
    ASSERT_EQ(da.last.f_T_W, db.last.f_T_W) << "tick " << t;
    ASSERT_EQ(da.last.m_T_W, db.last.m_T_W) << "tick " << t;
    ASSERT_EQ(da.last.g, db.last.g) << "tick " << t;
    ASSERT_EQ(a.X_WP(1).matrix(), b.X_WP(1).matrix()) << "tick " << t;
    ASSERT_EQ(a.contacts(), b.contacts()) << "tick " << t;
    ASSERT_EQ(a.candidates(), b.candidates()) << "tick " << t;
    touching += a.contacts() > 0;
  }
  EXPECT_GT(touching, 100);  // the peg did press on the body
  da.Open();
  db.Open();
  EXPECT_EQ(a.seated(1), b.seated(1));
  EXPECT_EQ(a.X_WP(1).matrix(), b.X_WP(1).matrix());
}

// The carried part's candidate search skips shell points that cannot be within reach of another
// part (by clusters, and by each point's offset from its cluster's centre: φ is 1-Lipschitz).
// Against the search that tests every shell point, every tick of a grab, a carry down into the
// hole (the peg against its wall) and a release must give the same wrench and the same poses,
// bit for bit, with fewer evaluations of the body.
TEST(AssemblyField, CullingTheShellSearchChangesNothingButTheWork) {
  std::vector<std::shared_ptr<CountingBodyField>> bodies;
  std::vector<std::unique_ptr<AssemblyField>> fields;
  for (const bool cull : {true, false}) {
    std::vector<AssemblyPart> parts = Parts();
    bodies.push_back(std::make_shared<CountingBodyField>());
    parts[0].field_P = bodies.back();
    AssemblySettings settings;
    settings.cull_shell_search = cull;
    fields.push_back(std::make_unique<AssemblyField>(parts, PointShell{}, settings));
  }
  Driver culled = PickUp(*fields[0]);
  Driver every = PickUp(*fields[1]);
  ASSERT_EQ(fields[0]->carried(), 1);
  ASSERT_EQ(fields[1]->carried(), 1);
  const long calls_before[2] = {bodies[0]->calls, bodies[1]->calls};
  CarryIntoTheHoleInLockstep(*fields[0], culled, *fields[1], every);
  const long work[2] = {bodies[0]->calls - calls_before[0], bodies[1]->calls - calls_before[1]};
  std::printf("body evaluations while carrying: culled %ld, every point %ld\n", work[0], work[1]);
  EXPECT_LT(work[0], work[1] / 2);
}

// The substeps expand only the candidates whose bound φ0 − |∇φ| (|p − p0| + ‖R − R0‖ |r|) can
// reach 0 (the others get no force). Against expanding every candidate in every substep, the
// same carry into the hole with the peg on the wall gives the same ticks, bit for bit.
TEST(AssemblyField, SkippingFarCandidatesInTheSubstepsChangesNothing) {
  std::vector<std::unique_ptr<AssemblyField>> fields;
  for (const bool skip : {true, false}) {
    AssemblySettings settings;
    settings.skip_far_candidates = skip;
    fields.push_back(std::make_unique<AssemblyField>(Parts(), PointShell{}, settings));
  }
  Driver skipping = PickUp(*fields[0]);
  Driver every = PickUp(*fields[1]);
  ASSERT_EQ(fields[0]->carried(), 1);
  ASSERT_EQ(fields[1]->carried(), 1);
  CarryIntoTheHoleInLockstep(*fields[0], skipping, *fields[1], every);
}

// The candidate search keeps, per other part, the φ it last evaluated at each shell point of the
// carried part and skips the point while that bound is beyond the reach; the bounds hold only
// while the other parts stay put, that is within one carry. Three carries: peg A is put down
// 3.5 mm below peg B (its points' φ to B recorded), B is carried down onto A and left there, and A
// is picked up again and pushed up into B. Against the search that tests every shell point, every
// tick must be the same, bit for bit, and A must touch B in the last carry (with bounds kept
// from the first carry it would not).
TEST(AssemblyField, SearchBoundsDoNotOutliveTheCarryThatMadeThem) {
  const Eigen::Isometry3d start_B(Eigen::Translation3d(0.07, 0, 0.05));
  std::vector<std::vector<double>> traces[2];
  int touching_in_last_carry[2] = {0, 0};
  for (int run = 0; run < 2; ++run) {
    std::vector<AssemblyPart> parts = Parts();
    AssemblyPart b = parts[1];
    b.name = "peg B";
    b.X_WP = start_B;
    b.seats.clear();
    parts[1].seats.clear();
    parts.push_back(b);
    AssemblySettings settings;
    settings.cull_shell_search = run == 0;
    AssemblyField field(parts, PointShell{}, settings);
    Driver d{field, ToolKinematics{}, ToolWrench{}};
    d.trace = &traces[run];
    auto carry = [&](int part, const Eigen::Vector3d& by, int hold) {
      d.MoveTo(GripFor(field.X_WP(part)), 200);
      d.Hold(5);
      d.CloseUntilGrasped(-1.0, 0.2);
      ASSERT_EQ(field.carried(), part);
      d.MoveTo(d.tool.p_WT + by, 300);
      d.Hold(hold);
      d.Open();
      ASSERT_EQ(field.carried(), -1);
    };
    carry(1, Eigen::Vector3d(0, 0, 0.0185), 50);  // A's top 3.5 mm below B's peg
    if (HasFatalFailure()) return;
    carry(2, Eigen::Vector3d(0, 0, -0.0075), 300);  // B's peg down onto A's top
    if (HasFatalFailure()) return;
    const std::size_t before = traces[run].size();
    carry(1, Eigen::Vector3d(0, 0, 0.004), 300);  // A up into B
    if (HasFatalFailure()) return;
    for (std::size_t k = before; k < traces[run].size(); ++k)
      touching_in_last_carry[run] += traces[run][k][7] > 0;
  }
  ASSERT_EQ(traces[0].size(), traces[1].size());
  for (std::size_t k = 0; k < traces[0].size(); ++k)
    ASSERT_EQ(traces[0][k], traces[1][k]) << "tick " << k;
  EXPECT_GT(touching_in_last_carry[0], 100);
}

TEST(AssemblyField, ReleasingElsewhereLeavesThePartWhereItWasLetGo) {
  AssemblyField field(Parts());
  Driver d = PickUp(field);
  ASSERT_EQ(field.carried(), 1);
  d.MoveTo(d.tool.p_WT + Eigen::Vector3d(-0.02, 0.01, 0.05), 300);
  d.Hold(300);
  Eigen::Isometry3d X_WT = Eigen::Isometry3d::Identity();
  X_WT.translation() = d.tool.p_WT;
  const Eigen::Isometry3d expected = X_WT * field.X_TP();
  d.Open();
  ASSERT_EQ(field.carried(), -1);
  EXPECT_FALSE(field.seated(1));
  const Eigen::Isometry3d released = field.X_WP(1);
  EXPECT_LT((released.translation() - expected.translation()).norm(), 1e-5);
  const Eigen::Vector3d release_grip = d.tool.p_WT;
  d.MoveTo(d.tool.p_WT + Eigen::Vector3d(0, -0.05, 0), 200);
  d.Hold(100);
  EXPECT_EQ(field.X_WP(1).matrix(), released.matrix());
  EXPECT_FALSE(field.seated(1));
  // Coming back and closing picks it up again where it was left.
  d.MoveTo(release_grip, 200);
  d.CloseUntilGrasped(-1.0, 0.2);
  EXPECT_EQ(field.carried(), 1);
  EXPECT_EQ(field.X_WP(1).matrix(), released.matrix());
}

TEST(AssemblyField, ToolShellTouchesTheBody) {
  AssemblyField field(Parts(), PointShell::Sphere(0.003, 60));
  ToolKinematics tool;
  tool.p_WT = Eigen::Vector3d(0.01, 0.015, kTopZ + 0.004);  // sphere 1 mm above the top face
  EXPECT_EQ(field.Evaluate(tool).f_T_W.norm(), 0.0);
  tool.time = 1e-3;
  tool.p_WT.z() = kTopZ + 0.002;  // sphere bottom 1 mm into the top face
  const ToolWrench w = field.Evaluate(tool);
  EXPECT_GT(w.f_T_W.z(), 0.5);
  EXPECT_NEAR(w.f_T_W.x(), 0.0, 1e-3 * w.f_T_W.z() + 1e-9);
  EXPECT_GT(field.contacts(), 0);
  EXPECT_EQ(field.carried(), -1);
}

TEST(AssemblyField, RejectsBadInput) {
  EXPECT_THROW(AssemblyField(std::vector<AssemblyPart>{}), std::invalid_argument);
  std::vector<AssemblyPart> parts = Parts();
  parts[1].seats[0].other = 1;  // itself
  EXPECT_THROW(AssemblyField{parts}, std::invalid_argument);
  parts = Parts();
  parts[1].shell_P = PointShell{};
  EXPECT_THROW(AssemblyField{parts}, std::invalid_argument);
  parts = Parts();
  parts[0].field_P = nullptr;
  EXPECT_THROW(AssemblyField{parts}, std::invalid_argument);
  AssemblySettings s;
  s.substeps = 0;
  EXPECT_THROW(AssemblyField(Parts(), PointShell{}, s), std::invalid_argument);
}

TEST(AssemblyField, EvaluateAllocatesNothing) {
  ASSERT_TRUE(test_support::MallocCounterActive());
  AssemblyField field(Parts(), PointShell::Sphere(0.003, 30));
  Driver d{field, ToolKinematics{}, ToolWrench{}};
  d.tool.p_WT = GripFor(kStart_WP);
  d.Hold(2);
  long allocations = 0;
  {
    test_support::MallocCounter counter;
    d.CloseUntilGrasped(-1.0, 0.2);
    Eigen::Isometry3d target(Eigen::Translation3d(0.015, -0.012, kTopZ + 0.012 - 0.003));
    d.MoveTo(GripFor(target), 300);
    d.Hold(50);
    d.Open();
    (void)field.LatestState();
    allocations = counter.count();
  }
  EXPECT_EQ(allocations, 0);
  EXPECT_EQ(field.carried(), -1);
}

// Alignment snap: the settings used below (capture 15 mm / 20°).
AssemblySettings AlignOn() {
  AssemblySettings s;
  s.align.enabled = true;
  return s;
}

// The seat of the peg in W (body at the origin) and its axis.
const Eigen::Vector3d kSeatOrigin = kSeat_BP.translation();
const Eigen::Vector3d kAxis = Eigen::Vector3d::UnitZ();

Eigen::Isometry3d PoseAt(const Eigen::Vector3d& p, const Eigen::AngleAxisd& r) {
  Eigen::Isometry3d X = Eigen::Isometry3d::Identity();
  X.linear() = r.toRotationMatrix();
  X.translation() = p;
  return X;
}

// Independent reference: the force toward the axis is −k_a w e_⊥ before the cap (the file
// comment's formula evaluated here with the angle from acos and the ramp as a polynomial).
double Ramp(double x) { return x <= 0 ? 0.0 : x >= 1 ? 1.0 : 3 * x * x - 2 * x * x * x; }

TEST(AssemblyField, AlignmentSnapPullsTowardTheSeatAxis) {
  AssemblyField field(Parts(), PointShell{}, AlignOn());
  const AlignmentSnapSettings& a = field.settings().align;
  std::srand(7);
  const auto uniform = [] { return 2.0 * std::rand() / RAND_MAX - 1.0; };
  int pulled = 0;
  for (int k = 0; k < 2000; ++k) {
    const Eigen::Vector3d e = 0.017 * Eigen::Vector3d(uniform(), uniform(), uniform());
    const Eigen::Vector3d tilt_axis = Eigen::Vector3d(uniform(), uniform(), 0).normalized();
    const double tilt = 0.4 * std::abs(uniform());
    const Eigen::Isometry3d X = PoseAt(kSeatOrigin + e, Eigen::AngleAxisd(tilt, tilt_axis));
    Eigen::Vector3d f, tau;
    const bool captured = field.AlignmentWrench(1, X, &f, &tau);
    const Eigen::Vector3d z = X.linear().col(2);
    const double angle = std::acos(std::clamp(z.dot(kAxis), -1.0, 1.0));
    const double w = Ramp(1 - e.norm() / a.capture_distance) * Ramp(1 - angle / a.capture_angle);
    if (e.norm() >= a.capture_distance || angle >= a.capture_angle) {
      // Beyond capture: nothing at all.
      EXPECT_FALSE(captured);
      EXPECT_EQ(f, Eigen::Vector3d::Zero());
      EXPECT_EQ(tau, Eigen::Vector3d::Zero());
      continue;
    }
    const Eigen::Vector3d e_perp(e.x(), e.y(), 0);
    const Eigen::Vector3d f_expected = -a.stiffness * w * e_perp;
    const double cap = std::min(1.0, a.max_force / f_expected.norm());
    EXPECT_LT((f - cap * f_expected).norm(), 1e-9 + 1e-9 * f_expected.norm()) << k;
    // No pull along the axis; toward it, never more than the cap.
    EXPECT_NEAR(f.dot(kAxis), 0.0, 1e-12);
    EXPECT_LE(f.norm(), a.max_force + 1e-12);
    if (w > 1e-6 && e_perp.norm() > 1e-4) {
      EXPECT_LT(f.dot(e_perp), 0.0);
      EXPECT_LT(f.normalized().cross(-e_perp.normalized()).norm(), 1e-9);
      ++pulled;
    }
    // The torque turns the part's axis toward the seat's: about z × a, of size min(k_α w α, cap).
    if (angle > 1e-3 && w > 1e-6) {
      EXPECT_GT(tau.dot(z.cross(kAxis)), 0.0);
      EXPECT_NEAR(tau.norm(), std::min(a.rot_stiffness * w * angle, a.max_torque), 1e-12);
    }
  }
  EXPECT_GT(pulled, 100);
}

TEST(AssemblyField, AlignmentSnapIsContinuousAtTheCaptureBoundary) {
  AssemblyField field(Parts(), PointShell{}, AlignOn());
  const AlignmentSnapSettings& a = field.settings().align;
  // Walk outward along rays through the distance boundary, and across the angle boundary, in
  // steps of 1 µm / 1 µrad: neighbouring samples never differ by more than a Lipschitz step
  // (a jump at the boundary would be k_a·e_⊥ there, up to the 1 N cap).
  double max_step_f = 0, max_step_t = 0, near_boundary = 0;
  for (int ray = 0; ray < 12; ++ray) {
    const double phi = 2 * kPi * ray / 12, theta = 0.3 + 0.1 * ray;
    const Eigen::Vector3d dir(std::sin(theta) * std::cos(phi), std::sin(theta) * std::sin(phi),
                              std::cos(theta));
    const Eigen::AngleAxisd tilt(0.1, Eigen::Vector3d(-std::sin(phi), std::cos(phi), 0));
    Eigen::Vector3d f_prev, t_prev;
    for (int k = 0; k <= 4000; ++k) {
      const double r = a.capture_distance - 2e-3 + 1e-6 * k;
      Eigen::Vector3d f, t;
      field.AlignmentWrench(1, PoseAt(kSeatOrigin + r * dir, tilt), &f, &t);
      if (k > 0) {
        max_step_f = std::max(max_step_f, (f - f_prev).norm());
        max_step_t = std::max(max_step_t, (t - t_prev).norm());
      }
      if (std::abs(r - a.capture_distance) < 2e-6)
        near_boundary = std::max(near_boundary, f.norm());
      if (r > a.capture_distance + 1e-12) {
        EXPECT_EQ(f.norm() + t.norm(), 0.0) << r;
      }
      f_prev = f;
      t_prev = t;
    }
    // Across the angle boundary, 8 mm off the axis.
    for (int k = 0; k <= 4000; ++k) {
      const double angle = a.capture_angle - 2e-3 + 1e-6 * k;
      Eigen::Vector3d f, t;
      field.AlignmentWrench(
          1,
          PoseAt(kSeatOrigin + 0.008 * Eigen::Vector3d(std::cos(phi), std::sin(phi), 0),
                 Eigen::AngleAxisd(angle, Eigen::Vector3d(-std::sin(phi), std::cos(phi), 0))),
          &f, &t);
      if (k > 0) {
        max_step_f = std::max(max_step_f, (f - f_prev).norm());
        max_step_t = std::max(max_step_t, (t - t_prev).norm());
      }
      if (angle > a.capture_angle + 1e-12) {
        EXPECT_EQ(f.norm() + t.norm(), 0.0) << angle;
      }
      f_prev = f;
      t_prev = t;
    }
  }
  std::printf("largest change per 1 µm / 1 µrad step: %.3g N, %.3g N·m\n", max_step_f, max_step_t);
  EXPECT_LT(max_step_f, 1e-3);
  EXPECT_LT(max_step_t, 1e-5);
  EXPECT_LT(near_boundary, 1e-6);
}

TEST(AssemblyField, AlignmentSnapOffPullsNothing) {
  AssemblyField field(Parts());  // default settings: snap off
  EXPECT_FALSE(field.settings().align.enabled);
  Eigen::Vector3d f, t;
  EXPECT_FALSE(field.AlignmentWrench(1,
                                     PoseAt(kSeatOrigin + Eigen::Vector3d(0.004, 0.002, 0.005),
                                            Eigen::AngleAxisd(0.1, Eigen::Vector3d::UnitX())),
                                     &f, &t));
  EXPECT_EQ(f, Eigen::Vector3d::Zero());
  EXPECT_EQ(t, Eigen::Vector3d::Zero());
  AssemblySettings bad = AlignOn();
  bad.align.capture_angle = 0;
  EXPECT_THROW(AssemblyField(Parts(), PointShell{}, bad), std::invalid_argument);
  bad = AlignOn();
  bad.align.max_force = -1;
  EXPECT_THROW(AssemblyField(Parts(), PointShell{}, bad), std::invalid_argument);
}

// Carrying the peg to rest 3.6 mm off the hole's axis, its bottom 1 mm above the top face (no
// contact; capture widened to 30 mm so the pull is well above the test's tolerances):
// with snap on the user feels the pull toward the axis (at rest the coupling passes f_a on), and
// the part sits nearer the axis than the grip's target; with snap off nothing.
TEST(AssemblyField, CarriedPartNearItsSeatIsFeltPulledTowardTheAxis) {
  for (const bool on : {true, false}) {
    AssemblySettings settings = on ? AlignOn() : AssemblySettings{};
    settings.align.capture_distance = 0.03;
    AssemblyField field(Parts(), PointShell{}, settings);
    Driver d = PickUp(field);
    ASSERT_EQ(field.carried(), 1);
    Eigen::Isometry3d hover = kSeat_BP;
    hover.translation() += Eigen::Vector3d(0.003, -0.002, 0.012);  // peg bottom 1 mm above
    d.MoveTo(GripFor(hover), 500);
    d.Hold(800);
    ASSERT_EQ(field.carried(), 1);
    EXPECT_EQ(field.contacts(), 0);
    const Eigen::Vector3d e_perp(0.003, -0.002, 0);
    if (!on) {
      EXPECT_LT(d.last.f_T_W.norm(), 1e-3);
      continue;
    }
    Eigen::Vector3d f, t;
    ASSERT_TRUE(field.AlignmentWrench(1, field.X_WP(1), &f, &t));
    EXPECT_GT(f.norm(), 0.1);
    EXPECT_LT((d.last.f_T_W - f).norm(), 1e-3 * f.norm() + 1e-4);
    EXPECT_GT(d.last.f_T_W.normalized().dot(-e_perp.normalized()), 0.999);
    // The part is drawn off its target toward the axis: f_a = k_c (p_V − p_target) at rest.
    const Eigen::Vector3d off = field.X_WP(1).translation() - hover.translation();
    EXPECT_LT(off.dot(e_perp), 0.0);
    EXPECT_LT((off * field.settings().coupling_stiffness - f).norm(), 1e-3 + 1e-3 * f.norm());
  }
}

TEST(AssemblyField, EvaluateAllocatesNothingWithAlignmentSnap) {
  ASSERT_TRUE(test_support::MallocCounterActive());
  AssemblyField field(Parts(), PointShell::Sphere(0.003, 30), AlignOn());
  Driver d{field, ToolKinematics{}, ToolWrench{}};
  d.tool.p_WT = GripFor(kStart_WP);
  d.Hold(2);
  long allocations = 0;
  {
    test_support::MallocCounter counter;
    d.CloseUntilGrasped(-1.0, 0.2);
    Eigen::Isometry3d near = kSeat_BP;
    near.translation() += Eigen::Vector3d(0.003, 0.001, 0.004);
    d.MoveTo(GripFor(near), 300);
    d.Hold(50);
    d.Open();
    (void)field.LatestState();
    allocations = counter.count();
  }
  EXPECT_EQ(allocations, 0);
  EXPECT_EQ(field.carried(), -1);
}

}  // namespace
}  // namespace spidarcad::haptics
