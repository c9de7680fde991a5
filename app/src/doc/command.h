// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
// Commands and the undo history. Every change to a Document is a Command run through
// Document::Execute; the factories in namespace `edit` make one for each kind of edit.
//
// Contract of a Command:
// - The first Do computes the edit from the document as it is, validates the result and commits
//   it; if anything is wrong it throws (ModelError, SceneError or DocumentError naming the
//   object, node and field) and the document is exactly as it was (strong guarantee).
// - Undo restores the state before Do exactly (content and revisions); a later Do (redo) restores
//   the state after the first Do exactly. History calls them in stack order only.
//
// Drags: an edit made with `dragging = true` merges into the previous undo step when that step
// is a dragging edit of the same field of the same node (or object), with no EndDrag, undo, redo
// or other command in between. Call Document::EndDrag() when the slider is released.
#pragma once

#include <Eigen/Geometry>
#include <cstddef>
#include <deque>
#include <memory>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <vector>

#include "doc/document.h"

namespace spidarcad::app {

// One undoable edit.
class Command {
 public:
  virtual ~Command() = default;
  // Applies the edit (see the file comment for the guarantees).
  virtual void Do(Document& doc) = 0;
  // Reverts the edit.
  virtual void Undo(Document& doc) = 0;
  // Text for the Edit menu without the verb "Undo": e.g. "Set radius".
  virtual std::string Description() const = 0;
  // Absorbs `next` (already done) into this command when both are parts of one drag; returns
  // whether it did. After a merge, Undo of this command reverts both.
  virtual bool MergeWith(Command& next) { return false; }
};

// Several commands as one undo step, done in order and undone in reverse. If one throws, those
// already done are undone before the exception propagates.
class MacroCommand : public Command {
 public:
  // A macro with this Edit-menu text.
  MacroCommand(std::string description, std::vector<std::unique_ptr<Command>> commands);
  void Do(Document& doc) override;
  void Undo(Document& doc) override;
  std::string Description() const override { return description_; }

 private:
  std::string description_;
  std::vector<std::unique_ptr<Command>> commands_;
};

// Undo and redo stacks with a bounded depth and drag merging.
class History {
 public:
  // Keeps at most max_depth undo steps (the oldest are dropped); max_depth >= 1.
  explicit History(std::size_t max_depth = 1000);

  // Does the command on doc and pushes it (or merges it into the top step); clears redo. A
  // command that throws is not pushed and the redo stack is kept.
  void Execute(Document& doc, std::unique_ptr<Command> command);
  // Undoes the top step; false when there is none.
  bool Undo(Document& doc);
  // Redoes the last undone step; false when there is none.
  bool Redo(Document& doc);
  // Closes the current drag (no merge into the top step from now on).
  void EndDrag() { merge_open_ = false; }
  // Drops every step.
  void Clear();

  // True when there is something to undo.
  bool CanUndo() const { return !undo_.empty(); }
  // True when there is something to redo.
  bool CanRedo() const { return !redo_.empty(); }
  // Description of the step Undo would revert ("" when none).
  std::string UndoDescription() const;
  // Description of the step Redo would redo ("" when none).
  std::string RedoDescription() const;
  // Number of undo steps.
  std::size_t undo_size() const { return undo_.size(); }
  // Number of redo steps.
  std::size_t redo_size() const { return redo_.size(); }
  // Maximum number of undo steps kept.
  std::size_t max_depth() const { return max_depth_; }
  // Changes the depth (drops the oldest steps beyond it); >= 1.
  void set_max_depth(std::size_t depth);

 private:
  std::size_t max_depth_;
  std::deque<std::unique_ptr<Command>> undo_;
  std::vector<std::unique_ptr<Command>> redo_;
  bool merge_open_ = false;
};

// Adds a mesh read from a file (an STL/OBJ/PLY surface, VTU or TetGen tetrahedra) as a mesh
// object with no source and import_source = `file`. At least one of surface and volume must be
// non-null (else Do throws DocumentError). The object gets `name`, made unique in the document
// at the first Do (UniqueObjectName: "part", "part copy", ...). Its id is in doc.last_created().
class ImportMeshCommand : public Command {
 public:
  ImportMeshCommand(std::string name, std::string file,
                    std::shared_ptr<const modeling::TriangleMesh> surface,
                    std::shared_ptr<const modeling::TetMesh> volume);
  void Do(Document& doc) override;
  void Undo(Document& doc) override;
  std::string Description() const override { return "Import mesh " + name_; }

