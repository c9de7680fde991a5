// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#include "doc/document.h"

#include <algorithm>
#include <cmath>
#include <map>
#include <set>
#include <sstream>

#include "doc/command.h"
#include "doc/document_io.h"

namespace spidarcad::app {
namespace {

template <class... Ts>
struct Overloaded : Ts... {
  using Ts::operator()...;
};
template <class... Ts>
Overloaded(Ts...) -> Overloaded<Ts...>;

std::string Describe(const DocObject& object) {
  return std::string(ObjectKindName(object.data)) + " '" + object.name + "' (id " +
         std::to_string(object.id) + ")";
}

std::string FormatNumber(double v) {
  std::ostringstream s;
  s.precision(17);
  s << v;
  return s.str();
}

bool AllFinite(const Eigen::Ref<const Eigen::MatrixXd>& m) { return m.allFinite(); }

// Visits every node of a tree with its path.
template <class F>
void ForEachNode(const modeling::ImplicitNode& node, NodePath* path, F&& f) {
  f(node, *path);
  for (int i = 0; i < static_cast<int>(node.children.size()); ++i) {
    path->push_back(i);
    ForEachNode(node.children[i], path, f);
    path->pop_back();
  }
}

nlohmann::json MatrixJson(const Eigen::Ref<const Eigen::MatrixXd>& m) {
  nlohmann::json cols = nlohmann::json::array();
  for (Eigen::Index c = 0; c < m.cols(); ++c) {
    nlohmann::json col = nlohmann::json::array();
    for (Eigen::Index r = 0; r < m.rows(); ++r) col.push_back(m(r, c));
    cols.push_back(col);
  }
  return cols;
}

nlohmann::json IntMatrixJson(const Eigen::Ref<const Eigen::MatrixXi>& m) {
  nlohmann::json cols = nlohmann::json::array();
  for (Eigen::Index c = 0; c < m.cols(); ++c) {
    nlohmann::json col = nlohmann::json::array();
    for (Eigen::Index r = 0; r < m.rows(); ++r) col.push_back(m(r, c));
    cols.push_back(col);
  }
  return cols;
}

nlohmann::json BoxJson(const Eigen::AlignedBox3d& b) {
  return {{"min", {b.min().x(), b.min().y(), b.min().z()}},
          {"max", {b.max().x(), b.max().y(), b.max().z()}}};
}

}  // namespace

int SculptVertexCount(const SculptMesh& mesh) { return static_cast<int>(mesh.vertices.cols()); }
Eigen::Vector3d SculptVertex(const SculptMesh& mesh, int v) { return mesh.vertices.col(v); }
void SetSculptVertex(SculptMesh* mesh, int v, const Eigen::Vector3d& position) {
  mesh->vertices.col(v) = position;
}

const char* ObjectKindName(const ObjectData& data) {
  static constexpr const char* kNames[] = {"solid", "mesh", "fe_model", "sculpt", "rigid_part"};
  static_assert(sizeof(kNames) / sizeof(kNames[0]) == std::variant_size_v<ObjectData>);
  return kNames[data.index()];
}

const modeling::ImplicitNode* TreeOf(const DocObject& object) {
  if (const auto* s = std::get_if<SolidData>(&object.data)) return &s->root;
  if (const auto* r = std::get_if<RigidPartData>(&object.data)) return &r->root;
  return nullptr;
}

modeling::ImplicitNode* TreeOf(DocObject* object) {
  return const_cast<modeling::ImplicitNode*>(TreeOf(static_cast<const DocObject&>(*object)));
}

std::string PathPointer(const NodePath& path) {
  std::string s;
  for (int i : path) s += "/children/" + std::to_string(i);
  return s;
}

Document::Document() : history_(std::make_unique<History>()) { saved_signature_ = Signature(); }

Document::~Document() = default;

const DocObject* Document::Find(ObjectId id) const {
  for (const DocObject& o : objects_) {
    if (o.id == id) return &o;
  }
  return nullptr;
}

const DocObject& Document::Get(ObjectId id) const {
  const DocObject* o = Find(id);
  if (o == nullptr)
    throw DocumentError("no object with id " + std::to_string(id) + " in the document");
  return *o;
}

int Document::IndexOf(ObjectId id) const {
  for (int i = 0; i < static_cast<int>(objects_.size()); ++i) {
    if (objects_[i].id == id) return i;
  }
  return -1;
}

const DocObject* Document::FindByName(const std::string& name) const {
  for (const DocObject& o : objects_) {
    if (o.name == name) return &o;
  }
  return nullptr;
}

const modeling::ImplicitNode& Document::Node(ObjectId id, const NodePath& path) const {
  const DocObject& object = Get(id);
  const modeling::ImplicitNode* node = TreeOf(object);
  if (node == nullptr) throw DocumentError(Describe(object) + " has no node tree");
  for (size_t depth = 0; depth < path.size(); ++depth) {
    const int i = path[depth];
    if (i < 0 || i >= static_cast<int>(node->children.size())) {
      throw DocumentError(Describe(object) + ": no node at " +
                          PathPointer(NodePath(path.begin(), path.begin() + depth + 1)) +
                          " (the node at '" +
                          PathPointer(NodePath(path.begin(), path.begin() + depth)) + "' has " +
                          std::to_string(node->children.size()) + " children)");
    }
    node = &node->children[i];
  }
  return *node;
}

std::optional<std::pair<ObjectId, NodePath>> Document::FindNodeById(
    const std::string& node_id) const {
  if (node_id.empty()) return std::nullopt;
  for (const DocObject& o : objects_) {
    const modeling::ImplicitNode* root = TreeOf(o);
    if (root == nullptr) continue;
    std::optional<NodePath> found;
    NodePath path;
    ForEachNode(*root, &path, [&](const modeling::ImplicitNode& n, const NodePath& p) {
      if (!found && n.id == node_id) found = p;
    });
    if (found) return std::make_pair(o.id, *found);
  }
  return std::nullopt;
}

bool Document::NodeIdUsed(const std::string& node_id) const {
  return FindNodeById(node_id).has_value();
}

bool Document::NodeNameUsed(const std::string& name) const {
  if (name.empty()) return false;
  for (const DocObject& o : objects_) {
    const modeling::ImplicitNode* root = TreeOf(o);
    if (root == nullptr) continue;
    bool used = false;
    NodePath path;
    ForEachNode(*root, &path, [&](const modeling::ImplicitNode& n, const NodePath&) {
      used = used || n.name == name;
    });
    if (used) return true;
  }
  return false;
}

bool Document::IsMeshOutOfDate(ObjectId mesh) const {
  const DocObject& object = Get(mesh);
  const auto* data = std::get_if<MeshData>(&object.data);
  if (data == nullptr) throw DocumentError(Describe(object) + " is not a mesh");
  if (data->source == 0) return false;
  const DocObject* source = Find(data->source);
  return source == nullptr || source->revision != data->source_revision;
}

bool Document::dirty() const { return Signature() != saved_signature_; }

std::vector<std::pair<ObjectId, std::uint64_t>> Document::Signature() const {
  std::vector<std::pair<ObjectId, std::uint64_t>> s;
  s.reserve(objects_.size() + 1);
  s.emplace_back(0, description_revision_);
  s.emplace_back(0, snap_revision_);
  for (const DocObject& o : objects_) s.emplace_back(o.id, o.revision);
  return s;
}

modeling::Scene Document::ToScene() const {
  modeling::Scene scene;
  scene.description = description_;
  scene.snap = snap_;
  for (const DocObject& o : objects_) {
    if (const auto* s = std::get_if<SolidData>(&o.data)) scene.solids.push_back({o.name, s->root});
  }
  scene.parts = parts_;
  return scene;
}

nlohmann::json Document::ToJson(bool with_revisions) const {
  nlohmann::json objects = nlohmann::json::array();
  for (const DocObject& o : objects_) {
    nlohmann::json j = {{"id", o.id}, {"name", o.name}, {"kind", ObjectKindName(o.data)}};
    if (with_revisions) j["revision"] = o.revision;
    std::visit(
        Overloaded{
            [&](const SolidData& s) { j["root"] = modeling::NodeToJson(s.root); },
            [&](const MeshData& m) {
              j["source"] = m.source;
              j["source_revision"] = m.source_revision;
              j["settings"] = {m.settings.cell_size, m.settings.max_tet_volume,
                               m.settings.max_radius_edge};
              if (!m.settings.mesher.empty()) j["settings"].push_back(m.settings.mesher);
              if (m.settings.sharp_edges) j["settings"].push_back("sharp_edges");
              if (!m.settings.surface_mesher.empty())
                j["settings"].push_back(m.settings.surface_mesher);
              if (m.settings.flat_cells != 0.0)
                j["settings"].push_back({{"flat_cells", m.settings.flat_cells}});
              j["import_source"] = m.import_source;
              if (m.surface) {
                j["surface"] = {{"vertices", MatrixJson(m.surface->vertices)},
                                {"triangles", IntMatrixJson(m.surface->triangles)}};
              }
              if (m.volume) {
                j["volume"] = {{"nodes", MatrixJson(m.volume->nodes)},
                               {"tets", IntMatrixJson(m.volume->tets)},
                               {"regions", IntMatrixJson(m.volume->regions)}};
              }
            },
            [&](const FeModelData& f) {
              j["tet_mesh"] = f.tet_mesh;
              j["youngs_modulus"] = f.material.youngs_modulus;
              j["poisson_ratio"] = f.material.poisson_ratio;
              nlohmann::json boxes = nlohmann::json::array();
              for (const auto& b : f.fixed_boxes) boxes.push_back(BoxJson(b));
              j["fixed_boxes"] = boxes;
              nlohmann::json loads = nlohmann::json::array();
              for (const auto& l : f.loads) {
                nlohmann::json e = BoxJson(l.box);
                e["force"] = {l.force.x(), l.force.y(), l.force.z()};
                loads.push_back(e);
              }
              j["loads"] = loads;
              nlohmann::json regions = nlohmann::json::array();
              for (const auto& r : f.region_materials) {
                regions.push_back({r.region, r.material.youngs_modulus, r.material.poisson_ratio});
              }
              j["region_materials"] = regions;
              j["element_order"] = f.element_order;
              j["precompute_key"] = f.precompute_key;
            },
            [&](const SculptData& s) {
              j["vertices"] = MatrixJson(s.mesh->vertices);
              j["triangles"] = IntMatrixJson(s.mesh->triangles);
            },
            [&](const RigidPartData& r) {
              j["root"] = modeling::NodeToJson(r.root);
              j["X_WP"] = MatrixJson(r.X_WP.matrix());
              j["fixed"] = r.fixed;
              nlohmann::json seats = nlohmann::json::array();
              for (const auto& seat : r.seats) {
                seats.push_back(
                    {{"on", seat.on},
                     {"position", {seat.position.x(), seat.position.y(), seat.position.z()}},
                     {"quaternion",
                      {seat.rotation.w(), seat.rotation.x(), seat.rotation.y(), seat.rotation.z()}},
                     {"position_tolerance", seat.position_tolerance},
                     {"angle_tolerance", seat.angle_tolerance}});
              }
              j["seats"] = seats;
            },
        },
        o.data);
    objects.push_back(std::move(j));
  }
  nlohmann::json doc = {{"description", description_}, {"objects", objects}};
  if (snap_) {
    doc["snap"] = {snap_->max_force, snap_->vertex_radius, snap_->edge_radius, snap_->face_radius};
  }
  if (view_) {
    doc["view"] = {view_->position.x(),    view_->position.y(),    view_->position.z(),
                   view_->focal_point.x(), view_->focal_point.y(), view_->focal_point.z(),
                   view_->view_up.x(),     view_->view_up.y(),     view_->view_up.z(),
                   view_->view_angle};
  }
  if (device_) doc["device"] = {device_->a, device_->b, device_->c, device_->d};
  if (with_revisions) {
    doc["description_revision"] = description_revision_;
    doc["snap_revision"] = snap_revision_;
  }
  return doc;
}

int Document::Load(const std::string& path) {
  const int version = ReadDocumentFile(path, this);  // throws SceneError naming the file
  file_path_ = path;
  return version;
}

void Document::AdoptContent(std::vector<DocObject> objects, std::string description,
                            std::optional<modeling::SceneSnap> snap,
                            std::vector<modeling::ScenePart> parts, std::optional<DocView> view,
                            const std::string& source) {
  // Ids and revisions in order; references arrive as index + 1 (document.h).
  const ObjectId first_id = next_id_;
  const std::uint64_t first_revision = next_revision_;
  std::vector<ObjectId> ids;
  for (DocObject& o : objects) {
    o.id = first_id + ids.size();
    o.revision = first_revision + ids.size();
    ids.push_back(o.id);
  }
  auto pointer = [](std::size_t i) { return "/objects/" + std::to_string(i); };
  for (std::size_t i = 0; i < objects.size(); ++i) {
    if (auto* m = std::get_if<MeshData>(&objects[i].data)) {
      const bool up_to_date = m->source_revision == 1;
      if (m->source != 0) {
        const std::size_t k = m->source - 1;
        m->source = ids.at(k);
        m->source_revision = up_to_date ? objects[k].revision : 0;
      } else {
        m->source_revision = 0;
      }
    }
    if (auto* f = std::get_if<FeModelData>(&objects[i].data)) f->tet_mesh = ids.at(f->tet_mesh - 1);
  }
  // Validate each object as a command adding it would: against the objects without a tree and
  // the trees before it (so that a repeated node id is reported at its second use).
  Document scratch;
  for (const DocObject& o : objects) {
    if (TreeOf(o) == nullptr) scratch.objects_.push_back(o);
  }
  for (std::size_t i = 0; i < objects.size(); ++i) {
    try {
      scratch.ValidateChange({objects[i]});
      if (TreeOf(objects[i]) != nullptr) scratch.objects_.push_back(objects[i]);
    } catch (const modeling::ModelError& e) {
      const std::string path = e.path();
      const std::size_t root = path.find("/root");
      throw modeling::SceneError(
          source, 0, 0,
          pointer(i) + (root == std::string::npos ? "" : path.substr(root)) + "/" + e.field(),
          e.what());
    } catch (const DocumentError& e) {
      throw modeling::SceneError(source, 0, 0, pointer(i), e.what());
    }
  }
  // Commit (nothing below throws).
  next_id_ = first_id + objects.size();
  next_revision_ = first_revision + objects.size();
  objects_ = std::move(objects);
  description_ = std::move(description);
  description_revision_ = NewRevision();
  snap_ = snap;
  snap_revision_ = NewRevision();
  view_ = std::move(view);
  device_.reset();
  parts_ = std::move(parts);
  history_->Clear();
  fe_cache_.clear();
  last_created_.clear();
  file_path_.clear();
  Touch();
  saved_signature_ = Signature();
}

void Document::LoadScene(const modeling::Scene& scene, const std::string& source) {
  // Node ids are unique within a scene (docs/scene-format.md); LoadScene checks each tree alone.
  std::map<std::string, int> owner;
  for (int s = 0; s < static_cast<int>(scene.solids.size()); ++s) {
    std::set<std::string> mine;
    NodePath path;
    ForEachNode(
        scene.solids[s].root, &path, [&](const modeling::ImplicitNode& n, const NodePath& p) {
          if (n.id.empty()) return;
          auto it = owner.find(n.id);
          if (it != owner.end() && it->second != s) {
            throw modeling::SceneError(
                source, 0, 0, "/solids/" + std::to_string(s) + "/root" + PathPointer(p) + "/id",
                "node id '" + n.id + "' is already used in solid " + std::to_string(it->second) +
                    " ('" + scene.solids[it->second].name + "'); ids must be unique in a scene");
          }
          owner.emplace(n.id, s);
        });
  }
  std::vector<DocObject> objects;
  for (const modeling::Solid& s : scene.solids) {
    DocObject o;
    o.id = NewObjectId();
    o.name = s.name;
    o.revision = NewRevision();
    o.data = SolidData{s.root};
    objects.push_back(std::move(o));
  }
  objects_ = std::move(objects);
  description_ = scene.description;
  description_revision_ = NewRevision();
  snap_ = scene.snap;
  snap_revision_ = NewRevision();
  view_.reset();
  device_.reset();
  parts_ = scene.parts;
  history_->Clear();
  fe_cache_.clear();
  last_created_.clear();
  file_path_.clear();
  Touch();
  saved_signature_ = Signature();
}

void Document::MarkRecovered(const std::string& original) {
  file_path_ = original;
  saved_signature_.clear();  // no content has an empty signature: dirty until saved
}

void Document::Save(const std::string& path) {
  const modeling::Scene scene = ToScene();
  // Parts name their solid: one renamed or deleted since the load would make a file that does
  // not load again.
  for (std::size_t i = 0; i < scene.parts.size(); ++i) {
    const modeling::ScenePart& part = scene.parts[i];
    const bool found = std::any_of(scene.solids.begin(), scene.solids.end(),
                                   [&](const modeling::Solid& s) { return s.name == part.solid; });
    if (!found) {
      throw modeling::SceneError(
          path, 0, 0, "/parts/" + std::to_string(i) + "/solid",
          "not saved: assembly part '" + part.name + "' is made of solid '" + part.solid +
              "', which is no longer in the scene; rename a solid back to '" + part.solid +
              "' or undo its deletion, then save again");
    }
  }
  WriteDocumentFile(*this, path);
  file_path_ = path;
  saved_signature_ = Signature();
}

void Document::Clear() {
  objects_.clear();
  description_.clear();
  description_revision_ = NewRevision();
  snap_.reset();
  snap_revision_ = NewRevision();
  view_.reset();
  device_.reset();
  parts_.clear();
  history_->Clear();
  fe_cache_.clear();
  last_created_.clear();
  file_path_.clear();
  Touch();
  saved_signature_ = Signature();
}

void Document::Execute(std::unique_ptr<Command> command) {
  last_created_.clear();
  history_->Execute(*this, std::move(command));
}

bool Document::Undo() {
  last_created_.clear();
  return history_->Undo(*this);
}

bool Document::Redo() {
  last_created_.clear();
  return history_->Redo(*this);
}

void Document::EndDrag() { history_->EndDrag(); }

void Document::SetFePrecomputation(ObjectId fe_model, std::any value) {
  const DocObject& o = Get(fe_model);
  if (!std::holds_alternative<FeModelData>(o.data))
    throw DocumentError(Describe(o) + " is not an FE model");
  // Keep one entry per object (the newest); entries of older revisions are dropped.
  std::erase_if(fe_cache_,
                [&](const CacheEntry& e) { return e.id == fe_model || Find(e.id) == nullptr; });
  fe_cache_.push_back({fe_model, o.revision, std::move(value)});
}

std::any Document::FePrecomputation(ObjectId fe_model) const {
  const DocObject* o = Find(fe_model);
  if (o == nullptr) return {};
  for (const CacheEntry& e : fe_cache_) {
    if (e.id == fe_model && e.revision == o->revision) return e.value;
  }
  return {};
}

void Document::ValidateChange(const std::vector<DocObject>& changed) const {
  // The document as it would be: changed objects replace their namesakes or are added.
  std::vector<const DocObject*> view;
  std::set<ObjectId> changed_ids;
  for (const DocObject& c : changed) changed_ids.insert(c.id);
  for (const DocObject& o : objects_) {
    if (!changed_ids.count(o.id)) view.push_back(&o);
  }
  for (const DocObject& c : changed) view.push_back(&c);
  auto find = [&](ObjectId id) -> const DocObject* {
    for (const DocObject* o : view) {
      if (o->id == id) return o;
    }
    return nullptr;
  };

  // Scene ids of the unchanged trees.
  std::map<std::string, const DocObject*> ids;
  for (const DocObject& o : objects_) {
    if (changed_ids.count(o.id)) continue;
    if (const modeling::ImplicitNode* root = TreeOf(o)) {
      NodePath path;
      ForEachNode(*root, &path, [&](const modeling::ImplicitNode& n, const NodePath&) {
        if (!n.id.empty()) ids.emplace(n.id, &o);
      });
    }
  }

  for (const DocObject& c : changed) {
    if (c.name.empty()) throw DocumentError(Describe(c) + ": the name must not be empty");
    std::visit(
        Overloaded{
            [&](const SolidData&) {},
            [&](const MeshData& m) {
              if (!m.surface && !m.volume)
                throw DocumentError(Describe(c) + " holds neither a surface nor a volume mesh");
              if (m.surface && !AllFinite(m.surface->vertices))
                throw DocumentError(Describe(c) + ": surface vertices must be finite");
              if (m.volume && !AllFinite(m.volume->nodes))
                throw DocumentError(Describe(c) + ": volume nodes must be finite");
              if (m.volume && m.volume->regions.size() != m.volume->tets.cols()) {
                throw DocumentError(Describe(c) + ": field 'volume/regions': " +
                                    std::to_string(m.volume->regions.size()) + " labels for " +
                                    std::to_string(m.volume->tets.cols()) + " tets");
              }
              const MeshSettings& s = m.settings;
              if (!(s.cell_size >= 0) || !(s.max_tet_volume >= 0) || !(s.max_radius_edge >= 0) ||
                  !std::isfinite(s.cell_size + s.max_tet_volume + s.max_radius_edge)) {
                throw DocumentError(Describe(c) +
                                    ": field 'settings': every setting must be finite and >= 0");
              }
              if (!s.mesher.empty() && s.mesher != "tetgen" && s.mesher != "cgal") {
                throw DocumentError(Describe(c) + ": field 'settings/mesher': \"" + s.mesher +
                                    "\" is not a mesher (expected tetgen or cgal)");
              }
            },
            [&](const FeModelData& f) {
              const DocObject* mesh = find(f.tet_mesh);
              const MeshData* md = mesh ? std::get_if<MeshData>(&mesh->data) : nullptr;
              if (md == nullptr || !md->volume) {
                throw DocumentError(Describe(c) + ": field 'tet_mesh': object " +
                                    std::to_string(f.tet_mesh) +
                                    " is not a mesh object with a volume mesh");
              }
              try {
                f.material.Validate();
              } catch (const std::invalid_argument& e) {
                throw DocumentError(Describe(c) + ": field 'material': " + e.what());
              }
              if (f.element_order != 1 && f.element_order != 2) {
                throw DocumentError(Describe(c) + ": field 'element_order' must be 1 or 2, got " +
                                    std::to_string(f.element_order));
              }
              std::set<int> regions;
              for (size_t k = 0; k < f.region_materials.size(); ++k) {
                const RegionMaterial& r = f.region_materials[k];
                if (!regions.insert(r.region).second) {
                  throw DocumentError(Describe(c) + ": field 'region_materials/" +
                                      std::to_string(k) + "': region " + std::to_string(r.region) +
                                      " is listed twice");
                }
                try {
                  r.material.Validate();
                } catch (const std::invalid_argument& e) {
                  throw DocumentError(Describe(c) + ": field 'region_materials/" +
                                      std::to_string(k) + "': " + e.what());
                }
              }
              for (size_t k = 0; k < f.loads.size(); ++k) {
                const FeLoad& l = f.loads[k];
                if (!l.force.allFinite() || !l.box.min().allFinite() || !l.box.max().allFinite() ||
                    (l.box.min().array() > l.box.max().array()).any()) {
                  throw DocumentError(Describe(c) + ": field 'loads/" + std::to_string(k) +
                                      "': needs a finite force and finite corners with min <= max");
                }
              }
              for (size_t b = 0; b < f.fixed_boxes.size(); ++b) {
                const auto& box = f.fixed_boxes[b];
                if (!box.min().allFinite() || !box.max().allFinite() ||
                    (box.min().array() > box.max().array()).any()) {
                  throw DocumentError(
                      Describe(c) + ": field 'fixed_boxes/" + std::to_string(b) +
                      "': needs finite corners with min <= max, got min (" +
                      FormatNumber(box.min().x()) + ", " + FormatNumber(box.min().y()) + ", " +
                      FormatNumber(box.min().z()) + ") max (" + FormatNumber(box.max().x()) + ", " +
                      FormatNumber(box.max().y()) + ", " + FormatNumber(box.max().z()) + ")");
                }
              }
            },
            [&](const SculptData& s) {
              if (!s.mesh) throw DocumentError(Describe(c) + " has no mesh");
              if (!AllFinite(s.mesh->vertices))
                throw DocumentError(Describe(c) + ": vertices must be finite");
              const int n = SculptVertexCount(*s.mesh);
              if (s.mesh->triangles.size() > 0 &&
                  (s.mesh->triangles.minCoeff() < 0 || s.mesh->triangles.maxCoeff() >= n)) {
                throw DocumentError(Describe(c) + ": a triangle refers to a vertex outside [0, " +
                                    std::to_string(n) + ")");
              }
            },
            [&](const RigidPartData& r) {
              if (!r.X_WP.matrix().allFinite())
                throw DocumentError(Describe(c) + ": field 'X_WP' must be finite");
              const Eigen::Matrix3d R = r.X_WP.linear();
              if (!(R.transpose() * R).isIdentity(1e-9) || R.determinant() < 0) {
                throw DocumentError(
                    Describe(c) +
                    ": field 'X_WP' must have a proper rotation (orthonormal, det +1)");
              }
              for (size_t k = 0; k < r.seats.size(); ++k) {
                const modeling::SceneSeat& seat = r.seats[k];
                if (seat.on.empty() || !seat.position.allFinite() ||
                    !seat.rotation.coeffs().allFinite() ||
                    std::abs(seat.rotation.norm() - 1.0) > 1e-6 ||
                    !(seat.position_tolerance >= 0) || !(seat.angle_tolerance >= 0)) {
                  throw DocumentError(Describe(c) + ": field 'seats/" + std::to_string(k) +
                                      "': needs a part name, a finite position, a unit quaternion "
                                      "and tolerances >= 0");
                }
              }
            },
        },
        c.data);
    if (const modeling::ImplicitNode* root = TreeOf(c)) {
      // Pointer as in a scene file for solids.
      std::string prefix;
      if (std::holds_alternative<SolidData>(c.data)) {
        int index = 0;
        for (const DocObject& o : objects_) {
          if (o.id == c.id) break;
          if (std::holds_alternative<SolidData>(o.data)) ++index;
        }
        prefix = "/solids/" + std::to_string(index) + "/root";
      } else {
        prefix = "/rigid_parts/" + c.name + "/root";
      }
      modeling::ValidateTree(*root, prefix);
      NodePath path;
      ForEachNode(*root, &path, [&](const modeling::ImplicitNode& n, const NodePath& p) {
        if (n.id.empty()) return;
        auto [it, inserted] = ids.emplace(n.id, &c);
        if (!inserted) {
          throw modeling::ModelError(prefix + PathPointer(p), "id",
                                     "node id '" + n.id + "' at " + prefix + PathPointer(p) +
                                         " of " + Describe(c) + " is already used by a node of " +
                                         Describe(*it->second) + "; ids must be unique in a scene");
        }
      });
    }
  }
}

void Document::RawInsert(int index, DocObject object) {
  if (index < 0 || index > static_cast<int>(objects_.size()))
    index = static_cast<int>(objects_.size());
  objects_.insert(objects_.begin() + index, std::move(object));
  Touch();
}

DocObject Document::RawErase(ObjectId id) {
  const int i = IndexOf(id);
  if (i < 0) throw DocumentError("no object with id " + std::to_string(id) + " in the document");
  DocObject o = std::move(objects_[i]);
  objects_.erase(objects_.begin() + i);
  Touch();
  return o;
}

void Document::RawReplace(DocObject object) {
  const int i = IndexOf(object.id);
  if (i < 0)
    throw DocumentError("no object with id " + std::to_string(object.id) + " in the document");
  objects_[i] = std::move(object);
  Touch();
}

DocObject& Document::RawMutable(ObjectId id) {
  const int i = IndexOf(id);
  if (i < 0) throw DocumentError("no object with id " + std::to_string(id) + " in the document");
  Touch();
  return objects_[i];
}

void Document::RawMove(ObjectId id, int index) {
  const int i = IndexOf(id);
  if (i < 0) throw DocumentError("no object with id " + std::to_string(id) + " in the document");
  index = std::clamp(index, 0, static_cast<int>(objects_.size()) - 1);
  DocObject o = std::move(objects_[i]);
  objects_.erase(objects_.begin() + i);
  objects_.insert(objects_.begin() + index, std::move(o));
  Touch();
}

void Document::RawSetSnap(std::optional<modeling::SceneSnap> snap, std::uint64_t revision) {
  snap_ = snap;
  snap_revision_ = revision;
  Touch();
}

void Document::RawSetDescription(std::string text, std::uint64_t revision) {
  description_ = std::move(text);
  description_revision_ = revision;
  Touch();
}

}  // namespace spidarcad::app
