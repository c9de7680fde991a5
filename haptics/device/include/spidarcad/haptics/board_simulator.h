// The SPIDAR-G controller board in software: its firmware logic (packet parsing, session
// handshake, motor enable / e-stop, tension clamping, the command watchdog) on top of the
// physical SimulatedSpidarG, speaking docs/protocol.md byte for byte. LoopbackTransport
// connects the host driver to it in-process through the same Transport interface as libusb,
// with seeded fault injection (packet loss, corruption, reordering, stalls, unplug).
// Time: the board advances one sample period per Tick; the loopback ticks it once each time
// the host waits for a packet (Receive with a timeout) and none is buffered, so host and board
// share one virtual clock and runs are deterministic.
// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#pragma once

#include <array>
#include <cstdint>

#include "spidarcad/haptics/encoder.h"
#include "spidarcad/haptics/simulated_device.h"
#include "spidarcad/haptics/usb_protocol.h"
#include "spidarcad/haptics/usb_transport.h"

namespace spidarcad::haptics::usb {

// Settings of the simulated board.
struct BoardConfig {
  SimulatedDeviceConfig device;                      // the physical device behind the board
  double sample_period = 1e-3;                       // s between State packets (1 kHz)
  std::uint16_t firmware_version = 1;                // reported in HelloReply
  std::uint8_t protocol_version = kProtocolVersion;  // another value simulates old firmware
  std::uint16_t default_watchdog_ms = 20;            // used until a Hello asks for another
  std::array<char, 16> serial{'S', 'I', 'M', '-', '0', '0', '0', '1'};  // NUL-padded
};

// The firmware. HandlePacket and Tick are noexcept and allocate nothing.
class BoardSimulator {
 public:
  // Throws std::invalid_argument on a bad device config or sample period.
  explicit BoardSimulator(const BoardConfig& config = {});

  // Firmware receive path: one transfer from the host. Invalid packets are counted and
  // dropped; a Hello queues a HelloReply (see TakeReply). Returns the decode result.
  DecodeResult HandlePacket(const std::uint8_t* data, std::size_t size) noexcept;
  // Moves a pending HelloReply into `out`; false if none.
  bool TakeReply(Packet* out) noexcept;
  // One sample period: watchdog, motors, encoder sample. Writes a State to `out` and returns
  // true while a session is open (after a Hello); false otherwise (the board stays silent).
  bool Tick(Packet* out) noexcept;
  // Power loss and return (unplug/replug): session closed, motors off, sequences restart.
  void PowerCycle() noexcept;

  // The physical device (set the hand's pose, inject an e-stop or a fault, read the truth).
  SimulatedSpidarG& device() noexcept { return device_; }
  const SimulatedSpidarG& device() const noexcept { return device_; }
  const BoardConfig& config() const noexcept { return config_; }
  // True when the motor drivers are enabled.
  bool motors_enabled() const noexcept { return motors_enabled_; }
  // True after the watchdog stopped the motors, until the next valid Command.
  bool watchdog_tripped() const noexcept { return watchdog_tripped_; }
  // Watchdog period in force, ms.
  std::uint16_t watchdog_ms() const noexcept { return watchdog_ms_; }
  // Tensions the firmware applies (after clamping and enable), N.
  const Vector8d& applied_tensions() const noexcept { return applied_; }
  // Sequence of the last Command applied.
  std::uint32_t last_command_sequence() const noexcept { return last_command_sequence_; }
  // Packets dropped because they failed to decode, or were stale Commands.
  std::uint64_t rejected_packets() const noexcept { return rejected_; }
  // Number of watchdog trips since construction.
  std::uint64_t watchdog_trips() const noexcept { return watchdog_trips_; }
  // The counts the board sent in State `sequence`, if among the last 256 (test oracle).
  bool SentCounts(std::uint32_t sequence, EncoderCounts* counts) const noexcept;

 private:
  void Emit(Packet* out) noexcept;

  BoardConfig config_;
  SimulatedSpidarG device_;
  bool session_open_ = false;
  bool motors_enabled_ = false;
  bool stop_latched_ = false;
  bool watchdog_tripped_ = false;
  bool reply_pending_ = false;
  HelloReplyPacket reply_{};
  std::uint16_t watchdog_ms_ = 20;
  std::uint64_t time_us_ = 0;
  std::uint64_t last_command_time_us_ = 0;
  std::uint32_t state_sequence_ = 0;
  std::uint32_t last_command_sequence_ = 0;
  std::uint64_t rejected_ = 0;
  std::uint64_t watchdog_trips_ = 0;
  Vector8d applied_ = Vector8d::Zero();
  std::array<EncoderCounts, 256> history_{};
  std::array<std::uint32_t, 256> history_sequence_{};
};

// Faults the loopback link injects. Probabilities are per packet (per board tick for stalls);
// every draw comes from `seed`.
struct LinkFaults {
  double loss = 0.0;        // a packet (either direction) vanishes
  double corruption = 0.0;  // a packet arrives with 1..3 bits flipped
  double reorder = 0.0;     // a board->host packet is held and delivered after the next one
  double stall = 0.0;       // a stall begins: nothing flows either way for stall_ticks ticks
  int stall_ticks = 50;     // length of a stall, board ticks
  std::uint64_t seed = 1;
};

// What the loopback did to the traffic.
struct LinkCounters {
  std::uint64_t delivered = 0;  // packets handed to the receiver (either direction)
  std::uint64_t lost = 0;
  std::uint64_t corrupted = 0;
  std::uint64_t reordered = 0;
  std::uint64_t stalled_ticks = 0;
};

// In-process transport to a BoardSimulator. Send/Receive are noexcept, allocation-free.
class LoopbackTransport final : public Transport {
 public:
  // `board` must outlive the transport.
  explicit LoopbackTransport(BoardSimulator* board, const LinkFaults& faults = {});

  TransportResult Open() noexcept override;
  void Close() noexcept override;
  bool is_open() const noexcept override { return open_; }
  TransportResult Send(const std::uint8_t* data, std::size_t size,
                       int timeout_ms) noexcept override;
  TransportResult Receive(std::uint8_t* data, std::size_t capacity, std::size_t* received,
                          int timeout_ms) noexcept override;
  const char* last_error() const noexcept override { return error_; }

  // Unplugs (false) or replugs (true) the board; replugging power-cycles it.
  void SetPlugged(bool plugged) noexcept;
  bool plugged() const noexcept { return plugged_; }
  // Starts a stall of `ticks` board ticks now.
  void StartStall(int ticks) noexcept { stall_remaining_ = ticks; }
  // Changes the fault probabilities (the random stream continues).
  void set_faults(const LinkFaults& faults) noexcept;
  const LinkCounters& counters() const noexcept { return counters_; }
  BoardSimulator& board() noexcept { return *board_; }

 private:
  double Uniform() noexcept;
  // Applies loss/corruption; false if the packet is lost.
  bool Damage(Packet* packet) noexcept;
  void Enqueue(const Packet& packet) noexcept;
  void Push(const Packet& packet) noexcept;

  BoardSimulator* board_;
  LinkFaults faults_;
  LinkCounters counters_;
  std::uint64_t rng_state_;
  bool open_ = false;
  bool plugged_ = true;
  int stall_remaining_ = 0;
  static constexpr int kQueueSize = 16;
  std::array<Packet, kQueueSize> queue_{};
  int head_ = 0;
  int count_ = 0;
  bool held_valid_ = false;
  Packet held_{};
  char error_[96] = {};
};

}  // namespace spidarcad::haptics::usb
