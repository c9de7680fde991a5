// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#include "scene/trajectory_player.h"

#include <cstdint>
#include <filesystem>
#include <stdexcept>
#include <utility>

#include "doc/input_error.h"

namespace spidarcad::app {

void CheckTrajectoryFile(const std::string& path) {
  std::error_code ec;
  const std::filesystem::file_status status = std::filesystem::status(path, ec);
  if (ec || !std::filesystem::exists(status)) return;  // Trajectory::Load names it
  if (!std::filesystem::is_regular_file(status)) {
    throw InputError("--trajectory '" + path +
                     "': not a regular file (a directory, device or pipe); give a CSV file "
                     "(t,x,y,z,qw,qx,qy,qz,grasp)");
  }
  const std::uintmax_t size = std::filesystem::file_size(path, ec);
  if (!ec && size > static_cast<std::uintmax_t>(kMaxTrajectoryFileBytes)) {
    throw InputError(
        "--trajectory '" + path + "': " + std::to_string(size) + " bytes, more than the " +
        std::to_string(kMaxTrajectoryFileBytes) +
        " bytes (256 MiB) a trajectory may have (docs/limits.md); sample it more coarsely (the "
        "player interpolates between samples)");
  }
}

TrajectoryPlayer::TrajectoryPlayer(haptics::Trajectory trajectory, Sink sink)
    : trajectory_(std::move(trajectory)), sink_(std::move(sink)) {
  if (trajectory_.empty())
    throw std::invalid_argument("TrajectoryPlayer: the trajectory has no samples");
  if (!sink_) throw std::invalid_argument("TrajectoryPlayer: no sink");
}

TrajectoryPlayer::~TrajectoryPlayer() { Stop(); }

void TrajectoryPlayer::Start() {
  if (started_) return;
  start_ = std::chrono::steady_clock::now();
  started_ = true;
  sink_(trajectory_.Sample(trajectory_.start_time()));
  thread_ = std::thread([this] { Run(); });
}

void TrajectoryPlayer::Stop() {
  stop_.store(true, std::memory_order_release);
  if (thread_.joinable()) thread_.join();
}

double TrajectoryPlayer::elapsed() const {
  if (!started_) return 0.0;
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - start_).count();
}

haptics::TrajectorySample TrajectoryPlayer::Current() const {
  return trajectory_.Sample(trajectory_.start_time() + elapsed());
}

void TrajectoryPlayer::Run() {
  const double t0 = trajectory_.start_time(), length = duration();
  while (!stop_.load(std::memory_order_acquire)) {
    // The next whole millisecond after now (a late wake-up skips the missed ones).
    const auto now = std::chrono::steady_clock::now();
    const long next_ms =
        std::chrono::duration_cast<std::chrono::milliseconds>(now - start_).count() + 1;
    std::this_thread::sleep_until(start_ + std::chrono::milliseconds(next_ms));
    const double tau = elapsed();
    sink_(trajectory_.Sample(t0 + tau));
    if (tau >= length) break;  // the last sample written: held from now on
  }
  done_.store(true, std::memory_order_release);
}

}  // namespace spidarcad::app
