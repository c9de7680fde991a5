// The seam between the haptic loop and the hardware: a SPIDAR-G reports 8 encoder counters and
// takes 8 string tensions. Implemented by the simulated device (simulated_device.h) and, later,
// the USB driver. Every method the haptic tick calls (Read, WriteTensions, status) is noexcept,
// allocates nothing, takes no lock and does no I/O beyond the transfer itself.
// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#pragma once

#include <cstdint>

#include "spidarcad/haptics/encoder.h"
#include "spidarcad/haptics/geometry.h"

namespace spidarcad::haptics {

// State of a device. Anything but kOk means the loop must command zero force.
enum class DeviceStatus : std::uint8_t {
  kOk = 0,        // reading and writing normally
  kNotConnected,  // no device (unplugged, never opened)
  kCommError,     // a transfer failed or timed out; the reading is stale
  kFault,         // the device reported a fault (motor driver, over-current, encoder)
  kStopped,       // emergency stop pressed on the device; motors disabled
};

// One word for a status ("ok", "not_connected", ...).
constexpr const char* DeviceStatusName(DeviceStatus status) {
  switch (status) {
    case DeviceStatus::kOk:
      return "ok";
    case DeviceStatus::kNotConnected:
      return "not_connected";
    case DeviceStatus::kCommError:
      return "comm_error";
    case DeviceStatus::kFault:
      return "fault";
    case DeviceStatus::kStopped:
      return "stopped";
  }
  return "unknown";
}

// One sample of the encoders.
struct EncoderReading {
  EncoderCounts counts{};       // counters since homing, counts (see encoder.h for the model)
  std::uint32_t sequence = 0;   // increases by one per device sample; a repeat means stale data
  double time = 0.0;            // device time of the sample, s
  std::uint8_t slack_mask = 0;  // bit i set: string i's commanded tension is below the slack
                                // threshold, so its length may not be taut (not trustworthy)
  DeviceStatus status = DeviceStatus::kNotConnected;
};

// What the haptic loop needs to know about a device before it runs.
struct DeviceInfo {
  SpidarGeometry geometry;   // frame half-sides and pole half-length, m
  EncoderSpec encoder;       // nominal counts per revolution and pulley radius
  GripPose home_pose;        // the pose at which the counters were zeroed (homing jig), in D
  double tension_min = 0.0;  // N; the device cannot push (strings only pull)
  double tension_max = 8.0;  // N; motor torque / current limit divided by the pulley radius
};

// A SPIDAR-G. Units: counts for the encoders, N for tensions, s for time.
class Device {
 public:
  virtual ~Device() = default;

  // Static description (geometry, nominal encoder, homing pose, tension range).
  virtual const DeviceInfo& info() const noexcept = 0;
  // Latest encoder sample into `reading` (its status is also the return value). On an error the
  // counts are the last good ones and the sequence does not advance.
  virtual DeviceStatus Read(EncoderReading* reading) noexcept = 0;
  // Commands string tensions τ (N, shape 8). The device clamps to [tension_min, tension_max];
  // NaN entries are treated as 0. Returns the device status (not kOk: nothing was applied).
  virtual DeviceStatus WriteTensions(const Vector8d& tension) noexcept = 0;
  // Current status without a transfer.
  virtual DeviceStatus status() const noexcept = 0;
};

}  // namespace spidarcad::haptics
