// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
// The only file that includes <libusb.h>.
#include <libusb.h>

#include <cstdio>
#include <cstring>
#include <utility>

#include "spidarcad/haptics/usb_transport.h"

namespace spidarcad::haptics::usb {
namespace {

TransportResult FromLibusb(int code) noexcept {
  switch (code) {
    case LIBUSB_SUCCESS: return TransportResult::kOk;
    case LIBUSB_ERROR_TIMEOUT: return TransportResult::kTimeout;
    case LIBUSB_ERROR_NO_DEVICE: return TransportResult::kDisconnected;
    case LIBUSB_ERROR_NOT_FOUND: return TransportResult::kNotFound;
    case LIBUSB_ERROR_ACCESS: return TransportResult::kNoAccess;
    default: return TransportResult::kError;
  }
}

// Reads the serial string of an open device ("" when it has none or it cannot be read).
std::string ReadSerial(libusb_device_handle* handle, const libusb_device_descriptor& desc) {
  if (handle == nullptr || desc.iSerialNumber == 0) return {};
  unsigned char buffer[128] = {};
  const int n = libusb_get_string_descriptor_ascii(handle, desc.iSerialNumber, buffer,
                                                   sizeof(buffer));
  if (n <= 0) return {};
  return std::string(reinterpret_cast<const char*>(buffer), static_cast<std::size_t>(n));
}

}  // namespace

const char* TransportResultName(TransportResult result) noexcept {
  switch (result) {
    case TransportResult::kOk: return "ok";
    case TransportResult::kTimeout: return "timeout";
    case TransportResult::kDisconnected: return "disconnected";
    case TransportResult::kNotFound: return "not_found";
    case TransportResult::kNoAccess: return "no_access";
    case TransportResult::kError: return "error";
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
    const int rc = libusb_open(list[i], &handle);
    if (rc != LIBUSB_SUCCESS) {
      result = FromLibusb(rc);
      if (result == TransportResult::kNotFound) result = TransportResult::kError;
      SetError("libusb_open", rc);
      continue;
    }
    std::string serial;
    try {
      serial = ReadSerial(handle, desc);
    } catch (...) {
    }
    if (!serial_.empty() && serial != serial_) {
      libusb_close(handle);
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
      libusb_close(handle);
      continue;
    }
    handle_ = handle;
    result = TransportResult::kOk;
    error_[0] = '\0';
  }
  libusb_free_device_list(list, 1);
  return result;
}

void LibusbTransport::Close() noexcept {
  if (handle_ == nullptr) return;
  libusb_release_interface(handle_, kInterface);
  if (kernel_driver_detached_) libusb_attach_kernel_driver(handle_, kInterface);
  libusb_close(handle_);
  handle_ = nullptr;
  kernel_driver_detached_ = false;
}

TransportResult LibusbTransport::Send(const std::uint8_t* data, std::size_t size,
                                      int timeout_ms) noexcept {
  if (handle_ == nullptr) return TransportResult::kDisconnected;
  int transferred = 0;
  // libusb takes a non-const buffer for both directions; an OUT transfer does not write it.
  const int rc = libusb_bulk_transfer(handle_, kEndpointOut, const_cast<std::uint8_t*>(data),
                                      static_cast<int>(size), &transferred,
                                      timeout_ms > 0 ? static_cast<unsigned>(timeout_ms) : 1u);
  if (rc == LIBUSB_SUCCESS && transferred != static_cast<int>(size)) {
    std::snprintf(error_, sizeof(error_), "short write: %d of %d bytes", transferred,
                  static_cast<int>(size));
    return TransportResult::kError;
  }
  const TransportResult result = FromLibusb(rc);
  if (result == TransportResult::kDisconnected) {
    SetError("bulk OUT", rc);
    Close();
  } else if (result != TransportResult::kOk && result != TransportResult::kTimeout) {
    SetError("bulk OUT", rc);
  }
  return result;
}

TransportResult LibusbTransport::Receive(std::uint8_t* data, std::size_t capacity,
                                         std::size_t* received, int timeout_ms) noexcept {
  *received = 0;
  if (handle_ == nullptr) return TransportResult::kDisconnected;
  int transferred = 0;
  const int rc = libusb_bulk_transfer(handle_, kEndpointIn, data, static_cast<int>(capacity),
                                      &transferred,
                                      timeout_ms > 0 ? static_cast<unsigned>(timeout_ms) : 1u);
  // A timeout may still have delivered bytes; a partial packet fails the length check later.
  *received = static_cast<std::size_t>(transferred > 0 ? transferred : 0);
  if (rc == LIBUSB_ERROR_TIMEOUT && transferred > 0) return TransportResult::kOk;
  const TransportResult result = FromLibusb(rc);
  if (result == TransportResult::kDisconnected) {
    SetError("bulk IN", rc);
    Close();
  } else if (result != TransportResult::kOk && result != TransportResult::kTimeout) {
    SetError("bulk IN", rc);
  }
  return result;
}

UsbEnumeration ListUsbBoards(std::uint16_t vendor_id, std::uint16_t product_id) noexcept {
  UsbEnumeration out;
  try {
    libusb_context* context = nullptr;
    const int rc = libusb_init(&context);
    if (rc != LIBUSB_SUCCESS) {
      out.error = std::string("libusb_init failed: ") +
                  libusb_strerror(static_cast<libusb_error>(rc));
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
