// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#include "doc/recent_files.h"

#include <unistd.h>

#include <algorithm>
#include <cstdlib>
#include <fstream>
#include <nlohmann/json.hpp>
#include <sstream>
#include <system_error>

namespace spidarcad::app {

namespace fs = std::filesystem;

fs::path DefaultRecentFilesPath() {
  if (const char* d = std::getenv("XDG_CONFIG_HOME"); d != nullptr && *d != 0)
    return fs::path(d) / "spidarcad" / "recent.json";
  if (const char* h = std::getenv("HOME"); h != nullptr && *h != 0)
    return fs::path(h) / ".config" / "spidarcad" / "recent.json";
  return {};
}

std::string NormalisedPath(const std::string& path) {
  std::error_code ec;
  const fs::path absolute = fs::absolute(path, ec);
  return (ec ? fs::path(path) : absolute).lexically_normal().string();
}

RecentFiles::RecentFiles(fs::path store) : store_(std::move(store)) {}

void RecentFiles::Load() {
  paths_.clear();
  if (store_.empty()) return;
  std::ifstream in(store_);
  if (!in) return;
  std::stringstream text;
  text << in.rdbuf();
  const nlohmann::json j = nlohmann::json::parse(text.str(), nullptr, false);
  if (!j.is_object() || !j.contains("files") || !j.at("files").is_array()) return;
  const nlohmann::json& files = j.at("files");
  // Oldest first, so that Add leaves the most recent at the front.
  for (auto it = files.rbegin(); it != files.rend(); ++it) {
    if (it->is_string() && !it->get<std::string>().empty()) Add(it->get<std::string>());
  }
}

std::string RecentFiles::Save() const {
  if (store_.empty()) return "";
  std::error_code ec;
  fs::create_directories(store_.parent_path(), ec);
  nlohmann::json j = {{"format", "spidarcad-recent"}, {"version", 1}, {"files", paths_}};
  const fs::path temporary =
      store_.string() + ".tmp-" + std::to_string(static_cast<long>(::getpid()));
  {
    std::ofstream out(temporary, std::ios::trunc);
    out << j.dump(2) << "\n";
    out.flush();
    if (!out) {
      fs::remove(temporary, ec);
      return "cannot write the recent-files list " + temporary.string();
    }
  }
  fs::rename(temporary, store_, ec);
  if (ec) {
    fs::remove(temporary, ec);
    return "cannot replace the recent-files list " + store_.string() + ": " + ec.message();
  }
  return "";
}

void RecentFiles::Add(const std::string& path) {
  const std::string normalised = NormalisedPath(path);
  Remove(normalised);
  paths_.insert(paths_.begin(), normalised);
  if (paths_.size() > static_cast<size_t>(kMaxEntries)) paths_.resize(kMaxEntries);
}

void RecentFiles::Remove(const std::string& path) {
  const std::string normalised = NormalisedPath(path);
  paths_.erase(std::remove(paths_.begin(), paths_.end(), normalised), paths_.end());
}

std::vector<RecentEntry> RecentFiles::Entries() const {
  std::vector<RecentEntry> out;
  for (const std::string& p : paths_) {
    std::error_code ec;
    out.push_back({p, fs::is_regular_file(p, ec)});
  }
  return out;
}

}  // namespace spidarcad::app
