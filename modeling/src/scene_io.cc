// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#include "spidarcad/modeling/scene_io.h"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <map>
#include <new>
#include <set>
#include <sstream>
#include <vector>

namespace spidarcad::modeling {

using nlohmann::json;

namespace {

std::string Location(const std::string& file, int line, int column, const std::string& pointer) {
  std::string out = file.empty() ? std::string("<json>") : file;
  if (line > 0) out += ":" + std::to_string(line) + ":" + std::to_string(column);
  out += ": ";
  if (!pointer.empty()) out += "field " + pointer + ": ";
  return out;
}

template <class... Ts>
struct Overloaded : Ts... {
  using Ts::operator()...;
};
template <class... Ts>
Overloaded(Ts...) -> Overloaded<Ts...>;

// A key as a JSON pointer token (RFC 6901): '~' -> "~0", '/' -> "~1".
std::string EscapePointerToken(const std::string& key) {
  std::string out;
  for (char c : key) {
    if (c == '~') {
      out += "~0";
    } else if (c == '/') {
      out += "~1";
    } else {
      out += c;
    }
  }
  return out;
}

// Error without file position yet (filled in by ParseScene). `message` is kept raw in what().
[[noreturn]] void Fail(const std::string& pointer, const std::string& message) {
  throw SceneError("", 0, 0, pointer, message);
}

// Reads the fields of one JSON object, remembering which were used to reject unknown ones.
class ObjectReader {
 public:
  ObjectReader(const json& j, std::string path, std::string what)
      : j_(j), path_(std::move(path)), what_(std::move(what)) {
    if (!j_.is_object()) Fail(path_, what_ + " must be a JSON object, got " + j_.type_name());
  }

  bool Has(const char* key) const { return j_.contains(key); }

  const json& Get(const char* key) {
    used_.insert(key);
    if (!j_.contains(key)) Fail(path_, "missing field '" + std::string(key) + "' of " + what_);
    return j_.at(key);
  }

  double Number(const char* key) {
    const json& v = Get(key);
    if (!v.is_number())
      Fail(Path(key),
           "field '" + std::string(key) + "' of " + what_ + " must be a number, got " + Dump(v));
    return v.get<double>();
  }
  double Number(const char* key, double fallback) {
    return Has(key) ? Number(key) : (used_.insert(key), fallback);
  }

  int Count(const char* key) {
    const json& v = Get(key);
    if (!v.is_number_integer()) {
      Fail(Path(key),
           "field '" + std::string(key) + "' of " + what_ + " must be an integer, got " + Dump(v));
    }
    const long long n = v.get<long long>();
    if (n < -1000000000LL || n > 1000000000LL)
      Fail(Path(key), "field '" + std::string(key) + "' is out of range: " + Dump(v));
    return static_cast<int>(n);
  }

  bool Bool(const char* key, bool fallback) {
    if (!Has(key)) {
      used_.insert(key);
      return fallback;
    }
    const json& v = Get(key);
    if (!v.is_boolean())
      Fail(Path(key), "field '" + std::string(key) + "' of " + what_ +
                          " must be true or false, got " + Dump(v));
    return v.get<bool>();
  }

  std::string String(const char* key, const std::string& fallback) {
    if (!Has(key)) {
      used_.insert(key);
      return fallback;
    }
    const json& v = Get(key);
    if (!v.is_string())
      Fail(Path(key),
           "field '" + std::string(key) + "' of " + what_ + " must be a string, got " + Dump(v));
    return v.get<std::string>();
  }

  Eigen::Vector3d Vector3(const char* key) {
    const json& v = Get(key);
    if (!v.is_array() || v.size() != 3) {
      Fail(Path(key), "field '" + std::string(key) + "' of " + what_ +
                          " must be an array of 3 numbers, got " + Dump(v));
    }
    Eigen::Vector3d out;
    for (int i = 0; i < 3; ++i) {
      if (!v[i].is_number())
        Fail(Path(key) + "/" + std::to_string(i), "must be a number, got " + Dump(v[i]));
      out[i] = v[i].get<double>();
    }
    return out;
  }
  Eigen::Vector3d Vector3(const char* key, const Eigen::Vector3d& fallback) {
    if (!Has(key)) {
      used_.insert(key);
      return fallback;
    }
    return Vector3(key);
  }

  std::vector<Eigen::Vector2d> Points2(const char* key) {
    const json& v = Get(key);
    if (!v.is_array())
      Fail(Path(key), "field '" + std::string(key) + "' of " + what_ +
                          " must be an array of [x, y] pairs, got " + Dump(v));
    std::vector<Eigen::Vector2d> out;
    for (size_t i = 0; i < v.size(); ++i) {
      const json& p = v[i];
      const std::string at = Path(key) + "/" + std::to_string(i);
      if (!p.is_array() || p.size() != 2 || !p[0].is_number() || !p[1].is_number()) {
        Fail(at, "profile vertex must be an array of 2 numbers [x, y], got " + Dump(p));
      }
      out.emplace_back(p[0].get<double>(), p[1].get<double>());
    }
    return out;
  }

