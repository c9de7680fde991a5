// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#include "doc/assets.h"

#include <cstdlib>
#include <filesystem>
#include <system_error>

namespace spidarcad::app {

std::string AssetPath(const std::string& relative) {
  namespace fs = std::filesystem;
  std::error_code ec;
  if (const char* dir = std::getenv("SPIDARCAD_ASSETS_DIR"); dir != nullptr && *dir != 0) {
    const fs::path p = fs::path(dir) / relative;
    if (fs::exists(p, ec)) return p.string();
  }
  const fs::path local = fs::path("assets") / relative;
  if (fs::exists(local, ec)) return local.string();
  const fs::path exe = fs::read_symlink("/proc/self/exe", ec);
  if (!ec) {
    const fs::path installed =
        exe.parent_path() / ".." / "share" / "spidarcad" / "assets" / relative;
    if (fs::exists(installed, ec)) return installed.lexically_normal().string();
  }
  return local.string();
}

}  // namespace spidarcad::app
