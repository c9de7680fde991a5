// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
// The Document (ARCHITECTURE.md, "Document, commands, jobs"): every scene object of an editing
// session, each with a stable id and a name, plus the undo history.
//
// - Object ids are uint64, start at 1 and are never reused (an undone "add" followed by a new add
//   gets a new id; a redo brings the original id back).
// - Revisions: every object carries a content revision drawn from one document-wide counter. An
//   edit gives the object a fresh revision; undo and redo restore the revision the content had, so
//   equal revisions of an object mean equal content (a mesh made from revision r of a solid is up
//   to date whenever the solid is at r again, e.g. after undo). revision() of the Document itself
//   only grows: it changes on every change, including undo and redo (the UI re-meshes previews
//   when it moves).
// - Nodes of an implicit tree are addressed by (object id, NodePath): the child indices from the
//   root ({} is the root, {1, 0} the first child of the second child). Undo and redo restore the
//   tree exactly, so a path taken before an edit is valid again after the edit is undone.
//   FindNodeById maps a node's scene id (ImplicitNode::id) to its path.
// - The Document is changed only through commands (command.h): Execute, Undo, Redo. Reading is
//   free. Everything here belongs to the main thread.
#pragma once

#include <Eigen/Geometry>
#include <any>
#include <cstdint>
#include <memory>
#include <nlohmann/json.hpp>
#include <optional>
#include <stdexcept>
#include <string>
#include <utility>
#include <variant>
#include <vector>

#include "spidarcad/fem/material.h"
#include "spidarcad/haptics/geometry.h"
#include "spidarcad/modeling/implicit_node.h"
#include "spidarcad/modeling/scene_io.h"
#include "spidarcad/modeling/surface_mesher.h"
#include "spidarcad/modeling/tet_mesh.h"

