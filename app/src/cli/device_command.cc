// `spidarcad device list`: the SPIDAR-G controller boards on the USB bus.
// `spidarcad device selftest`: the USB driver against the in-process board simulator, with
// optional link faults; prints link statistics and timing.
// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <memory>
#include <string>
#include <vector>

#include "cli/cli_common.h"
#include "cli/commands.h"
#include "spidarcad/haptics/board_simulator.h"
#include "spidarcad/haptics/usb_device.h"
#include "spidarcad/haptics/usb_transport.h"

namespace spidarcad::app {
namespace {

namespace usb = haptics::usb;

constexpr const char* kUdevHelp =
    "  Give your user access without root (once):\n"
    "    sudo cp assets/udev/99-spidarcad.rules /etc/udev/rules.d/\n"
    "    sudo udevadm control --reload-rules && sudo udevadm trigger\n"
    "  then unplug and replug the board. The rules give the 'plugdev' group access: add\n"
    "  yourself with `sudo usermod -aG plugdev $USER` and log in again.\n";

void RunList() {
  char id[16];
  std::snprintf(id, sizeof(id), "%04x:%04x", usb::kVendorId, usb::kProductId);
  const usb::UsbEnumeration scan = usb::ListUsbBoards();
  if (!scan.usb_available) {
    std::printf("USB is not available: %s\n", scan.error.c_str());
    std::printf("No SPIDAR-G controller can be listed (looked for USB id %s).\n", id);
    throw CommandExit{1};
  }
  if (scan.boards.empty()) {
    std::printf("No SPIDAR-G controller attached (looked for USB id %s among %d USB device%s).\n",
                id, scan.devices_seen, scan.devices_seen == 1 ? "" : "s");
    std::printf(
        "  Check the cable and the board's power. If `lsusb` shows %s but this list is empty,\n"
        "  the board may be claimed by another program.\n"
        "  Note: %s is a pid.codes test id used by prototype boards (docs/protocol.md).\n",
        id, id);
    return;
  }
  std::printf("%zu SPIDAR-G controller%s found:\n", scan.boards.size(),
              scan.boards.size() == 1 ? "" : "s");
  std::printf("  %-9s %-8s %-9s %-20s %s\n", "bus", "address", "id", "serial", "access");
  bool denied = false;
  for (const usb::UsbBoardInfo& board : scan.boards) {
    char board_id[16];
    std::snprintf(board_id, sizeof(board_id), "%04x:%04x", board.vendor_id, board.product_id);
    const std::string serial =
        board.serial.empty() ? (board.accessible ? "(none)" : "(unreadable)") : board.serial;
    const std::string access = board.accessible ? "ok" : "DENIED (" + board.access_error + ")";
    std::printf("  %03d       %03d      %-9s %-20s %s\n", board.bus, board.address, board_id,
                serial.c_str(), access.c_str());
    denied |= !board.accessible;
  }
  if (denied) {
    std::printf("Permission is missing for at least one board.\n%s", kUdevHelp);
  }
}

// Most ticks one selftest runs: it keeps every tick's time (8 bytes each) for the percentiles.
constexpr int kMaxSelftestTicks = 10000000;

struct SelftestOptions {
  int ticks = 5000;
  double loss = 0.0;
  double corruption = 0.0;
  double reorder = 0.0;
  double stall = 0.0;
  std::uint64_t seed = 1;
};

void RunSelftest(const SelftestOptions& o) {
  auto check_probability = [](const char* name, double p) {
    if (!(p >= 0.0 && p <= 1.0)) {
      throw InputError(std::string(name) + ": expected a probability in [0, 1], got " +
                       FormatNumber(p));
    }
  };
  check_probability("--loss", o.loss);
  check_probability("--corruption", o.corruption);
  check_probability("--reorder", o.reorder);
  check_probability("--stall", o.stall);
  if (o.ticks < 1 || o.ticks > kMaxSelftestTicks) {
    throw InputError("--ticks: must be in [1, " + std::to_string(kMaxSelftestTicks) +
                     "] (10000 s of 1 kHz ticks, 80 MB of kept timings; docs/limits.md), got " +
                     std::to_string(o.ticks) +
                     "; for a longer soak run several selftests with different --seed");
  }

  usb::BoardConfig board_config;
  board_config.device.seed = o.seed;
  usb::BoardSimulator board(board_config);
  usb::LinkFaults faults;
  faults.loss = o.loss;
  faults.corruption = o.corruption;
  faults.reorder = o.reorder;
  faults.stall = o.stall;
  faults.seed = o.seed;
  auto transport = std::make_unique<usb::LoopbackTransport>(&board, faults);
  usb::LoopbackTransport* link = transport.get();
  usb::UsbSpidarG driver(std::move(transport), board.device().info());
  if (driver.Open() != haptics::DeviceStatus::kOk) {
    std::printf("handshake failed: %s\n", driver.last_error());
    throw CommandExit{1};
  }
  haptics::Vector8d tension = haptics::Vector8d::Constant(1.0);
  haptics::EncoderReading reading;
  std::vector<double> tick_us;
  tick_us.reserve(static_cast<std::size_t>(o.ticks));
  int ok = 0;
  for (int i = 0; i < o.ticks; ++i) {
    const auto start = std::chrono::steady_clock::now();
    if (driver.Read(&reading) == haptics::DeviceStatus::kOk) ++ok;
    driver.WriteTensions(tension);
    const auto stop = std::chrono::steady_clock::now();
    tick_us.push_back(std::chrono::duration<double, std::micro>(stop - start).count());
  }
  std::sort(tick_us.begin(), tick_us.end());
  auto pct = [&](double q) {
    return tick_us[std::min(tick_us.size() - 1, static_cast<std::size_t>(q * tick_us.size()))];
  };
  const usb::UsbLinkStats& s = driver.stats();
  std::printf("driver <-> simulated board (loopback), %d ticks, seed %llu\n", o.ticks,
              static_cast<unsigned long long>(o.seed));
  std::printf("  ticks ok %d (%.1f %%), comm_error %llu, final status %s\n", ok,
              100.0 * ok / o.ticks, static_cast<unsigned long long>(s.comm_error_ticks),
              haptics::DeviceStatusName(driver.status()));
  std::printf(
      "  states %llu, lost %llu, corrupt %llu, stale %llu, timeouts %llu, "
      "disconnects %llu, connects %llu\n",
      static_cast<unsigned long long>(s.states), static_cast<unsigned long long>(s.lost),
      static_cast<unsigned long long>(s.corrupt), static_cast<unsigned long long>(s.stale),
      static_cast<unsigned long long>(s.timeouts), static_cast<unsigned long long>(s.disconnects),
      static_cast<unsigned long long>(s.connects));
  const usb::LinkCounters& c = link->counters();
  std::printf("  link injected: lost %llu, corrupted %llu, reordered %llu, stalled ticks %llu\n",
              static_cast<unsigned long long>(c.lost), static_cast<unsigned long long>(c.corrupted),
              static_cast<unsigned long long>(c.reordered),
              static_cast<unsigned long long>(c.stalled_ticks));
  std::printf("  board: rejected %llu, watchdog trips %llu\n",
              static_cast<unsigned long long>(board.rejected_packets()),
              static_cast<unsigned long long>(board.watchdog_trips()));
  std::printf(
      "  round trip (Read + WriteTensions incl. board firmware and physics), us: "
      "p50 %.2f  p99 %.2f  p99.9 %.2f  max %.2f\n",
      pct(0.5), pct(0.99), pct(0.999), tick_us.back());
}

}  // namespace

void RegisterDeviceCommand(CLI::App& app) {
  CLI::App* device = app.add_subcommand(
      "device", "USB SPIDAR-G controller boards: list them, or self-test the driver");
  device->require_subcommand(1);

  device
      ->add_subcommand("list",
                       "List SPIDAR-G controllers on the USB bus (id, bus/address, serial, "
                       "access); says so when none is attached or permission is missing")
      ->callback([]() { RunList(); });

  auto options = std::make_shared<SelftestOptions>();
  CLI::App* selftest = device->add_subcommand(
      "selftest",
      "Run the USB driver against the in-process board simulator (no hardware) with optional "
      "link faults, and print link statistics and round-trip times");
  selftest->add_option("--ticks", options->ticks,
                       "Haptic ticks to run, in [1, 10000000] (default 5000)");
  selftest->add_option("--loss", options->loss, "Packet loss probability (default 0)");
  selftest->add_option("--corruption", options->corruption,
                       "Packet corruption probability (default 0)");
  selftest->add_option("--reorder", options->reorder, "Packet reordering probability (default 0)");
  selftest->add_option("--stall", options->stall,
                       "Probability per tick that a 50 ms stall begins (default 0)");
  selftest->add_option("--seed", options->seed, "Seed of the device and the faults (default 1)");
  selftest->callback([options]() { RunSelftest(*options); });
}

}  // namespace spidarcad::app
