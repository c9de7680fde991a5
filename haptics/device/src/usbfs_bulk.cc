// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#include "usbfs_bulk.h"

#include <linux/usbdevice_fs.h>
#include <sys/ioctl.h>

#include <cerrno>
#include <climits>

namespace spidarcad::haptics::usb::detail {

TransportResult TransportResultFromErrno(int error_number) noexcept {
  switch (error_number) {
    case 0:
      return TransportResult::kOk;
    case ETIMEDOUT:
    case EINTR:  // a signal cut the wait short: nothing moved, try again next tick
      return TransportResult::kTimeout;
    case ENODEV:     // the device node's device was unplugged
    case ESHUTDOWN:  // its host controller or port was shut down
    case ENOENT:     // the transfer was killed because the device went away
      return TransportResult::kDisconnected;
    default:
      return TransportResult::kError;
  }
}

const char* UsbfsErrnoName(int error_number) noexcept {
  switch (error_number) {
    case ETIMEDOUT:
      return "ETIMEDOUT (timed out)";
    case ENODEV:
      return "ENODEV (device unplugged)";
    case ESHUTDOWN:
      return "ESHUTDOWN (host controller or port shut down)";
    case ENOENT:
      return "ENOENT (transfer killed, device gone)";
    case EPIPE:
      return "EPIPE (endpoint stalled)";
    case EPROTO:
      return "EPROTO (USB protocol error)";
    case EILSEQ:
      return "EILSEQ (CRC or bit-stuffing error)";
    case EOVERFLOW:
      return "EOVERFLOW (device sent more than the buffer holds)";
    case ENOTTY:
      return "ENOTTY (not a usbfs device node)";
    case EBADF:
      return "EBADF (bad file descriptor)";
    case EINVAL:
      return "EINVAL (invalid endpoint or length)";
    case ENOMEM:
      return "ENOMEM (usbfs memory limit)";
    case EINTR:
      return "EINTR (interrupted)";
    case EACCES:
      return "EACCES (permission denied)";
    case EPERM:
      return "EPERM (operation not permitted)";
    default:
      return nullptr;
  }
}

TransportResult UsbfsBulk(int fd, unsigned char endpoint, std::uint8_t* data, std::size_t length,
                          int timeout_ms, std::size_t* transferred, int* error_number) noexcept {
  *transferred = 0;
  *error_number = 0;
  if (length > static_cast<std::size_t>(UINT_MAX)) {
    *error_number = EINVAL;
    return TransportResult::kError;
  }
  usbdevfs_bulktransfer bulk{};
  bulk.ep = endpoint;
  bulk.len = static_cast<unsigned int>(length);
  bulk.timeout = timeout_ms > 0 ? static_cast<unsigned int>(timeout_ms) : 1u;
  bulk.data = data;
  const int rc = ioctl(fd, USBDEVFS_BULK, &bulk);
  if (rc < 0) {
    const int e = errno;
    *error_number = e != 0 ? e : EIO;
    return TransportResultFromErrno(*error_number);
  }
  *transferred = static_cast<std::size_t>(rc);
  return TransportResult::kOk;
}

}  // namespace spidarcad::haptics::usb::detail
