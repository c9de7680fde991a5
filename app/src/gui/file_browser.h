// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
// The window's in-window file browser (File → Open, Import mesh; no GTK): a path text box above
// a listing of the current directory: the parent entry "..", the sub-directories, then the
// files the browser's filter accepts (documents: .json and recovery files; meshes: .stl, .obj,
// .ply, .vtu, .node), each group sorted by name without regard to case; hidden entries (a
// leading dot) are left out. The listing, the filter and the path resolution have no ImGui in
// them (tested in tests/app/file_browser_test.cc); DrawFileBrowser draws the dialog. Main
// thread only.
#pragma once

#include <filesystem>
#include <optional>
#include <string>
#include <vector>

namespace spidarcad::app {

// Which files a browser lists.
enum class BrowseFilter {
  kDocuments,  // .json (scenes, documents), .spidarcad (recovery files)
  kMeshes,     // .stl .obj .ply (surfaces), .vtu .node (tetrahedra)
};

// True when the file name's extension (any case) is one `filter` lists.
bool MatchesFilter(const std::string& file_name, BrowseFilter filter);

// One row of a listing.
struct BrowserEntry {
  std::string name;        // file or directory name; ".." for the parent
  bool directory = false;  // a directory (or the parent entry)
};

// The listing of `directory` (see the file comment): "..", unless it is the root, then the
// directories, then the matching files. Entries that cannot be read are skipped. Throws
// std::runtime_error naming the directory when it cannot be listed at all.
std::vector<BrowserEntry> ListDirectory(const std::filesystem::path& directory,
                                        BrowseFilter filter);

// The path `typed` in the path box means: itself when absolute, else relative to `directory`;
// "~" at its start is $HOME. Lexically normalised.
std::filesystem::path ResolveTypedPath(const std::string& typed,
                                       const std::filesystem::path& directory);

// State of one browser dialog across frames.
struct FileBrowserState {
  BrowseFilter filter = BrowseFilter::kDocuments;
  std::string title = "Open";         // popup title and button label
  std::filesystem::path directory;    // the directory listed
  char path[1024] = "";               // the path box
  std::vector<BrowserEntry> entries;  // listing of `directory`
  std::string error;                  // why the listing or the choice failed
  bool open_requested = false;        // open the popup at the next draw
  int selected = -1;                  // highlighted row
};

// Asks the browser to open at the next DrawFileBrowser, listing `directory` (its parent when it
// is a file, the working directory when empty).
void OpenFileBrowser(FileBrowserState* state, BrowseFilter filter, const std::string& title,
                     const std::filesystem::path& directory);

// Changes the listed directory (refreshes the listing; an unreadable one sets `error` and keeps
// the previous listing).
void BrowseTo(FileBrowserState* state, const std::filesystem::path& directory);

// What the path box's content asks for: a directory is browsed into (nullopt returned); a file
// (existing or not) is returned, resolved against the listed directory.
std::optional<std::string> SubmitTypedPath(FileBrowserState* state);

// Draws the dialog when open; returns the chosen file once (double-click on a file, Enter in the
// path box or the title button), else nullopt.
std::optional<std::string> DrawFileBrowser(FileBrowserState* state);

}  // namespace spidarcad::app
