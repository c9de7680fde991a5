// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
// Tests of the recent-files list (doc/recent_files.h): order, cap, dedupe, missing files, the
// store's round trip and its tolerance of bad content, and where it lives.
#include "doc/recent_files.h"

#include <gtest/gtest.h>
#include <stdlib.h>

#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

namespace spidarcad::app {
namespace {

namespace fs = std::filesystem;

// A fresh directory under the test output directory, named after `tag`.
fs::path Scratch(const std::string& tag) {
  const fs::path dir = fs::path(SPIDARCAD_TEST_OUTPUT_DIR) / ("recent_" + tag);
  fs::remove_all(dir);
  fs::create_directories(dir);
  return dir;
}

// Creates an empty file and returns its path.
std::string Touch(const fs::path& path) {
  std::ofstream(path) << "{}";
  return path.string();
}

TEST(RecentFiles, PutsTheLatestFirstAndMovesAReopenedFileToTheFront) {
  RecentFiles recent("");
  recent.Add("/a/one.json");
  recent.Add("/a/two.json");
  recent.Add("/a/three.json");
  EXPECT_EQ(recent.paths(),
            (std::vector<std::string>{"/a/three.json", "/a/two.json", "/a/one.json"}));
  recent.Add("/a/one.json");
  EXPECT_EQ(recent.paths(),
            (std::vector<std::string>{"/a/one.json", "/a/three.json", "/a/two.json"}));
}

TEST(RecentFiles, KeepsOnlyTheEightMostRecent) {
  RecentFiles recent("");
  for (int i = 0; i < 11; ++i) recent.Add("/d/f" + std::to_string(i) + ".json");
  ASSERT_EQ(recent.paths().size(), 8u);
  // Files 10 down to 3: the three oldest (0, 1, 2) fell off.
  for (int k = 0; k < 8; ++k)
    EXPECT_EQ(recent.paths()[k], "/d/f" + std::to_string(10 - k) + ".json");
}

TEST(RecentFiles, CountsSpellingsOfOneFileOnce) {
  const fs::path cwd = fs::current_path();
  RecentFiles recent("");
  recent.Add("scene.json");
  recent.Add("./sub/../scene.json");
  recent.Add((cwd / "scene.json").string());
  ASSERT_EQ(recent.paths().size(), 1u);
  EXPECT_EQ(recent.paths()[0], (cwd / "scene.json").lexically_normal().string());
}

TEST(RecentFiles, MarksMissingFilesAndRemovesOnRequest) {
  const fs::path dir = Scratch("missing");
  const std::string here = Touch(dir / "here.json");
  const std::string gone = (dir / "gone.json").string();
  RecentFiles recent("");
  recent.Add(gone);
  recent.Add(here);
  const std::vector<RecentEntry> entries = recent.Entries();
  ASSERT_EQ(entries.size(), 2u);
  EXPECT_EQ(entries[0].path, here);
  EXPECT_TRUE(entries[0].exists);
  EXPECT_EQ(entries[1].path, gone);
  EXPECT_FALSE(entries[1].exists);
  recent.Remove(gone);
  EXPECT_EQ(recent.paths(), std::vector<std::string>{here});
}

TEST(RecentFiles, SavesAndLoadsTheSameListInTheSameOrder) {
  const fs::path dir = Scratch("roundtrip");
  const fs::path store = dir / "config" / "spidarcad" / "recent.json";
  RecentFiles a(store);
  for (const char* name : {"/x/1.json", "/x/2.json", "/x/3.json"}) a.Add(name);
  ASSERT_EQ(a.Save(), "");
  RecentFiles b(store);
  b.Load();
  EXPECT_EQ(b.paths(), a.paths());
  // The store is the documented JSON.
  std::ifstream in(store);
  std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  EXPECT_NE(text.find("\"spidarcad-recent\""), std::string::npos) << text;
  EXPECT_LT(text.find("/x/3.json"), text.find("/x/1.json")) << text;
}

TEST(RecentFiles, LoadsAnEmptyListFromAMissingOrBadStoreAndSkipsBadEntries) {
  const fs::path dir = Scratch("bad");
  RecentFiles missing(dir / "none.json");
  missing.Load();
  EXPECT_TRUE(missing.paths().empty());
  std::ofstream(dir / "garbage.json") << "{ not json";
  RecentFiles garbage(dir / "garbage.json");
  garbage.Add("/kept/before.json");
  garbage.Load();
  EXPECT_TRUE(garbage.paths().empty());
  // Twelve entries with a number, an empty string and a duplicate among them: the strings, each
  // once, at most eight.
  nlohmann::json files = nlohmann::json::array({"/m/a.json", 7, "", "/m/a.json"});
  for (int i = 0; i < 8; ++i) files.push_back("/m/f" + std::to_string(i) + ".json");
  std::ofstream(dir / "mixed.json") << nlohmann::json{{"files", files}}.dump();
  RecentFiles mixed(dir / "mixed.json");
  mixed.Load();
  ASSERT_EQ(mixed.paths().size(), 8u);
  EXPECT_EQ(mixed.paths()[0], "/m/a.json");
  EXPECT_EQ(mixed.paths()[1], "/m/f0.json");
  EXPECT_EQ(mixed.paths()[7], "/m/f6.json");
}

TEST(RecentFiles, LivesUnderXdgConfigHomeElseUnderHomeDotConfig) {
  const char* xdg = std::getenv("XDG_CONFIG_HOME");
  const std::string saved_xdg = xdg != nullptr ? xdg : "";
  ::setenv("XDG_CONFIG_HOME", "/cfg", 1);
  EXPECT_EQ(DefaultRecentFilesPath(), fs::path("/cfg/spidarcad/recent.json"));
  ::unsetenv("XDG_CONFIG_HOME");
  const char* home = std::getenv("HOME");
  if (home != nullptr && *home != 0) {
    EXPECT_EQ(DefaultRecentFilesPath(), fs::path(home) / ".config/spidarcad/recent.json");
  }
  if (xdg != nullptr) ::setenv("XDG_CONFIG_HOME", saved_xdg.c_str(), 1);
}

TEST(RecentFiles, ReportsAStoreThatCannotBeWritten) {
  const fs::path dir = Scratch("readonly");
  std::ofstream(dir / "file") << "x";  // a file where the directory should be
  RecentFiles recent(dir / "file" / "recent.json");
  recent.Add("/y/a.json");
  EXPECT_NE(recent.Save(), "");
}

}  // namespace
}  // namespace spidarcad::app
