// The wire protocol between the host and a SPIDAR-G controller board over USB (docs/protocol.md
// is the specification; this file is its executable form). Every packet is kPacketSize bytes,
// little-endian, framed by a magic, a protocol version, a packet type and a sequence number,
// and closed by a CRC-16/CCITT-FALSE over all preceding bytes.
// Encode/Decode work on caller-provided fixed buffers: noexcept, no allocation, no I/O, so the
// 1 kHz haptic tick may call them.
// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>

#include "spidarcad/haptics/geometry.h"

namespace spidarcad::haptics::usb {

// PLACEHOLDER ids for prototypes: 0x1209 is pid.codes' shared vendor id and 0x0001 one of its
// test product ids. A board that ships must be given its own allocated product id.
inline constexpr std::uint16_t kVendorId = 0x1209;
// See kVendorId: a pid.codes test product id, for prototypes only.
inline constexpr std::uint16_t kProductId = 0x0001;
// USB interface number that carries the protocol (vendor-specific class 0xFF).
inline constexpr int kInterface = 0;
// Bulk OUT endpoint: host -> board (Hello, Command).
inline constexpr std::uint8_t kEndpointOut = 0x01;
// Bulk IN endpoint: board -> host (HelloReply, State).
inline constexpr std::uint8_t kEndpointIn = 0x81;

// Size of every packet, bytes (one full-speed bulk max packet).
inline constexpr std::size_t kPacketSize = 64;
// Protocol version this code speaks; the board must report the same.
inline constexpr std::uint8_t kProtocolVersion = 1;
// The two magic bytes at offset 0: 'S', 'G'.
inline constexpr std::uint8_t kMagic0 = 0x53;
// Second magic byte.
inline constexpr std::uint8_t kMagic1 = 0x47;
// Offset of the CRC-16 (the last two bytes); the CRC covers bytes [0, kCrcOffset).
inline constexpr std::size_t kCrcOffset = kPacketSize - 2;

// One packet on the wire.
using Packet = std::array<std::uint8_t, kPacketSize>;

// Packet type byte (offset 3).
enum class PacketType : std::uint8_t {
  kHello = 0x01,       // host -> board: start a session, ask for a watchdog period
  kHelloReply = 0x02,  // board -> host: firmware description
  kCommand = 0x10,     // host -> board: motor tensions and enable flags
  kState = 0x20,       // board -> host: encoder sample
};

// Command flags (Command offset 24).
inline constexpr std::uint8_t kCommandEnable = 0x01;      // drive the motors (else all off)
inline constexpr std::uint8_t kCommandStop = 0x02;        // software emergency stop (latched)
inline constexpr std::uint8_t kCommandClearFault = 0x04;  // clear a latched fault / stop

// State flags (State offset 53).
inline constexpr std::uint8_t kStateMotorsEnabled = 0x01;    // motor drivers on
inline constexpr std::uint8_t kStateWatchdogTripped = 0x02;  // commands stopped; motors off
inline constexpr std::uint8_t kStateEmergencyStop = 0x04;    // e-stop (button or kCommandStop)
inline constexpr std::uint8_t kStateFault = 0x08;            // driver / encoder fault

// Host -> board: open a session. Motors stay off until a Command with kCommandEnable.
struct HelloPacket {
  std::uint32_t sequence = 0;      // host sequence number
  std::uint16_t watchdog_ms = 20;  // requested watchdog period, ms (board clamps to 5..1000)
};

// Board -> host: answer to Hello.
struct HelloReplyPacket {
  std::uint32_t sequence = 0;          // echoes the Hello's sequence
  std::uint16_t firmware_version = 0;  // board firmware version (informative)
  std::uint16_t watchdog_ms = 0;       // watchdog period in force, ms
  std::uint16_t tension_max_mn = 0;    // largest tension the board applies, mN
  std::uint16_t counts_per_rev = 0;    // encoder counts per pulley revolution
  std::uint16_t sample_period_us = 0;  // State period, µs (1000 at 1 kHz)
  std::array<char, 16> serial{};       // ASCII serial number, NUL-padded
};

// Host -> board: motor command.
struct CommandPacket {
  std::uint32_t sequence = 0;                           // host sequence, +1 per command
  std::array<std::uint16_t, kNumStrings> tension_mn{};  // string tensions, mN (0..65535)
  std::uint8_t flags = 0;                               // kCommand* bits
};

// Board -> host: one encoder sample.
struct StatePacket {
  std::uint32_t sequence = 0;                      // board sample counter, +1 per sample
  std::uint64_t time_us = 0;                       // board time of the sample, µs since power-up
  std::array<std::int32_t, kNumStrings> counts{};  // encoder counters since homing
  std::uint32_t command_sequence = 0;              // sequence of the last Command the board applied
  std::uint8_t slack_mask = 0;  // bit i: string i commanded below the slack threshold
  std::uint8_t flags = 0;       // kState* bits
};

// Why a buffer was not accepted.
enum class DecodeResult : std::uint8_t {
  kOk = 0,
  kWrongLength,   // not exactly kPacketSize bytes
  kBadMagic,      // bytes 0..1 are not 'S','G'
  kBadChecksum,   // CRC-16 mismatch (corruption)
  kWrongVersion,  // a valid packet of another protocol version
  kWrongType,     // a valid packet of another type than asked for
};

// One word for a decode result ("ok", "wrong_length", ...).
const char* DecodeResultName(DecodeResult result) noexcept;

// CRC-16/CCITT-FALSE (poly 0x1021, init 0xFFFF, no reflection, no final xor) of `size` bytes.
std::uint16_t Crc16(const std::uint8_t* data, std::size_t size) noexcept;

// Encoders: fill all kPacketSize bytes of `out` (reserved bytes zero, CRC last).
void Encode(const HelloPacket& packet, Packet* out) noexcept;
// See Encode(HelloPacket).
void Encode(const HelloReplyPacket& packet, Packet* out) noexcept;
// See Encode(HelloPacket).
void Encode(const CommandPacket& packet, Packet* out) noexcept;
// See Encode(HelloPacket).
void Encode(const StatePacket& packet, Packet* out) noexcept;

// Checks length, magic, CRC and version in that order (type not checked) and returns the type
// byte in `type` when the result is kOk.
DecodeResult Inspect(const std::uint8_t* data, std::size_t size, PacketType* type) noexcept;

// Decoders: Inspect, then the type; `out` is written only on kOk.
DecodeResult Decode(const std::uint8_t* data, std::size_t size, HelloPacket* out) noexcept;
// See Decode(HelloPacket).
DecodeResult Decode(const std::uint8_t* data, std::size_t size, HelloReplyPacket* out) noexcept;
// See Decode(HelloPacket).
DecodeResult Decode(const std::uint8_t* data, std::size_t size, CommandPacket* out) noexcept;
// See Decode(HelloPacket).
DecodeResult Decode(const std::uint8_t* data, std::size_t size, StatePacket* out) noexcept;

// N -> mN for the wire: NaN and negatives -> 0, rounded to the nearest mN, saturated at 65535.
std::uint16_t TensionToMilliNewton(double tension) noexcept;
// mN -> N.
inline double MilliNewtonToTension(std::uint16_t mn) noexcept { return 1e-3 * mn; }

// Re-stamps the version byte of an encoded packet and recomputes its CRC (tests and the
// simulator's "other firmware" mode).
void SetVersionForTesting(std::uint8_t version, Packet* packet) noexcept;

}  // namespace spidarcad::haptics::usb
