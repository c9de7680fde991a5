// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
// The only file that includes <libusb.h>. libusb does everything off the haptic tick (find,
// open, claim, release); the per-tick Send/Receive are USBDEVFS_BULK ioctls (usbfs_bulk.h) on
// the device node this file opens itself and hands to libusb with libusb_wrap_sys_device.
#include <fcntl.h>
#include <libusb.h>
#include <unistd.h>

#include <cerrno>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <utility>

#include "spidarcad/haptics/usb_transport.h"
#include "usbfs_bulk.h"

namespace spidarcad::haptics::usb {
namespace {

TransportResult FromLibusb(int code) noexcept {
  switch (code) {
    case LIBUSB_SUCCESS:
      return TransportResult::kOk;
    case LIBUSB_ERROR_TIMEOUT:
      return TransportResult::kTimeout;
    case LIBUSB_ERROR_NO_DEVICE:
      return TransportResult::kDisconnected;
    case LIBUSB_ERROR_NOT_FOUND:
      return TransportResult::kNotFound;
    case LIBUSB_ERROR_ACCESS:
      return TransportResult::kNoAccess;
    default:
      return TransportResult::kError;
  }
}

// Reads the serial string of an open device ("" when it has none or it cannot be read).
std::string ReadSerial(libusb_device_handle* handle, const libusb_device_descriptor& desc) {
  if (handle == nullptr || desc.iSerialNumber == 0) return {};
  unsigned char buffer[128] = {};
  const int n =
      libusb_get_string_descriptor_ascii(handle, desc.iSerialNumber, buffer, sizeof(buffer));
  if (n <= 0) return {};
  return std::string(reinterpret_cast<const char*>(buffer), static_cast<std::size_t>(n));
}

}  // namespace

const char* TransportResultName(TransportResult result) noexcept {
  switch (result) {
    case TransportResult::kOk:
      return "ok";
    case TransportResult::kTimeout:
      return "timeout";
    case TransportResult::kDisconnected:
      return "disconnected";
    case TransportResult::kNotFound:
      return "not_found";
    case TransportResult::kNoAccess:
      return "no_access";
    case TransportResult::kError:
      return "error";
  }
  return "unknown";
}

LibusbTransport::LibusbTransport(std::uint16_t vendor_id, std::uint16_t product_id,
                                 std::string serial)
    : vendor_id_(vendor_id), product_id_(product_id), serial_(std::move(serial)) {}

LibusbTransport::~LibusbTransport() {
  Close();
  if (context_ != nullptr) libusb_exit(context_);
}

void LibusbTransport::SetError(const char* what, int code) noexcept {
  std::snprintf(error_, sizeof(error_), "%s: %s", what,
                libusb_strerror(static_cast<libusb_error>(code)));
}

// Opens /dev/bus/usb/BBB/DDD ourselves, so that the fd used by the tick's ioctls is ours, and
// wraps it in a libusb handle for the claim, the serial string and the release. Wrapping works
// with an ordinary (device-discovery) context: libusb's Linux backend builds a separate device
// for the fd, reads its descriptors through it, and its libusb_close leaves the fd open.
TransportResult LibusbTransport::OpenNode(int bus, int address, libusb_device_handle** handle,
                                          int* fd) noexcept {
  *handle = nullptr;
  *fd = -1;
  char path[40];
  std::snprintf(path, sizeof(path), "/dev/bus/usb/%03d/%03d", bus, address);
  const int node = ::open(path, O_RDWR | O_CLOEXEC);
  if (node < 0) {
    const int e = errno;
    if (e == EACCES || e == EPERM) {
      std::snprintf(error_, sizeof(error_),
                    "permission denied on %s (udev rules missing, see assets/udev)", path);
      return TransportResult::kNoAccess;
    }
    if (e == ENOENT) {
      std::snprintf(error_, sizeof(error_), "%s does not exist (unplugged, or no devtmpfs)", path);
      return TransportResult::kNotFound;
    }
    if (e == ENODEV) {
      std::snprintf(error_, sizeof(error_), "%s: the device is gone (unplugged)", path);
      return TransportResult::kDisconnected;
    }
    std::snprintf(error_, sizeof(error_), "open %s: %s", path, std::strerror(e));
    return TransportResult::kError;
  }
  const int rc = libusb_wrap_sys_device(context_, static_cast<intptr_t>(node), handle);
  if (rc != LIBUSB_SUCCESS) {
    *handle = nullptr;
    ::close(node);
    SetError("libusb_wrap_sys_device", rc);
    const TransportResult result = FromLibusb(rc);
    return result == TransportResult::kNotFound ? TransportResult::kError : result;
  }
  *fd = node;
  return TransportResult::kOk;
}

TransportResult LibusbTransport::Open() noexcept {
  Close();
  error_[0] = '\0';
  if (context_ == nullptr) {
    const int rc = libusb_init(&context_);
    if (rc != LIBUSB_SUCCESS) {
      context_ = nullptr;
      SetError("libusb_init", rc);
      return TransportResult::kError;
    }
  }
  libusb_device** list = nullptr;
  const ssize_t count = libusb_get_device_list(context_, &list);
  if (count < 0) {
    SetError("libusb_get_device_list", static_cast<int>(count));
    return TransportResult::kError;
  }
  TransportResult result = TransportResult::kNotFound;
  std::snprintf(error_, sizeof(error_), "no USB device %04x:%04x among %d devices", vendor_id_,
                product_id_, static_cast<int>(count));
  for (ssize_t i = 0; i < count && handle_ == nullptr; ++i) {
    libusb_device_descriptor desc{};
    if (libusb_get_device_descriptor(list[i], &desc) != LIBUSB_SUCCESS) continue;
    if (desc.idVendor != vendor_id_ || desc.idProduct != product_id_) continue;
    libusb_device_handle* handle = nullptr;
    int fd = -1;
    const TransportResult opened =
        OpenNode(libusb_get_bus_number(list[i]), libusb_get_device_address(list[i]), &handle, &fd);
    if (opened != TransportResult::kOk) {
      result = opened;
      continue;
    }
    const auto discard = [&handle, &fd]() noexcept {
      libusb_close(handle);  // does not close a wrapped fd
      ::close(fd);
    };
    std::string serial;
    try {
      serial = ReadSerial(handle, desc);
    } catch (...) {
    }
    if (!serial_.empty() && serial != serial_) {
      discard();
      continue;
    }
    kernel_driver_detached_ = false;
    if (libusb_kernel_driver_active(handle, kInterface) == 1 &&
        libusb_detach_kernel_driver(handle, kInterface) == LIBUSB_SUCCESS) {
      kernel_driver_detached_ = true;
    }
    const int claim = libusb_claim_interface(handle, kInterface);
    if (claim != LIBUSB_SUCCESS) {
      SetError("libusb_claim_interface", claim);
      result = FromLibusb(claim);
      if (result == TransportResult::kNotFound) result = TransportResult::kError;
      if (kernel_driver_detached_) libusb_attach_kernel_driver(handle, kInterface);
      kernel_driver_detached_ = false;
      discard();
      continue;
    }
    handle_ = handle;
    fd_ = fd;
    lost_ = false;
    abandoned_ = false;
    result = TransportResult::kOk;
    error_[0] = '\0';
  }
  libusb_free_device_list(list, 1);
  return result;
}

// Off the tick only (libusb locks and frees). After an unplug seen by a transfer (lost_), the
// device is gone: skip the release and the driver re-attach, just free the handle and the fd.
void LibusbTransport::Close() noexcept {
  if (handle_ != nullptr) {
    if (!lost_) {
      libusb_release_interface(handle_, kInterface);
      if (kernel_driver_detached_) libusb_attach_kernel_driver(handle_, kInterface);
    }
    libusb_close(handle_);  // leaves the wrapped fd open: close it after
  }
  if (fd_ >= 0) ::close(fd_);
  handle_ = nullptr;
  fd_ = -1;
  lost_ = false;
  abandoned_ = false;
  kernel_driver_detached_ = false;
}

// Tick path: snprintf into the fixed error_ buffer, no strerror, no libusb call. A device-gone
// errno does not Close() here (libusb_close locks and frees): it marks the link lost, so
// is_open() turns false at once and the next Open() or Close(), made off the tick, releases it.
TransportResult LibusbTransport::TransferFailed(const char* what, TransportResult result,
                                                int error_number) noexcept {
  if (result == TransportResult::kTimeout) return result;
  const char* name = detail::UsbfsErrnoName(error_number);
  if (name != nullptr) {
    std::snprintf(error_, sizeof(error_), "%s: %s", what, name);
  } else {
    std::snprintf(error_, sizeof(error_), "%s: errno %d", what, error_number);
  }
  if (result == TransportResult::kDisconnected) lost_ = true;
  return result;
}

TransportResult LibusbTransport::Send(const std::uint8_t* data, std::size_t size,
                                      int timeout_ms) noexcept {
  if (!is_open()) return TransportResult::kDisconnected;
  std::size_t transferred = 0;
  int error_number = 0;
  // The ioctl's struct takes a non-const pointer for both directions; OUT only reads it.
  const TransportResult result =
      detail::UsbfsBulk(fd_, kEndpointOut, const_cast<std::uint8_t*>(data), size, timeout_ms,
                        &transferred, &error_number);
  if (result != TransportResult::kOk) return TransferFailed("bulk OUT", result, error_number);
  if (transferred != size) {
    std::snprintf(error_, sizeof(error_), "short write: %d of %d bytes",
                  static_cast<int>(transferred), static_cast<int>(size));
    return TransportResult::kError;
  }
  return TransportResult::kOk;
}

TransportResult LibusbTransport::Receive(std::uint8_t* data, std::size_t capacity,
                                         std::size_t* received, int timeout_ms) noexcept {
  *received = 0;
  if (!is_open()) return TransportResult::kDisconnected;
  std::size_t transferred = 0;
  int error_number = 0;
  const TransportResult result =
      detail::UsbfsBulk(fd_, kEndpointIn, data, capacity, timeout_ms, &transferred, &error_number);
  // USBDEVFS_BULK reports a timeout as -ETIMEDOUT and drops any partial IN data, so the
  // "timeout that still delivered bytes" case of libusb_bulk_transfer no longer exists: a
  // timeout delivers nothing, and a short packet (kOk) fails the length check in Decode.
  if (result != TransportResult::kOk) return TransferFailed("bulk IN", result, error_number);
  *received = transferred;
  return TransportResult::kOk;
}

UsbEnumeration ListUsbBoards(std::uint16_t vendor_id, std::uint16_t product_id) noexcept {
  UsbEnumeration out;
  try {
    libusb_context* context = nullptr;
    const int rc = libusb_init(&context);
    if (rc != LIBUSB_SUCCESS) {
      out.error =
          std::string("libusb_init failed: ") + libusb_strerror(static_cast<libusb_error>(rc));
      return out;
    }
    out.usb_available = true;
    libusb_device** list = nullptr;
    const ssize_t count = libusb_get_device_list(context, &list);
    if (count < 0) {
      out.usb_available = false;
      out.error = std::string("libusb_get_device_list failed: ") +
                  libusb_strerror(static_cast<libusb_error>(count));
      libusb_exit(context);
      return out;
    }
    out.devices_seen = static_cast<int>(count);
    for (ssize_t i = 0; i < count; ++i) {
      libusb_device_descriptor desc{};
      if (libusb_get_device_descriptor(list[i], &desc) != LIBUSB_SUCCESS) continue;
      if (desc.idVendor != vendor_id || desc.idProduct != product_id) continue;
      UsbBoardInfo board;
      board.vendor_id = desc.idVendor;
      board.product_id = desc.idProduct;
      board.bus = libusb_get_bus_number(list[i]);
      board.address = libusb_get_device_address(list[i]);
      libusb_device_handle* handle = nullptr;
      const int open_rc = libusb_open(list[i], &handle);
      if (open_rc == LIBUSB_SUCCESS) {
        board.accessible = true;
        board.serial = ReadSerial(handle, desc);
        libusb_close(handle);
      } else {
        board.access_error = libusb_strerror(static_cast<libusb_error>(open_rc));
      }
      out.boards.push_back(std::move(board));
    }
    libusb_free_device_list(list, 1);
    libusb_exit(context);
  } catch (...) {
    out.error = "out of memory while listing USB devices";
  }
  return out;
}

}  // namespace spidarcad::haptics::usb
