// Benchmarks of the USB protocol and the driver round trip through the board simulator.
// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#include <benchmark/benchmark.h>

#include <memory>

#include "bench_cli.h"
#include "spidarcad/haptics/board_simulator.h"
#include "spidarcad/haptics/usb_device.h"
#include "spidarcad/haptics/usb_protocol.h"

namespace usb = spidarcad::haptics::usb;

static void BM_EncodeState(benchmark::State& st) {
  usb::StatePacket s;
  s.counts = {1, -2, 3, -4, 5, -6, 7, -8};
  usb::Packet p;
  for (auto _ : st) {
    ++s.sequence;
    usb::Encode(s, &p);
    benchmark::DoNotOptimize(p);
  }
}
BENCHMARK(BM_EncodeState);

static void BM_DecodeState(benchmark::State& st) {
  usb::StatePacket s;
  s.counts = {1, -2, 3, -4, 5, -6, 7, -8};
  usb::Packet p;
  usb::Encode(s, &p);
  usb::StatePacket out;
  for (auto _ : st) {
    benchmark::DoNotOptimize(usb::Decode(p.data(), p.size(), &out));
    benchmark::DoNotOptimize(out);
  }
}
BENCHMARK(BM_DecodeState);

static void BM_EncodeCommand(benchmark::State& st) {
  usb::CommandPacket c;
  usb::Packet p;
  for (auto _ : st) {
    ++c.sequence;
    usb::Encode(c, &p);
    benchmark::DoNotOptimize(p);
  }
}
BENCHMARK(BM_EncodeCommand);

static void BM_Crc16_62Bytes(benchmark::State& st) {
  usb::Packet p{};
  for (auto _ : st) benchmark::DoNotOptimize(usb::Crc16(p.data(), usb::kCrcOffset));
}
BENCHMARK(BM_Crc16_62Bytes);

// One haptic tick: Read (board firmware + SimulatedSpidarG step + State encode/decode) and
// WriteTensions (Command encode, board decode and apply).
static void BM_DriverTickThroughSimulator(benchmark::State& st) {
  usb::BoardSimulator board;
  usb::LinkFaults faults;
  faults.corruption = st.range(0) / 100.0;
  auto transport = std::make_unique<usb::LoopbackTransport>(&board, faults);
  usb::UsbSpidarG driver(std::move(transport), board.device().info());
  driver.Open();
  spidarcad::haptics::EncoderReading reading;
  const spidarcad::haptics::Vector8d t = spidarcad::haptics::Vector8d::Constant(1.0);
  for (auto _ : st) {
    driver.Read(&reading);
    driver.WriteTensions(t);
  }
  benchmark::DoNotOptimize(reading);
}
BENCHMARK(BM_DriverTickThroughSimulator)->Arg(0)->Arg(10);

// The simulated device alone, for subtraction: the driver's share is the difference.
static void BM_SimulatedDeviceStepOnly(benchmark::State& st) {
  spidarcad::haptics::SimulatedSpidarG device;
  spidarcad::haptics::EncoderReading reading;
  const spidarcad::haptics::Vector8d t = spidarcad::haptics::Vector8d::Constant(1.0);
  for (auto _ : st) {
    device.WriteTensions(t);
    device.Step(1e-3);
    device.Read(&reading);
  }
  benchmark::DoNotOptimize(reading);
}
BENCHMARK(BM_SimulatedDeviceStepOnly);

// What this program measures (its --help).
constexpr const char* kBenchDescription =
    "Benchmarks of the USB protocol and the driver round trip through the board simulator.";

int main(int argc, char** argv) {
  return spidarcad::bench::RunBenchmarkMain(argc, argv, kBenchDescription);
}
