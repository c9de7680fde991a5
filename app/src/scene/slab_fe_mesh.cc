// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#include "scene/slab_fe_mesh.h"

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <exception>
#include <optional>
#include <stdexcept>
#include <string>
#include <thread>
#include <utility>

#include "scene/vtu_io.h"
#include "spidarcad/base/every_core.h"
#include "spidarcad/fem/cache_file.h"
#include "spidarcad/fem/precompute_cache.h"
#include "spidarcad/fem/substructure.h"
#include "spidarcad/modeling/feature_sharpening.h"
#include "spidarcad/modeling/surface_mesher.h"
#include "spidarcad/modeling/tetgen_mesher.h"

namespace spidarcad::app {
namespace {

using Clock = std::chrono::steady_clock;

double Seconds(Clock::time_point t0) {
  return std::chrono::duration<double>(Clock::now() - t0).count();
}

bool SameSurface(const modeling::TriangleMesh& a, const modeling::TriangleMesh& b) {
  return a.vertices.cols() == b.vertices.cols() && a.triangles.cols() == b.triangles.cols() &&
         (a.vertices.array() == b.vertices.array()).all() &&
         (a.triangles.array() == b.triangles.array()).all();
}

// Slab files: magic and format version (bump it when TetrahedralizeSlab's switches change, so
// that files of the old meshes are not taken for the new). 2: surfaces of 8,000 triangles or more
// meshed on moved vertices (modeling::kSlabPerturbFromTriangles, 2026-12-07).
constexpr char kSlabFileMagic[8] = {'S', 'P', 'D', 'S', 'L', 'A', 'B', '1'};
constexpr std::uint32_t kSlabFileVersion = 2;

std::uint64_t SlabKey(const modeling::TriangleMesh& surface, double max_radius_edge) {
  std::uint64_t h = modeling::SurfaceHash(surface);
  h = fem::Fnv1a64(&kSlabFileVersion, sizeof(kSlabFileVersion), h);
  return fem::Fnv1a64(&max_radius_edge, sizeof(max_radius_edge), h);
}

template <class Matrix>
void PutMatrix(fem::ByteWriter* w, const Matrix& m) {
  w->Put(static_cast<std::int64_t>(m.cols()));
  w->PutArray(m.data(), static_cast<std::size_t>(m.size()));
}

// A matrix of fixed row count (3 or 4) written by PutMatrix.
template <class Matrix>
bool GetMatrix(fem::ByteReader* r, Matrix* m) {
  std::int64_t cols = 0;
  if (!r->Get(&cols) || cols < 0 ||
      static_cast<std::uint64_t>(cols) > r->remaining() / (sizeof(typename Matrix::Scalar) * 3))
    return false;
  m->resize(Matrix::RowsAtCompileTime, cols);
  return r->GetArray(m->data(), static_cast<std::size_t>(m->size()));
}

std::vector<unsigned char> SerializeSlab(std::uint64_t key, double max_radius_edge,
                                         const modeling::TriangleMesh& surface,
                                         const modeling::TetMesh& tets) {
  fem::ByteWriter w;
  w.Put(kSlabFileVersion);
  w.Put(key);
  w.Put(max_radius_edge);
  PutMatrix(&w, surface.vertices);
  PutMatrix(&w, surface.triangles);
  PutMatrix(&w, tets.nodes);
  PutMatrix(&w, tets.tets);
  w.Put(static_cast<std::int64_t>(tets.regions.size()));
  w.PutArray(tets.regions.data(), static_cast<std::size_t>(tets.regions.size()));
  return std::move(w.bytes());
}

// The tets of `surface` from a slab file body, or nothing with the reason.
std::optional<modeling::TetMesh> DeserializeSlab(const fem::MappedCacheFile& body,
                                                 std::uint64_t key, double max_radius_edge,
                                                 const modeling::TriangleMesh& surface,
                                                 std::string* why) {
  fem::ByteReader r(body.data(), body.size());
  auto fail = [&](const std::string& reason) -> std::optional<modeling::TetMesh> {
    *why = reason;
    return std::nullopt;
  };
  std::uint32_t version = 0;
  std::uint64_t file_key = 0;
  double bound = 0.0;
  if (!r.Get(&version) || version != kSlabFileVersion)
    return fail("format version " + std::to_string(version) + ", expected " +
                std::to_string(kSlabFileVersion));
  if (!r.Get(&file_key) || file_key != key)
    return fail("holds key " + fem::HexKey(file_key) + ", expected " + fem::HexKey(key));
  modeling::TriangleMesh stored;
  modeling::TetMesh tets;
  std::int64_t num_regions = 0;
  if (!r.Get(&bound) || !GetMatrix(&r, &stored.vertices) || !GetMatrix(&r, &stored.triangles) ||
      !GetMatrix(&r, &tets.nodes) || !GetMatrix(&r, &tets.tets) || !r.Get(&num_regions) ||
      num_regions != tets.tets.cols())
    return fail("truncated or inconsistent");
  tets.regions.resize(num_regions);
  if (!r.GetArray(tets.regions.data(), static_cast<std::size_t>(num_regions)) || r.remaining() != 0)
    return fail("truncated or inconsistent");
  if (bound != max_radius_edge || !SameSurface(stored, surface))
    return fail("its slab differs (a hash collision)");
  if (tets.tets.size() > 0 &&
      (tets.tets.minCoeff() < 0 || tets.tets.maxCoeff() >= tets.nodes.cols()))
    return fail("a tet names a node it does not have");
  if (!tets.nodes.allFinite()) return fail("non-finite node positions");
  return tets;
}

// The plane across `axis` nearest below x that holds no grid vertex: half-way between two grid
// planes, or with the lattice a quarter of a cell past one (its vertices lie on the grid planes
// and half-way between them). MeshSurface centres its grid on the bounds (at their low corner
// when they span whole cells, as the callers' grids do).
double PlaneOffTheGrid(const Eigen::AlignedBox3d& grid_bounds, double cell, bool lattice, int axis,
                       double x) {
  const double lo = grid_bounds.min()[axis], hi = grid_bounds.max()[axis];
  const double n = std::max(1.0, std::ceil((hi - lo) / cell - 1e-9));
  const double origin = lattice ? 0.5 * (lo + hi) - 0.5 * cell * n : lo;
  return origin + cell * (std::floor((x - origin) / cell) + (lattice ? 0.25 : 0.5));
}

// The slab of each piece, in the cut's order of pieces (a slab's strips in order; SlabFeMesh::
// piece_slab): empty without strips.
std::vector<int> PieceSlabs(const std::vector<std::vector<double>>& strip_planes) {
  std::vector<int> slab;
  for (std::size_t k = 0; k < strip_planes.size(); ++k)
    slab.insert(slab.end(), strip_planes[k].size() + 1, static_cast<int>(k));
  return slab;
}

// SlabMeshOptions::strips: the strips of the slabs (across x at `planes`) that hold more than
// kStripSlabShare times the mean of the surface's triangles per slab (by centroid), and at least
// options.strip_min_triangles of them, across the
// longer of the box's y and z extents, the slab's part of the surface spanned evenly.
void ChooseStrips(const modeling::TriangleMesh& surface, const Eigen::AlignedBox3d& box,
                  double cell, const std::vector<double>& planes, const SlabMeshOptions& options,
                  int* strip_axis, std::vector<std::vector<double>>* strip_planes) {
  const int n = static_cast<int>(planes.size()) + 1;
  const Eigen::Vector3d extent = box.sizes();
  const int a = extent.y() >= extent.z() ? 1 : 2;
  *strip_axis = a;
  std::vector<long> count(n, 0);
  std::vector<double> lo(n, 1e300), hi(n, -1e300);  // the slab's part across the strip axis
  // Each triangle's slab (by centroid, as the cut assigns it) and its extent across the axis.
  const Eigen::Index nt = surface.triangles.cols();
  std::vector<int> slab_of(nt);
  std::vector<double> below(nt), above(nt);
  for (Eigen::Index t = 0; t < nt; ++t) {
    double x = 0.0;
    below[t] = 1e300;
    above[t] = -1e300;
    for (int j = 0; j < 3; ++j) {
      const auto q = surface.vertices.col(surface.triangles(j, t));
      x += q.x() / 3.0;
      below[t] = std::min(below[t], q[a]);
      above[t] = std::max(above[t], q[a]);
    }
    const int k =
        static_cast<int>(std::lower_bound(planes.begin(), planes.end(), x) - planes.begin());
    slab_of[t] = k;
    ++count[k];
    lo[k] = std::min(lo[k], below[t]);
    hi[k] = std::max(hi[k], above[t]);
  }
  const double mean = static_cast<double>(surface.triangles.cols()) / n;
  strip_planes->assign(n, {});
  bool any = false;
  for (int k = 0; k < n; ++k) {
    if (static_cast<double>(count[k]) <= kStripSlabShare * mean ||
        count[k] < options.strip_min_triangles)
      continue;
    std::vector<double>& p = (*strip_planes)[k];
    for (int j = 1; j < options.strips; ++j) {
      const double c = PlaneOffTheGrid(box, cell, options.lattice, a,
                                       lo[k] + (hi[k] - lo[k]) * j / options.strips);
      if (!(c > lo[k] && c < hi[k] && (p.empty() || c > p.back()))) continue;
      // The plane must cross one of the slab's triangles (not only a gap between them).
      bool crosses = false;
      for (Eigen::Index t = 0; t < nt && !crosses; ++t)
        crosses = slab_of[t] == k && below[t] < c && above[t] > c;
      if (crosses) p.push_back(c);
    }
    any = any || !p.empty();
  }
  if (!any) strip_planes->clear();
}

}  // namespace

Eigen::VectorXi SlabPieceLabels(const fem::TetMesh& mesh, const std::vector<double>& planes,
                                int strip_axis,
                                const std::vector<std::vector<double>>& strip_planes,
                                std::vector<int>* piece_slab) {
  Eigen::VectorXi slab = fem::SlabBlocks(mesh, 0, planes);
  if (!strip_planes.empty() &&
      (strip_planes.size() != planes.size() + 1 || strip_axis < 1 || strip_axis > 2))
    throw std::invalid_argument("slab pieces: " + std::to_string(strip_planes.size()) +
                                " strip lists for " + std::to_string(planes.size() + 1) +
                                " slabs, or a strip axis other than y or z");
  *piece_slab = PieceSlabs(strip_planes);
  if (strip_planes.empty()) return slab;
  std::vector<int> first(strip_planes.size() + 1, 0);  // each slab's first piece
  for (std::size_t k = 0; k < strip_planes.size(); ++k)
    first[k + 1] = first[k] + static_cast<int>(strip_planes[k].size()) + 1;
  Eigen::VectorXi piece(mesh.num_elements());
  for (int e = 0; e < mesh.num_elements(); ++e) {
    double c = 0.0;
    for (int j = 0; j < 4; ++j) c += 0.25 * mesh.nodes(mesh.elements(e, j), strip_axis);
    const std::vector<double>& p = strip_planes[slab(e)];
    piece(e) =
        first[slab(e)] + static_cast<int>(std::upper_bound(p.begin(), p.end(), c) - p.begin());
  }
  return piece;
}

int SlabFeMesh::num_remeshed() const {
  return static_cast<int>(std::count(remeshed.begin(), remeshed.end(), 1));
}

std::vector<double> SlabPlanes(const Eigen::AlignedBox3d& grid_bounds, double cell, int slabs,
                               const SlabMeshOptions& options, int axis) {
  if (axis < 0 || axis > 2)
    throw std::invalid_argument("SlabPlanes: axis must be 0, 1 or 2, got " + std::to_string(axis));
  std::vector<double> planes;
  const double lo = grid_bounds.min()[axis], hi = grid_bounds.max()[axis];
  for (int k = 1; k < slabs; ++k) {
    const double p =
        PlaneOffTheGrid(grid_bounds, cell, options.lattice, axis, lo + (hi - lo) * k / slabs);
    if (planes.empty() || p > planes.back()) planes.push_back(p);
  }
  return planes;
}

// The cut's snap, in spacings: a vertex this near a plane is moved onto it (MeshSurfaceInSlabs),
// which SurfaceSlabPlanes keeps triangles out of.
constexpr double kSnapPerSpacing = 0.1;

std::vector<double> SurfaceSlabPlanes(const modeling::TriangleMesh& surface,
                                      const Eigen::AlignedBox3d& box, double spacing, int slabs) {
  std::vector<double> planes = SlabPlanes(box, spacing, slabs);
  const double snap = kSnapPerSpacing * spacing;  // MeshSurfaceInSlabs's cut
  // Planes c that would snap a triangle into themselves: c in [max x − snap, min x + snap] of a
  // triangle whose corners span at most 2 snap across x.
  std::vector<std::pair<double, double>> bad;
  for (Eigen::Index t = 0; t < surface.triangles.cols(); ++t) {
    double lo = surface.vertices(0, surface.triangles(0, t)), hi = lo;
    for (int k = 1; k < 3; ++k) {
      lo = std::min(lo, surface.vertices(0, surface.triangles(k, t)));
      hi = std::max(hi, surface.vertices(0, surface.triangles(k, t)));
    }
    if (hi - lo <= 2.0 * snap) bad.emplace_back(hi - snap, lo + snap);
  }
  auto clear = [&bad](double c) {
    return std::none_of(bad.begin(), bad.end(), [c](const std::pair<double, double>& r) {
      return c >= r.first && c <= r.second;
    });
  };
  for (double& c : planes) {
    for (int k : {0, 1, -1, 2, -2, 3, -3, 4, -4}) {
      if (clear(c + k * snap)) {
        c += k * snap;
        break;
      }
    }
  }
  return planes;
}

SlabFeMesh MeshSolidInSlabs(const modeling::CompiledSolid& solid,
                            const Eigen::AlignedBox3d& grid_bounds, double cell,
                            const std::vector<double>& planes, const SlabMeshOptions& options) {
  const auto t = Clock::now();
  modeling::SurfaceMeshSettings ss;
  ss.bounds = grid_bounds;
  ss.cell_size = cell;
  ss.snap_cells = options.snap_cells;
  ss.flat_coarsen_cells = options.flat_coarsen_cells;
  if (options.lattice) ss.mesher = modeling::SurfaceMesher::kLattice;
  ss.cancel = options.cancel;
  if (options.progress) ss.progress = [&options](double f) { options.progress(0.3 * f); };
  modeling::SharpSurface placed = modeling::MeshSurfaceKeepingVolume(solid, ss);
  const double surface_seconds = Seconds(t);
  Eigen::AlignedBox3d grid = grid_bounds;
  std::vector<double> moved_planes = planes;
  if (placed.grid_shift != 0.0) {
    grid = modeling::SharpGridPlacement(ss, placed.grid_shift).bounds;
    for (double& x : moved_planes) x += placed.grid_shift * cell;
  }
  SlabFeMesh out = MeshSurfaceInSlabs(placed.mesh, grid, cell, moved_planes, options);
  out.surface_seconds = surface_seconds;
  out.grid_placements = placed.placements;
  out.grid_shift_cells = placed.grid_shift;
  out.solid_volume = placed.solid_volume;
  return out;
}

// A grid surface's median edge is about 0.73 of its cell (the platform's snapped surface at
// 12.5 mm: 9.15 mm), so a sculpt made from a solid gets about the cell the solid's slabs use:
// sections no denser than the solid's (a plane's dense factor grows with the cube of its dofs).
constexpr double kSpacingPerMedianEdge = 1.4;

double SurfaceSlabSpacing(const modeling::TriangleMesh& surface) {
  const long n = surface.triangles.cols();
  if (n == 0) throw std::invalid_argument("slab spacing: the surface has no triangles");
  std::vector<double> lengths;
  lengths.reserve(static_cast<std::size_t>(3 * n));
  for (long t = 0; t < n; ++t) {
    for (int k = 0; k < 3; ++k) {
      const int a = surface.triangles(k, t), b = surface.triangles((k + 1) % 3, t);
      if (a < b) lengths.push_back((surface.vertices.col(a) - surface.vertices.col(b)).norm());
    }
  }
  if (lengths.empty()) throw std::invalid_argument("slab spacing: the surface has no edges");
  auto mid = lengths.begin() + static_cast<std::ptrdiff_t>(lengths.size() / 2);
  std::nth_element(lengths.begin(), mid, lengths.end());
  if (!(*mid > 0.0) || !std::isfinite(*mid))
    throw std::invalid_argument("slab spacing: the surface's median edge length is not positive");
  return kSpacingPerMedianEdge * *mid;
}

SlabFeMesh MeshSurfaceInSlabs(const modeling::TriangleMesh& surface, const Eigen::AlignedBox3d& box,
                              double spacing, const std::vector<double>& planes,
                              const SlabMeshOptions& options) {
  SlabFeMesh out;
  out.planes = planes;
  out.grid_bounds = box;
  out.cell = spacing;
  const double max_radius_edge = options.max_radius_edge;
  const std::filesystem::path& cache_directory = options.cache_directory;
  const SlabFeMesh* previous = options.previous;
  if (previous != nullptr && (previous->planes != planes || previous->cell != spacing ||
                              !previous->grid_bounds.isApprox(box, 0.0)))
    previous = nullptr;
  auto report = [&options](double f) {
    if (options.progress) options.progress(f);
  };

  if (previous != nullptr) {
    out.strip_axis = previous->strip_axis;
    out.strip_planes = previous->strip_planes;
  } else if (options.strips > 1) {
    ChooseStrips(surface, box, spacing, planes, options, &out.strip_axis, &out.strip_planes);
  }

  out.piece_slab = PieceSlabs(out.strip_planes);

  auto t = Clock::now();
  modeling::SlabCut cut;
  cut.axis = 0;
  cut.planes = planes;
  cut.strip_axis = out.strip_axis;
  cut.strip_planes = out.strip_planes;
  cut.snap = kSnapPerSpacing * spacing;
  cut.section_spacing = spacing;
  modeling::SlabSurfaces slabs = modeling::CutSurfaceIntoSlabs(surface, cut);
  out.cut_seconds = Seconds(t);

  modeling::TetMeshSettings ts;
  ts.max_radius_edge = max_radius_edge;
  ts.cancel = options.cancel;
  const std::size_t n = slabs.slabs.size();
  out.slab_surfaces = std::move(slabs.slabs);
  out.slab_tets.resize(n);
  out.remeshed.assign(n, 0);
  out.loaded.assign(n, 0);
  auto cancelled = [&options] {
    return options.cancel != nullptr && options.cancel->load(std::memory_order_relaxed);
  };
  // Each piece from the previous mesh (same surface), from the cache directory, or else from
  // TetGen (`todo`, in piece order).
  std::vector<std::size_t> todo;
  std::vector<std::uint64_t> keys(n, 0);
  auto file_of = [&](std::size_t k) {
    return cache_directory.empty() ? std::filesystem::path()
                                   : cache_directory / (fem::HexKey(keys[k]) + ".slab");
  };
  for (std::size_t k = 0; k < n; ++k) {
    if (cancelled()) throw modeling::TetMeshingCancelled();
    const modeling::TriangleMesh& s = out.slab_surfaces[k];
    if (previous != nullptr && k < previous->slab_surfaces.size() &&
        modeling::SurfaceHash(s) == modeling::SurfaceHash(previous->slab_surfaces[k]) &&
        SameSurface(s, previous->slab_surfaces[k])) {
      out.slab_tets[k] = previous->slab_tets[k];
      continue;
    }
    keys[k] = SlabKey(s, max_radius_edge);
    const std::filesystem::path file = file_of(k);
    if (!file.empty()) {
      t = Clock::now();
      std::string why;
      std::optional<modeling::TetMesh> tets;
      if (auto body = fem::MapCacheFile(file, kSlabFileMagic, &why)) {
        tets = DeserializeSlab(*body, keys[k], max_radius_edge, s, &why);
        if (!tets) why = file.string() + ": " + why;
      }
      out.cache_read_seconds += Seconds(t);
      if (tets) {
        out.slab_tets[k] = std::move(*tets);
        out.loaded[k] = 1;
        continue;
      }
      if (why != "absent")
        out.cache_notes.push_back("slab " + std::to_string(k) + ": refused " + why);
    }
    todo.push_back(k);
  }
  report(0.35 + 0.6 * static_cast<double>(n - todo.size()) / static_cast<double>(n));

  // TetGen on the pieces left, on as many threads as there are cores (this one among them) when
  // libtet's globals are written once (modeling::TetgenRunsConcurrently), else in turn. The first
  // failure in piece order is thrown once every thread has stopped; a failure or a cancel stops
  // the others from taking another piece.
  t = Clock::now();
  {
    std::vector<std::exception_ptr> errors(todo.size());
    std::atomic<std::size_t> next{0}, done{n - todo.size()};
    std::atomic<bool> stop{false};
    auto work = [&](bool reports) {
      for (std::size_t i; !stop.load() && (i = next.fetch_add(1)) < todo.size();) {
        try {
          if (cancelled()) throw modeling::TetMeshingCancelled();
          out.slab_tets[todo[i]] = modeling::TetrahedralizeSlab(out.slab_surfaces[todo[i]], ts);
        } catch (...) {
          errors[i] = std::current_exception();
          stop.store(true);
        }
        const std::size_t finished = done.fetch_add(1) + 1;
        if (reports) report(0.35 + 0.6 * static_cast<double>(finished) / static_cast<double>(n));
      }
    };
    if (modeling::TetgenRunsConcurrently()) {
      const std::thread::id caller = std::this_thread::get_id();
      base::RunOnEveryCore(todo.size(), [&] { work(std::this_thread::get_id() == caller); });
    } else {
      work(true);
    }
    for (const std::exception_ptr& error : errors)
      if (error) std::rethrow_exception(error);
  }
  out.tetgen_seconds += Seconds(t);
  for (const std::size_t k : todo) {
    out.remeshed[k] = 1;
    const std::filesystem::path file = file_of(k);
    if (file.empty()) continue;
    t = Clock::now();
    std::string error;
    if (!fem::WriteCacheFile(
            file, kSlabFileMagic,
            SerializeSlab(keys[k], max_radius_edge, out.slab_surfaces[k], out.slab_tets[k]),
            &error))
      out.cache_notes.push_back("slab " + std::to_string(k) + ": not saved: " + error);
    out.cache_write_seconds += Seconds(t);
  }

  t = Clock::now();
  modeling::SlabTetMesh joined = modeling::JoinSlabs(out.slab_tets);
  out.mesh = ToFemMesh(joined.mesh);
  out.mesh.regions.setZero(out.mesh.num_elements());
  joined.mesh.regions.setZero(out.mesh.num_elements());
  out.volume = std::make_shared<const modeling::TetMesh>(std::move(joined.mesh));
  out.slab = joined.slab;
  out.join_seconds = Seconds(t);
  report(1.0);
  return out;
}

}  // namespace spidarcad::app
