// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
// The list of recently opened documents behind File → Open Recent: most recent first, at most
// kMaxEntries, each file once (paths compared made absolute and normalised). Stored as JSON
// ({"format": "spidarcad-recent", "version": 1, "files": [...]}) in
// $XDG_CONFIG_HOME/spidarcad/recent.json, else $HOME/.config/spidarcad/recent.json. A file that
// no longer exists stays in the list (the menu shows it disabled) until it is opened again or
// pushed out. Reading never throws (a missing or unreadable store is an empty list); writing is
// atomic (temporary file renamed over the store). Main thread only.
#pragma once

#include <filesystem>
#include <string>
#include <vector>

namespace spidarcad::app {

// The store of the recent list (see the file comment); "" when neither XDG_CONFIG_HOME nor HOME
// is set (the list then lives in memory only).
std::filesystem::path DefaultRecentFilesPath();

// One entry of the recent list.
struct RecentEntry {
  std::string path;     // absolute, normalised
  bool exists = false;  // the file exists now
};

// The recent list (see the file comment).
class RecentFiles {
 public:
  // Entries kept.
  static constexpr int kMaxEntries = 8;
  // A list stored at `store` ("" for memory only); Load() reads it.
  explicit RecentFiles(std::filesystem::path store = DefaultRecentFilesPath());
  // Replaces the list by the store's content; a missing, unreadable or malformed store gives an
  // empty list, entries that are not strings are skipped, and the cap and dedupe apply.
  void Load();
  // Writes the list to the store (creating its directory). Returns "" or the error text (the
  // store is untouched then).
  std::string Save() const;
  // Puts `path` first (made absolute and normalised; an existing entry for it moves to the
  // front) and drops the oldest beyond kMaxEntries.
  void Add(const std::string& path);
  // Removes the entry of `path`, if any.
  void Remove(const std::string& path);
  // The paths, most recent first.
  const std::vector<std::string>& paths() const { return paths_; }
  // The paths with whether each exists now.
  std::vector<RecentEntry> Entries() const;
  // Where the list is stored ("" for memory only).
  const std::filesystem::path& store() const { return store_; }

 private:
  std::filesystem::path store_;
  std::vector<std::string> paths_;
};

// `path` made absolute (against the working directory) and lexically normalised, as the recent
// list and the recovery files compare paths.
std::string NormalisedPath(const std::string& path);

}  // namespace spidarcad::app
