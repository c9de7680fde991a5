// The tree panel of the workbench window: the scene's solids and their node trees, the other
// objects (meshes, FE models, sculpts, rigid parts; a mesh or FE model whose source changed since
// it was meshed is marked stale, with Refresh), the selected node's parameters, the editing
// buttons and the Edit menu (undo, redo, copy, paste, delete).
//
// TreeController holds the logic without any ImGui: it maps the panel's intents (select, edit a
// parameter, add, wrap, delete, rename, duplicate, copy, paste, undo, redo, save) to Document
// commands (doc/command.h, doc/clipboard.h) on the SceneModel's Document. Every intent either
// succeeds or leaves the Document exactly as it was and keeps the error text (what was wrong and
// at which node) for the panel to show next to that node. SceneModel::Refresh picks the edits up.
// DrawTreePanel and the menu/shortcut functions draw it with ImGui. Main thread only.
//
// Units: parameters are SI inside (m, rad); the panel shows lengths in mm and angles in degrees
// (DisplayScale).
// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#pragma once

#include <functional>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "doc/clipboard.h"
#include "doc/document.h"
#include "scene/scene_model.h"

namespace spidarcad::app {

// A node of a solid's tree: the Document object and the path from its root ({}: the root).
struct NodeRef {
  ObjectId object = 0;
  NodePath path;
  bool operator==(const NodeRef& other) const = default;
};

// How a node field is shown and edited.
enum class FieldUnit {
  kLength,  // m inside, mm shown
  kAngle,   // rad inside, degrees shown
  kCount,   // integer
  kFlag,    // bool
  kPlain,   // dimensionless (axes, normals, scale factors)
};

// The unit of a node field as the scene format names it ("radius" -> kLength, "angle" ->
// kAngle, "count" -> kCount, "keep_original" -> kFlag, "axis" -> kPlain, ...).
FieldUnit UnitOfField(const std::string& field);
// Factor from SI to the displayed value: 1000 for lengths (mm), 180/π for angles, else 1.
double DisplayScale(FieldUnit unit);
// Text of the displayed unit: "mm", "deg" or "".
const char* DisplayUnitText(FieldUnit unit);

// The primitive types the modeller has, by scene-format name ("sphere", "box", ...).
const std::vector<std::string>& PrimitiveTypeNames();
// The node types that take children (booleans, blends, offset/shell, transforms, arrays).
const std::vector<std::string>& OperationTypeNames();
// A node of type `type` (scene-format name) with default parameters (an extrusion gets a
// 40 mm square profile). Throws std::invalid_argument for an unknown type.
modeling::ImplicitNode DefaultNode(const std::string& type);
// Label of a node in the tree: its name, else its id, else its type; with the type appended
// when a name or id is shown ("lid (rounded_box)").
std::string NodeLabel(const modeling::ImplicitNode& node);

// Why object `id` is stale, or "" when it is not: a mesh object made from a source whose source
// changed since it was meshed ("'knob' changed since this mesh was made") or was deleted ("its
// source (object 3) was deleted"); an FE model whose mesh is stale ("its mesh 'knob tets' is
// stale: ..."). Solids, imported meshes, sculpts (edited copies: they keep no link to what they
// were copied from) and rigid parts are never stale.
std::string StaleReason(const Document& doc, ObjectId id);
// The mesh object Refresh meshes again for object `id`: the object itself when it is a mesh made
// from a source that still exists, the mesh of an FE model likewise; 0 otherwise.
ObjectId RefreshableMesh(const Document& doc, ObjectId id);

// The panel's logic on a SceneModel's Document (see the file comment).
class TreeController {
 public:
  // Works on `model` (which must outlive the controller).
  explicit TreeController(SceneModel* model);

  // ---- selection ----
  // Selects a node (not checked until used; Revalidate fixes stale selections).
  void Select(ObjectId object, NodePath path = {});
  // Selects the first solid (or rigid part) whose name is `name`, else the first node (of any
  // solid) whose name or id is `name`, else the first other object (a mesh, FE model, sculpt)
  // of that name; "OBJECT/i/j" selects child j of child i of that object's root.
  // Returns false (selection unchanged) when there is none.
  bool SelectByName(const std::string& name);
  // Clears the selection.
  void ClearSelection() { selected_.reset(); }
  // The selected node, if any.
  const std::optional<NodeRef>& selection() const { return selected_; }
  // The selected node of the Document, or null when nothing (valid) is selected.
  const modeling::ImplicitNode* SelectedNode() const;
  // After undo, redo, delete or reload: a selection whose path leads nowhere moves up to the
  // nearest existing ancestor; one whose object is gone is cleared; an object without a tree
  // (mesh, FE model, sculpt) stays selected as a whole (path {}).
  void Revalidate();

