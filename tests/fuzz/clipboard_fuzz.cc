// Fuzz harness: clipboard text (app::ParseClipboard, pasted from the system clipboard). Any text
// is either parsed or refused with a ClipboardError; accepted text pastes as a new solid into an
// empty document, and undo leaves the document empty again.
// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#include <cstddef>
#include <cstdint>
#include <string>

#include "doc/clipboard.h"
#include "doc/document.h"
#include "fuzz_support.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  using namespace spidarcad::app;
  const std::string text(reinterpret_cast<const char*>(data), size);
  try {
    ParseClipboard(text);
  } catch (const ClipboardError&) {
    return 0;
  }
  Document doc;
  doc.Execute(PasteAsSolid(text));
  if (doc.objects().size() != 1) {
    spidarcad::fuzz::Violated("clipboard", "accepted text did not paste exactly one solid");
  }
  doc.Undo();
  if (!doc.objects().empty())
    spidarcad::fuzz::Violated("clipboard", "undo of a paste left objects");
  return 0;
}
