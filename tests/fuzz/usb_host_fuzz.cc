// Fuzz harness: USB packets board -> host, as the driver (haptics::usb::UsbSpidarG) receives
// them through a scripted transport. The input is a script of records: one control byte
// (usb_fuzz_common.h) and 64 packet bytes, delivered by Receive one at a time, or turned into a
// timeout, a short transfer or an unplug. The driver opens, then reads and commands until the
// script ends. Whatever arrives: every packet the host sends is a valid Hello or Command,
// readings are delivered only with status kOk, and nothing crashes.
// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <memory>

#include "spidarcad/haptics/usb_device.h"
#include "usb_fuzz_common.h"

namespace {

using namespace spidarcad::fuzz;
namespace usb = spidarcad::haptics::usb;
using spidarcad::haptics::DeviceStatus;

// Plays the fuzz script as the board's side of the link.
class ScriptedTransport final : public usb::Transport {
 public:
  ScriptedTransport(const std::uint8_t* data, std::size_t size) : in_(data, size) {}
  usb::TransportResult Open() noexcept override {
    if (in_.empty()) return usb::TransportResult::kNotFound;
    open_ = true;
    return usb::TransportResult::kOk;
  }
  void Close() noexcept override { open_ = false; }
  bool is_open() const noexcept override { return open_; }
  usb::TransportResult Send(const std::uint8_t* data, std::size_t size,
                            int timeout_ms) noexcept override {
    if (!open_) return usb::TransportResult::kDisconnected;
    usb::PacketType type{};
    if (usb::Inspect(data, size, &type) != usb::DecodeResult::kOk ||
        (type != usb::PacketType::kHello && type != usb::PacketType::kCommand)) {
      Violated("usb_host", "the host sent a packet that is not a valid Hello or Command");
    }
    CheckAllDecoders("usb_host", data, size);
    std::memcpy(&last_sent_sequence_, data + 4, 4);
    if (type == usb::PacketType::kHello)
      last_hello_ = last_sent_sequence_;
    else
      last_command_ = last_sent_sequence_;
    return usb::TransportResult::kOk;
  }
  usb::TransportResult Receive(std::uint8_t* data, std::size_t capacity, std::size_t* received,
                               int timeout_ms) noexcept override {
    *received = 0;
    if (!open_) return usb::TransportResult::kDisconnected;
    if (in_.empty()) return usb::TransportResult::kTimeout;
    const PacketControl c = ParseControl(in_.Byte());
    usb::Packet p{};
    in_.Bytes(p.data(), p.size());
    Frame(c, &p);
    if (c.echo) {
      // Sequence numbers the host expects: the Hello's for a HelloReply; for a State, the last
      // Command's as command_sequence and a sample counter that moves forward.
      if (p[3] == static_cast<std::uint8_t>(usb::PacketType::kHelloReply)) {
        std::memcpy(p.data() + 4, &last_hello_, 4);
      } else if (p[3] == static_cast<std::uint8_t>(usb::PacketType::kState)) {
        state_sequence_ += 1 + (p[4] & 0x03);
        std::memcpy(p.data() + 4, &state_sequence_, 4);
        std::memcpy(p.data() + 8 + 8 + 4 * 8, &last_command_, 4);
      }
      if (c.frame) Reseal(&p);
    }
    CheckAllDecoders("usb_host", p.data(), p.size());
    if (c.action == 6) return usb::TransportResult::kTimeout;
    if (c.action == 7) {
      open_ = false;
      return usb::TransportResult::kDisconnected;
    }
    std::size_t n = c.action == 5 ? p[0] % p.size() : p.size();
    n = std::min(n, capacity);
    std::memcpy(data, p.data(), n);
    *received = n;
    return usb::TransportResult::kOk;
  }
  const char* last_error() const noexcept override { return ""; }
  bool exhausted() const { return in_.empty(); }

 private:
  ByteReader in_;
  bool open_ = false;
  std::uint32_t last_sent_sequence_ = 0;
  std::uint32_t last_hello_ = 0;
  std::uint32_t last_command_ = 0;
  std::uint32_t state_sequence_ = 0;
};

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  auto transport = std::make_unique<ScriptedTransport>(data, size);
  ScriptedTransport* link = transport.get();
  usb::UsbDeviceConfig config;
  config.reconnect_every = 3;
  config.disconnect_after = 5;
  usb::UsbSpidarG driver(std::move(transport), spidarcad::haptics::DeviceInfo{}, config);
  driver.Open();
  spidarcad::haptics::Vector8d tension = spidarcad::haptics::Vector8d::Constant(1.0);
  for (int tick = 0; tick < 256 && !link->exhausted(); ++tick) {
    spidarcad::haptics::EncoderReading reading;
    const DeviceStatus status = driver.Read(&reading);
    if (status != reading.status) Violated("usb_host", "Read's result and reading.status differ");
    if (tick % 7 == 3) driver.SetEmergencyStop(tick % 2 == 0);
    driver.WriteTensions(tension);
    if (std::strlen(driver.last_error()) >= 320) Violated("usb_host", "last_error overflows");
  }
  return 0;
}
