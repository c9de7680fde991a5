// Runs the built `spidarcad device` subcommands: `list` with no board attached (this machine
// has no USB bus) and `selftest` against the board simulator.
// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <sys/wait.h>

#include <cstdio>
#include <regex>
#include <string>

#include "spidarcad/haptics/usb_transport.h"
#include "spidarcad_runner.h"

namespace {

using spidarcad::test_support::CommandRun;
using spidarcad::test_support::RunSpidarcad;

using testing::HasSubstr;

TEST(DeviceCommand, ListSaysNoDeviceAndExitsZeroWhenNothingIsAttached) {
  // Only meaningful where no board is plugged in (true on the build machine).
  const spidarcad::haptics::usb::UsbEnumeration scan = spidarcad::haptics::usb::ListUsbBoards();
  if (!scan.usb_available || !scan.boards.empty()) {
    GTEST_SKIP() << "a board is attached or USB is unavailable here";
  }
  const CommandRun run = RunSpidarcad("device list");
  EXPECT_EQ(run.status, 0) << run.all();
  EXPECT_THAT(run.all(), HasSubstr("No SPIDAR-G controller attached"));
  EXPECT_THAT(run.all(), HasSubstr("1209:0001"));
  EXPECT_THAT(run.all(), HasSubstr("among " + std::to_string(scan.devices_seen) + " USB device"));
}

TEST(DeviceCommand, DeviceWithoutSubcommandIsBadInput) {
  const CommandRun run = RunSpidarcad("device");
  EXPECT_EQ(run.status, 2) << run.all();
}

TEST(DeviceCommand, SelftestOnACleanLinkHasEveryTickOk) {
  const CommandRun run = RunSpidarcad("device selftest --ticks 500");
  EXPECT_EQ(run.status, 0) << run.all();
  EXPECT_THAT(run.all(), HasSubstr("ticks ok 500 (100.0 %)"));
  EXPECT_THAT(run.all(), HasSubstr("lost 0, corrupt 0"));
}

TEST(DeviceCommand, SelftestWithFaultsCountsThem) {
  const CommandRun run = RunSpidarcad("device selftest --ticks 2000 --corruption 0.1 --seed 3");
  EXPECT_EQ(run.status, 0) << run.all();
  const std::string printed = run.all();
  std::smatch m;
  ASSERT_TRUE(std::regex_search(printed, m, std::regex("corrupt ([0-9]+)"))) << printed;
  EXPECT_GT(std::stoi(m[1]), 0);
}

TEST(DeviceCommand, SelftestRejectsABadProbability) {
  const CommandRun run = RunSpidarcad("device selftest --loss 1.5");
  EXPECT_EQ(run.status, 2) << run.all();
  EXPECT_THAT(run.all(), HasSubstr("--loss"));
  EXPECT_THAT(run.all(), HasSubstr("1.5"));
}

TEST(DeviceCommand, SelftestRefusesMoreTicksThanItsLimitNamingTheRange) {
  // 2e9 ticks used to reserve 16 GB of timings and end in std::bad_alloc (exit 1).
  for (const char* ticks : {"2000000000", "10000001", "0"}) {
    const CommandRun run = RunSpidarcad(std::string("device selftest --ticks ") + ticks);
    EXPECT_EQ(run.status, 2) << ticks << "\n" << run.all();
    EXPECT_THAT(run.err, HasSubstr("--ticks: must be in [1, 10000000]"));
    EXPECT_THAT(run.err, HasSubstr(std::string("got ") + ticks));
  }
}

}  // namespace
