// Tests of the USB wire protocol: byte layout against docs/protocol.md, CRC against the
// published check value, rejection of every single-bit error, wrong length, version and type.
// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#include "spidarcad/haptics/usb_protocol.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <limits>

#include "support/malloc_counter.h"

namespace spidarcad::haptics::usb {
namespace {

// Independent little-endian readers (not the ones in usb_protocol.cc).
std::uint32_t Le32(const Packet& p, int at) {
  return std::uint32_t{p[at]} | std::uint32_t{p[at + 1]} << 8 | std::uint32_t{p[at + 2]} << 16 |
         std::uint32_t{p[at + 3]} << 24;
}
std::uint16_t Le16(const Packet& p, int at) {
  return static_cast<std::uint16_t>(p[at] | p[at + 1] << 8);
}

StatePacket SampleState() {
  StatePacket s;
  s.sequence = 0xA1B2C3D4u;
  s.time_us = 0x0102030405060708ull;
  s.counts = {1,
              -1,
              123456,
              -123456,
              std::numeric_limits<std::int32_t>::max(),
              std::numeric_limits<std::int32_t>::min(),
              0,
              42};
  s.command_sequence = 77;
  s.slack_mask = 0x81;
  s.flags = kStateMotorsEnabled | kStateWatchdogTripped;
  return s;
}

TEST(Crc16, MatchesPublishedCheckValue) {
  // CRC-16/CCITT-FALSE check value for the ASCII string "123456789" (CRC catalogue).
  const char* text = "123456789";
  EXPECT_EQ(Crc16(reinterpret_cast<const std::uint8_t*>(text), 9), 0x29B1);
  // Empty input: the initial value.
  EXPECT_EQ(Crc16(nullptr, 0), 0xFFFF);
}

TEST(UsbProtocol, StateLayoutMatchesDocumentedOffsets) {
  Packet p;
  Encode(SampleState(), &p);
  EXPECT_EQ(p[0], 'S');
  EXPECT_EQ(p[1], 'G');
  EXPECT_EQ(p[2], 1);
  EXPECT_EQ(p[3], 0x20);
  EXPECT_EQ(Le32(p, 4), 0xA1B2C3D4u);
  EXPECT_EQ(Le32(p, 8), 0x05060708u);
  EXPECT_EQ(Le32(p, 12), 0x01020304u);
  EXPECT_EQ(static_cast<std::int32_t>(Le32(p, 16)), 1);
  EXPECT_EQ(static_cast<std::int32_t>(Le32(p, 20)), -1);
  EXPECT_EQ(p[20], 0xFF);  // two's complement, little-endian
  EXPECT_EQ(static_cast<std::int32_t>(Le32(p, 28)), -123456);
  EXPECT_EQ(static_cast<std::int32_t>(Le32(p, 44)), 42);
  EXPECT_EQ(Le32(p, 48), 77u);
  EXPECT_EQ(p[52], 0x81);
  EXPECT_EQ(p[53], 0x03);
  for (int i = 54; i < 62; ++i) EXPECT_EQ(p[i], 0) << "reserved byte " << i;
  // CRC stored little-endian at 62.
  EXPECT_EQ(Le16(p, 62), Crc16(p.data(), 62));
}

TEST(UsbProtocol, CommandLayoutMatchesDocumentedOffsets) {
  CommandPacket c;
  c.sequence = 5;
  for (int i = 0; i < kNumStrings; ++i) c.tension_mn[i] = static_cast<std::uint16_t>(1000 * i + 7);
  c.flags = kCommandEnable | kCommandClearFault;
  Packet p;
  Encode(c, &p);
  EXPECT_EQ(p[3], 0x10);
  EXPECT_EQ(Le32(p, 4), 5u);
  for (int i = 0; i < kNumStrings; ++i) EXPECT_EQ(Le16(p, 8 + 2 * i), 1000 * i + 7);
  EXPECT_EQ(p[24], 0x05);
  for (int i = 25; i < 62; ++i) EXPECT_EQ(p[i], 0) << "reserved byte " << i;
}

TEST(UsbProtocol, HelloAndReplyRoundTrip) {
  HelloPacket hello{9, 35};
  Packet p;
  Encode(hello, &p);
  EXPECT_EQ(p[3], 0x01);
  EXPECT_EQ(Le16(p, 8), 35);
  HelloPacket h2;
  ASSERT_EQ(Decode(p.data(), p.size(), &h2), DecodeResult::kOk);
  EXPECT_EQ(h2.sequence, 9u);
  EXPECT_EQ(h2.watchdog_ms, 35);

  HelloReplyPacket reply;
  reply.sequence = 9;
  reply.firmware_version = 0x0102;
  reply.watchdog_ms = 35;
  reply.tension_max_mn = 8000;
  reply.counts_per_rev = 2000;
  reply.sample_period_us = 1000;
  std::memcpy(reply.serial.data(), "ABC-123", 7);
  Encode(reply, &p);
  EXPECT_EQ(Le16(p, 12), 8000);
  EXPECT_EQ(p[18], 'A');
  HelloReplyPacket r2;
  ASSERT_EQ(Decode(p.data(), p.size(), &r2), DecodeResult::kOk);
  EXPECT_EQ(r2.firmware_version, 0x0102);
  EXPECT_EQ(r2.counts_per_rev, 2000);
  EXPECT_EQ(r2.sample_period_us, 1000);
  EXPECT_STREQ(r2.serial.data(), "ABC-123");
}

TEST(UsbProtocol, StateRoundTripsExactly) {
  const StatePacket s = SampleState();
  Packet p;
  Encode(s, &p);
  StatePacket d;
  ASSERT_EQ(Decode(p.data(), p.size(), &d), DecodeResult::kOk);
  EXPECT_EQ(d.sequence, s.sequence);
  EXPECT_EQ(d.time_us, s.time_us);
  EXPECT_EQ(d.counts, s.counts);
  EXPECT_EQ(d.command_sequence, s.command_sequence);
  EXPECT_EQ(d.slack_mask, s.slack_mask);
  EXPECT_EQ(d.flags, s.flags);
}

TEST(UsbProtocol, RejectsEverySingleBitError) {
  Packet good;
  Encode(SampleState(), &good);
  for (int bit = 0; bit < static_cast<int>(kPacketSize) * 8; ++bit) {
    Packet bad = good;
    bad[bit / 8] ^= static_cast<std::uint8_t>(1u << (bit % 8));
    StatePacket out;
    out.sequence = 12345;
    const DecodeResult r = Decode(bad.data(), bad.size(), &out);
    EXPECT_NE(r, DecodeResult::kOk) << "bit " << bit;
    EXPECT_EQ(out.sequence, 12345u) << "output written for a rejected packet, bit " << bit;
  }
}

TEST(UsbProtocol, RejectsWrongLengthVersionTypeAndMagic) {
  Packet p;
  Encode(SampleState(), &p);
  StatePacket out;
  EXPECT_EQ(Decode(p.data(), p.size() - 1, &out), DecodeResult::kWrongLength);
  EXPECT_EQ(Decode(p.data(), 0, &out), DecodeResult::kWrongLength);
  EXPECT_EQ(Decode(nullptr, kPacketSize, &out), DecodeResult::kWrongLength);
  std::uint8_t longer[kPacketSize + 1] = {};
  std::memcpy(longer, p.data(), kPacketSize);
  EXPECT_EQ(Decode(longer, sizeof(longer), &out), DecodeResult::kWrongLength);

  Packet v2 = p;
  SetVersionForTesting(2, &v2);  // CRC valid, version not
  EXPECT_EQ(Crc16(v2.data(), kCrcOffset), Le16(v2, 62));
  EXPECT_EQ(Decode(v2.data(), v2.size(), &out), DecodeResult::kWrongVersion);

  CommandPacket command;
  EXPECT_EQ(Decode(p.data(), p.size(), &command), DecodeResult::kWrongType);

  Packet magic = p;
  magic[0] = 'X';
  EXPECT_EQ(Decode(magic.data(), magic.size(), &out), DecodeResult::kBadMagic);
  PacketType type{};
  EXPECT_EQ(Inspect(p.data(), p.size(), &type), DecodeResult::kOk);
  EXPECT_EQ(type, PacketType::kState);
}

TEST(UsbProtocol, TensionConversionClampsRoundsAndZeroesNaN) {
  EXPECT_EQ(TensionToMilliNewton(std::nan("")), 0);
  EXPECT_EQ(TensionToMilliNewton(-1.0), 0);
  EXPECT_EQ(TensionToMilliNewton(0.0), 0);
  EXPECT_EQ(TensionToMilliNewton(1.2344), 1234);
  EXPECT_EQ(TensionToMilliNewton(1.2346), 1235);
  EXPECT_EQ(TensionToMilliNewton(8.0), 8000);
  EXPECT_EQ(TensionToMilliNewton(1e9), 65535);
  EXPECT_EQ(TensionToMilliNewton(std::numeric_limits<double>::infinity()), 65535);
  EXPECT_DOUBLE_EQ(MilliNewtonToTension(2500), 2.5);
}

TEST(UsbProtocol, EncodeAndDecodeAllocateNothing) {
  Packet p;
  StatePacket out;
  const StatePacket s = SampleState();
  ASSERT_TRUE(test_support::MallocCounterActive()) << "the counting malloc is not in use";
  test_support::MallocCounter counter;
  for (int i = 0; i < 100; ++i) {
    Encode(s, &p);
    Decode(p.data(), p.size(), &out);
  }
  EXPECT_EQ(counter.count(), 0);
  EXPECT_EQ(out.sequence, s.sequence);
}

}  // namespace
}  // namespace spidarcad::haptics::usb
