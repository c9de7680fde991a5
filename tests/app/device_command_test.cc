// Runs the built `spidarcad device` subcommands: `list` with no board attached (this machine
// has no USB bus) and `selftest` against the board simulator.
// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#include <sys/wait.h>

#include <cstdio>
#include <regex>
#include <string>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "spidarcad/haptics/usb_transport.h"

namespace {

using testing::HasSubstr;

struct CommandRun {
  int status = -1;
  std::string out;  // stdout and stderr, in order
};

CommandRun RunSpidarcad(const std::string& args) {
  const std::string command = std::string(SPIDARCAD_EXE) + " " + args + " 2>&1";
  CommandRun run;
  FILE* pipe = popen(command.c_str(), "r");
  if (pipe == nullptr) return run;
  char buffer[4096];
  size_t n;
  while ((n = fread(buffer, 1, sizeof(buffer), pipe)) > 0) run.out.append(buffer, n);
  const int raw = pclose(pipe);
  run.status = WIFEXITED(raw) ? WEXITSTATUS(raw) : -1;
  return run;
}

TEST(DeviceCommand, ListSaysNoDeviceAndExitsZeroWhenNothingIsAttached) {
  // Only meaningful where no board is plugged in (true on the build machine).
  const spidarcad::haptics::usb::UsbEnumeration scan = spidarcad::haptics::usb::ListUsbBoards();
  if (!scan.usb_available || !scan.boards.empty()) {
    GTEST_SKIP() << "a board is attached or USB is unavailable here";
  }
  const CommandRun run = RunSpidarcad("device list");
  EXPECT_EQ(run.status, 0) << run.out;
  EXPECT_THAT(run.out, HasSubstr("No SPIDAR-G controller attached"));
  EXPECT_THAT(run.out, HasSubstr("1209:0001"));
  EXPECT_THAT(run.out, HasSubstr("among " + std::to_string(scan.devices_seen) + " USB device"));
}

TEST(DeviceCommand, DeviceWithoutSubcommandIsBadInput) {
  const CommandRun run = RunSpidarcad("device");
  EXPECT_EQ(run.status, 2) << run.out;
}

TEST(DeviceCommand, SelftestOnACleanLinkHasEveryTickOk) {
  const CommandRun run = RunSpidarcad("device selftest --ticks 500");
  EXPECT_EQ(run.status, 0) << run.out;
  EXPECT_THAT(run.out, HasSubstr("ticks ok 500 (100.0 %)"));
  EXPECT_THAT(run.out, HasSubstr("lost 0, corrupt 0"));
}

TEST(DeviceCommand, SelftestWithFaultsCountsThem) {
  const CommandRun run = RunSpidarcad("device selftest --ticks 2000 --corruption 0.1 --seed 3");
  EXPECT_EQ(run.status, 0) << run.out;
  std::smatch m;
  ASSERT_TRUE(std::regex_search(run.out, m, std::regex("corrupt ([0-9]+)"))) << run.out;
  EXPECT_GT(std::stoi(m[1]), 0);
}

TEST(DeviceCommand, SelftestRejectsABadProbability) {
  const CommandRun run = RunSpidarcad("device selftest --loss 1.5");
  EXPECT_EQ(run.status, 2) << run.out;
  EXPECT_THAT(run.out, HasSubstr("--loss"));
  EXPECT_THAT(run.out, HasSubstr("1.5"));
}

}  // namespace
