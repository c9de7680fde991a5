// Tests of the per-tick USB path of LibusbTransport: the USBDEVFS_BULK wrapper and its errno
// mapping (haptics/device/src/usbfs_bulk.h), and LibusbTransport with no board attached.
// The success path (a real bulk transfer on a claimed usbfs node) needs a board on a USB bus:
// this container has none, and no fake kernel is built here, so it is not exercised. What is
// tested: the errno table, that the ioctl on real non-usbfs fds (a pipe, /dev/null, a closed
// fd) fails cleanly with 0 bytes and without allocating, and the not-open paths.
// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#include <fcntl.h>
#include <gtest/gtest.h>
#include <unistd.h>

#include <array>
#include <cerrno>
#include <climits>
#include <cstdint>
#include <string>

#include "spidarcad/haptics/usb_transport.h"
#include "support/malloc_counter.h"
#include "usbfs_bulk.h"

namespace spidarcad::haptics::usb {
namespace {

using detail::TransportResultFromErrno;
using detail::UsbfsBulk;
using detail::UsbfsErrnoName;

TEST(Usbfs, ErrnoMappingTable) {
  struct Row {
    int error_number;
    TransportResult expected;
  };
  const Row rows[] = {
      {0, TransportResult::kOk},
      {ETIMEDOUT, TransportResult::kTimeout},
      {ENODEV, TransportResult::kDisconnected},
      {ESHUTDOWN, TransportResult::kDisconnected},
      {ENOENT, TransportResult::kDisconnected},
      {EPIPE, TransportResult::kError},
      {EPROTO, TransportResult::kError},
      {EILSEQ, TransportResult::kError},
      {EOVERFLOW, TransportResult::kError},
      {ENOTTY, TransportResult::kError},
      {EBADF, TransportResult::kError},
      {EINVAL, TransportResult::kError},
      {ENOMEM, TransportResult::kError},
      {EINTR, TransportResult::kTimeout},
      {EIO, TransportResult::kError},
      {EAGAIN, TransportResult::kError},
      {12345, TransportResult::kError},
      {-1, TransportResult::kError},
  };
  for (const Row& row : rows) {
    EXPECT_EQ(TransportResultFromErrno(row.error_number), row.expected)
        << "errno " << row.error_number << ": got "
        << TransportResultName(TransportResultFromErrno(row.error_number)) << ", expected "
        << TransportResultName(row.expected);
  }
}

TEST(Usbfs, ErrnoNamesCoverTheMappedErrnos) {
  for (int e : {ETIMEDOUT, ENODEV, ESHUTDOWN, ENOENT, EPIPE, EPROTO, EILSEQ, EOVERFLOW, ENOTTY,
                EBADF, EINVAL}) {
    ASSERT_NE(UsbfsErrnoName(e), nullptr) << "errno " << e;
    EXPECT_GT(std::string(UsbfsErrnoName(e)).size(), 3u);
  }
  EXPECT_NE(std::string(UsbfsErrnoName(EPIPE)).find("EPIPE"), std::string::npos);
  EXPECT_EQ(UsbfsErrnoName(12345), nullptr);
  EXPECT_EQ(UsbfsErrnoName(0), nullptr);
}

// Runs UsbfsBulk in both directions on `fd`, expecting failure with `expected_errno`, 0 bytes
// and no allocation.
void ExpectBulkFails(int fd, int expected_errno, const char* what) {
  ASSERT_TRUE(test_support::MallocCounterActive()) << "the counting malloc is not in use";
  std::array<std::uint8_t, 64> buffer{};
  buffer.fill(0xAB);
  TransportResult out_result = TransportResult::kOk;
  TransportResult in_result = TransportResult::kOk;
  std::size_t out_bytes = 99;
  std::size_t in_bytes = 99;
  int out_errno = 0;
  int in_errno = 0;
  long allocations = -1;
  {
    test_support::MallocCounter counter;
    out_result =
        UsbfsBulk(fd, kEndpointOut, buffer.data(), buffer.size(), 5, &out_bytes, &out_errno);
    in_result = UsbfsBulk(fd, kEndpointIn, buffer.data(), buffer.size(), 0, &in_bytes, &in_errno);
    allocations = counter.count();
  }
  EXPECT_EQ(out_result, TransportResult::kError) << what;
  EXPECT_EQ(in_result, TransportResult::kError) << what;
  EXPECT_EQ(out_errno, expected_errno) << what;
  EXPECT_EQ(in_errno, expected_errno) << what;
  EXPECT_EQ(out_bytes, 0u) << what;
  EXPECT_EQ(in_bytes, 0u) << what;
  EXPECT_EQ(allocations, 0) << what;
  for (std::uint8_t b : buffer) ASSERT_EQ(b, 0xAB) << what << ": the buffer was written";
}

TEST(Usbfs, BulkOnAPipeIsNotTtyErrorWithoutAllocating) {
  int fds[2] = {-1, -1};
  ASSERT_EQ(pipe2(fds, O_CLOEXEC), 0);
  ExpectBulkFails(fds[0], ENOTTY, "pipe read end");
  ExpectBulkFails(fds[1], ENOTTY, "pipe write end");
  close(fds[0]);
  close(fds[1]);
}

TEST(Usbfs, BulkOnDevNullIsNotTtyErrorWithoutAllocating) {
  const int fd = open("/dev/null", O_RDWR | O_CLOEXEC);
  ASSERT_GE(fd, 0);
  ExpectBulkFails(fd, ENOTTY, "/dev/null");
  close(fd);
}

TEST(Usbfs, BulkOnAClosedFdIsBadFdErrorWithoutAllocating) {
  int fds[2] = {-1, -1};
  ASSERT_EQ(pipe2(fds, O_CLOEXEC), 0);
  close(fds[0]);
  close(fds[1]);
  // Nothing else in this single-threaded test opens files in between: fds[0] stays closed.
  ExpectBulkFails(fds[0], EBADF, "closed fd");
  ExpectBulkFails(-1, EBADF, "fd -1");
}

TEST(Usbfs, BulkRejectsALengthTheIoctlCannotCarry) {
  if (sizeof(std::size_t) <= sizeof(unsigned int)) GTEST_SKIP() << "size_t is 32-bit here";
  std::uint8_t byte = 0;
  std::size_t transferred = 7;
  int error_number = 0;
  const std::size_t too_long = static_cast<std::size_t>(UINT_MAX) + 1;
  EXPECT_EQ(UsbfsBulk(-1, kEndpointIn, &byte, too_long, 1, &transferred, &error_number),
            TransportResult::kError);
  EXPECT_EQ(error_number, EINVAL);
  EXPECT_EQ(transferred, 0u);
}

// This machine has no USB bus (../shared/STACK-NOTES.md "USB"): libusb initialises, the list
// is empty, and Open must say which board it looked for.
TEST(Usbfs, LibusbTransportOpenWithNoBoardIsNotFound) {
  LibusbTransport transport;
  EXPECT_EQ(transport.Open(), TransportResult::kNotFound) << transport.last_error();
  const std::string error = transport.last_error();
  EXPECT_NE(error.find("no USB device 1209:0001"), std::string::npos) << error;
  EXPECT_FALSE(transport.is_open());
  transport.Close();  // safe when not open
  transport.Close();
  EXPECT_FALSE(transport.is_open());
  EXPECT_EQ(transport.Open(), TransportResult::kNotFound) << "a second Open behaves the same";
}

TEST(Usbfs, LibusbTransportNotOpenSendReceiveAreDisconnectedWithoutAllocating) {
  ASSERT_TRUE(test_support::MallocCounterActive()) << "the counting malloc is not in use";
  for (bool tried_open : {false, true}) {
    LibusbTransport transport;
    if (tried_open) {
      ASSERT_NE(transport.Open(), TransportResult::kOk);
    }
    std::array<std::uint8_t, 64> buffer{};
    std::size_t received = 5;
    TransportResult sent = TransportResult::kOk;
    TransportResult got = TransportResult::kOk;
    long allocations = -1;
    {
      test_support::MallocCounter counter;
      for (int i = 0; i < 100; ++i) {
        sent = transport.Send(buffer.data(), buffer.size(), 1);
        got = transport.Receive(buffer.data(), buffer.size(), &received, 0);
      }
      allocations = counter.count();
    }
    EXPECT_EQ(sent, TransportResult::kDisconnected) << "tried_open " << tried_open;
    EXPECT_EQ(got, TransportResult::kDisconnected) << "tried_open " << tried_open;
    EXPECT_EQ(received, 0u);
    EXPECT_EQ(allocations, 0) << "tried_open " << tried_open;
  }
}

}  // namespace
}  // namespace spidarcad::haptics::usb
