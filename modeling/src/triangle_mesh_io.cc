// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#include "spidarcad/modeling/triangle_mesh_io.h"

#include <algorithm>
#include <array>
#include <cctype>
#include <cerrno>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <map>
#include <sstream>
#include <vector>

namespace spidarcad::modeling {

namespace {

std::string Location(const std::string& file, long line, long byte_offset) {
  std::string s = file;
  if (line > 0)
    s += ":" + std::to_string(line);
  else if (byte_offset >= 0)
    s += ": byte " + std::to_string(byte_offset);
  return s;
}

std::string Lower(std::string s) {
  for (char& c : s) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return s;
}

std::string Extension(const std::string& path) {
  const auto dot = path.find_last_of('.');
  const auto slash = path.find_last_of('/');
  if (dot == std::string::npos || (slash != std::string::npos && dot < slash)) return "";
  return Lower(path.substr(dot + 1));
}

std::string ReadWholeFile(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in)
    throw MeshFileError(path, 0, -1,
                        std::string("cannot open for reading: ") + std::strerror(errno));
  std::ostringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

// Builds a TriangleMesh from vectors, checking every index.
TriangleMesh Assemble(const std::vector<double>& xyz, const std::vector<int>& tri,
                      const std::vector<long>& tri_line, const std::string& file) {
  const long nv = static_cast<long>(xyz.size() / 3);
  TriangleMesh mesh;
  mesh.vertices.resize(3, nv);
  std::copy(xyz.begin(), xyz.end(), mesh.vertices.data());
  const long nf = static_cast<long>(tri.size() / 3);
  mesh.triangles.resize(3, nf);
  for (long f = 0; f < nf; ++f) {
    for (int k = 0; k < 3; ++k) {
      const int i = tri[3 * f + k];
      if (i < 0 || i >= nv) {
        throw MeshFileError(file, tri_line.empty() ? 0 : tri_line[f], -1,
                            "face " + std::to_string(f) + " has vertex index " + std::to_string(i) +
                                " outside [0, " + std::to_string(nv) + ")");
      }
      mesh.triangles(k, f) = i;
    }
    if (tri[3 * f] == tri[3 * f + 1] || tri[3 * f + 1] == tri[3 * f + 2] ||
        tri[3 * f] == tri[3 * f + 2]) {
      throw MeshFileError(file, tri_line.empty() ? 0 : tri_line[f], -1,
                          "face " + std::to_string(f) + " repeats a vertex (" +
                              std::to_string(tri[3 * f]) + ", " + std::to_string(tri[3 * f + 1]) +
                              ", " + std::to_string(tri[3 * f + 2]) + ")");
    }
  }
  return mesh;
}

// Whitespace tokens with their 1-based line numbers.
struct Token {
  std::string text;
  long line;
};

std::vector<Token> Tokenize(const std::string& text, size_t begin, size_t end, long first_line) {
  std::vector<Token> tokens;
  long line = first_line;
  size_t i = begin;
  while (i < end) {
    const char c = text[i];
    if (c == '\n') {
      ++line;
      ++i;
    } else if (std::isspace(static_cast<unsigned char>(c))) {
      ++i;
    } else {
      size_t j = i;
      while (j < end && !std::isspace(static_cast<unsigned char>(text[j]))) ++j;
      tokens.push_back({text.substr(i, j - i), line});
      i = j;
    }
  }
  return tokens;
}

double ParseDouble(const std::string& s, const std::string& file, long line,
                   const std::string& what) {
  char* end = nullptr;
  errno = 0;
  const double v = std::strtod(s.c_str(), &end);
  // Not errno == ERANGE: strtod sets it for underflow too, i.e. for a subnormal (finite) value
  // that the binary formats carry and the writers print. Overflow gives inf, refused here.
  if (s.empty() || end != s.c_str() + s.size() || !std::isfinite(v)) {
    throw MeshFileError(file, line, -1,
                        "expected a finite number for " + what + ", found '" + s + "'");
  }
  return v;
}

long ParseLong(const std::string& s, const std::string& file, long line, const std::string& what) {
  char* end = nullptr;
  errno = 0;
  const long v = std::strtol(s.c_str(), &end, 10);
  if (s.empty() || end != s.c_str() + s.size() || errno == ERANGE) {
    throw MeshFileError(file, line, -1, "expected an integer for " + what + ", found '" + s + "'");
  }
  return v;
}

// Welds vertices with identical coordinates (STL).
class Welder {
 public:
  int Add(const std::array<double, 3>& p) {
    auto [it, inserted] = index_.emplace(p, static_cast<int>(xyz_.size() / 3));
    if (inserted) xyz_.insert(xyz_.end(), p.begin(), p.end());
    return it->second;
  }
  const std::vector<double>& xyz() const { return xyz_; }

