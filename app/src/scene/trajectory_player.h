// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
// Plays a scripted grip trajectory (haptics/trajectory.h, the CSV of `spidarcad run
// --trajectory`) into the window's haptic runtime in wall-clock time: a thread of its own samples
// the trajectory every millisecond (absolute-time sleeps, so the rate does not depend on the
// window's frame rate) and hands the sample to a sink, normally HapticRuntime::SetTarget. Time
// t0 + τ of the trajectory is played τ seconds after Start (t0 = its first sample's time); after
// its end the last sample is held (written once more, then the thread ends).
//
// The sink is called from the player's thread only; while the player runs nobody else may write
// the runtime's target (its triple buffer has one writer). Frame D, SI units.
#pragma once

#include <atomic>
#include <chrono>
#include <functional>
#include <string>
#include <thread>

#include "spidarcad/haptics/trajectory.h"

namespace spidarcad::app {

// Largest trajectory file `run` and the window read, bytes (docs/limits.md).
constexpr long long kMaxTrajectoryFileBytes = 256LL << 20;

// Checks that `path` (given as --trajectory) is a regular file of at most
// kMaxTrajectoryFileBytes before it is read: not a directory, device or pipe, which would be read
// without end. Throws InputError naming the file and the limit. A missing file passes (the
// reader names it).
void CheckTrajectoryFile(const std::string& path);

// A trajectory played on its own thread.
class TrajectoryPlayer {
 public:
  using Sink = std::function<void(const haptics::TrajectorySample&)>;
  // `trajectory` must not be empty (throws std::invalid_argument); `sink` must not be null.
  TrajectoryPlayer(haptics::Trajectory trajectory, Sink sink);
  // Stops the thread.
  ~TrajectoryPlayer();
  TrajectoryPlayer(const TrajectoryPlayer&) = delete;
  TrajectoryPlayer& operator=(const TrajectoryPlayer&) = delete;

  // Starts playing now (the first sample is written before Start returns). Once only.
  void Start();
  // Stops the thread (joins it). Safe to call twice or before Start.
  void Stop();
  // Seconds since Start (0 before).
  double elapsed() const;
  // Length of the trajectory, s (last minus first sample time).
  double duration() const { return trajectory_.end_time() - trajectory_.start_time(); }
  // True once elapsed() >= duration() + `margin` (s).
  bool finished(double margin = 0.0) const { return started_ && elapsed() >= duration() + margin; }
  // True once the thread has written the last sample and ended (the target is then held there).
  bool done() const { return done_.load(std::memory_order_acquire); }
  // The trajectory's sample at the current elapsed time (held before the start and after the end).
  haptics::TrajectorySample Current() const;
  const haptics::Trajectory& trajectory() const { return trajectory_; }

 private:
  void Run();

  haptics::Trajectory trajectory_;
  Sink sink_;
  std::chrono::steady_clock::time_point start_{};
  bool started_ = false;
  std::atomic<bool> stop_{false};
  std::atomic<bool> done_{false};
  std::thread thread_;
};

}  // namespace spidarcad::app
