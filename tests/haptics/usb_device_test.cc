// Tests of the USB driver (UsbSpidarG) through the board simulator and the loopback transport:
// a clean link, then each fault (loss, corruption, reordering, stalls, unplug, version
// mismatch, e-stop, the device-side watchdog), and libusb with no device attached.
// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#include "spidarcad/haptics/usb_device.h"

#include <gtest/gtest.h>

#include <memory>
#include <string>

#include "spidarcad/haptics/board_simulator.h"
#include "support/malloc_counter.h"

namespace spidarcad::haptics::usb {
namespace {

BoardConfig TestBoard() {
  BoardConfig config;
  config.device.seed = 7;
  return config;
}

// A driver wired to a simulated board through the loopback.
struct Rig {
  explicit Rig(const LinkFaults& faults = {}, const BoardConfig& board_config = TestBoard(),
               const UsbDeviceConfig& driver_config = {})
      : board(board_config) {
    auto transport = std::make_unique<LoopbackTransport>(&board, faults);
    link = transport.get();
    driver =
        std::make_unique<UsbSpidarG>(std::move(transport), board.device().info(), driver_config);
  }
  BoardSimulator board;
  LoopbackTransport* link = nullptr;
  std::unique_ptr<UsbSpidarG> driver;
};

Vector8d Tensions() {
  Vector8d t;
  t << 0.5, 1.0, 1.5, 2.0, 2.5, 3.0, 3.5, 4.0;
  return t;
}

// Runs `ticks` haptic ticks (Read then WriteTensions) and checks every reading the driver
// calls kOk against what the board really sent under that sequence. Returns the kOk count.
int RunAndCheck(Rig& rig, int ticks, const Vector8d& tension, int* mismatches) {
  int ok = 0;
  std::uint32_t last_sequence = 0;
  for (int i = 0; i < ticks; ++i) {
    EncoderReading reading;
    const DeviceStatus status = rig.driver->Read(&reading);
    EXPECT_EQ(status, reading.status);
    if (status == DeviceStatus::kOk) {
      ++ok;
      EncoderCounts sent{};
      if (!rig.board.SentCounts(reading.sequence, &sent) || sent != reading.counts) ++*mismatches;
      if (last_sequence != 0 && reading.sequence <= last_sequence) ++*mismatches;
      last_sequence = reading.sequence;
    }
    rig.driver->WriteTensions(tension);
  }
  return ok;
}

TEST(UsbSpidarG, CleanLinkDeliversEveryStateAndAppliesTensions) {
  Rig rig;
  ASSERT_EQ(rig.driver->Open(), DeviceStatus::kOk) << rig.driver->last_error();
  EXPECT_EQ(rig.driver->board_info().counts_per_rev, 2000);
  EXPECT_EQ(rig.driver->board_info().tension_max_mn, 8000);
  EXPECT_EQ(rig.board.watchdog_ms(), 20);
  int mismatches = 0;
  EXPECT_EQ(RunAndCheck(rig, 200, Tensions(), &mismatches), 200);
  EXPECT_EQ(mismatches, 0);
  EXPECT_EQ(rig.driver->stats().lost, 0u);
  EXPECT_EQ(rig.driver->stats().corrupt, 0u);
  EXPECT_TRUE(rig.board.motors_enabled());
  // The board applies the commanded tensions to the mN and the motors follow.
  for (int i = 0; i < kNumStrings; ++i) {
    EXPECT_DOUBLE_EQ(rig.board.applied_tensions()[i], Tensions()[i]);
    EXPECT_NEAR(rig.board.device().actual_tensions()[i], Tensions()[i], 1e-6);
  }
}

TEST(UsbSpidarG, ReadingsMatchTheDeviceAndFollowThePose) {
  Rig rig;
  ASSERT_EQ(rig.driver->Open(), DeviceStatus::kOk);
  EncoderReading first;
  rig.driver->Read(&first);
  rig.driver->Read(&first);
  ASSERT_EQ(first.status, DeviceStatus::kOk);
  // The driver reports exactly what the physical device measured.
  EncoderReading truth;
  rig.board.device().Read(&truth);
  EXPECT_EQ(first.counts, truth.counts);
  EXPECT_NEAR(first.time, rig.board.device().time(), 1e-9);
  // Move the grip 2 cm along x: counts change the way the device's own counters do.
  GripPose moved = rig.board.device().true_pose();
  moved.p0.x() += 0.02;
  moved.p1.x() += 0.02;
  moved.p2.x() += 0.02;
  rig.board.device().SetTruePose(moved);
  EncoderReading after;
  rig.driver->Read(&after);
  rig.board.device().Read(&truth);
  EXPECT_EQ(after.counts, truth.counts);
  EXPECT_NE(after.counts, first.counts);
}

TEST(UsbSpidarG, PacketLossIsCountedAndNeverDeliversWrongData) {
  LinkFaults faults;
  faults.loss = 0.2;
  faults.seed = 11;
  Rig rig(faults);
  ASSERT_EQ(rig.driver->Open(), DeviceStatus::kOk);
  int mismatches = 0;
  const int ok = RunAndCheck(rig, 2000, Tensions(), &mismatches);
  EXPECT_EQ(mismatches, 0);
  EXPECT_GT(ok, 1000);
  EXPECT_GT(rig.driver->stats().comm_error_ticks, 0u);
  EXPECT_GT(rig.link->counters().lost, 0u);
  EXPECT_EQ(
      rig.driver->status() == DeviceStatus::kOk || rig.driver->status() == DeviceStatus::kCommError,
      true);
}

TEST(UsbSpidarG, CorruptionIsDetectedByTheChecksum) {
  LinkFaults faults;
  faults.corruption = 0.2;
  faults.seed = 12;
  Rig rig(faults);
  ASSERT_EQ(rig.driver->Open(), DeviceStatus::kOk);
  int mismatches = 0;
  const int ok = RunAndCheck(rig, 2000, Tensions(), &mismatches);
  EXPECT_EQ(mismatches, 0);
  EXPECT_GT(ok, 1500);
  EXPECT_GT(rig.driver->stats().corrupt, 100u);
  // Corrupt commands are rejected by the board too.
  EXPECT_GT(rig.board.rejected_packets(), 100u);
}

TEST(UsbSpidarG, TotalCorruptionGivesCommErrorZeroForceThenNotConnected) {
  Rig rig;
  ASSERT_EQ(rig.driver->Open(), DeviceStatus::kOk);
  int mismatches = 0;
  RunAndCheck(rig, 50, Tensions(), &mismatches);
  ASSERT_TRUE(rig.board.motors_enabled());
  LinkFaults all;
  all.corruption = 1.0;
  rig.link->set_faults(all);
  EncoderReading reading;
  EXPECT_EQ(rig.driver->Read(&reading), DeviceStatus::kCommError);
  // Nothing the board sent can be decoded: every tick is an error, and the motors stop
  // (corrupt commands are dropped by the board, so its watchdog trips).
  for (int i = 0; i < 40; ++i) {
    EXPECT_NE(rig.driver->Read(&reading), DeviceStatus::kOk);
    rig.driver->WriteTensions(Tensions());
  }
  EXPECT_FALSE(rig.board.motors_enabled());
  EXPECT_TRUE(rig.board.watchdog_tripped());
  for (int i = 0; i < 20; ++i) rig.driver->Read(&reading);
  EXPECT_EQ(rig.driver->status(), DeviceStatus::kNotConnected);
  EXPECT_EQ(rig.driver->stats().disconnects, 1u);
}

// A transport that forwards to the loopback and records how the driver lets go of the link:
// Abandon (tick-safe) marks it unused like LibusbTransport does; Close releases it.
class RecordingTransport final : public Transport {
 public:
  explicit RecordingTransport(std::unique_ptr<LoopbackTransport> inner)
      : inner_(std::move(inner)) {}
  TransportResult Open() noexcept override {
    if (abandoned_) Close();  // LibusbTransport::Open releases an abandoned link first
    return inner_->Open();
  }
  void Close() noexcept override {
    ++closes;
    abandoned_ = false;
    inner_->Close();
  }
  void Abandon() noexcept override {
    ++abandons;
    abandoned_ = true;
  }
  bool is_open() const noexcept override { return inner_->is_open() && !abandoned_; }
  TransportResult Send(const std::uint8_t* data, std::size_t size,
                       int timeout_ms) noexcept override {
    return abandoned_ ? TransportResult::kDisconnected : inner_->Send(data, size, timeout_ms);
  }
  TransportResult Receive(std::uint8_t* data, std::size_t capacity, std::size_t* received,
                          int timeout_ms) noexcept override {
    *received = 0;
    return abandoned_ ? TransportResult::kDisconnected
                      : inner_->Receive(data, capacity, received, timeout_ms);
  }
  const char* last_error() const noexcept override { return inner_->last_error(); }
  LoopbackTransport& inner() { return *inner_; }
  int closes = 0, abandons = 0;