 private:
  std::map<std::array<double, 3>, int> index_;
  std::vector<double> xyz_;
};

// ---------------------------------------------------------------- STL

TriangleMesh ReadStlAscii(const std::string& text, const std::string& file) {
  const std::vector<Token> t = Tokenize(text, 0, text.size(), 1);
  size_t k = 0;
  auto expect = [&](const char* word) {
    if (k >= t.size())
      throw MeshFileError(file, t.empty() ? 1 : t.back().line, -1,
                          std::string("unexpected end of file, expected '") + word + "'");
    if (Lower(t[k].text) != word)
      throw MeshFileError(file, t[k].line, -1,
                          std::string("expected '") + word + "', found '" + t[k].text + "'");
    ++k;
  };
  auto number = [&](const char* what) {
    if (k >= t.size())
      throw MeshFileError(file, t.back().line, -1,
                          std::string("unexpected end of file, expected ") + what);
    const double v = ParseDouble(t[k].text, file, t[k].line, what);
    ++k;
    return v;
  };
  expect("solid");
  // The name runs to the end of the first line.
  while (k < t.size() && t[k].line == t[0].line) ++k;
  Welder welder;
  std::vector<int> tri;
  std::vector<long> tri_line;
  while (true) {
    if (k >= t.size())
      throw MeshFileError(file, t.back().line, -1,
                          "unexpected end of file, expected 'facet' or 'endsolid'");
    if (Lower(t[k].text) == "endsolid") break;
    const long facet_line = t[k].line;
    expect("facet");
    expect("normal");
    for (int i = 0; i < 3; ++i) number("facet normal component");
    expect("outer");
    expect("loop");
    int corner[3];
    for (int c = 0; c < 3; ++c) {
      expect("vertex");
      std::array<double, 3> p;
      for (int i = 0; i < 3; ++i) p[i] = number("vertex coordinate");
      corner[c] = welder.Add(p);
    }
    expect("endloop");
    expect("endfacet");
    if (corner[0] != corner[1] && corner[1] != corner[2] && corner[0] != corner[2]) {
      tri.insert(tri.end(), corner, corner + 3);
      tri_line.push_back(facet_line);
    }
  }
  return Assemble(welder.xyz(), tri, tri_line, file);
}

template <typename T>
T ReadLe(const std::string& data, size_t offset) {
  T v;
  std::memcpy(&v, data.data() + offset, sizeof(T));  // x86-64 is little-endian
  return v;
}

TriangleMesh ReadStlBinary(const std::string& data, const std::string& file) {
  if (data.size() < 84) {
    throw MeshFileError(
        file, 0, static_cast<long>(data.size()),
        "binary STL shorter than its 84-byte header (" + std::to_string(data.size()) + " bytes)");
  }
  const uint32_t n = ReadLe<uint32_t>(data, 80);
  const size_t expected = 84 + 50 * static_cast<size_t>(n);
  if (data.size() != expected) {
    throw MeshFileError(file, 0, 80,
                        "binary STL header announces " + std::to_string(n) + " triangles (" +
                            std::to_string(expected) + " bytes) but the file has " +
                            std::to_string(data.size()) + " bytes");
  }
  Welder welder;
  std::vector<int> tri;
  tri.reserve(3 * n);
  for (uint32_t f = 0; f < n; ++f) {
    const size_t base = 84 + 50 * static_cast<size_t>(f) + 12;
    int corner[3];
    for (int c = 0; c < 3; ++c) {
      std::array<double, 3> p;
      for (int i = 0; i < 3; ++i) {
        const size_t at = base + 12 * c + 4 * i;
        const float x = ReadLe<float>(data, at);
        if (!std::isfinite(x))
          throw MeshFileError(file, 0, static_cast<long>(at),
                              "non-finite vertex coordinate in triangle " + std::to_string(f));
        p[i] = x;
      }
      corner[c] = welder.Add(p);
    }
    if (corner[0] != corner[1] && corner[1] != corner[2] && corner[0] != corner[2])
      tri.insert(tri.end(), corner, corner + 3);
  }
  return Assemble(welder.xyz(), tri, {}, file);
}

TriangleMesh ReadStl(const std::string& file) {
  const std::string data = ReadWholeFile(file);
  bool size_matches = false;
  if (data.size() >= 84)
    size_matches = data.size() == 84 + 50 * static_cast<size_t>(ReadLe<uint32_t>(data, 80));
  size_t first = 0;
  while (first < data.size() && std::isspace(static_cast<unsigned char>(data[first]))) ++first;
  const bool starts_solid = Lower(data.substr(first, 5)) == "solid";
  if (starts_solid && !size_matches) return ReadStlAscii(data, file);
  return ReadStlBinary(data, file);
}

Eigen::Vector3d Normal(const TriangleMesh& mesh, Eigen::Index f) {
  const Eigen::Vector3d a = mesh.vertices.col(mesh.triangles(0, f)),
                        b = mesh.vertices.col(mesh.triangles(1, f)),
                        c = mesh.vertices.col(mesh.triangles(2, f));
  const Eigen::Vector3d n = (b - a).cross(c - a);
  const double len = n.norm();
  return len > 0 ? Eigen::Vector3d(n / len) : Eigen::Vector3d::Zero();
}

// ---------------------------------------------------------------- OBJ

TriangleMesh ReadObj(const std::string& file) {
  const std::string text = ReadWholeFile(file);
  std::vector<double> xyz;
  std::vector<int> tri;
  std::vector<long> tri_line;
  std::istringstream in(text);
  std::string line;
  long line_no = 0;
  while (std::getline(in, line)) {
    ++line_no;
    if (!line.empty() && line.back() == '\r') line.pop_back();
    const std::vector<Token> t = Tokenize(line, 0, line.size(), line_no);
    if (t.empty() || t[0].text[0] == '#') continue;
    if (t[0].text == "v") {
      if (t.size() < 4 || t.size() > 5)
        throw MeshFileError(file, line_no, -1,
                            "vertex needs 3 coordinates (and an optional w), found " +
                                std::to_string(t.size() - 1) + " values");
      for (int i = 1; i <= 3; ++i)
        xyz.push_back(ParseDouble(t[i].text, file, line_no, "vertex coordinate"));
    } else if (t[0].text == "f") {
      if (t.size() < 4)
        throw MeshFileError(
            file, line_no, -1,
            "face needs at least 3 vertices, found " + std::to_string(t.size() - 1));
      std::vector<int> corners;
      const long nv = static_cast<long>(xyz.size() / 3);
      for (size_t i = 1; i < t.size(); ++i) {
        const std::string first = t[i].text.substr(0, t[i].text.find('/'));
        const long v = ParseLong(first, file, line_no, "face vertex index");
        // 1-based; negative counts back from the last vertex defined so far.
        const long index = v > 0 ? v - 1 : nv + v;
        if (v == 0 || index < 0 || index >= nv) {
          throw MeshFileError(file, line_no, -1,
                              "face vertex index " + std::to_string(v) + " refers to no vertex (" +
                                  std::to_string(nv) + " defined so far)");
        }
        corners.push_back(static_cast<int>(index));
      }
      for (size_t i = 1; i + 1 < corners.size(); ++i) {
        tri.insert(tri.end(), {corners[0], corners[i], corners[i + 1]});
        tri_line.push_back(line_no);
      }
    }
    // Other statements (vt, vn, g, o, s, usemtl, mtllib, l, p, ...) carry nothing we keep.
  }
  return Assemble(xyz, tri, tri_line, file);
}

// ---------------------------------------------------------------- PLY

enum class PlyType { kInt8, kUint8, kInt16, kUint16, kInt32, kUint32, kFloat32, kFloat64 };

bool ParsePlyType(const std::string& s, PlyType* type) {
  static const std::map<std::string, PlyType> kTypes = {
      {"char", PlyType::kInt8},      {"int8", PlyType::kInt8},       {"uchar", PlyType::kUint8},
      {"uint8", PlyType::kUint8},    {"short", PlyType::kInt16},     {"int16", PlyType::kInt16},
      {"ushort", PlyType::kUint16},  {"uint16", PlyType::kUint16},   {"int", PlyType::kInt32},
      {"int32", PlyType::kInt32},    {"uint", PlyType::kUint32},     {"uint32", PlyType::kUint32},
      {"float", PlyType::kFloat32},  {"float32", PlyType::kFloat32}, {"double", PlyType::kFloat64},
      {"float64", PlyType::kFloat64}};
  const auto it = kTypes.find(s);
  if (it == kTypes.end()) return false;
  *type = it->second;
  return true;
}

size_t PlySize(PlyType t) {
  switch (t) {
    case PlyType::kInt8:
    case PlyType::kUint8:
      return 1;
    case PlyType::kInt16:
    case PlyType::kUint16:
      return 2;
    case PlyType::kInt32:
    case PlyType::kUint32:
    case PlyType::kFloat32:
      return 4;
    case PlyType::kFloat64:
      return 8;
  }
  return 0;
}

// Longest list a PLY file may declare (a count, e.g. of a face's corners, beyond int's range
// cannot be a real face and would not fit the indices).
constexpr double kMaxPlyListLength = 2147483647.0;

struct PlyProperty {
  std::string name;
  bool is_list = false;
  PlyType count_type = PlyType::kUint8;
  PlyType type = PlyType::kFloat32;
};

struct PlyElement {
  std::string name;
  long count = 0;
  long header_line = 0;
  std::vector<PlyProperty> properties;
};

// Reads values either from ASCII tokens or from binary little-endian bytes.
class PlyCursor {
 public:
  PlyCursor(const std::string& data, size_t begin, long first_line, bool binary,
            const std::string& file)
      : data_(data), pos_(begin), binary_(binary), file_(file) {
    if (!binary_) tokens_ = Tokenize(data, begin, data.size(), first_line);
  }
  double Read(PlyType type, const std::string& what) {
    if (!binary_) {
      if (k_ >= tokens_.size())
        throw MeshFileError(file_, tokens_.empty() ? 0 : tokens_.back().line, -1,
                            "unexpected end of data, expected " + what);
      const Token& t = tokens_[k_++];
      return ParseDouble(t.text, file_, t.line, what);
    }
    const size_t n = PlySize(type);
    if (pos_ + n > data_.size()) {
      throw MeshFileError(
          file_, 0, static_cast<long>(pos_),
          "unexpected end of data, expected " + what + " (" + std::to_string(n) + " bytes)");
    }
    double v = 0;
    switch (type) {
      case PlyType::kInt8:
        v = ReadLe<int8_t>(data_, pos_);
        break;
      case PlyType::kUint8:
        v = ReadLe<uint8_t>(data_, pos_);
        break;
      case PlyType::kInt16:
        v = ReadLe<int16_t>(data_, pos_);
        break;
      case PlyType::kUint16:
        v = ReadLe<uint16_t>(data_, pos_);
        break;
      case PlyType::kInt32:
        v = ReadLe<int32_t>(data_, pos_);
        break;
      case PlyType::kUint32:
        v = ReadLe<uint32_t>(data_, pos_);
        break;
      case PlyType::kFloat32:
        v = ReadLe<float>(data_, pos_);
        break;
      case PlyType::kFloat64:
        v = ReadLe<double>(data_, pos_);
        break;
    }
    pos_ += n;
    if (!std::isfinite(v))
      throw MeshFileError(file_, 0, static_cast<long>(pos_ - n), "non-finite " + what);
    return v;
  }
  // Where the value about to be read sits: a line (ASCII) or byte offset (binary).
  long Line() const {
    return binary_ ? 0
                   : (k_ < tokens_.size() ? tokens_[k_].line
                                          : (tokens_.empty() ? 0 : tokens_.back().line));
  }
  long Offset() const { return binary_ ? static_cast<long>(pos_) : -1; }
  bool AtEnd() const { return binary_ ? pos_ == data_.size() : k_ == tokens_.size(); }

