// JSON scene files holding implicit solids (docs/scene-format.md): a versioned header
// ("format": "spidarcad-scene", "version": 1, "units": "m") and a list of named solids, each a
// node tree. Loading validates every tree; errors name the file, line, column and the JSON
// pointer of the offending field.
// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <nlohmann/json.hpp>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

#include "spidarcad/modeling/implicit_node.h"

namespace spidarcad::modeling {

// Value of the "format" field of a scene file.
inline constexpr const char* kSceneFormat = "spidarcad-scene";
// The scene format version this code reads and writes.
inline constexpr int kSceneVersion = 1;
// Largest scene file LoadScene reads, bytes (64 MiB; docs/limits.md). Larger files, and paths
// that are not regular files (a directory, /dev/zero, a pipe), are refused before reading.
inline constexpr long long kMaxSceneFileBytes = 64LL << 20;
// Deepest nesting of JSON arrays and objects ParseScene accepts (docs/limits.md); checked by a
// streaming pass before the document is built, so deeper text cannot exhaust the stack.
inline constexpr int kMaxJsonDepth = 1000;

// One named implicit solid of a scene.
struct Solid {
  std::string name;
  ImplicitNode root;
};

// Where an assembly part fits on another part: its pose in the other part's frame O when
// seated, X_OS = (position, rotation), and how close a release must come to snap to it.
struct SceneSeat {
  std::string on;                                                // the other part's name
  Eigen::Vector3d position = Eigen::Vector3d::Zero();            // p_OS, m
  Eigen::Quaterniond rotation = Eigen::Quaterniond::Identity();  // R_OS (unit)
  double position_tolerance = 2e-3;                              // m, >= 0
  double angle_tolerance = 0.1;                                  // rad, >= 0
};

// A rigid part of an assembly scene (docs/scene-format.md, "parts"): a solid of the scene is its
// geometry in the part's own frame P, placed in the world at X_WP = (position, rotation).
struct ScenePart {
  std::string name;                                              // unique, not empty
  std::string solid;                                             // name of a solid of the scene
  Eigen::Vector3d position = Eigen::Vector3d::Zero();            // p_WP, m
  Eigen::Quaterniond rotation = Eigen::Quaterniond::Identity();  // R_WP (unit)
  bool fixed = false;            // true: "kind": "fixed"; false: "graspable"
  std::vector<SceneSeat> seats;  // where it fits
};

// Snap forces of a scene (docs/scene-format.md, "snap"): a gentle pull of the grip toward the
// vertices, edges and faces of the solids near it (haptics::SnapField). Radii in scene metres
// (W), the force in N as felt at the grip. Every field is > 0 and finite.
struct SceneSnap {
  double max_force = 1.0;       // F_max, N
  double vertex_radius = 8e-3;  // capture radius of vertices, m
  double edge_radius = 5e-3;    // capture radius of edges, m
  double face_radius = 3e-3;    // capture radius of faces, m
};

// A scene: a description, its solids, (optionally) assembly parts made of them and snap forces.
struct Scene {
  std::string description;
  std::vector<Solid> solids;
  std::vector<ScenePart> parts;
  std::optional<SceneSnap> snap;  // absent: no snap forces
};

// 1-based line and column, in valid JSON text, of the value a JSON pointer (RFC 6901) names, or
// of the deepest value along it that exists: where an error about that field points.
void LocateJsonPointer(const std::string& text, const std::string& pointer, int* line, int* column);

// A bad scene file or document: where (file, line, column, JSON pointer) and what.
class SceneError : public std::runtime_error {
 public:
  // line and column are 1-based, 0 when unknown; pointer is a JSON pointer ("" for the file).
  SceneError(const std::string& file, int line, int column, const std::string& pointer,
             const std::string& what);
  const std::string& file() const { return file_; }
  int line() const { return line_; }
  int column() const { return column_; }
  // JSON pointer of the offending field, e.g. "/solids/0/root/children/1/radius".
  const std::string& pointer() const { return pointer_; }
  // What was wrong, without the location prefix that what() carries.
  const std::string& message() const { return message_; }

 private:
  std::string file_;
  int line_;
  int column_;
  std::string pointer_;
  std::string message_;
};

// Node tree from JSON. path is the JSON pointer of `json` used in errors. Throws SceneError
// (file empty, line 0) for a wrong type, unknown field or missing field, and for a tree deeper
// than kMaxTreeDepth or larger than kMaxTreeNodes (naming the node where the limit is passed,
// before building further); does not validate values (call ValidateTree).
ImplicitNode NodeFromJson(const nlohmann::json& json, const std::string& path = "");
// JSON of a node tree (every field written, so that a load restores it exactly).
nlohmann::json NodeToJson(const ImplicitNode& node);

// Scene from a parsed document; validates every solid. `source` names the document in errors.
Scene SceneFromJson(const nlohmann::json& json, const std::string& source = "<json>");
// JSON document of a scene, with the format header.
nlohmann::json SceneToJson(const Scene& scene);

// Parses JSON text (any JSON document: scenes, documents, clipboard text, calibration files)
// without recursion and without letting a JSON library exception escape: nesting deeper than
// kMaxJsonDepth, a number beyond a double and a syntax error are SceneErrors naming `source`,
// the line and column and, where known, the JSON pointer of the field.
nlohmann::json ParseJsonText(const std::string& text, const std::string& source);

// Parses and validates scene text. Errors carry `source` as the file and the line and column
// of the offending text (syntax errors, numbers beyond a double, nesting deeper than
// kMaxJsonDepth) or field (semantic errors), and the JSON pointer of the field where known.
// Never lets a JSON library exception escape: every failure is a SceneError.
Scene ParseScene(const std::string& text, const std::string& source = "<string>");
// The same for text a caller has already parsed with ParseJsonText (`parsed`), so that the text
// is not parsed a second time: the same checks and the same errors, located in `text`.
Scene ParseScene(const nlohmann::json& parsed, const std::string& text, const std::string& source);
// The whole text of the file at `path`, for a JSON reader. Before reading it refuses, with a
// SceneError naming the path (line 0), a missing file, a path that is not a regular file (a
// directory, a device such as /dev/zero, a pipe: each could be read forever) and a file larger
// than max_bytes; `what` names the kind of file in the messages ("scene file").
std::string ReadBoundedFile(const std::string& path, long long max_bytes, const std::string& what);
// Reads a scene file. Throws SceneError (unreadable file, not a regular file, larger than
// kMaxSceneFileBytes, syntax, bad field) naming path.
Scene LoadScene(const std::string& path);
// Writes a scene file (indented JSON) through a temporary file renamed over path. Throws
// SceneError if it cannot be written.
void SaveScene(const Scene& scene, const std::string& path);

}  // namespace spidarcad::modeling