 private:
  std::unique_ptr<LoopbackTransport> inner_;
  bool abandoned_ = false;
};

// When the driver gives up on a link from the tick (no valid data), it abandons the transport
// instead of closing it (a real board's close goes through libusb, which locks and frees); the
// release happens at the next Open, off the tick.
TEST(UsbSpidarG, GivingUpOnTheTickAbandonsTheLinkAndTheNextOpenReleasesIt) {
  BoardSimulator board(TestBoard());
  UsbDeviceConfig config;
  config.reconnect_every = 0;  // re-opening is the caller's, off the tick
  auto recording =
      std::make_unique<RecordingTransport>(std::make_unique<LoopbackTransport>(&board));
  RecordingTransport* link = recording.get();
  UsbSpidarG driver(std::move(recording), board.device().info(), config);
  ASSERT_EQ(driver.Open(), DeviceStatus::kOk);
  EncoderReading reading;
  for (int i = 0; i < 20; ++i) {
    driver.Read(&reading);
    driver.WriteTensions(Tensions());
  }
  ASSERT_EQ(driver.status(), DeviceStatus::kOk);
  const int closes_before = link->closes;
  LinkFaults all;
  all.corruption = 1.0;
  link->inner().set_faults(all);
  for (int i = 0; i < 200 && driver.status() != DeviceStatus::kNotConnected; ++i) {
    driver.Read(&reading);
    driver.WriteTensions(Tensions());
  }
  ASSERT_EQ(driver.status(), DeviceStatus::kNotConnected);
  EXPECT_EQ(link->abandons, 1);
  EXPECT_EQ(link->closes, closes_before) << "the tick closed the transport";
  EXPECT_FALSE(link->is_open());
  EXPECT_NE(std::string(driver.last_error()).find("no valid data"), std::string::npos);
  // Off the tick: the faults cleared, Open releases the abandoned link and reconnects.
  link->inner().set_faults({});
  EXPECT_EQ(driver.Open(), DeviceStatus::kOk);
  EXPECT_GT(link->closes, closes_before);
}

TEST(UsbSpidarG, ReorderedPacketsAreDroppedAsStale) {
  LinkFaults faults;
  faults.reorder = 0.2;
  faults.seed = 13;
  Rig rig(faults);
  ASSERT_EQ(rig.driver->Open(), DeviceStatus::kOk);
  int mismatches = 0;  // also counts any non-increasing sequence
  const int ok = RunAndCheck(rig, 2000, Tensions(), &mismatches);
  EXPECT_EQ(mismatches, 0);
  EXPECT_GT(ok, 1500);
  EXPECT_GT(rig.link->counters().reordered, 100u);
  EXPECT_GT(rig.driver->stats().stale, 100u);
}

TEST(UsbSpidarG, StallStopsTheMotorsAndTheDriverReconnectsAfterIt) {
  UsbDeviceConfig config;
  config.reconnect_every = 20;
  Rig rig({}, TestBoard(), config);
  ASSERT_EQ(rig.driver->Open(), DeviceStatus::kOk);
  int mismatches = 0;
  RunAndCheck(rig, 50, Tensions(), &mismatches);
  rig.link->StartStall(300);  // 300 ms without traffic
  EncoderReading reading;
  bool saw_comm_error = false;
  bool saw_not_connected = false;
  int ticks = 0;
  for (; ticks < 3000; ++ticks) {
    const DeviceStatus s = rig.driver->Read(&reading);
    saw_comm_error |= s == DeviceStatus::kCommError;
    saw_not_connected |= s == DeviceStatus::kNotConnected;
    if (saw_not_connected && s == DeviceStatus::kOk) break;
    rig.driver->WriteTensions(Tensions());
  }
  EXPECT_TRUE(saw_comm_error);
  EXPECT_TRUE(saw_not_connected);
  EXPECT_EQ(rig.driver->status(), DeviceStatus::kOk);
  EXPECT_GE(rig.board.watchdog_trips(), 1u);
  EXPECT_EQ(rig.driver->stats().connects, 2u);
  // Force comes back after the reconnect.
  RunAndCheck(rig, 10, Tensions(), &mismatches);
  EXPECT_EQ(mismatches, 0);
  EXPECT_TRUE(rig.board.motors_enabled());
}

TEST(UsbSpidarG, WatchdogStopsTheMotorsWhenCommandsStop) {
  Rig rig;
  ASSERT_EQ(rig.driver->Open(), DeviceStatus::kOk);
  int mismatches = 0;
  RunAndCheck(rig, 20, Tensions(), &mismatches);
  ASSERT_TRUE(rig.board.motors_enabled());
  // The host keeps reading but stops commanding: the board must cut the motors after
  // watchdog_ms (20 ms at 1 ms per tick), not before.
  EncoderReading reading;
  int tripped_at = -1;
  for (int i = 1; i <= 40 && tripped_at < 0; ++i) {
    rig.driver->Read(&reading);
    if (!rig.board.motors_enabled()) tripped_at = i;
  }
  EXPECT_EQ(tripped_at, 21);
  EXPECT_TRUE(rig.board.watchdog_tripped());
  EXPECT_TRUE(rig.board.applied_tensions().isZero());
  for (int i = 0; i < 20; ++i) rig.board.device().Step(1e-3);
  EXPECT_LT(rig.board.device().actual_tensions().maxCoeff(), 0.01);
  // Commands again: motors back on.
  RunAndCheck(rig, 3, Tensions(), &mismatches);
  EXPECT_TRUE(rig.board.motors_enabled());
  EXPECT_FALSE(rig.board.watchdog_tripped());
}

TEST(UsbSpidarG, UnplugGivesNotConnectedAndReplugReconnects) {
  UsbDeviceConfig config;
  config.reconnect_every = 10;
  Rig rig({}, TestBoard(), config);
  ASSERT_EQ(rig.driver->Open(), DeviceStatus::kOk);
  int mismatches = 0;
  RunAndCheck(rig, 20, Tensions(), &mismatches);
  rig.link->SetPlugged(false);
  EncoderReading reading;
  for (int i = 0; i < 50; ++i) {
    EXPECT_EQ(rig.driver->Read(&reading), DeviceStatus::kNotConnected);
    EXPECT_EQ(rig.driver->WriteTensions(Tensions()), DeviceStatus::kNotConnected);
  }
  EXPECT_NE(std::string(rig.driver->last_error()), "");
  rig.link->SetPlugged(true);  // the board power-cycles
  EXPECT_FALSE(rig.board.motors_enabled());
  int ok = 0;
  for (int i = 0; i < 30; ++i) {
    if (rig.driver->Read(&reading) == DeviceStatus::kOk) ++ok;
    rig.driver->WriteTensions(Tensions());
  }
  EXPECT_GT(ok, 15);
  EXPECT_TRUE(rig.board.motors_enabled());
  EXPECT_EQ(rig.driver->stats().connects, 2u);
}

TEST(UsbSpidarG, VersionMismatchIsAFaultWithAClearMessage) {
  BoardConfig board = TestBoard();
  board.protocol_version = 2;
  Rig rig({}, board);
  EXPECT_EQ(rig.driver->Open(), DeviceStatus::kFault);
  EXPECT_NE(std::string(rig.driver->last_error()).find("version mismatch"), std::string::npos)
      << rig.driver->last_error();
  EncoderReading reading;
  EXPECT_EQ(rig.driver->Read(&reading), DeviceStatus::kFault);
  EXPECT_FALSE(rig.board.motors_enabled());
}

TEST(UsbSpidarG, EmergencyStopOnTheDeviceIsReportedAndLatchedInSoftware) {
  Rig rig;
  ASSERT_EQ(rig.driver->Open(), DeviceStatus::kOk);
  int mismatches = 0;
  RunAndCheck(rig, 5, Tensions(), &mismatches);
  rig.board.device().SetStatus(DeviceStatus::kStopped);
  EncoderReading reading;
  EXPECT_EQ(rig.driver->Read(&reading), DeviceStatus::kStopped);
  rig.driver->WriteTensions(Tensions());
  EXPECT_FALSE(rig.board.motors_enabled());
  rig.board.device().SetStatus(DeviceStatus::kOk);
  rig.driver->Read(&reading);
  rig.driver->SetEmergencyStop(true);
  rig.driver->WriteTensions(Tensions());
  EXPECT_EQ(rig.driver->Read(&reading), DeviceStatus::kStopped);
  EXPECT_FALSE(rig.board.motors_enabled());
  rig.driver->SetEmergencyStop(false);
  rig.driver->WriteTensions(Vector8d::Zero());
  EXPECT_EQ(rig.driver->Read(&reading), DeviceStatus::kOk);
  rig.driver->WriteTensions(Tensions());
  EXPECT_TRUE(rig.board.motors_enabled());
}

TEST(UsbSpidarG, CommErrorCommandsZeroForce) {
  Rig rig;
  ASSERT_EQ(rig.driver->Open(), DeviceStatus::kOk);
  int mismatches = 0;
  RunAndCheck(rig, 5, Tensions(), &mismatches);
  rig.link->StartStall(1);  // one tick without a State
  EncoderReading reading;
  ASSERT_EQ(rig.driver->Read(&reading), DeviceStatus::kCommError);
  EXPECT_EQ(rig.driver->WriteTensions(Tensions()), DeviceStatus::kCommError);
  EXPECT_TRUE(rig.board.applied_tensions().isZero());
  EXPECT_FALSE(rig.board.motors_enabled());
}

TEST(UsbSpidarG, SteadyStateTicksAllocateNothing) {
  Rig rig;
  ASSERT_EQ(rig.driver->Open(), DeviceStatus::kOk);
  EncoderReading reading;
  const Vector8d t = Tensions();
  ASSERT_TRUE(test_support::MallocCounterActive()) << "the counting malloc is not in use";
  test_support::MallocCounter counter;
  for (int i = 0; i < 500; ++i) {
    rig.driver->Read(&reading);
    rig.driver->WriteTensions(t);
  }
  EXPECT_EQ(counter.count(), 0);
  EXPECT_EQ(reading.status, DeviceStatus::kOk);
}

TEST(UsbSpidarG, LibusbWithNoBoardAttachedReportsNotConnected) {
  DeviceInfo info;
  UsbDeviceConfig config;
  config.reconnect_every = 1;
  UsbSpidarG driver(std::make_unique<LibusbTransport>(), info, config);
  EXPECT_EQ(driver.Open(), DeviceStatus::kNotConnected);
  const std::string error = driver.last_error();
  EXPECT_NE(error.find("1209:0001"), std::string::npos) << error;
  EncoderReading reading;
  for (int i = 0; i < 3; ++i) {
    EXPECT_EQ(driver.Read(&reading), DeviceStatus::kNotConnected);
    EXPECT_EQ(driver.WriteTensions(Vector8d::Constant(1.0)), DeviceStatus::kNotConnected);
  }
  const UsbEnumeration list = ListUsbBoards();
  if (list.usb_available) {
    EXPECT_TRUE(list.boards.empty());
  }
}

}  // namespace
}  // namespace spidarcad::haptics::usb
