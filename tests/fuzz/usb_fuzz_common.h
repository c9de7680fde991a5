// Shared pieces of the two USB harnesses: turning fuzz bytes into packets that get past the
// framing (magic, version, CRC) often enough to reach the payload decoders, and the codec round
// trip every decoded packet must survive (Encode(Decode(p)) decodes to the same fields).
// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#pragma once

#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <cstring>

#include "fuzz_support.h"
#include "spidarcad/haptics/usb_protocol.h"

namespace spidarcad::fuzz {

namespace usb = haptics::usb;

// Reads fuzz bytes front to back; past the end it yields zeros.
class ByteReader {
 public:
  ByteReader(const std::uint8_t* data, std::size_t size) : data_(data), size_(size) {}
  bool empty() const { return pos_ >= size_; }
  std::uint8_t Byte() { return pos_ < size_ ? data_[pos_++] : 0; }
  // Copies up to n bytes into out (zero-filled past the end); returns how many were real.
  std::size_t Bytes(std::uint8_t* out, std::size_t n) {
    const std::size_t real = std::min(n, size_ - std::min(pos_, size_));
    if (real > 0) std::memcpy(out, data_ + pos_, real);
    std::memset(out + real, 0, n - real);
    pos_ += n;
    return real;
  }

 private:
  const std::uint8_t* data_;
  std::size_t size_;
  std::size_t pos_ = 0;
};

// Control byte of one packet in a fuzz script.
struct PacketControl {
  bool frame = false;       // bit 0: stamp magic and version, recompute the CRC at the end
  bool set_type = false;    // bit 1: type byte from bits 2..3 (Hello, HelloReply, Command, State)
  bool echo = false;        // bit 4: the harness fills sequence fields the peer expects
  std::uint8_t type = 0;    // bits 2..3
  std::uint8_t action = 0;  // bits 5..7: 0..4 deliver; 5 short packet; 6 timeout; 7 unplug
};

inline PacketControl ParseControl(std::uint8_t b) {
  PacketControl c;
  c.frame = b & 0x01;
  c.set_type = b & 0x02;
  c.type = (b >> 2) & 0x03;
  c.echo = b & 0x10;
  c.action = b >> 5;
  return c;
}

inline usb::PacketType TypeOf(std::uint8_t index) {
  constexpr usb::PacketType kTypes[4] = {usb::PacketType::kHello, usb::PacketType::kHelloReply,
                                         usb::PacketType::kCommand, usb::PacketType::kState};
  return kTypes[index & 3];
}

// Applies the control's framing to a packet (type first, then magic/version/CRC).
inline void Frame(const PacketControl& c, usb::Packet* p) {
  if (c.set_type) (*p)[3] = static_cast<std::uint8_t>(TypeOf(c.type));
  if (c.frame) {
    (*p)[0] = usb::kMagic0;
    (*p)[1] = usb::kMagic1;
    usb::SetVersionForTesting(usb::kProtocolVersion, p);  // also recomputes the CRC
  }
}

// Recomputes the CRC after the harness edited payload bytes.
inline void Reseal(usb::Packet* p) {
  const std::uint16_t crc = usb::Crc16(p->data(), usb::kCrcOffset);
  (*p)[usb::kCrcOffset] = static_cast<std::uint8_t>(crc & 0xFF);
  (*p)[usb::kCrcOffset + 1] = static_cast<std::uint8_t>(crc >> 8);
}

inline bool Same(const usb::HelloPacket& a, const usb::HelloPacket& b) {
  return a.sequence == b.sequence && a.watchdog_ms == b.watchdog_ms;
}
inline bool Same(const usb::HelloReplyPacket& a, const usb::HelloReplyPacket& b) {
  return a.sequence == b.sequence && a.firmware_version == b.firmware_version &&
         a.watchdog_ms == b.watchdog_ms && a.tension_max_mn == b.tension_max_mn &&
         a.counts_per_rev == b.counts_per_rev && a.sample_period_us == b.sample_period_us &&
         a.serial == b.serial;
}
inline bool Same(const usb::CommandPacket& a, const usb::CommandPacket& b) {
  return a.sequence == b.sequence && a.tension_mn == b.tension_mn && a.flags == b.flags;
}
inline bool Same(const usb::StatePacket& a, const usb::StatePacket& b) {
  return a.sequence == b.sequence && a.time_us == b.time_us && a.counts == b.counts &&
         a.command_sequence == b.command_sequence && a.slack_mask == b.slack_mask &&
         a.flags == b.flags;
}

// Decodes `data` as packet type T; when that succeeds, encodes the result and decodes it again,
// which must give the same fields and the same type.
template <typename T>
void CheckRoundTrip(const char* harness, const std::uint8_t* data, std::size_t size) {
  T first;
  if (usb::Decode(data, size, &first) != usb::DecodeResult::kOk) return;
  usb::Packet encoded;
  usb::Encode(first, &encoded);
  T second;
  if (usb::Decode(encoded.data(), encoded.size(), &second) != usb::DecodeResult::kOk) {
    Violated(harness, "an encoded packet does not decode");
  }
  if (!Same(first, second)) Violated(harness, "a packet changes in a decode/encode round trip");
  usb::PacketType type{};
  if (usb::Inspect(data, size, &type) != usb::DecodeResult::kOk ||
      usb::Inspect(encoded.data(), encoded.size(), &type) != usb::DecodeResult::kOk ||
      type != static_cast<usb::PacketType>(data[3])) {
    Violated(harness, "Inspect disagrees with Decode");
  }
}

// Every decoder on one buffer, each with its round trip.
inline void CheckAllDecoders(const char* harness, const std::uint8_t* data, std::size_t size) {
  CheckRoundTrip<usb::HelloPacket>(harness, data, size);
  CheckRoundTrip<usb::HelloReplyPacket>(harness, data, size);
  CheckRoundTrip<usb::CommandPacket>(harness, data, size);
  CheckRoundTrip<usb::StatePacket>(harness, data, size);
  usb::PacketType type{};
  const usb::DecodeResult r = usb::Inspect(data, size, &type);
  if (usb::DecodeResultName(r) == nullptr) Violated(harness, "DecodeResultName gave null");
}

}  // namespace spidarcad::fuzz
