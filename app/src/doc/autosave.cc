// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#include "doc/autosave.h"

#include <unistd.h>

#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <system_error>

#include "doc/document_io.h"
#include "spidarcad/fem/precompute_cache.h"

namespace spidarcad::app {

namespace fs = std::filesystem;

fs::path DefaultRecoveryDirectory() {
  if (const char* d = std::getenv("SPIDARCAD_RECOVERY_DIR"); d != nullptr && *d != 0) return d;
  if (const char* d = std::getenv("XDG_STATE_HOME"); d != nullptr && *d != 0)
    return fs::path(d) / "spidarcad" / "recovery";
  if (const char* h = std::getenv("HOME"); h != nullptr && *h != 0) {
    return fs::path(h) / ".local" / "state" / "spidarcad" / "recovery";
  }
  std::error_code ec;
  return fs::temp_directory_path(ec) / "spidarcad-recovery";
}

std::vector<RecoveryFile> ListRecoveryFiles(const fs::path& directory) {
  std::vector<RecoveryFile> out;
  std::error_code ec;
  for (fs::directory_iterator it(directory, ec), end; !ec && it != end; it.increment(ec)) {
    const fs::path p = it->path();
    if (p.extension() != ".spidarcad" || !it->is_regular_file(ec)) continue;
    RecoveryFile f;
    f.path = p;
    if (!ReadRecoveredFrom(p.string(), &f.original)) continue;
    f.written = fs::last_write_time(p, ec);
    out.push_back(std::move(f));
  }
  std::sort(out.begin(), out.end(),
            [](const RecoveryFile& a, const RecoveryFile& b) { return a.written > b.written; });
  return out;
}

Autosaver::Autosaver(fs::path directory, Clock::duration interval)
    : directory_(std::move(directory)), interval_(interval), last_write_(Clock::now()) {}

fs::path Autosaver::RecoveryPathFor(const Document& doc) const {
  if (doc.file_path().empty())
    return directory_ / ("untitled-" + std::to_string(::getpid()) + ".spidarcad");
  std::error_code ec;
  fs::path absolute = fs::absolute(doc.file_path(), ec);
  const std::string key = ec ? doc.file_path() : absolute.lexically_normal().string();
  char hex[17];
  std::snprintf(hex, sizeof hex, "%016llx",
                static_cast<unsigned long long>(fem::Fnv1a64(key.data(), key.size())));
  return directory_ / (std::string(hex) + ".spidarcad");
}

bool Autosaver::Tick(const Document& doc, Clock::time_point now) {
  if (!doc.dirty()) return false;
  if (wrote_any_ && doc.revision() == last_revision_) return false;
  if (now - last_write_ < interval_) return false;
  const fs::path path = RecoveryPathFor(doc);
  try {
    std::error_code ec;
    fs::create_directories(directory_, ec);
    DocumentWriteOptions options;
    options.force_version2 = true;
    options.mark_recovery = true;
    if (!doc.file_path().empty())
      options.recovered_from = fs::absolute(doc.file_path(), ec).lexically_normal().string();
    WriteDocumentFile(doc, path.string(), options);
  } catch (const std::exception& e) {
    last_error_ = e.what();
    return false;
  }
  if (!last_path_.empty() && last_path_ != path) {
    std::error_code ec;
    fs::remove(last_path_, ec);
  }
  last_error_.clear();
  last_path_ = path;
  last_write_ = now;
  last_revision_ = doc.revision();
  wrote_any_ = true;
  return true;
}

void Autosaver::Discard(const Document& doc) {
  std::error_code ec;
  fs::remove(RecoveryPathFor(doc), ec);
  if (!last_path_.empty()) fs::remove(last_path_, ec);
  last_path_.clear();
  wrote_any_ = false;
}

}  // namespace spidarcad::app
