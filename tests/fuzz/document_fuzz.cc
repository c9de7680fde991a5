// Fuzz harness: document files (app::ParseDocumentText, versions 1 and 2, docs/scene-format.md).
// Any text either loads or is refused with a SceneError that leaves the document as it was; an
// accepted document survives a round trip through DocumentToFileJson unchanged.
// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#include <cstddef>
#include <cstdint>
#include <string>

#include "doc/document.h"
#include "doc/document_io.h"
#include "fuzz_support.h"
#include "spidarcad/modeling/scene_io.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  using namespace spidarcad::app;
  const std::string text(reinterpret_cast<const char*>(data), size);
  Document doc;
  try {
    ParseDocumentText(text, "fuzz.json", &doc);
  } catch (const spidarcad::modeling::SceneError&) {
    if (!doc.objects().empty()) {
      spidarcad::fuzz::Violated("document", "a refused document left objects behind");
    }
    return 0;
  }
  const std::string once = DocumentToFileJson(doc).dump();
  Document again;
  try {
    ParseDocumentText(once, "round-trip", &again);
  } catch (const spidarcad::modeling::SceneError& e) {
    spidarcad::fuzz::Violated("document",
                              std::string("a loaded document does not load again: ") + e.what());
  }
  if (DocumentToFileJson(again).dump() != once) {
    spidarcad::fuzz::Violated("document", "a loaded document changes in a save/load round trip");
  }
  return 0;
}
