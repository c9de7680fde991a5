// Tests of the haptic tick (HapticLoop::Step) on the simulated SPIDAR-G: forces checked against
// the field laws evaluated here at the TRUE grip pose, safety events one by one, determinism,
// the scene hand-off between threads, and a tick that allocates nothing.
// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#include "spidarcad/haptics/haptic_loop.h"

#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <atomic>
#include <cmath>
#include <cstring>
#include <limits>
#include <random>
#include <thread>

#include "spidarcad/haptics/kinematics.h"
#include "spidarcad/haptics/simulated_device.h"
#include "support/malloc_counter.h"

namespace spidarcad::haptics {
namespace {

LoopSettings TestSettings() {
  LoopSettings s;
  s.fk.max_residual = 5e-3;  // the default simulated device is uncalibrated
  return s;
}

struct Rig {
  explicit Rig(const SimulatedDeviceConfig& config, const LoopSettings& settings = TestSettings())
      : device(config),
        loop(device.info(),
             EncoderCalibration::Nominal(
                 device.info().encoder,
                 InverseKinematics(device.info().geometry, device.info().home_pose)),
             settings) {}
  TickOutputs Tick(const GripPose& pose, double dt = 1e-3, double lateness = 0.0) {
    device.SetTruePose(pose);
    device.Step(dt > 0 && std::isfinite(dt) ? dt : 1e-3);
    TickInputs in;
    device.Read(&in.reading);
    in.lateness = lateness;
    const TickOutputs out = loop.Step(in, dt);
    device.WriteTensions(out.tau);
    return out;
  }
  SimulatedSpidarG device;
  HapticLoop loop;
};

GripPose MovingPose(double d, int k) {
  const double t = 1e-3 * k;
  const Eigen::Vector3d p0(0.05 * std::cos(2.0 * t), 0.05 * std::sin(2.0 * t),
                           -0.025 + 0.01 * std::sin(3.0 * t));
  const Eigen::Matrix3d R =
      Eigen::AngleAxisd(0.3 * std::sin(1.5 * t), Eigen::Vector3d(0.3, 0.5, 0.8).normalized())
          .toRotationMatrix();
  return GripPose::FromFrame(p0, R, M_PI / 2 + 0.2 * std::sin(t), d);
}

GripPose At(const Eigen::Vector3d& p0) {
  return GripPose::FromFrame(p0, Eigen::Matrix3d::Identity(), M_PI / 2, 0.04);
}

bool AllEqual(const Vector8d& tau, double value) { return (tau.array() == value).all(); }

// A field that returns NaN.
class NanField final : public ForceField {
 public:
  ToolWrench Evaluate(const ToolKinematics&) noexcept override {
    ToolWrench w;
    w.f_T_W.x() = std::numeric_limits<double>::quiet_NaN();
    return w;
  }
  const char* name() const noexcept override { return "nan"; }
};

// An active (energy-producing) field: negative damping f = +β v.
class ActiveField final : public ForceField {
 public:
  explicit ActiveField(double beta) : beta_(beta) {}
  ToolWrench Evaluate(const ToolKinematics& tool) noexcept override {
    ToolWrench w;
    w.f_T_W = beta_ * tool.v_WT;
    return w;
  }
  const char* name() const noexcept override { return "active"; }

