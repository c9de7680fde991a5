// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#include "doc/clipboard.h"

#include <utility>

#include "spidarcad/modeling/scene_io.h"

namespace spidarcad::app {
namespace {

constexpr const char* kClipboardFormat = "spidarcad-clipboard";
constexpr int kClipboardVersion = 1;

nlohmann::json Wrap(const char* key, nlohmann::json value) {
  return {{"format", kClipboardFormat}, {"version", kClipboardVersion}, {key, std::move(value)}};
}

const nlohmann::json& Field(const nlohmann::json& object, const std::string& key,
                            const std::string& pointer) {
  auto it = object.find(key);
  if (it == object.end())
    throw ClipboardError("clipboard: " + pointer + " lacks the field '" + key + "'");
  return *it;
}

// A node from JSON at pointer, with values validated.
modeling::ImplicitNode ReadNode(const nlohmann::json& json, const std::string& pointer) {
  try {
    modeling::ImplicitNode node = modeling::NodeFromJson(json, pointer);
    modeling::ValidateTree(node, pointer);
    return node;
  } catch (const modeling::SceneError& e) {
    throw ClipboardError("clipboard: field " + e.pointer() + ": " + e.message());
  } catch (const modeling::ModelError& e) {
    throw ClipboardError("clipboard: " + std::string(e.what()));
  }
}

ClipboardContent ReadSolid(const nlohmann::json& solid, const std::string& pointer) {
  if (!solid.is_object())
    throw ClipboardError("clipboard: " + pointer + " must be an object {\"name\", \"root\"}");
  for (auto it = solid.begin(); it != solid.end(); ++it) {
    if (it.key() != "name" && it.key() != "root") {
      throw ClipboardError("clipboard: unknown field '" + it.key() + "' in the solid at " +
                           pointer + " (fields: name, root)");
    }
  }
  const nlohmann::json& name = Field(solid, "name", pointer);
  if (!name.is_string() || name.get<std::string>().empty()) {
    throw ClipboardError("clipboard: field " + pointer + "/name must be a non-empty string, got " +
                         name.dump());
  }
  ClipboardContent content;
  content.is_solid = true;
  content.name = name.get<std::string>();
  content.root = ReadNode(Field(solid, "root", pointer), pointer + "/root");
  return content;
}

}  // namespace

ClipboardContent ParseClipboard(const std::string& text) {
  if (text.empty()) throw ClipboardError("clipboard: nothing to paste (the clipboard is empty)");
  nlohmann::json json;
  try {
    // Syntax errors, nesting deeper than modeling::kMaxJsonDepth and numbers beyond a double,
    // each with its line and column; no recursion, no JSON library exception.
    json = modeling::ParseJsonText(text, "clipboard");
  } catch (const modeling::SceneError& e) {
    std::string where = "clipboard: not JSON: line " + std::to_string(e.line()) + ", column " +
                        std::to_string(e.column());
    if (!e.pointer().empty()) where += ", field " + e.pointer();
    throw ClipboardError(where + ": " + e.message());
  }
  if (!json.is_object())
    throw ClipboardError("clipboard: expected a JSON object, got " + std::string(json.type_name()));
  if (json.contains("format")) {
    if (json["format"] != kClipboardFormat) {
      throw ClipboardError("clipboard: field /format must be \"" + std::string(kClipboardFormat) +
                           "\", got " + json["format"].dump());
    }
    const nlohmann::json& version = Field(json, "version", "the clipboard document");
    if (version != kClipboardVersion) {
      throw ClipboardError("clipboard: field /version: version " + version.dump() +
                           " is not supported (this build reads " +
                           std::to_string(kClipboardVersion) + ")");
    }
    for (auto it = json.begin(); it != json.end(); ++it) {
      if (it.key() != "format" && it.key() != "version" && it.key() != "solid" &&
          it.key() != "node") {
        throw ClipboardError("clipboard: unknown field '" + it.key() +
                             "' (fields: format, version, solid or node)");
      }
    }
    const bool has_solid = json.contains("solid"), has_node = json.contains("node");
    if (has_solid == has_node)
      throw ClipboardError("clipboard: needs exactly one of the fields 'solid' and 'node'");
    if (has_solid) return ReadSolid(json["solid"], "/solid");
    ClipboardContent content;
    content.root = ReadNode(json["node"], "/node");
    return content;
  }
  if (json.contains("root")) return ReadSolid(json, "");
  if (json.contains("type")) {
    ClipboardContent content;
    content.root = ReadNode(json, "");
    return content;
  }
  throw ClipboardError(
      "clipboard: not a spidarcad solid or node (no 'format', 'root' or 'type' field)");
}

void Clipboard::CopySolid(const Document& doc, ObjectId id) {
  const DocObject& object = doc.Get(id);
  const modeling::ImplicitNode* root = TreeOf(object);
  if (root == nullptr)
    throw DocumentError(std::string(ObjectKindName(object.data)) + " '" + object.name +
                        "' has no node tree to copy");
  text_ = Wrap("solid", {{"name", object.name}, {"root", modeling::NodeToJson(*root)}}).dump(2);
}

void Clipboard::CopyNode(const Document& doc, ObjectId id, const NodePath& path) {
  text_ = Wrap("node", modeling::NodeToJson(doc.Node(id, path))).dump(2);
}

std::unique_ptr<Command> PasteAsSolid(const std::string& text) {
  ClipboardContent content = ParseClipboard(text);
  std::string name = content.is_solid
                         ? content.name
                         : (content.root.name.empty() ? modeling::NodeTypeName(content.root.params)
                                                      : content.root.name);
  auto shared = std::make_shared<ClipboardContent>(std::move(content));
  // InsertObjectCommand is internal to command.cc: build the object through DuplicateObject's
  // sibling, a constant insert made unique at Do time.
  struct PasteSolid : Command {
    std::shared_ptr<ClipboardContent> content;
    std::string name;
    std::unique_ptr<Command> insert;
    void Do(Document& doc) override {
      if (!insert) {
        modeling::ImplicitNode root = content->root;
        MakePastedTreeUnique(doc, &root);
        auto command = edit::AddSolid(UniqueObjectName(doc, name), std::move(root));
        command->Do(doc);
        insert = std::move(command);
        return;
      }
      insert->Do(doc);
    }
    void Undo(Document& doc) override { insert->Undo(doc); }
    std::string Description() const override { return "Paste " + name; }
  };
  auto command = std::make_unique<PasteSolid>();
  command->content = std::move(shared);
  command->name = std::move(name);
  return command;
}

std::unique_ptr<Command> PasteAsChild(const std::string& text, ObjectId id, NodePath parent,
                                      int index) {
  ClipboardContent content = ParseClipboard(text);
  struct PasteChild : Command {
    modeling::ImplicitNode node;
    ObjectId id = 0;
    NodePath parent;
    int index = -1;
    std::unique_ptr<Command> add;
    void Do(Document& doc) override {
      if (!add) {
        modeling::ImplicitNode copy = node;
        MakePastedTreeUnique(doc, &copy);
        auto command = edit::AddNode(id, parent, index, std::move(copy));
        command->Do(doc);
        add = std::move(command);
        return;
      }
      add->Do(doc);
    }
    void Undo(Document& doc) override { add->Undo(doc); }
    std::string Description() const override { return "Paste"; }
  };
  auto command = std::make_unique<PasteChild>();
  command->node = std::move(content.root);
  command->id = id;
  command->parent = std::move(parent);
  command->index = index;
  return command;
}

}  // namespace spidarcad::app
