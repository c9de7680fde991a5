// Byte transport between the host driver and a SPIDAR-G controller board: one fixed-size
// packet per call, with a timeout. Two implementations: LibusbTransport (a real board,
// libusb_transport.cc) and LoopbackTransport (an in-process board simulator with fault
// injection, board_simulator.h). Send/Receive are noexcept and allocate nothing per call;
// Open/Close may allocate (libusb does) and belong outside the haptic tick. LibusbTransport uses
// libusb only off the tick (find, open, claim, release); each Send/Receive is one Linux usbfs
// USBDEVFS_BULK ioctl on the device node it opened itself (no user-space allocation). That
// success path needs a board and is not exercised by the tests.
// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#pragma once

#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

#include "spidarcad/haptics/usb_protocol.h"

// libusb's opaque types, declared so that this header does not need <libusb.h>.
struct libusb_context;
struct libusb_device_handle;

namespace spidarcad::haptics::usb {

// Outcome of a transport call.
enum class TransportResult : std::uint8_t {
  kOk = 0,
  kTimeout,       // nothing arrived / could not be sent within the timeout
  kDisconnected,  // the device is gone (unplugged) or was never opened
  kNotFound,      // Open: no device with the vendor/product id
  kNoAccess,      // Open: found, but the user may not open it (udev rules missing)
  kError,         // any other failure (see last_error())
};

// One word for a transport result ("ok", "timeout", ...).
const char* TransportResultName(TransportResult result) noexcept;

// A packet pipe to one board.
class Transport {
 public:
  virtual ~Transport() = default;
  // Finds and claims the board. May allocate; not for the haptic tick.
  virtual TransportResult Open() noexcept = 0;
  // Releases the board. Safe to call when not open.
  virtual void Close() noexcept = 0;
  // Stops using the board at once, from the haptic tick: is_open() turns false and nothing is
  // sent or received; the release itself may be deferred to the next Open() or Close() (off the
  // tick). Default: Close().
  virtual void Abandon() noexcept { Close(); }
  // True between a successful Open and Close / a detected unplug.
  virtual bool is_open() const noexcept = 0;
  // Sends `size` bytes as one transfer. timeout_ms <= 0: as short as the transport allows.
  virtual TransportResult Send(const std::uint8_t* data, std::size_t size,
                               int timeout_ms) noexcept = 0;
  // Receives one transfer of at most `capacity` bytes into `data`; `*received` is its length.
  // timeout_ms <= 0: only what is already buffered (usbfs: the shortest wait, 1 ms).
  virtual TransportResult Receive(std::uint8_t* data, std::size_t capacity, std::size_t* received,
                                  int timeout_ms) noexcept = 0;
  // Human-readable detail of the last failure (empty if none). Points to a fixed buffer.
  virtual const char* last_error() const noexcept = 0;
};

// A SPIDAR-G board: libusb finds vendor/product id (and serial) and claims kInterface on the
// device node /dev/bus/usb/BBB/DDD that this class opens itself (libusb_wrap_sys_device); Send
// and Receive are USBDEVFS_BULK ioctls on that node. Linux only. When a transfer finds the
// board unplugged, Send/Receive return kDisconnected and is_open() turns false without calling
// libusb; the stale handle is released by the next Open() or Close() (off the tick).
class LibusbTransport final : public Transport {
 public:
  // `serial`: open only the board with this serial number (empty: the first one found).
  explicit LibusbTransport(std::uint16_t vendor_id = kVendorId,
                           std::uint16_t product_id = kProductId, std::string serial = {});
  ~LibusbTransport() override;
  LibusbTransport(const LibusbTransport&) = delete;
  LibusbTransport& operator=(const LibusbTransport&) = delete;

  TransportResult Open() noexcept override;
  void Close() noexcept override;
  // Tick-safe: only marks the link unused (no libusb call); Open()/Close() release it.
  void Abandon() noexcept override { abandoned_ = true; }
  bool is_open() const noexcept override { return handle_ != nullptr && !lost_ && !abandoned_; }
  TransportResult Send(const std::uint8_t* data, std::size_t size,
                       int timeout_ms) noexcept override;
  TransportResult Receive(std::uint8_t* data, std::size_t capacity, std::size_t* received,
                          int timeout_ms) noexcept override;
  const char* last_error() const noexcept override { return error_; }

 private:
  void SetError(const char* what, int code) noexcept;
  // Records a failed transfer (errno `error_number`) in error_; on a device-gone errno marks
  // the link lost. Tick-safe: snprintf into error_ only.
  TransportResult TransferFailed(const char* what, TransportResult result,
                                 int error_number) noexcept;
  // Opens the device node of bus/address, wraps it in a libusb handle. Sets error_ on failure.
  TransportResult OpenNode(int bus, int address, libusb_device_handle** handle, int* fd) noexcept;

  std::uint16_t vendor_id_;
  std::uint16_t product_id_;
  std::string serial_;
  libusb_context* context_ = nullptr;
  libusb_device_handle* handle_ = nullptr;
  bool kernel_driver_detached_ = false;
  int fd_ = -1;             // the usbfs device node under handle_ (libusb_close does not close it)
  bool lost_ = false;       // a transfer found the device gone; handle_ awaits release off the tick
  bool abandoned_ = false;  // Abandon() was called; handle_ awaits release off the tick
  char error_[200] = {};
};

// One SPIDAR-G board seen on the USB bus.
struct UsbBoardInfo {
  std::uint16_t vendor_id = 0;
  std::uint16_t product_id = 0;
  int bus = 0;               // bus number
  int address = 0;           // device address on the bus
  std::string serial;        // serial number string; empty if it could not be read
  bool accessible = false;   // the current user could open it
  std::string access_error;  // why it could not be opened (when !accessible)
};

// Result of scanning the bus for boards.
struct UsbEnumeration {
  bool usb_available = false;        // libusb initialised
  std::string error;                 // why not (when !usb_available)
  int devices_seen = 0;              // USB devices of any kind on the system
  std::vector<UsbBoardInfo> boards;  // matching vendor/product id
};

// Lists the boards with `vendor_id`/`product_id`. Never throws; not for the haptic tick.
UsbEnumeration ListUsbBoards(std::uint16_t vendor_id = kVendorId,
                             std::uint16_t product_id = kProductId) noexcept;

}  // namespace spidarcad::haptics::usb