  // Rejects fields that were never asked for (typos such as "raduis").
  void RejectUnknown(const std::set<std::string>& also_allowed) const {
    for (auto it = j_.begin(); it != j_.end(); ++it) {
      if (used_.count(it.key()) == 0 && also_allowed.count(it.key()) == 0) {
        std::string known;
        for (const std::string& k : used_) known += (known.empty() ? "" : ", ") + k;
        for (const std::string& k : also_allowed) known += (known.empty() ? "" : ", ") + k;
        Fail(Path(it.key()),
             "unknown field '" + it.key() + "' in " + what_ + " (fields: " + known + ")");
      }
    }
  }

  std::string Path(const std::string& key) const { return path_ + "/" + EscapePointerToken(key); }

 private:
  static std::string Dump(const json& v) {
    std::string s = v.dump();
    if (s.size() > 60) s = s.substr(0, 57) + "...";
    return s;
  }

  const json& j_;
  std::string path_;
  std::string what_;
  std::set<std::string> used_;
};

NodeParams ReadParams(const std::string& type, ObjectReader& r) {
  if (type == "sphere") return SphereParams{r.Number("radius")};
  if (type == "box") return BoxParams{r.Vector3("size")};
  if (type == "rounded_box") return RoundedBoxParams{r.Vector3("size"), r.Number("radius")};
  if (type == "cylinder") {
    CylinderParams p;
    p.radius = r.Number("radius");
    p.height = r.Number("height");
    return p;
  }
  if (type == "capsule") {
    CapsuleParams p;
    p.a = r.Vector3("a");
    p.b = r.Vector3("b");
    p.radius = r.Number("radius");
    return p;
  }
  if (type == "cone") {
    ConeParams p;
    p.radius_bottom = r.Number("radius_bottom");
    p.radius_top = r.Number("radius_top");
    p.height = r.Number("height");
    return p;
  }
  if (type == "torus") {
    TorusParams p;
    p.major_radius = r.Number("major_radius");
    p.minor_radius = r.Number("minor_radius");
    return p;
  }
  if (type == "half_space") {
    HalfSpaceParams p;
    p.normal = r.Vector3("normal");
    p.offset = r.Number("offset", 0.0);
    return p;
  }
  if (type == "extrusion") {
    ExtrusionParams p;
    p.profile = r.Points2("profile");
    p.height = r.Number("height");
    return p;
  }
  if (type == "union") return UnionParams{};
  if (type == "intersection") return IntersectionParams{};
  if (type == "difference") return DifferenceParams{};
  if (type == "smooth_union") return SmoothUnionParams{r.Number("radius")};
  if (type == "smooth_intersection") return SmoothIntersectionParams{r.Number("radius")};
  if (type == "smooth_difference") return SmoothDifferenceParams{r.Number("radius")};
  if (type == "offset") return OffsetParams{r.Number("distance")};
  if (type == "shell") return ShellParams{r.Number("thickness")};
  if (type == "translate") return TranslateParams{r.Vector3("translation")};
  if (type == "rotate") {
    RotateParams p;
    p.axis = r.Vector3("axis");
    p.angle = r.Number("angle");
    return p;
  }
  if (type == "scale") {
    ScaleParams p;
    // "factors": one number (uniform) or [sx, sy, sz].
    if (r.Has("factors") && r.Get("factors").is_number()) {
      p.factors = Eigen::Vector3d::Constant(r.Number("factors"));
    } else {
      p.factors = r.Vector3("factors");
    }
    return p;
  }
  if (type == "mirror") {
    MirrorParams p;
    p.normal = r.Vector3("normal");
    p.offset = r.Number("offset", 0.0);
    p.keep_original = r.Bool("keep_original", false);
    return p;
  }
  if (type == "linear_array") {
    LinearArrayParams p;
    p.step = r.Vector3("step");
    p.count = r.Count("count");
    return p;
  }
  if (type == "polar_array") {
    PolarArrayParams p;
    p.axis = r.Vector3("axis", Eigen::Vector3d(0, 0, 1));
    p.count = r.Count("count");
    p.step_angle = r.Number("step_angle", p.count > 0 ? 2.0 * M_PI / p.count : 0.0);
    return p;
  }
  Fail(r.Path("type"), "unknown node type '" + type +
                           "' (types: sphere, box, rounded_box, cylinder, capsule, cone, torus, "
                           "half_space, extrusion, union, "
                           "intersection, difference, smooth_union, smooth_intersection, "
                           "smooth_difference, offset, shell, translate, "
                           "rotate, scale, mirror, linear_array, polar_array)");
}

// The parameter fields of each node type (besides type, id, name, children).
const std::map<std::string, std::vector<const char*>> kFields = {
    {"sphere", {"radius"}},
    {"box", {"size"}},
    {"rounded_box", {"size", "radius"}},
    {"cylinder", {"radius", "height"}},
    {"capsule", {"a", "b", "radius"}},
    {"cone", {"radius_bottom", "radius_top", "height"}},
    {"torus", {"major_radius", "minor_radius"}},
    {"half_space", {"normal", "offset"}},
    {"extrusion", {"profile", "height"}},
    {"union", {}},
    {"intersection", {}},
    {"difference", {}},
    {"smooth_union", {"radius"}},
    {"smooth_intersection", {"radius"}},
    {"smooth_difference", {"radius"}},
    {"offset", {"distance"}},
    {"shell", {"thickness"}},
    {"translate", {"translation"}},
    {"rotate", {"axis", "angle"}},
    {"scale", {"factors"}},
    {"mirror", {"normal", "offset", "keep_original"}},
    {"linear_array", {"step", "count"}},
    {"polar_array", {"axis", "count", "step_angle"}},
};

json Vec(const Eigen::Vector3d& v) { return json::array({v.x(), v.y(), v.z()}); }

// Splits a JSON pointer into unescaped tokens.
std::vector<std::string> PointerTokens(const std::string& pointer) {
  std::vector<std::string> tokens;
  size_t i = 0;
  while (i < pointer.size() && pointer[i] == '/') {
    const size_t next = pointer.find('/', i + 1);
    std::string token =
        pointer.substr(i + 1, next == std::string::npos ? std::string::npos : next - i - 1);
    std::string out;
    for (size_t k = 0; k < token.size(); ++k) {
      if (token[k] == '~' && k + 1 < token.size() && (token[k + 1] == '0' || token[k + 1] == '1')) {
        out += token[k + 1] == '1' ? '/' : '~';
        ++k;
      } else {
        out += token[k];
      }
    }
    tokens.push_back(out);
    if (next == std::string::npos) break;
    i = next;
  }
  return tokens;
}

// Finds, in syntactically valid JSON text, the byte offset of the value a pointer names, or
// of the deepest existing value along it when the pointer goes further than the document.
class PointerLocator {
 public:
  explicit PointerLocator(const std::string& s) : s_(s) {}

