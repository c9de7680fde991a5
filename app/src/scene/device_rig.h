// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
// The device side of a haptic session, shared by `spidarcad run` and the window: the Device the
// 1 kHz loop reads and commands, and (simulated devices) the physical SPIDAR-G that a simulated
// hand grips. Three rigs (--device):
//   simulated  haptics::SimulatedSpidarG read directly; each Read steps its physics by dt.
//   board-sim  the USB driver (haptics::usb::UsbSpidarG) over LoopbackTransport to the
//              in-process BoardSimulator, whose physical device the hand grips. The board runs
//              one sample period each time the driver waits for a State (virtual clock); while
//              it is silent (unplugged, link closed) the rig runs the physics itself with the
//              motors unpowered, so a hand holding the grip feels no force.
//   usb        the USB driver over libusb to a real board; no physical device (the user's hand
//              moves the grip). The board cannot report geometry: RigOptions::device's geometry,
//              encoder, homing pose and tension limit are assumed (the nominal SPIDAR-G by
//              default, --frame/--pole otherwise).
// Tick path (Read, Write, Link, RequestPlugged): noexcept, no allocation, lock or exception
// beyond the transfer itself (see usb_device.h). Start, Service and the strings are not for the
// tick. Frame D, SI units (N, s).
#pragma once

#include <atomic>
#include <cstdint>
#include <functional>
#include <memory>
#include <string>
#include <thread>

#include "spidarcad/haptics/board_simulator.h"
#include "spidarcad/haptics/device.h"
#include "spidarcad/haptics/encoder.h"
#include "spidarcad/haptics/simulated_device.h"
#include "spidarcad/haptics/usb_device.h"
#include "spidarcad/haptics/usb_transport.h"

namespace spidarcad::app {

// Which path to the device.
enum class RigKind { kSimulated, kBoardSim, kUsb };

// "simulated", "board-sim" or "usb" -> kind; false for any other name.
bool ParseRigKind(const std::string& name, RigKind* kind);

// The link between loop and device as the tick last saw it (for panels and summaries; a plain
// value, copied into the window's frame each tick).
struct RigLink {
  bool has_driver = false;  // board-sim, usb: the USB driver sits between loop and device
  haptics::DeviceStatus status = haptics::DeviceStatus::kOk;  // the driver's status
  haptics::usb::UsbLinkStats stats;  // the driver's counters since construction
  bool plugged = true;               // board-sim: the simulated cable is in
  char error[200] = {};              // the driver's last_error() ("" when none)
};

// One line on the link: "ok: 1234 states, lost 0, ...", or for a link that is down
// "not connected — retrying; run `spidarcad device list`, udev rules ...". Empty without a driver.
std::string DescribeLink(const RigLink& link);

// How to build a rig.
struct RigOptions {
  // simulated, board-sim: the physical device (its seed included). usb: what the board is
  // assumed to be (geometry, encoder, homing pose, tension limit).
  haptics::SimulatedDeviceConfig device;
  // board-sim, usb: the driver's timeouts and recovery policy.
  haptics::usb::UsbDeviceConfig usb;
  // board-sim: the faults the loopback link injects (loss, corruption, reordering, stalls;
  // seeded). None by default.
  haptics::usb::LinkFaults link_faults;
  // usb: re-open the board off the tick. The driver's in-tick reconnect is then disabled
  // (re-opening libusb allocates) and a failed link is handed to Service(), which a non-real-
  // time thread calls every service_interval() s (usb.reconnect_every sample periods).
  bool reconnect_off_tick = false;
  // usb: makes the transport (tests: a LoopbackTransport); empty: LibusbTransport.
  std::function<std::unique_ptr<haptics::usb::Transport>()> make_transport;
};

// The device side of a session. Construct with MakeDeviceRig, Start, then per tick Read ->
// HapticLoop::Step -> Write.
class DeviceRig {
 public:
  virtual ~DeviceRig() = default;
  // The loop's description of the device (geometry, encoder, homing pose, tension range).
  virtual const haptics::DeviceInfo& info() const = 0;
  // The simulated SPIDAR-G the hand grips; null for a real board (the user's hand).
  virtual haptics::SimulatedSpidarG* physical() = 0;
  // Before the first tick, with the hand's initial grip pose (D): opens the link. False when
  // the device did not answer (StartFailure() says what to check); the tick path then reports
  // kNotConnected and the rig keeps retrying (driver reconnect or Service).
  virtual bool Start(const haptics::GripPose& /*initial*/) { return true; }
  // Why Start failed, naming --device and what to check; empty when it did not.
  virtual std::string StartFailure() const { return {}; }
  // Tick: one sample period dt (s): advances the physics (simulated) and reads the encoders.
  virtual void Read(double dt, haptics::EncoderReading* reading) noexcept = 0;
  // Tick: commands the tensions of the tick, N (zero force unless the link is ok).
  virtual void Write(const haptics::Vector8d& tau) noexcept = 0;
  // Tick: the link's state after the last Read/Write.
  virtual void Link(RigLink* link) const noexcept { link->has_driver = false; }
  // Any thread: board-sim unplugs (false) or replugs (true) the simulated cable at the next
  // Read (fault injection; replugging power-cycles the board). Ignored by the other rigs.
  virtual void RequestPlugged(bool /*plugged*/) noexcept {}
  // Non-real-time thread: re-opens a failed link handed over by the tick (reconnect_off_tick).
  // Returns true when it tried. Never concurrently with itself.
  virtual bool Service() { return false; }
  // Seconds between Service calls; 0: the rig needs none.
  virtual double service_interval() const { return 0.0; }
  // The board's serial number from its handshake (board-sim: the simulator's "SIM-0001");
  // empty for the simulated rig or before a handshake succeeded. usb: the latest handshake's,
  // at Start or when Service re-opened the link (a board plugged in after start-up); any thread
  // but the tick.
  virtual std::string Serial() const { return {}; }
  // For summaries: "simulated (seed 1)", "board-sim (...)", "usb (libusb)".
  virtual std::string Describe() const = 0;
  // For summaries: the link statistics (empty: none). Not while the tick runs.
  virtual std::string LinkSummary() const { return {}; }
};

// While it lives, a thread of its own calls rig->Service() (re-opening a failed link off the
// haptic thread) at most every rig->service_interval() s, polling every 10 ms; nothing when the
// interval is 0. Create it from a thread that is not real time: threads inherit SCHED_FIFO from
// their creator. The destructor stops and joins the thread.
class RigServiceThread {
 public:
  explicit RigServiceThread(DeviceRig* rig);
  ~RigServiceThread();
  RigServiceThread(const RigServiceThread&) = delete;
  RigServiceThread& operator=(const RigServiceThread&) = delete;

