// The window's haptic runtime: the device path of --device (a DeviceRig: the simulated SPIDAR-G,
// the USB driver over the board simulator, or the USB driver to a real board), a simulated hand
// holding the simulated device's grip, read and driven by haptics::HapticLoop at 1 kHz on
// haptics::LoopRunner's thread (SCHED_FIFO when allowed), wired as `spidarcad run` wires them
// headless. The main thread sets the hand's TARGET pose (what the mouse sets; a real board
// ignores it: the user's hand holds the grip), reads the latest RuntimeFrame, publishes
// HapticScenes and presses the emergency stop; it never waits for the haptic thread, and the
// haptic thread never waits for it (triple buffers both ways). A real board that is absent or
// unplugged gives zero force (the loop's device-error path) while a service thread re-opens it
// off the tick. Frame D, SI units.
// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#pragma once

#include <array>
#include <atomic>
#include <cstdint>
#include <functional>
#include <memory>
#include <string>
#include <thread>
#include <vector>

#include "scene/device_rig.h"
#include "scene/device_session.h"
#include "spidarcad/haptics/encoder.h"
#include "spidarcad/haptics/force_field.h"
#include "spidarcad/haptics/geometry.h"
#include "spidarcad/haptics/haptic_loop.h"
#include "spidarcad/haptics/loop_runner.h"
#include "spidarcad/haptics/simulated_device.h"
#include "spidarcad/haptics/simulated_hand.h"
#include "spidarcad/haptics/trajectory.h"
#include "spidarcad/haptics/triple_buffer.h"

namespace spidarcad::app {

// Which device the runtime drives (--device of the window).
enum class RuntimeDevice {
  // haptics::SimulatedSpidarG with the paper's encoder errors, noise, stretch and motor lag,
  // read through a line-fit encoder calibration made at start-up on 24 simulated jig poses
  // (CalibrateSimulated, scene/device_rig.h, as `spidarcad run --calibrate`);
  // the grip is held by a haptics::SimulatedHand (mass-spring-damper) that follows the target.
  kSimulated = 0,
  // SimulatedDeviceConfig::Ideal() (no encoder error, noise or stretch; quantisation and motor
  // lag remain) with the nominal calibration, and a rigid hand: the grip IS the target pose.
  kIdeal = 1,
  // The simulated SPIDAR-G of kSimulated (same seed) behind the controller board's firmware
  // simulator, driven by the USB driver over the in-process loopback (the driver's whole path,
  // docs/protocol.md); the simulated hand holds the board's device. Nominal calibration, as
  // `spidarcad run --device board-sim` uses. The driver reconnects in the tick (the loopback
  // allocates nothing); RequestBoardPlugged simulates an unplug.
  kBoardSim = 2,
  // A real SPIDAR-G controller board over libusb: the nominal device and calibration, no
  // simulated hand (the target is ignored; the grip pose is the board's, measured). No board,
  // or unplugged: zero force, and the service thread re-opens it every
  // RuntimeSettings::usb.reconnect_every sample periods.
  kUsb = 3,
};

// "simulated", "ideal", "board-sim" or "usb" -> device; false for any other name.
bool ParseRuntimeDevice(const std::string& name, RuntimeDevice* device);
// The --device name of `device`.
const char* RuntimeDeviceName(RuntimeDevice device);

// Settings of HapticRuntime.
struct RuntimeSettings {
  RuntimeDevice device = RuntimeDevice::kSimulated;
  std::uint64_t seed = 1;  // seed of the simulated device's errors and noise
  // The device's frame half-sides a, b, c and pole half-length d, m (window --frame, --pole):
  // the simulated device's size; for kUsb the size the board is assumed to have.
  haptics::SpidarGeometry geometry;
  // A calibration file (`spidarcad calibrate --out`, docs/calibration-format.md) to read the
  // encoders through instead of the start-up line fit (kSimulated) or the nominal calibration
  // (kBoardSim, kUsb); "" for none. It must belong to this device (kind, seed or board serial,
  // frame, encoder): the constructor throws InputError naming the file and the mismatch. Not
  // with kIdeal. kUsb checks the serial after the handshake and needs the board at start.
  std::string calibration_file;
  // kUsb without calibration_file: read the board through the calibration remembered for its
  // serial number (RememberedCalibration, scene/calibration_file.h) when there is one that fits.
  bool use_remembered_calibration = true;
  haptics::HandSettings hand;         // the simulated hand (kSimulated, kBoardSim)
  haptics::LoopSettings loop;         // X_WD, damping, limits, ramp; tension set from the grip size
  haptics::RunnerSettings runner;     // 1 kHz, SCHED_FIFO when permitted
  haptics::usb::UsbDeviceConfig usb;  // kBoardSim, kUsb: the driver's timeouts and recovery
  // kUsb: makes the transport (tests: a LoopbackTransport to a BoardSimulator); empty: libusb.
  std::function<std::unique_ptr<haptics::usb::Transport>()> usb_transport;
};

// What the haptic thread publishes each tick for the window.
struct RuntimeFrame {
  haptics::ToolState tool;                                // the loop's output of the tick
  haptics::GripPose hand_pose;                            // true grip pose (the hand's), D;
                                                          // kUsb: the measured pose (last good)
  haptics::Vector8d lengths = haptics::Vector8d::Zero();  // calibrated string lengths, m
  double step_seconds = 0.0;                              // compute time of HapticLoop::Step, s
  RigLink link;                                           // the driver's link (kBoardSim, kUsb)
};

// One reading of a self-calibration session (HapticRuntime::SetCalibrationTensions), for
// CalibrationCollector::Offer (scene/calibration_collector.h).
struct CalibrationReading {
  haptics::EncoderReading reading;                        // the device sample of the tick
  haptics::Vector8d tension = haptics::Vector8d::Zero();  // tensions the motors held, N
  double held = 0.0;                                      // for this long when it was read, s
};

// Device + calibration + hand + loop + runner. Construct, Publish a scene, Start.
class HapticRuntime {
 public:
  // Builds the device (and calibrates it for kSimulated), the hand at `initial_target`, and the
  // loop; kBoardSim and kUsb open the link (a board that does not answer is not an error: see
  // link_at_start()). Throws std::invalid_argument on bad settings.
  HapticRuntime(const RuntimeSettings& settings, const haptics::GripPose& initial_target);
  // Stops the thread.
  ~HapticRuntime();
  HapticRuntime(const HapticRuntime&) = delete;
  HapticRuntime& operator=(const HapticRuntime&) = delete;

