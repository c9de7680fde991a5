// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#include <unistd.h>
#include <zlib.h>

#include <Eigen/Dense>
#include <algorithm>
#include <bit>
#include <cctype>
#include <cerrno>
#include <charconv>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <limits>
#include <sstream>
#include <stdexcept>
#include <string>
#include <string_view>
#include <tuple>
#include <utility>
#include <vector>

#include "spidarcad/modeling/tet_mesh.h"

namespace spidarcad::modeling {

namespace {

Eigen::Vector3d Node(const TetMesh& mesh, Eigen::Index t, int k) {
  return mesh.nodes.col(mesh.tets(k, t));
}

// Closes the file on scope exit; Close() reports write errors. `shown` is the path named in
// messages (the final name when writing a temporary file).
class File {
 public:
  explicit File(const std::string& path, const std::string& shown = "")
      : path_(shown.empty() ? path : shown), f_(std::fopen(path.c_str(), "wb")) {
    if (!f_) throw std::runtime_error(path_ + ": cannot open for writing: " + std::strerror(errno));
  }
  ~File() {
    if (f_) std::fclose(f_);
  }
  std::FILE* get() { return f_; }
  void Close() {
    const bool bad = std::ferror(f_) != 0;
    const int rc = std::fclose(f_);
    f_ = nullptr;
    if (bad || rc != 0) throw std::runtime_error(path_ + ": write failed");
  }

 private:
  std::string path_;
  std::FILE* f_;
};

void CheckArrays(const VtuArrays& arrays, Eigen::Index cols, const char* kind) {
  for (const auto& [name, values] : arrays) {
    if (name.empty() || name.find_first_of("\"<>&") != std::string::npos) {
      throw std::invalid_argument(std::string("WriteVtu: bad ") + kind + " array name '" + name +
                                  "'");
    }
    if (values.cols() != cols || values.rows() < 1) {
      throw std::invalid_argument(std::string("WriteVtu: ") + kind + " array '" + name + "' is " +
                                  std::to_string(values.rows()) + " by " +
                                  std::to_string(values.cols()) + ", expected k by " +
                                  std::to_string(cols));
    }
    if (!values.allFinite())
      throw std::invalid_argument(std::string("WriteVtu: ") + kind + " array '" + name +
                                  "' is not finite");
  }
}

}  // namespace

double TetVolume(const TetMesh& mesh, Eigen::Index t) {
  const Eigen::Vector3d p0 = Node(mesh, t, 0);
  return (Node(mesh, t, 1) - p0).dot((Node(mesh, t, 2) - p0).cross(Node(mesh, t, 3) - p0)) / 6.0;
}

double TotalVolume(const TetMesh& mesh) {
  double sum = 0.0;
  for (Eigen::Index t = 0; t < mesh.tets.cols(); ++t) sum += TetVolume(mesh, t);
  return sum;
}

Eigen::Matrix<double, 6, 1> DihedralAngles(const Eigen::Vector3d& p0, const Eigen::Vector3d& p1,
                                           const Eigen::Vector3d& p2, const Eigen::Vector3d& p3) {
  const Eigen::Vector3d p[4] = {p0, p1, p2, p3};
  static constexpr int kEdges[6][4] = {{0, 1, 2, 3}, {0, 2, 1, 3}, {0, 3, 1, 2},
                                       {1, 2, 0, 3}, {1, 3, 0, 2}, {2, 3, 0, 1}};
  Eigen::Matrix<double, 6, 1> angles;
  for (int e = 0; e < 6; ++e) {
    const auto& [i, j, k, l] = kEdges[e];
    const Eigen::Vector3d axis = (p[j] - p[i]).normalized();
    // The angle between the two faces at edge ij is the angle between the other two vertices'
    // offsets with their components along the edge removed.
    Eigen::Vector3d u = p[k] - p[i], v = p[l] - p[i];
    u -= u.dot(axis) * axis;
    v -= v.dot(axis) * axis;
    const double c = u.dot(v) / (u.norm() * v.norm());
    angles[e] = std::acos(std::clamp(c, -1.0, 1.0));
  }
  return angles;
}

double RadiusEdgeRatio(const Eigen::Vector3d& p0, const Eigen::Vector3d& p1,
                       const Eigen::Vector3d& p2, const Eigen::Vector3d& p3) {
  // Circumcentre c (relative to p0): 2 (p_i - p0) · c = |p_i - p0|², i = 1..3.
  Eigen::Matrix3d a;
  a.row(0) = 2 * (p1 - p0);
  a.row(1) = 2 * (p2 - p0);
  a.row(2) = 2 * (p3 - p0);
  const Eigen::Vector3d b((p1 - p0).squaredNorm(), (p2 - p0).squaredNorm(),
                          (p3 - p0).squaredNorm());
  const double radius = a.partialPivLu().solve(b).norm();
  const double shortest = std::sqrt(
      std::min({(p1 - p0).squaredNorm(), (p2 - p0).squaredNorm(), (p3 - p0).squaredNorm(),
                (p2 - p1).squaredNorm(), (p3 - p1).squaredNorm(), (p3 - p2).squaredNorm()}));
  return radius / shortest;
}

TetQuality MeasureTetQuality(const TetMesh& mesh) {
  TetQuality q;
  if (mesh.tets.cols() == 0) return q;
  q.min_dihedral_deg = std::numeric_limits<double>::infinity();
  q.min_volume = std::numeric_limits<double>::infinity();
  for (Eigen::Index t = 0; t < mesh.tets.cols(); ++t) {
    const Eigen::Vector3d p0 = Node(mesh, t, 0), p1 = Node(mesh, t, 1), p2 = Node(mesh, t, 2),
                          p3 = Node(mesh, t, 3);
    const Eigen::Matrix<double, 6, 1> angles = DihedralAngles(p0, p1, p2, p3) * (180.0 / M_PI);
    q.min_dihedral_deg = std::min(q.min_dihedral_deg, angles.minCoeff());
    q.max_dihedral_deg = std::max(q.max_dihedral_deg, angles.maxCoeff());
    q.max_radius_edge = std::max(q.max_radius_edge, RadiusEdgeRatio(p0, p1, p2, p3));
    const double v = TetVolume(mesh, t);
    q.min_volume = std::min(q.min_volume, v);
    q.total_volume += v;
  }
  return q;
}

void ValidateTetMesh(const TetMesh& mesh) {
  const Eigen::Index nv = mesh.nodes.cols(), nt = mesh.tets.cols();
  if (mesh.regions.size() != 0 && mesh.regions.size() != nt) {
    throw std::invalid_argument("TetMesh: " + std::to_string(mesh.regions.size()) +
                                " regions for " + std::to_string(nt) + " tets");
  }
  if (!mesh.nodes.allFinite())
    throw std::invalid_argument("TetMesh: a node coordinate is not finite");
  for (Eigen::Index t = 0; t < nt; ++t) {
    for (int k = 0; k < 4; ++k) {
      const int i = mesh.tets(k, t);
      if (i < 0 || i >= nv) {
        throw std::invalid_argument("TetMesh: tet " + std::to_string(t) + " has node index " +
                                    std::to_string(i) + " outside [0, " + std::to_string(nv) + ")");
      }
      for (int m = 0; m < k; ++m) {
        if (mesh.tets(m, t) == i)
          throw std::invalid_argument("TetMesh: tet " + std::to_string(t) + " repeats node " +
                                      std::to_string(i));
      }
    }
  }
}

void WriteVtu(const TetMesh& mesh, const std::string& path, const VtuArrays& point_data,
              const VtuArrays& cell_data) {
  ValidateTetMesh(mesh);
  const Eigen::Index nv = mesh.nodes.cols(), nt = mesh.tets.cols();
  CheckArrays(point_data, nv, "point");
  CheckArrays(cell_data, nt, "cell");
  for (const char* builtin : {"region", "volume", "min_dihedral_deg"}) {
    if (cell_data.count(builtin))
      throw std::invalid_argument(std::string("WriteVtu: cell array name '") + builtin +
                                  "' is reserved");
  }
  VtuGrid grid;
  grid.points = mesh.nodes;
  grid.cells = mesh.tets;
  grid.regions = mesh.regions.size() ? mesh.regions : Eigen::VectorXi::Zero(nt);
  grid.point_data = point_data;
  grid.cell_data = cell_data;
  Eigen::MatrixXd volume(1, nt), dihedral(1, nt);
  for (Eigen::Index t = 0; t < nt; ++t) {
    volume(0, t) = TetVolume(mesh, t);
    dihedral(0, t) =
        DihedralAngles(Node(mesh, t, 0), Node(mesh, t, 1), Node(mesh, t, 2), Node(mesh, t, 3))
            .minCoeff() *
        (180.0 / M_PI);
  }
  grid.cell_data["volume"] = volume;
  grid.cell_data["min_dihedral_deg"] = dihedral;
  WriteVtuGrid(grid, path, VtuEncoding::kAscii);
}

void WriteTetgenFiles(const TetMesh& mesh, const std::string& base) {
  ValidateTetMesh(mesh);
  {
    File file(base + ".node");
    std::FILE* f = file.get();
    std::fprintf(f, "# spidarcad tetrahedral mesh nodes, metres, 0-based\n%ld 3 0 0\n",
                 static_cast<long>(mesh.nodes.cols()));
    for (Eigen::Index i = 0; i < mesh.nodes.cols(); ++i) {
      std::fprintf(f, "%ld %.17g %.17g %.17g\n", static_cast<long>(i), mesh.nodes(0, i),
                   mesh.nodes(1, i), mesh.nodes(2, i));
    }
    file.Close();
  }
  File file(base + ".ele");
  std::FILE* f = file.get();
  std::fprintf(f, "# spidarcad tetrahedra, 0-based node indices, last column the region\n%ld 4 1\n",
               static_cast<long>(mesh.tets.cols()));
  for (Eigen::Index t = 0; t < mesh.tets.cols(); ++t) {
    std::fprintf(f, "%ld %d %d %d %d %d\n", static_cast<long>(t), mesh.tets(0, t), mesh.tets(1, t),
                 mesh.tets(2, t), mesh.tets(3, t), mesh.regions.size() ? mesh.regions[t] : 0);
  }
  file.Close();
}

// ---------------------------------------------------------------------------------------------
// VTU reading.

namespace {

constexpr int kMaxXmlDepth = 32;
constexpr std::size_t kMaxXmlElements = 100000;
constexpr int kMaxComponents = 64;
// zlib cannot expand a block by more than about 1032:1; a header claiming more is corrupt.
constexpr std::uint64_t kMaxZlibRatio = 1100;

// One XML element of the file (the tiny subset VTK writes: elements, attributes, text).
struct XmlElement {
  std::string name;
  std::vector<std::pair<std::string, std::string>> attributes;
  std::vector<int> children;
  // Character data directly inside the element (pieces between child elements).
  std::vector<std::string_view> text;
  std::size_t offset = 0;  // byte offset of '<'
  const std::string* Attribute(const std::string& key) const {
    for (const auto& [k, v] : attributes)
      if (k == key) return &v;
    return nullptr;
  }
};

class VtuParser {
 public:
  VtuParser(std::string_view bytes, const std::string& source) : in_(bytes), source_(source) {}

