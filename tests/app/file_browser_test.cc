// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
// Tests of the file browser's logic (gui/file_browser.h), without ImGui: which files each
// filter lists, the order and content of a listing, and what a typed path means.
#include "gui/file_browser.h"

#include <gtest/gtest.h>
#include <stdlib.h>

#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

namespace spidarcad::app {
namespace {

namespace fs = std::filesystem;

fs::path Scratch(const std::string& tag) {
  const fs::path dir = fs::path(SPIDARCAD_TEST_OUTPUT_DIR) / ("browser_" + tag);
  fs::remove_all(dir);
  fs::create_directories(dir);
  return dir;
}

std::vector<std::string> Names(const std::vector<BrowserEntry>& entries) {
  std::vector<std::string> out;
  for (const BrowserEntry& e : entries) out.push_back(e.name + (e.directory ? "/" : ""));
  return out;
}

TEST(FileBrowser, FiltersDocumentsAndMeshesByExtensionInAnyCase) {
  for (const char* yes : {"a.json", "B.JSON", "x.spidarcad"}) {
    EXPECT_TRUE(MatchesFilter(yes, BrowseFilter::kDocuments)) << yes;
    EXPECT_FALSE(MatchesFilter(yes, BrowseFilter::kMeshes)) << yes;
  }
  for (const char* yes : {"p.stl", "P.STL", "q.obj", "r.ply", "s.vtu", "t.node"}) {
    EXPECT_TRUE(MatchesFilter(yes, BrowseFilter::kMeshes)) << yes;
    EXPECT_FALSE(MatchesFilter(yes, BrowseFilter::kDocuments)) << yes;
  }
  for (const char* no : {"t.ele", "notes.txt", "json", "a.json.bak", "stl"}) {
    EXPECT_FALSE(MatchesFilter(no, BrowseFilter::kDocuments)) << no;
    EXPECT_FALSE(MatchesFilter(no, BrowseFilter::kMeshes)) << no;
  }
}

TEST(FileBrowser, ListsParentThenDirectoriesThenMatchingFilesEachSortedCaselessly) {
  const fs::path dir = Scratch("listing");
  for (const char* d : {"zeta", "Alpha", "beta", ".hidden_dir"}) fs::create_directory(dir / d);
  for (const char* f : {"b.json", "A.json", "c.stl", "notes.txt", ".hidden.json", "d.JSON",
                        "part.node", "part.ele"}) {
    std::ofstream(dir / f) << "x";
  }
  EXPECT_EQ(
      Names(ListDirectory(dir, BrowseFilter::kDocuments)),
      (std::vector<std::string>{"../", "Alpha/", "beta/", "zeta/", "A.json", "b.json", "d.JSON"}));
  EXPECT_EQ(Names(ListDirectory(dir, BrowseFilter::kMeshes)),
            (std::vector<std::string>{"../", "Alpha/", "beta/", "zeta/", "c.stl", "part.node"}));
}

TEST(FileBrowser, HasNoParentEntryAtTheRoot) {
  const std::vector<BrowserEntry> root = ListDirectory("/", BrowseFilter::kDocuments);
  ASSERT_FALSE(root.empty());
  for (const BrowserEntry& e : root) EXPECT_NE(e.name, "..");
}

TEST(FileBrowser, ThrowsNamingADirectoryThatCannotBeListed) {
  const fs::path missing = Scratch("gone") / "not_here";
  try {
    ListDirectory(missing, BrowseFilter::kDocuments);
    FAIL() << "listed a missing directory";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find(missing.string()), std::string::npos) << e.what();
  }
}

TEST(FileBrowser, ResolvesTypedPathsAgainstTheListedDirectoryAndHome) {
  EXPECT_EQ(ResolveTypedPath("scene.json", "/w/docs"), fs::path("/w/docs/scene.json"));
  EXPECT_EQ(ResolveTypedPath("../other/x.json", "/w/docs"), fs::path("/w/other/x.json"));
  EXPECT_EQ(ResolveTypedPath("/abs/y.json", "/w/docs"), fs::path("/abs/y.json"));
  EXPECT_EQ(ResolveTypedPath("sub/", "/w/docs"), fs::path("/w/docs/sub"));
  const char* home = std::getenv("HOME");
  if (home != nullptr && *home != 0) {
    EXPECT_EQ(ResolveTypedPath("~/z.json", "/w"), (fs::path(home) / "z.json").lexically_normal());
  }
}

TEST(FileBrowser, EntersATypedDirectoryAndReturnsATypedFile) {
  const fs::path dir = Scratch("submit");
  fs::create_directory(dir / "inner");
  std::ofstream(dir / "inner" / "doc.json") << "{}";
  FileBrowserState state;
  OpenFileBrowser(&state, BrowseFilter::kDocuments, "Open", dir);
  EXPECT_EQ(state.directory, dir.lexically_normal());
  std::snprintf(state.path, sizeof(state.path), "%s", "inner");
  EXPECT_FALSE(SubmitTypedPath(&state).has_value());
  EXPECT_EQ(state.directory, (dir / "inner").lexically_normal());
  EXPECT_EQ(Names(state.entries), (std::vector<std::string>{"../", "doc.json"}));
  std::snprintf(state.path, sizeof(state.path), "%s", "doc.json");
  const std::optional<std::string> chosen = SubmitTypedPath(&state);
  ASSERT_TRUE(chosen.has_value());
  EXPECT_EQ(*chosen, (dir / "inner" / "doc.json").lexically_normal().string());
  // A directory that cannot be listed keeps the listing and says why.
  BrowseTo(&state, dir / "missing");
  EXPECT_EQ(state.directory, (dir / "inner").lexically_normal());
  EXPECT_NE(state.error.find("missing"), std::string::npos) << state.error;
}

TEST(FileBrowser, OpensOnTheParentOfAFileAndOnTheWorkingDirectoryWhenEmpty) {
  const fs::path dir = Scratch("start");
  std::ofstream(dir / "a.json") << "{}";
  FileBrowserState state;
  OpenFileBrowser(&state, BrowseFilter::kDocuments, "Open", dir / "a.json");
  EXPECT_EQ(state.directory, dir.lexically_normal());
  EXPECT_TRUE(state.open_requested);
  OpenFileBrowser(&state, BrowseFilter::kMeshes, "Import", "");
  EXPECT_EQ(state.directory, fs::current_path().lexically_normal());
}

}  // namespace
}  // namespace spidarcad::app