  // Starts the 1 kHz thread (LoopRunner::Start), and for kUsb the thread that re-opens a lost
  // board (ServiceDevice). Do not call Tick or ServiceDevice yourself while they run.
  void Start();
  // Stops and joins the threads. Safe when not running.
  void Stop();

  // One tick: hand toward the target under the device wrench, device step, encoder read,
  // HapticLoop::Step, tensions out, RuntimeFrame published. Real-time safe (no allocation,
  // lock, I/O or exception). Called by the runner's thread, or directly by tests (virtual clock).
  void Tick(const haptics::TickTiming& timing) noexcept;

  // Main thread: the pose the hand moves toward (the mouse's grip pose), D. Ignored by kUsb.
  void SetTarget(const haptics::GripPose& target_D) noexcept;
  // Any thread: kBoardSim unplugs (false) or replugs (true) the simulated board at the next
  // tick (fault injection; the panel's checkbox). Ignored by the other devices.
  void RequestBoardPlugged(bool plugged) noexcept { rig_->RequestPlugged(plugged); }
  // Not while Start()ed: one re-open attempt of a lost board (kUsb; what the service thread
  // does every reconnect period). Returns true when it tried. For tests on a virtual clock.
  bool ServiceDevice() { return rig_->Service(); }
  // Main thread: the latest frame published by the haptic thread (lock-free, never waits).
  const RuntimeFrame& Latest() noexcept { return frames_.Latest(); }
  // Main thread: hands `scene` to the loop (HapticLoop::Publish; frees retired scenes).
  void Publish(std::unique_ptr<haptics::HapticScene> scene);

