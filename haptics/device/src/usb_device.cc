// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#include "spidarcad/haptics/usb_device.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <utility>

namespace spidarcad::haptics::usb {
namespace {

bool After(std::uint32_t a, std::uint32_t b) noexcept {
  return static_cast<std::int32_t>(a - b) > 0;
}

}  // namespace

UsbSpidarG::UsbSpidarG(std::unique_ptr<Transport> transport, const DeviceInfo& info,
                       const UsbDeviceConfig& config)
    : transport_(std::move(transport)), info_(info), config_(config) {
  std::snprintf(error_, sizeof(error_), "not opened");
}

UsbSpidarG::~UsbSpidarG() { Close(); }

void UsbSpidarG::Close() noexcept {
  if (transport_->is_open()) {
    status_ = DeviceStatus::kNotConnected;
    SendCommand(nullptr);  // motors off
    transport_->Close();
  }
  status_ = DeviceStatus::kNotConnected;
}

// Runs on the tick (Read/WriteTensions): Abandon, not Close, so that a real board's release
// (libusb locks and frees) waits for the next Open or Close, off the tick.
void UsbSpidarG::Disconnect(const char* why) noexcept {
  if (transport_->is_open()) transport_->Abandon();
  if (status_ != DeviceStatus::kNotConnected) ++stats_.disconnects;
  status_ = DeviceStatus::kNotConnected;
  reads_since_attempt_ = 0;
  consecutive_failures_ = 0;
  std::snprintf(error_, sizeof(error_), "%s", why);
}

DeviceStatus UsbSpidarG::Open() noexcept {
  if (transport_->is_open()) transport_->Close();
  status_ = DeviceStatus::kNotConnected;
  const TransportResult opened = transport_->Open();
  if (opened != TransportResult::kOk) {
    const char* hint = opened == TransportResult::kNoAccess
                           ? " (permission denied: install assets/udev/99-spidarcad.rules)"
                           : "";
    std::snprintf(error_, sizeof(error_), "cannot open SPIDAR-G board %04x:%04x: %s%s%s", kVendorId,
                  kProductId, TransportResultName(opened), transport_->last_error()[0] ? ": " : "",
                  transport_->last_error());
    const std::size_t used = std::strlen(error_);
    std::snprintf(error_ + used, sizeof(error_) - used, "%s", hint);
    return status_;
  }
  for (int attempt = 0; attempt < config_.handshake_attempts; ++attempt) {
    HelloPacket hello;
    hello.sequence = ++command_sequence_;
    hello.watchdog_ms = config_.watchdog_ms;
    Encode(hello, &buffer_);
    const TransportResult sent =
        transport_->Send(buffer_.data(), buffer_.size(), config_.handshake_timeout_ms);
    if (sent == TransportResult::kDisconnected) break;
    // Skip States of a previous session until the reply (or a few tries).
    for (int k = 0; k < 4; ++k) {
      std::size_t n = 0;
      const TransportResult got =
          transport_->Receive(buffer_.data(), buffer_.size(), &n, config_.handshake_timeout_ms);
      if (got != TransportResult::kOk) break;
      HelloReplyPacket reply;
      const DecodeResult d = Decode(buffer_.data(), n, &reply);
      if (d == DecodeResult::kWrongVersion) {
        std::snprintf(error_, sizeof(error_),
                      "protocol version mismatch: the board speaks version %u, this driver %u "
                      "(update the firmware or spidarcad)",
                      static_cast<unsigned>(buffer_[2]), static_cast<unsigned>(kProtocolVersion));
        ++stats_.wrong_version;
        transport_->Close();
        status_ = DeviceStatus::kFault;
        return status_;
      }
      if (d == DecodeResult::kOk && reply.sequence == hello.sequence) {
        board_ = reply;
        have_state_ = false;
        consecutive_failures_ = 0;
        reads_since_attempt_ = 0;
        ++stats_.connects;
        // No State yet: not kOk until the first one arrives.
        status_ = DeviceStatus::kCommError;
        error_[0] = '\0';
        return DeviceStatus::kOk;
      }
    }
  }
  std::snprintf(error_, sizeof(error_), "SPIDAR-G board %04x:%04x did not answer the handshake",
                kVendorId, kProductId);
  transport_->Close();
  status_ = DeviceStatus::kNotConnected;
  return status_;
}

DeviceStatus UsbSpidarG::Read(EncoderReading* reading) noexcept {
  if (!transport_->is_open() && status_ != DeviceStatus::kNotConnected &&
      status_ != DeviceStatus::kFault) {
    Disconnect("the board was unplugged");
  }
  if (!transport_->is_open()) {
    status_ = status_ == DeviceStatus::kFault ? status_ : DeviceStatus::kNotConnected;
    if (config_.reconnect_every > 0 && ++reads_since_attempt_ >= config_.reconnect_every) {
      reads_since_attempt_ = 0;
      Open();
    }
  }
  bool fresh = false;
  if (transport_->is_open()) {
    for (int attempt = 0; attempt < config_.max_packets_per_read; ++attempt) {
      std::size_t n = 0;
      const TransportResult got =
          transport_->Receive(buffer_.data(), buffer_.size(), &n, config_.receive_timeout_ms);
      if (got == TransportResult::kDisconnected) {
        Disconnect("the board was unplugged");
        break;
      }
      if (got != TransportResult::kOk) {
        ++stats_.timeouts;
        break;
      }
      StatePacket state;
      const DecodeResult d = Decode(buffer_.data(), n, &state);
      if (d == DecodeResult::kWrongVersion) {
        ++stats_.wrong_version;
        continue;
      }
      if (d == DecodeResult::kWrongType) {
        ++stats_.wrong_type;
        continue;
      }
      if (d != DecodeResult::kOk) {
        ++stats_.corrupt;
        continue;
      }
      if (have_state_ && !After(state.sequence, last_state_.sequence)) {
        ++stats_.stale;
        continue;
      }
      if (have_state_) stats_.lost += state.sequence - last_state_.sequence - 1;
      last_state_ = state;
      have_state_ = true;
      fresh = true;
      ++stats_.states;
      break;
    }
  }
  if (transport_->is_open()) {
    if (fresh) {
      consecutive_failures_ = 0;
      if (last_state_.flags & kStateFault) {
        status_ = DeviceStatus::kFault;
      } else if (last_state_.flags & kStateEmergencyStop) {
        status_ = DeviceStatus::kStopped;
      } else if (After(command_sequence_, last_state_.command_sequence + config_.max_command_lag)) {
        status_ = DeviceStatus::kCommError;  // the board is not getting our commands
        ++stats_.comm_error_ticks;
      } else {
        status_ = DeviceStatus::kOk;
      }
    } else {
      status_ = DeviceStatus::kCommError;
      ++stats_.comm_error_ticks;
      if (++consecutive_failures_ >= config_.disconnect_after) {
        Disconnect("no valid data from the board; reconnecting");
      }
    }
  }
  if (reading != nullptr) {
    reading->counts = last_state_.counts;
    reading->sequence = last_state_.sequence;
    reading->time = 1e-6 * static_cast<double>(last_state_.time_us);
    reading->slack_mask = last_state_.slack_mask;
    reading->status = status_;
  }
  return status_;
}

void UsbSpidarG::SendCommand(const Vector8d* tension) noexcept {
  CommandPacket command;
  command.sequence = ++command_sequence_;
  if (tension != nullptr) {
    for (int i = 0; i < kNumStrings; ++i) {
      double t = (*tension)[i];
      if (std::isnan(t)) t = 0.0;
      t = std::clamp(t, info_.tension_min, info_.tension_max);
      command.tension_mn[i] = TensionToMilliNewton(t);
    }
    command.flags = kCommandEnable;
  }
  if (emergency_stop_) command.flags = kCommandStop;
  if (clear_stop_) {
    command.flags |= kCommandClearFault;
    clear_stop_ = false;
  }
  Encode(command, &buffer_);
  const TransportResult sent =
      transport_->Send(buffer_.data(), buffer_.size(), config_.send_timeout_ms);
  if (sent == TransportResult::kDisconnected) {
    Disconnect("the board was unplugged");
  } else if (sent != TransportResult::kOk) {
    ++stats_.send_failures;
  }
}

DeviceStatus UsbSpidarG::WriteTensions(const Vector8d& tension) noexcept {
  if (!transport_->is_open()) return status_;
  // Anything but kOk: zero force (motors disabled), and report that nothing was applied.
  SendCommand(status_ == DeviceStatus::kOk ? &tension : nullptr);
  return status_;
}

}  // namespace spidarcad::haptics::usb