  // ---- edits (true on success; false: nothing changed, error() says why) ----
  // Sets one field of the selected node from its SI value as the scene format spells it
  // (SetNodeField). With `dragging`, consecutive edits of the same field merge into one undo
  // step until EndDrag.
  bool SetField(const std::string& field, const nlohmann::json& value_si, bool dragging = false);
  // Ends a drag (the slider was released).
  void EndDrag();
  // Adds a primitive of `type`: as the last child of the selected node, or (as_new_solid, or
  // nothing selected) as a new solid named after the type. Selects the new node.
  bool AddPrimitive(const std::string& type, bool as_new_solid);
  // Wraps the selected node in a new operation or transform node of `type` (a difference gets a
  // default sphere as the part subtracted, in the same undo step). Selects the new node.
  bool Wrap(const std::string& type);
  // Deletes the selected node with its subtree, or the whole object when the root (or an object
  // without a tree: a mesh, FE model, sculpt) is selected.
  bool DeleteSelected();
  // Asks for the selected object to be meshed again from its source (RefreshableMesh); the window
  // starts the Job (SceneModel::StartRefreshJob), which lands as one undo step. False, with
  // error(), when the selection has nothing to refresh.
  bool RequestRefresh();
  // The object whose Refresh was asked for (0: none); cleared.
  ObjectId TakeRefreshRequest() { return std::exchange(refresh_request_, 0); }
  // Renames the selected object (root selected) or node.
  bool RenameSelected(const std::string& name);
  // Duplicates the selected object (DuplicateObject) and selects the copy.
  bool DuplicateSelected();
  // Copies the selection to the clipboard: the whole solid when the root is selected, else the
  // subtree.
  bool Copy();
  // Pastes: a copied solid as a new object; a subtree as the last child of the selected node
  // (or of its parent when the selected node is a primitive), or as a new object when nothing
  // is selected. Selects what was pasted.
  bool Paste();
  // Undo / redo the last step; false when there was nothing to undo / redo, or when the history
  // hold says to wait (error() then says why and nothing changes).
  bool Undo();
  bool Redo();
  // Asked before every undo and redo: why they must wait ("let go of part 'x' first"), or ""
  // when they may run. The window passes its active mode's Mode::HistoryHold.
  void set_history_hold(std::function<std::string()> hold) { history_hold_ = std::move(hold); }
  // Saves to `path` ("" -> the Document's file). False with error() when there is no file yet
  // or writing failed.
  bool Save(const std::string& path = "");

  // ---- state for the panel ----
  // Error of the last failed intent ("" after a success).
  const std::string& error() const { return error_; }
  // The node the error is about (where the panel shows it), if any.
  const std::optional<NodeRef>& error_at() const { return error_at_; }
  // Short text of the last success ("Pasted 'knob copy'", "Saved ..."), for the status line.
  const std::string& message() const { return message_; }
  // Window title: "spidarcad — <file or scene name>" with a leading "*" when dirty.
  std::string Title() const;
  // The clipboard (the window mirrors it to the system clipboard).
  Clipboard& clipboard() { return clipboard_; }
  // The model and its Document.
  SceneModel& model() { return *model_; }
  Document& document() { return model_->document(); }

 private:
  // Runs `edit`; on an exception records the error at `where` and returns false.
  template <typename Edit>
  bool Try(const std::optional<NodeRef>& where, Edit&& edit);
  // True when a valid node is selected; else sets the error.
  bool NeedSelection(const char* what);
  // True (with the error set) when the history hold says undo and redo must wait.
  bool HistoryHeld(const char* what);

  SceneModel* model_;
  Clipboard clipboard_;
  std::optional<NodeRef> selected_;
  std::string error_;
  std::optional<NodeRef> error_at_;
  std::string message_;
  std::function<std::string()> history_hold_;
  ObjectId refresh_request_ = 0;
};

// UI state of the tree panel across frames.
struct TreePanelState {
  char rename[128] = "";                   // text of the rename field
  std::optional<NodeRef> rename_for;       // selection the rename field was filled for
  bool open_save_as = false;               // request to open the Save As dialog this frame
  char save_path[512] = "";                // path field of the Save As dialog
  std::optional<NodeRef> drawn_selection;  // selection when the tree was last drawn
  bool clicked = false;  // the selection changed by a click in the tree (no scrolling)
  // An edit asked for from a node's context menu while the tree was being drawn; run after the
  // tree is drawn (an edit then would change the nodes being iterated).
  std::function<void(TreeController*)> pending;
};

// Draws the tree (objects and nodes, click to select, right-click menu), the selected node's
// parameters (mm / degrees; drags merge into one undo step), the add/wrap/delete/rename/
// duplicate buttons and the last error next to its node. `tree_height` bounds the scrolling tree
// region in pixels. Call inside an ImGui window.
void DrawTreePanel(TreeController* tree, TreePanelState* state, float tree_height);
// Draws the Edit menu items (Undo, Redo, Copy, Paste, Delete) inside an open menu.
void DrawEditMenuItems(TreeController* tree);
// Draws File → Save / Save As items inside an open menu.
void DrawSaveMenuItems(TreeController* tree, TreePanelState* state);
// The Save As dialog (a path field), opened by DrawSaveMenuItems or Ctrl+Shift+S.
void DrawSaveAsDialog(TreeController* tree, TreePanelState* state);
// Keyboard shortcuts when no text field has the keyboard: Ctrl+Z undo, Ctrl+Y / Ctrl+Shift+Z
// redo, Ctrl+C copy, Ctrl+V paste, Delete, Ctrl+S save, Ctrl+Shift+S save as.
void HandleTreeShortcuts(TreeController* tree, TreePanelState* state);

}  // namespace spidarcad::app
