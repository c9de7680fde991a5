// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#include "gui/file_browser.h"

#include <imgui.h>

#include <algorithm>
#include <cctype>
#include <cstdio>
#include <cstdlib>
#include <stdexcept>
#include <system_error>

namespace spidarcad::app {

namespace fs = std::filesystem;

namespace {

std::string Lower(std::string text) {
  for (char& c : text) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return text;
}

bool NameLess(const BrowserEntry& a, const BrowserEntry& b) {
  const std::string la = Lower(a.name), lb = Lower(b.name);
  return la != lb ? la < lb : a.name < b.name;
}

void SetPathBox(FileBrowserState* state, const std::string& text) {
  std::snprintf(state->path, sizeof(state->path), "%s", text.c_str());
}

}  // namespace

bool MatchesFilter(const std::string& file_name, BrowseFilter filter) {
  const std::string ext = Lower(fs::path(file_name).extension().string());
  switch (filter) {
    case BrowseFilter::kDocuments:
      return ext == ".json" || ext == ".spidarcad";
    case BrowseFilter::kMeshes:
      return ext == ".stl" || ext == ".obj" || ext == ".ply" || ext == ".vtu" || ext == ".node";
  }
  return false;
}

std::vector<BrowserEntry> ListDirectory(const fs::path& directory, BrowseFilter filter) {
  std::error_code ec;
  fs::directory_iterator it(directory, ec);
  if (ec) {
    throw std::runtime_error("cannot list " + directory.string() + ": " + ec.message());
  }
  std::vector<BrowserEntry> dirs, files;
  const fs::directory_iterator end;
  for (; it != end; it.increment(ec)) {
    if (ec) break;
    const std::string name = it->path().filename().string();
    if (name.empty() || name[0] == '.') continue;
    std::error_code type_ec;
    if (it->is_directory(type_ec)) {
      dirs.push_back({name, true});
    } else if (!type_ec && MatchesFilter(name, filter)) {
      files.push_back({name, false});
    }
  }
  std::sort(dirs.begin(), dirs.end(), NameLess);
  std::sort(files.begin(), files.end(), NameLess);
  std::vector<BrowserEntry> out;
  const fs::path normal = fs::absolute(directory, ec).lexically_normal();
  if (normal.has_relative_path()) out.push_back({"..", true});
  out.insert(out.end(), dirs.begin(), dirs.end());
  out.insert(out.end(), files.begin(), files.end());
  return out;
}

fs::path ResolveTypedPath(const std::string& typed, const fs::path& directory) {
  std::string text = typed;
  if (!text.empty() && text[0] == '~' && (text.size() == 1 || text[1] == '/')) {
    const char* home = std::getenv("HOME");
    if (home != nullptr && *home != 0) text = std::string(home) + text.substr(1);
  }
  fs::path p(text);
  if (p.is_relative()) p = directory / p;
  p = p.lexically_normal();
  // "dir/" normalises to "dir/" (an empty filename): drop the trailing separator.
  if (!p.has_filename() && p.has_relative_path()) p = p.parent_path();
  return p;
}

void OpenFileBrowser(FileBrowserState* state, BrowseFilter filter, const std::string& title,
                     const fs::path& directory) {
  state->filter = filter;
  state->title = title;
  state->open_requested = true;
  state->error.clear();
  std::error_code ec;
  fs::path dir = directory.empty() ? fs::current_path(ec) : directory;
  if (!fs::is_directory(dir, ec)) dir = dir.parent_path();
  if (dir.empty() || !fs::is_directory(dir, ec)) dir = fs::current_path(ec);
  state->directory.clear();
  BrowseTo(state, fs::absolute(dir, ec).lexically_normal());
}

void BrowseTo(FileBrowserState* state, const fs::path& directory) {
  try {
    state->entries = ListDirectory(directory, state->filter);
  } catch (const std::exception& e) {
    state->error = e.what();
    return;
  }
  fs::path dir = directory.lexically_normal();
  if (!dir.has_filename() && dir.has_relative_path()) dir = dir.parent_path();
  state->directory = dir;
  state->error.clear();
  state->selected = -1;
  std::string text = dir.string();
  if (text.empty() || text.back() != '/') text += '/';
  SetPathBox(state, text);
}

std::optional<std::string> SubmitTypedPath(FileBrowserState* state) {
  const fs::path p = ResolveTypedPath(state->path, state->directory);
  std::error_code ec;
  if (fs::is_directory(p, ec)) {
    BrowseTo(state, p);
    return std::nullopt;
  }
  return p.string();
}

std::optional<std::string> DrawFileBrowser(FileBrowserState* state) {
  const std::string popup = state->title + "##file_browser";
  if (state->open_requested) {
    ImGui::OpenPopup(popup.c_str());
    state->open_requested = false;
  }
  const ImGuiViewport* viewport = ImGui::GetMainViewport();
  ImGui::SetNextWindowSize(ImVec2(std::min(640.0f, viewport->Size.x - 40.0f),
                                  std::min(460.0f, viewport->Size.y - 60.0f)),
                           ImGuiCond_Appearing);
  ImGui::SetNextWindowPos(
      ImVec2(viewport->Pos.x + 0.5f * viewport->Size.x, viewport->Pos.y + 0.5f * viewport->Size.y),
      ImGuiCond_Appearing, ImVec2(0.5f, 0.5f));
  if (!ImGui::BeginPopupModal(popup.c_str(), nullptr)) return std::nullopt;
  std::optional<std::string> chosen;
  ImGui::TextDisabled("%s", state->filter == BrowseFilter::kDocuments
                                ? "Documents and scenes (.json), recovery files (.spidarcad)"
                                : "Meshes: .stl .obj .ply (surface), .vtu .node (tetrahedra)");
  const float button = ImGui::CalcTextSize(state->title.c_str()).x + 2.0f * 8.0f;
  ImGui::SetNextItemWidth(-button - ImGui::GetStyle().ItemSpacing.x);
  if (ImGui::IsWindowAppearing()) ImGui::SetKeyboardFocusHere();
  const bool enter = ImGui::InputText("##path", state->path, sizeof(state->path),
                                      ImGuiInputTextFlags_EnterReturnsTrue);
  ImGui::SameLine();
  if (ImGui::Button(state->title.c_str()) || enter) chosen = SubmitTypedPath(state);
  const float footer = ImGui::GetFrameHeightWithSpacing() * (state->error.empty() ? 1.0f : 2.2f);
  ImGui::BeginChild("listing", ImVec2(0.0f, -footer), true);
  std::optional<fs::path> browse;
  for (int i = 0; i < static_cast<int>(state->entries.size()); ++i) {
    const BrowserEntry& e = state->entries[i];
    const std::string label = e.directory && e.name != ".." ? e.name + "/" : e.name;
    ImGui::PushID(i);
    if (ImGui::Selectable(label.c_str(), state->selected == i,
                          ImGuiSelectableFlags_AllowDoubleClick)) {
      state->selected = i;
      if (e.directory) {
        browse = e.name == ".." ? state->directory.parent_path() : state->directory / e.name;
      } else {
        SetPathBox(state, (state->directory / e.name).string());
        if (ImGui::IsMouseDoubleClicked(ImGuiMouseButton_Left)) {
          chosen = (state->directory / e.name).string();
        }
      }
    }
    ImGui::PopID();
  }
  ImGui::EndChild();
  if (browse) BrowseTo(state, *browse);
  if (!state->error.empty()) {
    ImGui::PushTextWrapPos(0.0f);
    ImGui::TextColored(ImVec4(0.80f, 0.10f, 0.10f, 1.0f), "%s", state->error.c_str());
    ImGui::PopTextWrapPos();
  }
  if (ImGui::Button("Cancel") || ImGui::IsKeyPressed(ImGui::GetKeyIndex(ImGuiKey_Escape))) {
    ImGui::CloseCurrentPopup();
    chosen.reset();
  }
  if (chosen) ImGui::CloseCurrentPopup();
  ImGui::EndPopup();
  return chosen;
}

}  // namespace spidarcad::app
