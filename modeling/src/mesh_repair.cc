// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#include "spidarcad/modeling/mesh_repair.h"

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <deque>
#include <map>
#include <numbers>
#include <unordered_map>

#include "spidarcad/modeling/triangle_mesh_io.h"

namespace spidarcad::modeling {

namespace {

using Tri = std::array<int, 3>;

std::string Num(double x) {
  char buffer[48];
  std::snprintf(buffer, sizeof buffer, "%.9g", x);
  return buffer;
}

std::string Point(const Eigen::Vector3d& p) {
  return "(" + Num(p.x()) + ", " + Num(p.y()) + ", " + Num(p.z()) + ")";
}

// Undirected edge key.
uint64_t EdgeKey(int a, int b) {
  if (a > b) std::swap(a, b);
  return (static_cast<uint64_t>(static_cast<uint32_t>(a)) << 32) | static_cast<uint32_t>(b);
}

// Welds vertices within eps (grid hashing of cell 2 eps, each compared with its cell and the
// neighbours'); returns each vertex's representative (the lowest index of its cluster).
std::vector<int> WeldTargets(const Eigen::Matrix3Xd& v, double eps, long* welded) {
  const Eigen::Index nv = v.cols();
  std::vector<int> target(nv);
  for (Eigen::Index i = 0; i < nv; ++i) target[i] = static_cast<int>(i);
  *welded = 0;
  if (nv == 0) return target;
  const Eigen::Vector3d lo = v.rowwise().minCoeff();
  const double h = std::max(2.0 * eps, 1e-300);
  using Key = std::array<int64_t, 3>;
  std::map<Key, std::vector<int>> cells;
  for (Eigen::Index i = 0; i < nv; ++i) {
    const Eigen::Vector3d p = v.col(i);
    Key c;
    for (int a = 0; a < 3; ++a) c[a] = static_cast<int64_t>(std::floor((p[a] - lo[a]) / h));
    int found = -1;
    for (int dz = -1; dz <= 1 && found < 0; ++dz)
      for (int dy = -1; dy <= 1 && found < 0; ++dy)
        for (int dx = -1; dx <= 1 && found < 0; ++dx) {
          const auto it = cells.find(Key{c[0] + dx, c[1] + dy, c[2] + dz});
          if (it == cells.end()) continue;
          for (int j : it->second)
            if ((v.col(j) - p).norm() <= eps) {
              found = j;
              break;
            }
        }
    if (found >= 0) {
      target[i] = found;
      ++*welded;
    } else {
      cells[c].push_back(static_cast<int>(i));
    }
  }
  return target;
}

// Twice the area of triangle t against the tolerance: whether it is zero.
bool ZeroArea(const Eigen::Matrix3Xd& v, const Tri& t, double area_tolerance) {
  const Eigen::Vector3d a = v.col(t[0]), b = v.col(t[1]), c = v.col(t[2]);
  const double longest =
      std::max({(b - a).squaredNorm(), (c - b).squaredNorm(), (a - c).squaredNorm()});
  return (b - a).cross(c - a).norm() <= area_tolerance * longest;
}

// Solid angle of triangle (a, b, c) seen from p (Van Oosterom and Strackee), signed: positive
// when p is on the inner side of a counter-clockwise (outward) triangle.
double SolidAngle(const Eigen::Vector3d& p, const Eigen::Vector3d& a, const Eigen::Vector3d& b,
                  const Eigen::Vector3d& c) {
  const Eigen::Vector3d ra = a - p, rb = b - p, rc = c - p;
  const double la = ra.norm(), lb = rb.norm(), lc = rc.norm();
  const double numerator = ra.dot(rb.cross(rc));
  const double denominator = la * lb * lc + ra.dot(rb) * lc + rb.dot(rc) * la + rc.dot(ra) * lb;
  return 2.0 * std::atan2(numerator, denominator);
}

// The working state of a repair: triangles with the file position each came from.
struct Soup {
  const Eigen::Matrix3Xd* vertices;
  std::vector<Tri> tris;
  std::vector<long> origin;  // 0-based index of the triangle in the input
};

class Repairer {
 public:
  Repairer(const MeshRepairSettings& settings, MeshRepairReport* report, std::string source)
      : settings_(settings), report_(*report), prefix_(source.empty() ? "" : source + ": ") {}

