// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
// One loader for the headless commands (`run`, `mesh`, `fem`, `import`): opens a version 2
// document or a version 1 scene file (docs/scene-format.md) and gives a Document. A version 1
// file is read by modeling::LoadScene exactly as before (same checks, same messages), so the
// commands behave byte for byte as they did on scene files; a version 2 file is read by the
// document reader (doc/document_io.h), which also meshes its generated meshes.
#pragma once

#include <memory>
#include <string>
#include <vector>

#include "doc/document.h"
#include "spidarcad/modeling/scene_io.h"

namespace spidarcad::app {

// A file opened by OpenDocumentFile.
struct OpenedDocument {
  std::string path;               // the file
  int version = 1;                // 1: a version 1 scene file; 2: a version 2 document
  std::unique_ptr<Document> doc;  // its content (never null)
};

// The version the file declares ("version" at the top level): 2 for a document, 1 otherwise
// (including files that are not JSON or cannot be read: the version 1 reader names the problem).
// Reads the file with a streaming parser that stops at the version, so it costs little.
int DocumentFileVersion(const std::string& path);

// Opens a document or scene file. Throws InputError naming the file, line, column and field
// (the SceneError's message) when it does not load; nothing else is touched.
OpenedDocument OpenDocumentFile(const std::string& path);

// The JSON pointer of object `id` in the file: "/objects/i" (version 2) or "/solids/k"
// (version 1, where k counts the solids only); "" when the document has no such object.
std::string ObjectPointer(const OpenedDocument& opened, ObjectId id);

// "'a', 'b'" naming every object whose kind (ObjectKindName) is one of `kinds` (empty: any),
// in document order, or "none" when there is none.
std::string ObjectNames(const Document& doc, const std::vector<std::string>& kinds);

}  // namespace spidarcad::app