  size_t Locate(const std::string& pointer) {
    i_ = 0;
    Ws();
    size_t found = i_;
    for (const std::string& token : PointerTokens(pointer)) {
      Ws();
      if (i_ >= s_.size()) return found;
      if (s_[i_] == '{') {
        ++i_;
        bool hit = false;
        while (true) {
          Ws();
          if (i_ >= s_.size() || s_[i_] != '"') return found;
          const std::string key = ReadString();
          Ws();
          if (i_ >= s_.size() || s_[i_] != ':') return found;
          ++i_;
          Ws();
          if (key == token) {
            hit = true;
            break;
          }
          SkipValue();
          Ws();
          if (i_ < s_.size() && s_[i_] == ',') {
            ++i_;
            continue;
          }
          return found;
        }
        if (!hit) return found;
        found = i_;
      } else if (s_[i_] == '[') {
        // An index the text cannot hold (too many digits for any array here) points nowhere.
        if (token.empty() || token.size() > 15 ||
            token.find_first_not_of("0123456789") != std::string::npos) {
          return found;
        }
        const long long index = std::stoll(token);
        ++i_;
        for (long long k = 0; k < index; ++k) {
          Ws();
          if (i_ < s_.size() && s_[i_] == ']') return found;
          SkipValue();
          Ws();
          if (i_ >= s_.size() || s_[i_] != ',') return found;
          ++i_;
        }
        Ws();
        if (i_ >= s_.size() || s_[i_] == ']') return found;
        found = i_;
      } else {
        return found;
      }
    }
    return found;
  }

 private:
  void Ws() {
    while (i_ < s_.size() && std::isspace(static_cast<unsigned char>(s_[i_]))) ++i_;
  }
  std::string ReadString() {
    std::string out;
    ++i_;
    while (i_ < s_.size() && s_[i_] != '"') {
      if (s_[i_] == '\\' && i_ + 1 < s_.size()) {
        out += s_[i_ + 1];  // good enough for the plain ASCII keys of this format
        i_ += 2;
        continue;
      }
      out += s_[i_++];
    }
    ++i_;
    return out;
  }
  void SkipValue() {
    Ws();
    if (i_ >= s_.size()) return;
    if (s_[i_] == '"') {
      ReadString();
      return;
    }
    if (s_[i_] == '{' || s_[i_] == '[') {
      int depth = 0;
      while (i_ < s_.size()) {
        const char c = s_[i_];
        if (c == '"') {
          ReadString();
          continue;
        }
        if (c == '{' || c == '[') ++depth;
        if (c == '}' || c == ']') {
          --depth;
          if (depth == 0) {
            ++i_;
            return;
          }
        }
        ++i_;
      }
      return;
    }
    while (i_ < s_.size() && s_[i_] != ',' && s_[i_] != '}' && s_[i_] != ']' &&
           !std::isspace(static_cast<unsigned char>(s_[i_]))) {
      ++i_;
    }
  }

