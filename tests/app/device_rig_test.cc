// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
// Tests of the device rigs (runtime/device_rig.h) and of the window's haptic runtime on them
// (--device board-sim and usb): tracking on a virtual clock checked against the board's true
// pose and the closed-form rest point of the hand, zero force on unplug and the reconnect,
// the off-tick re-open of a real board's link, allocation-free ticks, and the window's
// --device runs.
#include "scene/device_rig.h"

#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <memory>
#include <numbers>
#include <string>
#include <thread>

#include "doc/input_error.h"
#include "scene/calibration_file.h"
#include "scene/haptic_runtime.h"
#include "scene/scene_fields.h"
#include "spidarcad/haptics/board_simulator.h"
#include "spidarcad/haptics/kinematics.h"
#include "spidarcad/haptics/simulated_device.h"
#include "spidarcad_runner.h"
#include "support/malloc_counter.h"
#include "support/scoped_env.h"
#include "window_test_support.h"

namespace spidarcad::app {
namespace {

using haptics::DeviceStatus;
using haptics::GripPose;
using haptics::SpidarGeometry;
using window_test::RunTicks;
using window_test::SpringScene;
constexpr double kPi = std::numbers::pi;

DemoFieldSettings TranslationSprings(double k) {
  DemoFieldSettings field;
  field.k_translation = k;
  field.k_rotation = 0.0;
  field.k_grasp = 0.0;
  return field;
}

GripPose At(const Eigen::Vector3d& p) {
  return GripPose::FromFrame(p, Eigen::Matrix3d::Identity(), kPi / 2, SpidarGeometry{}.d);
}

TEST(DeviceRig, ParsesTheDeviceNamesOfRun) {
  RigKind kind = RigKind::kUsb;
  EXPECT_TRUE(ParseRigKind("simulated", &kind));
  EXPECT_EQ(kind, RigKind::kSimulated);
  EXPECT_TRUE(ParseRigKind("board-sim", &kind));
  EXPECT_EQ(kind, RigKind::kBoardSim);
  EXPECT_TRUE(ParseRigKind("usb", &kind));
  EXPECT_EQ(kind, RigKind::kUsb);
  EXPECT_FALSE(ParseRigKind("ideal", &kind));  // the window's, not run's
  EXPECT_FALSE(ParseRigKind("USB", &kind));
  RuntimeDevice device = RuntimeDevice::kSimulated;
  for (const char* name : {"simulated", "ideal", "board-sim", "usb"}) {
    ASSERT_TRUE(ParseRuntimeDevice(name, &device)) << name;
    EXPECT_EQ(std::string(RuntimeDeviceName(device)), name);
  }
  EXPECT_FALSE(ParseRuntimeDevice("board_sim", &device));
  // The existing numbers stay.
  EXPECT_EQ(static_cast<int>(RuntimeDevice::kSimulated), 0);
  EXPECT_EQ(static_cast<int>(RuntimeDevice::kIdeal), 1);
}

// A rig that only counts Service calls (the interval is its setting).
class ServiceCountingRig final : public DeviceRig {
 public:
  explicit ServiceCountingRig(double interval) : interval_(interval) {}
  const haptics::DeviceInfo& info() const override { return info_; }
  haptics::SimulatedSpidarG* physical() override { return nullptr; }
  bool Start(const haptics::GripPose&) override { return true; }
  void Read(double, haptics::EncoderReading*) noexcept override {}
  void Write(const haptics::Vector8d&) noexcept override {}
  bool Service() override {
    calls.fetch_add(1);
    return true;
  }
  double service_interval() const override { return interval_; }
  std::string Describe() const override { return "counting"; }
  std::atomic<int> calls{0};