 private:
  const std::string& data_;
  size_t pos_;
  bool binary_;
  const std::string& file_;
  std::vector<Token> tokens_;
  size_t k_ = 0;
};

TriangleMesh ReadPly(const std::string& file) {
  const std::string data = ReadWholeFile(file);
  // Header: text lines up to end_header.
  size_t pos = 0;
  long line_no = 0;
  auto next_line = [&](std::string* line) {
    if (pos >= data.size()) return false;
    size_t e = data.find('\n', pos);
    if (e == std::string::npos) e = data.size();
    *line = data.substr(pos, e - pos);
    if (!line->empty() && line->back() == '\r') line->pop_back();
    pos = std::min(e + 1, data.size());
    ++line_no;
    return true;
  };
  std::string line;
  if (!next_line(&line) || line != "ply")
    throw MeshFileError(file, 1, -1, "not a PLY file: the first line must be 'ply'");
  bool binary = false, have_format = false, ended = false;
  std::vector<PlyElement> elements;
  while (next_line(&line)) {
    const std::vector<Token> t = Tokenize(line, 0, line.size(), line_no);
    if (t.empty()) continue;
    const std::string& key = t[0].text;
    if (key == "end_header") {
      ended = true;
      break;
    } else if (key == "comment" || key == "obj_info") {
      continue;
    } else if (key == "format") {
      if (t.size() != 3)
        throw MeshFileError(file, line_no, -1, "format line needs a format and a version");
      if (t[1].text == "ascii")
        binary = false;
      else if (t[1].text == "binary_little_endian")
        binary = true;
      else
        throw MeshFileError(
            file, line_no, -1,
            "unsupported PLY format '" + t[1].text + "' (ascii or binary_little_endian)");
      have_format = true;
    } else if (key == "element") {
      if (t.size() != 3)
        throw MeshFileError(file, line_no, -1, "element line needs a name and a count");
      const long count = ParseLong(t[2].text, file, line_no, "element count");
      if (count < 0) throw MeshFileError(file, line_no, -1, "negative element count " + t[2].text);
      elements.push_back({t[1].text, count, line_no, {}});
    } else if (key == "property") {
      if (elements.empty()) throw MeshFileError(file, line_no, -1, "property before any element");
      PlyProperty p;
      if (t.size() == 5 && t[1].text == "list") {
        p.is_list = true;
        if (!ParsePlyType(t[2].text, &p.count_type) || !ParsePlyType(t[3].text, &p.type)) {
          throw MeshFileError(file, line_no, -1, "unknown type in list property '" + line + "'");
        }
        p.name = t[4].text;
      } else if (t.size() == 3) {
        if (!ParsePlyType(t[1].text, &p.type))
          throw MeshFileError(file, line_no, -1, "unknown property type '" + t[1].text + "'");
        p.name = t[2].text;
      } else {
        throw MeshFileError(file, line_no, -1, "malformed property line '" + line + "'");
      }
      elements.back().properties.push_back(p);
    } else {
      throw MeshFileError(file, line_no, -1, "unknown header keyword '" + key + "'");
    }
  }
  if (!ended) throw MeshFileError(file, line_no, -1, "header has no 'end_header'");
  if (!have_format) throw MeshFileError(file, line_no, -1, "header has no 'format' line");

  std::vector<double> xyz;
  std::vector<int> tri;
  std::vector<long> tri_line;
  PlyCursor cursor(data, pos, line_no + 1, binary, file);
  bool have_vertices = false, have_faces = false;
  for (const PlyElement& e : elements) {
    int xyz_prop[3] = {-1, -1, -1};
    int face_prop = -1;
    for (size_t i = 0; i < e.properties.size(); ++i) {
      const PlyProperty& p = e.properties[i];
      if (e.name == "vertex" && !p.is_list) {
        if (p.name == "x") xyz_prop[0] = static_cast<int>(i);
        if (p.name == "y") xyz_prop[1] = static_cast<int>(i);
        if (p.name == "z") xyz_prop[2] = static_cast<int>(i);
      }
      if (e.name == "face" && p.is_list && (p.name == "vertex_indices" || p.name == "vertex_index"))
        face_prop = static_cast<int>(i);
    }
    if (e.name == "vertex") {
      if (xyz_prop[0] < 0 || xyz_prop[1] < 0 || xyz_prop[2] < 0) {
        throw MeshFileError(file, e.header_line, -1,
                            "element vertex lacks one of the properties x, y, z");
      }
      have_vertices = true;
    }
    if (e.name == "face") {
      if (face_prop < 0)
        throw MeshFileError(file, e.header_line, -1,
                            "element face lacks a list property vertex_indices");
      have_faces = true;
    }
    // An element without properties has no data to read, whatever its count (which may be
    // huge: looping over it would only spin).
    if (e.properties.empty()) continue;
    for (long item = 0; item < e.count; ++item) {
      double p_xyz[3] = {0, 0, 0};
      for (size_t i = 0; i < e.properties.size(); ++i) {
        const PlyProperty& p = e.properties[i];
        const std::string what = e.name + " " + std::to_string(item) + " property " + p.name;
        if (!p.is_list) {
          const double v = cursor.Read(p.type, what);
          for (int a = 0; a < 3; ++a)
            if (xyz_prop[a] == static_cast<int>(i)) p_xyz[a] = v;
          continue;
        }
        const long at_line = cursor.Line(), at_offset = cursor.Offset();
        const double n_real = cursor.Read(p.count_type, what + " count");
        // Checked before the conversion: a double beyond long's range has no long value.
        if (!(n_real >= 0 && n_real <= kMaxPlyListLength && n_real == std::floor(n_real))) {
          throw MeshFileError(file, at_line, at_offset,
                              "bad list count " + std::to_string(n_real) + " in " + what +
                                  " (an integer in [0, " +
                                  std::to_string(static_cast<long>(kMaxPlyListLength)) + "])");
        }
        const long n = static_cast<long>(n_real);
        std::vector<int> corners;
        for (long c = 0; c < n; ++c) {
          const long c_line = cursor.Line(), c_offset = cursor.Offset();
          const double v = cursor.Read(p.type, what + " entry");
          // Entries of other lists are skipped (any value; only face corners become ints).
          if (static_cast<int>(i) != face_prop) continue;
          if (v != std::floor(v) || v < 0 || v > 2e9) {
            throw MeshFileError(file, c_line, c_offset,
                                "bad vertex index " + std::to_string(v) + " in " + what);
          }
          corners.push_back(static_cast<int>(v));
        }
        if (static_cast<int>(i) == face_prop) {
          if (n < 3)
            throw MeshFileError(file, at_line, at_offset,
                                "face " + std::to_string(item) + " has " + std::to_string(n) +
                                    " vertices (at least 3)");
          for (size_t c = 1; c + 1 < corners.size(); ++c) {
            tri.insert(tri.end(), {corners[0], corners[c], corners[c + 1]});
            tri_line.push_back(at_line);
          }
        }
      }
      if (e.name == "vertex") xyz.insert(xyz.end(), p_xyz, p_xyz + 3);
    }
  }
  if (!have_vertices) throw MeshFileError(file, line_no, -1, "header declares no element vertex");
  if (!have_faces) throw MeshFileError(file, line_no, -1, "header declares no element face");
  if (!cursor.AtEnd())
    throw MeshFileError(file, cursor.Line(), cursor.Offset(),
                        "data continues after the last declared element");
  // Binary files have no lines: report index errors without one.
  if (binary) tri_line.clear();
  return Assemble(xyz, tri, tri_line, file);
}

// ---------------------------------------------------------------- writers

class Output {
 public:
  explicit Output(const std::string& path) : path_(path), f_(std::fopen(path.c_str(), "wb")) {
    if (!f_)
      throw MeshFileError(path, 0, -1,
                          std::string("cannot open for writing: ") + std::strerror(errno));
  }
  ~Output() {
    if (f_) std::fclose(f_);
  }
  std::FILE* get() { return f_; }
  void Close() {
    const bool bad = std::ferror(f_) != 0;
    const int rc = std::fclose(f_);
    f_ = nullptr;
    if (bad || rc != 0) throw MeshFileError(path_, 0, -1, "write failed");
  }

