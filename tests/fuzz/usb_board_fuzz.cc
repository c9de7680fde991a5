// Fuzz harness: USB packets host -> board, as the board (BoardSimulator, the firmware's model)
// receives them, plus every packet decoder with its round trip. The input is a script of
// records: one control byte (usb_fuzz_common.h: framing, type, action) and 64 packet bytes.
// The board must never apply a tension above its maximum or a non-finite one, must keep the
// watchdog period in 5..1000 ms, and every State it emits must decode.
// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#include <cmath>
#include <cstddef>
#include <cstdint>

#include "spidarcad/haptics/board_simulator.h"
#include "usb_fuzz_common.h"

namespace {

using namespace spidarcad::fuzz;
namespace usb = spidarcad::haptics::usb;

void CheckEmitted(const usb::Packet& p) {
  usb::PacketType type{};
  if (usb::Inspect(p.data(), p.size(), &type) != usb::DecodeResult::kOk) {
    Violated("usb_board", "the board emitted a packet that does not decode");
  }
  CheckAllDecoders("usb_board", p.data(), p.size());
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  static usb::BoardConfig config = [] {
    usb::BoardConfig c;
    c.device.seed = 1;
    return c;
  }();
  usb::BoardSimulator board(config);
  ByteReader in(data, size);
  const double max_tension =
      usb::MilliNewtonToTension(usb::TensionToMilliNewton(config.device.tension_max));
  for (int record = 0; record < 64 && !in.empty(); ++record) {
    const PacketControl c = ParseControl(in.Byte());
    usb::Packet p{};
    in.Bytes(p.data(), p.size());
    Frame(c, &p);
    if (c.echo && TypeOf(c.type) == usb::PacketType::kCommand && c.set_type) {
      // A sequence newer than the board's last, so that the command is applied.
      const std::uint32_t seq = board.last_command_sequence() + 1 + (p[4] & 0x0F);
      for (int k = 0; k < 4; ++k) p[4 + k] = static_cast<std::uint8_t>(seq >> (8 * k));
      Reseal(&p);
    }
    CheckAllDecoders("usb_board", p.data(), p.size());
    if (c.action <= 4) {
      board.HandlePacket(p.data(), p.size());
    } else if (c.action == 5) {
      board.HandlePacket(p.data(), p[0] % (p.size() + 2));  // short (or 64/65-byte) transfer
    } else if (c.action == 6) {
      usb::Packet out;
      for (int t = 0; t < 1 + (p[1] & 0x1F); ++t) {
        if (board.Tick(&out)) CheckEmitted(out);
      }
    } else {
      board.PowerCycle();
    }
    usb::Packet reply;
    while (board.TakeReply(&reply)) CheckEmitted(reply);
    usb::Packet state;
    if (board.Tick(&state)) CheckEmitted(state);
    const auto& applied = board.applied_tensions();
    if (!applied.allFinite() || applied.minCoeff() < 0.0 || applied.maxCoeff() > max_tension) {
      Violated("usb_board", "the board applies a tension outside [0, tension_max]");
    }
    if (board.watchdog_ms() < 5 || board.watchdog_ms() > 1000) {
      Violated("usb_board", "the watchdog period left 5..1000 ms");
    }
  }
  return 0;
}
