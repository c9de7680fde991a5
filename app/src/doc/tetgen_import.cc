// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#include "doc/tetgen_import.h"

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <sstream>
#include <utility>
#include <vector>

#include "doc/input_error.h"

namespace spidarcad::app {

namespace {

// The non-empty lines of a TetGen file without their '#' comments, with their 1-based numbers,
// each split into words.
struct Line {
  long number = 0;
  std::vector<std::string> words;
};

std::vector<Line> SplitLines(const std::string& text) {
  std::vector<Line> out;
  std::istringstream in(text);
  std::string raw;
  long number = 0;
  while (std::getline(in, raw)) {
    ++number;
    raw.resize(std::min(raw.size(), raw.find('#')));
    std::istringstream words(raw);
    Line line{number, {}};
    for (std::string w; words >> w;) line.words.push_back(std::move(w));
    if (!line.words.empty()) out.push_back(std::move(line));
  }
  return out;
}

// A word as an error message quotes it: at most 40 characters, bytes outside printable ASCII
// as \xNN.
std::string Quoted(const std::string& word) {
  constexpr std::size_t kMax = 40;
  std::string out = "'";
  for (std::size_t i = 0; i < word.size() && i < kMax; ++i) {
    const unsigned char c = static_cast<unsigned char>(word[i]);
    if (c >= 0x20 && c < 0x7f) {
      out += static_cast<char>(c);
    } else {
      char hex[5];
      std::snprintf(hex, sizeof hex, "\\x%02x", c);
      out += hex;
    }
  }
  if (word.size() > kMax) out += "...";
  return out + "'";
}

[[noreturn]] void Fail(const std::string& file, long line, const std::string& what) {
  throw InputError(file + ":" + std::to_string(line) + ": " + what);
}

// Word k of `line` as a finite double. A value too small for a normal double reads as the
// nearest subnormal (or zero), as the writers print it; one beyond the largest double is refused.
double Number(const std::string& file, const Line& line, std::size_t k, const char* field) {
  if (k >= line.words.size()) Fail(file, line.number, std::string(field) + " is missing");
  const std::string& w = line.words[k];
  char* end = nullptr;
  const double v = std::strtod(w.c_str(), &end);
  if (end != w.c_str() + w.size() || !std::isfinite(v)) {
    Fail(file, line.number, std::string(field) + " is not a finite number: " + Quoted(w));
  }
  return v;
}

long Integer(const std::string& file, const Line& line, std::size_t k, const char* field) {
  const double v = Number(file, line, k, field);
  if (v != std::floor(v) || std::abs(v) > 2e9)
    Fail(file, line.number, std::string(field) + " is not an integer: " + Quoted(line.words[k]));
  return static_cast<long>(v);
}

// Checks that `lines` (header included) hold exactly `count` records after the header.
void CheckCount(const std::string& file, const std::vector<Line>& lines, long count,
                const char* what) {
  const long records = static_cast<long>(lines.size()) - 1;
  if (records < count) {
    Fail(file, lines.back().number,
         "the header announces " + std::to_string(count) + " " + what + ", the file has " +
             std::to_string(records));
  }
  if (records > count) {
    Fail(file, lines[count + 1].number,
         "the header announces " + std::to_string(count) + " " + what + ", the file has " +
             std::to_string(records) + " (fix the count in the header or remove the extra lines)");
  }
}

// The record number in word 0 of line k of a block numbered consecutively from 0 or 1; sets
// *base from the first one.
void CheckRecordNumber(const std::string& file, const Line& line, long k, long* base,
                       const char* field) {
  const long index = Integer(file, line, 0, field);
  if (k == 0) {
    if (index != 0 && index != 1) {
      Fail(file, line.number,
           std::string(field) + " " + std::to_string(index) + ": numbering starts from 0 or 1");
    }
    *base = index;
  } else if (index != *base + k) {
    Fail(file, line.number,
         std::string(field) + " " + std::to_string(index) + ", expected " +
             std::to_string(*base + k));
  }
}

double SignedVolume(const modeling::TetMesh& m, Eigen::Index t) {
  const Eigen::Vector3d a = m.nodes.col(m.tets(0, t)), b = m.nodes.col(m.tets(1, t)),
                        c = m.nodes.col(m.tets(2, t)), d = m.nodes.col(m.tets(3, t));
  return (b - a).dot((c - a).cross(d - a)) / 6.0;
}

}  // namespace

int OrientTetsPositively(modeling::TetMesh* m,
                         const std::function<std::string(Eigen::Index)>& where) {
  int flipped = 0;
  for (Eigen::Index t = 0; t < m->tets.cols(); ++t) {
    const double v = SignedVolume(*m, t);
    if (v == 0.0) throw InputError(where(t) + " has zero volume");
    if (!std::isfinite(v)) {
      throw InputError(where(t) +
                       " has a volume beyond the largest double (its coordinates are too large)");
    }
    if (v < 0.0) {
      std::swap(m->tets(1, t), m->tets(2, t));
      ++flipped;
    }
  }
  return flipped;
}

modeling::TetMesh ParseTetgenFiles(const std::string& node_text, const std::string& ele_text,
                                   const std::string& node_file, const std::string& ele_file,
                                   int* flipped) {
  const std::vector<Line> nodes = SplitLines(node_text);
  if (nodes.empty()) throw InputError(node_file + ": empty .node file (no header line)");
  const Line& nh = nodes[0];
  const long count = Integer(node_file, nh, 0, "the number of points");
  const long dim = nh.words.size() > 1 ? Integer(node_file, nh, 1, "the dimension") : 3;
  const long attributes = nh.words.size() > 2 ? Integer(node_file, nh, 2, "attributes") : 0;
  const long markers = nh.words.size() > 3 ? Integer(node_file, nh, 3, "boundary markers") : 0;
  if (dim != 3) Fail(node_file, nh.number, "dimension is " + std::to_string(dim) + ", not 3");
  if (count <= 0) Fail(node_file, nh.number, "the number of points must be > 0");
  if (attributes < 0 || markers < 0 || markers > 1)
    Fail(node_file, nh.number, "attributes must be >= 0 and boundary markers 0 or 1");
  CheckCount(node_file, nodes, count, "points");
  modeling::TetMesh m;
  m.nodes.resize(3, count);
  long base = 0;
  for (long k = 0; k < count; ++k) {
    const Line& line = nodes[k + 1];
    CheckRecordNumber(node_file, line, k, &base, "point number");
    for (int i = 0; i < 3; ++i) {
      static const char* kAxes[3] = {"x", "y", "z"};
      m.nodes(i, k) = Number(node_file, line, 1 + i, kAxes[i]);
    }
    // Attributes and the marker may be left out (TetGen reads them as 0); those present are
    // numbers.
    const std::size_t extra = static_cast<std::size_t>(attributes + markers);
    for (std::size_t i = 4; i < line.words.size() && i < 4 + extra; ++i) {
      Number(node_file, line, i,
             i < 4 + static_cast<std::size_t>(attributes) ? "an attribute" : "the boundary marker");
    }
  }

  const std::vector<Line> eles = SplitLines(ele_text);
  if (eles.empty()) throw InputError(ele_file + ": empty .ele file (no header line)");
  const Line& eh = eles[0];
  const long tets = Integer(ele_file, eh, 0, "the number of tetrahedra");
  const long per = eh.words.size() > 1 ? Integer(ele_file, eh, 1, "nodes per tetrahedron") : 4;
  const long region = eh.words.size() > 2 ? Integer(ele_file, eh, 2, "region attribute") : 0;
  if (tets <= 0) Fail(ele_file, eh.number, "the number of tetrahedra must be > 0");
  if (per != 4 && per != 10) Fail(ele_file, eh.number, "nodes per tetrahedron must be 4 or 10");
  if (region < 0) Fail(ele_file, eh.number, "the number of region attributes must be >= 0");
  CheckCount(ele_file, eles, tets, "tetrahedra");
  m.tets.resize(4, tets);
  m.regions = Eigen::VectorXi::Zero(tets);  // 0: unknown, as TetGen without -A
  long tet_base = 0;
  for (long t = 0; t < tets; ++t) {
    const Line& line = eles[t + 1];
    CheckRecordNumber(ele_file, line, t, &tet_base, "tetrahedron number");
    // A quadratic tetrahedron's edge nodes are checked like its corners, then dropped.
    for (long c = 0; c < per; ++c) {
      const std::size_t k = static_cast<std::size_t>(1 + c);
      const long n = Integer(ele_file, line, k, "a node number") - base;
      if (n < 0 || n >= count) {
        Fail(ele_file, line.number, "node " + line.words[k] + " is not a point of " + node_file);
      }
      if (c >= 4) continue;
      // A repeated corner makes the volume zero, but the rounded triple product of two equal
      // edge vectors need not be exactly 0, so it is caught here by index.
      for (long prev = 0; prev < c; ++prev) {
        if (m.tets(static_cast<Eigen::Index>(prev), t) == n) {
          Fail(ele_file, line.number,
               "tetrahedron " + std::to_string(tet_base + t) + " repeats node " + line.words[k] +
                   " (a tetrahedron needs four distinct corners)");
        }
      }
      m.tets(static_cast<Eigen::Index>(c), t) = static_cast<int>(n);
    }
    if (region > 0) {
      m.regions(t) = static_cast<int>(
          Integer(ele_file, line, static_cast<std::size_t>(1 + per), "the region"));
    }
  }
  const int flips = OrientTetsPositively(&m, [&](Eigen::Index t) {
    return ele_file + ":" + std::to_string(eles[t + 1].number) + ": tetrahedron " +
           std::to_string(tet_base + t);
  });
  if (flipped != nullptr) *flipped = flips;
  return m;
}

}  // namespace spidarcad::app