  VtuGrid Parse();

 private:
  [[noreturn]] void Fail(std::size_t offset, const std::string& message) const {
    throw VtuError(source_, offset, message);
  }
  std::string Where(const XmlElement& e) const {
    std::string w = "<" + e.name;
    if (const std::string* name = e.Attribute("Name")) w += " Name=\"" + *name + "\"";
    return w + ">";
  }

  // XML.
  void ParseXml();
  std::string ReadName(std::size_t* pos) const;
  std::string DecodeEntities(std::string_view raw, std::size_t offset) const;

  // Attributes.
  std::int64_t IntegerAttribute(const XmlElement& e, const std::string& key, bool required,
                                std::int64_t fallback) const;

  // Arrays.
  struct Array {
    bool integral = false;
    std::vector<std::int64_t> ints;
    std::vector<double> reals;
    std::size_t size() const { return integral ? ints.size() : reals.size(); }
    double Real(std::size_t i) const { return integral ? static_cast<double>(ints[i]) : reals[i]; }
  };
  // Decodes a DataArray of `tuples` tuples (−1: any count) of `components` components
  // (0: take the attribute, default 1).
  Array DecodeArray(const XmlElement& e, std::int64_t tuples, int components, int* components_out);
  void DecodeAscii(const XmlElement& e, int type, std::uint64_t expected, bool any_count,
                   Array* out) const;
  void DecodeBinary(const XmlElement& e, int type, std::uint64_t expected, bool any_count,
                    bool base64, std::size_t start, std::size_t end, Array* out) const;

