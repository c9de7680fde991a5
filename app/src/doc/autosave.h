// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
// Autosave and crash recovery. An Autosaver writes the document, as a version 2 file marked with
// "recovered_from" (docs/scene-format.md), to a recovery file when the document is dirty and at
// least `interval` has passed since its last autosave; a clean save or a close removes the file.
// At start, ListRecoveryFiles finds what a crashed or killed session left behind.
//
// Recovery directory: $SPIDARCAD_RECOVERY_DIR if set, else $XDG_STATE_HOME/spidarcad/recovery,
// else $HOME/.local/state/spidarcad/recovery, else "spidarcad-recovery" in the system temporary
// directory. File: <16 hex digits of FNV-1a 64 of the document's path>.spidarcad, or
// untitled-<pid>.spidarcad for a document never saved (one per process).
#pragma once

#include <chrono>
#include <filesystem>
#include <string>
#include <vector>

#include "doc/document.h"

namespace spidarcad::app {

// The recovery directory (see the file comment); not created here.
std::filesystem::path DefaultRecoveryDirectory();

// A file left by an Autosaver.
struct RecoveryFile {
  std::filesystem::path path;               // the recovery file (load it with Document::Load)
  std::string original;                     // the document's own file, "" for an untitled document
  std::filesystem::file_time_type written;  // when it was written
};

// Recovery files in directory, newest first; unreadable files and others are skipped.
std::vector<RecoveryFile> ListRecoveryFiles(
    const std::filesystem::path& directory = DefaultRecoveryDirectory());

// Writes recovery copies of one document (main thread; call Tick from the event loop).
class Autosaver {
 public:
  using Clock = std::chrono::steady_clock;
  // Autosaves into directory at most every interval.
  explicit Autosaver(std::filesystem::path directory = DefaultRecoveryDirectory(),
                     Clock::duration interval = std::chrono::seconds(60));
  // Recovery file of doc as it is now (depends on doc.file_path()).
  std::filesystem::path RecoveryPathFor(const Document& doc) const;
  // Writes the recovery file when doc is dirty, its revision moved since the last autosave and
  // at least interval passed since the last autosave (or since construction). Returns true when
  // it wrote. Never throws: a failed write is reported in last_error() and retried next time.
  bool Tick(const Document& doc, Clock::time_point now = Clock::now());
  // After a successful Save, or when the document is closed: removes its recovery file (and that
  // of the path it had before, when a Save As renamed it).
  void Discard(const Document& doc);
  // Why the last write failed ("" after a success).
  const std::string& last_error() const { return last_error_; }
  // The directory.
  const std::filesystem::path& directory() const { return directory_; }

 private:
  std::filesystem::path directory_;
  Clock::duration interval_;
  Clock::time_point last_write_;
  std::uint64_t last_revision_ = 0;
  bool wrote_any_ = false;
  std::filesystem::path last_path_;
  std::string last_error_;
};

}  // namespace spidarcad::app