  TriangleMesh Run(const TriangleMesh& mesh);

 private:
  [[noreturn]] void Fail(MeshDefect defect, long origin, const std::string& what) const {
    throw MeshDefectError(defect, origin + 1, prefix_ + what);
  }
  std::string TriangleName(size_t t) const {
    return "triangle " + std::to_string(soup_.origin[t] + 1) + " of the file";
  }
  std::string EdgeText(int a, int b) const {
    return "the edge from " + Point(soup_.vertices->col(a)) + " to " +
           Point(soup_.vertices->col(b));
  }
  void DropDegenerate();
  void DropDuplicates();
  void CheckEdges();
  void Orient();
  void CheckSelfIntersections(const TriangleMesh& out);

  const MeshRepairSettings& settings_;
  MeshRepairReport& report_;
  std::string prefix_;
  Soup soup_;
  double eps_ = 0.0;
};

void Repairer::DropDegenerate() {
  const Eigen::Matrix3Xd& v = *soup_.vertices;
  std::vector<Tri> kept, degenerate;
  std::vector<long> kept_origin;
  for (size_t t = 0; t < soup_.tris.size(); ++t) {
    if (ZeroArea(v, soup_.tris[t], settings_.area_tolerance)) {
      degenerate.push_back(soup_.tris[t]);
    } else {
      kept.push_back(soup_.tris[t]);
      kept_origin.push_back(soup_.origin[t]);
    }
  }
  report_.degenerate_triangles = static_cast<long>(degenerate.size());
  soup_.tris = std::move(kept);
  soup_.origin = std::move(kept_origin);
  if (degenerate.empty()) return;
  // A zero-area triangle (a, m, c) with m between a and c stood for a crack along (a, c): the
  // triangle across (a, c) is split at m so that its edges meet (a, m) and (m, c).
  std::unordered_map<uint64_t, std::vector<int>> edge_tris;
  auto add = [&](int t) {
    for (int k = 0; k < 3; ++k)
      edge_tris[EdgeKey(soup_.tris[t][k], soup_.tris[t][(k + 1) % 3])].push_back(t);
  };
  auto remove = [&](int t) {
    for (int k = 0; k < 3; ++k) {
      auto& list = edge_tris[EdgeKey(soup_.tris[t][k], soup_.tris[t][(k + 1) % 3])];
      list.erase(std::remove(list.begin(), list.end(), t), list.end());
    }
  };
  for (size_t t = 0; t < soup_.tris.size(); ++t) add(static_cast<int>(t));
  for (const Tri& d : degenerate) {
    // The middle corner is the one opposite the longest edge.
    int middle = 0;
    double longest = -1.0;
    for (int k = 0; k < 3; ++k) {
      const double len = (v.col(d[(k + 1) % 3]) - v.col(d[(k + 2) % 3])).squaredNorm();
      if (len > longest) {
        longest = len;
        middle = k;
      }
    }
    const int m = d[middle], a = d[(middle + 1) % 3], c = d[(middle + 2) % 3];
    const auto it = edge_tris.find(EdgeKey(a, c));
    if (it == edge_tris.end()) continue;
    const std::vector<int> across = it->second;
    for (int t : across) {
      const Tri tri = soup_.tris[t];
      int k = 0;
      while (!((tri[k] == a && tri[(k + 1) % 3] == c) || (tri[k] == c && tri[(k + 1) % 3] == a)))
        ++k;
      const int u = tri[k], w = tri[(k + 1) % 3], opposite = tri[(k + 2) % 3];
      if (opposite == m) continue;
      remove(t);
      soup_.tris[t] = Tri{u, m, opposite};
      add(t);
      soup_.tris.push_back(Tri{m, w, opposite});
      soup_.origin.push_back(soup_.origin[t]);
      add(static_cast<int>(soup_.tris.size() - 1));
      ++report_.split_triangles;
    }
  }
}

void Repairer::DropDuplicates() {
  // Group the triangles by their sorted corners; the orientation is the parity of the sort.
  std::map<Tri, std::vector<int>> groups;
  for (size_t t = 0; t < soup_.tris.size(); ++t) {
    Tri s = soup_.tris[t];
    std::sort(s.begin(), s.end());
    groups[s].push_back(static_cast<int>(t));
  }
  std::vector<char> drop(soup_.tris.size(), 0);
  for (const auto& [key, members] : groups) {
    if (members.size() < 2) continue;
    // Same orientation as `key` (an even permutation of it) or opposite.
    std::vector<int> plus, minus;
    for (int t : members) {
      const Tri& tri = soup_.tris[t];
      int k = 0;
      while (tri[k] != key[0]) ++k;
      (tri[(k + 1) % 3] == key[1] ? plus : minus).push_back(t);
    }
    const size_t pairs = std::min(plus.size(), minus.size());
    report_.back_to_back_pairs += static_cast<long>(pairs);
    for (size_t i = 0; i < pairs; ++i) drop[plus[i]] = drop[minus[i]] = 1;
    // Of the rest (one orientation only), the first is kept.
    const std::vector<int>& rest = plus.size() > pairs ? plus : minus;
    for (size_t i = pairs + 1; i < rest.size(); ++i) {
      drop[rest[i]] = 1;
      ++report_.duplicate_triangles;
    }
  }
  std::vector<Tri> kept;
  std::vector<long> kept_origin;
  for (size_t t = 0; t < soup_.tris.size(); ++t) {
    if (drop[t]) continue;
    kept.push_back(soup_.tris[t]);
    kept_origin.push_back(soup_.origin[t]);
  }
  soup_.tris = std::move(kept);
  soup_.origin = std::move(kept_origin);
}

void Repairer::CheckEdges() {
  std::unordered_map<uint64_t, int> count;
  for (const Tri& t : soup_.tris)
    for (int k = 0; k < 3; ++k) ++count[EdgeKey(t[k], t[(k + 1) % 3])];
  long open = 0, non_manifold = 0;
  for (const auto& [key, n] : count) {
    open += n == 1;
    non_manifold += n >= 3;
  }
  if (non_manifold == 0 && open == 0) return;
  // The first offending triangle in file order.
  size_t first = 0;
  int fa = 0, fb = 0, fn = 0;
  long first_origin = -1;
  for (size_t t = 0; t < soup_.tris.size(); ++t) {
    for (int k = 0; k < 3; ++k) {
      const int a = soup_.tris[t][k], b = soup_.tris[t][(k + 1) % 3];
      const int n = count[EdgeKey(a, b)];
      const bool bad = non_manifold > 0 ? n >= 3 : n == 1;
      if (bad && (first_origin < 0 || soup_.origin[t] < first_origin)) {
        first = t;
        fa = a;
        fb = b;
        fn = n;
        first_origin = soup_.origin[t];
      }
    }
  }
  const std::string tol = "the weld tolerance (" + Num(eps_) + " in the file's units)";
  if (non_manifold > 0) {
    Fail(MeshDefect::kNonManifoldEdge, first_origin,
         "the surface is non-manifold: " + std::to_string(non_manifold) +
             " edges have three or more triangles; the first is " + EdgeText(fa, fb) + " of " +
             TriangleName(first) + ", shared by " + std::to_string(fn) +
             " triangles. A solid's surface has two triangles on every edge: separate the parts "
             "that meet along this edge in the modeller (or union them into one closed shell) and "
             "export again");
  }
  Fail(MeshDefect::kOpen, first_origin,
       "the surface is open: " + std::to_string(open) +
           " edges have one triangle only (holes or cracks wider than " + tol + "); the first is " +
           EdgeText(fa, fb) + " of " + TriangleName(first) +
           ". Close the holes in the modeller (export the part as a closed solid), or, if the "
           "edges are a crack from rounding, raise the weld tolerance");
}

void Repairer::Orient() {
  const size_t nf = soup_.tris.size();
  const Eigen::Matrix3Xd& v = *soup_.vertices;
  // Each edge has exactly two triangles here (CheckEdges).
  std::unordered_map<uint64_t, std::array<int, 2>> edge_tris;
  for (size_t t = 0; t < nf; ++t)
    for (int k = 0; k < 3; ++k) {
      auto [it, inserted] = edge_tris.try_emplace(
          EdgeKey(soup_.tris[t][k], soup_.tris[t][(k + 1) % 3]), std::array<int, 2>{-1, -1});
      it->second[it->second[0] < 0 ? 0 : 1] = static_cast<int>(t);
    }
  // Whether triangle t traverses a -> b.
  auto traverses = [&](int t, int a, int b) {
    for (int k = 0; k < 3; ++k)
      if (soup_.tris[t][k] == a && soup_.tris[t][(k + 1) % 3] == b) return true;
    return false;
  };
  std::vector<int> component(nf, -1);
  std::vector<char> flip(nf, 0);
  int components = 0;
  for (size_t seed = 0; seed < nf; ++seed) {
    if (component[seed] >= 0) continue;
    std::deque<int> queue{static_cast<int>(seed)};
    component[seed] = components;
    while (!queue.empty()) {
      const int t = queue.front();
      queue.pop_front();
      for (int k = 0; k < 3; ++k) {
        // t's edge a -> b as it will be after its flip.
        int a = soup_.tris[t][k], b = soup_.tris[t][(k + 1) % 3];
        if (flip[t]) std::swap(a, b);
        const auto& pair = edge_tris.at(EdgeKey(a, b));
        const int n = pair[0] == t ? pair[1] : pair[0];
        // Consistent: n traverses b -> a after its flip.
        const bool n_needs_flip = traverses(n, a, b);
        if (component[n] < 0) {
          component[n] = components;
          flip[n] = n_needs_flip;
          queue.push_back(n);
        } else if (static_cast<bool>(flip[n]) != n_needs_flip) {
          Fail(MeshDefect::kNonOrientable, soup_.origin[n],
               "the surface is not orientable (a Moebius-like band): no orientation of " +
                   TriangleName(n) + " agrees with all its neighbours across " + EdgeText(a, b) +
                   ". A solid's boundary is orientable: rebuild this part");
        }
      }
    }
    ++components;
  }
  auto oriented = [&](size_t t) {
    Tri tri = soup_.tris[t];
    if (flip[t]) std::swap(tri[1], tri[2]);
    return tri;
  };
  // Each component outward: positive volume unless it lies inside an odd number of the others
  // (a cavity). Nesting by the winding number of one of its vertices against each other
  // component (with that component's own orientation: +-1 inside, 0 outside).
  std::vector<double> volume(components, 0.0);
  for (size_t t = 0; t < nf; ++t) {
    const Tri tri = oriented(t);
    volume[component[t]] +=
        v.col(tri[0]).dot(Eigen::Vector3d(v.col(tri[1])).cross(Eigen::Vector3d(v.col(tri[2])))) /
        6.0;
  }
  std::vector<char> reverse(components, 0);
  constexpr int kMaxNestingTest = 64;
  if (components <= kMaxNestingTest) {
    // The probe of a component: the centroid of its first triangle (a vertex could be shared
    // with another component where they touch).
    std::vector<Eigen::Vector3d> probe(components);
    std::vector<char> has_probe(components, 0);
    for (size_t t = 0; t < nf; ++t) {
      if (has_probe[component[t]]) continue;
      has_probe[component[t]] = 1;
      const Tri& tri = soup_.tris[t];
      probe[component[t]] = (v.col(tri[0]) + v.col(tri[1]) + v.col(tri[2])) / 3.0;
    }
    std::vector<double> winding(components * components, 0.0);
    for (size_t t = 0; t < nf; ++t) {
      const Tri tri = oriented(t);
      const int owner = component[t];
      for (int c = 0; c < components; ++c) {
        if (c == owner) continue;
        winding[c * components + owner] +=
            SolidAngle(probe[c], v.col(tri[0]), v.col(tri[1]), v.col(tri[2]));
      }
    }
    for (int c = 0; c < components; ++c) {
      int depth = 0;
      for (int d = 0; d < components; ++d)
        if (d != c && std::abs(winding[c * components + d]) > 2.0 * std::numbers::pi) ++depth;
      const bool want_positive = depth % 2 == 0;
      reverse[c] = (volume[c] > 0) != want_positive;
    }
  } else {
    double total = 0.0;
    for (double x : volume) total += x;
    for (int c = 0; c < components; ++c) reverse[c] = total < 0;
  }
  for (size_t t = 0; t < nf; ++t) {
    if (reverse[component[t]]) flip[t] = !flip[t];
    if (flip[t]) {
      std::swap(soup_.tris[t][1], soup_.tris[t][2]);
      ++report_.flipped_triangles;
    }
  }
}

void Repairer::CheckSelfIntersections(const TriangleMesh& out) {
  if (!settings_.check_self_intersections) return;
  std::vector<std::pair<int, int>> pairs;
  try {
    pairs = FindSelfIntersections(out);
  } catch (const std::invalid_argument& e) {
    Fail(MeshDefect::kSelfIntersection, -1,
         std::string("the self-intersection test failed: ") + e.what());
  }
  if (pairs.empty()) return;
  // The pair whose first triangle comes first in the file.
  auto order = [&](const std::pair<int, int>& p) {
    return std::minmax(soup_.origin[p.first], soup_.origin[p.second]);
  };
  const auto first =
      *std::min_element(pairs.begin(), pairs.end(),
                        [&](const auto& x, const auto& y) { return order(x) < order(y); });
  const auto [lo, hi] = order(first);
  Fail(MeshDefect::kSelfIntersection, lo,
       "the surface intersects itself: " + std::to_string(pairs.size()) +
           " pairs of triangles cross; the first is triangle " + std::to_string(lo + 1) +
           " and triangle " + std::to_string(hi + 1) + " of the file (near " +
           Point(out.vertices.col(out.triangles(0, first.first))) +
           "). Remove the overlap in the modeller (a boolean union of the overlapping parts) "
           "and export again");
}

TriangleMesh Repairer::Run(const TriangleMesh& mesh) {
  const auto start = std::chrono::steady_clock::now();
  const Eigen::Index nv = mesh.vertices.cols(), nf = mesh.triangles.cols();
  report_ = MeshRepairReport{};
  report_.input_vertices = nv;
  report_.input_triangles = nf;
  for (Eigen::Index i = 0; i < nv; ++i)
    if (!mesh.vertices.col(i).allFinite())
      throw MeshDefectError(MeshDefect::kNonFinite, 0,
                            prefix_ + "vertex " + std::to_string(i + 1) +
                                " has a non-finite coordinate " + Point(mesh.vertices.col(i)) +
                                ": fix or remove it");
  for (Eigen::Index f = 0; f < nf; ++f)
    for (int k = 0; k < 3; ++k)
      if (mesh.triangles(k, f) < 0 || mesh.triangles(k, f) >= nv)
        throw std::invalid_argument(prefix_ + "triangle " + std::to_string(f + 1) +
                                    " has a vertex index outside [0, " + std::to_string(nv) + ")");
  const double diagonal =
      nv ? (mesh.vertices.rowwise().maxCoeff() - mesh.vertices.rowwise().minCoeff()).norm() : 0.0;
  eps_ = settings_.weld_tolerance * diagonal;
  const std::vector<int> target = WeldTargets(mesh.vertices, eps_, &report_.welded_vertices);
  soup_.vertices = &mesh.vertices;
  for (Eigen::Index f = 0; f < nf; ++f) {
    const Tri t{target[mesh.triangles(0, f)], target[mesh.triangles(1, f)],
                target[mesh.triangles(2, f)]};
    if (t[0] == t[1] || t[1] == t[2] || t[0] == t[2]) {
      ++report_.collapsed_triangles;
      continue;
    }
    soup_.tris.push_back(t);
    soup_.origin.push_back(f);
  }
  DropDegenerate();
  DropDuplicates();
  if (soup_.tris.empty()) {
    throw MeshDefectError(MeshDefect::kEmpty, 0,
                          prefix_ + "no triangle is left of " + std::to_string(nf) +
                              " after dropping the zero-area and back-to-back ones: the file "
                              "holds no solid");
  }
  CheckEdges();
  Orient();
  // Compact the vertices (in order of first use by index) and build the output.
  std::vector<int> index(nv, -1);
  for (const Tri& t : soup_.tris)
    for (int c : t) index[c] = 0;
  int used = 0;
  for (Eigen::Index i = 0; i < nv; ++i)
    if (index[i] == 0) index[i] = used++;
  report_.unused_vertices = static_cast<long>(nv - report_.welded_vertices - used);
  TriangleMesh out;
  out.vertices.resize(3, used);
  for (Eigen::Index i = 0; i < nv; ++i)
    if (index[i] >= 0) out.vertices.col(index[i]) = mesh.vertices.col(i);
  out.triangles.resize(3, static_cast<Eigen::Index>(soup_.tris.size()));
  for (size_t t = 0; t < soup_.tris.size(); ++t)
    for (int k = 0; k < 3; ++k) out.triangles(k, t) = index[soup_.tris[t][k]];
  CheckSelfIntersections(out);
  report_.output_vertices = used;
  report_.output_triangles = static_cast<long>(soup_.tris.size());
  report_.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return out;
}

}  // namespace

const char* MeshDefectName(MeshDefect defect) {
  switch (defect) {
    case MeshDefect::kNonFinite:
      return "non-finite coordinate";
    case MeshDefect::kEmpty:
      return "empty";
    case MeshDefect::kOpen:
      return "open";
    case MeshDefect::kNonManifoldEdge:
      return "non-manifold edge";
    case MeshDefect::kNonOrientable:
      return "non-orientable";
    case MeshDefect::kSelfIntersection:
      return "self-intersection";
  }
  return "unknown";
}

bool MeshRepairReport::Changed() const {
  return welded_vertices || unused_vertices || collapsed_triangles || degenerate_triangles ||
         split_triangles || duplicate_triangles || back_to_back_pairs || flipped_triangles;
}

std::vector<std::string> MeshRepairReport::Lines() const {
  std::vector<std::string> lines;
  auto line = [&](long n, const std::string& what) {
    if (n > 0) lines.push_back(std::to_string(n) + " " + what);
  };
  line(welded_vertices, "vertices welded into a neighbour within the tolerance");
  line(collapsed_triangles, "triangles dropped that lost a corner to the welding");
  line(degenerate_triangles, "zero-area triangles dropped");
  line(split_triangles, "triangles split at the middle corner of a dropped zero-area one");
  line(duplicate_triangles, "repeated triangles dropped");
  line(back_to_back_pairs, "back-to-back triangle pairs dropped (both of each)");
  line(flipped_triangles, "triangles turned over (consistent, outward orientation)");
  line(unused_vertices, "unused vertices dropped");
  if (lines.empty()) lines.push_back("no repair needed");
  return lines;
}

TriangleMesh RepairTriangleMesh(const TriangleMesh& mesh, const MeshRepairSettings& settings,
                                MeshRepairReport* report, const std::string& source) {
  if (!(settings.weld_tolerance >= 0.0 && settings.weld_tolerance < 0.1))
    throw std::invalid_argument("MeshRepairSettings::weld_tolerance = " +
                                Num(settings.weld_tolerance) + ": must be in [0, 0.1)");
  if (!(settings.area_tolerance >= 0.0 && settings.area_tolerance < 1.0))
    throw std::invalid_argument("MeshRepairSettings::area_tolerance = " +
                                Num(settings.area_tolerance) + ": must be in [0, 1)");
  MeshRepairReport local;
  Repairer repairer(settings, report ? report : &local, source);
  return repairer.Run(mesh);
}

TriangleMesh ImportSolidMesh(const std::string& path, const MeshRepairSettings& settings,
                             MeshRepairReport* report) {
  return RepairTriangleMesh(ReadTriangleMesh(path), settings, report, path);
}

}  // namespace spidarcad::modeling
