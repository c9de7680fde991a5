// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#include "spidarcad/haptics/usb_protocol.h"

#include <cmath>
#include <cstring>

namespace spidarcad::haptics::usb {
namespace {

// Byte offsets of the header (docs/protocol.md, "Packet layouts"); each payload starts at byte 8,
// and its fields are written below at their absolute offsets from the table.
constexpr std::size_t kOffsetMagic = 0;
constexpr std::size_t kOffsetVersion = 2;
constexpr std::size_t kOffsetType = 3;
constexpr std::size_t kOffsetSequence = 4;

void Put16(std::uint8_t* p, std::uint16_t v) noexcept {
  p[0] = static_cast<std::uint8_t>(v);
  p[1] = static_cast<std::uint8_t>(v >> 8);
}
void Put32(std::uint8_t* p, std::uint32_t v) noexcept {
  for (int i = 0; i < 4; ++i) p[i] = static_cast<std::uint8_t>(v >> (8 * i));
}
void Put64(std::uint8_t* p, std::uint64_t v) noexcept {
  for (int i = 0; i < 8; ++i) p[i] = static_cast<std::uint8_t>(v >> (8 * i));
}
std::uint16_t Get16(const std::uint8_t* p) noexcept {
  return static_cast<std::uint16_t>(p[0] | (p[1] << 8));
}
std::uint32_t Get32(const std::uint8_t* p) noexcept {
  std::uint32_t v = 0;
  for (int i = 0; i < 4; ++i) v |= static_cast<std::uint32_t>(p[i]) << (8 * i);
  return v;
}
std::uint64_t Get64(const std::uint8_t* p) noexcept {
  std::uint64_t v = 0;
  for (int i = 0; i < 8; ++i) v |= static_cast<std::uint64_t>(p[i]) << (8 * i);
  return v;
}

// Header, zeroed body; the caller fills the payload and then calls Seal.
std::uint8_t* Begin(PacketType type, std::uint32_t sequence, Packet* out) noexcept {
  std::uint8_t* p = out->data();
  std::memset(p, 0, kPacketSize);
  p[kOffsetMagic] = kMagic0;
  p[kOffsetMagic + 1] = kMagic1;
  p[kOffsetVersion] = kProtocolVersion;
  p[kOffsetType] = static_cast<std::uint8_t>(type);
  Put32(p + kOffsetSequence, sequence);
  return p;
}

void Seal(Packet* out) noexcept { Put16(out->data() + kCrcOffset, Crc16(out->data(), kCrcOffset)); }

DecodeResult Check(const std::uint8_t* data, std::size_t size, PacketType want) noexcept {
  PacketType type{};
  const DecodeResult r = Inspect(data, size, &type);
  if (r != DecodeResult::kOk) return r;
  return type == want ? DecodeResult::kOk : DecodeResult::kWrongType;
}

}  // namespace

const char* DecodeResultName(DecodeResult result) noexcept {
  switch (result) {
    case DecodeResult::kOk:
      return "ok";
    case DecodeResult::kWrongLength:
      return "wrong_length";
    case DecodeResult::kBadMagic:
      return "bad_magic";
    case DecodeResult::kBadChecksum:
      return "bad_checksum";
    case DecodeResult::kWrongVersion:
      return "wrong_version";
    case DecodeResult::kWrongType:
      return "wrong_type";
  }
  return "unknown";
}

namespace {

// CRC-16/CCITT-FALSE table: entry b is the CRC register after shifting byte b through it.
constexpr std::array<std::uint16_t, 256> MakeCrcTable() {
  std::array<std::uint16_t, 256> table{};
  for (int b = 0; b < 256; ++b) {
    std::uint16_t crc = static_cast<std::uint16_t>(b << 8);
    for (int bit = 0; bit < 8; ++bit) {
      crc = (crc & 0x8000) ? static_cast<std::uint16_t>((crc << 1) ^ 0x1021)
                           : static_cast<std::uint16_t>(crc << 1);
    }
    table[b] = crc;
  }
  return table;
}
constexpr std::array<std::uint16_t, 256> kCrcTable = MakeCrcTable();

}  // namespace

std::uint16_t Crc16(const std::uint8_t* data, std::size_t size) noexcept {
  std::uint16_t crc = 0xFFFF;
  for (std::size_t i = 0; i < size; ++i) {
    crc = static_cast<std::uint16_t>((crc << 8) ^ kCrcTable[((crc >> 8) ^ data[i]) & 0xFF]);
  }
  return crc;
}

void Encode(const HelloPacket& packet, Packet* out) noexcept {
  std::uint8_t* p = Begin(PacketType::kHello, packet.sequence, out);
  Put16(p + 8, packet.watchdog_ms);
  Seal(out);
}

void Encode(const HelloReplyPacket& packet, Packet* out) noexcept {
  std::uint8_t* p = Begin(PacketType::kHelloReply, packet.sequence, out);
  Put16(p + 8, packet.firmware_version);
  Put16(p + 10, packet.watchdog_ms);
  Put16(p + 12, packet.tension_max_mn);
  Put16(p + 14, packet.counts_per_rev);
  Put16(p + 16, packet.sample_period_us);
  std::memcpy(p + 18, packet.serial.data(), packet.serial.size());
  Seal(out);
}

void Encode(const CommandPacket& packet, Packet* out) noexcept {
  std::uint8_t* p = Begin(PacketType::kCommand, packet.sequence, out);
  for (int i = 0; i < kNumStrings; ++i) Put16(p + 8 + 2 * i, packet.tension_mn[i]);
  p[24] = packet.flags;
  Seal(out);
}

void Encode(const StatePacket& packet, Packet* out) noexcept {
  std::uint8_t* p = Begin(PacketType::kState, packet.sequence, out);
  Put64(p + 8, packet.time_us);
  for (int i = 0; i < kNumStrings; ++i) {
    Put32(p + 16 + 4 * i, static_cast<std::uint32_t>(packet.counts[i]));
  }
  Put32(p + 48, packet.command_sequence);
  p[52] = packet.slack_mask;
  p[53] = packet.flags;
  Seal(out);
}

DecodeResult Inspect(const std::uint8_t* data, std::size_t size, PacketType* type) noexcept {
  if (data == nullptr || size != kPacketSize) return DecodeResult::kWrongLength;
  if (data[kOffsetMagic] != kMagic0 || data[kOffsetMagic + 1] != kMagic1) {
    return DecodeResult::kBadMagic;
  }
  if (Crc16(data, kCrcOffset) != Get16(data + kCrcOffset)) return DecodeResult::kBadChecksum;
  if (data[kOffsetVersion] != kProtocolVersion) return DecodeResult::kWrongVersion;
  if (type != nullptr) *type = static_cast<PacketType>(data[kOffsetType]);
  return DecodeResult::kOk;
}

DecodeResult Decode(const std::uint8_t* data, std::size_t size, HelloPacket* out) noexcept {
  const DecodeResult r = Check(data, size, PacketType::kHello);
  if (r != DecodeResult::kOk) return r;
  out->sequence = Get32(data + kOffsetSequence);
  out->watchdog_ms = Get16(data + 8);
  return r;
}

DecodeResult Decode(const std::uint8_t* data, std::size_t size, HelloReplyPacket* out) noexcept {
  const DecodeResult r = Check(data, size, PacketType::kHelloReply);
  if (r != DecodeResult::kOk) return r;
  out->sequence = Get32(data + kOffsetSequence);
  out->firmware_version = Get16(data + 8);
  out->watchdog_ms = Get16(data + 10);
  out->tension_max_mn = Get16(data + 12);
  out->counts_per_rev = Get16(data + 14);
  out->sample_period_us = Get16(data + 16);
  std::memcpy(out->serial.data(), data + 18, out->serial.size());
  return r;
}

DecodeResult Decode(const std::uint8_t* data, std::size_t size, CommandPacket* out) noexcept {
  const DecodeResult r = Check(data, size, PacketType::kCommand);
  if (r != DecodeResult::kOk) return r;
  out->sequence = Get32(data + kOffsetSequence);
  for (int i = 0; i < kNumStrings; ++i) out->tension_mn[i] = Get16(data + 8 + 2 * i);
  out->flags = data[24];
  return r;
}

DecodeResult Decode(const std::uint8_t* data, std::size_t size, StatePacket* out) noexcept {
  const DecodeResult r = Check(data, size, PacketType::kState);
  if (r != DecodeResult::kOk) return r;
  out->sequence = Get32(data + kOffsetSequence);
  out->time_us = Get64(data + 8);
  for (int i = 0; i < kNumStrings; ++i) {
    out->counts[i] = static_cast<std::int32_t>(Get32(data + 16 + 4 * i));
  }
  out->command_sequence = Get32(data + 48);
  out->slack_mask = data[52];
  out->flags = data[53];
  return r;
}

std::uint16_t TensionToMilliNewton(double tension) noexcept {
  if (!(tension > 0.0)) return 0;  // NaN, zero, negative
  const double mn = std::round(tension * 1000.0);
  if (mn >= 65535.0) return 65535;
  return static_cast<std::uint16_t>(mn);
}

void SetVersionForTesting(std::uint8_t version, Packet* packet) noexcept {
  (*packet)[kOffsetVersion] = version;
  Seal(packet);
}

}  // namespace spidarcad::haptics::usb