namespace spidarcad::app {

class Command;
class History;

// Stable object id: > 0, unique within a Document, never reused.
using ObjectId = std::uint64_t;
// Location of a node in a tree: child indices from the root; {} is the root.
using NodePath = std::vector<int>;

// The mesh type of sculpt objects. Kept behind this alias and the three Sculpt* functions below so
// that the sculpt module's own type can replace it.
using SculptMesh = modeling::TriangleMesh;
// Number of vertices of a sculpt mesh.
int SculptVertexCount(const SculptMesh& mesh);
// Position (m) of vertex v.
Eigen::Vector3d SculptVertex(const SculptMesh& mesh, int v);
// Sets the position (m) of vertex v.
void SetSculptVertex(SculptMesh* mesh, int v, const Eigen::Vector3d& position);

// An implicit solid (a node tree).
struct SolidData {
  modeling::ImplicitNode root;
};
// How a mesh object was made from its source, kept so that it can be made again (0: the
// mesher's default).
struct MeshSettings {
  double cell_size = 0.0;        // surface grid cell edge, m (>= 0)
  double max_tet_volume = 0.0;   // largest tet volume, m³ (>= 0)
  double max_radius_edge = 0.0;  // TetGen radius-edge bound, -, (0 or >= 1)
  // Tetrahedral mesher: "" or "tetgen" (TetGen on the grid surface), "cgal" (CGAL Mesh_3 from
  // the solid's function; solids only).
  std::string mesher = {};
  bool sharp_edges = false;  // the grid surface was sharpened onto the solid's creases (TetGen)
  // Surface mesher: "" (marching tetrahedra on the grid, with its clean-up) or "lattice" (the
  // lattice route of `spidarcad mesh`, modeling::SurfaceMesher::kLattice; solids only).
  std::string surface_mesher = {};
  // Marching tetrahedra's flat faces coarsened: edges shorter than flat_cells × cell_size
  // collapsed where the surface is planar (modeling::SurfaceMeshSettings::flat_coarsen_cells,
  // in [0, 1]; 0: off). FE mode sets it for quadratic elements (kQuadraticFlatCells,
  // scene/fe_setup.h). Solids meshed by TetGen on the marching-tetrahedra surface only.
  double flat_cells = 0.0;
  // The planes x = slab_planes[k] (m, increasing) the tetrahedra were meshed in slabs between (FE
  // mode); empty: in one piece. FE mode factors such a mesh slab by slab (fem::SlabBlocks).
  std::vector<double> slab_planes = {};
  // The strips the slabs were cut into (modeling::SlabCut::strip_planes: per slab, planes across
  // slab_strip_axis, 1 = y or 2 = z, m, increasing); empty: none. FE mode factors each strip as a
  // block of its own in its slab's place (SlabFeMesh::piece_slab).
  int slab_strip_axis = 1;
  std::vector<std::vector<double>> slab_strips = {};
};
// Meshes made from another object (usually a solid) by a Job, or imported from a file. Either
// mesh may be absent. The data are immutable and shared between copies (undo snapshots,
// duplicates).
struct MeshData {
  ObjectId source = 0;                                    // object meshed (0: none)
  std::uint64_t source_revision = 0;                      // revision of the source that was meshed
  std::shared_ptr<const modeling::TriangleMesh> surface;  // boundary surface, or null
  std::shared_ptr<const modeling::TetMesh> volume;        // tetrahedra, or null
  MeshSettings settings;                                  // how it was meshed from source
  std::string import_source;  // file it was imported from (STL/OBJ/PLY/VTU), or ""
};
// A load of an FE model: the force spread evenly over the nodes inside a box.
struct FeLoad {
  Eigen::AlignedBox3d box;                          // m, closed
  Eigen::Vector3d force = Eigen::Vector3d::Zero();  // total force, N (W)
};
// A material for one region label of the tet mesh (overrides FeModelData::material there).
struct RegionMaterial {
  int region = 0;          // TetMesh::regions label
  fem::Material material;  // E [Pa], ν [-]
};
// A linear elastic FE model of a tet mesh. Its precomputation is cached outside the undo state
// (Document::SetFePrecomputation) and on disk under precompute_key (fem::PrecomputeCache).
struct FeModelData {
  ObjectId tet_mesh = 0;                         // a mesh object holding a volume mesh
  fem::Material material;                        // E [Pa], ν [-] (every region not listed below)
  std::vector<Eigen::AlignedBox3d> fixed_boxes;  // nodes inside any box (m, closed) are clamped
  std::vector<FeLoad> loads;                     // applied loads
  std::vector<RegionMaterial> region_materials;  // per-region materials (regions unique)
  int element_order = 1;                         // 1 (4-node) or 2 (10-node tets)
  std::uint64_t precompute_key = 0;              // fem::PrecomputeKey of its columns (0: none yet)
};
// A freeform sculpt mesh. Copy on write: strokes change it in place only when no undo snapshot
// shares it.
struct SculptData {
  std::shared_ptr<SculptMesh> mesh;
};
// A rigid part: an implicit solid (in its part frame P) placed in the world by X_WP, with the
// seats where it fits on other parts (SceneSeat::on names another rigid part object).
struct RigidPartData {
  modeling::ImplicitNode root;
  Eigen::Isometry3d X_WP = Eigen::Isometry3d::Identity();
  bool fixed = false;                      // true: never grasped (the base)
  std::vector<modeling::SceneSeat> seats;  // seats on other parts
};
// The camera of the window, saved with the document (not part of the undo state).
struct DocView {
  Eigen::Vector3d position = Eigen::Vector3d(0.5, -0.5, 0.4);  // eye, m (W)
  Eigen::Vector3d focal_point = Eigen::Vector3d::Zero();       // m (W)
  Eigen::Vector3d view_up = Eigen::Vector3d::UnitZ();          // unit
  double view_angle = 30.0;                                    // vertical field of view, degrees
};
// What an object is; the alternative held is its kind.
using ObjectData = std::variant<SolidData, MeshData, FeModelData, SculptData, RigidPartData>;

// One scene object.
struct DocObject {
  ObjectId id = 0;
  std::string name;
  std::uint64_t revision = 0;  // content revision (see the file comment)
  ObjectData data;
};

// Kind name of an object: "solid", "mesh", "fe_model", "sculpt", "rigid_part".
const char* ObjectKindName(const ObjectData& data);
// The implicit tree of a solid or rigid part; null for the other kinds.
const modeling::ImplicitNode* TreeOf(const DocObject& object);
// Mutable variant of TreeOf.
modeling::ImplicitNode* TreeOf(DocObject* object);
// Path as a JSON-pointer suffix, e.g. {1, 0} -> "/children/1/children/0" ({} -> "").
std::string PathPointer(const NodePath& path);

// A bad edit or lookup (unknown object id, bad path, wrong kind, invalid value): the message names
// the object, the node path or field, and the value. Tree values that ValidateTree rejects throw
// modeling::ModelError instead; bad JSON values throw modeling::SceneError.
class DocumentError : public std::invalid_argument {
 public:
  using std::invalid_argument::invalid_argument;
};

// The document: objects in display (and file) order, the undo history, the dirty flag.
class Document {
 public:
  // An empty, clean document with an empty history (default depth).
  Document();
  ~Document();
  Document(const Document&) = delete;
  Document& operator=(const Document&) = delete;

