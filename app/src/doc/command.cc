// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#include "doc/command.h"

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <functional>
#include <set>
#include <stdexcept>
#include <utility>

#include "doc/mesh_import.h"

namespace spidarcad::app {
namespace {

std::string Describe(const DocObject& object) {
  return std::string(ObjectKindName(object.data)) + " '" + object.name + "' (id " +
         std::to_string(object.id) + ")";
}

// ---- generic commands ----

// Edits copies of some objects at the first Do, validates them and commits; later Do and Undo
// swap the stored snapshots. Object ids and the object list are unchanged.
class ReplaceObjectsCommand : public Command {
 public:
  using EditFn = std::function<void(const Document&, std::vector<DocObject>&)>;
  ReplaceObjectsCommand(std::vector<ObjectId> ids, std::string description, EditFn edit,
                        std::string merge_key)
      : ids_(std::move(ids)),
        description_(std::move(description)),
        edit_(std::move(edit)),
        merge_key_(std::move(merge_key)) {}

  void Do(Document& doc) override {
    if (!done_) {
      std::vector<DocObject> copies;
      for (ObjectId id : ids_) copies.push_back(doc.Get(id));
      std::vector<DocObject> before = copies;
      edit_(doc, copies);
      for (size_t i = 0; i < copies.size(); ++i) {
        if (copies[i].id != ids_[i]) throw std::logic_error("an edit changed an object id");
      }
      doc.ValidateChange(copies);
      for (DocObject& c : copies) c.revision = doc.NewRevision();
      before_ = std::move(before);
      after_ = std::move(copies);
      done_ = true;
      edit_ = nullptr;
    }
    for (const DocObject& o : after_) doc.RawReplace(o);
  }
  void Undo(Document& doc) override {
    for (const DocObject& o : before_) doc.RawReplace(o);
  }
  std::string Description() const override { return description_; }
  bool MergeWith(Command& next) override {
    auto* n = dynamic_cast<ReplaceObjectsCommand*>(&next);
    if (n == nullptr || merge_key_.empty() || n->merge_key_ != merge_key_ || n->ids_ != ids_ ||
        !n->done_)
      return false;
    after_ = std::move(n->after_);
    return true;
  }

 private:
  std::vector<ObjectId> ids_;
  std::string description_;
  EditFn edit_;
  std::string merge_key_;
  bool done_ = false;
  std::vector<DocObject> before_, after_;
};

// Inserts an object made at the first Do; undo removes it.
class InsertObjectCommand : public Command {
 public:
  // Returns the object (id and revision are filled in afterwards) and its index (-1: end).
  using MakeFn = std::function<std::pair<int, DocObject>(const Document&)>;
  InsertObjectCommand(std::string description, MakeFn make)
      : description_(std::move(description)), make_(std::move(make)) {}

  void Do(Document& doc) override {
    if (!done_) {
      auto [index, object] = make_(doc);
      object.id = doc.NewObjectId();
      object.revision = doc.NewRevision();
      doc.ValidateChange({object});
      const int n = static_cast<int>(doc.objects().size());
      index_ = (index < 0 || index > n) ? n : index;
      object_ = std::move(object);
      done_ = true;
      make_ = nullptr;
    }
    doc.RawInsert(index_, object_);
    doc.NoteCreated(object_.id);
  }
  void Undo(Document& doc) override { doc.RawErase(object_.id); }
  std::string Description() const override { return description_; }

 private:
  std::string description_;
  MakeFn make_;
  bool done_ = false;
  int index_ = -1;
  DocObject object_;
};

// Removes one object; undo puts it back at its place.
class EraseObjectCommand : public Command {
 public:
  explicit EraseObjectCommand(ObjectId id) : id_(id) {}
  void Do(Document& doc) override {
    if (!done_) {
      index_ = doc.IndexOf(id_);
      if (index_ < 0)
        throw DocumentError("no object with id " + std::to_string(id_) + " in the document");
      description_ = "Delete " + doc.Get(id_).name;
      done_ = true;
    }
    object_ = doc.RawErase(id_);
  }
  void Undo(Document& doc) override { doc.RawInsert(index_, std::move(object_)); }
  std::string Description() const override { return description_; }

