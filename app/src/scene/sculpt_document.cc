// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#include "scene/sculpt_document.h"

#include <algorithm>
#include <cstdint>
#include <numbers>
#include <stdexcept>
#include <utility>
#include <variant>
#include <vector>

#include "scene/fe_setup.h"

namespace spidarcad::app {

std::shared_ptr<const modeling::TriangleMesh> SculptableSurface(const DocObject& object) {
  const auto* mesh = std::get_if<MeshData>(&object.data);
  if (mesh == nullptr || !mesh->surface || !IsClosedSurface(*mesh->surface)) return nullptr;
  return mesh->surface;
}

bool CanSculptCopyOf(const DocObject& object) {
  if (std::holds_alternative<SolidData>(object.data)) return true;
  return SculptableSurface(object) != nullptr;
}

std::string SculptStrokeTitle(modeling::SculptTool tool, const std::string& object_name) {
  std::string tool_name = modeling::SculptToolName(tool);
  std::replace(tool_name.begin(), tool_name.end(), '_', '/');  // "push_pull" -> "push/pull"
  return "Sculpt stroke (" + tool_name + ") on " + object_name;
}

std::unique_ptr<Command> MakeStrokeCommand(ObjectId id, const std::string& name,
                                           modeling::SculptTool tool,
                                           const modeling::SculptEdit& edit,
                                           const modeling::SculptMesh& mesh) {
  const std::string title = SculptStrokeTitle(tool, name);
  const bool topology_changed =
      !edit.added_positions.empty() || !edit.rewritten.empty() || !edit.added_triangles.empty();
  if (topology_changed) return edit::ReplaceSculptMesh(id, mesh.ToTriangleMesh(), title);
  std::vector<int> vertices;
  std::vector<Eigen::Vector3d> positions;
  const std::size_t n = std::min(edit.moved.size(), edit.new_positions.size());
  for (std::size_t k = 0; k < n; ++k) {
    const bool changed =
        k >= edit.old_positions.size() || edit.old_positions[k] != edit.new_positions[k];
    if (!changed) continue;
    vertices.push_back(edit.moved[k]);
    positions.push_back(edit.new_positions[k]);
  }
  if (vertices.empty()) return nullptr;
  Eigen::Matrix3Xd matrix(3, static_cast<Eigen::Index>(positions.size()));
  for (std::size_t k = 0; k < positions.size(); ++k)
    matrix.col(static_cast<Eigen::Index>(k)) = positions[k];
  return edit::SculptStroke(id, std::move(vertices), std::move(matrix), title);
}

DocumentSculpt::DocumentSculpt(Document* doc, ObjectId id, const SculptModeSettings& settings)
    : doc_(doc), id_(id) {
  const DocObject* object = doc_ != nullptr ? doc_->Find(id) : nullptr;
  const auto* data = object != nullptr ? std::get_if<SculptData>(&object->data) : nullptr;
  if (data == nullptr || !data->mesh) {
    throw std::invalid_argument("object " + std::to_string(id) + " is not a sculpt object");
  }
  name_ = object->name;
  settings.Validate();
  session_.settings() = settings;
  try {
    session_.SetMesh(*data->mesh);
  } catch (const std::invalid_argument& e) {
    throw std::invalid_argument("sculpt object '" + name_ + "' cannot be sculpted: " + e.what());
  }
  start_volume_ = session_.mesh()->volume();
  start_grid_seconds_ = session_.last_grid_seconds();
}

SculptFrameEvent DocumentSculpt::Step(const haptics::ToolKinematics& tool) {
  const SculptFrameEvent event = session_.Step(tool, false);
  if (event == SculptFrameEvent::kEnded) Record();
  return event;
}

void DocumentSculpt::Finish(const haptics::ToolKinematics& tool) {
  if (!session_.stroke_active()) return;
  haptics::ToolKinematics open = tool;
  // Open: at rest (pi/2) or at the end angle, whichever is larger.
  open.grasp = std::max(std::numbers::pi / 2, session_.settings().stroke_end_angle);
  Step(open);
}

void DocumentSculpt::Record() {
  ++strokes_;
  const modeling::SculptEdit* edit = session_.last_edit();
  if (edit == nullptr || !session_.mesh()) return;
  std::unique_ptr<Command> command =
      MakeStrokeCommand(id_, name_, session_.settings().tool.tool, *edit, *session_.mesh());
  session_.ForgetHistory();  // the Document holds the strokes
  if (command != nullptr) doc_->Execute(std::move(command));
}

}  // namespace spidarcad::app
