// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#include "scene/scene_model.h"

#include <algorithm>
#include <cctype>
#include <stdexcept>
#include <variant>

#include "scene/scene_fields.h"
#include "scene/snap_features.h"
#include "spidarcad/modeling/scene_io.h"
#include "spidarcad/modeling/surface_mesher.h"
#include "spidarcad/modeling/tetgen_mesher.h"
#include "spidarcad/modeling/triangle_mesh_io.h"

namespace spidarcad::app {

namespace {

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
  x.p_WDo =
      Eigen::Vector3d(centre.x(), centre.y(), bounds_W.max().z() + x.world_scale * kClearance);
  return x;
}

SceneModel::SceneModel() : doc_(std::make_unique<Document>()) {}

SceneModel::~SceneModel() = default;

namespace {

// Result of a preview job's work: a surface and the box it was meshed in, or why not.
struct PreviewResult {
  std::string error;
  Eigen::AlignedBox3d bounds_W;
  modeling::TriangleMesh mesh;
  double cell = 0.0;
};

// Box of `solid` (FindBounds at about 1/64 of its size); throws std::runtime_error naming
// `what` when the solid is empty or unbounded, modeling::MeshingCancelled when `cancel` is raised.
Eigen::AlignedBox3d SolidBox(const modeling::CompiledSolid& solid, const std::string& what,
                             const std::atomic<bool>* cancel = nullptr) {
  bool unbounded = false;
  const Eigen::AlignedBox3d box = SolidBounds(solid, &unbounded, cancel);
  if (unbounded) throw std::runtime_error(what + " is unbounded (reaches the 20 m search box)");
  if (box.isEmpty()) throw std::runtime_error(what + " is empty");
  return box;
}

}  // namespace

void SceneModel::Load(const std::string& source, const Eigen::Vector3d& travel,
                      const DeviceToWorld* keep) {
  Adopt(Prepare(source), travel, keep);
}

PreparedScene SceneModel::Prepare(const std::string& source, const std::atomic<bool>* cancel,
                                  PrepareProgress* progress) {
  PreparedScene prepared;
  prepared.source = source;
  prepared.doc = std::make_unique<Document>();
  Document& doc = *prepared.doc;
  if (source == kNoSceneName) {
    modeling::Scene scene;
    scene.description = "empty scene";
    doc.LoadScene(scene, "<empty scene>");
  } else if (source == kDemoSceneName) {
    doc.LoadScene(modeling::ParseScene(DemoSceneJson(), "<built-in demo scene>"),
                  "<built-in demo scene>");
  } else {
    const int version = doc.Load(source);  // SceneError names file, line and field
    prepared.assembly = version == 1 && !doc.parts().empty();
    std::error_code ec;
    prepared.mtime = std::filesystem::last_write_time(source, ec);
  }
  // The file's reading and each solid's compilation look at the flag between them only.
  const auto check_cancel = [cancel] {
    if (cancel != nullptr && cancel->load()) throw modeling::MeshingCancelled();
  };
  check_cancel();
  int solids = 0;
  for (const DocObject& d : doc.objects()) solids += std::holds_alternative<SolidData>(d.data);
  if (progress != nullptr) progress->solids_total.store(solids);
  int i = 0;
  for (const DocObject& d : doc.objects()) {
    const auto* data = std::get_if<SolidData>(&d.data);
    if (data == nullptr) continue;
    SceneObject object;
    object.id = d.id;
    object.name = d.name;
    object.source_revision = d.revision;
    try {
      object.solid = std::make_shared<const modeling::CompiledSolid>(
          modeling::CompiledSolid::Compile(data->root, "/solids/" + std::to_string(i) + "/root"));
      check_cancel();
      object.bounds_W = SolidBox(*object.solid, "solid '" + d.name + "'", cancel);
    } catch (const modeling::MeshingCancelled&) {
      throw;
    } catch (const std::exception& e) {
      const std::string text = e.what();
      // SolidBox's messages already name the solid.
      throw std::runtime_error(
          source + ": " +
          (text.rfind("solid '", 0) == 0 ? text : "solid '" + d.name + "': " + text));
    }
    object.colour = kColours[i % kColours.size()];
    prepared.objects.push_back(std::move(object));
    ++i;
    if (progress != nullptr) progress->solids_done.store(i);
  }
  return prepared;
}

void SceneModel::Adopt(PreparedScene&& prepared, const Eigen::Vector3d& travel,
                       const DeviceToWorld* keep) {
  doc_ = std::move(prepared.doc);
  synced_revision_ = doc_->revision();
  objects_ = std::move(prepared.objects);
  Eigen::AlignedBox3d all;
  for (const SceneObject& o : objects_) all.extend(o.bounds_W);
  x_wd_ = keep != nullptr ? DeviceToWorld(*keep) : ChooseDeviceToWorld(all, travel);
  source_ = std::move(prepared.source);
  mtime_ = prepared.mtime;
  ++generation_;
}

void SceneModel::Save(const std::string& path) {
  doc_->Save(path);  // temporary file renamed over path; SceneError on failure
  source_ = path;
  std::error_code ec;
  mtime_ = std::filesystem::last_write_time(path, ec);
}

int SceneModel::IndexOf(ObjectId id) const {
  for (size_t i = 0; i < objects_.size(); ++i) {
    if (objects_[i].id == id) return static_cast<int>(i);
  }
  return -1;
}

bool SceneModel::Refresh() {
  if (doc_->revision() == synced_revision_) return false;
  synced_revision_ = doc_->revision();
  bool changed = false;
  std::vector<SceneObject> next;
  for (const DocObject& d : doc_->objects()) {
    const auto* data = std::get_if<SolidData>(&d.data);
    if (data == nullptr) continue;
    SceneObject o;
    const int old = IndexOf(d.id);
    if (old >= 0) {
      o = std::move(objects_[old]);
    } else {
      o.id = d.id;
    }
    o.name = d.name;
    if (o.solid != nullptr && d.revision == o.source_revision) {
      o.error.clear();  // back at the compiled revision (e.g. undo of a failing edit)
      o.error_revision = 0;
    } else if (d.revision != o.error_revision) {
      try {
        o.solid = std::make_shared<const modeling::CompiledSolid>(modeling::CompiledSolid::Compile(
            data->root, "/objects/" + std::to_string(d.id) + "/root"));
        o.source_revision = d.revision;
        o.error.clear();
        o.error_revision = 0;
        changed = true;
      } catch (const std::exception& e) {
        o.error = e.what();  // keep the last good solid, preview and haptics
        o.error_revision = d.revision;
      }
    }
    next.push_back(std::move(o));
  }
  // Objects that went away change the haptic scene too.
  for (const SceneObject& o : objects_) {
    const bool kept =
        std::any_of(next.begin(), next.end(), [&](const SceneObject& n) { return n.id == o.id; });
    if (!kept && o.solid != nullptr) changed = true;
  }
  for (size_t i = 0; i < next.size(); ++i) next[i].colour = kColours[i % kColours.size()];
  objects_ = std::move(next);
  return changed;
}

bool SceneModel::SourceChanged() const {
  if (source_ == kNoSceneName || source_ == kDemoSceneName || source_.empty()) return false;
  if (doc_->dirty()) return false;  // a reload would lose the edits
  std::error_code ec;
  const auto now = std::filesystem::last_write_time(source_, ec);
  return !ec && now != mtime_;
}

void SceneModel::TakeSourceChange() {
  std::error_code ec;
  const auto now = std::filesystem::last_write_time(source_, ec);
  if (!ec) mtime_ = now;
}

void SceneModel::StartPreview(JobQueue* jobs, SceneObject* object, double cells_across) {
  const std::shared_ptr<const modeling::CompiledSolid> solid = object->solid;
  const int generation = generation_;
  const int sequence = ++preview_counter_;
  const ObjectId id = object->id;
  const std::uint64_t revision = object->source_revision;
  const std::string name = object->name;
  Job& job =
      jobs->Start("Preview " + name,
                  [this, id, solid, generation, sequence, revision, cells_across,
                   name](JobContext& context) -> Job::Finisher {
                    auto result = std::make_shared<PreviewResult>();
                    try {
                      context.SetPhase("bounds");
                      const std::atomic<bool>* cancel = context.cancel_flag();
                      result->bounds_W = SolidBox(*solid, "solid '" + name + "'", cancel);
                      const double cell = result->bounds_W.sizes().maxCoeff() / cells_across;
                      modeling::SurfaceMeshSettings s;
                      s.bounds = result->bounds_W;
                      s.bounds.min().array() -= 2.0 * cell;
                      s.bounds.max().array() += 2.0 * cell;
                      s.cell_size = cell;
                      s.cancel = cancel;
                      s.progress = context.ProgressRange(0.0, 1.0);
                      context.SetPhase("surface");
                      result->mesh = modeling::MeshSurface(*solid, s);
                      result->cell = cell;
                    } catch (const std::exception& e) {
                      if (context.cancelled()) throw;  // superseded or cancelled: nothing lands
                      // A solid that cannot be previewed (empty, unbounded, too fine a grid): the
                      // error lands on the object, which keeps its last preview; no retry for this
                      // revision.
                      result->error = e.what();
                    }
                    return [this, id, generation, sequence, revision, cells_across, result]() {
                      if (generation != generation_) return;  // scene reloaded
                      const int i = IndexOf(id);
                      if (i < 0) return;  // object deleted
                      SceneObject& o = objects_[i];
                      if (sequence <= o.preview_sequence) return;  // a newer preview already landed
                      o.preview_sequence = sequence;
                      o.preview_revision = revision;
                      o.preview_cells_across = cells_across;
                      if (!result->error.empty()) {
                        if (revision == o.source_revision) {
                          o.error = result->error;
                          o.error_revision = revision;
                        }
                        return;
                      }
                      if (revision == o.source_revision && o.error_revision == revision) {
                        o.error.clear();
                        o.error_revision = 0;
                      }
                      o.bounds_W = result->bounds_W;
                      o.preview = std::move(result->mesh);
                      o.preview_cell = result->cell;
                      ++o.revision;
                    };
                  });
  object->preview_job = &job;
  object->preview_job_revision = revision;
  object->preview_job_cells_across = cells_across;
}

void SceneModel::StartPreviewJobs(JobQueue* jobs, double cells_across) {
  for (SceneObject& o : objects_) {
    if (o.solid != nullptr) StartPreview(jobs, &o, cells_across);
  }
}

void SceneModel::UpdatePreviews(JobQueue* jobs, double coarse_cells_across,
                                double fine_cells_across) {
  for (SceneObject& o : objects_) {
    if (o.solid == nullptr) continue;
    Job* running = nullptr;
    if (o.preview_job != nullptr) {
      for (const auto& job : jobs->jobs()) {
        if (job.get() == o.preview_job && job->state() == Job::State::kRunning) running = job.get();
      }
    }
    if (running == nullptr) o.preview_job = nullptr;
    const bool current = o.preview_revision == o.source_revision;
    if (running != nullptr) {
      // A fine pass of a shape that has changed since only delays the coarse pass of the new one.
      if (o.preview_job_revision != o.source_revision &&
          o.preview_job_cells_across > coarse_cells_across && !running->cancel_requested()) {
        running->Cancel();
      }
      continue;
    }
    if (!current) {
      StartPreview(jobs, &o, coarse_cells_across);
    } else if (o.preview_cells_across < fine_cells_across) {
      StartPreview(jobs, &o, fine_cells_across);
    }
  }
}

FeMeshInput SceneModel::MeshJobInput(int index, MeshKind kind, const MeshSettings& settings) const {
  if (index < 0 || index >= static_cast<int>(objects_.size())) {
    throw std::out_of_range("no scene object " + std::to_string(index));
  }
  if (!(settings.cell_size > 0.0)) throw std::invalid_argument("mesh resolution must be > 0");
  const SceneObject& o = objects_[index];
  if (o.solid == nullptr) {
    throw std::invalid_argument("solid '" + o.name + "' does not compile: " + o.error);
  }
  const bool tets = kind == MeshKind::kTetrahedra;
  MeshSettings s = settings;
  if (!tets) s.mesher.clear();  // the grid surface: no tetrahedral mesher
  return PrepareSolidMesh(*doc_, o.id, s, tets);
}

Job& SceneModel::StartMeshJob(JobQueue* jobs, int index, MeshKind kind,
                              const MeshSettings& settings) {
  FeMeshInput input = MeshJobInput(index, kind, settings);
  const std::string title = std::string(kind == MeshKind::kTetrahedra ? "Tetrahedra" : "Surface") +
                            " of " + objects_[index].name;
  return StartDocumentMeshJob(jobs, title, std::move(input), 0);
}

std::string SceneModel::MeshJobOverBudget(int index, MeshKind kind,
                                          const MeshSettings& settings) const {
  const FeMeshInput input = MeshJobInput(index, kind, settings);  // checks the index first
  return LargeMeshQuestion(objects_[index].name, input);
}

Job& SceneModel::StartRefreshJob(JobQueue* jobs, ObjectId mesh) {
  FeMeshInput input = PrepareFeRemesh(*doc_, mesh);
  const std::string title = "Refresh " + doc_->Get(mesh).name;
  return StartDocumentMeshJob(jobs, title, std::move(input), mesh);
}

Job& SceneModel::StartDocumentMeshJob(JobQueue* jobs, std::string title, FeMeshInput input,
                                      ObjectId mesh) {
  const int generation = generation_;
  return jobs->Start(
      std::move(title), [this, input, mesh, generation](JobContext& context) -> Job::Finisher {
        const bool cgal = input.kind == FeSourceKind::kSolid && input.settings.mesher == "cgal";
        context.SetPhase(!input.volume ? "surface"
                         : cgal        ? "tetrahedra (CGAL Mesh_3)"
                                       : "surface and tetrahedra (TetGen)");
        auto result = std::make_shared<FeMeshResult>(
            MeshFeSource(input, context.cancel_flag(), context.ProgressRange(0.0, 1.0)));
        if (context.cancelled()) throw std::runtime_error("cancelled");
        return [this, input, mesh, generation, result]() {
          if (generation != generation_) return;  // another document: nothing to land on
          // Throws (the job fails, nothing changes) when the source changed or went away.
          doc_->Execute(mesh == 0 ? AddMeshOf(input, *result)
                                  : RefreshFeMesh(mesh, input, *result));
          if (mesh == 0) landed_mesh_ = doc_->last_created().front();
        };
      });
}

namespace {

// True when fields built with `a` at scale sa are the fields built with `b` at scale sb.
bool SameFieldOptions(const SceneHapticsOptions& a, double sa, const SceneHapticsOptions& b,
                      double sb) {
  return sa == sb && a.tool == b.tool && a.stiffness == b.stiffness && a.damping == b.damping &&
         a.static_friction == b.static_friction && a.dynamic_friction == b.dynamic_friction &&
         a.shell_radius == b.shell_radius && a.shell_rings == b.shell_rings &&
         a.shell_around == b.shell_around && a.coupling_stiffness == b.coupling_stiffness &&
         a.coupling_damping == b.coupling_damping && a.grip_d == b.grip_d;
}

}  // namespace

SceneModel::ContactEntry SceneModel::TakeContactEntry(
    ObjectId id, ToolModel tool, const std::vector<const modeling::CompiledSolid*>& solids,
    const SceneHapticsOptions& options, double world_scale) {
  ContactEntry e;
  const auto it = std::find_if(contacts_.begin(), contacts_.end(),
                               [&](const ContactEntry& c) { return c.id == id && c.tool == tool; });
  if (it != contacts_.end()) {
    e = std::move(*it);
    contacts_.erase(it);
  } else {
    e.id = id;
    e.tool = tool;
    e.channel = std::make_shared<ContactChannel>();
  }
  // The wrapper of the previous scene ran its fallback (the reused field was stale): that is
  // the field to go on with.
  if (e.fallback && e.channel->marker.Latest().field == e.fallback.get()) e.current = e.fallback;
  e.fallback.reset();
  if (e.solids != solids || !SameFieldOptions(e.options, e.world_scale, options, world_scale)) {
    e.current.reset();
  }
  e.solids = solids;
  e.options = options;
  e.world_scale = world_scale;
  return e;
}

std::unique_ptr<haptics::HapticScene> SceneModel::BuildHapticScene(
    const DemoFieldSettings& field, const SceneHapticsOptions& options) {
  const double s = x_wd_.world_scale;
  std::vector<CompiledSceneSolid> solids;
  std::vector<ObjectId> ids;
  std::vector<const modeling::CompiledSolid*> keys;
  for (const SceneObject& o : objects_) {
    if (o.solid == nullptr) continue;  // never compiled: nothing to touch
    solids.push_back({o.name, o.solid});
    ids.push_back(o.id);
    keys.push_back(o.solid.get());
  }
  // Snap features of the Document's scene, found again only when the Document changed.
  const SnapInput* snap = nullptr;
  if (doc_->snap() && !solids.empty()) {
    if (snap_generation_ != generation_ || snap_revision_ != doc_->revision() ||
        snap_tolerance_ != options.snap_tolerance) {
      snap_generation_ = generation_;
      snap_revision_ = doc_->revision();
      snap_tolerance_ = options.snap_tolerance;
      try {
        snap_input_ =
            SnapInput{*doc_->snap(), ExtractSnapFeatures(doc_->ToScene(), options.snap_tolerance)};
      } catch (const std::exception&) {
        snap_input_.reset();  // a tree that does not evaluate (its error shows on the object)
      }
    }
    if (snap_input_) snap = &*snap_input_;
  }
  SolidFields built = BuildSolidFields(solids, options, s, snap);

  ContinuitySettings continuity;  // lengths are grip lengths: into W
  continuity.max_move *= s;
  continuity.max_seed_move *= s;
  continuity.seed_clearance *= s;
  auto scene = std::make_unique<haptics::HapticScene>();
  std::vector<ContactEntry> next;
  if (options.tool == ToolModel::kProxy) {
    for (std::size_t i = 0; i < built.proxies.size(); ++i) {
      ContactEntry e = TakeContactEntry(ids[i], ToolModel::kProxy, {keys[i]}, options, s);
      std::shared_ptr<haptics::ProxyField> fresh(std::move(built.proxies[i]));
      auto reuse = std::static_pointer_cast<haptics::ProxyField>(e.current);
      scene->Add(std::make_unique<ContinuousProxyField>(reuse, fresh, built.distance[i], e.channel,
                                                        continuity));
      if (reuse) {
        e.fallback = fresh;
      } else {
        e.current = fresh;
      }
      next.push_back(std::move(e));
    }
  } else if (built.shell) {
    ContactEntry e = TakeContactEntry(0, ToolModel::kShell, keys, options, s);
    std::shared_ptr<haptics::PointShellField> fresh(std::move(built.shell));
    auto reuse = std::static_pointer_cast<haptics::PointShellField>(e.current);
    scene->Add(std::make_unique<ContinuousShellField>(reuse, fresh, built.shell_environment,
                                                      e.channel, continuity));
    if (reuse) {
      e.fallback = fresh;
    } else {
      e.current = fresh;
    }
    next.push_back(std::move(e));
  }
  contacts_ = std::move(next);
  if (built.snap) scene->Add(std::move(built.snap));
  if (field.enabled) {
    scene->Add(std::make_unique<CentringSpringField>(field, x_wd_));
  }
  return scene;
}

std::vector<ContactMarker> SceneModel::ContactMarkers() {
  std::vector<ContactMarker> out;
  out.reserve(contacts_.size());
  for (ContactEntry& e : contacts_) out.push_back(e.channel->marker.Latest());
  return out;
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