 private:
  std::atomic<bool> stop_{false};
  std::thread thread_;
};

// The rig of `kind`. Throws std::invalid_argument on a bad device configuration.
std::unique_ptr<DeviceRig> MakeDeviceRig(RigKind kind, const RigOptions& options = {});

// The nominal SPIDAR-G (the simulated device's defaults, without its errors): what a real board
// is assumed to be.
haptics::DeviceInfo NominalDeviceInfo();

// FK acceptance (FkSettings::max_residual, m) when the encoders are read through the NOMINAL
// calibration: the simulated device's encoder errors (gain ~6 %) leave millimetre residuals.
inline constexpr double kNominalFkMaxResidual = 5e-3;

// The nominal encoder calibration of `info`: nominal gain per count, zero at its homing pose.
haptics::EncoderCalibration NominalCalibration(const haptics::DeviceInfo& info);

// The start-up calibration of a simulated SPIDAR-G, shared by the window (HapticRuntime, device
// `simulated`) and `spidarcad run --calibrate`: the paper's line fit per string
// (haptics::FitLinesPerString, offset and gain) on kCalibrationJigPoses known jig poses
// (haptics::RandomGripPoses: centres in a cube of half side min(a, b, c) / 2, rotations up to
// 0.5 rad, grasp within ±0.4 rad of rest, seed 7), each held with kCalibrationJigTension N on
// every string (haptics::GatherKnownSamples), starting from NominalCalibration.
inline constexpr int kCalibrationJigPoses = 24;
inline constexpr double kCalibrationJigTension = 1.0;  // N
struct SimulatedCalibration {
  // True when the fit succeeded. False: `calibration` is the nominal one; read the device with
  // FK accepting kNominalFkMaxResidual (as without calibration) and say so (`description`).
  bool ok = false;
  haptics::EncoderCalibration calibration;  // what the loop reads the encoders with
  double rms_residual = 0.0;  // fit: RMS of (model − measured) length over the jig samples, m
  // One line: "line-fit calibration on 24 jig poses (rms 0.012 mm)", or
  // "NOMINAL calibration (line fit failed: <status>)".
  std::string description;
};
// Calibrates `device` (not null). It moves the device's grip through the jig poses and advances
// its clock and noise: call it before the session's first tick and put the grip back where the
// hand holds it. Deterministic for a given device seed. Never throws on a failed fit (see ok).
SimulatedCalibration CalibrateSimulated(haptics::SimulatedSpidarG* device);

}  // namespace spidarcad::app
