// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#include "gui/workbench_panels.h"

#include <imgui.h>

#include <algorithm>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <stdexcept>
#include <string>
#include <variant>

#include "doc/command.h"
#include "gui/panels.h"
#include "gui/scene_view.h"
#include "scene/fe_setup.h"

namespace spidarcad::app {

namespace {

constexpr ImGuiWindowFlags kDockedFlags = ImGuiWindowFlags_NoMove | ImGuiWindowFlags_NoResize |
                                          ImGuiWindowFlags_NoCollapse |
                                          ImGuiWindowFlags_NoSavedSettings;
const ImVec4 kRed(0.80f, 0.10f, 0.10f, 1.0f);
const ImVec4 kGreen(0.10f, 0.50f, 0.20f, 1.0f);

const SceneObject* Selected(const SceneModel& model, const WorkbenchState& state) {
  const auto& objects = model.objects();
  if (state.selected < 0 || state.selected >= static_cast<int>(objects.size())) return nullptr;
  return &objects[state.selected];
}

// The selected Document object when it is a mesh object (its name in *name), else null.
const MeshData* SelectedMesh(const SceneModel& model, const WorkbenchState& state,
                             std::string* name = nullptr) {
  const DocObject* o = model.document().Find(state.selected_object);
  const auto* m = o != nullptr ? std::get_if<MeshData>(&o->data) : nullptr;
  if (m != nullptr && name != nullptr) *name = o->name;
  return m;
}

void OpenExport(WorkbenchState* state, const SceneModel& model, bool tets) {
  state->open_export = true;
  state->export_tets = tets;
  state->export_message.clear();
  const SceneObject* o = Selected(model, *state);
  std::string name = o != nullptr ? o->name : "mesh";
  SelectedMesh(model, *state, &name);
  const std::string path = name + (tets ? ".vtu" : ".stl");
  std::snprintf(state->export_path, sizeof(state->export_path), "%s", path.c_str());
}

}  // namespace

void StartMeshAction(SceneModel* model, JobQueue* jobs, WorkbenchState* state, MeshKind kind) {
  const SceneObject* o = Selected(*model, *state);
  if (o == nullptr) {
    state->status = "Mesh: the scene has no object to mesh";
    state->status_error = true;
    return;
  }
  MeshSettings settings;
  settings.cell_size = state->resolution_mm * 1e-3;
  settings.sharp_edges = state->sharp_edges && !(kind == MeshKind::kTetrahedra && state->cgal);
  if (kind == MeshKind::kTetrahedra) settings.mesher = state->cgal ? "cgal" : "tetgen";
  if (state->lattice && settings.mesher != "cgal") settings.surface_mesher = "lattice";
  // The estimate needs the solid's box, whose search takes seconds for a long tape (a union of
  // 100,000 spheres: about 6 s): it runs in a Job, and the question, or the mesh Job, comes
  // when it lands (unless the document was replaced meanwhile). Bad input is refused at once.
  FeMeshInput input;
  try {
    if (!(settings.cell_size > 0.0)) throw std::invalid_argument("mesh resolution must be > 0");
    if (o->solid == nullptr) {
      throw std::invalid_argument("solid '" + o->name + "' does not compile: " + o->error);
    }
    MeshSettings estimated = settings;
    if (kind != MeshKind::kTetrahedra) estimated.mesher.clear();  // the grid surface
    input = PrepareSolidMesh(model->document(), o->id, estimated, kind == MeshKind::kTetrahedra);
  } catch (const std::exception& e) {
    state->status = std::string("Mesh: ") + e.what();
    state->status_error = true;
    return;
  }
  const std::string name = o->name;
  const int index = state->selected;
  const int generation = model->generation();
  jobs->Start("Estimate the mesh of " + name, [=](JobContext& ctx) -> Job::Finisher {
    ctx.SetPhase("box");
    std::string question = LargeMeshQuestion(name, input, ctx.cancel_flag());
    return [=, question = std::move(question)] {
      if (model->generation() != generation) return;  // another document
      if (!question.empty()) {
        state->pending_mesh_text = question;
        state->pending_mesh_kind = kind;
        state->pending_mesh_index = index;
        state->pending_mesh_settings = settings;
        state->status = "Mesh: waiting for an answer (the mesh is large)";
        state->status_error = false;
        return;
      }
      model->StartMeshJob(jobs, index, kind, settings);  // throws: the job failed, said so
    };
  });
  state->status = "Mesh: estimating the mesh of '" + name + "'";
  state->status_error = false;
}

void AnswerMeshQuestion(SceneModel* model, JobQueue* jobs, WorkbenchState* state, bool proceed) {
  if (state->pending_mesh_text.empty()) return;
  state->pending_mesh_text.clear();
  if (!proceed) {
    state->status = "Mesh: cancelled, nothing changed";
    state->status_error = false;
    return;
  }
  try {
    model->StartMeshJob(jobs, state->pending_mesh_index, state->pending_mesh_kind,
                        state->pending_mesh_settings);
    state->status.clear();
  } catch (const std::exception& e) {
    state->status = std::string("Mesh: ") + e.what();
    state->status_error = true;
  }
}

bool StartRefreshAction(SceneModel* model, JobQueue* jobs, WorkbenchState* state, ObjectId id) {
  const Document& doc = model->document();
  ObjectId mesh = id;
  if (const DocObject* o = doc.Find(id)) {
    if (const auto* fe = std::get_if<FeModelData>(&o->data)) mesh = fe->tet_mesh;
  }
  try {
    model->StartRefreshJob(jobs, mesh);
    state->status.clear();
    return true;
  } catch (const std::exception& e) {
    state->status = std::string("Refresh: ") + e.what();
    state->status_error = true;
    return false;
  }
}

float DrawMenuBar(SceneModel* model, JobQueue* jobs, WorkbenchState* state,
                  WorkbenchActions* actions, TreeController* tree, TreePanelState* tree_state,
                  const std::vector<RecentEntry>* recent) {
  float height = 0.0f;
  if (!ImGui::BeginMainMenuBar()) return height;
  height = ImGui::GetWindowSize().y;
  if (ImGui::BeginMenu("File")) {
    if (ImGui::MenuItem("New", "Ctrl+N")) actions->file_new = true;
    if (ImGui::MenuItem("Open...", "Ctrl+O")) actions->file_open = true;
    if (ImGui::BeginMenu("Open Recent", recent != nullptr)) {
      if (recent->empty()) ImGui::MenuItem("(no recent documents)", nullptr, false, false);
      for (size_t i = 0; i < recent->size(); ++i) {
        const RecentEntry& e = (*recent)[i];
        ImGui::PushID(static_cast<int>(i));
        const std::string label =
            std::filesystem::path(e.path).filename().string() + (e.exists ? "" : "  (missing)");
        if (ImGui::MenuItem(label.c_str(), nullptr, false, e.exists)) actions->open_recent = e.path;
        if (ImGui::IsItemHovered(ImGuiHoveredFlags_AllowWhenDisabled)) {
          ImGui::SetTooltip("%s", e.path.c_str());
        }
        ImGui::PopID();
      }
      ImGui::Separator();
      if (ImGui::MenuItem("Clear the list", nullptr, false, !recent->empty())) {
        actions->clear_recent = true;
      }
      ImGui::EndMenu();
    }
    ImGui::Separator();
    if (tree != nullptr && tree_state != nullptr) {
      DrawSaveMenuItems(tree, tree_state);
      ImGui::Separator();
    }
    if (ImGui::MenuItem("Import mesh (STL/OBJ/PLY/VTU/.node)...", "Ctrl+I")) {
      actions->file_import = true;
    }
    const SceneObject* o = Selected(*model, *state);
    const MeshData* m = SelectedMesh(*model, *state);
    if (ImGui::MenuItem("Export surface (STL/OBJ/PLY)...", nullptr, false,
                        o != nullptr || m != nullptr)) {
      OpenExport(state, *model, false);
    }
    if (ImGui::MenuItem("Export tetrahedra (VTU, .node/.ele)...", nullptr, false,
                        m != nullptr && m->volume != nullptr)) {
      OpenExport(state, *model, true);
    }
    ImGui::Separator();
    if (ImGui::MenuItem("Quit", "Esc")) actions->quit = true;
    ImGui::EndMenu();
  }
  if (tree != nullptr && ImGui::BeginMenu("Edit")) {
    DrawEditMenuItems(tree);
    ImGui::EndMenu();
  }
  if (ImGui::BeginMenu("Mesh")) {
    if (ImGui::MenuItem("Surface")) StartMeshAction(model, jobs, state, MeshKind::kSurface);
    if (ImGui::MenuItem("Tetrahedra (TetGen)")) {
      StartMeshAction(model, jobs, state, MeshKind::kTetrahedra);
    }
    ImGui::Separator();
    if (ImGui::MenuItem("Cancel all jobs", nullptr, false, jobs->busy())) jobs->CancelAll();
    ImGui::EndMenu();
  }
  if (ImGui::BeginMenu("Haptics")) {
    if (ImGui::MenuItem("Emergency stop", "Space")) actions->emergency_stop = true;
    if (ImGui::MenuItem("Re-arm (force ramp)")) actions->rearm = true;
    if (ImGui::MenuItem("Calibrate device...")) actions->calibrate = true;
    ImGui::Separator();
    DrawContactControls(state);
    if (tree != nullptr) {
      ImGui::Separator();
      const bool snapping = tree->document().snap().has_value();
      if (ImGui::MenuItem("Snap forces", nullptr, snapping)) {
        try {
          ToggleSnapForces(&tree->document(), state);
        } catch (const std::exception& e) {
          state->status = std::string("Snap forces: ") + e.what();
          state->status_error = true;
        }
      }
      if (ImGui::IsItemHovered()) {
        ImGui::SetTooltip(
            "Pull the grip toward the solids' vertices, edges and faces as it comes near them\n"
            "(saved with the document; one undo step). Model mode names the snapped feature.");
      }
    }
    ImGui::EndMenu();
  }
  if (ImGui::BeginMenu("View")) {
    if (ImGui::MenuItem("Fit to the selection", "F")) actions->fit_view = true;
    if (ImGui::MenuItem("Front", "1")) actions->standard_view = 0;
    if (ImGui::MenuItem("Right", "3")) actions->standard_view = 1;
    if (ImGui::MenuItem("Top", "7")) actions->standard_view = 2;
    if (ImGui::MenuItem("Iso", "0")) actions->standard_view = 3;
    ImGui::Separator();
    if (ImGui::MenuItem("Reset camera", "C")) actions->reset_camera = true;
    if (ImGui::MenuItem("Reset grip", "R")) actions->reset_grip = true;
    ImGui::MenuItem("Show mesh edges of the selected object", nullptr, &state->show_edges);
    ImGui::MenuItem("Device and loop figures", nullptr, &state->show_figures);
    ImGui::EndMenu();
  }
  if (ImGui::BeginMenu("Help")) {
    DrawControlsHelp();
    ImGui::EndMenu();
  }
  ImGui::EndMainMenuBar();
  return height;
}

void DrawScenePanel(SceneModel* model, JobQueue* jobs, WorkbenchState* state, float x, float y,
                    float width, float height, TreeController* tree, TreePanelState* tree_state) {
  ImGui::SetNextWindowPos(ImVec2(x, y));
  ImGui::SetNextWindowSize(ImVec2(width, height));
  ImGui::Begin("Document", nullptr, kDockedFlags);
  ImGui::PushTextWrapPos(width - 10.0f);
  ImGui::TextDisabled("%s", model->source().c_str());
  if (!model->description().empty()) {
    // One line (the tree needs the room); the whole text as a tooltip.
    const std::string& d = model->description();
    const size_t cut = std::min<size_t>(d.find_first_of(".:\n"), 52);
    ImGui::TextDisabled("%s%s", d.substr(0, cut).c_str(), cut < d.size() ? " ..." : "");
    if (ImGui::IsItemHovered()) ImGui::SetTooltip("%s", d.c_str());
  }
  ImGui::PopTextWrapPos();
  const DeviceToWorld& x_wd = model->device_to_world();
  ImGui::TextDisabled("X_WD: scale %.2f, device centre at (%.0f, %.0f, %.0f) mm", x_wd.world_scale,
                      x_wd.p_WDo.x() * 1e3, x_wd.p_WDo.y() * 1e3, x_wd.p_WDo.z() * 1e3);
  if (tree != nullptr && tree_state != nullptr) {
    // The tree takes about 40 % of the panel; the properties below it scroll with the panel.
    const float line = ImGui::GetFrameHeightWithSpacing();
    const float tree_height = std::clamp(0.4f * height, 4.0f * line, 16.0f * line);
    // A mesh the Mesh action just landed becomes the selection; a Refresh asked for in the tree
    // starts its job.
    if (const ObjectId landed = model->TakeLandedMesh(); landed != 0) tree->Select(landed);
    DrawTreePanel(tree, tree_state, tree_height);
    if (const ObjectId refresh = tree->TakeRefreshRequest(); refresh != 0) {
      StartRefreshAction(model, jobs, state, refresh);
    }
    state->selected_object = tree->selection() ? tree->selection()->object : 0;
    if (tree->selection()) {
      // A solid, or the solid a selected mesh was made from, is what the Mesh action meshes.
      ObjectId solid = tree->selection()->object;
      const DocObject* o = model->document().Find(solid);
      if (const auto* m = o != nullptr ? std::get_if<MeshData>(&o->data) : nullptr) {
        solid = m->source;
      }
      const int index = model->IndexOf(solid);
      if (index >= 0) state->selected = index;
    }
    const SceneObject* o = Selected(*model, *state);
    if (o != nullptr) {
      const long tris = o->preview.triangles.cols();
      ImGui::TextDisabled("preview of '%s': %ld tri%s", o->name.c_str(), tris,
                          tris > 0 ? "" : " (meshing...)");
    }
  }
  if (model->document().objects().empty()) {
    // An empty document (an assembly's rigid parts are objects too, though not Model mode's
    // solids): how to start, and the controls (also in the Help menu).
    ImGui::Separator();
    ImGui::PushTextWrapPos(width - 10.0f);
    ImGui::TextUnformatted(
        "No solids in this scene: add one with Add..., or open a scene file "
        "(spidarcad SCENE.json).");
    ImGui::PopTextWrapPos();
    ImGui::Separator();
    DrawControlsHelp();
  }
  DrawJobs(jobs, state, width);
  // The Mesh action's over-budget question.
  if (!state->pending_mesh_text.empty() && !ImGui::IsPopupOpen("Large mesh")) {
    ImGui::OpenPopup("Large mesh");
  }
  if (ImGui::BeginPopupModal("Large mesh", nullptr, ImGuiWindowFlags_AlwaysAutoResize)) {
    ImGui::PushTextWrapPos(ImGui::GetFontSize() * 30.0f);
    ImGui::TextUnformatted(state->pending_mesh_text.c_str());
    ImGui::PopTextWrapPos();
    if (ImGui::Button("Proceed")) {
      AnswerMeshQuestion(model, jobs, state, true);
      ImGui::CloseCurrentPopup();
    }
    ImGui::SameLine();
    if (ImGui::Button("Cancel") || state->pending_mesh_text.empty()) {
      AnswerMeshQuestion(model, jobs, state, false);
      ImGui::CloseCurrentPopup();
    }
    ImGui::EndPopup();
  }
  ImGui::End();
}

void DrawMeshControls(SceneModel* model, JobQueue* jobs, WorkbenchState* state) {
  const SceneObject* o = Selected(*model, *state);
  if (o != nullptr) {
    ImGui::TextDisabled("solid '%s' -> a mesh object in the tree", o->name.c_str());
  }
  ImGui::PushItemWidth(90.0f);
  ImGui::InputFloat("cell [mm]", &state->resolution_mm, 0.5f, 2.0f, "%.1f");
  state->resolution_mm = std::clamp(state->resolution_mm, 0.5f, 50.0f);
  ImGui::PopItemWidth();
  if (!state->cgal) {
    ImGui::Checkbox("sharp edges", &state->sharp_edges);
    ImGui::SameLine();
    ImGui::Checkbox("lattice", &state->lattice);
    if (ImGui::IsItemHovered())
      ImGui::SetTooltip(
          "Surface by the lattice route (spidarcad mesh's default): faster, no angle under "
          "about 15 deg on smooth surfaces; else marching tetrahedra and its clean-up");
  }
  ImGui::TextUnformatted("tets:");
  ImGui::SameLine();
  if (ImGui::RadioButton("TetGen", !state->cgal)) state->cgal = false;
  ImGui::SameLine();
  if (ImGui::RadioButton("CGAL", state->cgal)) state->cgal = true;
  if (ImGui::Button("Surface")) StartMeshAction(model, jobs, state, MeshKind::kSurface);
  ImGui::SameLine();
  if (ImGui::Button("Tetrahedra")) StartMeshAction(model, jobs, state, MeshKind::kTetrahedra);
}

void DrawJobs(JobQueue* jobs, WorkbenchState* state, float width) {
  int row = 0;
  for (const auto& job : jobs->jobs()) {
    if (job->state() != Job::State::kRunning) continue;
    ImGui::PushID(row++);
    char overlay[160];
    std::snprintf(overlay, sizeof(overlay), "%s: %s %.0f%%", job->title().c_str(),
                  job->phase().c_str(), 100.0 * job->progress());
    ImGui::ProgressBar(static_cast<float>(job->progress()), ImVec2(width - 90.0f, 0.0f), overlay);
    ImGui::SameLine();
    if (job->cancel_requested()) {
      ImGui::TextDisabled("cancelling");
    } else if (ImGui::Button("Cancel")) {
      job->Cancel();
    }
    ImGui::PopID();
  }
  if (!state->status.empty()) {
    ImGui::PushTextWrapPos(width - 10.0f);
    ImGui::TextColored(state->status_error ? kRed : kGreen, "%s", state->status.c_str());
    ImGui::PopTextWrapPos();
  }
}

bool ToggleSnapForces(Document* doc, WorkbenchState* state) {
  if (doc->snap()) {
    const modeling::SceneSnap was = *doc->snap();
    doc->Execute(edit::SetSnap(std::nullopt));
    state->snap_settings = was;
    return false;
  }
  doc->Execute(edit::SetSnap(state->snap_settings));
  return true;
}

void DrawContactControls(WorkbenchState* state) {
  SceneHapticsOptions& c = state->contact;
  ImGui::TextDisabled("Touch: how the grip feels the solids");
  if (ImGui::MenuItem("Point (proxy)", nullptr, c.tool == ToolModel::kProxy) &&
      c.tool != ToolModel::kProxy) {
    c.tool = ToolModel::kProxy;
    state->contact_changed = true;
  }
  if (ImGui::IsItemHovered()) {
    ImGui::SetTooltip("A god-object proxy per solid on the grip centre, with friction.");
  }
  if (ImGui::MenuItem("Grip (six-DOF)", nullptr, c.tool == ToolModel::kShell) &&
      c.tool != ToolModel::kShell) {
    c.tool = ToolModel::kShell;
    state->contact_changed = true;
  }
  if (ImGui::IsItemHovered()) {
    ImGui::SetTooltip(
        "The cross grip as a rigid six-DOF tool (point shell with virtual coupling):\n"
        "its poles touch, torques are felt.");
  }
  ImGui::PushItemWidth(150.0f);
  float k = static_cast<float>(c.stiffness);
  if (ImGui::SliderFloat("stiffness [N/m]", &k, 200.0f, 3000.0f, "%.0f")) {
    c.stiffness = std::clamp(static_cast<double>(k), 200.0, 3000.0);
    c.coupling_stiffness = std::min(c.stiffness, 1000.0);
    state->contact_changed = true;
  }
  if (c.tool == ToolModel::kProxy) {
    float b = static_cast<float>(c.damping);
    if (ImGui::SliderFloat("damping [N·s/m]", &b, 0.0f, 5.0f, "%.1f")) {
      c.damping = std::clamp(static_cast<double>(b), 0.0, 5.0);
      state->contact_changed = true;
    }
    float mu[2] = {static_cast<float>(c.static_friction), static_cast<float>(c.dynamic_friction)};
    if (ImGui::SliderFloat2("friction μs, μd", mu, 0.0f, 1.0f, "%.2f")) {
      c.static_friction = std::clamp(static_cast<double>(mu[0]), 0.0, 1.0);
      c.dynamic_friction = std::clamp(static_cast<double>(mu[1]), 0.0, c.static_friction);
      state->contact_changed = true;
    }
  } else {
    float b = static_cast<float>(c.coupling_damping);
    if (ImGui::SliderFloat("coupling damping [N·s/m]", &b, 0.0f, 10.0f, "%.1f")) {
      c.coupling_damping = std::clamp(static_cast<double>(b), 0.0, 10.0);
      state->contact_changed = true;
    }
  }
  ImGui::PopItemWidth();
}

void DrawLoopFigures(const LoopStats& s, WorkbenchActions* actions) {
  // The stop first: always in sight, whatever the strip's height.
  if (s.emergency_stop) {
    if (ImGui::Button("Re-arm forces")) actions->rearm = true;
    ImGui::SameLine();
    ImGui::TextColored(kRed, "stopped: zero force");
  } else {
    ImGui::PushStyleColor(ImGuiCol_Button, ImVec4(0.85f, 0.15f, 0.12f, 1.0f));
    ImGui::PushStyleColor(ImGuiCol_ButtonHovered, ImVec4(0.95f, 0.25f, 0.2f, 1.0f));
    ImGui::PushStyleColor(ImGuiCol_Text, ImVec4(1, 1, 1, 1));
    if (ImGui::Button("EMERGENCY STOP (Space)")) actions->emergency_stop = true;
    ImGui::PopStyleColor(3);
  }
  const bool fifo = s.realtime == haptics::RealtimeStatus::kFifo;
  ImGui::Text("1 kHz loop, %llu ticks", static_cast<unsigned long long>(s.ticks));
  ImGui::SameLine();
  ImGui::TextColored(fifo ? kGreen : ImVec4(0.75f, 0.35f, 0.0f, 1.0f), "%s",
                     fifo ? "SCHED_FIFO" : haptics::RealtimeStatusName(s.realtime));
  if (!fifo) {
    ImGui::SameLine();
    ImGui::TextDisabled("(normal scheduling)");
  }
  if (ImGui::BeginTable("loopstats", 5, ImGuiTableFlags_RowBg | ImGuiTableFlags_SizingFixedFit)) {
    ImGui::TableSetupColumn("µs", ImGuiTableColumnFlags_WidthFixed, 104.0f);
    ImGui::TableSetupColumn("p50", ImGuiTableColumnFlags_WidthFixed, 42.0f);
    ImGui::TableSetupColumn("p99", ImGuiTableColumnFlags_WidthFixed, 42.0f);
    ImGui::TableSetupColumn("p99.9", ImGuiTableColumnFlags_WidthFixed, 46.0f);
    ImGui::TableSetupColumn("max", ImGuiTableColumnFlags_WidthFixed, 48.0f);
    ImGui::TableHeadersRow();
    auto row = [](const char* name, const std::array<double, 4>& v) {
      ImGui::TableNextRow();
      ImGui::TableSetColumnIndex(0);
      ImGui::TextUnformatted(name);
      for (int k = 0; k < 4; ++k) {
        ImGui::TableSetColumnIndex(k + 1);
        ImGui::Text("%.1f", v[k] * 1e6);
      }
    };
    row("loop step", s.step);
    row("tick + simulation", s.tick);
    row("period jitter", s.jitter);
    ImGui::EndTable();
  }
  ImGui::TextDisabled("overruns %llu   force ramp %.2f",
                      static_cast<unsigned long long>(s.overruns), s.ramp);
  // Safety events in two columns, non-zero counts highlighted.
  if (ImGui::BeginTable("events", 4, ImGuiTableFlags_SizingFixedFit)) {
    for (int i = 0; i < haptics::kNumSafetyEvents; ++i) {
      if (i % 2 == 0) ImGui::TableNextRow();
      ImGui::TableSetColumnIndex((i % 2) * 2);
      ImGui::TextDisabled("%s", haptics::SafetyEventName(i));
      ImGui::TableSetColumnIndex((i % 2) * 2 + 1);
      if (s.events[i] > 0) {
        ImGui::Text("%8llu", static_cast<unsigned long long>(s.events[i]));
      } else {
        ImGui::TextDisabled("%8d", 0);
      }
    }
    ImGui::EndTable();
  }
}

void DrawStopBanner(float x0, float x1, float y) {
  const char* text = "EMERGENCY STOP: zero force. Re-arm in the loop panel.";
  ImDrawList* draw = ImGui::GetForegroundDrawList();
  const ImVec2 size = ImGui::CalcTextSize(text);
  const float cx = 0.5f * (x0 + x1);
  const ImVec2 a(cx - 0.5f * size.x - 16.0f, y), b(cx + 0.5f * size.x + 16.0f, y + size.y + 14.0f);
  draw->AddRectFilled(a, b, IM_COL32(205, 25, 25, 255), 4.0f);
  draw->AddText(ImVec2(a.x + 16.0f, a.y + 7.0f), IM_COL32(255, 255, 255, 255), text);
}

void DrawExportDialog(const SceneModel& model, WorkbenchState* state) {
  if (state->open_export) {
    ImGui::OpenPopup("Export");
    state->open_export = false;
  }
  ImGui::SetNextWindowSize(ImVec2(520.0f, 0.0f));
  if (!ImGui::BeginPopupModal("Export", nullptr, ImGuiWindowFlags_AlwaysAutoResize)) return;
  const SceneObject* o = Selected(model, *state);
  std::string mesh_name;
  const MeshData* m = SelectedMesh(model, *state, &mesh_name);
  if (o == nullptr && m == nullptr) {
    ImGui::TextUnformatted("No object selected.");
  } else if (state->export_tets) {
    const long nodes = m != nullptr && m->volume ? static_cast<long>(m->volume->nodes.cols()) : 0;
    const long tets = m != nullptr && m->volume ? static_cast<long>(m->volume->tets.cols()) : 0;
    ImGui::Text("Tetrahedra of '%s' (%ld nodes, %ld tets)", mesh_name.c_str(), nodes, tets);
    ImGui::TextDisabled("path ending in .vtu (ParaView) or .node/.ele (TetGen files)");
  } else if (m != nullptr) {
    ImGui::Text("Surface of mesh object '%s' (%s)", mesh_name.c_str(),
                m->surface ? (std::to_string(m->surface->triangles.cols()) + " triangles").c_str()
                           : "the boundary of its tetrahedra");
    ImGui::TextDisabled("path ending in .stl, .obj or .ply; coordinates in metres (W)");
  } else {
    ImGui::Text("Surface of '%s' (preview, %ld triangles)", o->name.c_str(),
                static_cast<long>(o->preview.triangles.cols()));
    ImGui::TextDisabled("the preview; mesh the solid for a mesh object to export");
  }
  ImGui::SetNextItemWidth(500.0f);
  ImGui::InputText("##path", state->export_path, sizeof(state->export_path));
  if (ImGui::Button("Export") && (o != nullptr || m != nullptr)) {
    const std::string path = state->export_path;
    std::string error;
    if (state->export_tets) {
      error = m != nullptr && m->volume ? ExportTetrahedra(*m->volume, path)
                                        : ExportTetrahedra(modeling::TetMesh{}, path);
    } else {
      error =
          m != nullptr ? ExportSurface(DrawnSurface(*m), path) : ExportSurface(o->preview, path);
    }
    state->export_failed = !error.empty();
    state->export_message = error.empty() ? "wrote " + path : error;
  }
  ImGui::SameLine();
  if (ImGui::Button("Close")) ImGui::CloseCurrentPopup();
  if (!state->export_message.empty()) {
    ImGui::PushTextWrapPos(500.0f);
    ImGui::TextColored(state->export_failed ? kRed : kGreen, "%s", state->export_message.c_str());
    ImGui::PopTextWrapPos();
  }
  ImGui::EndPopup();
}

}  // namespace spidarcad::app
