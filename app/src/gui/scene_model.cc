// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#include "gui/scene_model.h"

#include <algorithm>
#include <cctype>
#include <stdexcept>

#include "gui/scene_fields.h"
#include "spidarcad/modeling/scene_io.h"
#include "spidarcad/modeling/tetgen_mesher.h"
#include "spidarcad/modeling/triangle_mesh_io.h"

namespace spidarcad::app {

namespace {

// Half-side of the box searched for each solid, m.
constexpr double kSearchHalfSide = 10.0;
// Height of the device centre above the top of the solids, in D, m.
constexpr double kClearance = 0.06;

std::string Lower(std::string s) {
  for (char& c : s) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return s;
}

}  // namespace

const std::array<std::array<double, 3>, 3> SceneModel::kColours = {{
    {0.85, 0.72, 0.50},  // sand
    {0.55, 0.72, 0.55},  // sage
    {0.72, 0.60, 0.82},  // lilac
}};

const char* DemoSceneJson() {
  return R"({
  "format": "spidarcad-scene", "version": 1, "units": "m",
  "description": "Built-in demo: a bracket block with a bore and a knob, under the grip.",
  "solids": [
    {"name": "bracket", "root": {"type": "translate", "translation": [-0.04, 0.0, -0.09],
      "children": [{"type": "difference", "children": [
        {"type": "rounded_box", "size": [0.14, 0.10, 0.05], "radius": 0.006},
        {"type": "cylinder", "radius": 0.022, "height": 0.08}]}]}},
    {"name": "knob", "root": {"type": "translate", "translation": [0.08, 0.03, -0.085],
      "children": [{"type": "sphere", "radius": 0.035}]}}
  ]
})";
}

DeviceToWorld ChooseDeviceToWorld(const Eigen::AlignedBox3d& bounds_W,
                                  const Eigen::Vector3d& travel) {
  DeviceToWorld x;
  if (bounds_W.isEmpty()) return x;
  const Eigen::Vector3d size = bounds_W.sizes();
  // Reach in D: 80 % of the travel across x and y; below the centre, travel − clearance in z.
  const double reach_x = 1.6 * travel.x(), reach_y = 1.6 * travel.y();
  const double reach_z = 0.9 * travel.z() - kClearance;
  x.world_scale = std::max({1.0, size.x() / reach_x, size.y() / reach_y, size.z() / reach_z});
  const Eigen::Vector3d centre = bounds_W.center();
  // Device centre above the middle of the top face: p_W(p_D = 0) = p_WDo.
  x.p_WDo = Eigen::Vector3d(centre.x(), centre.y(), bounds_W.max().z() + x.world_scale * kClearance);
  return x;
}

void SceneModel::Load(const std::string& source, const Eigen::Vector3d& travel,
                      const DeviceToWorld* keep) {
  modeling::Scene scene;
  std::filesystem::file_time_type mtime{};
  if (source == kNoSceneName) {
    scene.description = "empty scene";
  } else if (source == kDemoSceneName) {
    scene = modeling::ParseScene(DemoSceneJson(), "<built-in demo scene>");
  } else {
    scene = modeling::LoadScene(source);  // SceneError names file, line and field
    std::error_code ec;
    mtime = std::filesystem::last_write_time(source, ec);
  }
  std::vector<SceneObject> objects;
  Eigen::AlignedBox3d all;
  const Eigen::AlignedBox3d search(Eigen::Vector3d::Constant(-kSearchHalfSide),
                                   Eigen::Vector3d::Constant(kSearchHalfSide));
  for (size_t i = 0; i < scene.solids.size(); ++i) {
    const modeling::Solid& s = scene.solids[i];
    SceneObject object;
    object.name = s.name;
    try {
      object.solid = std::make_shared<const modeling::CompiledSolid>(
          modeling::CompiledSolid::Compile(s.root, "/solids/" + std::to_string(i) + "/root"));
    } catch (const std::exception& e) {
      throw std::runtime_error(source + ": solid '" + s.name + "': " + e.what());
    }
    const Eigen::AlignedBox3d rough = modeling::FindBounds(*object.solid, search, 0.01);
    if (rough.isEmpty()) {
      throw std::runtime_error(source + ": solid '" + s.name + "' is empty");
    }
    if ((rough.min().array() <= -kSearchHalfSide + 0.01).any() ||
        (rough.max().array() >= kSearchHalfSide - 0.01).any()) {
      throw std::runtime_error(source + ": solid '" + s.name +
                               "' is unbounded (reaches the 20 m search box)");
    }
    object.bounds_W = modeling::FindBounds(*object.solid, rough, rough.sizes().maxCoeff() / 64.0);
    object.colour = kColours[i % kColours.size()];
    all.extend(object.bounds_W);
    objects.push_back(std::move(object));
  }
  objects_ = std::move(objects);
  x_wd_ = keep != nullptr ? DeviceToWorld(*keep) : ChooseDeviceToWorld(all, travel);
  source_ = source;
  description_ = scene.description;
  mtime_ = mtime;
  ++generation_;
}

bool SceneModel::SourceChanged() const {
  if (source_ == kNoSceneName || source_ == kDemoSceneName || source_.empty()) return false;
  std::error_code ec;
  const auto now = std::filesystem::last_write_time(source_, ec);
  return !ec && now != mtime_;
}

