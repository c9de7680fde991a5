// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#include "scene/assembly_scene.h"

#include <algorithm>
#include <cmath>
#include <map>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

#include "scene/solid_distance_field.h"
#include "spidarcad/modeling/surface_mesher.h"

namespace spidarcad::app {

haptics::PointShell SampleSurfaceShell(const modeling::CompiledSolid& solid, double spacing,
                                       double search_half_extent) {
  if (!(spacing > 0) || !std::isfinite(spacing)) {
    throw std::invalid_argument("SampleSurfaceShell: spacing = " + std::to_string(spacing) +
                                " must be > 0");
  }
  const Eigen::Vector3d h = Eigen::Vector3d::Constant(search_half_extent);
  const Eigen::AlignedBox3d bounds =
      modeling::FindBounds(solid, Eigen::AlignedBox3d(-h, h), spacing);
  if (bounds.isEmpty()) throw std::invalid_argument("SampleSurfaceShell: the solid is empty");
  modeling::SurfaceMeshSettings mesh_settings;
  mesh_settings.bounds = Eigen::AlignedBox3d(bounds.min() - Eigen::Vector3d::Constant(spacing),
                                             bounds.max() + Eigen::Vector3d::Constant(spacing));
  mesh_settings.cell_size = spacing;
  const modeling::TriangleMesh mesh = modeling::MeshSurface(solid, mesh_settings);
  std::vector<Eigen::Vector3d> points, normals;
  points.reserve(mesh.vertices.cols());
  normals.reserve(mesh.vertices.cols());
  for (Eigen::Index i = 0; i < mesh.vertices.cols(); ++i) {
    const Eigen::Vector3d p = mesh.vertices.col(i);
    Eigen::Vector3d g;
    solid.ValueAndGradient(p, &g);
    const double n = g.norm();
    if (!(n > 1e-9) || !std::isfinite(n)) continue;  // a point on a crease with no gradient
    points.push_back(p);
    normals.push_back(-g / n);
  }
  if (points.empty()) throw std::invalid_argument("SampleSurfaceShell: no surface points");
  return haptics::PointShell::FromPoints(points, normals);
}

Eigen::Isometry3d PartPose(const Eigen::Vector3d& position, const Eigen::Quaterniond& rotation) {
  Eigen::Isometry3d X = Eigen::Isometry3d::Identity();
  X.linear() = rotation.normalized().toRotationMatrix();
  X.translation() = position;
  return X;
}

std::unique_ptr<haptics::AssemblyField> BuildAssemblyField(const modeling::Scene& scene,
                                                           const AssemblySceneSettings& settings) {
  const int n = static_cast<int>(scene.parts.size());
  if (n == 0) throw std::invalid_argument("BuildAssemblyField: the scene has no parts");
  if (n > haptics::kMaxAssemblyParts) {
    throw std::invalid_argument("BuildAssemblyField: " + std::to_string(n) + " parts, at most " +
                                std::to_string(haptics::kMaxAssemblyParts));
  }
  std::map<std::string, int> index;
  for (int i = 0; i < n; ++i) index[scene.parts[i].name] = i;
  // One compiled solid, field and shell per solid name (parts may share a solid).
  struct Compiled {
    std::shared_ptr<const SolidDistanceField> field;
    haptics::PointShell shell;
    bool sampled = false;
  };
  std::map<std::string, Compiled> compiled;
  std::vector<haptics::AssemblyPart> parts;
  for (int i = 0; i < n; ++i) {
    const modeling::ScenePart& sp = scene.parts[i];
    const std::string where =
        "BuildAssemblyField: part '" + sp.name + "' (solid '" + sp.solid + "')";
    Compiled& c = compiled[sp.solid];
    if (c.field == nullptr) {
      const modeling::Solid* solid = nullptr;
      for (const modeling::Solid& s : scene.solids) {
        if (s.name == sp.solid) solid = &s;
      }
      if (solid == nullptr) throw std::invalid_argument(where + ": no such solid");
      try {
        auto cs = std::make_shared<const modeling::CompiledSolid>(
            modeling::CompiledSolid::Compile(solid->root));
        if (settings.specialization_cell > 0) {
          // Pruned tapes over the part's bounds plus a margin where other parts' shells come near.
          const Eigen::Vector3d h = Eigen::Vector3d::Constant(settings.search_half_extent);
          const Eigen::AlignedBox3d b =
              modeling::FindBounds(*cs, Eigen::AlignedBox3d(-h, h), settings.specialization_cell);
          const Eigen::Vector3d margin = Eigen::Vector3d::Constant(0.02);
          modeling::CellSpecializationSettings cell;
          cell.cell_size = settings.specialization_cell;
          c.field = std::make_shared<const SolidDistanceField>(
              cs, b.isEmpty()
                      ? nullptr
                      : std::make_shared<const modeling::CellSpecializedSolid>(
                            cs, Eigen::AlignedBox3d(b.min() - margin, b.max() + margin), cell));
        } else {
          c.field = std::make_shared<const SolidDistanceField>(cs);
        }
      } catch (const std::exception& e) {
        throw std::invalid_argument(where + ": " + e.what());
      }
    }
    if (!sp.fixed && !c.sampled) {
      try {
        c.shell = SampleSurfaceShell(c.field->solid(), settings.shell_spacing,
                                     settings.search_half_extent);
      } catch (const std::exception& e) {
        throw std::invalid_argument(where + ": " + e.what());
      }
      c.sampled = true;
    }
    haptics::AssemblyPart part;
    part.name = sp.name;
    part.field_P = c.field;
    if (!sp.fixed) part.shell_P = c.shell;
    part.X_WP = PartPose(sp.position, sp.rotation);
    part.fixed = sp.fixed;
    for (const modeling::SceneSeat& ss : sp.seats) {
      const auto it = index.find(ss.on);
      if (it == index.end())
        throw std::invalid_argument(where + ": seat on unknown part '" + ss.on + "'");
      haptics::AssemblySeat seat;
      seat.other = it->second;
      seat.X_OS = PartPose(ss.position, ss.rotation);
      seat.position_tolerance = ss.position_tolerance;
      seat.angle_tolerance = ss.angle_tolerance;
      part.seats.push_back(seat);
    }
    parts.push_back(std::move(part));
  }
  haptics::PointShell tool;
  if (settings.tool_radius > 0)
    tool = haptics::PointShell::Sphere(settings.tool_radius, settings.tool_points);
  return std::make_unique<haptics::AssemblyField>(std::move(parts), std::move(tool),
                                                  settings.field);
}

std::string FormatAssemblySummary(const std::vector<std::string>& names,
                                  const std::vector<bool>& fixed,
                                  const haptics::AssemblyState& state) {
  const int n = static_cast<int>(std::min(names.size(), fixed.size()));
  const bool published = state.count == static_cast<int>(names.size());
  int graspable = 0, seated_count = 0, carried = -1;
  std::string seated;
  for (int i = 0; i < n; ++i) {
    if (fixed[i]) continue;
    ++graspable;
    if (!published) continue;
    if (state.carried == i) {
      carried = i;  // a carried part is not seated
    } else if (i < haptics::kMaxAssemblyParts && state.seated[i]) {
      ++seated_count;
      seated += (seated.empty() ? "" : ", ") + names[i];
    }
  }
  std::ostringstream os;
  os << "assembly: " << seated_count << " of " << graspable << " parts seated";
  if (!seated.empty()) os << " (" << seated << ")";
  os << ", carried: " << (carried >= 0 ? names[carried] : std::string("none")) << "\n";
  return os.str();
}

std::string FormatAssemblySummary(const haptics::AssemblyField& field,
                                  const haptics::AssemblyState& state) {
  std::vector<std::string> names;
  std::vector<bool> fixed;
  for (int i = 0; i < field.size(); ++i) {
    names.push_back(field.part(i).name);
    fixed.push_back(field.part(i).fixed);
  }
  return FormatAssemblySummary(names, fixed, state);
}

}  // namespace spidarcad::app
