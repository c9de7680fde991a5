// Calibration files: the string-length calibration of one SPIDAR-G, with the device it belongs
// to, as JSON (format "spidarcad-calibration", version 1; docs/calibration-format.md). Written
// by `spidarcad calibrate --out`, read by `calibrate --load`, `run --calibration` and the window.
// Units: SI (m, N); the frame geometry is in the device frame D.
// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#pragma once

#include <cstdint>
#include <string>

#include "spidarcad/haptics/calibration.h"
#include "spidarcad/haptics/encoder.h"
#include "spidarcad/haptics/geometry.h"

namespace spidarcad::app {

// The device a calibration belongs to.
struct CalibrationDevice {
  // "simulated", "board-sim" (the same simulated SPIDAR-G behind the board simulator) or "usb".
  std::string kind = "simulated";
  std::string serial;      // usb: the board's serial number (HelloReply); "" for the others
  std::uint64_t seed = 0;  // simulated, board-sim: the simulated device's seed
  haptics::SpidarGeometry geometry;  // frame half-sides a, b, c and pole half-length d, m
  haptics::EncoderSpec encoder;      // nominal counts per revolution and pulley radius

  // One phrase: "simulated SPIDAR-G seed 3" or "USB board serial SPG-0042".
  std::string Describe() const;
};

// How well the calibration explained its data.
struct CalibrationFit {
  int samples = 0;            // samples used (poses, the homing one included)
  int iterations = 0;         // solver iterations (0 for the line fit)
  double condition = 0.0;     // condition number of the scaled parameter information
  double rms_residual = 0.0;  // over all lengths, m
  haptics::Vector8d string_rms_residual = haptics::Vector8d::Zero();  // per string, m
};

// The contents of a calibration file.
struct CalibrationFile {
  CalibrationDevice device;
  std::string date;    // when it was made, ISO 8601 UTC ("2026-12-02T01:45:03Z")
  std::string method;  // "self" (self-calibration) or "line" (the paper's jig line fit)
  haptics::EncoderCalibration calibration;  // per-string offset, gain, quadratic, stretch
  CalibrationFit fit;
};

// The fit summary of a calibration result over `samples` samples.
CalibrationFit FitOf(const haptics::CalibrationResult& result, int samples);

// The current time as ISO 8601 UTC to the second, "YYYY-MM-DDTHH:MM:SSZ".
std::string NowIso8601Utc();

// The file as JSON text (2-space indented, numbers to full precision).
std::string CalibrationFileJson(const CalibrationFile& file);

// Writes `file` to `path` atomically: a temporary file in the same directory, flushed to disk,
// then renamed over `path`; nothing is left behind on failure. Throws InputError naming `path`
// (prefixed with `option`, e.g. "--out") when it cannot be written.
void SaveCalibrationFile(const CalibrationFile& file, const std::string& path,
                         const std::string& option = "--out");

// Largest calibration file LoadCalibrationFile reads, bytes (1 MiB; a calibration is a few kB).
inline constexpr long long kMaxCalibrationFileBytes = 1LL << 20;
// Reads and validates every field of a calibration file. Throws InputError naming the file
// and the field that is missing or wrong and what was expected (e.g. "cal.json: field
// 'strings[2].gain': expected a number, got \"x\""); a file that is not JSON with its line
// and column; a path that is not a regular file or a file over kMaxCalibrationFileBytes before
// reading it.
CalibrationFile LoadCalibrationFile(const std::string& path);

// Empty when the calibration in `file` belongs to `device`; otherwise why not, naming both
// (another kind of device, another seed or serial, another frame or pole, another encoder).
// simulated and board-sim are the same simulated SPIDAR-G: their files are interchangeable.
std::string CalibrationMismatch(const CalibrationFile& file, const CalibrationDevice& device);

// ---- per-device memory: the calibration a lab made for its board, found again next time ----
// The file that remembers which calibration file belongs to which USB board:
// $XDG_CONFIG_HOME/spidarcad/devices.json, else $HOME/.config/spidarcad/devices.json ("" when
// neither variable is set). JSON: {"format": "spidarcad-devices", "version": 1,
// "calibrations": {"usb:SERIAL": "/absolute/path.json", ...}}.
std::string DeviceMemoryPath();

// The calibration file remembered for `device` (an absolute path), or "" when none is (only USB
// boards are remembered: a simulated device is recalibrated at every start, and reproducible
// runs name their file). An unreadable memory file counts as empty.
std::string RememberedCalibration(const CalibrationDevice& device);

// Remembers `path` (made absolute) as the calibration of `device` (kind "usb" only; others are
// ignored and give true). Written atomically; returns false with the reason in *why when the
// memory file cannot be written (the calibration file itself is unaffected).
bool RememberCalibration(const CalibrationDevice& device, const std::string& path,
                         std::string* why);

}  // namespace spidarcad::app
