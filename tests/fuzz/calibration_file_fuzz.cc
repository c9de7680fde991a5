// Fuzz harness: calibration files (app::LoadCalibrationFile, docs/calibration-format.md). Any
// bytes either load or are refused with an InputError; an accepted file, written again with
// CalibrationFileJson, loads to the same text.
// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#include <cstddef>
#include <cstdint>
#include <string>

#include "doc/input_error.h"
#include "fuzz_support.h"
#include "scene/calibration_file.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  using namespace spidarcad::app;
  static spidarcad::fuzz::ScratchFile file("calibration.json");
  CalibrationFile loaded;
  try {
    loaded = LoadCalibrationFile(file.Write(data, size));
  } catch (const InputError&) {
    return 0;
  }
  const std::string once = CalibrationFileJson(loaded);
  CalibrationFile again;
  try {
    again = LoadCalibrationFile(
        file.Write(reinterpret_cast<const std::uint8_t*>(once.data()), once.size()));
  } catch (const InputError& e) {
    spidarcad::fuzz::Violated("calibration_file",
                              std::string("a loaded file does not load again: ") + e.what());
  }
  if (CalibrationFileJson(again) != once) {
    spidarcad::fuzz::Violated("calibration_file",
                              "a loaded file changes in a write/load round trip");
  }
  return 0;
}