 private:
  double interval_;
  haptics::DeviceInfo info_;
};

// run --device usb and the window re-open a lost board from this thread: it calls Service
// repeatedly while it lives, never when the rig needs no service, and stops when destroyed.
TEST(DeviceRig, ServiceThreadServicesTheRigUntilItIsDestroyed) {
  ServiceCountingRig rig(0.02);
  {
    const RigServiceThread service(&rig);
    const auto give_up = std::chrono::steady_clock::now() + std::chrono::seconds(10);
    while (rig.calls.load() < 3 && std::chrono::steady_clock::now() < give_up)
      std::this_thread::sleep_for(std::chrono::milliseconds(5));
    EXPECT_GE(rig.calls.load(), 3);
  }
  const int after = rig.calls.load();
  std::this_thread::sleep_for(std::chrono::milliseconds(100));
  EXPECT_EQ(rig.calls.load(), after) << "Service called after the thread was destroyed";
  ServiceCountingRig idle(0.0);
  {
    const RigServiceThread service(&idle);
    std::this_thread::sleep_for(std::chrono::milliseconds(100));
  }
  EXPECT_EQ(idle.calls.load(), 0);
}

// A lab's board that was not plugged in when the window started: once the link is re-opened off
// the tick, the rig (and so the calibration wizard, through HapticRuntime::serial) knows which
// board it is, without a restart.
TEST(DeviceRig, UsbBoardPluggedInAfterStartUpGivesItsSerialNumber) {
  haptics::usb::BoardConfig config;
  config.serial = {'L', 'A', 'B', '-', '4', '2'};
  haptics::usb::BoardSimulator board(config);
  haptics::usb::LoopbackTransport* cable = nullptr;
  RigOptions options;
  options.reconnect_off_tick = true;
  options.make_transport = [&board, &cable] {
    auto transport = std::make_unique<haptics::usb::LoopbackTransport>(&board);
    transport->SetPlugged(false);
    cable = transport.get();
    return transport;
  };
  std::unique_ptr<DeviceRig> rig = MakeDeviceRig(RigKind::kUsb, options);
  ASSERT_NE(cable, nullptr);
  EXPECT_FALSE(rig->Start(At(Eigen::Vector3d::Zero())));
  EXPECT_EQ(rig->Serial(), "");
  haptics::EncoderReading reading;
  rig->Read(1e-3, &reading);    // the tick hands the closed link to Service
  EXPECT_TRUE(rig->Service());  // which tries: still unplugged
  EXPECT_EQ(rig->Serial(), "");
  cable->SetPlugged(true);
  rig->Read(1e-3, &reading);
  EXPECT_TRUE(rig->Service());
  EXPECT_EQ(rig->Serial(), "LAB-42");
  rig->Read(1e-3, &reading);  // the tick has the link back
  RigLink link;
  rig->Link(&link);
  EXPECT_NE(link.status, DeviceStatus::kNotConnected);
}

TEST(DeviceRig, SimulatedRigReadsExactlyWhatTheDeviceItWrapsReads) {
  // Independent reference: a SimulatedSpidarG of the same configuration, stepped by hand.
  RigOptions options;
  options.device.seed = 5;
  std::unique_ptr<DeviceRig> rig = MakeDeviceRig(RigKind::kSimulated, options);
  haptics::SimulatedSpidarG reference(options.device);
  ASSERT_NE(rig->physical(), nullptr);
  EXPECT_TRUE(rig->Start(GripPose::Rest(0.04)));
  const GripPose pose = At({0.02, -0.01, 0.03});
  const haptics::Vector8d tau = haptics::Vector8d::Constant(1.5);
  for (int k = 0; k < 50; ++k) {
    rig->physical()->SetTruePose(pose);
    reference.SetTruePose(pose);
    haptics::EncoderReading a, b;
    rig->Read(1e-3, &a);
    reference.Step(1e-3);
    reference.Read(&b);
    ASSERT_EQ(a.counts, b.counts) << k;
    ASSERT_EQ(a.sequence, b.sequence) << k;
    rig->Write(tau);
    reference.WriteTensions(tau);
  }
  RigLink link;
  rig->Link(&link);
  EXPECT_FALSE(link.has_driver);
  EXPECT_EQ(DescribeLink(link), "");
  EXPECT_EQ(rig->Describe(), "simulated (seed 5)");
}

// kBoardSim on a virtual clock: the hand (300 N/m toward the target) and a 150 N/m centring
// spring balance at p = k_h p_t / (k_h + k) (closed form); the loop measures the board's true
// grip pose through the driver, the board's packets and the nominal calibration.
TEST(HapticRuntimeBoardSim, TracksTheBoardsTruePoseAndSettlesAtTheClosedFormRestPoint) {
  RuntimeSettings settings;
  settings.device = RuntimeDevice::kBoardSim;
  HapticRuntime runtime(settings, GripPose::Rest(0.04));
  EXPECT_EQ(runtime.link_at_start(), "");
  ASSERT_NE(runtime.physical_device(), nullptr);
  const DemoFieldSettings field = TranslationSprings(150.0);
  runtime.Publish(SpringScene(field));
  const Eigen::Vector3d p_target(0.05, 0.03, -0.04);
  runtime.SetTarget(At(p_target));
  // Nominal calibration of a device with 6.2 ± 1.5 % encoder gain error (no line fit, as
  // `run --device board-sim`): the measured displacement from the homing pose is off by up to
  // ~10 % of it, plus quantisation and noise. Bound: 0.1 |p − p_home| + 0.5 mm.
  const Eigen::Vector3d p_home = runtime.info().home_pose.p0;
  double worst = 0.0;  // largest |measured − true| / bound over the run after the first ticks
  for (int k = 0; k < 3000; ++k) {
    RunTicks(&runtime, 1);
    const RuntimeFrame& f = runtime.Latest();
    // The frame's hand pose is the board device's true pose (what the hand holds).
    ASSERT_LT((f.hand_pose.p0 - runtime.physical_device()->true_pose().p0).norm(), 1e-12);
    if (k >= 2) {
      ASSERT_EQ(f.tool.fk_status, haptics::FkStatus::kOk) << "tick " << k;
      ASSERT_EQ(f.tool.events & haptics::kEventDeviceError, 0u) << "tick " << k;
      const double bound = 0.1 * (f.hand_pose.p0 - p_home).norm() + 5e-4;
      worst = std::max(worst, (f.tool.pose_D.p0 - f.hand_pose.p0).norm() / bound);
    }
  }
  const RuntimeFrame& f = runtime.Latest();
  EXPECT_LT(worst, 1.0) << "worst |measured − true grip centre| / bound";
  const double kh = settings.hand.stiffness, k = field.k_translation;
  const Eigen::Vector3d expected = kh * p_target / (kh + k);
  EXPECT_LT((f.hand_pose.p0 - expected).norm(), 2e-3)
      << f.hand_pose.p0.transpose() << " vs " << expected.transpose();
  EXPECT_GT((f.hand_pose.p0 - p_target).norm(), 0.01);  // really pushed back through the board
  EXPECT_EQ(f.link.status, DeviceStatus::kOk);
  EXPECT_TRUE(f.link.has_driver);
  EXPECT_GE(f.link.stats.states, 2999u);
  EXPECT_EQ(f.link.stats.connects, 1u);
  EXPECT_NE(runtime.description().find("board-sim"), std::string::npos) << runtime.description();
  EXPECT_EQ(DescribeLink(f.link).rfind("ok: states ", 0), 0u) << DescribeLink(f.link);
}

// The same scene and target on kSimulated (line-fit calibration) and kBoardSim (nominal, over
// the driver): the hands come to rest within millimetres of each other.
TEST(HapticRuntimeBoardSim, RestsWhereTheSimulatedDeviceRests) {
  Eigen::Vector3d rest[2];
  const RuntimeDevice devices[2] = {RuntimeDevice::kSimulated, RuntimeDevice::kBoardSim};
  for (int i = 0; i < 2; ++i) {
    RuntimeSettings settings;
    settings.device = devices[i];
    HapticRuntime runtime(settings, GripPose::Rest(0.04));
    runtime.Publish(SpringScene(TranslationSprings(200.0)));
    runtime.SetTarget(At({-0.06, 0.04, 0.05}));
    RunTicks(&runtime, 3000);
    rest[i] = runtime.Latest().hand_pose.p0;
  }
  EXPECT_LT((rest[0] - rest[1]).norm(), 2e-3)
      << rest[0].transpose() << " vs " << rest[1].transpose();
}

TEST(HapticRuntimeBoardSim, UnplugGivesZeroForceWithinATickAndReplugBringsTheLinkBack) {
  RuntimeSettings settings;
  settings.device = RuntimeDevice::kBoardSim;
  HapticRuntime runtime(settings, GripPose::Rest(0.04));
  runtime.Publish(SpringScene(DemoFieldSettings{}));
  runtime.SetTarget(At({0.06, 0.0, 0.0}));
  RunTicks(&runtime, 800);  // past the 0.5 s force ramp
  ASSERT_GT(runtime.Latest().tool.wrench_D.head<3>().norm(), 3.0);
  ASSERT_GT(runtime.physical_device()->TrueWrench().head<3>().norm(), 2.0);

  runtime.RequestBoardPlugged(false);
  for (int k = 0; k < 400; ++k) {
    RunTicks(&runtime, 1);
    const RuntimeFrame& f = runtime.Latest();
    // The unplug is seen at the first tick: device error, zero force commanded.
    ASSERT_TRUE(f.tool.events & haptics::kEventDeviceError) << "tick " << k;
    ASSERT_EQ(f.tool.wrench_D, haptics::Vector7d::Zero()) << "tick " << k;
    ASSERT_EQ(f.link.status, DeviceStatus::kNotConnected) << "tick " << k;
    ASSERT_FALSE(f.link.plugged);
    // Physically: the board is unpowered; the motors (2 ms lag) let go within a few ticks.
    if (k >= 15) {
      ASSERT_LT(runtime.physical_device()->TrueWrench().norm(), 0.02) << "tick " << k;
    }
  }
  const std::string down = DescribeLink(runtime.Latest().link);
  EXPECT_EQ(down.rfind("not connected — retrying; run `spidarcad device list`, udev rules "
                       "assets/udev/99-spidarcad.rules",
                       0),
            0u)
      << down;

  runtime.RequestBoardPlugged(true);
  int back = -1;
  const int reconnect = settings.usb.reconnect_every;
  for (int k = 0; k < reconnect + 50 && back < 0; ++k) {
    RunTicks(&runtime, 1);
    if (runtime.Latest().link.status == DeviceStatus::kOk) back = k;
  }
  ASSERT_GE(back, 0) << "no reconnect within " << reconnect + 50 << " ticks";
  EXPECT_LE(back, reconnect + 5);
  EXPECT_EQ(runtime.Latest().link.stats.connects, 2u);
  EXPECT_GE(runtime.Latest().link.stats.disconnects, 1u);
  // Force comes back through the ramp.
  RunTicks(&runtime, 800);
  EXPECT_EQ(runtime.Latest().tool.ramp, 1.0);
  EXPECT_GT(runtime.Latest().tool.wrench_D.head<3>().norm(), 3.0);
  EXPECT_GT(runtime.physical_device()->TrueWrench().head<3>().norm(), 2.0);
}

TEST(HapticRuntimeBoardSim, TicksAllocateNothingThroughAnUnplugAndReconnect) {
  ASSERT_TRUE(test_support::MallocCounterActive());
  RuntimeSettings settings;
  settings.device = RuntimeDevice::kBoardSim;
  settings.usb.reconnect_every = 50;
  HapticRuntime runtime(settings, GripPose::Rest(0.04));
  runtime.Publish(SpringScene(DemoFieldSettings{}));
  runtime.SetTarget(At({0.05, -0.03, 0.02}));
  RunTicks(&runtime, 300);
  long allocations = 0;
  {
    test_support::MallocCounter counter;
    RunTicks(&runtime, 500);
    runtime.RequestBoardPlugged(false);
    RunTicks(&runtime, 200);
    runtime.RequestBoardPlugged(true);
    RunTicks(&runtime, 300);
    allocations = counter.count();
  }
  EXPECT_EQ(allocations, 0);
  EXPECT_EQ(runtime.Latest().link.status, DeviceStatus::kOk);
  EXPECT_EQ(runtime.Latest().link.stats.connects, 2u);
}

// kUsb over a test transport (the loopback to a board simulator that nobody's simulated hand
// holds: the test moves the grip, as a user would).
struct UsbBench {
  haptics::usb::BoardSimulator board;
  haptics::usb::LoopbackTransport* link = nullptr;  // owned by the runtime's driver
  std::unique_ptr<HapticRuntime> runtime;

