// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#include "spidarcad/modeling/tetgen_mesher.h"

#include <dlfcn.h>

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <limits>
#include <mutex>
#include <new>
#include <string>
#include <unordered_map>
#include <vector>

#include "spidarcad/base/check.h"
#include "triangle_predicates.h"

// TetGen defines REAL and many lowercase macros: this is the only file that includes it.
#define TETLIBRARY
#include <tetgen.h>

// TetGen 1.5 writes two sets of globals at the start of every run: the exact predicates'
// constants and static filters (exactinit, from the run's bounding box) and the tables that walk
// its mesh (tetgenmesh::inittables). libtet calls both through its PLT, so these definitions,
// which the executable exports, replace them: the library's own version runs once, with the static
// filter off (the filter is the one value that depends on the run), and later calls write nothing.
// Runs on several threads then share read-only globals (TetgenRunsConcurrently checks that the
// library's calls reach these definitions).
namespace {
std::once_flag tetgen_predicates_once, tetgen_tables_once;
bool tetgen_predicates_ready = false, tetgen_tables_ready = false;

template <class Function>
Function LibraryTetgen(const char* symbol) {
  return reinterpret_cast<Function>(dlsym(RTLD_NEXT, symbol));
}
}  // namespace

void exactinit(int /*verbose*/, int /*noexact*/, int /*nofilter*/, REAL /*maxx*/, REAL /*maxy*/,
               REAL /*maxz*/) {
  std::call_once(tetgen_predicates_once, [] {
    using ExactInit = void (*)(int, int, int, REAL, REAL, REAL);
    if (const auto library = LibraryTetgen<ExactInit>("_Z9exactinitiiiddd")) {
      library(0, 0, 1, 1.0, 1.0, 1.0);  // exact arithmetic, no static filter
      tetgen_predicates_ready = true;
    }
  });
  // Never uninitialised predicates (they would give wrong signs): a failed run instead.
  if (!tetgen_predicates_ready)
    throw spidarcad::modeling::TetgenError(2, "TetGen failed: libtet's exactinit was not found");
}

// TetGen 1.5 also shuffles its points with srand(seed) and rand() (incrementaldelaunay,
// collectremovepoints, insertconstrainedpoints), and glibc's generator is one for the process:
// two runs at once interleave their draws and insert the points in another order, so each makes
// another (valid) mesh from run to run. Inside a run (TetgenDraws, around tetrahedralize) these
// definitions draw from the calling thread's own generator, glibc's own algorithm
// (srandom_r/random_r on a 128-byte state, as rand's), so a run makes the mesh it makes alone;
// elsewhere they forward to glibc's.
namespace {
thread_local bool tetgen_draws = false;
struct ThreadRandom {
  random_data data{};
  alignas(std::int32_t) char state[128] = {};  // random_r reads it as int32_t
  bool ready = false;
  // random() is seeded with 1 until srandom is called.
  void Seed(unsigned seed) {
    if (!ready) {
      initstate_r(seed, state, sizeof state, &data);
      ready = true;
    } else {
      srandom_r(seed, &data);
    }
  }
};
thread_local ThreadRandom tetgen_random;

// Marks the calling thread's TetGen run for rand and srand.
class TetgenDraws {
 public:
  TetgenDraws() { tetgen_draws = true; }
  ~TetgenDraws() { tetgen_draws = false; }
  TetgenDraws(const TetgenDraws&) = delete;
  TetgenDraws& operator=(const TetgenDraws&) = delete;
};
}  // namespace

void srand(unsigned seed) noexcept {
  if (tetgen_draws) {
    tetgen_random.Seed(seed);
    return;
  }
  static const auto library = reinterpret_cast<void (*)(unsigned)>(dlsym(RTLD_NEXT, "srand"));
  if (library != nullptr) library(seed);
}

int rand() noexcept {
  if (tetgen_draws) {
    if (!tetgen_random.ready) tetgen_random.Seed(1);
    std::int32_t value = 0;
    random_r(&tetgen_random.data, &value);
    return value;
  }
  static const auto library = reinterpret_cast<int (*)()>(dlsym(RTLD_NEXT, "rand"));
  return library != nullptr ? library() : 0;
}

