// `spidarcad calibrate --device board-sim|usb`: a self-calibration session on a connected
// board. Poses come from the device while the user (board-sim: a simulated hand) waves the grip;
// a progress line on stderr says how many useful poses were collected and which octants of the
// workspace still need some; then the before/after table and the calibration file.
// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#pragma once

#include <cstdint>
#include <string>

#include "spidarcad/haptics/geometry.h"

namespace spidarcad::app {

// What `calibrate --device` was asked.
struct CalibrationSessionOptions {
  std::string device = "board-sim";  // board-sim or usb
  std::uint64_t seed = 1;            // board-sim: the simulated device's seed
  haptics::SpidarGeometry geometry;  // the device's frame and pole, m
  int poses = 200;                   // useful poses to collect
  std::string out;                   // calibration file to write ("" for none)
  bool json = false;                 // the table as JSON on stdout
  double max_seconds = 0.0;          // give up after this long; 0: 180 s (board-sim, virtual
                                     // time) or 300 s (usb)
};

// Runs the session. Throws InputError (exit 2) on bad options or when no board answers
// (naming `spidarcad device list`); CommandExit{1} when the calibration fails.
void RunCalibrationSession(const CalibrationSessionOptions& options);

}  // namespace spidarcad::app
