// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#include "scene/document_file.h"

#include <cstdint>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <variant>

#include "doc/document_io.h"
#include "doc/input_error.h"

namespace spidarcad::app {
namespace {

// Streams the JSON until the top level's "version" has been read; stops at once after it, on
// anything nested deeper than modeling::kMaxJsonDepth, and on a syntax error.
class VersionFinder : public nlohmann::json_sax<nlohmann::json> {
 public:
  int version() const { return version_; }

  bool null() override { return Value(); }
  bool boolean(bool) override { return Value(); }
  bool number_integer(number_integer_t v) override { return Integer(v); }
  bool number_unsigned(number_unsigned_t v) override {
    return Integer(v > 1000 ? 1000 : static_cast<std::int64_t>(v));
  }
  bool number_float(number_float_t, const string_t&) override { return Value(); }
  bool string(string_t&) override { return Value(); }
  bool binary(binary_t&) override { return Value(); }
  bool start_object(std::size_t) override { return Enter(); }
  bool end_object() override { return Leave(); }
  bool start_array(std::size_t) override { return Enter(); }
  bool end_array() override { return Leave(); }
  bool key(string_t& k) override {
    at_version_ = depth_ == 1 && k == "version";
    return true;
  }
  bool parse_error(std::size_t, const std::string&, const nlohmann::detail::exception&) override {
    return false;
  }

 private:
  bool Value() {
    const bool stop = at_version_;
    at_version_ = false;
    return !stop;
  }
  bool Integer(std::int64_t v) {
    if (at_version_) {
      version_ = v == 2 ? 2 : 1;
      return false;  // found: stop reading
    }
    return true;
  }
  bool Enter() {
    if (at_version_) return false;  // "version" is not a number: version 1's reader says so
    return ++depth_ <= modeling::kMaxJsonDepth;
  }
  bool Leave() {
    --depth_;
    return true;
  }

  int depth_ = 0;
  bool at_version_ = false;
  int version_ = 1;
};

}  // namespace

int DocumentFileVersion(const std::string& path) {
  std::error_code ec;
  if (!std::filesystem::is_regular_file(path, ec)) return 1;
  std::ifstream in(path, std::ios::binary);
  if (!in) return 1;
  VersionFinder finder;
  try {
    nlohmann::json::sax_parse(in, &finder);
  } catch (const std::exception&) {
    return 1;
  }
  return finder.version();
}

OpenedDocument OpenDocumentFile(const std::string& path) {
  OpenedDocument opened;
  opened.path = path;
  opened.doc = std::make_unique<Document>();
  opened.version = DocumentFileVersion(path);
  try {
    if (opened.version == 2) {
      ReadDocumentFile(path, opened.doc.get());
    } else {
      opened.doc->LoadScene(modeling::LoadScene(path), path);
    }
  } catch (const modeling::SceneError& e) {
    throw InputError(e.what());
  }
  return opened;
}

std::string ObjectPointer(const OpenedDocument& opened, ObjectId id) {
  const std::vector<DocObject>& objects = opened.doc->objects();
  int solids = 0;
  for (std::size_t i = 0; i < objects.size(); ++i) {
    if (objects[i].id == id)
      return opened.version == 2 ? "/objects/" + std::to_string(i)
                                 : "/solids/" + std::to_string(solids);
    if (std::holds_alternative<SolidData>(objects[i].data)) ++solids;
  }
  return "";
}

std::string ObjectNames(const Document& doc, const std::vector<std::string>& kinds) {
  std::string names;
  for (const DocObject& o : doc.objects()) {
    const std::string kind = ObjectKindName(o.data);
    bool wanted = kinds.empty();
    for (const std::string& k : kinds) wanted = wanted || k == kind;
    if (wanted) names += (names.empty() ? "" : ", ") + ("'" + o.name + "'");
  }
  return names.empty() ? "none" : names;
}

}  // namespace spidarcad::app