  std::string_view in_;
  std::string source_;
  std::vector<XmlElement> elements_;
  std::vector<int> roots_;
  // Appended data: position of the first byte after '_' (npos when absent) and its encoding.
  std::size_t appended_ = std::string_view::npos;
  bool appended_base64_ = false;
  std::size_t appended_offset_ = 0;  // offset of the <AppendedData> tag
  bool big_endian_ = false;
  int header_bytes_ = 4;
  bool zlib_ = false;
};

bool IsSpace(char c) { return c == ' ' || c == '\t' || c == '\n' || c == '\r'; }
bool IsNameChar(char c) {
  return std::isalnum(static_cast<unsigned char>(c)) || c == '_' || c == ':' || c == '-' ||
         c == '.';
}

std::string Printable(std::string_view text) {
  std::string out;
  for (char c : text.substr(0, 40)) out += std::isprint(static_cast<unsigned char>(c)) ? c : '?';
  if (text.size() > 40) out += "...";
  return out;
}

std::string VtuParser::ReadName(std::size_t* pos) const {
  const std::size_t start = *pos;
  while (*pos < in_.size() && IsNameChar(in_[*pos])) ++*pos;
  if (*pos == start)
    Fail(start, "expected an XML name, found '" + Printable(in_.substr(start, 8)) + "'");
  return std::string(in_.substr(start, *pos - start));
}

std::string VtuParser::DecodeEntities(std::string_view raw, std::size_t offset) const {
  std::string out;
  for (std::size_t i = 0; i < raw.size(); ++i) {
    if (raw[i] != '&') {
      out += raw[i];
      continue;
    }
    static constexpr std::pair<const char*, char> kEntities[] = {
        {"&lt;", '<'}, {"&gt;", '>'}, {"&amp;", '&'}, {"&quot;", '"'}, {"&apos;", '\''}};
    bool found = false;
    for (const auto& [text, c] : kEntities) {
      if (raw.substr(i, std::strlen(text)) == text) {
        out += c;
        i += std::strlen(text) - 1;
        found = true;
        break;
      }
    }
    if (!found) Fail(offset + i, "unsupported XML entity '" + Printable(raw.substr(i, 8)) + "'");
  }
  return out;
}

void VtuParser::ParseXml() {
  std::vector<int> stack;
  std::size_t pos = 0;
  // A UTF-8 byte order mark is allowed before the declaration.
  if (in_.substr(0, 3) == "\xEF\xBB\xBF") pos = 3;
  while (pos < in_.size()) {
    const std::size_t lt = in_.find('<', pos);
    const std::size_t text_end = lt == std::string_view::npos ? in_.size() : lt;
    if (text_end > pos) {
      const std::string_view text = in_.substr(pos, text_end - pos);
      if (!stack.empty()) {
        elements_[stack.back()].text.push_back(text);
      } else {
        for (std::size_t i = 0; i < text.size(); ++i)
          if (!IsSpace(text[i])) Fail(pos + i, "text outside the root element");
      }
    }
    if (lt == std::string_view::npos) break;
    pos = lt;
    if (in_.substr(pos, 2) == "<?") {
      const std::size_t end = in_.find("?>", pos + 2);
      if (end == std::string_view::npos) Fail(pos, "unterminated '<?' declaration");
      pos = end + 2;
      continue;
    }
    if (in_.substr(pos, 4) == "<!--") {
      const std::size_t end = in_.find("-->", pos + 4);
      if (end == std::string_view::npos) Fail(pos, "unterminated XML comment");
      pos = end + 3;
      continue;
    }
    if (in_.substr(pos, 2) == "<!") Fail(pos, "unsupported XML construct (DOCTYPE or CDATA)");
    if (in_.substr(pos, 2) == "</") {
      std::size_t p = pos + 2;
      const std::string name = ReadName(&p);
      while (p < in_.size() && IsSpace(in_[p])) ++p;
      if (p >= in_.size() || in_[p] != '>') Fail(pos, "malformed end tag </" + name);
      if (stack.empty() || elements_[stack.back()].name != name) {
        Fail(pos, "end tag </" + name + "> does not match " +
                      (stack.empty() ? std::string("any open element")
                                     : "<" + elements_[stack.back()].name + "> at byte " +
                                           std::to_string(elements_[stack.back()].offset)));
      }
      stack.pop_back();
      pos = p + 1;
      continue;
    }
    // Start tag.
    if (elements_.size() >= kMaxXmlElements) Fail(pos, "more than 100000 XML elements");
    XmlElement e;
    e.offset = pos;
    std::size_t p = pos + 1;
    e.name = ReadName(&p);
    bool self_closing = false;
    for (;;) {
      while (p < in_.size() && IsSpace(in_[p])) ++p;
      if (p >= in_.size()) Fail(pos, "unterminated tag <" + e.name);
      if (in_[p] == '>') {
        ++p;
        break;
      }
      if (in_.substr(p, 2) == "/>") {
        p += 2;
        self_closing = true;
        break;
      }
      const std::size_t key_at = p;
      const std::string key = ReadName(&p);
      while (p < in_.size() && IsSpace(in_[p])) ++p;
      if (p >= in_.size() || in_[p] != '=') Fail(key_at, "attribute " + key + " has no value");
      ++p;
      while (p < in_.size() && IsSpace(in_[p])) ++p;
      if (p >= in_.size() || (in_[p] != '"' && in_[p] != '\'')) {
        Fail(key_at, "attribute " + key + ": value is not quoted");
      }
      const char quote = in_[p];
      const std::size_t end = in_.find(quote, p + 1);
      if (end == std::string_view::npos) Fail(key_at, "attribute " + key + ": unterminated value");
      for (const auto& [k, v] : e.attributes)
        if (k == key) Fail(key_at, "attribute " + key + " repeated in <" + e.name + ">");
      e.attributes.emplace_back(key, DecodeEntities(in_.substr(p + 1, end - p - 1), p + 1));
      p = end + 1;
    }
    const int index = static_cast<int>(elements_.size());
    if (stack.empty()) {
      roots_.push_back(index);
    } else {
      elements_[stack.back()].children.push_back(index);
    }
    const bool appended = e.name == "AppendedData" && !self_closing;
    elements_.push_back(std::move(e));
    if (appended) {
      // Raw data may hold any byte: stop parsing XML here. The data starts after '_'.
      const XmlElement& a = elements_.back();
      appended_offset_ = a.offset;
      const std::string* encoding = a.Attribute("encoding");
      if (encoding == nullptr || (*encoding != "raw" && *encoding != "base64")) {
        Fail(a.offset, "<AppendedData>: encoding '" + (encoding ? *encoding : std::string()) +
                           "' is not raw or base64");
      }
      appended_base64_ = *encoding == "base64";
      while (p < in_.size() && IsSpace(in_[p])) ++p;
      if (p >= in_.size() || in_[p] != '_') {
        Fail(p, "<AppendedData>: the data must start with '_'");
      }
      appended_ = p + 1;
      return;
    }
    if (!self_closing) {
      if (static_cast<int>(stack.size()) >= kMaxXmlDepth) Fail(pos, "XML nested too deeply");
      stack.push_back(index);
    }
    pos = p;
  }
  if (!stack.empty()) {
    Fail(in_.size(), "the file ends inside <" + elements_[stack.back()].name + "> opened at byte " +
                         std::to_string(elements_[stack.back()].offset) + " (truncated?)");
  }
}

bool ParseInt64(std::string_view text, std::int64_t* value) {
  if (!text.empty() && text[0] == '+') text.remove_prefix(1);
  const auto [ptr, ec] = std::from_chars(text.data(), text.data() + text.size(), *value);
  return ec == std::errc() && ptr == text.data() + text.size() && !text.empty();
}

std::int64_t VtuParser::IntegerAttribute(const XmlElement& e, const std::string& key, bool required,
                                         std::int64_t fallback) const {
  const std::string* value = e.Attribute(key);
  if (value == nullptr) {
    if (required) Fail(e.offset, Where(e) + ": attribute " + key + " is missing");
    return fallback;
  }
  std::string_view text = *value;
  while (!text.empty() && IsSpace(text.front())) text.remove_prefix(1);
  while (!text.empty() && IsSpace(text.back())) text.remove_suffix(1);
  std::int64_t v = 0;
  if (!ParseInt64(text, &v)) {
    Fail(e.offset, Where(e) + ": " + key + "=\"" + Printable(*value) + "\" is not an integer");
  }
  return v;
}

// Scalar types of DataArray.
enum ScalarType {
  kInt8,
  kUInt8,
  kInt16,
  kUInt16,
  kInt32,
  kUInt32,
  kInt64,
  kUInt64,
  kFloat32,
  kFloat64
};
constexpr const char* kTypeNames[] = {"Int8",   "UInt8", "Int16",  "UInt16",  "Int32",
                                      "UInt32", "Int64", "UInt64", "Float32", "Float64"};
constexpr int kTypeSizes[] = {1, 1, 2, 2, 4, 4, 8, 8, 4, 8};

// " (VTK_NAME)" of common VTK cell types, else "".
std::string CellTypeName(std::int64_t type) {
  switch (type) {
    case 1:
      return " (VTK_VERTEX)";
    case 3:
      return " (VTK_LINE)";
    case 5:
      return " (VTK_TRIANGLE)";
    case 9:
      return " (VTK_QUAD)";
    case 12:
      return " (VTK_HEXAHEDRON)";
    case 13:
      return " (VTK_WEDGE)";
    case 14:
      return " (VTK_PYRAMID)";
    case 22:
      return " (VTK_QUADRATIC_TRIANGLE)";
    case 25:
      return " (VTK_QUADRATIC_HEXAHEDRON)";
    case 42:
      return " (VTK_POLYHEDRON)";
    default:
      return "";
  }
}

int ScalarTypeOf(const std::string& name) {
  for (int t = 0; t < 10; ++t)
    if (name == kTypeNames[t]) return t;
  if (name == "Char") return kInt8;
  if (name == "UChar") return kUInt8;
  return -1;
}

void VtuParser::DecodeAscii(const XmlElement& e, int type, std::uint64_t expected, bool any_count,
                            Array* out) const {
  const bool integral = type < kFloat32;
  for (std::string_view piece : e.text) {
    std::size_t i = 0;
    while (i < piece.size()) {
      while (i < piece.size() && IsSpace(piece[i])) ++i;
      if (i >= piece.size()) break;
      std::size_t j = i;
      while (j < piece.size() && !IsSpace(piece[j])) ++j;
      const std::string_view token = piece.substr(i, j - i);
      const std::size_t offset = static_cast<std::size_t>(token.data() - in_.data());
      const std::uint64_t index = out->size();
      if (!any_count && index >= expected) {
        Fail(offset, Where(e) + ": more than the " + std::to_string(expected) +
                         " values expected (NumberOfTuples x NumberOfComponents)");
      }
      if (integral) {
        std::int64_t v = 0;
        if (!ParseInt64(token, &v)) {
          std::uint64_t u = 0;
          const auto [ptr, ec] = std::from_chars(token.data(), token.data() + token.size(), u);
          Fail(offset, Where(e) + ": value " + std::to_string(index) + " '" + Printable(token) +
                           (ec == std::errc() && ptr == token.data() + token.size()
                                ? "' is too large"
                                : "' is not an integer"));
        }
        out->ints.push_back(v);
      } else {
        double v = 0.0;
        const char* first = token.data();
        if (token.size() > 1 && token[0] == '+') ++first;
        const auto [ptr, ec] = std::from_chars(first, token.data() + token.size(), v);
        if (ptr != token.data() + token.size() ||
            (ec != std::errc() && ec != std::errc::result_out_of_range)) {
          Fail(offset, Where(e) + ": value " + std::to_string(index) + " '" + Printable(token) +
                           "' is not a number");
        }
        if (ec == std::errc::result_out_of_range) {
          Fail(offset, Where(e) + ": value " + std::to_string(index) + " '" + Printable(token) +
                           "' is out of the range of a double");
        }
        out->reals.push_back(v);
      }
      i = j;
    }
  }
  if (!any_count && out->size() != expected) {
    const std::size_t end =
        e.text.empty()
            ? e.offset
            : static_cast<std::size_t>(e.text.back().data() + e.text.back().size() - in_.data());
    Fail(end, Where(e) + ": " + std::to_string(out->size()) + " values, expected " +
                  std::to_string(expected) + " (NumberOfTuples x NumberOfComponents)");
  }
}

// Reads bytes from raw or base64-encoded data, bounded by [start, end) of the input.
class ByteReader {
 public:
  ByteReader(std::string_view in, std::size_t start, std::size_t end, bool base64)
      : in_(in), pos_(start), end_(std::min(end, in.size())), base64_(base64) {}
  // Position in the input of the next unread byte (or encoded character).
  std::size_t position() const { return pos_; }
  // Appends n bytes to *out; false (with *bad_offset set) when the data ends first or holds a
  // character that is not base64.
  bool Read(std::uint64_t n, std::string* out, std::size_t* bad_offset) {
    if (!base64_) {
      if (pos_ > end_ || n > end_ - pos_) {
        *bad_offset = end_;
        return false;
      }
      out->append(in_.data() + pos_, static_cast<std::size_t>(n));
      pos_ += static_cast<std::size_t>(n);
      return true;
    }
    // Four encoded characters make at most three bytes: refuse early what cannot be there.
    if (n > (end_ - std::min(pos_, end_)) / 4 * 3 + pending_.size()) {
      *bad_offset = end_;
      return false;
    }
    while (pending_.size() < n) {
      if (!Quantum(bad_offset)) return false;
    }
    out->append(pending_, 0, static_cast<std::size_t>(n));
    pending_.erase(0, static_cast<std::size_t>(n));
    return true;
  }