  const std::string& s_;
  size_t i_ = 0;
};

// 1-based line and column of a 0-based byte offset.
void LineColumn(const std::string& text, size_t offset, int* line, int* column) {
  offset = std::min(offset, text.size());
  *line = 1;
  size_t line_start = 0;
  for (size_t i = 0; i < offset; ++i) {
    if (text[i] == '\n') {
      ++*line;
      line_start = i + 1;
    }
  }
  *column = static_cast<int>(offset - line_start) + 1;
}

}  // namespace

void LocateJsonPointer(const std::string& text, const std::string& pointer, int* line,
                       int* column) {
  PointerLocator locator(text);
  LineColumn(text, locator.Locate(pointer), line, column);
}

SceneError::SceneError(const std::string& file, int line, int column, const std::string& pointer,
                       const std::string& what)
    : std::runtime_error(Location(file, line, column, pointer) + what),
      file_(file),
      line_(line),
      column_(column),
      pointer_(pointer),
      message_(what) {}

namespace {

// NodeFromJson below one node: depth is the node's level (root 1), *count the nodes read so far.
ImplicitNode ReadNode(const json& j, const std::string& path, int depth, long* count) {
  if (depth > kMaxTreeDepth) {
    Fail(path, "the node tree is deeper than " + std::to_string(kMaxTreeDepth) +
                   " levels (the limit of docs/limits.md); flatten it, e.g. fold nested translate "
                   "nodes into one, "
                   "or put siblings under one union instead of nesting them");
  }
  if (++*count > kMaxTreeNodes) {
    Fail(path, "the node tree has more than " + std::to_string(kMaxTreeNodes) +
                   " nodes (the limit of docs/limits.md); use linear_array or polar_array nodes "
                   "for repeated parts, "
                   "or split the solid");
  }
  ObjectReader r(j, path.empty() ? "" : path, "a node");
  if (!r.Has("type"))
    Fail(path, "a node needs a field 'type' (e.g. \"sphere\", \"union\", \"translate\")");
  const std::string type = r.String("type", "");
  ObjectReader params(j, path, "a " + type + " node");
  ImplicitNode node;
  // Unknown fields first: a misspelt field would otherwise be reported as a missing one.
  const auto fields = kFields.find(type);
  if (fields != kFields.end()) {
    for (auto it = j.begin(); it != j.end(); ++it) {
      const std::string& key = it.key();
      if (key == "type" || key == "id" || key == "name" || key == "children") continue;
      if (std::find(fields->second.begin(), fields->second.end(), key) == fields->second.end()) {
        std::string known = "type, id, name, children";
        for (const char* f : fields->second) known += std::string(", ") + f;
        Fail(path + "/" + EscapePointerToken(key),
             "unknown field '" + key + "' in a " + type + " node (fields: " + known + ")");
      }
    }
  }
  node.params = ReadParams(type, params);
  node.id = params.String("id", "");
  node.name = params.String("name", "");
  if (params.Has("children")) {
    const json& children = params.Get("children");
    if (!children.is_array())
      Fail(path + "/children",
           "field 'children' must be an array of nodes, got " + std::string(children.type_name()));
    for (size_t i = 0; i < children.size(); ++i) {
      node.children.push_back(
          ReadNode(children[i], path + "/children/" + std::to_string(i), depth + 1, count));
    }
  }
  params.RejectUnknown({"type"});
  return node;
}

}  // namespace

ImplicitNode NodeFromJson(const json& j, const std::string& path) {
  long count = 0;
  return ReadNode(j, path, 1, &count);
}

json NodeToJson(const ImplicitNode& node) {
  json j;
  j["type"] = NodeTypeName(node.params);
  if (!node.id.empty()) j["id"] = node.id;
  if (!node.name.empty()) j["name"] = node.name;
  std::visit(Overloaded{
                 [&](const SphereParams& p) { j["radius"] = p.radius; },
                 [&](const BoxParams& p) { j["size"] = Vec(p.size); },
                 [&](const RoundedBoxParams& p) {
                   j["size"] = Vec(p.size);
                   j["radius"] = p.radius;
                 },
                 [&](const CylinderParams& p) {
                   j["radius"] = p.radius;
                   j["height"] = p.height;
                 },
                 [&](const CapsuleParams& p) {
                   j["a"] = Vec(p.a);
                   j["b"] = Vec(p.b);
                   j["radius"] = p.radius;
                 },
                 [&](const ConeParams& p) {
                   j["radius_bottom"] = p.radius_bottom;
                   j["radius_top"] = p.radius_top;
                   j["height"] = p.height;
                 },
                 [&](const TorusParams& p) {
                   j["major_radius"] = p.major_radius;
                   j["minor_radius"] = p.minor_radius;
                 },
                 [&](const HalfSpaceParams& p) {
                   j["normal"] = Vec(p.normal);
                   j["offset"] = p.offset;
                 },
                 [&](const ExtrusionParams& p) {
                   json profile = json::array();
                   for (const Eigen::Vector2d& v : p.profile) profile.push_back({v.x(), v.y()});
                   j["profile"] = profile;
                   j["height"] = p.height;
                 },
                 [&](const UnionParams&) {},
                 [&](const IntersectionParams&) {},
                 [&](const DifferenceParams&) {},
                 [&](const SmoothUnionParams& p) { j["radius"] = p.radius; },
                 [&](const SmoothIntersectionParams& p) { j["radius"] = p.radius; },
                 [&](const SmoothDifferenceParams& p) { j["radius"] = p.radius; },
                 [&](const OffsetParams& p) { j["distance"] = p.distance; },
                 [&](const ShellParams& p) { j["thickness"] = p.thickness; },
                 [&](const TranslateParams& p) { j["translation"] = Vec(p.translation); },
                 [&](const RotateParams& p) {
                   j["axis"] = Vec(p.axis);
                   j["angle"] = p.angle;
                 },
                 [&](const ScaleParams& p) { j["factors"] = Vec(p.factors); },
                 [&](const MirrorParams& p) {
                   j["normal"] = Vec(p.normal);
                   j["offset"] = p.offset;
                   j["keep_original"] = p.keep_original;
                 },
                 [&](const LinearArrayParams& p) {
                   j["step"] = Vec(p.step);
                   j["count"] = p.count;
                 },
                 [&](const PolarArrayParams& p) {
                   j["axis"] = Vec(p.axis);
                   j["count"] = p.count;
                   j["step_angle"] = p.step_angle;
                 },
             },
             node.params);
  if (!node.children.empty()) {
    json children = json::array();
    for (const ImplicitNode& c : node.children) children.push_back(NodeToJson(c));
    j["children"] = children;
  }
  return j;
}

namespace {

// Reads a pose's rotation: "quaternion": [w, x, y, z] (normalised here), or "axis": [x, y, z]
// with "angle" (rad), or neither (identity).
Eigen::Quaterniond ReadRotation(ObjectReader& r, const std::string& path) {
  if (r.Has("quaternion")) {
    if (r.Has("axis") || r.Has("angle")) {
      Fail(path, "give the rotation either as 'quaternion' or as 'axis' and 'angle', not both");
    }
    const json& v = r.Get("quaternion");
    if (!v.is_array() || v.size() != 4)
      Fail(path + "/quaternion", "must be an array of 4 numbers [w, x, y, z], got " + v.dump());
    double q[4];
    for (int i = 0; i < 4; ++i) {
      if (!v[i].is_number())
        Fail(path + "/quaternion/" + std::to_string(i), "must be a number, got " + v[i].dump());
      q[i] = v[i].get<double>();
    }
    Eigen::Quaterniond out(q[0], q[1], q[2], q[3]);
    const double n = out.norm();
    if (!(n > 1e-12) || !std::isfinite(n))
      Fail(path + "/quaternion", "must be a non-zero finite quaternion, got " + v.dump());
    // A unit quaternion (as saved) is kept bit for bit, so that save/load round trips exactly.
    if (std::abs(n - 1.0) > 1e-15) out.normalize();
    return out;
  }
  const double angle = r.Number("angle", 0.0);
  if (!std::isfinite(angle)) Fail(path + "/angle", "must be finite");
  const Eigen::Vector3d axis = r.Vector3("axis", Eigen::Vector3d::UnitZ());
  if (!axis.allFinite() || !(axis.norm() > 1e-12))
    Fail(path + "/axis", "must be a non-zero finite vector");
  return Eigen::Quaterniond(Eigen::AngleAxisd(angle, axis.normalized()));
}

double ReadTolerance(ObjectReader& r, const char* key, double fallback, const std::string& path) {
  const double v = r.Number(key, fallback);
  if (!(v >= 0) || !std::isfinite(v))
    Fail(path + "/" + key, "must be finite and >= 0, got " + std::to_string(v));
  return v;
}

json QuaternionJson(const Eigen::Quaterniond& q) {
  return json::array({q.w(), q.x(), q.y(), q.z()});
}

// The "parts" array of a scene; checks names against the scene's solids and parts.
std::vector<ScenePart> ReadParts(const json& parts, const std::vector<Solid>& solids) {
  if (!parts.is_array())
    Fail("/parts", "must be an array of parts, got " + std::string(parts.type_name()));
  std::vector<ScenePart> out;
  for (size_t i = 0; i < parts.size(); ++i) {
    const std::string path = "/parts/" + std::to_string(i);
    ObjectReader r(parts[i], path, "a part");
    ScenePart part;
    part.name = r.String("name", "");
    if (part.name.empty()) Fail(path + "/name", "a part needs a non-empty name");
    for (const ScenePart& other : out) {
      if (other.name == part.name) Fail(path + "/name", "duplicate part name '" + part.name + "'");
    }
    part.solid = r.String("solid", "");
    if (std::none_of(solids.begin(), solids.end(),
                     [&](const Solid& s) { return s.name == part.solid; })) {
      Fail(path + "/solid", "no solid named '" + part.solid + "' in the scene");
    }
    part.position = r.Vector3("position", Eigen::Vector3d::Zero());
    if (!part.position.allFinite()) Fail(path + "/position", "must be finite");
    part.rotation = ReadRotation(r, path);
    const std::string kind = r.String("kind", "graspable");
    if (kind != "fixed" && kind != "graspable") {
      Fail(path + "/kind", "must be \"fixed\" or \"graspable\", got \"" + kind + "\"");
    }
    part.fixed = kind == "fixed";
    if (r.Has("seats")) {
      const json& seats = r.Get("seats");
      if (!seats.is_array())
        Fail(path + "/seats", "must be an array of seats, got " + std::string(seats.type_name()));
      for (size_t k = 0; k < seats.size(); ++k) {
        const std::string sp = path + "/seats/" + std::to_string(k);
        ObjectReader sr(seats[k], sp, "a seat");
        SceneSeat seat;
        seat.on = sr.String("on", "");
        if (seat.on.empty()) Fail(sp + "/on", "a seat needs the name of the part it sits on");
        if (seat.on == part.name)
          Fail(sp + "/on", "a part cannot sit on itself ('" + seat.on + "')");
        seat.position = sr.Vector3("position", Eigen::Vector3d::Zero());
        if (!seat.position.allFinite()) Fail(sp + "/position", "must be finite");
        seat.rotation = ReadRotation(sr, sp);
        seat.position_tolerance =
            ReadTolerance(sr, "position_tolerance", seat.position_tolerance, sp);
        seat.angle_tolerance = ReadTolerance(sr, "angle_tolerance", seat.angle_tolerance, sp);
        sr.RejectUnknown({});
        part.seats.push_back(seat);
      }
    }
    r.RejectUnknown({});
    out.push_back(std::move(part));
  }
  // Seats name parts that exist (any order).
  for (size_t i = 0; i < out.size(); ++i) {
    for (size_t k = 0; k < out[i].seats.size(); ++k) {
      const std::string& on = out[i].seats[k].on;
      if (std::none_of(out.begin(), out.end(), [&](const ScenePart& p) { return p.name == on; })) {
        Fail("/parts/" + std::to_string(i) + "/seats/" + std::to_string(k) + "/on",
             "no part named '" + on + "'");
      }
    }
  }
  return out;
}

// The "snap" object of a scene: every field optional, each > 0 and finite.
SceneSnap ReadSnap(const json& j) {
  ObjectReader r(j, "/snap", "the snap settings");
  SceneSnap snap;
  const auto positive = [&](const char* key, double fallback) {
    const double v = r.Number(key, fallback);
    if (!(v > 0) || !std::isfinite(v)) {
      Fail(std::string("/snap/") + key,
           std::string("field '") + key + "' must be finite and > 0, got " + json(v).dump());
    }
    return v;
  };
  snap.max_force = positive("max_force", snap.max_force);
  snap.vertex_radius = positive("vertex_radius", snap.vertex_radius);
  snap.edge_radius = positive("edge_radius", snap.edge_radius);
  snap.face_radius = positive("face_radius", snap.face_radius);
  r.RejectUnknown({});
  return snap;
}

}  // namespace

Scene SceneFromJson(const json& j, const std::string& source) {
  try {
    ObjectReader r(j, "", "a scene document");
    const json& format = r.Get("format");
    if (!format.is_string() || format.get<std::string>() != kSceneFormat) {
      Fail("/format", std::string("must be \"") + kSceneFormat + "\", got " + format.dump());
    }
    const json& version = r.Get("version");
    if (!version.is_number_integer() || version.get<long long>() != kSceneVersion) {
      Fail("/version", "unsupported scene version " + version.dump() +
                           " (this build reads version " + std::to_string(kSceneVersion) + ")");
    }
    const std::string units = r.String("units", "m");
    if (units != "m") Fail("/units", "must be \"m\" (scenes are in metres), got \"" + units + "\"");
    Scene scene;
    scene.description = r.String("description", "");
    const json& solids = r.Get("solids");
    if (!solids.is_array())
      Fail("/solids", "must be an array of solids, got " + std::string(solids.type_name()));
    for (size_t i = 0; i < solids.size(); ++i) {
      const std::string path = "/solids/" + std::to_string(i);
      ObjectReader s(solids[i], path, "a solid");
      Solid solid;
      solid.name = s.String("name", "");
      solid.root = NodeFromJson(s.Get("root"), path + "/root");
      s.RejectUnknown({});
      try {
        ValidateTree(solid.root, path + "/root");
      } catch (const ModelError& e) {
        Fail(e.path() + "/" + e.field(), e.what());
      }
      scene.solids.push_back(std::move(solid));
    }
    if (r.Has("parts")) scene.parts = ReadParts(r.Get("parts"), scene.solids);
    if (r.Has("snap")) scene.snap = ReadSnap(r.Get("snap"));
    r.RejectUnknown({});
    return scene;
  } catch (const SceneError& e) {
    throw SceneError(source, e.line(), e.column(), e.pointer(), e.message());
  }
}

json SceneToJson(const Scene& scene) {
  json j;
  j["format"] = kSceneFormat;
  j["version"] = kSceneVersion;
  j["units"] = "m";
  if (!scene.description.empty()) j["description"] = scene.description;
  json solids = json::array();
  for (const Solid& s : scene.solids) {
    json js;
    js["name"] = s.name;
    js["root"] = NodeToJson(s.root);
    solids.push_back(js);
  }
  j["solids"] = solids;
  if (!scene.parts.empty()) {
    json parts = json::array();
    for (const ScenePart& p : scene.parts) {
      json jp;
      jp["name"] = p.name;
      jp["solid"] = p.solid;
      jp["position"] = Vec(p.position);
      jp["quaternion"] = QuaternionJson(p.rotation);
      jp["kind"] = p.fixed ? "fixed" : "graspable";
      if (!p.seats.empty()) {
        json seats = json::array();
        for (const SceneSeat& seat : p.seats) {
          json js;
          js["on"] = seat.on;
          js["position"] = Vec(seat.position);
          js["quaternion"] = QuaternionJson(seat.rotation);
          js["position_tolerance"] = seat.position_tolerance;
          js["angle_tolerance"] = seat.angle_tolerance;
          seats.push_back(js);
        }
        jp["seats"] = seats;
      }
      parts.push_back(jp);
    }
    j["parts"] = parts;
  }
  if (scene.snap) {
    json snap;
    snap["max_force"] = scene.snap->max_force;
    snap["vertex_radius"] = scene.snap->vertex_radius;
    snap["edge_radius"] = scene.snap->edge_radius;
    snap["face_radius"] = scene.snap->face_radius;
    j["snap"] = snap;
  }
  return j;
}

namespace {

// Streaming pass over the text before the document is built (nlohmann's SAX parser is not
// recursive): refuses nesting deeper than kMaxJsonDepth and keeps the JSON pointer of the value
// being read, so that errors (a number beyond a double) can name the field.
class PrescanHandler {
 public:
  bool null() { return Value(); }
  bool boolean(bool) { return Value(); }
  bool number_integer(json::number_integer_t) { return Value(); }
  bool number_unsigned(json::number_unsigned_t) { return Value(); }
  bool number_float(json::number_float_t, const json::string_t&) { return Value(); }
  bool string(json::string_t&) { return Value(); }
  bool binary(json::binary_t&) { return Value(); }
  bool start_object(std::size_t) { return Open(false); }
  bool key(json::string_t& k) {
    frames_.back().key = k;
    return true;
  }
  bool end_object() { return Close(); }
  bool start_array(std::size_t) { return Open(true); }
  bool end_array() { return Close(); }
  bool parse_error(std::size_t position, const std::string& last_token,
                   const nlohmann::detail::exception& e) {
    error_position = position;
    error_token = last_token;
    error_id = e.id;
    error_what = e.what();
    error_pointer = Pointer(true);
    return false;
  }

