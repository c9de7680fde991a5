// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#include "scene/sculpt_document.h"

#include <algorithm>
#include <cstdint>
#include <utility>
#include <variant>
#include <vector>

namespace spidarcad::app {
namespace {

// See SculptableSurface.
bool IsClosedSurface(const modeling::TriangleMesh& mesh) {
  const Eigen::Index vertex_count = mesh.vertices.cols();
  const Eigen::Index triangle_count = mesh.triangles.cols();
  if (vertex_count < 4 || triangle_count < 4) return false;
  std::vector<std::uint64_t> edges;
  edges.reserve(3 * static_cast<std::size_t>(triangle_count));
  for (Eigen::Index t = 0; t < triangle_count; ++t) {
    for (int k = 0; k < 3; ++k) {
      const int a = mesh.triangles(k, t);
      const int b = mesh.triangles((k + 1) % 3, t);
      if (a < 0 || a >= vertex_count || b < 0 || b >= vertex_count || a == b) return false;
      edges.push_back(static_cast<std::uint64_t>(a) << 32 | static_cast<std::uint32_t>(b));
    }
  }
  std::sort(edges.begin(), edges.end());
  if (std::adjacent_find(edges.begin(), edges.end()) != edges.end()) return false;
  for (const std::uint64_t e : edges) {
    const std::uint64_t reverse = (e & 0xffffffffu) << 32 | e >> 32;
    if (!std::binary_search(edges.begin(), edges.end(), reverse)) return false;
  }
  return true;
}

}  // namespace

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

}  // namespace spidarcad::app
