// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#include "scene/assembly_scene.h"

#include <algorithm>
#include <cmath>
#include <map>
#include <sstream>
#include <stdexcept>
#include <string>
#include <variant>
#include <vector>

#include "scene/solid_distance_field.h"
#include "spidarcad/modeling/scene_io.h"
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

struct AssemblyGeometryCache::Entry {
  std::shared_ptr<const SolidDistanceField> field;
  haptics::PointShell shell;
  bool sampled = false;
};

std::unique_ptr<haptics::AssemblyField> BuildAssemblyField(
    const std::vector<AssemblyPartInput>& inputs, const AssemblySceneSettings& settings,
    AssemblyGeometryCache* cache) {
  const int n = static_cast<int>(inputs.size());
  if (n == 0) throw std::invalid_argument("BuildAssemblyField: the scene has no parts");
  if (n > haptics::kMaxAssemblyParts) {
    throw std::invalid_argument("BuildAssemblyField: " + std::to_string(n) + " parts, at most " +
                                std::to_string(haptics::kMaxAssemblyParts));
  }
  std::map<std::string, int> index;
  for (int i = 0; i < n; ++i) index.emplace(inputs[i].name, i);
  // One compiled solid, field and shell per tree (parts may share one), found in the cache when
  // an earlier build made it with the same settings.
  std::ostringstream shape;
  shape.precision(17);
  shape << "|" << settings.shell_spacing << "|" << settings.search_half_extent << "|"
        << settings.specialization_cell;
  using Entry = AssemblyGeometryCache::Entry;
  std::map<std::string, std::shared_ptr<Entry>> used;
  int compiled = 0;
  std::vector<haptics::AssemblyPart> parts;
  for (int i = 0; i < n; ++i) {
    const AssemblyPartInput& in = inputs[i];
    const std::string where =
        "BuildAssemblyField: part '" + in.name + "' (solid '" + in.solid + "')";
    if (in.root == nullptr) throw std::invalid_argument(where + ": no such solid");
    const std::string key = modeling::NodeToJson(*in.root).dump() + shape.str();
    std::shared_ptr<Entry>& c = used[key];
    if (c == nullptr && cache != nullptr) {
      const auto it = cache->entries_.find(key);
      if (it != cache->entries_.end()) c = it->second;
    }
    if (c == nullptr) {
      c = std::make_shared<Entry>();
      ++compiled;
      try {
        auto cs = std::make_shared<const modeling::CompiledSolid>(
            modeling::CompiledSolid::Compile(*in.root));
        if (settings.specialization_cell > 0) {
          // Pruned tapes over the part's bounds plus a margin where other parts' shells come near.
          const Eigen::Vector3d h = Eigen::Vector3d::Constant(settings.search_half_extent);
          const Eigen::AlignedBox3d b =
              modeling::FindBounds(*cs, Eigen::AlignedBox3d(-h, h), settings.specialization_cell);
          const Eigen::Vector3d margin = Eigen::Vector3d::Constant(0.02);
          modeling::CellSpecializationSettings cell;
          cell.cell_size = settings.specialization_cell;
          c->field = std::make_shared<const SolidDistanceField>(
              cs, b.isEmpty()
                      ? nullptr
                      : std::make_shared<const modeling::CellSpecializedSolid>(
                            cs, Eigen::AlignedBox3d(b.min() - margin, b.max() + margin), cell));
        } else {
          c->field = std::make_shared<const SolidDistanceField>(cs);
        }
      } catch (const std::exception& e) {
        throw std::invalid_argument(where + ": " + e.what());
      }
    }
    if (!in.fixed && !c->sampled) {
      try {
        c->shell = SampleSurfaceShell(c->field->solid(), settings.shell_spacing,
                                      settings.search_half_extent);
      } catch (const std::exception& e) {
        throw std::invalid_argument(where + ": " + e.what());
      }
      c->sampled = true;
    }
    haptics::AssemblyPart part;
    part.name = in.name;
    part.field_P = c->field;
    if (!in.fixed) part.shell_P = c->shell;
    part.X_WP = in.X_WP;
    part.fixed = in.fixed;
    for (const modeling::SceneSeat& ss : in.seats) {
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
  auto field =
      std::make_unique<haptics::AssemblyField>(std::move(parts), std::move(tool), settings.field);
  if (cache != nullptr) {
    cache->entries_ = std::move(used);
    cache->compiled_last_ = compiled;
  }
  return field;
}

std::vector<AssemblyPartInput> ScenePartInputs(const modeling::Scene& scene) {
  std::vector<AssemblyPartInput> inputs;
  for (const modeling::ScenePart& sp : scene.parts) {
    AssemblyPartInput in;
    in.name = sp.name;
    in.solid = sp.solid;
    for (const modeling::Solid& s : scene.solids) {
      if (s.name == sp.solid) in.root = &s.root;
    }
    in.X_WP = PartPose(sp.position, sp.rotation);
    in.fixed = sp.fixed;
    in.seats = sp.seats;
    inputs.push_back(std::move(in));
  }
  return inputs;
}

std::unique_ptr<haptics::AssemblyField> BuildAssemblyField(const modeling::Scene& scene,
                                                           const AssemblySceneSettings& settings) {
  return BuildAssemblyField(ScenePartInputs(scene), settings, nullptr);
}

std::vector<AssemblyPartInput> RigidPartInputs(const Document& doc, std::vector<ObjectId>* ids) {
  std::vector<AssemblyPartInput> inputs;
  if (ids != nullptr) ids->clear();
  for (const DocObject& o : doc.objects()) {
    const auto* r = std::get_if<RigidPartData>(&o.data);
    if (r == nullptr) continue;
    AssemblyPartInput in;
    in.name = o.name;
    in.solid = o.name;
    in.root = &r->root;
    in.X_WP = r->X_WP;
    in.fixed = r->fixed;
    in.seats = r->seats;
    inputs.push_back(std::move(in));
    if (ids != nullptr) ids->push_back(o.id);
  }
  return inputs;
}

namespace {

// Appends `suffix` to every non-empty node id of the tree.
void SuffixIds(modeling::ImplicitNode* node, const std::string& suffix) {
  if (!node->id.empty()) node->id += suffix;
  for (modeling::ImplicitNode& child : node->children) SuffixIds(&child, suffix);
}

}  // namespace

bool AdoptScenePartsAsRigidParts(Document* doc) {
  const std::vector<modeling::ScenePart>& parts = doc->parts();
  if (parts.empty()) return false;
  const std::vector<DocObject>& old = doc->objects();
  auto is_part_solid = [&](const DocObject& o) {
    return std::holds_alternative<SolidData>(o.data) &&
           std::any_of(parts.begin(), parts.end(),
                       [&](const modeling::ScenePart& p) { return p.solid == o.name; });
  };
  // Where each kept object goes (references go to AdoptContent as index + 1, document.h).
  std::vector<int> new_index(old.size(), -1);
  int kept = 0;
  for (size_t i = 0; i < old.size(); ++i) {
    if (!is_part_solid(old[i])) new_index[i] = kept++;
  }
  auto remap = [&](ObjectId ref) -> ObjectId {
    const int k = doc->IndexOf(ref);
    if (k < 0 || new_index[k] < 0) {
      throw modeling::SceneError(doc->file_path(), 0, 0, "/parts",
                                 "an object refers to solid '" + (k < 0 ? "?" : old[k].name) +
                                     "', which is an assembly part");
    }
    return static_cast<ObjectId>(new_index[k] + 1);
  };
  std::vector<DocObject> objects;
  for (const DocObject& o : old) {
    if (is_part_solid(o)) continue;
    DocObject copy = o;
    if (auto* m = std::get_if<MeshData>(&copy.data)) {
      m->source_revision = m->source != 0 && !doc->IsMeshOutOfDate(o.id) ? 1 : 0;
      if (m->source != 0) m->source = remap(m->source);
    }
    if (auto* f = std::get_if<FeModelData>(&copy.data)) f->tet_mesh = remap(f->tet_mesh);
    objects.push_back(std::move(copy));
  }
  std::map<std::string, int> copies;  // solid name -> copies made
  for (const modeling::ScenePart& p : parts) {
    const DocObject* solid = nullptr;
    for (const DocObject& o : old) {
      if (o.name == p.solid && std::holds_alternative<SolidData>(o.data)) {
        solid = &o;
        break;
      }
    }
    if (solid == nullptr) {
      throw modeling::SceneError(doc->file_path(), 0, 0, "/parts",
                                 "part '" + p.name + "' names no solid '" + p.solid + "'");
    }
    RigidPartData r;
    r.root = std::get<SolidData>(solid->data).root;
    if (copies[p.solid]++ > 0) SuffixIds(&r.root, "_" + p.name);
    r.X_WP = PartPose(p.position, p.rotation);
    r.fixed = p.fixed;
    r.seats = p.seats;
    DocObject o;
    o.name = p.name;
    o.data = std::move(r);
    objects.push_back(std::move(o));
  }
  const std::string path = doc->file_path();
  doc->AdoptContent(std::move(objects), doc->description(), doc->snap(), {}, doc->view(),
                    path.empty() ? std::string("<document>") : path);
  doc->set_file_path(path);
  return true;
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
