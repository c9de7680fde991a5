// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#include "spidarcad/haptics/board_simulator.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <stdexcept>
#include <string>

namespace spidarcad::haptics::usb {
namespace {

// True when sequence `a` is after `b` (wrap-around aware).
bool After(std::uint32_t a, std::uint32_t b) noexcept {
  return static_cast<std::int32_t>(a - b) > 0;
}

}  // namespace

BoardSimulator::BoardSimulator(const BoardConfig& config)
    : config_(config), device_(config.device) {
  if (!(config.sample_period > 0.0) || config.sample_period > 0.1) {
    throw std::invalid_argument("BoardConfig.sample_period must be in (0, 0.1] s, got " +
                                std::to_string(config.sample_period));
  }
  watchdog_ms_ = config.default_watchdog_ms;
}

DecodeResult BoardSimulator::HandlePacket(const std::uint8_t* data, std::size_t size) noexcept {
  PacketType type{};
  DecodeResult result = Inspect(data, size, &type);
  if (result != DecodeResult::kOk) {
    ++rejected_;
    return result;
  }
  if (type == PacketType::kHello) {
    HelloPacket hello;
    result = Decode(data, size, &hello);
    if (result != DecodeResult::kOk) return result;
    // A new session: motors off until a Command enables them.
    session_open_ = true;
    motors_enabled_ = false;
    watchdog_tripped_ = false;
    applied_.setZero();
    watchdog_ms_ = std::clamp<std::uint16_t>(hello.watchdog_ms, 5, 1000);
    last_command_sequence_ = hello.sequence;
    last_command_time_us_ = time_us_;
    reply_ = HelloReplyPacket{};
    reply_.sequence = hello.sequence;
    reply_.firmware_version = config_.firmware_version;
    reply_.watchdog_ms = watchdog_ms_;
    reply_.tension_max_mn = TensionToMilliNewton(config_.device.tension_max);
    reply_.counts_per_rev = static_cast<std::uint16_t>(config_.device.encoder.counts_per_rev);
    reply_.sample_period_us = static_cast<std::uint16_t>(std::lround(config_.sample_period * 1e6));
    reply_.serial = config_.serial;
    reply_pending_ = true;
    return result;
  }
  if (type == PacketType::kCommand) {
    CommandPacket command;
    result = Decode(data, size, &command);
    if (result != DecodeResult::kOk) return result;
    // Commands before a Hello, and commands not newer than the last applied, are dropped.
    if (!session_open_ || !After(command.sequence, last_command_sequence_)) {
      ++rejected_;
      return result;
    }
    last_command_sequence_ = command.sequence;
    last_command_time_us_ = time_us_;
    watchdog_tripped_ = false;
    if (command.flags & kCommandClearFault) stop_latched_ = false;
    if (command.flags & kCommandStop) stop_latched_ = true;
    const bool hardware_ok = device_.status() == DeviceStatus::kOk;
    motors_enabled_ = (command.flags & kCommandEnable) && !stop_latched_ && hardware_ok;
    const std::uint16_t max_mn = TensionToMilliNewton(config_.device.tension_max);
    for (int i = 0; i < kNumStrings; ++i) {
      const std::uint16_t mn = std::min(command.tension_mn[i], max_mn);
      applied_[i] = motors_enabled_ ? MilliNewtonToTension(mn) : 0.0;
    }
    return result;
  }
  // HelloReply and State only travel board -> host.
  ++rejected_;
  return DecodeResult::kWrongType;
}

bool BoardSimulator::TakeReply(Packet* out) noexcept {
  if (!reply_pending_) return false;
  reply_pending_ = false;
  Encode(reply_, out);
  if (config_.protocol_version != kProtocolVersion) {
    SetVersionForTesting(config_.protocol_version, out);
  }
  return true;
}

bool BoardSimulator::Tick(Packet* out) noexcept {
  time_us_ += static_cast<std::uint64_t>(std::llround(config_.sample_period * 1e6));
  // Watchdog: no valid Command for longer than the period -> motors off.
  if (session_open_ && motors_enabled_ &&
      time_us_ - last_command_time_us_ > 1000ull * watchdog_ms_) {
    motors_enabled_ = false;
    watchdog_tripped_ = true;
    ++watchdog_trips_;
    applied_.setZero();
  }
  if (device_.status() != DeviceStatus::kOk || stop_latched_) {
    motors_enabled_ = false;
    applied_.setZero();
  }
  device_.WriteTensions(applied_);
  device_.Step(config_.sample_period);
  if (!session_open_) return false;
  ++state_sequence_;
  Emit(out);
  return true;
}

void BoardSimulator::Emit(Packet* out) noexcept {
  EncoderReading reading;
  device_.Read(&reading);
  StatePacket state;
  state.sequence = state_sequence_;
  state.time_us = time_us_;
  state.counts = reading.counts;
  state.command_sequence = last_command_sequence_;
  state.slack_mask = reading.slack_mask;
  std::uint8_t flags = 0;
  if (motors_enabled_) flags |= kStateMotorsEnabled;
  if (watchdog_tripped_) flags |= kStateWatchdogTripped;
  if (stop_latched_ || device_.status() == DeviceStatus::kStopped) flags |= kStateEmergencyStop;
  if (device_.status() == DeviceStatus::kFault) flags |= kStateFault;
  state.flags = flags;
  Encode(state, out);
  if (config_.protocol_version != kProtocolVersion) {
    SetVersionForTesting(config_.protocol_version, out);
  }
  // Oracle for tests: what was sent under this sequence.
  history_[state_sequence_ % 256] = reading.counts;
  history_sequence_[state_sequence_ % 256] = state_sequence_;
}

void BoardSimulator::PowerCycle() noexcept {
  session_open_ = false;
  motors_enabled_ = false;
  stop_latched_ = false;
  watchdog_tripped_ = false;
  reply_pending_ = false;
  applied_.setZero();
  state_sequence_ = 0;
  last_command_sequence_ = 0;
  watchdog_ms_ = config_.default_watchdog_ms;
  history_sequence_.fill(0);
}

bool BoardSimulator::SentCounts(std::uint32_t sequence, EncoderCounts* counts) const noexcept {
  if (sequence == 0 || history_sequence_[sequence % 256] != sequence) return false;
  *counts = history_[sequence % 256];
  return true;
}

// ---------------------------------------------------------------------------------------------

LoopbackTransport::LoopbackTransport(BoardSimulator* board, const LinkFaults& faults)
    : board_(board), faults_(faults), rng_state_(faults.seed * 0x9E3779B97F4A7C15ull + 1) {}

void LoopbackTransport::set_faults(const LinkFaults& faults) noexcept { faults_ = faults; }

double LoopbackTransport::Uniform() noexcept {
  // splitmix64
  std::uint64_t z = (rng_state_ += 0x9E3779B97F4A7C15ull);
  z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
  z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
  z ^= z >> 31;
  return static_cast<double>(z >> 11) * 0x1.0p-53;
}

TransportResult LoopbackTransport::Open() noexcept {
  if (!plugged_) {
    std::snprintf(error_, sizeof(error_), "loopback: board unplugged");
    return TransportResult::kNotFound;
  }
  open_ = true;
  count_ = 0;
  head_ = 0;
  held_valid_ = false;
  error_[0] = '\0';
  return TransportResult::kOk;
}

void LoopbackTransport::Close() noexcept {
  open_ = false;
  count_ = 0;
  held_valid_ = false;
}

void LoopbackTransport::SetPlugged(bool plugged) noexcept {
  if (plugged && !plugged_) board_->PowerCycle();
  plugged_ = plugged;
  if (!plugged) {
    open_ = false;
    count_ = 0;
    held_valid_ = false;
    std::snprintf(error_, sizeof(error_), "loopback: board unplugged");
  }
}

bool LoopbackTransport::Damage(Packet* packet) noexcept {
  if (faults_.loss > 0.0 && Uniform() < faults_.loss) {
    ++counters_.lost;
    return false;
  }
  if (faults_.corruption > 0.0 && Uniform() < faults_.corruption) {
    const int flips = 1 + static_cast<int>(Uniform() * 3.0);
    for (int k = 0; k < flips; ++k) {
      const int bit = std::min(static_cast<int>(Uniform() * kPacketSize * 8),
                               static_cast<int>(kPacketSize * 8) - 1);
      (*packet)[bit / 8] ^= static_cast<std::uint8_t>(1u << (bit % 8));
    }
    ++counters_.corrupted;
  }
  return true;
}

void LoopbackTransport::Push(const Packet& packet) noexcept {
  if (count_ == kQueueSize) {  // overflow: the oldest is lost, like a full FIFO
    head_ = (head_ + 1) % kQueueSize;
    --count_;
    ++counters_.lost;
  }
  queue_[(head_ + count_) % kQueueSize] = packet;
  ++count_;
}

void LoopbackTransport::Enqueue(const Packet& packet) noexcept {
  Packet copy = packet;
  if (!Damage(&copy)) return;
  if (!held_valid_ && faults_.reorder > 0.0 && Uniform() < faults_.reorder) {
    held_ = copy;
    held_valid_ = true;
    ++counters_.reordered;
    return;
  }
  Push(copy);
  if (held_valid_) {
    Push(held_);
    held_valid_ = false;
  }
}

TransportResult LoopbackTransport::Send(const std::uint8_t* data, std::size_t size,
                                        int /*timeout_ms*/) noexcept {
  if (!plugged_ || !open_) return TransportResult::kDisconnected;
  if (size > kPacketSize) return TransportResult::kError;
  if (stall_remaining_ > 0) return TransportResult::kTimeout;  // endpoint NAKs
  Packet packet{};
  std::memcpy(packet.data(), data, size);
  if (!Damage(&packet)) return TransportResult::kOk;  // lost on the wire: the host can't tell
  ++counters_.delivered;
  board_->HandlePacket(packet.data(), size);
  Packet reply;
  if (board_->TakeReply(&reply)) Enqueue(reply);
  return TransportResult::kOk;
}

TransportResult LoopbackTransport::Receive(std::uint8_t* data, std::size_t capacity,
                                           std::size_t* received, int timeout_ms) noexcept {
  *received = 0;
  if (!plugged_ || !open_) return TransportResult::kDisconnected;
  if (count_ == 0 && timeout_ms > 0) {
    // The host waits: the board runs one sample period.
    if (stall_remaining_ == 0 && faults_.stall > 0.0 && Uniform() < faults_.stall) {
      stall_remaining_ = faults_.stall_ticks;
    }
    Packet state;
    const bool emitted = board_->Tick(&state);
    if (stall_remaining_ > 0) {
      --stall_remaining_;
      ++counters_.stalled_ticks;
    } else if (emitted) {
      Enqueue(state);
    }
  }
  if (count_ == 0) return TransportResult::kTimeout;
  const Packet& packet = queue_[head_];
  head_ = (head_ + 1) % kQueueSize;
  --count_;
  const std::size_t n = std::min(capacity, kPacketSize);
  std::memcpy(data, packet.data(), n);
  *received = n;
  ++counters_.delivered;
  return TransportResult::kOk;
}

}  // namespace spidarcad::haptics::usb
