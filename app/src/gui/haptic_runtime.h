// The window's haptic runtime: a simulated SPIDAR-G held by a simulated hand, read and driven by
// haptics::HapticLoop at 1 kHz on haptics::LoopRunner's thread (SCHED_FIFO when allowed), wired
// as `spidarcad run` wires them headless. The main thread sets the hand's TARGET pose (what the
// mouse sets), reads the latest RuntimeFrame, publishes HapticScenes and presses the emergency
// stop; it never waits for the haptic thread, and the haptic thread never waits for it (triple
// buffers both ways). Frame D for poses, SI units.
// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#pragma once

#include <array>
#include <atomic>
#include <cstdint>
#include <memory>
#include <string>

#include "gui/device_session.h"
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

// Which device the runtime simulates.
enum class RuntimeDevice {
  // haptics::SimulatedSpidarG with the paper's encoder errors, noise, stretch and motor lag,
  // read through a line-fit encoder calibration made at start-up on 24 simulated jig poses;
  // the grip is held by a haptics::SimulatedHand (mass-spring-damper) that follows the target.
  kSimulated,
  // SimulatedDeviceConfig::Ideal() (no encoder error, noise or stretch; quantisation and motor
  // lag remain) with the nominal calibration, and a rigid hand: the grip IS the target pose.
  kIdeal,
};

// Settings of HapticRuntime.
struct RuntimeSettings {
  RuntimeDevice device = RuntimeDevice::kSimulated;
  std::uint64_t seed = 1;          // seed of the simulated device's errors and noise
  haptics::HandSettings hand;      // the simulated hand (kSimulated only)
  haptics::LoopSettings loop;      // X_WD, damping, limits, ramp; tension set from the grip size
  haptics::RunnerSettings runner;  // 1 kHz, SCHED_FIFO when permitted
};

// What the haptic thread publishes each tick for the window.
struct RuntimeFrame {
  haptics::ToolState tool;                              // the loop's output of the tick
  haptics::GripPose hand_pose;                          // true grip pose (the hand's), D
  haptics::Vector8d lengths = haptics::Vector8d::Zero();  // calibrated string lengths, m
  double step_seconds = 0.0;                            // compute time of HapticLoop::Step, s
};

// Device + calibration + hand + loop + runner. Construct, Publish a scene, Start.
class HapticRuntime {
 public:
  // Builds the device (and calibrates it for kSimulated), the hand at `initial_target`, and the
  // loop. Throws std::invalid_argument on bad settings.
  HapticRuntime(const RuntimeSettings& settings, const haptics::GripPose& initial_target);
  // Stops the thread.
  ~HapticRuntime();
  HapticRuntime(const HapticRuntime&) = delete;
  HapticRuntime& operator=(const HapticRuntime&) = delete;

  // Starts the 1 kHz thread (LoopRunner::Start). Do not call Tick yourself while it runs.
  void Start();
  // Stops and joins the thread. Safe when not running.
  void Stop();

  // One tick: hand toward the target under the device wrench, device step, encoder read,
  // HapticLoop::Step, tensions out, RuntimeFrame published. Real-time safe (no allocation,
  // lock, I/O or exception). Called by the runner's thread, or directly by tests (virtual clock).
  void Tick(const haptics::TickTiming& timing) noexcept;

  // Main thread: the pose the hand moves toward (the mouse's grip pose), D.
  void SetTarget(const haptics::GripPose& target_D) noexcept;
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
  const haptics::DeviceInfo& info() const { return device_->info(); }
  const RuntimeSettings& settings() const { return settings_; }

 private:
  RuntimeSettings settings_;
  std::unique_ptr<haptics::SimulatedSpidarG> device_;
  haptics::EncoderCalibration calibration_;
  std::unique_ptr<haptics::HapticLoop> loop_;
  haptics::SimulatedHand hand_;
  haptics::TripleBuffer<haptics::TrajectorySample> targets_;  // main -> haptic
  haptics::TripleBuffer<RuntimeFrame> frames_;                // haptic -> main
  haptics::LatencyHistogram step_time_;
  haptics::LoopRunner runner_;
  std::atomic<std::uint64_t> ticks_{0};
  std::string description_;
};

// Loop statistics for the window's panel and the exit summary (read on the main thread while
// the haptic thread runs: counts may be one tick apart).
struct LoopStats {
  haptics::RealtimeStatus realtime = haptics::RealtimeStatus::kNotStarted;
  std::uint64_t ticks = 0;       // ticks run
  std::uint64_t overruns = 0;    // runner wake-ups so late that slots were skipped
  // Percentiles p50, p99, p99.9 and the maximum, s, of: HapticLoop::Step's compute time; the
  // whole tick (hand and device simulation included, LoopRunner::compute()); the period jitter
  // |actual − nominal period| (LoopRunner::jitter()).
  std::array<double, 4> step{};
  std::array<double, 4> tick{};
  std::array<double, 4> jitter{};
  std::array<std::uint64_t, haptics::kNumSafetyEvents> events{};  // ticks with each event
  bool emergency_stop = false;   // latched stop
  double ramp = 0.0;             // force ramp of the latest tick
};

// Gathers LoopStats from `runtime` and its latest frame.
LoopStats CollectLoopStats(const HapticRuntime& runtime, const RuntimeFrame& latest);

// Two lines for stdout: "loop: N ticks, SCHED_FIFO|fallback (...), step p50 ... µs ..." and
// "safety events: name=count, ...".
std::string FormatLoopSummary(const LoopStats& stats);

// The device part of the window's frame from the haptic runtime's frame: poses, lengths,
// tensions, wrenches, statuses; the FK residual is recomputed from the lengths.
DeviceFrame MakeDeviceFrame(const RuntimeFrame& frame, const haptics::SpidarGeometry& geometry,
                            const std::string& source);

// Turns a grip pose into the hand's target sample (centre, rotation, grasp), D.
haptics::TrajectorySample TargetFromPose(const haptics::GripPose& pose);

}  // namespace spidarcad::app
