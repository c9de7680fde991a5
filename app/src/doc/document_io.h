// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
// The document file (docs/scene-format.md, "Version 2"): one JSON file holding every object of
// a Document. Version 1 scene files (solids, parts, snap) are read by modeling::ParseScene and
// written whenever the document holds nothing more; everything else is written as version 2:
// an "objects" list in document order whose large arrays (mesh vertices, triangles, tets,
// regions) are base64 of little-endian raw arrays with their dtype and shape. A file is
// written to a temporary file in the same directory, flushed and renamed over the target, so a
// reader sees the old file or the new one, never half of one.
#pragma once

#include <cstdint>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "doc/document.h"

namespace spidarcad::app {

// The highest document format version this code reads and writes.
inline constexpr int kDocumentVersion = 2;

// Options of the writer.
struct DocumentWriteOptions {
  // Write version 2 even when version 1 would hold everything (recovery files do).
  bool force_version2 = false;
  // Original file of an autosaved copy ("recovered_from"; "" for none or an untitled document).
  std::string recovered_from;
  // Include "recovered_from" even when it is empty (marks an autosave of an untitled document).
  bool mark_recovery = false;
};

// True when version 1 can hold the document: solids only (plus their parts and snap), no view.
bool FitsSceneVersion1(const Document& doc);
// The file's JSON (version 1 or 2 per FitsSceneVersion1 and options).
nlohmann::json DocumentToFileJson(const Document& doc, const DocumentWriteOptions& options = {});
// Writes the file atomically (temporary file in the same directory, fsync, rename). Throws
// modeling::SceneError naming path when it cannot be written; path is untouched then.
void WriteDocumentFile(const Document& doc, const std::string& path,
                       const DocumentWriteOptions& options = {});
// Replaces doc's content with the document text (version 1 or 2) and returns the version read.
// The text is parsed once (a version 1 scene too). Throws modeling::SceneError naming source,
// the line and column and the JSON pointer of the bad field; doc is unchanged then.
int ParseDocumentText(const std::string& text, const std::string& source, Document* doc);
// Largest document file ReadDocumentFile reads, bytes (256 MiB; docs/limits.md): documents hold
// meshes, so they may be larger than scene files (kMaxSceneFileBytes).
inline constexpr long long kMaxDocumentFileBytes = 256LL << 20;
// Reads a document file into doc (ParseDocumentText of its bytes, read once) and returns the
// version read (1 or 2). Does not set file_path(). A path that is not a regular file (a directory,
// /dev/zero, a pipe) or a file larger than kMaxDocumentFileBytes is refused before reading
// (modeling::ReadBoundedFile).
int ReadDocumentFile(const std::string& path, Document* doc);
// "recovered_from" of a version 2 file: true when present (then *original holds it); false for
// files without it or unreadable ones.
bool ReadRecoveredFrom(const std::string& path, std::string* original);

// ---- raw arrays (exposed for tests) ----
// Standard base64 (RFC 4648, with padding) of bytes.
std::string Base64Encode(const void* data, std::size_t size);
// Bytes of standard base64 text; throws std::invalid_argument naming the offset of a bad character
// or a bad length.
std::vector<std::uint8_t> Base64Decode(const std::string& text);

}  // namespace spidarcad::app