  bool too_deep = false;           // nesting passed kMaxJsonDepth
  std::size_t error_position = 0;  // parse_error: bytes read (1-based index of the last one)
  std::string error_token;
  int error_id = 0;
  std::string error_what;
  std::string error_pointer;  // of the value being read when it stopped

 private:
  struct Frame {
    bool array = false;
    long long next = 0;  // arrays: index of the next element
    std::string key;     // objects: the current key
  };

  bool Value() {
    if (!frames_.empty() && frames_.back().array) ++frames_.back().next;
    return true;
  }
  bool Open(bool array) {
    Value();
    if (static_cast<int>(frames_.size()) >= kMaxJsonDepth) {
      too_deep = true;
      error_pointer = Pointer(false);
      return false;
    }
    frames_.push_back({array, 0, {}});
    return true;
  }
  bool Close() {
    frames_.pop_back();
    return true;
  }
  // Pointer of the value begun last (pending: of the value about to begin).
  std::string Pointer(bool pending) const {
    std::string out;
    for (size_t i = 0; i < frames_.size(); ++i) {
      const Frame& f = frames_[i];
      const bool last = i + 1 == frames_.size();
      if (f.array) {
        out += "/" + std::to_string(pending && last ? f.next : f.next - 1);
      } else {
        out += "/" + EscapePointerToken(f.key);
      }
    }
    return out;
  }