  // Any thread: latches zero force (HapticLoop::RequestEmergencyStop).
  void EmergencyStop() noexcept { loop_->RequestEmergencyStop(); }
  // Any thread: releases the stop; forces come back through the loop's ramp.
  void Rearm() noexcept { loop_->ClearEmergencyStop(); }
  // True while the emergency stop is latched.
  bool emergency_stopped() const noexcept { return loop_->emergency_stop(); }

  // The loop (event counts, settings), the runner (jitter and tick histograms, SCHED_FIFO
  // state) and the histogram of HapticLoop::Step's own compute time.
  const haptics::HapticLoop& loop() const { return *loop_; }
  const haptics::LoopRunner& runner() const { return runner_; }
  const haptics::LatencyHistogram& step_time() const { return step_time_; }
  // Ticks run (by the thread or by Tick calls).
  std::uint64_t ticks() const noexcept { return ticks_.load(std::memory_order_relaxed); }
  // One line on the device and its calibration ("simulated SPIDAR-G, line-fit calibration ...").
  const std::string& description() const { return description_; }
  const haptics::DeviceInfo& info() const { return rig_->info(); }
  // The simulated SPIDAR-G the hand holds (kSimulated, kIdeal, kBoardSim: the board's device);
  // null for kUsb. Test oracle: read it only while the thread is stopped.
  const haptics::SimulatedSpidarG* physical_device() const { return device_; }
  const RuntimeSettings& settings() const { return settings_; }
  // kBoardSim, kUsb: empty when the link opened at construction, else what to check (the
  // window keeps running, at zero force, and retries).
  const std::string& link_at_start() const { return link_at_start_; }
  // kUsb: why a remembered calibration was not used (gone, unreadable, another board's); "".
  const std::string& calibration_note() const { return calibration_note_; }
  // kBoardSim, kUsb: the board's serial number from its latest handshake: at construction or,
  // for a board that was absent then (or replugged), when the link was re-opened ("" while no
  // board has answered, and for the simulated devices). Main thread.
  std::string serial() const;

  // ---- self-calibration sessions (the window's calibration wizard) ----
  // Holds per tension schedule: CalibrationTensionSchedule(info(), kCalibrationHolds, seed),
  // used in turn and from the start again (300 s at kCalibrationHoldSeconds each).
  static constexpr int kCalibrationHolds = 3000;
  // Readings kept between two TakeCalibrationReadings calls (4 s of ticks at 1 kHz).
  static constexpr int kCalibrationRingSize = 4096;
  // Any thread: while on, each tick that reads the device (status ok) and would not command
  // zero force (no zero-force safety event, force ramp complete) commands the session's
  // tensions instead of the loop's (the force fields are not felt meanwhile; the emergency stop
  // still zeroes them): the schedule's vectors in turn, each held kCalibrationHoldSeconds
  // (scene/calibration_collector.h), restarting the hold after any tick that did not; and
  // hands the tick's reading with the tensions held and for how long to
  // TakeCalibrationReadings. Off: the loop's tensions from the next tick.
  void SetCalibrationTensions(bool on) noexcept {
    calibration_on_.store(on, std::memory_order_release);
  }
  bool calibration_tensions() const noexcept {
    return calibration_on_.load(std::memory_order_acquire);
  }
  // Main thread: appends the session readings published since the last call to *out, oldest
  // first. Returns how many were dropped since the last call because more than
  // kCalibrationRingSize piled up (lock-free; the haptic thread never waits).
  long TakeCalibrationReadings(std::vector<CalibrationReading>* out);
  // Main thread: reads the encoders through `calibration` (of this device; FK with its default
  // acceptance) from the next tick, without a restart: the loop is rebuilt between two ticks
  // (the haptic thread, when running, is stopped for that moment and started again). The loop's
  // event counts start again, a latched emergency stop stays latched, forces ramp in again, and
  // the haptic scene must be published again. `description` replaces description(). Throws
  // std::invalid_argument for a calibration that is not valid (nothing changes then).
  void UseCalibration(const haptics::EncoderCalibration& calibration,
                      const std::string& description);
  // The device rig's link summary ("usb link: states ..."; empty for the simulated devices).
  // Not while Start()ed.
  std::string LinkSummary() const { return rig_->LinkSummary(); }

