// Internal to spidarcad_haptics (and its tests): one synchronous bulk transfer on a Linux usbfs
// device node (/dev/bus/usb/BBB/DDD) through the USBDEVFS_BULK ioctl, and the mapping of its
// errno to a TransportResult. This is the per-tick path of LibusbTransport: a single system
// call on a file descriptor we own, no allocation, lock, logging or exception in user space (the
// kernel copies the data through its own buffer). Linux only.
// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#pragma once

#include <cstddef>
#include <cstdint>

#include "spidarcad/haptics/usb_transport.h"

namespace spidarcad::haptics::usb::detail {

// The TransportResult of a failed USBDEVFS_BULK (or of opening a device node) with this errno:
//   0                                   -> kOk
//   ETIMEDOUT, EINTR (a signal)         -> kTimeout
//   ENODEV, ESHUTDOWN, ENOENT           -> kDisconnected (the device is gone)
//   everything else (EPIPE = endpoint stalled, EPROTO, EILSEQ, EOVERFLOW = the device sent more
//   than the buffer holds, ENOTTY = not a usbfs node, EBADF, EINVAL, ...) -> kError
TransportResult TransportResultFromErrno(int error_number) noexcept;

// A short static description of an errno for error messages ("ETIMEDOUT (timed out)"), or
// nullptr for an errno not in the list above. Unlike strerror it never allocates or formats.
const char* UsbfsErrnoName(int error_number) noexcept;

// One bulk transfer of `length` bytes on `endpoint` (bit 7 set: IN, device -> host, into `data`;
// clear: OUT, `data` is only read). Blocks for at most `timeout_ms` milliseconds; timeout_ms <= 0
// means the shortest wait, 1 ms (the kernel reads a 0 timeout as "wait forever").
// On return `*transferred` is the number of bytes moved (0 on any failure: on a timeout the
// kernel drops whatever part of an IN transfer had arrived) and `*error_number` is the errno of a
// failed ioctl (0 on success). A short transfer is kOk: the caller checks the length.
// Never allocates; safe to call from the haptic tick.
TransportResult UsbfsBulk(int fd, unsigned char endpoint, std::uint8_t* data, std::size_t length,
                          int timeout_ms, std::size_t* transferred, int* error_number) noexcept;

}  // namespace spidarcad::haptics::usb::detail