  // ---- reading ----
  // Every object, in order.
  const std::vector<DocObject>& objects() const { return objects_; }
  // The object with this id, or null.
  const DocObject* Find(ObjectId id) const;
  // The object with this id; throws DocumentError if there is none.
  const DocObject& Get(ObjectId id) const;
  // Position of the object in objects(), or -1.
  int IndexOf(ObjectId id) const;
  // First object with this name, or null.
  const DocObject* FindByName(const std::string& name) const;
  // The node at path in the tree of a solid or rigid part; throws DocumentError naming the object
  // and the path when the object has no tree or the path leads nowhere.
  const modeling::ImplicitNode& Node(ObjectId id, const NodePath& path) const;
  // Where the node with this scene id (ImplicitNode::id) is, or nullopt.
  std::optional<std::pair<ObjectId, NodePath>> FindNodeById(const std::string& node_id) const;
  // True when a node of any tree has this scene id.
  bool NodeIdUsed(const std::string& node_id) const;
  // True when a node of any tree has this name.
  bool NodeNameUsed(const std::string& name) const;
  // True for a mesh object whose source is gone or has changed since it was meshed.
  bool IsMeshOutOfDate(ObjectId mesh) const;
  // Free text description of the scene.
  const std::string& description() const { return description_; }
  // The scene's snap forces ("snap" of the scene file; edit::SetSnap changes them).
  const std::optional<modeling::SceneSnap>& snap() const { return snap_; }
  // The saved camera, if any.
  const std::optional<DocView>& view() const { return view_; }
  // Sets the camera saved with the document (not undoable; does not make the document dirty).
  void set_view(std::optional<DocView> view) { view_ = std::move(view); }
  // The SPIDAR-G frame the document was made for: frame half-sides a, b, c and pole
  // half-length d, m (the paper's Sec. 8 scales the frame to the task). Saved with the document;
  // none: the device's own. Not part of the undo state; loading or clearing resets it.
  const std::optional<haptics::SpidarGeometry>& device() const { return device_; }
  // Sets the device frame (validated by the caller: SpidarGeometry::Validate).
  void set_device(std::optional<haptics::SpidarGeometry> device) { device_ = device; }
  // The scene's assembly parts as loaded ("parts"; kept as they are, not editable here). Save
  // writes them back and refuses, naming the part, when one names a solid no longer in the scene.
  const std::vector<modeling::ScenePart>& parts() const { return parts_; }
  // Grows on every change (edit, undo, redo, load).
  std::uint64_t revision() const { return revision_; }
  // True when the content differs from the last Save or Load (undoing back to it clears it).
  bool dirty() const;
  // File of the last successful Load or Save ("" before).
  const std::string& file_path() const { return file_path_; }
  // Sets file_path() without reading or writing (content converted after a Load keeps its file).
  void set_file_path(std::string path) { file_path_ = std::move(path); }
  // Ids of the objects created by the last Execute or Redo (e.g. the new solid of an AddSolid).
  const std::vector<ObjectId>& last_created() const { return last_created_; }

  // The implicit solids as a scene (rigid parts, meshes, FE models and sculpt meshes are not part
  // of the scene format yet and are left out).
  modeling::Scene ToScene() const;
  // The whole content as JSON (every object with its data; meshes written in full), for tests
  // and debugging. Revisions are included only when asked.
  nlohmann::json ToJson(bool with_revisions = false) const;