  std::vector<Frame> frames_;
};

// Byte offset of the bracket that opens nesting level kMaxJsonDepth + 1 (strings skipped), or
// the text's size.
size_t TooDeepOffset(const std::string& text) {
  int depth = 0;
  for (size_t i = 0; i < text.size(); ++i) {
    const char c = text[i];
    if (c == '"') {
      for (++i; i < text.size() && text[i] != '"'; ++i) {
        if (text[i] == '\\') ++i;
      }
    } else if (c == '[' || c == '{') {
      if (++depth > kMaxJsonDepth) return i;
    } else if (c == ']' || c == '}') {
      --depth;
    }
  }
  return text.size();
}

}  // namespace

json ParseJsonText(const std::string& text, const std::string& source) {
  PrescanHandler prescan;
  int line = 0, column = 0;
  if (!json::sax_parse(text, &prescan)) {
    if (prescan.too_deep) {
      LineColumn(text, TooDeepOffset(text), &line, &column);
      throw SceneError(
          source, line, column, prescan.error_pointer,
          "JSON arrays and objects nest deeper than " + std::to_string(kMaxJsonDepth) +
              " levels (the limit of docs/limits.md); a scene or document needs far fewer: check "
              "the file is a spidarcad file and flatten its node tree");
    }
    if (prescan.error_id == 406) {
      // A number beyond a double: point at its first character (the lexer stopped just after it).
      const size_t end = std::min(prescan.error_position, text.size());
      size_t begin = end >= prescan.error_token.size() ? end - prescan.error_token.size() : 0;
      while (begin > 0 && text.compare(begin, prescan.error_token.size(), prescan.error_token) != 0)
        --begin;
      LineColumn(text, begin, &line, &column);
      throw SceneError(source, line, column, prescan.error_pointer,
                       "the number " + prescan.error_token +
                           " is out of range (a double holds magnitudes up to about 1.8e308); "
                           "write a finite number");
    }
    // e.byte-style position: the 1-based index of the last character read.
    LineColumn(text, prescan.error_position > 0 ? prescan.error_position - 1 : 0, &line, &column);
    std::string what = prescan.error_what;
    // Drop nlohmann's own "[json.exception.parse_error.101] parse error at line L, column C: ".
    const size_t colon = what.find(": ");
    if (colon != std::string::npos) what = what.substr(colon + 2);
    throw SceneError(source, line, column, "", "JSON syntax error: " + what);
  }
  try {
    return json::parse(text);
  } catch (const json::exception& e) {  // not expected after the prescan
    throw SceneError(source, 0, 0, "", std::string("JSON error: ") + e.what());
  }
}

Scene ParseScene(const std::string& text, const std::string& source) {
  return ParseScene(ParseJsonText(text, source), text, source);
}

Scene ParseScene(const json& parsed, const std::string& text, const std::string& source) {
  try {
    return SceneFromJson(parsed, source);
  } catch (const SceneError& e) {
    PointerLocator locator(text);
    int line = 0, column = 0;
    LineColumn(text, locator.Locate(e.pointer()), &line, &column);
    throw SceneError(source, line, column, e.pointer(), e.message());
  }
}

std::string ReadBoundedFile(const std::string& path, long long max_bytes, const std::string& what) {
  std::error_code ec;
  const std::filesystem::file_status status = std::filesystem::status(path, ec);
  if (ec || !std::filesystem::exists(status)) {
    throw SceneError(path, 0, 0, "",
                     "cannot open the " + what + " for reading (no such file); check the path");
  }
  if (!std::filesystem::is_regular_file(status)) {
    throw SceneError(
        path, 0, 0, "",
        "is not a regular file (a directory, device or pipe); give the path of a " + what);
  }
  const std::uintmax_t size = std::filesystem::file_size(path, ec);
  if (ec) throw SceneError(path, 0, 0, "", "cannot read the size of the " + what);
  const std::string limit =
      std::to_string(max_bytes) + " bytes" +
      (max_bytes >= (1LL << 20) ? " (" + std::to_string(max_bytes >> 20) + " MiB)" : "");
  if (size > static_cast<std::uintmax_t>(max_bytes)) {
    throw SceneError(path, 0, 0, "",
                     "the file is " + std::to_string(size) + " bytes, more than the " + limit +
                         " a " + what + " may have (docs/limits.md); is it a " + what + "?");
  }
  std::ifstream in(path, std::ios::binary);
  if (!in)
    throw SceneError(path, 0, 0, "",
                     "cannot open the " + what + " for reading (check its permissions)");
  // Read at most the cap (plus one byte to notice a file that grew meanwhile).
  std::string text(static_cast<size_t>(size) + 1, '\0');
  in.read(text.data(), static_cast<std::streamsize>(text.size()));
  text.resize(static_cast<size_t>(in.gcount()));
  if (text.size() > static_cast<size_t>(max_bytes)) {
    throw SceneError(path, 0, 0, "",
                     "the file grew past the " + limit + " " + what + " limit while being read");
  }
  return text;
}

Scene LoadScene(const std::string& path) {
  const std::string text = ReadBoundedFile(path, kMaxSceneFileBytes, "scene file");
  try {
    return ParseScene(text, path);
  } catch (const std::bad_alloc&) {
    throw SceneError(
        path, 0, 0, "",
        "out of memory while reading the scene (" + std::to_string(text.size()) + " bytes)");
  }
}

void SaveScene(const Scene& scene, const std::string& path) {
  const std::string text = SceneToJson(scene).dump(2) + "\n";
  const std::string temporary = path + ".tmp";
  {
    std::ofstream out(temporary, std::ios::binary | std::ios::trunc);
    if (!out) throw SceneError(path, 0, 0, "", "cannot open '" + temporary + "' for writing");
    out << text;
    out.flush();
    if (!out) throw SceneError(path, 0, 0, "", "writing '" + temporary + "' failed");
  }
  std::error_code ec;
  std::filesystem::rename(temporary, path, ec);
  if (ec) {
    std::filesystem::remove(temporary, ec);
    throw SceneError(path, 0, 0, "", "cannot rename the temporary file over the scene file");
  }
}

}  // namespace spidarcad::modeling