 private:
  ObjectId id_;
  bool done_ = false;
  int index_ = -1;
  std::string description_;
  DocObject object_;
};

// Deletes an object and the FE models that use it.
class DeleteObjectCommand : public Command {
 public:
  explicit DeleteObjectCommand(ObjectId id) : id_(id) {}
  void Do(Document& doc) override {
    if (!macro_) {
      const DocObject& object = doc.Get(id_);
      std::vector<std::unique_ptr<Command>> steps;
      for (const DocObject& o : doc.objects()) {
        const auto* fe = std::get_if<FeModelData>(&o.data);
        if (fe != nullptr && fe->tet_mesh == id_)
          steps.push_back(std::make_unique<EraseObjectCommand>(o.id));
      }
      steps.push_back(std::make_unique<EraseObjectCommand>(id_));
      auto macro = std::make_unique<MacroCommand>("Delete " + object.name, std::move(steps));
      macro->Do(doc);
      macro_ = std::move(macro);
      return;
    }
    macro_->Do(doc);
  }
  void Undo(Document& doc) override { macro_->Undo(doc); }
  std::string Description() const override { return macro_ ? macro_->Description() : "Delete"; }

 private:
  ObjectId id_;
  std::unique_ptr<MacroCommand> macro_;
};

// Moves an object in the list.
class MoveObjectCommand : public Command {
 public:
  MoveObjectCommand(ObjectId id, int index) : id_(id), index_(index) {}
  void Do(Document& doc) override {
    if (old_index_ < 0) {
      old_index_ = doc.IndexOf(id_);
      if (old_index_ < 0)
        throw DocumentError("no object with id " + std::to_string(id_) + " in the document");
      description_ = "Move " + doc.Get(id_).name;
    }
    doc.RawMove(id_, index_);
  }
  void Undo(Document& doc) override { doc.RawMove(id_, old_index_); }
  std::string Description() const override { return description_; }

 private:
  ObjectId id_;
  int index_;
  int old_index_ = -1;
  std::string description_;
};

// Sets the description.
class DescriptionCommand : public Command {
 public:
  explicit DescriptionCommand(std::string text) : new_text_(std::move(text)) {}
  void Do(Document& doc) override {
    if (new_revision_ == 0) {
      old_text_ = doc.description();
      old_revision_ = doc.description_revision();
      new_revision_ = doc.NewRevision();
    }
    doc.RawSetDescription(new_text_, new_revision_);
  }
  void Undo(Document& doc) override { doc.RawSetDescription(old_text_, old_revision_); }
  std::string Description() const override { return "Set description"; }

 private:
  std::string new_text_, old_text_;
  std::uint64_t old_revision_ = 0, new_revision_ = 0;
};

// Sets the snap forces.
class SnapCommand : public Command {
 public:
  explicit SnapCommand(std::optional<modeling::SceneSnap> snap) : new_(snap) {}
  void Do(Document& doc) override {
    if (new_revision_ == 0) {
      if (new_) {
        const modeling::SceneSnap& s = *new_;
        for (double v : {s.max_force, s.vertex_radius, s.edge_radius, s.face_radius}) {
          if (!(v > 0) || !std::isfinite(v)) {
            throw DocumentError(
                "snap: every field (max_force, vertex_radius, edge_radius, face_radius) must be > "
                "0 and finite");
          }
        }
      }
      old_ = doc.snap();
      old_revision_ = doc.snap_revision();
      new_revision_ = doc.NewRevision();
    }
    doc.RawSetSnap(new_, new_revision_);
  }
  void Undo(Document& doc) override { doc.RawSetSnap(old_, old_revision_); }
  std::string Description() const override {
    return new_ ? "Set snap forces" : "Remove snap forces";
  }

