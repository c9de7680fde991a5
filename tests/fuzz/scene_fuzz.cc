// Fuzz harness: scene files (modeling::ParseScene, docs/scene-format.md). Any text either
// loads or is refused with a SceneError; an accepted scene survives a round trip through
// SceneToJson and SceneFromJson unchanged.
// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#include <cstddef>
#include <cstdint>
#include <string>

#include "fuzz_support.h"
#include "spidarcad/modeling/scene_io.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  using namespace spidarcad::modeling;
  const std::string text(reinterpret_cast<const char*>(data), size);
  Scene scene;
  try {
    scene = ParseScene(text, "fuzz.json");
  } catch (const SceneError&) {
    return 0;
  }
  const nlohmann::json once = SceneToJson(scene);
  Scene again;
  try {
    again = SceneFromJson(once, "round-trip");
  } catch (const SceneError& e) {
    spidarcad::fuzz::Violated("scene",
                              std::string("a loaded scene does not load again: ") + e.what());
  }
  if (SceneToJson(again) != once) {
    spidarcad::fuzz::Violated("scene", "a loaded scene changes in a save/load round trip");
  }
  return 0;
}
