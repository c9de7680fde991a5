// UsbSpidarG: the SPIDAR-G driver over a packet Transport (libusb for a real board, the
// loopback for the board simulator). Each Read waits for one State packet, validates it
// (length, magic, CRC, version, type) and checks its sequence (stale or reordered packets are
// dropped, gaps counted as lost); each WriteTensions sends one Command. A tick without a fresh
// valid State reports kCommError and the driver commands zero force (motors disabled) until
// data flows again; after `disconnect_after` such ticks, or an unplug, it closes the transport
// (kNotConnected) and re-opens it every `reconnect_every` Reads until the board answers the
// handshake again. Nothing throws; the app stays alive whatever the board does.
// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#pragma once

#include <cstdint>
#include <memory>

#include "spidarcad/haptics/device.h"
#include "spidarcad/haptics/usb_protocol.h"
#include "spidarcad/haptics/usb_transport.h"

namespace spidarcad::haptics::usb {

// Timeouts and recovery policy of the driver.
struct UsbDeviceConfig {
  int receive_timeout_ms = 2;      // wait for a State per Read (a sample is due every 1 ms)
  int send_timeout_ms = 2;         // per Command
  int handshake_timeout_ms = 100;  // per HelloReply wait
  int handshake_attempts = 5;      // Hello retries per Open
  int max_packets_per_read = 3;    // invalid/stale packets skipped before giving up the tick
  std::uint16_t watchdog_ms = 20;  // asked of the board in Hello
  int disconnect_after = 50;       // consecutive failed Reads -> kNotConnected, transport closed
  int reconnect_every = 200;       // Reads between re-open attempts (0: only explicit Open).
                                   // NOTE: re-opening libusb allocates; set 0 and call Open from
                                   // a non-real-time thread when that matters.
  std::uint32_t max_command_lag = 20;  // commands the board has not applied -> kCommError
};

// What the driver saw on the link since construction.
struct UsbLinkStats {
  std::uint64_t states = 0;            // fresh valid State packets accepted
  std::uint64_t timeouts = 0;          // Reads where nothing arrived
  std::uint64_t corrupt = 0;           // bad length, magic or CRC
  std::uint64_t wrong_version = 0;     // valid packets of another protocol version
  std::uint64_t wrong_type = 0;        // valid packets of an unexpected type
  std::uint64_t stale = 0;             // State not newer than the last accepted (reordered/repeat)
  std::uint64_t lost = 0;              // State sequence numbers skipped
  std::uint64_t send_failures = 0;     // Commands that could not be sent
  std::uint64_t comm_error_ticks = 0;  // Reads that returned kCommError
  std::uint64_t disconnects = 0;       // transport closed by the driver or unplugged
  std::uint64_t connects = 0;          // successful handshakes
};

// The driver. Read/WriteTensions/status are noexcept, allocation-free and lock-free on a
// connected link (see UsbDeviceConfig::reconnect_every for the one exception).
class UsbSpidarG final : public Device {
 public:
  // `info` describes the device (geometry, encoder, homing pose, tension range); the board
  // cannot report geometry. Does not open the transport: call Open().
  UsbSpidarG(std::unique_ptr<Transport> transport, const DeviceInfo& info,
             const UsbDeviceConfig& config = {});
  // Sends a motors-off Command (best effort) and closes the transport.
  ~UsbSpidarG() override;
  UsbSpidarG(const UsbSpidarG&) = delete;
  UsbSpidarG& operator=(const UsbSpidarG&) = delete;

  // Opens the transport and runs the Hello handshake. kOk on success (status() then reads
  // kCommError until the first State arrives at the next Read); kNotConnected when no board
  // answers (see last_error()); kFault when the board speaks another protocol version.
  DeviceStatus Open() noexcept;
  // Motors off (best effort), transport closed, status kNotConnected.
  void Close() noexcept;

  const DeviceInfo& info() const noexcept override { return info_; }
  DeviceStatus Read(EncoderReading* reading) noexcept override;
  DeviceStatus WriteTensions(const Vector8d& tension) noexcept override;
  DeviceStatus status() const noexcept override { return status_; }

  // Latches a software emergency stop on the board (true) or clears it (false).
  void SetEmergencyStop(bool stop) noexcept {
    emergency_stop_ = stop;
    clear_stop_ = !stop;
  }
  // Link statistics.
  const UsbLinkStats& stats() const noexcept { return stats_; }
  // The board's HelloReply from the last successful handshake.
  const HelloReplyPacket& board_info() const noexcept { return board_; }
  // Why the last Open failed, or what broke the link (fixed buffer, never null).
  const char* last_error() const noexcept { return error_; }
  Transport& transport() noexcept { return *transport_; }

 private:
  void Disconnect(const char* why) noexcept;
  void SendCommand(const Vector8d* tension) noexcept;

  std::unique_ptr<Transport> transport_;
  DeviceInfo info_;
  UsbDeviceConfig config_;
  DeviceStatus status_ = DeviceStatus::kNotConnected;
  UsbLinkStats stats_;
  HelloReplyPacket board_{};
  StatePacket last_state_{};
  bool have_state_ = false;
  std::uint32_t command_sequence_ = 0;
  int consecutive_failures_ = 0;
  int reads_since_attempt_ = 0;
  bool emergency_stop_ = false;
  bool clear_stop_ = false;
  Packet buffer_{};
  char error_[320] = {};
};

}  // namespace spidarcad::haptics::usb