  explicit UsbBench(bool plugged) {
    RuntimeSettings settings;
    settings.device = RuntimeDevice::kUsb;
    settings.usb_transport = [this, plugged] {
      auto transport = std::make_unique<haptics::usb::LoopbackTransport>(&board);
      transport->SetPlugged(plugged);
      link = transport.get();
      return transport;
    };
    runtime = std::make_unique<HapticRuntime>(settings, GripPose::Rest(0.04));
  }
};

TEST(HapticRuntimeUsb, AbsentBoardRunsAtZeroForceAndIsReopenedOffTheTick) {
  UsbBench bench(/*plugged=*/false);
  HapticRuntime& runtime = *bench.runtime;
  EXPECT_EQ(runtime.physical_device(), nullptr);
  EXPECT_EQ(runtime.link_at_start().rfind("--device usb: no SPIDAR-G controller board could be "
                                          "opened",
                                          0),
            0u)
      << runtime.link_at_start();
  EXPECT_NE(runtime.link_at_start().find("spidarcad device list"), std::string::npos);
  runtime.Publish(SpringScene(DemoFieldSettings{}));
  runtime.SetTarget(At({0.08, 0.0, 0.0}));  // ignored: the user's hand holds the grip
  for (int k = 0; k < 300; ++k) {
    RunTicks(&runtime, 1);
    ASSERT_EQ(runtime.Latest().tool.wrench_D, haptics::Vector7d::Zero());
    ASSERT_TRUE(runtime.Latest().tool.events & haptics::kEventDeviceError);
    ASSERT_EQ(runtime.Latest().link.status, DeviceStatus::kNotConnected);
  }
  EXPECT_EQ(DescribeLink(runtime.Latest().link)
                .rfind("not connected — retrying; run `spidarcad device list`", 0),
            0u);
  // The tick never re-opens the board (the driver's in-tick reconnect is off): only Service.
  EXPECT_EQ(runtime.Latest().link.stats.connects, 0u);
  EXPECT_TRUE(runtime.ServiceDevice());  // still unplugged: tried, failed
  RunTicks(&runtime, 5);
  EXPECT_EQ(runtime.Latest().link.status, DeviceStatus::kNotConnected);

  // The user plugs the board in and holds the grip 4 cm off centre.
  bench.link->SetPlugged(true);
  const GripPose held = At({0.04, 0.0, 0.0});
  bench.board.device().SetTruePose(held);
  EXPECT_TRUE(runtime.ServiceDevice());
  EXPECT_FALSE(runtime.ServiceDevice());  // the link is the tick's again: nothing to do
  RunTicks(&runtime, 800);
  const RuntimeFrame& f = runtime.Latest();
  ASSERT_EQ(f.link.status, DeviceStatus::kOk) << DescribeLink(f.link);
  EXPECT_EQ(f.link.stats.connects, 1u);
  ASSERT_EQ(f.tool.fk_status, haptics::FkStatus::kOk);
  // The grip is where the board's encoders say (nominal calibration: within 10 % of the 4 cm
  // displacement plus 0.5 mm, as above), not at the mouse's target; the frame's hand pose is
  // the measured one.
  EXPECT_LT((f.tool.pose_D.p0 - held.p0).norm(), 0.1 * 0.04 + 5e-4) << f.tool.pose_D.p0.transpose();
  EXPECT_EQ(f.hand_pose.p0, f.tool.pose_D.p0);
  // The springs pull the hand back toward the centre (100 N/m · 4 cm = 4 N along −x).
  EXPECT_EQ(f.tool.ramp, 1.0);
  EXPECT_LT(f.tool.wrench_D.x(), -3.0);
  EXPECT_LT(bench.board.device().TrueWrench().x(), -2.5);

  // Unplug while running: zero force at once, the link goes to Service.
  bench.link->SetPlugged(false);
  RunTicks(&runtime, 1);
  EXPECT_EQ(runtime.Latest().tool.wrench_D, haptics::Vector7d::Zero());
  EXPECT_EQ(runtime.Latest().link.status, DeviceStatus::kNotConnected);
  EXPECT_EQ(runtime.Latest().link.stats.disconnects, 1u);
  bench.link->SetPlugged(true);
  EXPECT_TRUE(runtime.ServiceDevice());
  RunTicks(&runtime, 10);
  EXPECT_EQ(runtime.Latest().link.status, DeviceStatus::kOk);
  EXPECT_EQ(runtime.Latest().link.stats.connects, 2u);
}

TEST(HapticRuntimeUsb, TicksAllocateNothingConnectedOrNot) {
  ASSERT_TRUE(test_support::MallocCounterActive());
  UsbBench bench(/*plugged=*/true);
  HapticRuntime& runtime = *bench.runtime;
  ASSERT_EQ(runtime.link_at_start(), "");
  runtime.Publish(SpringScene(DemoFieldSettings{}));
  bench.board.device().SetTruePose(At({-0.03, 0.02, 0.01}));
  RunTicks(&runtime, 300);
  long allocations = 0;
  {
    test_support::MallocCounter counter;
    RunTicks(&runtime, 500);  // connected
    bench.link->SetPlugged(false);
    RunTicks(&runtime, 300);  // not connected: the link waits for Service
    allocations = counter.count();
  }
  EXPECT_EQ(allocations, 0);
  EXPECT_EQ(runtime.Latest().link.status, DeviceStatus::kNotConnected);
}

// The CI case: libusb and no board (maybe no /dev/bus/usb at all). Nothing aborts; the ticks
// leave libusb alone (allocation-free) and Service retries.
TEST(HapticRuntimeUsb, LibusbWithoutABoardKeepsRunningAndAllocatesNothingPerTick) {
  ASSERT_TRUE(test_support::MallocCounterActive());
  RuntimeSettings settings;
  settings.device = RuntimeDevice::kUsb;
  HapticRuntime runtime(settings, GripPose::Rest(0.04));
  if (runtime.link_at_start().empty()) GTEST_SKIP() << "a SPIDAR-G board is attached";
  runtime.Publish(SpringScene(DemoFieldSettings{}));
  RunTicks(&runtime, 10);
  long allocations = 0;
  {
    // The ticks run on this thread (RunTicks); other threads (libusb's event thread) may
    // allocate meanwhile, and under AddressSanitizer, whose hook sees every thread, allocations
    // were counted here (docs/sanitizers.md): only this thread's allocations count.
    test_support::MallocCounter counter(test_support::MallocCounter::Threads::kThisThread);
    RunTicks(&runtime, 500);
    allocations = counter.count();
  }
  EXPECT_EQ(allocations, 0);
  EXPECT_TRUE(runtime.ServiceDevice());
  RunTicks(&runtime, 5);
  EXPECT_EQ(runtime.Latest().link.status, DeviceStatus::kNotConnected);
  EXPECT_EQ(runtime.Latest().tool.wrench_D, haptics::Vector7d::Zero());
  EXPECT_NE(runtime.LinkSummary().find("final status not_connected"), std::string::npos)
      << runtime.LinkSummary();
}

// The usb runtime on its threads: the service thread retries while the loop runs.
TEST(HapticRuntimeUsb, ServiceThreadReopensTheBoardWhileTheLoopRuns) {
  UsbBench bench(/*plugged=*/false);
  HapticRuntime& runtime = *bench.runtime;
  // Plugged before Start: the service thread (every 0.2 s) must find it.
  bench.link->SetPlugged(true);
  runtime.Start();
  bool ok = false;
  for (int k = 0; k < 300 && !ok; ++k) {  // up to 3 s
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
    ok = runtime.Latest().link.status == DeviceStatus::kOk;
  }
  runtime.Stop();
  EXPECT_TRUE(ok) << DescribeLink(runtime.Latest().link);
}

// The window with --device board-sim and usb (Xvfb).
TEST(SpidarcadWindowDevice, BoardSimAndAbsentUsbBoardRunAndSayWhatTheLinkIs) {
  const char* display = std::getenv("DISPLAY");
  if (display == nullptr || display[0] == '\0') GTEST_SKIP() << "no X display";
  using test_support::RunSpidarcad;
  const test_support::CommandRun board =
      RunSpidarcad("none --device board-sim --frames 30", "", "board");
  EXPECT_EQ(board.status, 0) << board.all();
  EXPECT_NE(board.out.find("device link: ok: states "), std::string::npos) << board.all();
  const test_support::CommandRun usb = RunSpidarcad("none --device usb --frames 30", "", "usb");
  EXPECT_EQ(usb.status, 0) << usb.all();
  EXPECT_NE(usb.out.find("device link: not connected — retrying; run `spidarcad device list`, "
                         "udev rules assets/udev/99-spidarcad.rules"),
            std::string::npos)
      << usb.all();
  EXPECT_NE(usb.err.find("--device usb: no SPIDAR-G controller board could be opened"),
            std::string::npos)
      << usb.all();
}

TEST(SpidarcadWindowDevice, RejectsAnUnknownDeviceNamingIt) {
  const test_support::CommandRun r =
      test_support::RunSpidarcad("--device bogus --frames 1", "", "bogus");
  EXPECT_EQ(r.status, 2) << r.all();
  EXPECT_NE(r.all().find("'bogus' is not a device; use simulated, ideal, board-sim or usb"),
            std::string::npos)
      << r.all();
}

// A calibration file for the device `runtime` drives: its nominal calibration with every
// string's offset moved by `shift` m, so that lengths read through it differ by exactly `shift`.
std::string ShiftedCalibrationFile(const HapticRuntime& runtime, const std::string& kind,
                                   const std::string& serial, double shift,
                                   const std::string& name) {
  CalibrationFile file;
  file.device.kind = kind;
  file.device.seed = runtime.settings().seed;
  file.device.serial = serial;
  file.device.geometry = runtime.info().geometry;
  file.device.encoder = runtime.info().encoder;
  file.date = "2026-12-02T04:00:00Z";
  file.method = "self";
  file.calibration = NominalCalibration(runtime.info());
  for (auto& string : file.calibration.strings) string.offset += shift;
  file.fit.samples = 50;
  const std::string path = std::string(SPIDARCAD_TEST_OUTPUT_DIR) + "/runtime_cal_" + name;
  SaveCalibrationFile(file, path);
  return path;
}

std::string StartError(const RuntimeSettings& settings) {
  try {
    HapticRuntime runtime(settings, GripPose::Rest(0.04));
  } catch (const InputError& e) {
    return e.what();
  }
  return "";
}

TEST(HapticRuntimeCalibration, TheEncodersAreReadThroughTheCalibrationFile) {
  RuntimeSettings settings;
  settings.device = RuntimeDevice::kBoardSim;  // nominal calibration without a file
  HapticRuntime nominal(settings, GripPose::Rest(0.04));
  const double shift = 0.005;
  settings.calibration_file = ShiftedCalibrationFile(nominal, "board-sim", "", shift, "shift.json");
  HapticRuntime calibrated(settings, GripPose::Rest(0.04));
  EXPECT_NE(calibrated.description().find(settings.calibration_file), std::string::npos)
      << calibrated.description();
  // Same seed, same virtual ticks: the same counts, read 5 mm longer on every string.
  RunTicks(&nominal, 1);
  RunTicks(&calibrated, 1);
  const haptics::Vector8d difference = calibrated.Latest().lengths - nominal.Latest().lengths;
  for (int i = 0; i < haptics::kNumStrings; ++i) EXPECT_NEAR(difference(i), shift, 1e-12) << i;
}

TEST(HapticRuntimeCalibration, AForeignOrUnreadableFileIsRefusedWithTheReason) {
  RuntimeSettings settings;
  settings.device = RuntimeDevice::kSimulated;
  settings.seed = 1;
  RuntimeSettings probe = settings;
  probe.device = RuntimeDevice::kBoardSim;
  const HapticRuntime reference(probe, GripPose::Rest(0.04));
  const std::string path = ShiftedCalibrationFile(reference, "simulated", "", 0.0, "seed1.json");
  settings.seed = 3;  // the file was made on seed 1
  settings.calibration_file = path;
  const std::string foreign = StartError(settings);
  EXPECT_NE(foreign.find("--calibration: " + path + " does not fit"), std::string::npos) << foreign;
  EXPECT_NE(foreign.find("seed 1"), std::string::npos) << foreign;
  settings.seed = 1;
  settings.geometry.a = 0.30;  // another frame
  EXPECT_NE(StartError(settings).find("--frame 0.3,0.24,0.24"), std::string::npos);
  settings.geometry = SpidarGeometry{};
  settings.calibration_file = path + ".missing";
  EXPECT_NE(StartError(settings).find("--calibration: "), std::string::npos);
  settings.calibration_file = path;
  settings.device = RuntimeDevice::kIdeal;
  EXPECT_NE(StartError(settings).find("not with --device ideal"), std::string::npos);
}

// kUsb over the loopback to a board simulator (serial SIM-0001), with a private device memory.
std::unique_ptr<HapticRuntime> UsbRuntime(haptics::usb::BoardSimulator* board,
                                          const std::string& calibration_file = "") {
  RuntimeSettings settings;
  settings.device = RuntimeDevice::kUsb;
  settings.calibration_file = calibration_file;
  settings.usb_transport = [board] {
    return std::make_unique<haptics::usb::LoopbackTransport>(board);
  };
  return std::make_unique<HapticRuntime>(settings, GripPose::Rest(0.04));
}

TEST(HapticRuntimeCalibration, AUsbBoardIsReadThroughTheCalibrationRememberedForItsSerial) {
  const std::string config = std::string(SPIDARCAD_TEST_OUTPUT_DIR) + "/runtime_cal_xdg";
  std::filesystem::remove_all(config);
  const test_support::ScopedEnv xdg("XDG_CONFIG_HOME", config.c_str());
  haptics::usb::BoardSimulator board;
  const auto plain = UsbRuntime(&board);
  ASSERT_EQ(plain->link_at_start(), "");
  EXPECT_EQ(plain->calibration_note(), "");  // nothing remembered
  const std::string mine = ShiftedCalibrationFile(*plain, "usb", "SIM-0001", 0.002, "mine.json");
  const std::string other = ShiftedCalibrationFile(*plain, "usb", "SPG-0042", 0.002, "other.json");

  CalibrationDevice this_board;
  this_board.kind = "usb";
  this_board.serial = "SIM-0001";
  std::string why;
  ASSERT_TRUE(RememberCalibration(this_board, mine, &why)) << why;
  haptics::usb::BoardSimulator board2;
  const auto remembered = UsbRuntime(&board2);
  EXPECT_NE(remembered->description().find(mine + " (remembered for this board)"),
            std::string::npos)
      << remembered->description();
  EXPECT_EQ(remembered->calibration_note(), "");

  // Another board's file remembered under this serial (edited by hand): not used, and said why.
  ASSERT_TRUE(RememberCalibration(this_board, other, &why)) << why;
  haptics::usb::BoardSimulator board3;
  const auto stale = UsbRuntime(&board3);
  EXPECT_EQ(stale->description().find("remembered"), std::string::npos) << stale->description();
  EXPECT_NE(stale->calibration_note().find("serial SPG-0042"), std::string::npos)
      << stale->calibration_note();

  // An explicit file of another board is refused (not silently replaced by the memory).
  haptics::usb::BoardSimulator board4;
  try {
    UsbRuntime(&board4, other);
    ADD_FAILURE() << "another board's file was accepted";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("does not fit"), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace spidarcad::app