void tetgenmesh::inittables() {
  std::call_once(tetgen_tables_once, [this] {
    using InitTables = void (*)(tetgenmesh*);
    if (const auto library = LibraryTetgen<InitTables>("_ZN10tetgenmesh10inittablesEv")) {
      library(this);
      tetgen_tables_ready = true;
    }
  });
  if (!tetgen_tables_ready)
    throw spidarcad::modeling::TetgenError(2, "TetGen failed: libtet's inittables was not found");
}

namespace spidarcad::modeling {

namespace internal {
int TetgenTerminateAnchor();  // tetgen_terminate.cc
}  // namespace internal

namespace {

using Clock = std::chrono::steady_clock;

double Seconds(Clock::time_point since) {
  return std::chrono::duration<double>(Clock::now() - since).count();
}

std::string TriangleText(const TriangleMesh& m, Eigen::Index f) {
  return std::to_string(f) + " (" + std::to_string(m.triangles(0, f)) + ", " +
         std::to_string(m.triangles(1, f)) + ", " + std::to_string(m.triangles(2, f)) + ")";
}

// Whether triangles f and g intersect other than along what they share.
bool TrianglesIntersect(const TriangleMesh& m, Eigen::Index f, Eigen::Index g) {
  std::array<int, 3> a, b;
  std::array<Eigen::Vector3d, 3> pa, pb;
  for (int k = 0; k < 3; ++k) {
    a[k] = m.triangles(k, f);
    b[k] = m.triangles(k, g);
    pa[k] = m.vertices.col(a[k]);
    pb[k] = m.vertices.col(b[k]);
  }
  return internal::TrianglesMeet(a, pa, b, pb);
}

void CheckSelfIntersections(const TriangleMesh& m) {
  const Eigen::Index nf = m.triangles.cols();
  std::vector<Eigen::AlignedBox3d> boxes(nf);
  Eigen::AlignedBox3d all;
  double mean_extent = 0.0;
  for (Eigen::Index f = 0; f < nf; ++f) {
    for (int k = 0; k < 3; ++k) boxes[f].extend(Eigen::Vector3d(m.vertices.col(m.triangles(k, f))));
    all.extend(boxes[f]);
    mean_extent += boxes[f].sizes().maxCoeff();
  }
  mean_extent /= std::max<Eigen::Index>(nf, 1);
  const Eigen::Vector3d size = all.sizes();
  // Cells about twice the mean triangle size, at most ~2 cells per triangle overall.
  double h = std::max(2.0 * mean_extent, 1e-12 * size.maxCoeff() + 1e-300);
  Eigen::Vector3i dims;
  for (int iter = 0;; ++iter) {
    for (int a = 0; a < 3; ++a) dims[a] = std::max(1, static_cast<int>(std::ceil(size[a] / h)));
    if (double(dims[0]) * dims[1] * dims[2] <= 2.0 * nf + 8 || iter > 60) break;
    h *= 1.25;
  }
  auto cell_of = [&](const Eigen::Vector3d& p) {
    Eigen::Vector3i c;
    for (int a = 0; a < 3; ++a)
      c[a] = std::clamp(static_cast<int>((p[a] - all.min()[a]) / h), 0, dims[a] - 1);
    return c;
  };
  auto flat = [&](const Eigen::Vector3i& c) {
    return (static_cast<long>(c[2]) * dims[1] + c[1]) * dims[0] + c[0];
  };
  // Bucket triangles (counting sort into one array).
  const long ncells = static_cast<long>(dims[0]) * dims[1] * dims[2];
  std::vector<long> start(ncells + 1, 0);
  std::vector<std::pair<Eigen::Vector3i, Eigen::Vector3i>> range(nf);
  for (Eigen::Index f = 0; f < nf; ++f) {
    range[f] = {cell_of(boxes[f].min()), cell_of(boxes[f].max())};
    const auto& [lo, hi] = range[f];
    for (int z = lo[2]; z <= hi[2]; ++z)
      for (int y = lo[1]; y <= hi[1]; ++y)
        for (int x = lo[0]; x <= hi[0]; ++x) ++start[flat({x, y, z}) + 1];
  }
  for (long c = 0; c < ncells; ++c) start[c + 1] += start[c];
  std::vector<int> items(start[ncells]);
  std::vector<long> fill(start.begin(), start.end() - 1);
  for (Eigen::Index f = 0; f < nf; ++f) {
    const auto& [lo, hi] = range[f];
    for (int z = lo[2]; z <= hi[2]; ++z)
      for (int y = lo[1]; y <= hi[1]; ++y)
        for (int x = lo[0]; x <= hi[0]; ++x) items[fill[flat({x, y, z})]++] = static_cast<int>(f);
  }
  for (long c = 0; c < ncells; ++c) {
    for (long i = start[c]; i < start[c + 1]; ++i) {
      for (long j = i + 1; j < start[c + 1]; ++j) {
        const int f = items[i], g = items[j];
        const Eigen::AlignedBox3d overlap = boxes[f].intersection(boxes[g]);
        if (overlap.isEmpty()) continue;
        if (flat(cell_of(overlap.min())) != c) continue;  // the pair is tested in one cell only
        if (TrianglesIntersect(m, f, g)) {
          throw SurfaceDefectError("surface intersects itself: triangles " +
                                   TriangleText(m, std::min(f, g)) + " and " +
                                   TriangleText(m, std::max(f, g)));
        }
      }
    }
  }
}

// Fixed-point text of a positive number for a TetGen switch (its parser takes no exponent).
std::string SwitchNumber(double x) {
  // 15 significant digits, in fixed notation.
  const int decimals = std::clamp(14 - static_cast<int>(std::floor(std::log10(x))), 0, 60);
  char buffer[128];
  std::snprintf(buffer, sizeof(buffer), "%.*f", decimals, x);
  std::string s = buffer;
  while (!s.empty() && s.back() == '0') s.pop_back();
  if (!s.empty() && s.back() == '.') s.pop_back();
  return s;
}

// Winding number of the closed, outward-oriented surface at p: 1 inside, 0 outside (the sum of
// the triangles' signed solid angles over 4 pi; Van Oosterom and Strackee).
double WindingNumber(const TriangleMesh& m, const Eigen::Vector3d& p) {
  double sum = 0.0;
  for (Eigen::Index f = 0; f < m.triangles.cols(); ++f) {
    const Eigen::Vector3d a = m.vertices.col(m.triangles(0, f)) - p;
    const Eigen::Vector3d b = m.vertices.col(m.triangles(1, f)) - p;
    const Eigen::Vector3d c = m.vertices.col(m.triangles(2, f)) - p;
    const double la = a.norm(), lb = b.norm(), lc = c.norm();
    sum += 2.0 * std::atan2(a.dot(b.cross(c)),
                            la * lb * lc + a.dot(b) * lc + b.dot(c) * la + c.dot(a) * lb);
  }
  return sum / (4.0 * 3.14159265358979323846);
}

// TetGen (given no hole points) fills every region the facets enclose, the cavities of a
// hollow solid included. Drops the tets of each region whose winding number (at one of its
// tets' centroid) says it lies outside the solid, and the Steiner nodes only they used; the
// surface's vertices (the first surface_vertices nodes) stay, in order.
void DropCavities(const TriangleMesh& surface, TetMesh* mesh) {
  const Eigen::Index nt = mesh->tets.cols();
  std::unordered_map<int, bool> inside;
  for (Eigen::Index t = 0; t < nt; ++t) {
    const int region = mesh->regions[t];
    if (inside.count(region)) continue;
    Eigen::Vector3d centroid = Eigen::Vector3d::Zero();
    for (int k = 0; k < 4; ++k) centroid += mesh->nodes.col(mesh->tets(k, t)) / 4.0;
    inside[region] = WindingNumber(surface, centroid) > 0.5;
  }
  if (inside.size() < 2) return;  // one region: the solid itself
  std::vector<Eigen::Index> kept;
  for (Eigen::Index t = 0; t < nt; ++t)
    if (inside.at(mesh->regions[t])) kept.push_back(t);
  if (static_cast<Eigen::Index>(kept.size()) == nt) return;
  const Eigen::Index nv = mesh->nodes.cols(), ns = surface.vertices.cols();
  std::vector<int> index(nv, -1);
  for (Eigen::Index i = 0; i < std::min(ns, nv); ++i) index[i] = 0;
  for (Eigen::Index t : kept)
    for (int k = 0; k < 4; ++k) index[mesh->tets(k, t)] = 0;
  int count = 0;
  for (Eigen::Index i = 0; i < nv; ++i)
    if (index[i] == 0) index[i] = count++;
  TetMesh out;
  out.nodes.resize(3, count);
  for (Eigen::Index i = 0; i < nv; ++i)
    if (index[i] >= 0) out.nodes.col(index[i]) = mesh->nodes.col(i);
  out.tets.resize(4, static_cast<Eigen::Index>(kept.size()));
  out.regions.resize(static_cast<Eigen::Index>(kept.size()));
  for (size_t j = 0; j < kept.size(); ++j) {
    for (int k = 0; k < 4; ++k) out.tets(k, j) = index[mesh->tets(k, kept[j])];
    out.regions[j] = mesh->regions[kept[j]];
  }
  *mesh = std::move(out);
}

// A value in [−1, 1) from the bits of a vertex's coordinate and the axis (splitmix64).
double HashUnit(double coordinate_x, double coordinate_y, double coordinate_z, int axis) {
  std::uint64_t h = 0x9e3779b97f4a7c15ull * static_cast<std::uint64_t>(axis + 1);
  for (double c : {coordinate_x, coordinate_y, coordinate_z}) {
    c += 0.0;  // −0 and +0 alike
    std::uint64_t bits = 0;
    std::memcpy(&bits, &c, sizeof bits);
    h ^= bits + 0x9e3779b97f4a7c15ull + (h << 6) + (h >> 2);
    h ^= h >> 30;
    h *= 0xbf58476d1ce4e5b9ull;
    h ^= h >> 27;
    h *= 0x94d049bb133111ebull;
    h ^= h >> 31;
  }
  return static_cast<double>(h >> 11) * 0x1.0p-52 - 1.0;
}

}  // namespace

TriangleMesh RepairSurface(const TriangleMesh& surface, double tolerance, long* welded,
                           long* dropped) {
  const Eigen::Index nv = surface.vertices.cols(), nf = surface.triangles.cols();
  for (Eigen::Index f = 0; f < nf; ++f)
    for (int k = 0; k < 3; ++k)
      if (surface.triangles(k, f) < 0 || surface.triangles(k, f) >= nv)
        throw SurfaceDefectError("triangle " + TriangleText(surface, f) +
                                 " has a vertex index outside [0, " + std::to_string(nv) + ")");
  Eigen::AlignedBox3d box;
  for (Eigen::Index i = 0; i < nv; ++i) box.extend(Eigen::Vector3d(surface.vertices.col(i)));
  const double eps = nv ? tolerance * box.diagonal().norm() : 0.0;
  // Hash vertices on a grid of cell 2 eps (at least the smallest positive double); compare each
  // with the vertices of its cell and the neighbours.
  std::vector<int> target(nv);
  for (Eigen::Index i = 0; i < nv; ++i) target[i] = static_cast<int>(i);
  long n_welded = 0;
  if (eps > 0 || tolerance == 0) {
    const double h = std::max(2 * eps, 1e-300);
    using Key = Eigen::Matrix<int64_t, 3, 1>;
    struct KeyHash {
      size_t operator()(const Key& k) const {
        return (size_t(k[0]) * 73856093u) ^ (size_t(k[1]) * 19349663u) ^ (size_t(k[2]) * 83492791u);
      }
    };
    struct KeyEq {
      bool operator()(const Key& a, const Key& b) const { return a == b; }
    };
    std::unordered_map<Key, std::vector<int>, KeyHash, KeyEq> cells;
    for (Eigen::Index i = 0; i < nv; ++i) {
      const Eigen::Vector3d p = surface.vertices.col(i);
      const Key c = ((p - box.min()) / h).array().floor().cast<int64_t>();
      int found = -1;
      for (int dz = -1; dz <= 1 && found < 0; ++dz)
        for (int dy = -1; dy <= 1 && found < 0; ++dy)
          for (int dx = -1; dx <= 1 && found < 0; ++dx) {
            const auto it = cells.find(c + Key(dx, dy, dz));
            if (it == cells.end()) continue;
            for (int j : it->second)
              if ((surface.vertices.col(j) - p).norm() <= eps) {
                found = j;
                break;
              }
          }
      if (found >= 0) {
        target[i] = found;
        ++n_welded;
      } else {
        cells[c].push_back(static_cast<int>(i));
      }
    }
  }
  // Keep the triangles with three distinct corners, renumber the used vertices in order.
  std::vector<int> new_index(nv, -1);
  std::vector<Eigen::Vector3i> kept;
  kept.reserve(nf);
  for (Eigen::Index f = 0; f < nf; ++f) {
    const Eigen::Vector3i t(target[surface.triangles(0, f)], target[surface.triangles(1, f)],
                            target[surface.triangles(2, f)]);
    if (t[0] != t[1] && t[1] != t[2] && t[0] != t[2]) kept.push_back(t);
  }
  for (const auto& t : kept)
    for (int k = 0; k < 3; ++k) new_index[t[k]] = 0;
  int count = 0;
  for (Eigen::Index i = 0; i < nv; ++i)
    if (new_index[i] == 0) new_index[i] = count++;
  TriangleMesh out;
  out.vertices.resize(3, count);
  for (Eigen::Index i = 0; i < nv; ++i)
    if (new_index[i] >= 0) out.vertices.col(new_index[i]) = surface.vertices.col(i);
  out.triangles.resize(3, static_cast<Eigen::Index>(kept.size()));
  for (size_t f = 0; f < kept.size(); ++f)
    for (int k = 0; k < 3; ++k) out.triangles(k, f) = new_index[kept[f][k]];
  if (welded) *welded = n_welded;
  if (dropped) *dropped = static_cast<long>(nf - kept.size());
  return out;
}

void CheckSurface(const TriangleMesh& m) {
  const Eigen::Index nv = m.vertices.cols(), nf = m.triangles.cols();
  if (nf < 4)
    throw SurfaceDefectError("surface has " + std::to_string(nf) +
                             " triangles: a closed surface needs at least 4");
  if (!m.vertices.allFinite())
    throw SurfaceDefectError("surface has a non-finite vertex coordinate");
  for (Eigen::Index f = 0; f < nf; ++f) {
    for (int k = 0; k < 3; ++k) {
      if (m.triangles(k, f) < 0 || m.triangles(k, f) >= nv) {
        throw SurfaceDefectError("triangle " + TriangleText(m, f) +
                                 " has a vertex index outside [0, " + std::to_string(nv) + ")");
      }
    }
    const int a = m.triangles(0, f), b = m.triangles(1, f), c = m.triangles(2, f);
    if (a == b || b == c || a == c)
      throw SurfaceDefectError("triangle " + TriangleText(m, f) + " repeats a vertex");
    const Eigen::Vector3d pa = m.vertices.col(a), pb = m.vertices.col(b), pc = m.vertices.col(c);
    const double longest = std::max({(pb - pa).norm(), (pc - pb).norm(), (pa - pc).norm()});
    if ((pb - pa).cross(pc - pa).norm() <= 1e-14 * longest * longest) {
      throw SurfaceDefectError("triangle " + TriangleText(m, f) + " is degenerate (zero area)");
    }
  }
  // Directed edges: each must occur once, and its reverse once.
  std::unordered_map<uint64_t, Eigen::Index> edges;
  edges.reserve(3 * nf);
  auto key = [](int a, int b) {
    return (static_cast<uint64_t>(static_cast<uint32_t>(a)) << 32) | static_cast<uint32_t>(b);
  };
  for (Eigen::Index f = 0; f < nf; ++f) {
    for (int k = 0; k < 3; ++k) {
      const int a = m.triangles(k, f), b = m.triangles((k + 1) % 3, f);
      const auto [it, inserted] = edges.emplace(key(a, b), f);
      if (!inserted) {
        throw SurfaceDefectError("edge (" + std::to_string(a) + ", " + std::to_string(b) +
                                 ") is traversed the same way by triangles " +
                                 TriangleText(m, it->second) + " and " + TriangleText(m, f) +
                                 ": the surface is non-manifold or inconsistently oriented");
      }
    }
  }
  for (const auto& [k, f] : edges) {
    const int a = static_cast<int>(k >> 32), b = static_cast<int>(k & 0xffffffffu);
    if (!edges.count(key(b, a))) {
      throw SurfaceDefectError(
          "edge (" + std::to_string(a) + ", " + std::to_string(b) + ") of triangle " +
          TriangleText(m, f) +
          " has no neighbour across it: the surface is open (or inconsistently oriented)");
    }
  }
  const double volume = MeshVolume(m);
  if (!(volume > 0)) {
    throw SurfaceDefectError("surface encloses volume " + std::to_string(volume) +
                             " m^3 <= 0: triangles must be counter-clockwise seen from outside");
  }
  CheckSelfIntersections(m);
}

TetMesh TetrahedralizeSurface(const TriangleMesh& input, const TetMeshSettings& settings,
                              TetMeshStats* stats) {
  if (!(settings.max_radius_edge == 0.0 ||
        (settings.max_radius_edge > 1.0 && std::isfinite(settings.max_radius_edge)))) {
    throw std::invalid_argument(
        "TetMeshSettings::max_radius_edge = " + std::to_string(settings.max_radius_edge) +
        ": must be 0 (off) or > 1");
  }
  if (!(settings.min_dihedral_deg >= 0.0 && settings.min_dihedral_deg < 30.0)) {
    throw std::invalid_argument("TetMeshSettings::min_dihedral_deg = " +
                                std::to_string(settings.min_dihedral_deg) + ": must be in [0, 30)");
  }
  if (!(settings.max_volume >= 0.0 && std::isfinite(settings.max_volume))) {
    throw std::invalid_argument(
        "TetMeshSettings::max_volume = " + std::to_string(settings.max_volume) + ": must be >= 0");
  }
  // Without tetgen_terminate.cc linked, a TetGen failure would exit the process.
  SPIDARCAD_CHECK_MSG(internal::TetgenTerminateAnchor() == 1, "tetgen_terminate.cc is not linked");
  auto cancelled = [&] { return settings.cancel && settings.cancel->load(); };
  auto progress = [&](double x) {
    if (settings.progress) settings.progress(x);
  };
  if (!std::isfinite(settings.weld_tolerance))
    throw std::invalid_argument("TetMeshSettings::weld_tolerance is not finite");
  TetMeshStats local_stats;
  TetMeshStats& st = stats ? *stats : local_stats;
  st = TetMeshStats{};
  progress(0.0);
  if (cancelled()) throw TetMeshingCancelled();
  auto t0 = Clock::now();
  TriangleMesh repaired_storage;
  if (settings.weld_tolerance >= 0) {
    repaired_storage =
        RepairSurface(input, settings.weld_tolerance, &st.welded_vertices, &st.dropped_triangles);
  }
  const TriangleMesh& surface = settings.weld_tolerance >= 0 ? repaired_storage : input;
  if (settings.check_surface) {
    CheckSurface(surface);
  } else {
    // Even unchecked, an index out of range would make TetGen read out of bounds.
    for (Eigen::Index f = 0; f < surface.triangles.cols(); ++f)
      for (int k = 0; k < 3; ++k)
        if (surface.triangles(k, f) < 0 || surface.triangles(k, f) >= surface.vertices.cols())
          throw SurfaceDefectError("triangle " + TriangleText(surface, f) +
                                   " has a vertex index outside [0, " +
                                   std::to_string(surface.vertices.cols()) + ")");
  }
  st.check_seconds = Seconds(t0);
  progress(0.2);
  if (cancelled()) throw TetMeshingCancelled();

  std::string switches = "pzA";
  if (settings.max_radius_edge > 0) {
    switches += "q" + SwitchNumber(settings.max_radius_edge);
    if (settings.min_dihedral_deg > 0) switches += "/" + SwitchNumber(settings.min_dihedral_deg);
  }
  if (settings.max_volume > 0) switches += "a" + SwitchNumber(settings.max_volume);
  if (settings.preserve_surface) switches += "Y";
  if (settings.keep_facets) switches += "M";
  switches += settings.extra_switches;
  switches += settings.quiet ? "Q" : "V";
  st.switches = switches;

  tetgenio in, out;
  in.firstnumber = 0;
  in.numberofpoints = static_cast<int>(surface.vertices.cols());
  in.pointlist = new REAL[3 * in.numberofpoints];
  std::copy(surface.vertices.data(), surface.vertices.data() + 3 * in.numberofpoints, in.pointlist);
  in.numberoffacets = static_cast<int>(surface.triangles.cols());
  in.facetlist = new tetgenio::facet[in.numberoffacets];
  for (int f = 0; f < in.numberoffacets; ++f) {
    tetgenio::facet& facet = in.facetlist[f];
    tetgenio::init(&facet);
    facet.numberofpolygons = 1;
    facet.polygonlist = new tetgenio::polygon[1];
    tetgenio::init(&facet.polygonlist[0]);
    facet.polygonlist[0].numberofvertices = 3;
    facet.polygonlist[0].vertexlist = new int[3];
    for (int k = 0; k < 3; ++k) facet.polygonlist[0].vertexlist[k] = surface.triangles(k, f);
  }
  t0 = Clock::now();
  auto run = [&switches](tetgenio* from, tetgenio* to) {
    try {
      std::vector<char> command(switches.begin(), switches.end());
      command.push_back('\0');
      const TetgenDraws draws;
      tetrahedralize(command.data(), from, to);
    } catch (const TetgenError&) {
      throw;
    } catch (int code) {
      throw TetgenError(code, "TetGen failed with code " + std::to_string(code));
    } catch (const std::bad_alloc&) {
      throw TetgenError(1, "TetGen failed: out of memory");
    }
  };
  const int n_in = in.numberofpoints;
  const bool perturb = settings.perturb_from_triangles > 0 &&
                       surface.triangles.cols() >= settings.perturb_from_triangles &&
                       settings.preserve_surface && settings.keep_facets && n_in > 0;
  if (perturb) {
    // Each vertex moved by up to perturb_amplitude of the box diagonal along each axis.
    const double amplitude =
        settings.perturb_amplitude *
        (surface.vertices.rowwise().maxCoeff() - surface.vertices.rowwise().minCoeff()).norm();
    for (int v = 0; v < n_in; ++v) {
      const double* exact = surface.vertices.col(v).data();
      for (int k = 0; k < 3; ++k)
        in.pointlist[3 * v + k] += amplitude * HashUnit(exact[0], exact[1], exact[2], k);
    }
  }
  bool moved_failed = false;
  try {
    run(&in, &out);
  } catch (const TetgenError&) {
    if (!perturb) throw;
    moved_failed = true;  // the moved surface may touch itself where the exact one does not
  }
  if (perturb) {
    // The exact positions back, where TetGen kept the input points first and in order (its
    // output does without `J`); every tet must keep its orientation by the robust predicate,
    // and none may become flat. Otherwise TetGen runs again on the exact positions.
    st.perturbed = !moved_failed && out.pointlist != nullptr && out.tetrahedronlist != nullptr &&
                   out.numberofcorners == 4 && out.numberofpoints >= n_in &&
                   std::equal(in.pointlist, in.pointlist + 3 * n_in, out.pointlist);
    if (st.perturbed) {
      std::vector<double> moved(out.pointlist, out.pointlist + 3 * out.numberofpoints);
      std::copy(surface.vertices.data(), surface.vertices.data() + 3 * n_in, out.pointlist);
      const int* tets = out.tetrahedronlist;
      for (int t = 0; t < out.numberoftetrahedra && st.perturbed; ++t) {
        const int* q = tets + 4 * t;
        if (*std::min_element(q, q + 4) < 0 || *std::max_element(q, q + 4) >= out.numberofpoints)
          break;  // refused below
        const double before =
            orient3d(&moved[3 * q[0]], &moved[3 * q[1]], &moved[3 * q[2]], &moved[3 * q[3]]);
        const double after = orient3d(out.pointlist + 3 * q[0], out.pointlist + 3 * q[1],
                                      out.pointlist + 3 * q[2], out.pointlist + 3 * q[3]);
        if (!((before > 0.0 && after > 0.0) || (before < 0.0 && after < 0.0))) st.perturbed = false;
      }
    }
    if (!st.perturbed) {
      if (cancelled()) throw TetMeshingCancelled();
      std::copy(surface.vertices.data(), surface.vertices.data() + 3 * n_in, in.pointlist);
      out.deinitialize();
      out.initialize();
      run(&in, &out);
    }
  }
  st.tetgen_seconds = Seconds(t0);
  progress(0.9);

  const int nv = out.numberofpoints, nt = out.numberoftetrahedra;
  if (nt <= 0 || nv < 4 || out.tetrahedronlist == nullptr || out.pointlist == nullptr) {
    throw TetgenError(0, "TetGen returned " + std::to_string(nt) + " tetrahedra and " +
                             std::to_string(nv) + " points for a surface of " +
                             std::to_string(surface.triangles.cols()) + " triangles");
  }
  if (out.numberofcorners != 4)
    throw TetgenError(
        0, "TetGen returned " + std::to_string(out.numberofcorners) + "-node tetrahedra");
  TetMesh mesh;
  mesh.nodes.resize(3, nv);
  std::copy(out.pointlist, out.pointlist + 3 * nv, mesh.nodes.data());
  mesh.tets.resize(4, nt);
  mesh.regions.setZero(nt);
  for (int t = 0; t < nt; ++t) {
    for (int k = 0; k < 4; ++k) {
      const int i = out.tetrahedronlist[4 * t + k];
      if (i < 0 || i >= nv)
        throw TetgenError(0, "TetGen returned tet " + std::to_string(t) + " with node index " +
                                 std::to_string(i));
      mesh.tets(k, t) = i;
    }
    if (out.numberoftetrahedronattributes > 0 && out.tetrahedronattributelist) {
      mesh.regions[t] = static_cast<int>(
          std::lround(out.tetrahedronattributelist[t * out.numberoftetrahedronattributes]));
    }
    if (TetVolume(mesh, t) < 0) std::swap(mesh.tets(2, t), mesh.tets(3, t));
  }
  DropCavities(surface, &mesh);
  st.quality = MeasureTetQuality(mesh);
  if (!(st.quality.min_volume > 0)) {
    throw TetgenError(0, "TetGen returned a tetrahedron of volume " +
                             std::to_string(st.quality.min_volume) + " m^3");
  }
  progress(1.0);
  return mesh;
}

bool TetgenRunsConcurrently() {
  // libtet's PLT calls bind to the first definition in the global lookup order: it must be the
  // one in this object (the executable), not libtet's own (RTLD_NEXT from here).
  Dl_info own{};
  if (dladdr(reinterpret_cast<void*>(&TetgenRunsConcurrently), &own) == 0) return false;
  for (const char* symbol :
       {"_Z9exactinitiiiddd", "_ZN10tetgenmesh10inittablesEv", "rand", "srand"}) {
    void* first = dlsym(RTLD_DEFAULT, symbol);
    Dl_info found{};
    if (first == nullptr || first == dlsym(RTLD_NEXT, symbol) || dladdr(first, &found) == 0 ||
        found.dli_fbase != own.dli_fbase)
      return false;
  }
  return true;
}

}  // namespace spidarcad::modeling