 private:
  static int Value(char c) {
    if (c >= 'A' && c <= 'Z') return c - 'A';
    if (c >= 'a' && c <= 'z') return c - 'a' + 26;
    if (c >= '0' && c <= '9') return c - '0' + 52;
    if (c == '+') return 62;
    if (c == '/') return 63;
    return -1;
  }
  // Decodes the next four characters (whitespace skipped); a padded quantum ends one encoded
  // block, and the next block may follow (VTK encodes headers and data separately).
  bool Quantum(std::size_t* bad_offset) {
    int v[4];
    int pad = 0;
    for (int k = 0; k < 4; ++k) {
      while (pos_ < end_ && IsSpace(in_[pos_])) ++pos_;
      if (pos_ >= end_) {
        *bad_offset = pos_;
        return false;
      }
      const char c = in_[pos_];
      if (c == '=' && k >= 2) {
        v[k] = 0;
        ++pad;
      } else {
        v[k] = Value(c);
        if (v[k] < 0 || pad > 0) {
          *bad_offset = pos_;
          return false;
        }
      }
      ++pos_;
    }
    const std::uint32_t bits = (v[0] << 18) | (v[1] << 12) | (v[2] << 6) | v[3];
    pending_ += static_cast<char>((bits >> 16) & 0xFF);
    if (pad < 2) pending_ += static_cast<char>((bits >> 8) & 0xFF);
    if (pad < 1) pending_ += static_cast<char>(bits & 0xFF);
    return true;
  }