 private:
  std::optional<modeling::SceneSnap> new_, old_;
  std::uint64_t old_revision_ = 0, new_revision_ = 0;
};

// A sculpt stroke: old and new positions of the moved vertices only.
class SculptStrokeCommand : public Command {
 public:
  SculptStrokeCommand(ObjectId id, std::vector<int> vertices, Eigen::Matrix3Xd new_positions,
                      std::string description)
      : id_(id),
        vertices_(std::move(vertices)),
        new_(std::move(new_positions)),
        description_(description.empty() ? "Sculpt stroke" : std::move(description)) {}
  void Do(Document& doc) override {
    if (new_revision_ == 0) {
      const DocObject& object = doc.Get(id_);
      const auto* data = std::get_if<SculptData>(&object.data);
      if (data == nullptr || !data->mesh)
        throw DocumentError(Describe(object) + " is not a sculpt mesh");
      if (static_cast<Eigen::Index>(vertices_.size()) != new_.cols()) {
        throw DocumentError(Describe(object) + ": a stroke of " + std::to_string(vertices_.size()) +
                            " vertices got " + std::to_string(new_.cols()) + " positions");
      }
      if (!new_.allFinite())
        throw DocumentError(Describe(object) + ": stroke positions must be finite");
      const int n = SculptVertexCount(*data->mesh);
      std::set<int> seen;
      for (int v : vertices_) {
        if (v < 0 || v >= n) {
          throw DocumentError(Describe(object) + ": stroke vertex " + std::to_string(v) +
                              " is outside [0, " + std::to_string(n) + ")");
        }
        if (!seen.insert(v).second)
          throw DocumentError(Describe(object) + ": stroke lists vertex " + std::to_string(v) +
                              " twice");
      }
      old_.resize(3, new_.cols());
      for (size_t k = 0; k < vertices_.size(); ++k)
        old_.col(k) = SculptVertex(*data->mesh, vertices_[k]);
      old_revision_ = object.revision;
      new_revision_ = doc.NewRevision();
    }
    Apply(doc, new_, new_revision_);
  }
  void Undo(Document& doc) override { Apply(doc, old_, old_revision_); }
  std::string Description() const override { return description_; }

 private:
  void Apply(Document& doc, const Eigen::Matrix3Xd& positions, std::uint64_t revision) {
    DocObject& object = doc.RawMutable(id_);
    auto& mesh = std::get<SculptData>(object.data).mesh;
    // Copy on write: undo snapshots or duplicates may share the mesh.
    if (mesh.use_count() > 1) mesh = std::make_shared<SculptMesh>(*mesh);
    for (size_t k = 0; k < vertices_.size(); ++k)
      SetSculptVertex(mesh.get(), vertices_[k], positions.col(k));
    object.revision = revision;
  }

