// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#include "gui/tree_panel.h"

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <numbers>
#include <sstream>
#include <stdexcept>
#include <utility>
#include <variant>

#define GLFW_INCLUDE_NONE
#include <GLFW/glfw3.h>
#include <imgui.h>

#include "doc/command.h"
#include "spidarcad/modeling/scene_io.h"

namespace spidarcad::app {

namespace {

// Fills `out` with one default node per alternative of NodeParams, in variant order.
template <std::size_t... I>
std::vector<modeling::NodeParams> AllDefaultParams(std::index_sequence<I...>) {
  return {modeling::NodeParams(std::in_place_index<I>)...};
}

const std::vector<modeling::NodeParams>& DefaultParamsOfEveryType() {
  static const std::vector<modeling::NodeParams> all =
      AllDefaultParams(std::make_index_sequence<std::variant_size_v<modeling::NodeParams>>());
  return all;
}

std::vector<std::string> TypeNames(bool primitives) {
  std::vector<std::string> names;
  for (const modeling::NodeParams& p : DefaultParamsOfEveryType()) {
    if (modeling::IsPrimitive(p) == primitives) names.emplace_back(modeling::NodeTypeName(p));
  }
  return names;
}

// The node at `path` below `root`, or null when the path leads nowhere.
const modeling::ImplicitNode* Walk(const modeling::ImplicitNode& root, const NodePath& path) {
  const modeling::ImplicitNode* node = &root;
  for (int i : path) {
    if (i < 0 || i >= static_cast<int>(node->children.size())) return nullptr;
    node = &node->children[i];
  }
  return node;
}

}  // namespace

FieldUnit UnitOfField(const std::string& field) {
  if (field == "angle" || field == "step_angle") return FieldUnit::kAngle;
  if (field == "count") return FieldUnit::kCount;
  if (field == "keep_original") return FieldUnit::kFlag;
  if (field == "axis" || field == "normal" || field == "factors") return FieldUnit::kPlain;
  // radius, size, height, a, b, radius_bottom, radius_top, major_radius, minor_radius, offset,
  // profile, distance, thickness, translation, step: metres.
  return FieldUnit::kLength;
}

double DisplayScale(FieldUnit unit) {
  switch (unit) {
    case FieldUnit::kLength:
      return 1e3;
    case FieldUnit::kAngle:
      return 180.0 / std::numbers::pi;
    default:
      return 1.0;
  }
}

const char* DisplayUnitText(FieldUnit unit) {
  switch (unit) {
    case FieldUnit::kLength:
      return "mm";
    case FieldUnit::kAngle:
      return "deg";
    default:
      return "";
  }
}

const std::vector<std::string>& PrimitiveTypeNames() {
  static const std::vector<std::string> names = TypeNames(true);
  return names;
}

const std::vector<std::string>& OperationTypeNames() {
  static const std::vector<std::string> names = TypeNames(false);
  return names;
}

modeling::ImplicitNode DefaultNode(const std::string& type) {
  for (const modeling::NodeParams& p : DefaultParamsOfEveryType()) {
    if (type != modeling::NodeTypeName(p)) continue;
    modeling::ImplicitNode node(p);
    if (auto* e = std::get_if<modeling::ExtrusionParams>(&node.params)) {
      e->profile = {{-0.02, -0.02}, {0.02, -0.02}, {0.02, 0.02}, {-0.02, 0.02}};
      e->height = 0.02;
    }
    return node;
  }
  throw std::invalid_argument("unknown node type '" + type + "'");
}

std::string NodeLabel(const modeling::ImplicitNode& node) {
  const std::string type = modeling::NodeTypeName(node.params);
  if (!node.name.empty()) return node.name + " (" + type + ")";
  if (!node.id.empty()) return node.id + " (" + type + ")";
  return type;
}

std::string StaleReason(const Document& doc, ObjectId id) {
  const DocObject* o = doc.Find(id);
  if (o == nullptr) return "";
  if (const auto* fe = std::get_if<FeModelData>(&o->data)) {
    const std::string mesh = StaleReason(doc, fe->tet_mesh);
    const DocObject* m = doc.Find(fe->tet_mesh);
    return mesh.empty() || m == nullptr ? "" : "its mesh '" + m->name + "' is stale: " + mesh;
  }
  const auto* m = std::get_if<MeshData>(&o->data);
  if (m == nullptr || m->source == 0 || !doc.IsMeshOutOfDate(id)) return "";
  const DocObject* source = doc.Find(m->source);
  if (source == nullptr) return "its source (object " + std::to_string(m->source) + ") was deleted";
  return "'" + source->name + "' changed since this mesh was made";
}

ObjectId RefreshableMesh(const Document& doc, ObjectId id) {
  const DocObject* o = doc.Find(id);
  if (o == nullptr) return 0;
  if (const auto* fe = std::get_if<FeModelData>(&o->data))
    return RefreshableMesh(doc, fe->tet_mesh);
  const auto* m = std::get_if<MeshData>(&o->data);
  if (m == nullptr || m->source == 0 || doc.Find(m->source) == nullptr) return 0;
  return id;
}

// ---- TreeController ----

TreeController::TreeController(SceneModel* model) : model_(model) {}

template <typename Edit>
bool TreeController::Try(const std::optional<NodeRef>& where, Edit&& edit) {
  try {
    edit();
  } catch (const std::exception& e) {
    error_ = e.what();
    error_at_ = where;
    message_.clear();
    return false;
  }
  error_.clear();
  error_at_.reset();
  return true;
}

void TreeController::Select(ObjectId object, NodePath path) {
  selected_ = NodeRef{object, std::move(path)};
}

bool TreeController::SelectByName(const std::string& name) {
  const Document& doc = document();
  if (const size_t slash = name.find('/'); slash != std::string::npos) {
    const DocObject* o = doc.FindByName(name.substr(0, slash));
    if (o == nullptr || TreeOf(*o) == nullptr) return false;
    NodePath path;
    std::stringstream in(name.substr(slash + 1));
    std::string part;
    while (std::getline(in, part, '/')) {
      if (part.empty() || part.find_first_not_of("0123456789") != std::string::npos ||
          part.size() > 6) {
        return false;
      }
      path.push_back(std::stoi(part));
    }
    if (Walk(*TreeOf(*o), path) == nullptr) return false;
    Select(o->id, std::move(path));
    return true;
  }
  for (const DocObject& o : doc.objects()) {
    if (o.name == name && TreeOf(o) != nullptr) {
      Select(o.id);
      return true;
    }
  }
  for (const DocObject& o : doc.objects()) {
    const modeling::ImplicitNode* root = TreeOf(o);
    if (root == nullptr) continue;
    // Depth first, children in order.
    std::vector<std::pair<const modeling::ImplicitNode*, NodePath>> stack = {{root, {}}};
    while (!stack.empty()) {
      auto [node, path] = std::move(stack.back());
      stack.pop_back();
      if (node->name == name || node->id == name) {
        Select(o.id, path);
        return true;
      }
      for (int i = static_cast<int>(node->children.size()) - 1; i >= 0; --i) {
        NodePath child = path;
        child.push_back(i);
        stack.emplace_back(&node->children[i], std::move(child));
      }
    }
  }
  // Objects without a tree (meshes, FE models, sculpts), selected as a whole.
  if (const DocObject* o = doc.FindByName(name)) {
    Select(o->id);
    return true;
  }
  return false;
}

const modeling::ImplicitNode* TreeController::SelectedNode() const {
  if (!selected_) return nullptr;
  const DocObject* o = model_->document().Find(selected_->object);
  if (o == nullptr || TreeOf(*o) == nullptr) return nullptr;
  return Walk(*TreeOf(*o), selected_->path);
}

void TreeController::Revalidate() {
  if (!selected_) return;
  const DocObject* o = document().Find(selected_->object);
  if (o == nullptr) {
    selected_.reset();
    return;
  }
  if (TreeOf(*o) == nullptr) {
    selected_->path.clear();  // a mesh, FE model or sculpt: selected as a whole (for the modes)
  } else {
    while (Walk(*TreeOf(*o), selected_->path) == nullptr) selected_->path.pop_back();
  }
  if (error_at_) {
    const DocObject* e = document().Find(error_at_->object);
    if (e == nullptr || TreeOf(*e) == nullptr || Walk(*TreeOf(*e), error_at_->path) == nullptr) {
      error_at_.reset();
    }
  }
}

bool TreeController::NeedSelection(const char* what) {
  if (SelectedNode() != nullptr) return true;
  error_ = std::string(what) + ": select a node of a solid first";
  error_at_.reset();
  message_.clear();
  return false;
}

bool TreeController::SetField(const std::string& field, const nlohmann::json& value_si,
                              bool dragging) {
  if (!NeedSelection("Edit")) return false;
  const NodeRef at = *selected_;
  return Try(at, [&] {
    document().Execute(edit::SetNodeField(at.object, at.path, field, value_si, dragging));
    message_ = "Set " + field;
  });
}

void TreeController::EndDrag() { document().EndDrag(); }

bool TreeController::AddPrimitive(const std::string& type, bool as_new_solid) {
  const modeling::ImplicitNode* parent = SelectedNode();
  if (as_new_solid || parent == nullptr) {
    return Try(std::nullopt, [&] {
      Document& doc = document();
      doc.Execute(edit::AddSolid(UniqueObjectName(doc, type), DefaultNode(type)));
      Select(doc.last_created().at(0));
      message_ = "Added solid '" + doc.Get(selected_->object).name + "'";
    });
  }
  const NodeRef at = *selected_;
  return Try(at, [&] {
    if (modeling::IsPrimitive(parent->params)) {
      throw DocumentError(std::string("a ") + modeling::NodeTypeName(parent->params) +
                          " takes no children: select an operation or transform, or wrap the " +
                          modeling::NodeTypeName(parent->params) + " first");
    }
    const int index = static_cast<int>(parent->children.size());
    document().Execute(edit::AddNode(at.object, at.path, -1, DefaultNode(type)));
    NodePath child = at.path;
    child.push_back(index);
    Select(at.object, std::move(child));
    message_ = "Added " + type;
  });
}

bool TreeController::Wrap(const std::string& type) {
  if (!NeedSelection("Wrap")) return false;
  const NodeRef at = *selected_;
  return Try(at, [&] {
    modeling::ImplicitNode wrapper = DefaultNode(type);
    if (modeling::IsPrimitive(wrapper.params)) {
      throw DocumentError("cannot wrap a node in a " + type + ": a primitive takes no children");
    }
    Document& doc = document();
    const bool difference =
        std::holds_alternative<modeling::DifferenceParams>(wrapper.params) ||
        std::holds_alternative<modeling::SmoothDifferenceParams>(wrapper.params);
    if (!difference) {
      doc.Execute(edit::WrapNode(at.object, at.path, wrapper.params));
    } else {
      // A difference needs a second child: the wrapped node minus a default sphere, one step.
      wrapper.children.push_back(*SelectedNode());
      wrapper.children.push_back(DefaultNode("sphere"));
      if (at.path.empty()) {
        doc.Execute(edit::ReplaceTree(at.object, std::move(wrapper)));
      } else {
        NodePath parent(at.path.begin(), at.path.end() - 1);
        std::vector<std::unique_ptr<Command>> steps;
        steps.push_back(edit::DeleteNode(at.object, at.path));
        steps.push_back(edit::AddNode(at.object, parent, at.path.back(), std::move(wrapper)));
        doc.Execute(std::make_unique<MacroCommand>("Wrap in " + type, std::move(steps)));
      }
    }
    message_ = "Wrapped in " + type;  // the wrapper takes the wrapped node's place and path
  });
}

bool TreeController::DeleteSelected() {
  const DocObject* whole = selected_ ? document().Find(selected_->object) : nullptr;
  if ((whole == nullptr || TreeOf(*whole) != nullptr) && !NeedSelection("Delete")) return false;
  const NodeRef at = *selected_;
  return Try(at, [&] {
    Document& doc = document();
    if (at.path.empty()) {
      const std::string name = doc.Get(at.object).name;
      doc.Execute(edit::DeleteObject(at.object));
      selected_.reset();
      message_ = "Deleted '" + name + "'";
    } else {
      doc.Execute(edit::DeleteNode(at.object, at.path));
      NodePath parent(at.path.begin(), at.path.end() - 1);
      Select(at.object, std::move(parent));
      message_ = "Deleted node";
    }
  });
}

bool TreeController::RequestRefresh() {
  const ObjectId id = selected_ ? selected_->object : 0;
  const DocObject* o = document().Find(id);
  if (o == nullptr) {
    error_ = "Refresh: select a mesh or an FE model first";
  } else if (RefreshableMesh(document(), id) == 0) {
    const std::string why = StaleReason(document(), id);
    error_ =
        "Refresh: '" + o->name + "' " +
        (why.empty() ? std::string("was not meshed from another object") : "cannot be: " + why);
  } else {
    refresh_request_ = id;
    error_.clear();
    error_at_.reset();
    message_ = "Refreshing '" + o->name + "'";
    return true;
  }
  error_at_.reset();
  message_.clear();
  return false;
}

bool TreeController::RenameSelected(const std::string& name) {
  if (!NeedSelection("Rename")) return false;
  const NodeRef at = *selected_;
  return Try(at, [&] {
    if (at.path.empty()) {
      document().Execute(edit::RenameObject(at.object, name));
    } else {
      document().Execute(edit::SetNodeName(at.object, at.path, name));
    }
    message_ = "Renamed to '" + name + "'";
  });
}

bool TreeController::DuplicateSelected() {
  if (!NeedSelection("Duplicate")) return false;
  const NodeRef at = *selected_;
  return Try(at, [&] {
    Document& doc = document();
    doc.Execute(edit::DuplicateObject(at.object));
    Select(doc.last_created().at(0));
    message_ = "Duplicated as '" + doc.Get(selected_->object).name + "'";
  });
}

bool TreeController::Copy() {
  if (!NeedSelection("Copy")) return false;
  const NodeRef at = *selected_;
  return Try(at, [&] {
    if (at.path.empty()) {
      clipboard_.CopySolid(document(), at.object);
      message_ = "Copied solid '" + document().Get(at.object).name + "'";
    } else {
      clipboard_.CopyNode(document(), at.object, at.path);
      message_ = "Copied " + NodeLabel(*SelectedNode());
    }
  });
}

bool TreeController::Paste() {
  if (clipboard_.empty()) {
    error_ = "Paste: the clipboard is empty (copy a solid or node first)";
    error_at_.reset();
    return false;
  }
  const modeling::ImplicitNode* selected = SelectedNode();
  return Try(selected_, [&] {
    Document& doc = document();
    const ClipboardContent content = ParseClipboard(clipboard_.text());
    if (content.is_solid || selected == nullptr) {
      doc.Execute(PasteAsSolid(clipboard_.text()));
      Select(doc.last_created().at(0));
      message_ = "Pasted solid '" + doc.Get(selected_->object).name + "'";
      return;
    }
    // Into the selected node, or beside a selected primitive (into its parent).
    NodeRef target = *selected_;
    if (modeling::IsPrimitive(selected->params)) {
      if (target.path.empty()) {
        throw DocumentError("Paste: '" + doc.Get(target.object).name + "' is a single " +
                            modeling::NodeTypeName(selected->params) +
                            ", which takes no children: select an operation or transform");
      }
      target.path.pop_back();
    }
    const int index = static_cast<int>(doc.Node(target.object, target.path).children.size());
    doc.Execute(PasteAsChild(clipboard_.text(), target.object, target.path, -1));
    NodePath child = target.path;
    child.push_back(index);
    Select(target.object, std::move(child));
    message_ = "Pasted " + NodeLabel(*SelectedNode());
  });
}

bool TreeController::HistoryHeld(const char* what) {
  const std::string why = history_hold_ ? history_hold_() : std::string();
  if (why.empty()) return false;
  error_ = std::string(what) + ": " + why;
  error_at_.reset();
  return true;
}

bool TreeController::Undo() {
  if (HistoryHeld("Undo")) return false;
  Document& doc = document();
  const std::string what = doc.history().UndoDescription();
  if (!doc.Undo()) {
    error_ = "Undo: nothing to undo";
    error_at_.reset();
    return false;
  }
  error_.clear();
  error_at_.reset();
  message_ = "Undid " + what;
  Revalidate();
  return true;
}

bool TreeController::Redo() {
  if (HistoryHeld("Redo")) return false;
  Document& doc = document();
  const std::string what = doc.history().RedoDescription();
  if (!doc.Redo()) {
    error_ = "Redo: nothing to redo";
    error_at_.reset();
    return false;
  }
  error_.clear();
  error_at_.reset();
  message_ = "Redid " + what;
  Revalidate();
  return true;
}

bool TreeController::Save(const std::string& path) {
  const std::string target = path.empty() ? document().file_path() : path;
  if (target.empty()) {
    error_ = "Save: the scene has no file yet: use File > Save As";
    error_at_.reset();
    return false;
  }
  return Try(std::nullopt, [&] {
    model_->Save(target);
    message_ = "Saved " + target;
  });
}

std::string TreeController::Title() const {
  const Document& doc = model_->document();
  std::string name = !doc.file_path().empty()
                         ? std::filesystem::path(doc.file_path()).filename().string()
                     : model_->source() == kNoSceneName ? std::string("untitled")
                                                        : model_->source();
  return std::string(doc.dirty() ? "*" : "") + "spidarcad — " + name;
}

// ---- ImGui ----

namespace {

const ImVec4 kErrorRed(0.80f, 0.10f, 0.10f, 1.0f);
const ImVec4 kStaleOrange(0.90f, 0.55f, 0.10f, 1.0f);

void ShowErrorHere(const TreeController& tree, const NodeRef& here) {
  if (tree.error().empty() || !tree.error_at() || !(*tree.error_at() == here)) return;
  ImGui::PushTextWrapPos(ImGui::GetContentRegionMax().x);
  ImGui::TextColored(kErrorRed, "%s", tree.error().c_str());
  ImGui::PopTextWrapPos();
}

void DrawNodeMenu(TreePanelState* state) {
  using Action = std::function<void(TreeController*)>;
  Action& pending = state->pending;
  if (ImGui::BeginMenu("Add child")) {
    for (const std::string& t : PrimitiveTypeNames()) {
      if (ImGui::MenuItem(t.c_str()))
        pending = [t](TreeController* c) { c->AddPrimitive(t, false); };
    }
    ImGui::Separator();
    for (const std::string& t : OperationTypeNames()) {
      if (ImGui::MenuItem(t.c_str())) {
        // An operation alone is invalid: add a default sphere and wrap it.
        pending = [t](TreeController* c) {
          if (c->AddPrimitive("sphere", false)) c->Wrap(t);
        };
      }
    }
    ImGui::EndMenu();
  }
  if (ImGui::BeginMenu("Wrap in")) {
    for (const std::string& t : OperationTypeNames()) {
      if (ImGui::MenuItem(t.c_str())) pending = [t](TreeController* c) { c->Wrap(t); };
    }
    ImGui::EndMenu();
  }
  ImGui::Separator();
  if (ImGui::MenuItem("Copy", "Ctrl+C")) {
    pending = [](TreeController* c) {
      if (c->Copy()) ImGui::SetClipboardText(c->clipboard().text().c_str());
    };
  }
  if (ImGui::MenuItem("Paste", "Ctrl+V")) pending = [](TreeController* c) { c->Paste(); };
  if (ImGui::MenuItem("Duplicate object"))
    pending = [](TreeController* c) { c->DuplicateSelected(); };
  if (ImGui::MenuItem("Delete", "Del")) pending = [](TreeController* c) { c->DeleteSelected(); };
}

void DrawNode(TreeController* tree, TreePanelState* state, const DocObject& object,
              const SceneObject* scene_object, const modeling::ImplicitNode& node, NodePath* path,
              bool scroll) {
  const NodeRef here{object.id, *path};
  const bool selected = tree->selection() && *tree->selection() == here;
  ImGuiTreeNodeFlags flags = ImGuiTreeNodeFlags_OpenOnArrow | ImGuiTreeNodeFlags_OpenOnDoubleClick |
                             ImGuiTreeNodeFlags_SpanAvailWidth | ImGuiTreeNodeFlags_DefaultOpen;
  if (selected) flags |= ImGuiTreeNodeFlags_Selected;
  if (node.children.empty()) flags |= ImGuiTreeNodeFlags_Leaf;
  std::string label = NodeLabel(node);
  if (path->empty()) {
    label = object.name + "  [" + label + "]";
    if (scene_object != nullptr && !scene_object->error.empty()) label += "  (!)";
  }
  const bool open = ImGui::TreeNodeEx("node", flags, "%s", label.c_str());
  if (selected && scroll) ImGui::SetScrollHereY(0.5f);  // selected from elsewhere: show it
  if (ImGui::IsItemClicked() && !ImGui::IsItemToggledOpen()) {
    tree->Select(object.id, *path);
    state->clicked = true;
  }
  if (ImGui::BeginPopupContextItem("menu")) {
    tree->Select(object.id, *path);
    DrawNodeMenu(state);
    ImGui::EndPopup();
  }
  if (path->empty() && scene_object != nullptr && !scene_object->error.empty()) {
    ImGui::PushTextWrapPos(ImGui::GetContentRegionMax().x);
    ImGui::TextColored(kErrorRed, "does not compile (last good shape kept): %s",
                       scene_object->error.c_str());
    ImGui::PopTextWrapPos();
  }
  ShowErrorHere(*tree, here);
  if (!open) return;
  for (int i = 0; i < static_cast<int>(node.children.size()); ++i) {
    ImGui::PushID(i);
    path->push_back(i);
    DrawNode(tree, state, object, scene_object, node.children[i], path, scroll);
    path->pop_back();
    ImGui::PopID();
  }
  ImGui::TreePop();
}

// One editor row per field of the selected node (scene-format names and values).
void DrawParameters(TreeController* tree, const modeling::ImplicitNode& node) {
  // No widget held: whatever drag there was has ended (also covers multi-field widgets whose
  // release IsItemDeactivatedAfterEdit may not see).
  if (!ImGui::IsAnyItemActive()) tree->EndDrag();
  const nlohmann::json j = modeling::NodeToJson(node);
  for (auto it = j.begin(); it != j.end(); ++it) {
    const std::string& field = it.key();
    if (field == "type" || field == "children" || field == "id" || field == "name") continue;
    const nlohmann::json& v = it.value();
    const FieldUnit unit = UnitOfField(field);
    const double scale = DisplayScale(unit);
    const float speed = unit == FieldUnit::kLength  ? 0.1f
                        : unit == FieldUnit::kAngle ? 0.5f
                                                    : 0.01f;
    const std::string label = field + (unit == FieldUnit::kLength || unit == FieldUnit::kAngle
                                           ? std::string(" [") + DisplayUnitText(unit) + "]"
                                           : std::string());
    ImGui::PushID(field.c_str());
    bool changed = false;
    nlohmann::json value;
    if (v.is_boolean()) {
      bool b = v.get<bool>();
      if (ImGui::Checkbox(label.c_str(), &b)) {
        tree->SetField(field, b, false);
      }
      ImGui::PopID();
      continue;
    }
    if (unit == FieldUnit::kCount && v.is_number()) {
      int n = v.get<int>();
      if (ImGui::DragInt(label.c_str(), &n, 0.1f)) {
        value = n;
        changed = true;
      }
    } else if (v.is_number()) {
      float f = static_cast<float>(v.get<double>() * scale);
      if (ImGui::DragFloat(label.c_str(), &f, speed, 0.0f, 0.0f, "%.2f")) {
        value = static_cast<double>(f) / scale;
        changed = true;
      }
    } else if (v.is_array() && v.size() == 3 && v[0].is_number()) {
      float f[3];
      for (int k = 0; k < 3; ++k) f[k] = static_cast<float>(v[k].get<double>() * scale);
      if (ImGui::DragFloat3(label.c_str(), f, speed, 0.0f, 0.0f, "%.2f")) {
        value = nlohmann::json::array();
        for (int k = 0; k < 3; ++k) value.push_back(static_cast<double>(f[k]) / scale);
        changed = true;
      }
    } else if (v.is_array() && !v.empty() && v[0].is_array()) {  // a profile: [[x, y], ...]
      ImGui::TextUnformatted(label.c_str());
      value = v;
      for (size_t p = 0; p < v.size(); ++p) {
        ImGui::PushID(static_cast<int>(p));
        float f[2] = {static_cast<float>(v[p][0].get<double>() * scale),
                      static_cast<float>(v[p][1].get<double>() * scale)};
        if (ImGui::DragFloat2("##v", f, speed, 0.0f, 0.0f, "%.2f")) {
          value[p] = {static_cast<double>(f[0]) / scale, static_cast<double>(f[1]) / scale};
          changed = true;
        }
        if (ImGui::IsItemDeactivatedAfterEdit()) tree->EndDrag();
        ImGui::PopID();
      }
    } else {
      ImGui::TextDisabled("%s: %s", field.c_str(), v.dump().c_str());
    }
    // A drag is one undo step: edits merge until the widget is released.
    if (changed) tree->SetField(field, value, true);
    if (ImGui::IsItemDeactivatedAfterEdit()) tree->EndDrag();
    ImGui::PopID();
  }
}

// What an object without a tree was made from, whether it is stale, and Refresh.
void DrawObjectProperties(TreeController* tree, const DocObject& object) {
  const Document& doc = tree->document();
  ImGui::Text("%s '%s'", ObjectKindName(object.data), object.name.c_str());
  const MeshData* m = std::get_if<MeshData>(&object.data);
  if (const auto* fe = std::get_if<FeModelData>(&object.data)) {
    const DocObject* mesh = doc.Find(fe->tet_mesh);
    if (mesh != nullptr) {
      ImGui::TextDisabled("on mesh '%s'", mesh->name.c_str());
      m = std::get_if<MeshData>(&mesh->data);
    }
  }
  if (m != nullptr && m->source != 0) {
    const DocObject* source = doc.Find(m->source);
    const MeshSettings& s = m->settings;
    char line[240];
    char flat[48] = "";
    if (s.flat_cells > 0.0)
      std::snprintf(flat, sizeof flat, ", flat faces coarsened (%.2g cells)", s.flat_cells);
    std::snprintf(line, sizeof line, "made from '%s': %s, cell %.1f mm%s%s%s%s",
                  source != nullptr ? source->name.c_str() : "(deleted)",
                  m->volume ? "tetrahedra" : "surface", 1e3 * s.cell_size,
                  s.surface_mesher == "lattice" ? ", lattice" : "",
                  m->volume ? (s.mesher == "cgal" ? ", CGAL" : ", TetGen") : "",
                  s.sharp_edges ? ", sharp edges" : "", flat);
    ImGui::PushTextWrapPos(ImGui::GetContentRegionMax().x);
    ImGui::TextDisabled("%s", line);
    ImGui::PopTextWrapPos();
  } else if (m != nullptr && !m->import_source.empty()) {
    ImGui::TextDisabled("imported from %s", m->import_source.c_str());
  } else if (std::holds_alternative<SculptData>(object.data)) {
    ImGui::TextDisabled("an edited copy: never stale");
  }
  const std::string stale = StaleReason(doc, object.id);
  if (!stale.empty()) {
    ImGui::PushTextWrapPos(ImGui::GetContentRegionMax().x);
    ImGui::TextColored(kStaleOrange, "stale: %s", stale.c_str());
    ImGui::PopTextWrapPos();
    if (RefreshableMesh(doc, object.id) != 0 && ImGui::Button("Refresh")) tree->RequestRefresh();
  }
}

}  // namespace

void DrawTreePanel(TreeController* tree, TreePanelState* state, float tree_height) {
  Document& doc = tree->document();
  const SceneModel& model = tree->model();
  tree->Revalidate();
  const bool scroll = tree->selection() != state->drawn_selection && !state->clicked;
  state->clicked = false;
  state->drawn_selection = tree->selection();
  ImGui::BeginChild("tree", ImVec2(0.0f, tree_height), true);
  if (doc.objects().empty()) {
    ImGui::TextDisabled("no solids: Add > new solid, paste one, or File > Open / Import mesh");
  }
  for (const DocObject& o : doc.objects()) {
    const modeling::ImplicitNode* root = TreeOf(o);
    if (root == nullptr) continue;
    ImGui::PushID(static_cast<int>(o.id));
    const int index = model.IndexOf(o.id);
    NodePath path;
    DrawNode(tree, state, o, index >= 0 ? &model.objects()[index] : nullptr, *root, &path, scroll);
    ImGui::PopID();
  }
  // The other objects (meshes, FE models, sculpts, rigid parts): listed and selectable (the modes
  // act on the selected one), not drawn or edited here.
  for (const DocObject& o : doc.objects()) {
    if (TreeOf(o) != nullptr) continue;
    std::string counts;
    if (const auto* m = std::get_if<MeshData>(&o.data)) {
      if (m->surface) counts += std::to_string(m->surface->triangles.cols()) + " triangles";
      if (m->volume) {
        counts += (counts.empty() ? "" : ", ") + std::to_string(m->volume->tets.cols()) + " tets";
      }
      if (!m->import_source.empty()) counts += ", imported";
    }
    const std::string stale = StaleReason(doc, o.id);
    const std::string label = o.name + "  [" + ObjectKindName(o.data) +
                              (counts.empty() ? "" : ": ") + counts + "]" +
                              (stale.empty() ? "" : "  (stale)");
    ImGui::PushID(static_cast<int>(o.id));
    if (!stale.empty()) ImGui::PushStyleColor(ImGuiCol_Text, kStaleOrange);
    const bool selected = tree->selection() && tree->selection()->object == o.id;
    if (ImGui::Selectable(label.c_str(), selected)) {
      tree->Select(o.id);
      state->clicked = true;
    }
    if (!stale.empty()) {
      ImGui::PopStyleColor();
      if (ImGui::IsItemHovered()) {
        ImGui::SetTooltip("Stale: %s.%s", stale.c_str(),
                          RefreshableMesh(doc, o.id) != 0
                              ? "\nRefresh (right-click, or below) meshes it again."
                              : "");
      }
    }
    if (selected && scroll) ImGui::SetScrollHereY(0.5f);  // selected from elsewhere: show it
    if (ImGui::BeginPopupContextItem("menu")) {
      tree->Select(o.id);
      const bool refreshable = RefreshableMesh(doc, o.id) != 0;
      if (ImGui::MenuItem("Refresh", nullptr, false, refreshable && !stale.empty())) {
        state->pending = [](TreeController* c) { c->RequestRefresh(); };
      }
      if (ImGui::MenuItem("Delete", "Del")) {
        state->pending = [](TreeController* c) { c->DeleteSelected(); };
      }
      ImGui::EndPopup();
    }
    ImGui::PopID();
  }
  ImGui::EndChild();
  if (state->pending) {
    const auto action = std::move(state->pending);
    state->pending = nullptr;
    action(tree);
  }

  // Buttons acting on the selection.
  if (ImGui::Button("Add...")) ImGui::OpenPopup("add");
  if (ImGui::BeginPopup("add")) {
    ImGui::TextDisabled("as child of the selected node");
    for (const std::string& t : PrimitiveTypeNames()) {
      if (ImGui::MenuItem(t.c_str())) tree->AddPrimitive(t, false);
    }
    ImGui::Separator();
    if (ImGui::BeginMenu("as a new solid")) {
      for (const std::string& t : PrimitiveTypeNames()) {
        if (ImGui::MenuItem(t.c_str())) tree->AddPrimitive(t, true);
      }
      ImGui::EndMenu();
    }
    ImGui::EndPopup();
  }
  ImGui::SameLine();
  if (ImGui::Button("Wrap...")) ImGui::OpenPopup("wrap");
  if (ImGui::BeginPopup("wrap")) {
    for (const std::string& t : OperationTypeNames()) {
      if (ImGui::MenuItem(t.c_str())) tree->Wrap(t);
    }
    ImGui::EndPopup();
  }
  ImGui::SameLine();
  if (ImGui::Button("Duplicate")) tree->DuplicateSelected();
  ImGui::SameLine();
  if (ImGui::Button("Delete")) tree->DeleteSelected();
  const History& history = doc.history();
  if (!history.CanUndo()) ImGui::BeginDisabled();
  if (ImGui::Button("Undo")) tree->Undo();
  if (!history.CanUndo()) ImGui::EndDisabled();
  ImGui::SameLine();
  if (!history.CanRedo()) ImGui::BeginDisabled();
  if (ImGui::Button("Redo")) tree->Redo();
  if (!history.CanRedo()) ImGui::EndDisabled();
  ImGui::SameLine();
  if (ImGui::Button("Copy")) {
    if (tree->Copy()) ImGui::SetClipboardText(tree->clipboard().text().c_str());
  }
  ImGui::SameLine();
  if (ImGui::Button("Paste")) {
    const char* text = ImGui::GetClipboardText();
    if (text != nullptr && text[0] != '\0') tree->clipboard().SetText(text);
    tree->Paste();
  }

  // The selected node: name and parameters.
  const modeling::ImplicitNode* node = tree->SelectedNode();
  const DocObject* whole = tree->selection() ? doc.Find(tree->selection()->object) : nullptr;
  if (node == nullptr && whole != nullptr && TreeOf(*whole) == nullptr) {
    DrawObjectProperties(tree, *whole);
  } else if (node == nullptr) {
    ImGui::TextDisabled("select a node to edit its parameters");
  } else {
    const NodeRef& sel = *tree->selection();
    const DocObject& object = doc.Get(sel.object);
    if (state->rename_for != sel) {
      const std::string& current = sel.path.empty() ? object.name : node->name;
      std::snprintf(state->rename, sizeof(state->rename), "%s", current.c_str());
      state->rename_for = sel;
    }
    // Room for the longest label ("radius_bottom [mm]") right of the fields.
    ImGui::PushItemWidth(-ImGui::CalcTextSize("radius_bottom [mm]").x - 8.0f);
    if (ImGui::InputText(sel.path.empty() ? "solid name" : "node name", state->rename,
                         sizeof(state->rename), ImGuiInputTextFlags_EnterReturnsTrue)) {
      tree->RenameSelected(state->rename);
      state->rename_for.reset();
    }
    node = tree->SelectedNode();  // the rename replaced the object
    if (node != nullptr) DrawParameters(tree, *node);
    ImGui::PopItemWidth();
  }
  // Errors with no node to sit next to (and the last success) at the bottom.
  if (!tree->error().empty() && !tree->error_at()) {
    ImGui::PushTextWrapPos(ImGui::GetContentRegionMax().x);
    ImGui::TextColored(kErrorRed, "%s", tree->error().c_str());
    ImGui::PopTextWrapPos();
  } else if (tree->error().empty() && !tree->message().empty()) {
    ImGui::TextDisabled("%s", tree->message().c_str());
  }
}

void DrawEditMenuItems(TreeController* tree) {
  const History& history = tree->document().history();
  const std::string undo = "Undo " + history.UndoDescription();
  const std::string redo = "Redo " + history.RedoDescription();
  if (ImGui::MenuItem(undo.c_str(), "Ctrl+Z", false, history.CanUndo())) tree->Undo();
  if (ImGui::MenuItem(redo.c_str(), "Ctrl+Y", false, history.CanRedo())) tree->Redo();
  ImGui::Separator();
  const bool has_selection = tree->SelectedNode() != nullptr;
  if (ImGui::MenuItem("Copy", "Ctrl+C", false, has_selection)) {
    if (tree->Copy()) ImGui::SetClipboardText(tree->clipboard().text().c_str());
  }
  if (ImGui::MenuItem("Paste", "Ctrl+V")) {
    const char* text = ImGui::GetClipboardText();
    if (text != nullptr && text[0] != '\0') tree->clipboard().SetText(text);
    tree->Paste();
  }
  if (ImGui::MenuItem("Duplicate object", nullptr, false, has_selection)) tree->DuplicateSelected();
  if (ImGui::MenuItem("Delete", "Del", false, has_selection)) tree->DeleteSelected();
}

void DrawSaveMenuItems(TreeController* tree, TreePanelState* state) {
  if (ImGui::MenuItem("Save", "Ctrl+S")) {
    if (tree->document().file_path().empty()) {
      state->open_save_as = true;
    } else {
      tree->Save();
    }
  }
  if (ImGui::MenuItem("Save As...", "Ctrl+Shift+S")) state->open_save_as = true;
}

void DrawSaveAsDialog(TreeController* tree, TreePanelState* state) {
  if (state->open_save_as) {
    ImGui::OpenPopup("Save As");
    state->open_save_as = false;
    const std::string& current = tree->document().file_path();
    std::snprintf(state->save_path, sizeof(state->save_path), "%s",
                  current.empty() ? "scene.json" : current.c_str());
  }
  ImGui::SetNextWindowSize(ImVec2(520.0f, 0.0f));
  if (!ImGui::BeginPopupModal("Save As", nullptr, ImGuiWindowFlags_AlwaysAutoResize)) return;
  ImGui::TextUnformatted("Scene file (spidarcad-scene JSON, metres):");
  ImGui::SetNextItemWidth(500.0f);
  const bool enter = ImGui::InputText("##path", state->save_path, sizeof(state->save_path),
                                      ImGuiInputTextFlags_EnterReturnsTrue);
  if ((ImGui::Button("Save") || enter) && tree->Save(state->save_path)) ImGui::CloseCurrentPopup();
  ImGui::SameLine();
  if (ImGui::Button("Cancel")) ImGui::CloseCurrentPopup();
  if (!tree->error().empty() && !tree->error_at()) {
    ImGui::PushTextWrapPos(500.0f);
    ImGui::TextColored(kErrorRed, "%s", tree->error().c_str());
    ImGui::PopTextWrapPos();
  }
  ImGui::EndPopup();
}

void HandleTreeShortcuts(TreeController* tree, TreePanelState* state) {
  const ImGuiIO& io = ImGui::GetIO();
  if (io.WantTextInput || !io.KeyCtrl) {
    if (!io.WantTextInput && !io.KeyCtrl && ImGui::IsKeyPressed(GLFW_KEY_DELETE, false)) {
      tree->DeleteSelected();
    }
    return;
  }
  if (ImGui::IsKeyPressed(GLFW_KEY_Z, true)) {
    if (io.KeyShift) {
      tree->Redo();
    } else {
      tree->Undo();
    }
  } else if (ImGui::IsKeyPressed(GLFW_KEY_Y, true)) {
    tree->Redo();
  } else if (ImGui::IsKeyPressed(GLFW_KEY_C, false)) {
    if (tree->Copy()) ImGui::SetClipboardText(tree->clipboard().text().c_str());
  } else if (ImGui::IsKeyPressed(GLFW_KEY_V, false)) {
    const char* text = ImGui::GetClipboardText();
    if (text != nullptr && text[0] != '\0') tree->clipboard().SetText(text);
    tree->Paste();
  } else if (ImGui::IsKeyPressed(GLFW_KEY_S, false)) {
    if (io.KeyShift || tree->document().file_path().empty()) {
      state->open_save_as = true;
    } else {
      tree->Save();
    }
  }
}

}  // namespace spidarcad::app