  // ---- files (not undoable: they reset the history) ----
  // Replaces the content with a document file (docs/scene-format.md: version 1 scenes and
  // version 2 documents). Throws modeling::SceneError (file, line, pointer) and leaves the
  // document as it was when the file is bad, including node ids repeated across solids.
  // Returns the version read: 1 for a scene file, 2 for a document. The file is read and
  // parsed once.
  int Load(const std::string& path);
  // Replaces the content with the solids of a scene (source names it in errors).
  void LoadScene(const modeling::Scene& scene, const std::string& source = "<scene>");
  // Writes the document (temporary file renamed over path: version 1 when it holds only what a
  // version 1 scene can, else version 2) and marks the document clean. Throws
  // modeling::SceneError when the file cannot be written (then nothing changes).
  void Save(const std::string& path);
  // Replaces the whole content (objects get fresh ids and revisions in this order; references
  // between them are given as indices into `objects`, see document_io.h) after validating it.
  // Throws SceneError naming `source` and the object; the document is unchanged then.
  // Used by the file reader; clean afterwards, history cleared.
  void AdoptContent(std::vector<DocObject> objects, std::string description,
                    std::optional<modeling::SceneSnap> snap, std::vector<modeling::ScenePart> parts,
                    std::optional<DocView> view, const std::string& source);
  // Empties the document and its history; clean.
  void Clear();
  // After loading a recovery file (doc/autosave.h): the document takes its original's path
  // (`original`, "" for an untitled document) and counts as unsaved until the next Save.
  void MarkRecovered(const std::string& original);

  // ---- editing ----
  // Runs a command and records it for undo. A command that throws leaves the document exactly
  // as it was and is not recorded (the exception propagates). Clears the redo stack.
  void Execute(std::unique_ptr<Command> command);
  // Undoes the last command; false when there is none.
  bool Undo();
  // Redoes the last undone command; false when there is none.
  bool Redo();
  // Ends a drag: the next edit starts a new undo step even if it edits the same field.
  void EndDrag();
  // The undo history (descriptions for the Edit menu, depth).
  History& history() { return *history_; }
  // Read-only history.
  const History& history() const { return *history_; }

  // ---- FE precomputation cache (outside the undo state) ----
  // Stores a precomputation made from the FE model at its current revision.
  void SetFePrecomputation(ObjectId fe_model, std::any value);
  // The stored precomputation if it was made from the model's current revision, else empty.
  std::any FePrecomputation(ObjectId fe_model) const;

  // ---- used by commands only (command.cc): no undo record, no validation ----
  // A fresh object id.
  ObjectId NewObjectId() { return next_id_++; }
  // A fresh revision number.
  std::uint64_t NewRevision() { return next_revision_++; }
  // Checks objects about to be committed (replacing those with the same id, or new): trees valid
  // with ids unique across the document, FE models pointing at volume meshes, finite values.
  // Throws ModelError or DocumentError.
  void ValidateChange(const std::vector<DocObject>& changed) const;
  // Inserts at index (clamped; -1 appends).
  void RawInsert(int index, DocObject object);
  // Removes and returns the object.
  DocObject RawErase(ObjectId id);
  // Replaces the object with the same id.
  void RawReplace(DocObject object);
  // Mutable access (the caller must bump the revision itself).
  DocObject& RawMutable(ObjectId id);
  // Moves an object to index (clamped).
  void RawMove(ObjectId id, int index);
  // Sets the description with its revision tag.
  void RawSetDescription(std::string text, std::uint64_t revision);
  // Sets the snap forces with their revision tag.
  void RawSetSnap(std::optional<modeling::SceneSnap> snap, std::uint64_t revision);
  // Revision tag of the snap settings.
  std::uint64_t snap_revision() const { return snap_revision_; }
  // Revision tag of the description.
  std::uint64_t description_revision() const { return description_revision_; }
  // Records that an object was created (for last_created()).
  void NoteCreated(ObjectId id) { last_created_.push_back(id); }

 private:
  // (id, revision) of every object in order, plus the description's tag: equal signatures mean
  // equal content.
  std::vector<std::pair<ObjectId, std::uint64_t>> Signature() const;
  void Touch() { ++revision_; }

  std::vector<DocObject> objects_;
  std::string description_;
  std::uint64_t description_revision_ = 0;
  std::optional<modeling::SceneSnap> snap_;
  std::uint64_t snap_revision_ = 0;
  std::optional<DocView> view_;
  std::optional<haptics::SpidarGeometry> device_;
  std::vector<modeling::ScenePart> parts_;
  ObjectId next_id_ = 1;
  std::uint64_t next_revision_ = 1;
  std::uint64_t revision_ = 0;
  std::vector<std::pair<ObjectId, std::uint64_t>> saved_signature_;
  std::string file_path_;
  std::vector<ObjectId> last_created_;
  std::unique_ptr<History> history_;
  struct CacheEntry {
    ObjectId id;
    std::uint64_t revision;
    std::any value;
  };
  std::vector<CacheEntry> fe_cache_;
};

}  // namespace spidarcad::app