 private:
  std::string path_;
  std::FILE* f_;
};

void CheckIndices(const TriangleMesh& mesh) {
  for (Eigen::Index f = 0; f < mesh.triangles.cols(); ++f) {
    for (int k = 0; k < 3; ++k) {
      if (mesh.triangles(k, f) < 0 || mesh.triangles(k, f) >= mesh.vertices.cols()) {
        throw std::invalid_argument("WriteTriangleMesh: triangle " + std::to_string(f) +
                                    " has vertex index " + std::to_string(mesh.triangles(k, f)) +
                                    " outside [0, " + std::to_string(mesh.vertices.cols()) + ")");
      }
    }
  }
}

}  // namespace

MeshFileError::MeshFileError(const std::string& file, long line, long byte_offset,
                             const std::string& what)
    : std::runtime_error(Location(file, line, byte_offset) + ": " + what),
      file_(file),
      line_(line),
      byte_offset_(line > 0 ? -1 : byte_offset),
      message_(what) {}

TriangleMesh ReadTriangleMesh(const std::string& path) {
  const std::string ext = Extension(path);
  if (ext == "stl") return ReadStl(path);
  if (ext == "obj") return ReadObj(path);
  if (ext == "ply") return ReadPly(path);
  throw MeshFileError(path, 0, -1, "unknown mesh file extension '" + ext + "' (stl, obj, ply)");
}

void WriteTriangleMesh(const TriangleMesh& mesh, const std::string& path, MeshFileFormat format) {
  CheckIndices(mesh);
  Output out(path);
  std::FILE* f = out.get();
  const Eigen::Index nv = mesh.vertices.cols(), nf = mesh.triangles.cols();
  switch (format) {
    case MeshFileFormat::kStlAscii: {
      std::fprintf(f, "solid spidarcad\n");
      for (Eigen::Index t = 0; t < nf; ++t) {
        const Eigen::Vector3d n = Normal(mesh, t);
        std::fprintf(f, "  facet normal %.9g %.9g %.9g\n    outer loop\n", n.x(), n.y(), n.z());
        for (int k = 0; k < 3; ++k) {
          const auto p = mesh.vertices.col(mesh.triangles(k, t));
          std::fprintf(f, "      vertex %.17g %.17g %.17g\n", p.x(), p.y(), p.z());
        }
        std::fprintf(f, "    endloop\n  endfacet\n");
      }
      std::fprintf(f, "endsolid spidarcad\n");
      break;
    }
    case MeshFileFormat::kStlBinary: {
      char header[80] = {};
      std::snprintf(header, sizeof(header), "binary STL from spidarcad, metres");
      std::fwrite(header, 1, 80, f);
      const uint32_t n = static_cast<uint32_t>(nf);
      std::fwrite(&n, 4, 1, f);
      for (Eigen::Index t = 0; t < nf; ++t) {
        float rec[12];
        const Eigen::Vector3d normal = Normal(mesh, t);
        for (int i = 0; i < 3; ++i) rec[i] = static_cast<float>(normal[i]);
        for (int k = 0; k < 3; ++k)
          for (int i = 0; i < 3; ++i)
            rec[3 + 3 * k + i] = static_cast<float>(mesh.vertices(i, mesh.triangles(k, t)));
        const uint16_t attribute = 0;
        std::fwrite(rec, 4, 12, f);
        std::fwrite(&attribute, 2, 1, f);
      }
      break;
    }
    case MeshFileFormat::kObj: {
      std::fprintf(f, "# spidarcad triangle mesh, metres\n");
      for (Eigen::Index i = 0; i < nv; ++i)
        std::fprintf(f, "v %.17g %.17g %.17g\n", mesh.vertices(0, i), mesh.vertices(1, i),
                     mesh.vertices(2, i));
      for (Eigen::Index t = 0; t < nf; ++t)
        std::fprintf(f, "f %d %d %d\n", mesh.triangles(0, t) + 1, mesh.triangles(1, t) + 1,
                     mesh.triangles(2, t) + 1);
      break;
    }
    case MeshFileFormat::kPlyAscii:
    case MeshFileFormat::kPlyBinary: {
      const bool binary = format == MeshFileFormat::kPlyBinary;
      std::fprintf(
          f,
          "ply\nformat %s 1.0\ncomment spidarcad triangle mesh, metres\nelement vertex %ld\n"
          "property double x\nproperty double y\nproperty double z\nelement face %ld\n"
          "property list uchar int vertex_indices\nend_header\n",
          binary ? "binary_little_endian" : "ascii", static_cast<long>(nv), static_cast<long>(nf));
      if (binary) {
        // An empty matrix has no data pointer, and fwrite may not be given a null one.
        if (nv > 0) std::fwrite(mesh.vertices.data(), sizeof(double), 3 * nv, f);
        for (Eigen::Index t = 0; t < nf; ++t) {
          const uint8_t three = 3;
          const int32_t idx[3] = {mesh.triangles(0, t), mesh.triangles(1, t), mesh.triangles(2, t)};
          std::fwrite(&three, 1, 1, f);
          std::fwrite(idx, 4, 3, f);
        }
      } else {
        for (Eigen::Index i = 0; i < nv; ++i)
          std::fprintf(f, "%.17g %.17g %.17g\n", mesh.vertices(0, i), mesh.vertices(1, i),
                       mesh.vertices(2, i));
        for (Eigen::Index t = 0; t < nf; ++t)
          std::fprintf(f, "3 %d %d %d\n", mesh.triangles(0, t), mesh.triangles(1, t),
                       mesh.triangles(2, t));
      }
      break;
    }
  }
  out.Close();
}

void WriteTriangleMesh(const TriangleMesh& mesh, const std::string& path) {
  const std::string ext = Extension(path);
  if (ext == "stl") return WriteTriangleMesh(mesh, path, MeshFileFormat::kStlBinary);
  if (ext == "obj") return WriteTriangleMesh(mesh, path, MeshFileFormat::kObj);
  if (ext == "ply") return WriteTriangleMesh(mesh, path, MeshFileFormat::kPlyBinary);
  throw std::invalid_argument("WriteTriangleMesh: unknown extension '" + ext + "' of " + path +
                              " (stl, obj, ply)");
}

}  // namespace spidarcad::modeling