 private:
  // Reads settings_.calibration_file (or, for kUsb, the remembered one) into calibration_ for
  // the board `serial` ("" for the simulated devices). True when a file was applied; throws
  // InputError for an explicit file that cannot be read or does not fit.
  bool ApplyCalibrationFile(const haptics::DeviceInfo& info, const std::string& serial);

  RuntimeSettings settings_;
  std::unique_ptr<DeviceRig> rig_;
  haptics::SimulatedSpidarG* device_ = nullptr;  // the rig's physical device; null for kUsb
  haptics::EncoderCalibration calibration_;
  std::unique_ptr<haptics::HapticLoop> loop_;
  haptics::SimulatedHand hand_;
  haptics::TripleBuffer<haptics::TrajectorySample> targets_;  // main -> haptic
  haptics::TripleBuffer<RuntimeFrame> frames_;                // haptic -> main
  haptics::LatencyHistogram step_time_;
  haptics::LoopRunner runner_;
  std::atomic<std::uint64_t> ticks_{0};
  std::string description_;
  std::string link_at_start_;
  std::string calibration_note_;
  std::string serial_;
  haptics::GripPose last_measured_;  // kUsb: the last pose FK accepted (haptic thread)
  // Self-calibration sessions: the schedule (made at construction), the haptic thread's place
  // in it, and the single-producer single-consumer ring of readings (haptic -> main).
  std::atomic<bool> calibration_on_{false};
  std::vector<haptics::Vector8d> calibration_schedule_;
  int calibration_ticks_per_hold_ = 100;
  int calibration_hold_ = 0;        // haptic thread
  int calibration_hold_ticks_ = 0;  // haptic thread: ticks the current vector was commanded
  std::unique_ptr<CalibrationReading[]> calibration_ring_;
  std::atomic<std::uint64_t> ring_written_{0};  // readings pushed (haptic thread)
  std::atomic<std::uint64_t> ring_read_{0};     // readings taken (main thread)
  std::atomic<std::uint64_t> ring_dropped_{0};  // readings not pushed: the ring was full
  std::uint64_t ring_dropped_reported_ = 0;     // main thread
  std::unique_ptr<RigServiceThread> service_;   // re-opens a lost board (kUsb) while started
};

// Loop statistics for the window's panel and the exit summary (read on the main thread while
// the haptic thread runs: counts may be one tick apart).
struct LoopStats {
  haptics::RealtimeStatus realtime = haptics::RealtimeStatus::kNotStarted;
  std::uint64_t ticks = 0;     // ticks run
  std::uint64_t overruns = 0;  // runner wake-ups so late that slots were skipped
  // Percentiles p50, p99, p99.9 and the maximum, s, of: HapticLoop::Step's compute time; the
  // whole tick (hand and device simulation included, LoopRunner::compute()); the period jitter
  // |actual − nominal period| (LoopRunner::jitter()).
  std::array<double, 4> step{};
  std::array<double, 4> tick{};
  std::array<double, 4> jitter{};
  std::array<std::uint64_t, haptics::kNumSafetyEvents> events{};  // ticks with each event
  bool emergency_stop = false;                                    // latched stop
  double ramp = 0.0;                                              // force ramp of the latest tick
  RigLink link;  // the device link of the latest tick (has_driver: board paths)
};

// Gathers LoopStats from `runtime` and its latest frame.
LoopStats CollectLoopStats(const HapticRuntime& runtime, const RuntimeFrame& latest);

// Lines for stdout: "loop: N ticks, SCHED_FIFO|fallback (...), step p50 ... µs ...",
// "safety events: name=count, ...", and with a driver "device link: <DescribeLink>".
std::string FormatLoopSummary(const LoopStats& stats);

// The device part of the window's frame from the haptic runtime's frame: poses, lengths,
// tensions, wrenches, statuses; the FK residual is recomputed from the lengths.
DeviceFrame MakeDeviceFrame(const RuntimeFrame& frame, const haptics::SpidarGeometry& geometry,
                            const std::string& source);

// Turns a grip pose into the hand's target sample (centre, rotation, grasp), D.
haptics::TrajectorySample TargetFromPose(const haptics::GripPose& pose);

}  // namespace spidarcad::app