void SceneModel::StartPreviewJobs(JobQueue* jobs, double cells_across) {
  for (size_t i = 0; i < objects_.size(); ++i) {
    const SceneObject& o = objects_[i];
    const double cell = o.bounds_W.sizes().maxCoeff() / cells_across;
    modeling::SurfaceMeshSettings settings;
    settings.bounds = o.bounds_W;
    settings.bounds.min().array() -= 2.0 * cell;
    settings.bounds.max().array() += 2.0 * cell;
    settings.cell_size = cell;
    const std::shared_ptr<const modeling::CompiledSolid> solid = o.solid;
    const int generation = generation_;
    jobs->Start("Preview " + o.name, [this, i, solid, settings, generation,
                                      cell](JobContext& context) -> Job::Finisher {
      modeling::SurfaceMeshSettings s = settings;
      s.cancel = context.cancel_flag();
      s.progress = context.ProgressRange(0.0, 1.0);
      context.SetPhase("surface");
      auto mesh = std::make_shared<modeling::TriangleMesh>(modeling::MeshSurface(*solid, s));
      return [this, i, mesh, generation, cell]() {
        if (generation != generation_ || i >= objects_.size()) return;  // scene reloaded
        objects_[i].preview = std::move(*mesh);
        objects_[i].preview_cell = cell;
        ++objects_[i].revision;
      };
    });
  }
}

Job& SceneModel::StartMeshJob(JobQueue* jobs, int index, MeshKind kind, double cell) {
  if (index < 0 || index >= static_cast<int>(objects_.size())) {
    throw std::out_of_range("no scene object " + std::to_string(index));
  }
  if (!(cell > 0.0)) throw std::invalid_argument("mesh resolution must be > 0");
  const SceneObject& o = objects_[index];
  modeling::SurfaceMeshSettings settings;
  settings.bounds = o.bounds_W;
  settings.bounds.min().array() -= 2.0 * cell;
  settings.bounds.max().array() += 2.0 * cell;
  settings.cell_size = cell;
  const std::shared_ptr<const modeling::CompiledSolid> solid = o.solid;
  const int generation = generation_;
  const std::string title = std::string(kind == MeshKind::kSurface ? "Surface" : "Tetrahedra") +
                            " of " + o.name;
  return jobs->Start(title, [this, index, solid, settings, generation, kind,
                             cell](JobContext& context) -> Job::Finisher {
    const bool tets = kind == MeshKind::kTetrahedra;
    modeling::SurfaceMeshSettings s = settings;
    s.cancel = context.cancel_flag();
    s.progress = context.ProgressRange(0.0, tets ? 0.4 : 1.0);
    context.SetPhase("surface");
    auto surface = std::make_shared<modeling::TriangleMesh>(modeling::MeshSurface(*solid, s));
    auto tet = std::make_shared<modeling::TetMesh>();
    if (tets) {
      context.SetPhase("tetrahedra (TetGen)");
      modeling::TetMeshSettings t;
      t.cancel = context.cancel_flag();
      t.progress = context.ProgressRange(0.4, 1.0);
      *tet = modeling::TetrahedralizeSurface(*surface, t);
    }
    if (context.cancelled()) throw std::runtime_error("cancelled");
    return [this, index, surface, tet, generation, tets, cell]() {
      if (generation != generation_ || index >= static_cast<int>(objects_.size())) return;
      SceneObject& object = objects_[index];
      object.surface = std::move(*surface);
      object.surface_cell = cell;
      if (tets) object.tets = std::move(*tet);
      ++object.revision;
    };
  });
}

std::unique_ptr<haptics::HapticScene> SceneModel::BuildHapticScene(const DemoFieldSettings& field,
                                                                   double stiffness_D,
                                                                   double damping_D) const {
  auto scene = std::make_unique<haptics::HapticScene>();
  const double s = x_wd_.world_scale;
  for (const SceneObject& o : objects_) {
    // Felt in D: a world displacement of s·x is a device displacement of x.
    scene->Add(std::make_unique<SolidPenaltyField>(o.solid, stiffness_D / s, damping_D / s));
  }
  if (field.enabled) {
    scene->Add(std::make_unique<CentringSpringField>(field, s, x_wd_.p_WDo));
  }
  return scene;
}

std::string ExportSurface(const modeling::TriangleMesh& mesh, const std::string& path) {
  if (mesh.triangles.cols() == 0) return "nothing to export: the object has no surface mesh yet";
  const std::string ext = Lower(std::filesystem::path(path).extension().string());
  if (ext != ".stl" && ext != ".obj" && ext != ".ply") {
    return "'" + path + "': unknown surface format '" + ext + "' (use .stl, .obj or .ply)";
  }
  try {
    modeling::WriteTriangleMesh(mesh, path);
  } catch (const std::exception& e) {
    return e.what();
  }
  return "";
}

std::string ExportTetrahedra(const modeling::TetMesh& mesh, const std::string& path) {
  if (mesh.tets.cols() == 0) {
    return "nothing to export: the object has no tetrahedra (run Mesh → Tetrahedra first)";
  }
  const std::filesystem::path p(path);
  const std::string ext = Lower(p.extension().string());
  try {
    if (ext == ".vtu") {
      modeling::WriteVtu(mesh, path);
    } else if (ext == ".node" || ext == ".ele" || ext.empty()) {
      std::filesystem::path base = p;
      base.replace_extension();
      modeling::WriteTetgenFiles(mesh, base.string());
    } else {
      return "'" + path + "': unknown tetrahedra format '" + ext +
             "' (use .vtu, or .node/.ele for TetGen files)";
    }
  } catch (const std::exception& e) {
    return e.what();
  }
  return "";
}

}  // namespace spidarcad::app