 private:
  std::string name_, file_;
  std::shared_ptr<const modeling::TriangleMesh> surface_;
  std::shared_ptr<const modeling::TetMesh> volume_;
  std::unique_ptr<Command> insert_;  // the insertion, fixed at the first Do
};

// Factories for every edit. None touches the document until the command is executed.
namespace edit {

// ---- objects ----
// Adds an implicit solid at index (-1: at the end). The new id is in doc.last_created().
std::unique_ptr<Command> AddSolid(std::string name, modeling::ImplicitNode root, int index = -1);
// Adds a rigid part: the solid `root` in its frame P, placed by X_WP.
std::unique_ptr<Command> AddRigidPart(std::string name, modeling::ImplicitNode root,
                                      const Eigen::Isometry3d& X_WP);
// Adds a mesh object made from `source` at `source_revision` (how a meshing Job's result lands).
// At least one of surface and volume must be non-null.
std::unique_ptr<Command> AddMesh(std::string name, ObjectId source, std::uint64_t source_revision,
                                 std::shared_ptr<const modeling::TriangleMesh> surface,
                                 std::shared_ptr<const modeling::TetMesh> volume);
// Imports a mesh file as a new mesh object named `name` ("" -> the file's stem): a surface from
// STL, OBJ or PLY, tetrahedra from VTU or TetGen .node (+ .ele), import_source = path
// (doc/mesh_import.h). The file is read here, before the document is touched: a bad file throws
// InputError naming the file, line or byte and field, and no command is made.
std::unique_ptr<Command> ImportMesh(const std::string& path, std::string name = {});
// Adds an FE model of the volume mesh held by mesh object tet_mesh, with elements of
// `element_order` (1 linear, 2 quadratic).
std::unique_ptr<Command> AddFeModel(std::string name, ObjectId tet_mesh,
                                    const fem::Material& material,
                                    std::vector<Eigen::AlignedBox3d> fixed_boxes,
                                    int element_order = 1);
// Adds a sculpt object holding a copy of mesh.
std::unique_ptr<Command> AddSculpt(std::string name, SculptMesh mesh);
// Deletes an object; deleting a mesh also deletes the FE models built on it (one undo step).
std::unique_ptr<Command> DeleteObject(ObjectId id);
// Renames an object (any non-empty name).
std::unique_ptr<Command> RenameObject(ObjectId id, std::string name);
// Moves an object to position index in the object list (clamped).
std::unique_ptr<Command> MoveObject(ObjectId id, int index);
// Inserts a copy of an object right after it: name gets " copy", node ids are made unique, mesh
// data are shared (they are immutable). The copy's id is in doc.last_created().
std::unique_ptr<Command> DuplicateObject(ObjectId id);
// Sets the scene description.
std::unique_ptr<Command> SetDescription(std::string text);
// Adds an object of any kind at index (-1: at the end); the new id is in doc.last_created().
std::unique_ptr<Command> AddObject(std::string name, ObjectData data, int index = -1);
// Replaces the data of an object by data of the same kind (e.g. a re-meshed mesh object).
std::unique_ptr<Command> SetObjectData(ObjectId id, ObjectData data);
// Sets (or, with nullopt, removes) the snap forces; every field > 0 and finite.
std::unique_ptr<Command> SetSnap(std::optional<modeling::SceneSnap> snap);

// ---- nodes of a solid's or rigid part's tree ----
// Inserts `node` (a subtree) as child `index` of the node at parent (-1: last child). Its ids
// must not be used elsewhere in the document (paste renames them, this does not).
std::unique_ptr<Command> AddNode(ObjectId id, NodePath parent, int index,
                                 modeling::ImplicitNode node);
// Replaces the node at path by a new node with `params` (an operation or transform) whose only
// child is the old node: e.g. wrap a sphere in a translate. The new node gets `node_id`/`name`.
std::unique_ptr<Command> WrapNode(ObjectId id, NodePath path, modeling::NodeParams params,
                                  std::string node_id = {}, std::string name = {});
// Deletes the node at path with its subtree (path must not be the root: delete the object).
std::unique_ptr<Command> DeleteNode(ObjectId id, NodePath path);
// Replaces the parameters of the node at path (the type may change if the children still fit).
// `field` names what changed ("radius"; "" for several) and keys drag merging.
std::unique_ptr<Command> SetNodeParams(ObjectId id, NodePath path, modeling::NodeParams params,
                                       std::string field = {}, bool dragging = false);
// Sets one field of the node at path from a JSON value, as the scene format spells it
// (docs/scene-format.md): e.g. ("radius", 0.02), ("size", [0.1, 0.2, 0.3]), ("id", "knob").
// "children" and "type" cannot be set this way.
std::unique_ptr<Command> SetNodeField(ObjectId id, NodePath path, std::string field,
                                      nlohmann::json value, bool dragging = false);
// Sets the human-readable name of the node at path.
std::unique_ptr<Command> SetNodeName(ObjectId id, NodePath path, std::string name);
// Moves the subtree at `path` of object `id` to become child `index` (-1: last) of the node at
// dst_parent of object dst_id. dst_parent and index are read in the trees as they are BEFORE
// the move (what the user pointed at); moving a node into its own subtree is an error.
std::unique_ptr<Command> MoveNode(ObjectId id, NodePath path, ObjectId dst_id, NodePath dst_parent,
                                  int index);
// Moves the node at path to position index among its siblings (index counts in the list
// without the node; clamped).
std::unique_ptr<Command> ReorderNode(ObjectId id, NodePath path, int index);
// Replaces a whole tree.
std::unique_ptr<Command> ReplaceTree(ObjectId id, modeling::ImplicitNode root);

// ---- FE models ----
// Sets the material (validated by fem::Material::Validate).
std::unique_ptr<Command> SetFeMaterial(ObjectId id, const fem::Material& material,
                                       bool dragging = false);
// Sets the boxes of clamped nodes (each finite, min <= max).
std::unique_ptr<Command> SetFixedBoxes(ObjectId id, std::vector<Eigen::AlignedBox3d> boxes);
// Sets the loads (boxes with a total force each).
std::unique_ptr<Command> SetFeLoads(ObjectId id, std::vector<FeLoad> loads);
// Sets the per-region materials (regions unique, each material valid).
std::unique_ptr<Command> SetRegionMaterials(ObjectId id, std::vector<RegionMaterial> materials);
// Sets the element order (1 or 2).
std::unique_ptr<Command> SetElementOrder(ObjectId id, int order);
// Records the disk cache key of the model's precomputation (fem::PrecomputeKey).
std::unique_ptr<Command> SetPrecomputeKey(ObjectId id, std::uint64_t key);

// ---- sculpt meshes ----
// Replaces the whole mesh (after a topology change or a remesh). `description` is the Edit-menu
// text ("" -> "Replace sculpt mesh").
std::unique_ptr<Command> ReplaceSculptMesh(ObjectId id, SculptMesh mesh,
                                           std::string description = {});
// One stroke: moves the listed vertices to new_positions (3 by #indices, m). Stores only the old
// and new positions of those vertices. `description` is the Edit-menu text ("" -> "Sculpt
// stroke").
std::unique_ptr<Command> SculptStroke(ObjectId id, std::vector<int> vertices,
                                      Eigen::Matrix3Xd new_positions, std::string description = {});

// ---- rigid parts ----
// Sets the pose X_WP (rotation must be orthonormal).
std::unique_ptr<Command> SetRigidPose(ObjectId id, const Eigen::Isometry3d& X_WP,
                                      bool dragging = false);
// Sets whether the part is fixed (never grasped).
std::unique_ptr<Command> SetRigidFixed(ObjectId id, bool fixed);
// Sets the seats of a part (each names another rigid part).
std::unique_ptr<Command> SetRigidSeats(ObjectId id, std::vector<modeling::SceneSeat> seats);

}  // namespace edit

// Gives every non-empty node id of `root` that is used elsewhere in doc (or repeated inside root)
// a free one ("knob" -> "knob_2", "knob_3", ...), and " copy" to node names already used in doc
// ("lid" -> "lid copy", "lid copy 2", ...). Used by paste and duplicate.
void MakePastedTreeUnique(const Document& doc, modeling::ImplicitNode* root);
// name, or name + " copy", " copy 2", ... the first that no object of doc has.
std::string UniqueObjectName(const Document& doc, const std::string& name);

}  // namespace spidarcad::app