 private:
  double beta_;
};

// Records on which thread it was destroyed.
std::atomic<int> g_destroyed{0};
std::atomic<bool> g_destroyed_on_haptic_thread{false};
thread_local bool t_is_haptic_thread = false;
class TracedField final : public ForceField {
 public:
  ~TracedField() override {
    g_destroyed.fetch_add(1);
    if (t_is_haptic_thread) g_destroyed_on_haptic_thread.store(true);
  }
  ToolWrench Evaluate(const ToolKinematics&) noexcept override { return {}; }
  const char* name() const noexcept override { return "traced"; }
};

std::unique_ptr<HapticScene> SceneWith(std::unique_ptr<ForceField> field) {
  auto scene = std::make_unique<HapticScene>();
  scene->Add(std::move(field));
  return scene;
}

TEST(HapticLoop, AllocatesNothingPerTick) {
  ASSERT_TRUE(test_support::MallocCounterActive()) << "the counting malloc is not in use";
  Rig rig{SimulatedDeviceConfig{}};
  rig.loop.Publish(MakeDemoScene());
  const double d = rig.device.info().geometry.d;
  rig.Tick(MovingPose(d, 0));
  long allocations = 0;
  int forced = 0;
  {
    test_support::MallocCounter counter;
    for (int k = 1; k <= 2000; ++k) {
      const TickOutputs out = rig.Tick(MovingPose(d, k));
      forced += out.wrench_D.head<3>().norm() > 0.1;
      (void)rig.loop.LatestToolState();
    }
    allocations = counter.count();
  }
  EXPECT_EQ(allocations, 0);
  EXPECT_GT(forced, 1000);  // the wall and the spring were really rendered
}

TEST(HapticLoop, SameInputsGiveBitIdenticalOutputs) {
  Rig a{SimulatedDeviceConfig{}};
  Rig b{SimulatedDeviceConfig{}};
  a.loop.Publish(MakeDemoScene());
  b.loop.Publish(MakeDemoScene());
  for (int k = 0; k < 1500; ++k) {
    const GripPose pose = MovingPose(0.04, k);
    const TickOutputs oa = a.Tick(pose);
    const TickOutputs ob = b.Tick(pose);
    ASSERT_EQ(std::memcmp(oa.tau.data(), ob.tau.data(), sizeof(double) * 8), 0) << "tick " << k;
    ASSERT_EQ(std::memcmp(oa.wrench_D.data(), ob.wrench_D.data(), sizeof(double) * 7), 0);
    ASSERT_EQ(oa.events, ob.events);
  }
}

TEST(HapticLoop, DisplaysTheSpringForceOnTheTrueGripAfterTheRamp) {
  LoopSettings settings = TestSettings();
  settings.ramp_time = 0.1;
  Rig rig{SimulatedDeviceConfig::Ideal(), settings};
  const Eigen::Vector3d anchor(0.02, -0.01, 0.03);
  const double k_spring = 40.0;
  rig.loop.Publish(SceneWith(std::make_unique<SpringField>(anchor, k_spring, 0.0)));
  const GripPose pose = At(Eigen::Vector3d(-0.03, 0.04, -0.02));
  for (int k = 0; k < 300; ++k) rig.Tick(pose);  // ramp done, motors settled
  const TickOutputs out = rig.Tick(pose);
  EXPECT_EQ(out.ramp, 1.0);
  EXPECT_FALSE(IsZeroForceEvent(out.events));
  const Eigen::Vector3d expected = -k_spring * (pose.p0 - anchor);  // 2.9 N
  const Eigen::Vector3d felt = rig.device.TrueWrench().head<3>();
  EXPECT_LT((felt - expected).norm(), 0.02 + 0.01 * expected.norm()) << felt.transpose();
  EXPECT_LT(rig.device.TrueWrench().segment<3>(3).norm(), 2e-3);  // no moment asked
}

TEST(HapticLoop, WallPushesOutOnlyWhenPenetrated) {
  LoopSettings settings = TestSettings();
  settings.ramp_time = 0.0;
  Rig rig{SimulatedDeviceConfig::Ideal(), settings};
  rig.loop.Publish(SceneWith(std::make_unique<PlaneWallField>(
      Eigen::Vector3d(0, 0, -0.03), Eigen::Vector3d(0, 0, 2.0), 1000.0, 0.0)));
  const GripPose outside = At(Eigen::Vector3d(0.01, 0.0, -0.025));
  for (int k = 0; k < 30; ++k) rig.Tick(outside);
  EXPECT_LT(rig.Tick(outside).wrench_D.norm(), 1e-9);
  const GripPose inside = At(Eigen::Vector3d(0.01, 0.0, -0.034));  // 4 mm in
  for (int k = 0; k < 30; ++k) rig.Tick(inside);
  const TickOutputs out = rig.Tick(inside);
  EXPECT_NEAR(out.wrench_D(2), 4.0, 0.05);  // 1000 N/m × 4 mm (± a count of quantisation)
  EXPECT_NEAR(out.wrench_D.head<2>().norm(), 0.0, 1e-9);
  EXPECT_NEAR(rig.device.TrueWrench()(2), 4.0, 0.08);
}

TEST(HapticLoop, TensionBoundsAndWrenchLimitAlwaysHold) {
  LoopSettings settings = TestSettings();
  settings.ramp_time = 0.0;
  settings.max_force = 6.0;
  Rig rig{SimulatedDeviceConfig{}, settings};
  // A spring so stiff that every pose asks for far more than the limit.
  rig.loop.Publish(
      SceneWith(std::make_unique<SpringField>(Eigen::Vector3d(0.2, 0.2, 0.2), 1e4, 0)));
  const double tau_min = settings.tension.tau_min, tau_max = settings.tension.tau_max;
  int limited = 0;
  for (int k = 0; k < 1000; ++k) {
    const TickOutputs out = rig.Tick(MovingPose(0.04, 7 * k));
    ASSERT_TRUE(((out.tau.array() >= tau_min) && (out.tau.array() <= tau_max)).all()) << k;
    ASSERT_LE(out.wrench_D.head<3>().norm(), 6.0 + 1e-9);
    ASSERT_LE(out.wrench_D.segment<3>(3).norm(), settings.max_moment + 1e-12);
    limited += (out.events & kEventWrenchLimited) != 0;
  }
  EXPECT_GT(limited, 900);
}

TEST(HapticLoop, RampsForceLinearlyWhenForcesSwitchOn) {
  LoopSettings settings = TestSettings();
  settings.ramp_time = 0.2;
  Rig rig{SimulatedDeviceConfig::Ideal(), settings};
  const Eigen::Vector3d anchor(0.0, 0.0, 0.0);
  rig.loop.Publish(SceneWith(std::make_unique<SpringField>(anchor, 50.0, 0.0)));
  const GripPose pose = At(Eigen::Vector3d(0.04, 0.0, 0.0));
  for (int k = 1; k <= 300; ++k) {
    const TickOutputs out = rig.Tick(pose);
    const double ramp = std::min(1.0, k * 1e-3 / 0.2);
    const Eigen::Vector3d full = -50.0 * (out.pose_D.p0 - anchor);
    ASSERT_NEAR(out.ramp, ramp, 1e-9) << k;
    ASSERT_LT((out.wrench_D.head<3>() - ramp * full).norm(), 1e-9) << k;
    ASSERT_EQ((out.events & kEventRamping) != 0, ramp < 1.0 - 1e-12) << k;
  }
}

// Runs `rig` past its ramp, then applies `fault` for one tick and checks zero force.
void ExpectZeroForceOn(Rig* rig, std::uint32_t event,
                       const std::function<TickOutputs(Rig*)>& faulty_tick) {
  const GripPose pose = At(Eigen::Vector3d(0.03, 0.0, 0.0));
  for (int k = 0; k < 600; ++k) rig->Tick(pose);
  const TickOutputs before = rig->Tick(pose);
  ASSERT_GT(before.wrench_D.norm(), 1.0);
  const TickOutputs out = faulty_tick(rig);
  EXPECT_TRUE(out.events & event) << out.events;
  EXPECT_TRUE(AllEqual(out.tau, rig->loop.settings().tension.tau_min));
  EXPECT_EQ(out.wrench_D.norm(), 0.0);
  // Recovery goes through the ramp from zero.
  const TickOutputs next = rig->Tick(pose);
  EXPECT_FALSE(IsZeroForceEvent(next.events));
  EXPECT_NEAR(next.ramp, 1e-3 / rig->loop.settings().ramp_time, 1e-12);
}

Rig* SpringRig() {
  auto* rig = new Rig{SimulatedDeviceConfig::Ideal()};
  rig->loop.Publish(SceneWith(std::make_unique<SpringField>(Eigen::Vector3d::Zero(), 100.0, 0)));
  return rig;
}

TEST(HapticLoop, ZeroForceOnDeviceError) {
  std::unique_ptr<Rig> rig(SpringRig());
  ExpectZeroForceOn(rig.get(), kEventDeviceError, [](Rig* r) {
    TickInputs in;
    r->device.Read(&in.reading);
    in.reading.status = DeviceStatus::kCommError;
    return r->loop.Step(in, 1e-3);
  });
}

TEST(HapticLoop, ZeroForceOnAMissedDeadlineBeyondTheThreshold) {
  std::unique_ptr<Rig> rig(SpringRig());
  // Below the threshold: forces stay on.
  const TickOutputs late = rig->Tick(At(Eigen::Vector3d(0.03, 0, 0)), 1e-3, 2e-3);
  EXPECT_FALSE(late.events & kEventDeadlineMissed);
  ExpectZeroForceOn(rig.get(), kEventDeadlineMissed,
                    [](Rig* r) { return r->Tick(At(Eigen::Vector3d(0.03, 0, 0)), 1e-3, 4e-3); });
}

TEST(HapticLoop, ZeroForceWhenForwardKinematicsRefuses) {
  std::unique_ptr<Rig> rig(SpringRig());
  ExpectZeroForceOn(rig.get(), kEventFkRefused, [](Rig* r) {
    TickInputs in;
    r->device.Read(&in.reading);
    in.reading.counts[3] += 4000;  // one string 10 cm longer: no pose fits
    return r->loop.Step(in, 1e-3);
  });
}

TEST(HapticLoop, ZeroForceOnNanFromAField) {
  Rig rig{SimulatedDeviceConfig::Ideal()};
  auto scene = std::make_unique<HapticScene>();
  scene->Add(std::make_unique<SpringField>(Eigen::Vector3d::Zero(), 100.0, 0));
  rig.loop.Publish(std::move(scene));
  ExpectZeroForceOn(&rig, kEventNan, [](Rig* r) {
    r->loop.Publish(SceneWith(std::make_unique<NanField>()));
    const TickOutputs out = r->Tick(At(Eigen::Vector3d(0.03, 0, 0)));
    r->loop.Publish(SceneWith(std::make_unique<SpringField>(Eigen::Vector3d::Zero(), 100.0, 0)));
    return out;
  });
}

TEST(HapticLoop, ZeroForceOnABadTimeStep) {
  std::unique_ptr<Rig> rig(SpringRig());
  ExpectZeroForceOn(rig.get(), kEventBadDt, [](Rig* r) {
    return r->Tick(At(Eigen::Vector3d(0.03, 0, 0)), std::numeric_limits<double>::quiet_NaN());
  });
}

TEST(HapticLoop, EmergencyStopLatchesUntilCleared) {
  std::unique_ptr<Rig> rig(SpringRig());
  const GripPose pose = At(Eigen::Vector3d(0.03, 0, 0));
  ExpectZeroForceOn(rig.get(), kEventEmergencyStop, [&](Rig* r) {
    r->loop.RequestEmergencyStop();
    for (int k = 0; k < 50; ++k) {
      const TickOutputs out = r->Tick(pose);
      EXPECT_TRUE(AllEqual(out.tau, r->loop.settings().tension.tau_min));
    }
    const TickOutputs out = r->Tick(pose);
    r->loop.ClearEmergencyStop();
    return out;
  });
  // The per-tick input flag works too.
  TickInputs in;
  rig->device.Read(&in.reading);
  in.emergency_stop = true;
  EXPECT_TRUE(rig->loop.Step(in, 1e-3).events & kEventEmergencyStop);
  EXPECT_GE(rig->loop.event_counts()[4], 52u);
}

TEST(HapticLoop, PassivityObserverRemovesTheEnergyAnActiveFieldCreates) {
  // The grip moves at constant velocity; an active field pushes along the motion. The energy
  // the scene gives the user, Σ f·v dt with v the TRUE velocity, grows without the observer
  // and stays near zero with it.
  auto run = [](bool observer) {
    LoopSettings settings = TestSettings();
    settings.passivity_observer = observer;
    settings.ramp_time = 0.0;
    Rig rig{SimulatedDeviceConfig::Ideal(), settings};
    rig.loop.Publish(SceneWith(std::make_unique<ActiveField>(20.0)));
    const Eigen::Vector3d v(0.05, -0.02, 0.03);
    double given = 0.0;
    for (int k = 0; k < 1000; ++k) {
      const TickOutputs out = rig.Tick(At(Eigen::Vector3d(-0.05, 0.02, -0.03) + 1e-3 * k * v));
      given += out.wrench_D.head<3>().dot(v) * 1e-3;
    }
    return given;
  };
  const double without = run(false);
  const double with = run(true);
  EXPECT_GT(without, 0.03);  // 20 N·s/m × (0.062 m/s)² × 1 s ≈ 0.077 J
  EXPECT_LT(with, 0.1 * without);
}

TEST(HapticLoop, OldScenesAreFreedOffTheHapticThread) {
  g_destroyed = 0;
  g_destroyed_on_haptic_thread = false;
  auto rig = std::make_unique<Rig>(SimulatedDeviceConfig::Ideal());
  const GripPose pose = At(Eigen::Vector3d(0.01, 0, 0));
  std::vector<TickInputs> inputs(4000);
  for (auto& in : inputs) {
    rig->device.SetTruePose(pose);
    rig->device.Step(1e-3);
    rig->device.Read(&in.reading);
  }
  std::atomic<bool> done{false};
  std::thread haptic([&] {
    t_is_haptic_thread = true;
    for (const auto& in : inputs) rig->loop.Step(in, 1e-3);
    done = true;
  });
  int published = 0;
  while (!done.load()) {
    rig->loop.Publish(SceneWith(std::make_unique<TracedField>()));
    ++published;
    std::this_thread::yield();
  }
  haptic.join();
  rig->loop.CollectRetired();
  rig.reset();  // frees the active and pending scenes
  EXPECT_EQ(g_destroyed.load(), published);
  EXPECT_FALSE(g_destroyed_on_haptic_thread.load());
}

TEST(HapticLoop, SceneIsTakenAtTheNextTickAndTheOldOneRetired) {
  g_destroyed = 0;
  Rig rig{SimulatedDeviceConfig::Ideal()};
  const GripPose pose = At(Eigen::Vector3d(0.01, 0, 0));
  rig.loop.Publish(SceneWith(std::make_unique<TracedField>()));
  rig.Tick(pose);
  EXPECT_FALSE(rig.loop.CollectRetired());  // nothing was active before (retired null)
  rig.loop.Publish(SceneWith(std::make_unique<SpringField>(Eigen::Vector3d::Zero(), 10, 0)));
  EXPECT_EQ(g_destroyed.load(), 0);
  rig.Tick(pose);
  EXPECT_EQ(g_destroyed.load(), 0);  // retired, not freed by the tick
  EXPECT_TRUE(rig.loop.CollectRetired());
  EXPECT_EQ(g_destroyed.load(), 1);
}

TEST(HapticLoop, PublishesTheLatestToolState) {
  Rig rig{SimulatedDeviceConfig::Ideal()};
  TickOutputs last;
  for (int k = 0; k < 5; ++k) last = rig.Tick(At(Eigen::Vector3d(0.01 * k, 0, 0)));
  const ToolState& state = rig.loop.LatestToolState();
  EXPECT_EQ(state.tick, 4u);
  EXPECT_NEAR(state.pose_D.p0.x(), 0.04, 1e-4);
  EXPECT_EQ(state.tau, last.tau);
}

TEST(HapticLoop, MapsTheToolIntoTheWorldWithScaleAndOffset) {
  LoopSettings settings = TestSettings();
  settings.X_WD.world_scale = 10.0;
  settings.X_WD.p_WDo = Eigen::Vector3d(1.0, 2.0, 3.0);
  settings.force_scale = 0.5;
  settings.ramp_time = 0.0;
  Rig rig{SimulatedDeviceConfig::Ideal(), settings};
  // Spring in W toward the world image of device point (0.01, 0, 0): (1.1, 2, 3).
  rig.loop.Publish(
      SceneWith(std::make_unique<SpringField>(Eigen::Vector3d(1.1, 2.0, 3.0), 10.0, 0)));
  const GripPose pose = At(Eigen::Vector3d(0.03, 0.01, 0.0));
  TickOutputs out;
  for (int k = 0; k < 20; ++k) out = rig.Tick(pose);
  EXPECT_LT((out.tool_W.p_WT - Eigen::Vector3d(1.3, 2.1, 3.0)).norm(), 1e-3);
  // f_W = −10 (0.2, 0.1, 0) N; displayed in D × 0.5.
  EXPECT_LT((out.wrench_D.head<3>() - Eigen::Vector3d(-1.0, -0.5, 0.0)).norm(), 5e-3);
}

}  // namespace
}  // namespace spidarcad::haptics
