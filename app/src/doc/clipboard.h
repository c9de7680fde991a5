// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
// Copy and paste of implicit solids and subtrees as JSON text, so that the text can also travel
// through the system clipboard (the window puts clipboard.text() there and hands pasted text to
// SetText). Text format:
//   {"format": "spidarcad-clipboard", "version": 1, "solid": {"name": ..., "root": NODE}}
//   {"format": "spidarcad-clipboard", "version": 1, "node": NODE}
// where NODE is a node of the scene format (docs/scene-format.md, modeling::NodeToJson). A bare
// NODE (an object with "type") or a bare solid ({"name", "root"}) is accepted as well.
// Pasting never changes the clipboard; pasted nodes get ids unique in the document (see
// MakePastedTreeUnique) and names that collide get a " copy" suffix.
#pragma once

#include <memory>
#include <stdexcept>
#include <string>

#include "doc/command.h"
#include "doc/document.h"

namespace spidarcad::app {

// Malformed clipboard text: says what was wrong and where (line and column for syntax errors,
// the JSON pointer of the field otherwise). Nothing was changed.
class ClipboardError : public std::invalid_argument {
 public:
  using std::invalid_argument::invalid_argument;
};

// What clipboard text holds.
struct ClipboardContent {
  bool is_solid = false;        // a whole solid (with its name) rather than a subtree
  std::string name;             // the solid's name (is_solid only)
  modeling::ImplicitNode root;  // the copied tree, validated
};

// Parses and validates clipboard text; throws ClipboardError.
ClipboardContent ParseClipboard(const std::string& text);

// The application's clipboard: one piece of JSON text.
class Clipboard {
 public:
  // Copies the tree of a solid or rigid part as a solid (with its name). Throws DocumentError.
  void CopySolid(const Document& doc, ObjectId id);
  // Copies the subtree at path of a solid or rigid part. Throws DocumentError.
  void CopyNode(const Document& doc, ObjectId id, const NodePath& path);
  // Replaces the text (e.g. from the system clipboard); it is checked only when pasted.
  void SetText(std::string text) { text_ = std::move(text); }
  // The JSON text (indented).
  const std::string& text() const { return text_; }
  // True when nothing was copied.
  bool empty() const { return text_.empty(); }

 private:
  std::string text_;
};

// Command pasting clipboard text as a new solid (appended; a subtree becomes a solid named after
// its node's name or type). Throws ClipboardError at once when the text is malformed.
std::unique_ptr<Command> PasteAsSolid(const std::string& text);
// Command pasting clipboard text (solid or subtree) as child `index` (-1: last) of the node at
// parent in object id. Throws ClipboardError at once when the text is malformed; the command
// throws like edit::AddNode when the place is wrong.
std::unique_ptr<Command> PasteAsChild(const std::string& text, ObjectId id, NodePath parent,
                                      int index = -1);

}  // namespace spidarcad::app