  std::string_view in_;
  std::size_t pos_, end_;
  bool base64_;
  std::string pending_;
};

std::uint64_t LoadUnsigned(const char* p, int size, bool big_endian) {
  std::uint64_t v = 0;
  for (int k = 0; k < size; ++k) {
    const auto byte = static_cast<unsigned char>(p[big_endian ? k : size - 1 - k]);
    v = (v << 8) | byte;
  }
  return v;
}

void VtuParser::DecodeBinary(const XmlElement& e, int type, std::uint64_t expected, bool any_count,
                             bool base64, std::size_t start, std::size_t end, Array* out) const {
  ByteReader reader(in_, start, end, base64);
  const int size = kTypeSizes[type];
  std::string header, data;
  std::size_t bad = 0;
  auto read = [&](std::uint64_t n, std::string* to, const std::string& what) {
    if (!reader.Read(n, to, &bad)) {
      Fail(bad, Where(e) + ": " + what + " (" + std::to_string(n) + " bytes) " +
                    (bad >= end || bad >= in_.size() ? "runs past the end of the data"
                                                     : "holds a character that is not base64"));
    }
  };
  const std::uint64_t expected_bytes = expected * static_cast<std::uint64_t>(size);
  if (!zlib_) {
    read(header_bytes_, &header, "the size header");
    const std::uint64_t n = LoadUnsigned(header.data(), header_bytes_, big_endian_);
    if (any_count ? n % size != 0 : n != expected_bytes) {
      Fail(reader.position(), Where(e) + ": the header declares " + std::to_string(n) +
                                  " bytes of data, expected " +
                                  (any_count ? "a multiple of " + std::to_string(size)
                                             : std::to_string(expected_bytes)));
    }
    read(n, &data, "the data");
  } else {
    read(3 * static_cast<std::uint64_t>(header_bytes_), &header, "the compression header");
    const std::uint64_t blocks = LoadUnsigned(header.data(), header_bytes_, big_endian_);
    const std::uint64_t block_size =
        LoadUnsigned(header.data() + header_bytes_, header_bytes_, big_endian_);
    const std::uint64_t last_size =
        LoadUnsigned(header.data() + 2 * header_bytes_, header_bytes_, big_endian_);
    if (blocks > (in_.size() / header_bytes_) + 1 || (blocks > 0 && block_size == 0) ||
        last_size > block_size) {
      Fail(reader.position(), Where(e) + ": corrupt compression header (" + std::to_string(blocks) +
                                  " blocks of " + std::to_string(block_size) + " bytes, last " +
                                  std::to_string(last_size) + ")");
    }
    const std::uint64_t total =
        blocks == 0 ? 0 : (blocks - 1) * block_size + (last_size == 0 ? block_size : last_size);
    if (blocks > 0 && (block_size > (std::uint64_t{1} << 40) / blocks)) {
      Fail(reader.position(), Where(e) + ": compression header declares too much data");
    }
    if (any_count ? total % size != 0 : total != expected_bytes) {
      Fail(reader.position(), Where(e) + ": the compression header declares " +
                                  std::to_string(total) + " bytes of data, expected " +
                                  (any_count ? "a multiple of " + std::to_string(size)
                                             : std::to_string(expected_bytes)));
    }
    std::string sizes;
    read(blocks * header_bytes_, &sizes, "the compressed block sizes");
    std::vector<std::uint64_t> compressed(blocks);
    std::uint64_t compressed_total = 0;
    for (std::uint64_t b = 0; b < blocks; ++b) {
      compressed[b] = LoadUnsigned(sizes.data() + b * header_bytes_, header_bytes_, big_endian_);
      compressed_total += std::min<std::uint64_t>(compressed[b], in_.size() + 1);
      if (compressed_total > in_.size()) {
        Fail(reader.position(), Where(e) + ": the compressed blocks (" +
                                    std::to_string(compressed_total) +
                                    "+ bytes) are larger than the file");
      }
      const std::uint64_t out_size = b + 1 == blocks && last_size != 0 ? last_size : block_size;
      if (compressed[b] > in_.size() || out_size > compressed[b] * kMaxZlibRatio + 64) {
        Fail(reader.position(), Where(e) + ": compressed block " + std::to_string(b) + " of " +
                                    std::to_string(compressed[b]) + " bytes cannot hold " +
                                    std::to_string(out_size) + " bytes");
      }
    }
    std::string block, plain;
    for (std::uint64_t b = 0; b < blocks; ++b) {
      const std::size_t at = reader.position();
      block.clear();
      read(compressed[b], &block, "compressed block " + std::to_string(b));
      const std::uint64_t out_size = b + 1 == blocks && last_size != 0 ? last_size : block_size;
      plain.resize(static_cast<std::size_t>(out_size));
      uLongf plain_size = static_cast<uLongf>(out_size);
      const int rc = uncompress(reinterpret_cast<Bytef*>(plain.data()), &plain_size,
                                reinterpret_cast<const Bytef*>(block.data()),
                                static_cast<uLong>(block.size()));
      if (rc != Z_OK || plain_size != out_size) {
        Fail(at, Where(e) + ": compressed block " + std::to_string(b) +
                     " does not inflate to its declared " + std::to_string(out_size) +
                     " bytes (zlib: " + (rc == Z_OK ? "size mismatch" : zError(rc)) + ")");
      }
      data += plain;
    }
  }
  const std::size_t n = data.size() / size;
  const bool integral = type < kFloat32;
  if (integral) {
    out->ints.resize(n);
  } else {
    out->reals.resize(n);
  }
  for (std::size_t i = 0; i < n; ++i) {
    char bytes[8];
    const char* src = data.data() + i * size;
    for (int k = 0; k < size; ++k) bytes[k] = src[big_endian_ ? size - 1 - k : k];  // to LE
    switch (type) {
      case kInt8:
        out->ints[i] = static_cast<std::int8_t>(bytes[0]);
        break;
      case kUInt8:
        out->ints[i] = static_cast<std::uint8_t>(bytes[0]);
        break;
      case kInt16: {
        std::int16_t v;
        std::memcpy(&v, bytes, 2);
        out->ints[i] = v;
        break;
      }
      case kUInt16: {
        std::uint16_t v;
        std::memcpy(&v, bytes, 2);
        out->ints[i] = v;
        break;
      }
      case kInt32: {
        std::int32_t v;
        std::memcpy(&v, bytes, 4);
        out->ints[i] = v;
        break;
      }
      case kUInt32: {
        std::uint32_t v;
        std::memcpy(&v, bytes, 4);
        out->ints[i] = v;
        break;
      }
      case kInt64: {
        std::int64_t v;
        std::memcpy(&v, bytes, 8);
        out->ints[i] = v;
        break;
      }
      case kUInt64: {
        std::uint64_t v;
        std::memcpy(&v, bytes, 8);
        if (v > static_cast<std::uint64_t>(std::numeric_limits<std::int64_t>::max())) {
          Fail(start, Where(e) + ": value " + std::to_string(i) + " = " + std::to_string(v) +
                          " is too large");
        }
        out->ints[i] = static_cast<std::int64_t>(v);
        break;
      }
      case kFloat32: {
        float v;
        std::memcpy(&v, bytes, 4);
        out->reals[i] = v;
        break;
      }
      default: {
        double v;
        std::memcpy(&v, bytes, 8);
        out->reals[i] = v;
        break;
      }
    }
  }
}

VtuParser::Array VtuParser::DecodeArray(const XmlElement& e, std::int64_t tuples, int components,
                                        int* components_out) {
  const std::string* type_name = e.Attribute("type");
  if (type_name == nullptr) Fail(e.offset, Where(e) + ": attribute type is missing");
  const int type = ScalarTypeOf(*type_name);
  if (type < 0) {
    Fail(e.offset, Where(e) + ": type \"" + Printable(*type_name) +
                       "\" is not a numeric type (Int8..UInt64, Float32, Float64)");
  }
  const std::int64_t declared = IntegerAttribute(e, "NumberOfComponents", false, 1);
  if (declared < 1 || declared > kMaxComponents) {
    Fail(e.offset, Where(e) + ": NumberOfComponents=" + std::to_string(declared) +
                       " is not in 1.." + std::to_string(kMaxComponents));
  }
  if (components > 0 && declared != components) {
    Fail(e.offset, Where(e) + ": NumberOfComponents=" + std::to_string(declared) + ", expected " +
                       std::to_string(components));
  }
  if (components_out) *components_out = static_cast<int>(declared);
  const bool any_count = tuples < 0;
  const std::uint64_t expected =
      any_count ? 0 : static_cast<std::uint64_t>(tuples) * static_cast<std::uint64_t>(declared);
  Array out;
  out.integral = type < kFloat32;
  const std::string* format = e.Attribute("format");
  if (format == nullptr) Fail(e.offset, Where(e) + ": attribute format is missing");
  if (*format == "ascii") {
    DecodeAscii(e, type, expected, any_count, &out);
  } else if (*format == "binary") {
    // Inline data: the one non-blank piece of text directly inside the element (child
    // elements such as <InformationKey> may come before or after it).
    std::string_view text;
    for (std::string_view piece : e.text) {
      if (std::all_of(piece.begin(), piece.end(), IsSpace)) continue;
      if (!text.empty()) Fail(e.offset, Where(e) + ": binary data is split by child elements");
      text = piece;
    }
    if (text.empty()) Fail(e.offset, Where(e) + ": binary data is missing");
    const auto start = static_cast<std::size_t>(text.data() - in_.data());
    DecodeBinary(e, type, expected, any_count, true, start, start + text.size(), &out);
  } else if (*format == "appended") {
    if (appended_ == std::string_view::npos) {
      Fail(e.offset, Where(e) + ": format=\"appended\" but the file has no <AppendedData>");
    }
    const std::int64_t offset = IntegerAttribute(e, "offset", true, 0);
    if (offset < 0 || static_cast<std::uint64_t>(offset) >= in_.size() - appended_) {
      Fail(e.offset, Where(e) + ": offset=" + std::to_string(offset) +
                         " is outside the appended data (" +
                         std::to_string(in_.size() - appended_) + " bytes)");
    }
    DecodeBinary(e, type, expected, any_count, appended_base64_,
                 appended_ + static_cast<std::size_t>(offset), in_.size(), &out);
  } else {
    Fail(e.offset,
         Where(e) + ": format \"" + Printable(*format) + "\" is not ascii, binary or appended");
  }
  if (any_count && out.size() % declared != 0) {
    Fail(e.offset, Where(e) + ": " + std::to_string(out.size()) +
                       " values do not make whole tuples of " + std::to_string(declared));
  }
  return out;
}

VtuGrid VtuParser::Parse() {
  ParseXml();
  if (roots_.empty()) Fail(0, "no XML element: not a .vtu file");
  const XmlElement& root = elements_[roots_.front()];
  if (root.name != "VTKFile")
    Fail(root.offset, "root element is <" + root.name + ">, expected <VTKFile>");
  const std::string* kind = root.Attribute("type");
  if (kind == nullptr || *kind != "UnstructuredGrid") {
    Fail(root.offset, "<VTKFile> type=\"" + (kind ? Printable(*kind) : std::string()) +
                          "\": only UnstructuredGrid (.vtu) files are read");
  }
  if (const std::string* order = root.Attribute("byte_order")) {
    if (*order == "BigEndian") {
      big_endian_ = true;
    } else if (*order != "LittleEndian") {
      Fail(root.offset,
           "<VTKFile> byte_order=\"" + Printable(*order) + "\" is not LittleEndian or BigEndian");
    }
  }
  if (const std::string* header = root.Attribute("header_type")) {
    if (*header == "UInt64") {
      header_bytes_ = 8;
    } else if (*header != "UInt32") {
      Fail(root.offset,
           "<VTKFile> header_type=\"" + Printable(*header) + "\" is not UInt32 or UInt64");
    }
  }
  if (const std::string* compressor = root.Attribute("compressor")) {
    if (*compressor == "vtkZLibDataCompressor") {
      zlib_ = true;
    } else if (!compressor->empty()) {
      Fail(root.offset, "<VTKFile> compressor=\"" + Printable(*compressor) +
                            "\" is not supported (only vtkZLibDataCompressor; save without "
                            "compression or with zlib)");
    }
  }
  const XmlElement* grid = nullptr;
  for (int c : root.children)
    if (elements_[c].name == "UnstructuredGrid") grid = &elements_[c];
  if (grid == nullptr) Fail(root.offset, "<VTKFile> has no <UnstructuredGrid>");
  std::vector<const XmlElement*> pieces;
  for (int c : grid->children)
    if (elements_[c].name == "Piece") pieces.push_back(&elements_[c]);
  if (pieces.size() != 1) {
    Fail(grid->offset, "<UnstructuredGrid> has " + std::to_string(pieces.size()) +
                           " <Piece> elements; exactly one is read (merge the blocks first)");
  }
  const XmlElement& piece = *pieces.front();
  const std::int64_t num_points = IntegerAttribute(piece, "NumberOfPoints", true, 0);
  const std::int64_t num_cells = IntegerAttribute(piece, "NumberOfCells", true, 0);
  const std::int64_t kMaxCount = std::numeric_limits<int>::max() / 10;
  const std::pair<const char*, std::int64_t> counts[] = {{"NumberOfPoints", num_points},
                                                         {"NumberOfCells", num_cells}};
  for (const auto& [name, value] : counts) {
    if (value < 0 || value > kMaxCount) {
      Fail(piece.offset, std::string("<Piece> ") + name + "=\"" + std::to_string(value) +
                             "\" is not a count in 0.." + std::to_string(kMaxCount));
    }
  }
  if (num_points == 0) Fail(piece.offset, "<Piece> NumberOfPoints=\"0\": the mesh has no points");
  if (num_cells == 0) Fail(piece.offset, "<Piece> NumberOfCells=\"0\": the mesh has no cells");

  auto child = [&](const XmlElement& parent, const std::string& name) -> const XmlElement* {
    const XmlElement* found = nullptr;
    for (int c : parent.children) {
      if (elements_[c].name != name) continue;
      if (found) Fail(elements_[c].offset, "<" + parent.name + "> has two <" + name + "> elements");
      found = &elements_[c];
    }
    return found;
  };
  auto arrays_of = [&](const XmlElement& parent) {
    std::vector<const XmlElement*> arrays;
    for (int c : parent.children)
      if (elements_[c].name == "DataArray") arrays.push_back(&elements_[c]);
    return arrays;
  };

  VtuGrid out;
  // Points.
  const XmlElement* points = child(piece, "Points");
  if (points == nullptr || arrays_of(*points).empty())
    Fail(piece.offset, "<Piece> has no <Points> array");
  {
    const XmlElement& e = *arrays_of(*points).front();
    const Array a = DecodeArray(e, num_points, 3, nullptr);
    out.points.resize(3, num_points);
    for (std::int64_t i = 0; i < 3 * num_points; ++i) {
      const double x = a.Real(static_cast<std::size_t>(i));
      if (!std::isfinite(x)) {
        Fail(e.offset, Where(e) + ": point " + std::to_string(i / 3) +
                           " has a non-finite coordinate (" + std::to_string(x) + ")");
      }
      out.points(i % 3, i / 3) = x;
    }
  }
  // Cells.
  const XmlElement* cells = child(piece, "Cells");
  if (cells == nullptr) Fail(piece.offset, "<Piece> has no <Cells>");
  const XmlElement *connectivity = nullptr, *offsets = nullptr, *types = nullptr;
  for (const XmlElement* e : arrays_of(*cells)) {
    const std::string* name = e->Attribute("Name");
    const std::string n = name ? *name : "";
    const XmlElement** slot = n == "connectivity" ? &connectivity
                              : n == "offsets"    ? &offsets
                              : n == "types"      ? &types
                                                  : nullptr;
    if (n == "faces" || n == "faceoffsets") {
      Fail(e->offset, Where(*e) + ": polyhedral cells are not tetrahedra");
    }
    if (slot == nullptr) continue;
    if (*slot) Fail(e->offset, "<Cells> has two arrays named " + n);
    *slot = e;
  }
  const std::pair<const XmlElement*, const char*> required[] = {
      {types, "types"}, {offsets, "offsets"}, {connectivity, "connectivity"}};
  for (const auto& [e, name] : required) {
    if (e == nullptr) Fail(cells->offset, std::string("<Cells> has no \"") + name + "\" array");
  }
  const Array type_values = DecodeArray(*types, num_cells, 1, nullptr);
  if (!type_values.integral) Fail(types->offset, Where(*types) + ": cell types must be integers");
  const std::int64_t first_type = type_values.ints[0];
  for (std::int64_t c = 0; c < num_cells; ++c) {
    const std::int64_t t = type_values.ints[c];
    if (t != 10 && t != 24) {
      Fail(types->offset, Where(*types) + ": cell " + std::to_string(c) + " has type " +
                              std::to_string(t) + CellTypeName(t) +
                              "; only VTK_TETRA (10) and VTK_QUADRATIC_TETRA (24) are accepted");
    }
    if (t != first_type) {
      Fail(types->offset, Where(*types) + ": cell " + std::to_string(c) + " has type " +
                              std::to_string(t) + " but cell 0 has type " +
                              std::to_string(first_type) + "; one kind of tetrahedron per file");
    }
  }
  const int npe = first_type == 10 ? 4 : 10;
  const Array offset_values = DecodeArray(*offsets, num_cells, 1, nullptr);
  if (!offset_values.integral)
    Fail(offsets->offset, Where(*offsets) + ": offsets must be integers");
  for (std::int64_t c = 0; c < num_cells; ++c) {
    if (offset_values.ints[c] != (c + 1) * npe) {
      Fail(offsets->offset, Where(*offsets) + ": cell " + std::to_string(c) + " ends at " +
                                std::to_string(offset_values.ints[c]) + ", expected " +
                                std::to_string((c + 1) * npe) + " (" + std::to_string(npe) +
                                " points per cell)");
    }
  }
  const Array conn = DecodeArray(*connectivity, num_cells * npe, 1, nullptr);
  if (!conn.integral)
    Fail(connectivity->offset, Where(*connectivity) + ": point indices must be integers");
  out.cells.resize(npe, num_cells);
  for (std::int64_t c = 0; c < num_cells; ++c) {
    for (int j = 0; j < npe; ++j) {
      const std::int64_t v = conn.ints[c * npe + j];
      if (v < 0 || v >= num_points) {
        Fail(connectivity->offset, Where(*connectivity) + ": cell " + std::to_string(c) +
                                       " names point " + std::to_string(v) + ", outside 0.." +
                                       std::to_string(num_points - 1) +
                                       " (NumberOfPoints = " + std::to_string(num_points) + ")");
      }
      for (int k = 0; k < j; ++k) {
        if (out.cells(k, c) == v) {
          Fail(connectivity->offset, Where(*connectivity) + ": cell " + std::to_string(c) +
                                         " names point " + std::to_string(v) + " twice");
        }
      }
      out.cells(j, c) = static_cast<int>(v);
    }
  }
  // Point and cell data.
  const std::tuple<const char*, std::int64_t, VtuArrays*> sections[] = {
      {"PointData", num_points, &out.point_data}, {"CellData", num_cells, &out.cell_data}};
  for (const auto& [section, count, target] : sections) {
    const XmlElement* data = child(piece, section);
    if (data == nullptr) continue;
    for (const XmlElement* e : arrays_of(*data)) {
      const std::string* name = e->Attribute("Name");
      if (name == nullptr || name->empty())
        Fail(e->offset, std::string("<") + section + ">: a DataArray has no Name");
      const std::string* type_name = e->Attribute("type");
      if (type_name && ScalarTypeOf(*type_name) < 0 &&
          (*type_name == "String" || *type_name == "Bit")) {
        continue;  // not numeric: skipped
      }
      if (target->count(*name) || (*name == "region" && out.regions.size() > 0)) {
        Fail(e->offset, std::string("<") + section + "> has two arrays named " + *name);
      }
      int components = 0;
      const Array a = DecodeArray(*e, count, 0, &components);
      if (std::string(section) == "CellData" && *name == "region") {
        if (components != 1) Fail(e->offset, Where(*e) + ": region must have one component");
        out.regions.resize(num_cells);
        for (std::int64_t c = 0; c < num_cells; ++c) {
          const double r = a.Real(static_cast<std::size_t>(c));
          if (!std::isfinite(r) || r != std::floor(r) || r < std::numeric_limits<int>::min() ||
              r > std::numeric_limits<int>::max()) {
            std::ostringstream s;
            s << Where(*e) << ": cell " << c << " has region " << r
              << ", which is not an integer label";
            Fail(e->offset, s.str());
          }
          out.regions(c) = static_cast<int>(r);
        }
        continue;
      }
      Eigen::MatrixXd values(components, count);
      for (std::int64_t i = 0; i < components * count; ++i)
        values.data()[i] = a.Real(static_cast<std::size_t>(i));
      (*target)[*name] = std::move(values);
    }
  }
  return out;
}

}  // namespace

VtuError::VtuError(const std::string& source, std::size_t offset, const std::string& message)
    : std::runtime_error(source + ": byte " + std::to_string(offset) + ": " + message),
      source_(source),
      offset_(offset) {}

VtuGrid ParseVtuGrid(std::string_view bytes, const std::string& source) {
  VtuParser parser(bytes, source);
  try {
    return parser.Parse();
  } catch (const VtuError&) {
    throw;
  } catch (const std::bad_alloc&) {
    throw VtuError(source, 0, "out of memory while reading (the counts are too large)");
  } catch (const std::length_error&) {
    throw VtuError(source, 0, "out of memory while reading (the counts are too large)");
  }
}

VtuGrid ReadVtuGrid(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw VtuError(path, 0, std::string("cannot open the file: ") + std::strerror(errno));
  std::string bytes;
  in.seekg(0, std::ios::end);
  const std::streamoff size = in.tellg();
  if (size < 0) throw VtuError(path, 0, "cannot read the file (not a regular file?)");
  in.seekg(0, std::ios::beg);
  bytes.resize(static_cast<std::size_t>(size));
  if (size > 0 && !in.read(bytes.data(), size)) throw VtuError(path, 0, "cannot read the file");
  return ParseVtuGrid(bytes, path);
}

// ---------------------------------------------------------------------------------------------
// VTU writing.

namespace {

void CheckGridArrays(const VtuArrays& arrays, Eigen::Index cols, const char* kind) {
  for (const auto& [name, values] : arrays) {
    if (name.empty() || name.find_first_of("\"<>&'") != std::string::npos) {
      throw std::invalid_argument(std::string("WriteVtuGrid: bad ") + kind + " array name '" +
                                  name + "'");
    }
    if (values.cols() != cols || values.rows() < 1 || values.rows() > kMaxComponents) {
      throw std::invalid_argument(std::string("WriteVtuGrid: ") + kind + " array '" + name +
                                  "' is " + std::to_string(values.rows()) + " by " +
                                  std::to_string(values.cols()) + ", expected k by " +
                                  std::to_string(cols) + " (k in 1..64)");
    }
    if (!values.allFinite()) {
      throw std::invalid_argument(std::string("WriteVtuGrid: ") + kind + " array '" + name +
                                  "' is not finite");
    }
  }
}

// One array to write: its XML attributes and its values as raw little-endian bytes or text.
struct OutArray {
  std::string type, name;
  int components = 1;
  std::string bytes;  // raw little-endian values
  std::string text;   // ascii values
};

template <typename T>
void AppendRaw(std::string* bytes, T v) {
  static_assert(std::endian::native == std::endian::little,
                "the writer assumes a little-endian host");
  char b[sizeof(T)];
  std::memcpy(b, &v, sizeof(T));
  bytes->append(b, sizeof(T));
}

OutArray RealArray(const std::string& name, const Eigen::MatrixXd& values, bool ascii) {
  OutArray a{"Float64", name, static_cast<int>(values.rows()), {}, {}};
  char buf[32];
  for (Eigen::Index i = 0; i < values.size(); ++i) {
    if (ascii) {
      if (i % (6 * a.components) == 0) a.text += "\n         ";
      std::snprintf(buf, sizeof(buf), " %.17g", values.data()[i]);
      a.text += buf;
    } else {
      AppendRaw(&a.bytes, values.data()[i]);
    }
  }
  return a;
}

template <typename T>
OutArray IntArray(const std::string& type, const std::string& name,
                  const std::vector<std::int64_t>& values, int per_line, bool ascii) {
  OutArray a{type, name, 1, {}, {}};
  for (std::size_t i = 0; i < values.size(); ++i) {
    if (ascii) {
      if (i % per_line == 0) a.text += "\n          ";
      a.text += (i % per_line ? " " : "") + std::to_string(values[i]);
    } else {
      AppendRaw(&a.bytes, static_cast<T>(values[i]));
    }
  }
  return a;
}

}  // namespace

void WriteVtuGrid(const VtuGrid& grid, const std::string& path, VtuEncoding encoding) {
  const Eigen::Index nv = grid.points.cols(), nt = grid.cells.cols();
  const int npe = static_cast<int>(grid.cells.rows());
  if (npe != 4 && npe != 10) {
    throw std::invalid_argument("WriteVtuGrid: cells have " + std::to_string(npe) +
                                " rows, expected 4 or 10");
  }
  if (!grid.points.allFinite())
    throw std::invalid_argument("WriteVtuGrid: a point coordinate is not finite");
  for (Eigen::Index t = 0; t < nt; ++t) {
    for (int k = 0; k < npe; ++k) {
      const int i = grid.cells(k, t);
      if (i < 0 || i >= nv) {
        throw std::invalid_argument("WriteVtuGrid: cell " + std::to_string(t) +
                                    " has point index " + std::to_string(i) + " outside [0, " +
                                    std::to_string(nv) + ")");
      }
      for (int m = 0; m < k; ++m) {
        if (grid.cells(m, t) == i) {
          throw std::invalid_argument("WriteVtuGrid: cell " + std::to_string(t) +
                                      " repeats point " + std::to_string(i));
        }
      }
    }
  }
  if (grid.regions.size() != 0 && grid.regions.size() != nt) {
    throw std::invalid_argument("WriteVtuGrid: " + std::to_string(grid.regions.size()) +
                                " regions for " + std::to_string(nt) + " cells");
  }
  CheckGridArrays(grid.point_data, nv, "point");
  CheckGridArrays(grid.cell_data, nt, "cell");
  if (grid.regions.size() != 0 && grid.cell_data.count("region")) {
    throw std::invalid_argument(
        "WriteVtuGrid: cell array name 'region' is reserved for the regions");
  }

  const bool ascii = encoding == VtuEncoding::kAscii;
  std::vector<OutArray> point_arrays, cell_arrays, cell_topology;
  for (const auto& [name, values] : grid.point_data)
    point_arrays.push_back(RealArray(name, values, ascii));
  if (grid.regions.size() != 0) {
    std::vector<std::int64_t> r(grid.regions.data(), grid.regions.data() + nt);
    cell_arrays.push_back(IntArray<std::int32_t>("Int32", "region", r, 16, ascii));
  }
  for (const auto& [name, values] : grid.cell_data)
    cell_arrays.push_back(RealArray(name, values, ascii));
  const OutArray points = RealArray("Points", grid.points, ascii);
  {
    std::vector<std::int64_t> conn, offs, types;
    for (Eigen::Index t = 0; t < nt; ++t) {
      for (int k = 0; k < npe; ++k) conn.push_back(grid.cells(k, t));
      offs.push_back(static_cast<std::int64_t>(npe) * (t + 1));
      types.push_back(npe == 4 ? 10 : 24);
    }
    cell_topology.push_back(IntArray<std::int64_t>("Int64", "connectivity", conn, npe, ascii));
    cell_topology.push_back(IntArray<std::int64_t>("Int64", "offsets", offs, 16, ascii));
    cell_topology.push_back(IntArray<std::uint8_t>("UInt8", "types", types, 32, ascii));
  }

  std::string xml, appended;
  auto emit = [&](const OutArray& a) {
    xml += "        <DataArray type=\"" + a.type + "\" Name=\"" + a.name + "\"";
    if (a.components != 1) xml += " NumberOfComponents=\"" + std::to_string(a.components) + "\"";
    if (ascii) {
      xml += " format=\"ascii\">" + a.text + "\n        </DataArray>\n";
    } else {
      xml += " format=\"appended\" offset=\"" + std::to_string(appended.size()) + "\"/>\n";
      AppendRaw(&appended, static_cast<std::uint64_t>(a.bytes.size()));
      appended += a.bytes;
    }
  };
  xml += "<?xml version=\"1.0\"?>\n";
  xml +=
      "<VTKFile type=\"UnstructuredGrid\" version=\"1.0\" byte_order=\"LittleEndian\" "
      "header_type=\"UInt64\">\n";
  xml += "  <UnstructuredGrid>\n";
  xml += "    <Piece NumberOfPoints=\"" + std::to_string(nv) + "\" NumberOfCells=\"" +
         std::to_string(nt) + "\">\n";
  xml += "      <PointData>\n";
  for (const OutArray& a : point_arrays) emit(a);
  xml += "      </PointData>\n      <CellData>\n";
  for (const OutArray& a : cell_arrays) emit(a);
  xml += "      </CellData>\n      <Points>\n";
  emit(points);
  xml += "      </Points>\n      <Cells>\n";
  for (const OutArray& a : cell_topology) emit(a);
  xml += "      </Cells>\n    </Piece>\n  </UnstructuredGrid>\n";
  if (!ascii) xml += "  <AppendedData encoding=\"raw\">\n   _";

  // Temporary file, then rename: nothing half-written under the final name.
  const std::string temp = path + ".tmp" + std::to_string(static_cast<long>(::getpid()));
  {
    File file(temp, path);
    std::FILE* f = file.get();
    std::fwrite(xml.data(), 1, xml.size(), f);
    if (!ascii) {
      std::fwrite(appended.data(), 1, appended.size(), f);
      std::fputs("\n  </AppendedData>\n", f);
    }
    std::fputs("</VTKFile>\n", f);
    try {
      file.Close();
    } catch (...) {
      std::remove(temp.c_str());
      throw;
    }
  }
  if (std::rename(temp.c_str(), path.c_str()) != 0) {
    const std::string reason = std::strerror(errno);
    std::remove(temp.c_str());
    throw std::runtime_error(path + ": cannot write the .vtu file: " + reason);
  }
}

}  // namespace spidarcad::modeling