  ObjectId id_;
  std::vector<int> vertices_;
  Eigen::Matrix3Xd new_, old_;
  std::string description_;
  std::uint64_t old_revision_ = 0, new_revision_ = 0;
};

// ---- helpers for tree edits ----

modeling::ImplicitNode& TreeRoot(DocObject& object) {
  modeling::ImplicitNode* root = TreeOf(&object);
  if (root == nullptr) throw DocumentError(Describe(object) + " has no node tree");
  return *root;
}

modeling::ImplicitNode& NodeAt(const Document& doc, DocObject& object, const NodePath& path) {
  doc.Node(object.id, path);  // throws a message naming the object and path if it leads nowhere
  modeling::ImplicitNode* node = &TreeRoot(object);
  for (int i : path) node = &node->children[i];
  return *node;
}

std::string PathKey(ObjectId id, const NodePath& path) {
  return std::to_string(id) + ":" + PathPointer(path);
}

using TreeFn = std::function<void(const Document&, DocObject&)>;

std::unique_ptr<Command> EditObject(ObjectId id, std::string description, TreeFn f,
                                    std::string merge_key = {}) {
  return std::make_unique<ReplaceObjectsCommand>(
      std::vector<ObjectId>{id}, std::move(description),
      [f = std::move(f)](const Document& doc, std::vector<DocObject>& objects) {
        f(doc, objects[0]);
      },
      std::move(merge_key));
}

template <class T>
T& DataAs(DocObject& object, const char* what) {
  T* data = std::get_if<T>(&object.data);
  if (data == nullptr) throw DocumentError(Describe(object) + " is not " + what);
  return *data;
}

std::unique_ptr<Command> InsertConstant(std::string description, DocObject object, int index) {
  return std::make_unique<InsertObjectCommand>(
      std::move(description), [object = std::move(object), index](const Document&) {
        return std::make_pair(index, object);
      });
}

std::string FieldDescription(const std::string& field) {
  return field.empty() ? "Edit node" : "Set " + field;
}

}  // namespace

// ---- ImportMeshCommand ----

ImportMeshCommand::ImportMeshCommand(std::string name, std::string file,
                                     std::shared_ptr<const modeling::TriangleMesh> surface,
                                     std::shared_ptr<const modeling::TetMesh> volume)
    : name_(std::move(name)),
      file_(std::move(file)),
      surface_(std::move(surface)),
      volume_(std::move(volume)) {}

void ImportMeshCommand::Do(Document& doc) {
  if (insert_) {  // redo
    insert_->Do(doc);
    return;
  }
  DocObject o;
  o.name = UniqueObjectName(doc, name_);
  MeshData data;
  data.surface = surface_;
  data.volume = volume_;
  data.import_source = file_;
  o.data = std::move(data);
  std::string name = o.name;
  std::unique_ptr<Command> insert = InsertConstant("Import mesh " + name, std::move(o), -1);
  insert->Do(doc);  // validates; throws with the document unchanged
  insert_ = std::move(insert);
  name_ = std::move(name);
}

void ImportMeshCommand::Undo(Document& doc) { insert_->Undo(doc); }

// ---- MacroCommand ----

MacroCommand::MacroCommand(std::string description, std::vector<std::unique_ptr<Command>> commands)
    : description_(std::move(description)), commands_(std::move(commands)) {}

void MacroCommand::Do(Document& doc) {
  size_t done = 0;
  try {
    for (; done < commands_.size(); ++done) commands_[done]->Do(doc);
  } catch (...) {
    while (done > 0) commands_[--done]->Undo(doc);
    throw;
  }
}

void MacroCommand::Undo(Document& doc) {
  for (size_t i = commands_.size(); i > 0; --i) commands_[i - 1]->Undo(doc);
}

// ---- History ----

History::History(std::size_t max_depth) : max_depth_(std::max<std::size_t>(1, max_depth)) {}

void History::Execute(Document& doc, std::unique_ptr<Command> command) {
  if (!command) throw std::invalid_argument("History::Execute: null command");
  command->Do(doc);  // throws: nothing changed, nothing recorded
  redo_.clear();
  if (merge_open_ && !undo_.empty() && undo_.back()->MergeWith(*command)) return;
  undo_.push_back(std::move(command));
  merge_open_ = true;
  while (undo_.size() > max_depth_) undo_.pop_front();
}

bool History::Undo(Document& doc) {
  merge_open_ = false;
  if (undo_.empty()) return false;
  std::unique_ptr<Command> command = std::move(undo_.back());
  undo_.pop_back();
  command->Undo(doc);
  redo_.push_back(std::move(command));
  return true;
}

bool History::Redo(Document& doc) {
  merge_open_ = false;
  if (redo_.empty()) return false;
  std::unique_ptr<Command> command = std::move(redo_.back());
  redo_.pop_back();
  command->Do(doc);
  undo_.push_back(std::move(command));
  while (undo_.size() > max_depth_) undo_.pop_front();
  return true;
}

void History::Clear() {
  undo_.clear();
  redo_.clear();
  merge_open_ = false;
}

std::string History::UndoDescription() const {
  return undo_.empty() ? "" : undo_.back()->Description();
}
std::string History::RedoDescription() const {
  return redo_.empty() ? "" : redo_.back()->Description();
}

void History::set_max_depth(std::size_t depth) {
  max_depth_ = std::max<std::size_t>(1, depth);
  while (undo_.size() > max_depth_) undo_.pop_front();
}

// ---- uniqueness for paste and duplicate ----

void MakePastedTreeUnique(const Document& doc, modeling::ImplicitNode* root) {
  // Ids and names in use, gathered once (the document may hold thousands of nodes).
  std::set<std::string> ids, names;
  std::function<void(const modeling::ImplicitNode&)> gather =
      [&](const modeling::ImplicitNode& node) {
        if (!node.id.empty()) ids.insert(node.id);
        if (!node.name.empty()) names.insert(node.name);
        for (const modeling::ImplicitNode& c : node.children) gather(c);
      };
  for (const DocObject& o : doc.objects()) {
    if (const modeling::ImplicitNode* tree = TreeOf(o)) gather(*tree);
  }
  const std::set<std::string> doc_names = names;  // only names used in the document collide
  std::function<void(modeling::ImplicitNode*)> visit = [&](modeling::ImplicitNode* node) {
    if (!node->id.empty()) {
      std::string id = node->id;
      for (int k = 2; ids.count(id); ++k) id = node->id + "_" + std::to_string(k);
      node->id = id;
      ids.insert(id);
    }
    if (!node->name.empty() && doc_names.count(node->name)) {
      std::string name = node->name + " copy";
      for (int k = 2; doc_names.count(name); ++k) name = node->name + " copy " + std::to_string(k);
      node->name = name;
    }
    for (modeling::ImplicitNode& c : node->children) visit(&c);
  };
  visit(root);
}

std::string UniqueObjectName(const Document& doc, const std::string& name) {
  if (doc.FindByName(name) == nullptr) return name;
  std::string candidate = name + " copy";
  for (int k = 2; doc.FindByName(candidate) != nullptr; ++k)
    candidate = name + " copy " + std::to_string(k);
  return candidate;
}

// ---- factories ----

namespace edit {

std::unique_ptr<Command> AddSolid(std::string name, modeling::ImplicitNode root, int index) {
  DocObject o;
  o.name = name;
  o.data = SolidData{std::move(root)};
  return InsertConstant("Add solid " + name, std::move(o), index);
}

std::unique_ptr<Command> AddRigidPart(std::string name, modeling::ImplicitNode root,
                                      const Eigen::Isometry3d& X_WP) {
  DocObject o;
  o.name = name;
  RigidPartData part;
  part.root = std::move(root);
  part.X_WP = X_WP;
  o.data = std::move(part);
  return InsertConstant("Add rigid part " + name, std::move(o), -1);
}

std::unique_ptr<Command> AddMesh(std::string name, ObjectId source, std::uint64_t source_revision,
                                 std::shared_ptr<const modeling::TriangleMesh> surface,
                                 std::shared_ptr<const modeling::TetMesh> volume) {
  DocObject o;
  o.name = name;
  MeshData mesh;
  mesh.source = source;
  mesh.source_revision = source_revision;
  mesh.surface = std::move(surface);
  mesh.volume = std::move(volume);
  o.data = std::move(mesh);
  return InsertConstant("Add mesh " + name, std::move(o), -1);
}

std::unique_ptr<Command> ImportMesh(const std::string& path, std::string name) {
  const MeshData data = ReadMeshFile(path);  // InputError names the file; nothing made then
  if (name.empty()) name = std::filesystem::path(path).stem().string();
  if (name.empty()) name = "mesh";
  return std::make_unique<ImportMeshCommand>(std::move(name), path, data.surface, data.volume);
}

std::unique_ptr<Command> AddFeModel(std::string name, ObjectId tet_mesh,
                                    const fem::Material& material,
                                    std::vector<Eigen::AlignedBox3d> fixed_boxes,
                                    int element_order) {
  if (element_order != 1 && element_order != 2)
    throw DocumentError("add FE model " + name + ": element order " +
                        std::to_string(element_order) + " (expected 1 or 2)");
  DocObject o;
  o.name = name;
  FeModelData model;
  model.tet_mesh = tet_mesh;
  model.element_order = element_order;
  model.material = material;
  model.fixed_boxes = std::move(fixed_boxes);
  o.data = std::move(model);
  return InsertConstant("Add FE model " + name, std::move(o), -1);
}

std::unique_ptr<Command> AddSculpt(std::string name, SculptMesh mesh) {
  DocObject o;
  o.name = name;
  o.data = SculptData{std::make_shared<SculptMesh>(std::move(mesh))};
  return InsertConstant("Add sculpt " + name, std::move(o), -1);
}

std::unique_ptr<Command> DeleteObject(ObjectId id) {
  return std::make_unique<DeleteObjectCommand>(id);
}

std::unique_ptr<Command> RenameObject(ObjectId id, std::string name) {
  return EditObject(id, "Rename to " + name,
                    [name](const Document&, DocObject& o) { o.name = name; });
}

std::unique_ptr<Command> MoveObject(ObjectId id, int index) {
  return std::make_unique<MoveObjectCommand>(id, index);
}

std::unique_ptr<Command> DuplicateObject(ObjectId id) {
  return std::make_unique<InsertObjectCommand>("Duplicate", [id](const Document& doc) {
    DocObject copy = doc.Get(id);
    copy.name = UniqueObjectName(doc, copy.name);
    if (modeling::ImplicitNode* root = TreeOf(&copy)) MakePastedTreeUnique(doc, root);
    return std::make_pair(doc.IndexOf(id) + 1, std::move(copy));
  });
}

std::unique_ptr<Command> SetDescription(std::string text) {
  return std::make_unique<DescriptionCommand>(std::move(text));
}

std::unique_ptr<Command> AddObject(std::string name, ObjectData data, int index) {
  DocObject o;
  o.name = name;
  o.data = std::move(data);
  if (auto* s = std::get_if<SculptData>(&o.data)) {
    // A private copy, so that in-place strokes never reach the caller's mesh.
    if (s->mesh) s->mesh = std::make_shared<SculptMesh>(*s->mesh);
  }
  const std::string kind = ObjectKindName(o.data);
  return InsertConstant("Add " + kind + " " + name, std::move(o), index);
}

std::unique_ptr<Command> SetObjectData(ObjectId id, ObjectData data) {
  return EditObject(id, "Edit object", [data = std::move(data)](const Document&, DocObject& o) {
    if (data.index() != o.data.index()) {
      throw DocumentError(Describe(o) + ": new data of kind " + ObjectKindName(data) +
                          " does not match its kind");
    }
    o.data = data;
    if (auto* s = std::get_if<SculptData>(&o.data)) {
      if (s->mesh) s->mesh = std::make_shared<SculptMesh>(*s->mesh);
    }
  });
}

std::unique_ptr<Command> SetSnap(std::optional<modeling::SceneSnap> snap) {
  return std::make_unique<SnapCommand>(snap);
}

std::unique_ptr<Command> AddNode(ObjectId id, NodePath parent, int index,
                                 modeling::ImplicitNode node) {
  const std::string type = modeling::NodeTypeName(node.params);
  return EditObject(id, "Add " + type,
                    [parent = std::move(parent), index, node = std::move(node)](const Document& doc,
                                                                                DocObject& o) {
                      modeling::ImplicitNode& p = NodeAt(doc, o, parent);
                      const int n = static_cast<int>(p.children.size());
                      if (index > n || index < -1) {
                        throw DocumentError(Describe(o) + ": cannot insert a child at index " +
                                            std::to_string(index) + " of the node at '" +
                                            PathPointer(parent) + "', which has " +
                                            std::to_string(n) + " children");
                      }
                      p.children.insert(p.children.begin() + (index < 0 ? n : index), node);
                    });
}

std::unique_ptr<Command> WrapNode(ObjectId id, NodePath path, modeling::NodeParams params,
                                  std::string node_id, std::string name) {
  const std::string type = modeling::NodeTypeName(params);
  return EditObject(id, "Wrap in " + type,
                    [path = std::move(path), params = std::move(params), node_id, name](
                        const Document& doc, DocObject& o) {
                      modeling::ImplicitNode& target = NodeAt(doc, o, path);
                      modeling::ImplicitNode wrapper(params, {std::move(target)}, node_id);
                      wrapper.name = name;
                      target = std::move(wrapper);
                    });
}

std::unique_ptr<Command> DeleteNode(ObjectId id, NodePath path) {
  return EditObject(id, "Delete node", [path = std::move(path)](const Document& doc, DocObject& o) {
    if (path.empty())
      throw DocumentError(Describe(o) +
                          ": cannot delete the root node (delete the object instead)");
    NodeAt(doc, o, path);
    NodePath parent(path.begin(), path.end() - 1);
    modeling::ImplicitNode& p = NodeAt(doc, o, parent);
    p.children.erase(p.children.begin() + path.back());
  });
}

std::unique_ptr<Command> SetNodeParams(ObjectId id, NodePath path, modeling::NodeParams params,
                                       std::string field, bool dragging) {
  std::string key = dragging ? "params:" + PathKey(id, path) + ":" + field : "";
  return EditObject(
      id, FieldDescription(field),
      [path = std::move(path), params = std::move(params)](const Document& doc, DocObject& o) {
        NodeAt(doc, o, path).params = params;
      },
      std::move(key));
}

std::unique_ptr<Command> SetNodeField(ObjectId id, NodePath path, std::string field,
                                      nlohmann::json value, bool dragging) {
  std::string key = dragging ? "params:" + PathKey(id, path) + ":" + field : "";
  return EditObject(
      id, FieldDescription(field),
      [path = std::move(path), field, value = std::move(value)](const Document& doc, DocObject& o) {
        if (field == "children" || field == "type") {
          throw DocumentError(Describe(o) + ": field '" + field + "' of the node at '" +
                              PathPointer(path) +
                              "' cannot be set as a value (use the node commands)");
        }
        modeling::ImplicitNode& node = NodeAt(doc, o, path);
        nlohmann::json j = modeling::NodeToJson(node);
        j[field] = value;
        node = modeling::NodeFromJson(
            j, "/objects/" + std::to_string(o.id) + "/root" + PathPointer(path));
      },
      std::move(key));
}

std::unique_ptr<Command> SetNodeName(ObjectId id, NodePath path, std::string name) {
  return EditObject(id, "Rename node to " + name,
                    [path = std::move(path), name](const Document& doc, DocObject& o) {
                      NodeAt(doc, o, path).name = name;
                    });
}

std::unique_ptr<Command> MoveNode(ObjectId id, NodePath path, ObjectId dst_id, NodePath dst_parent,
                                  int index) {
  std::vector<ObjectId> ids{id};
  if (dst_id != id) ids.push_back(dst_id);
  return std::make_unique<ReplaceObjectsCommand>(
      ids, "Move node",
      [id, dst_id, path, dst_parent, index](const Document& doc, std::vector<DocObject>& objects) {
        DocObject& src = objects[0];
        DocObject& dst = dst_id == id ? objects[0] : objects[1];
        if (path.empty()) throw DocumentError(Describe(src) + ": cannot move the root node");
        NodeAt(doc, src, path);
        modeling::ImplicitNode& dst_parent_node = NodeAt(doc, dst, dst_parent);  // checks the path
        const int dst_n = static_cast<int>(dst_parent_node.children.size());
        if (index > dst_n || index < -1) {
          throw DocumentError(Describe(dst) + ": cannot insert a child at index " +
                              std::to_string(index) + " of the node at '" +
                              PathPointer(dst_parent) + "', which has " + std::to_string(dst_n) +
                              " children");
        }
        const NodePath parent(path.begin(), path.end() - 1);
        const int i = path.back();
        NodePath target = dst_parent;
        int at = index < 0 ? dst_n : index;
        if (dst_id == id) {
          if (target.size() >= path.size() &&
              std::equal(path.begin(), path.end(), target.begin())) {
            throw DocumentError(Describe(src) + ": cannot move the node at '" + PathPointer(path) +
                                "' into its own subtree at '" + PathPointer(dst_parent) + "'");
          }
          // Removing the node shifts its later siblings (and everything below them) down by one.
          if (target.size() > parent.size() &&
              std::equal(parent.begin(), parent.end(), target.begin()) &&
              target[parent.size()] > i) {
            --target[parent.size()];
          }
          if (target == parent && at > i) --at;
        }
        modeling::ImplicitNode& old_parent = NodeAt(doc, src, parent);
        modeling::ImplicitNode moved = std::move(old_parent.children[i]);
        old_parent.children.erase(old_parent.children.begin() + i);
        modeling::ImplicitNode* p = &TreeRoot(dst);
        for (int k : target) p = &p->children[k];
        p->children.insert(p->children.begin() + at, std::move(moved));
      },
      "");
}

std::unique_ptr<Command> ReorderNode(ObjectId id, NodePath path, int index) {
  return EditObject(
      id, "Reorder node", [path = std::move(path), index](const Document& doc, DocObject& o) {
        if (path.empty())
          throw DocumentError(Describe(o) + ": the root node has no siblings to reorder");
        NodeAt(doc, o, path);
        modeling::ImplicitNode& p = NodeAt(doc, o, NodePath(path.begin(), path.end() - 1));
        modeling::ImplicitNode moved = std::move(p.children[path.back()]);
        p.children.erase(p.children.begin() + path.back());
        const int at = std::clamp(index, 0, static_cast<int>(p.children.size()));
        p.children.insert(p.children.begin() + at, std::move(moved));
      });
}

std::unique_ptr<Command> ReplaceTree(ObjectId id, modeling::ImplicitNode root) {
  return EditObject(id, "Replace tree", [root = std::move(root)](const Document&, DocObject& o) {
    TreeRoot(o) = root;
  });
}

std::unique_ptr<Command> SetFeMaterial(ObjectId id, const fem::Material& material, bool dragging) {
  return EditObject(
      id, "Set material",
      [material](const Document&, DocObject& o) {
        DataAs<FeModelData>(o, "an FE model").material = material;
      },
      dragging ? "material:" + std::to_string(id) : "");
}

std::unique_ptr<Command> SetFixedBoxes(ObjectId id, std::vector<Eigen::AlignedBox3d> boxes) {
  return EditObject(id, "Set fixed region",
                    [boxes = std::move(boxes)](const Document&, DocObject& o) {
                      DataAs<FeModelData>(o, "an FE model").fixed_boxes = boxes;
                    });
}

std::unique_ptr<Command> SetFeLoads(ObjectId id, std::vector<FeLoad> loads) {
  return EditObject(id, "Set loads", [loads = std::move(loads)](const Document&, DocObject& o) {
    DataAs<FeModelData>(o, "an FE model").loads = loads;
  });
}

std::unique_ptr<Command> SetRegionMaterials(ObjectId id, std::vector<RegionMaterial> materials) {
  return EditObject(id, "Set region materials",
                    [materials = std::move(materials)](const Document&, DocObject& o) {
                      DataAs<FeModelData>(o, "an FE model").region_materials = materials;
                    });
}

std::unique_ptr<Command> SetElementOrder(ObjectId id, int order) {
  return EditObject(id, "Set element order", [order](const Document&, DocObject& o) {
    DataAs<FeModelData>(o, "an FE model").element_order = order;
  });
}

std::unique_ptr<Command> SetPrecomputeKey(ObjectId id, std::uint64_t key) {
  return EditObject(id, "Record precomputation", [key](const Document&, DocObject& o) {
    DataAs<FeModelData>(o, "an FE model").precompute_key = key;
  });
}

std::unique_ptr<Command> ReplaceSculptMesh(ObjectId id, SculptMesh mesh, std::string description) {
  auto shared = std::make_shared<SculptMesh>(std::move(mesh));
  if (description.empty()) description = "Replace sculpt mesh";
  return EditObject(id, description, [shared](const Document&, DocObject& o) {
    // A private copy, so that a later in-place stroke cannot reach the command's snapshot.
    DataAs<SculptData>(o, "a sculpt mesh").mesh = std::make_shared<SculptMesh>(*shared);
  });
}

std::unique_ptr<Command> SculptStroke(ObjectId id, std::vector<int> vertices,
                                      Eigen::Matrix3Xd new_positions, std::string description) {
  return std::make_unique<SculptStrokeCommand>(id, std::move(vertices), std::move(new_positions),
                                               std::move(description));
}

std::unique_ptr<Command> SetRigidPose(ObjectId id, const Eigen::Isometry3d& X_WP, bool dragging) {
  return EditObject(
      id, "Move part",
      [X_WP](const Document&, DocObject& o) {
        DataAs<RigidPartData>(o, "a rigid part").X_WP = X_WP;
      },
      dragging ? "pose:" + std::to_string(id) : "");
}

std::unique_ptr<Command> SetRigidFixed(ObjectId id, bool fixed) {
  return EditObject(id, fixed ? "Fix part" : "Free part", [fixed](const Document&, DocObject& o) {
    DataAs<RigidPartData>(o, "a rigid part").fixed = fixed;
  });
}

std::unique_ptr<Command> SetRigidSeats(ObjectId id, std::vector<modeling::SceneSeat> seats) {
  return EditObject(id, "Set seats", [seats = std::move(seats)](const Document&, DocObject& o) {
    DataAs<RigidPartData>(o, "a rigid part").seats = seats;
  });
}

}  // namespace edit
}  // namespace spidarcad::app
