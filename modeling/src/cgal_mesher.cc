// CGAL Mesh_3 from the implicit function (see cgal_mesher.h). The only translation unit that
// includes CGAL: it instantiates Mesh_3 once (slow to compile, keep everything CGAL here).
// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#include "spidarcad/modeling/cgal_mesher.h"

#include <CGAL/Exact_predicates_inexact_constructions_kernel.h>
#include <CGAL/Labeled_mesh_domain_3.h>
#include <CGAL/Mesh_complex_3_in_triangulation_3.h>
#include <CGAL/Mesh_criteria_3.h>
#include <CGAL/Mesh_triangulation_3.h>
#include <CGAL/Random.h>
#include <CGAL/exude_mesh_3.h>
#include <CGAL/lloyd_optimize_mesh_3.h>
#include <CGAL/make_mesh_3.h>
#include <CGAL/odt_optimize_mesh_3.h>
#include <CGAL/perturb_mesh_3.h>

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <map>
#include <numeric>
#include <sstream>
#include <unordered_map>
#include <unordered_set>
#include <utility>
#include <vector>

namespace spidarcad::modeling {

namespace {

using Kernel = CGAL::Exact_predicates_inexact_constructions_kernel;
using Domain = CGAL::Labeled_mesh_domain_3<Kernel>;
using Triangulation = CGAL::Mesh_triangulation_3<Domain, CGAL::Default, CGAL::Sequential_tag>::type;
using C3t3 = CGAL::Mesh_complex_3_in_triangulation_3<Triangulation>;
using Criteria = CGAL::Mesh_criteria_3<Triangulation>;
using Mesher = CGAL::Mesh_3::Mesher_3<C3t3, Criteria, Domain>;
using Point = Kernel::Point_3;

using Clock = std::chrono::steady_clock;

double Since(Clock::time_point start) {
  return std::chrono::duration<double>(Clock::now() - start).count();
}

std::string Fmt(double v) {
  char buffer[64];
  std::snprintf(buffer, sizeof buffer, "%.6g", v);
  return buffer;
}

std::string FmtPoint(const Eigen::Vector3d& p) {
  return "(" + Fmt(p.x()) + ", " + Fmt(p.y()) + ", " + Fmt(p.z()) + ")";
}

std::string FmtBox(const Eigen::AlignedBox3d& b) {
  return FmtPoint(b.min()) + " .. " + FmtPoint(b.max());
}

void CheckSettings(const Eigen::AlignedBox3d& bounds, const CgalMeshSettings& s) {
  auto bad = [](const std::string& what) { throw CgalMeshError("CGAL mesher settings: " + what); };
  if (bounds.isEmpty() || !bounds.min().allFinite() || !bounds.max().allFinite() ||
      (bounds.sizes().array() <= 0.0).any()) {
    bad("bounds " + FmtBox(bounds) +
        " are empty or not finite; give the solid's box (e.g. FindBounds) padded by a facet_size");
  }
  if (!(s.facet_angle_deg > 0.0 && s.facet_angle_deg <= 30.0)) {
    bad("facet_angle_deg must be in (0, 30] (termination is guaranteed up to 30), got " +
        Fmt(s.facet_angle_deg));
  }
  if (!(s.facet_size > 0.0) || !std::isfinite(s.facet_size))
    bad("facet_size must be > 0 m, got " + Fmt(s.facet_size));
  if (!(s.facet_distance > 0.0) || !std::isfinite(s.facet_distance)) {
    bad("facet_distance must be > 0 m, got " + Fmt(s.facet_distance));
  }
  if (!(s.cell_radius_edge_ratio > 1.0) || !std::isfinite(s.cell_radius_edge_ratio)) {
    bad("cell_radius_edge_ratio must be > 1 (2 to 3 is usual), got " +
        Fmt(s.cell_radius_edge_ratio));
  }
  if (!(s.cell_size >= 0.0) || !std::isfinite(s.cell_size))
    bad("cell_size must be >= 0 m (0: unbounded), got " + Fmt(s.cell_size));
  if (!(s.optimizer_time_limit >= 0.0))
    bad("optimizer_time_limit must be >= 0 s, got " + Fmt(s.optimizer_time_limit));
  if (!(s.sliver_bound_deg >= 0.0 && s.sliver_bound_deg < 70.0)) {
    bad("sliver_bound_deg must be in [0, 70) degrees, got " + Fmt(s.sliver_bound_deg));
  }
  if (!(s.exude_time_limit >= 0.0))
    bad("exude_time_limit must be >= 0 s, got " + Fmt(s.exude_time_limit));
  if (s.smoothing_iterations < 1)
    bad("smoothing_iterations must be >= 1, got " + std::to_string(s.smoothing_iterations));
  if (s.max_vertices < 4) bad("max_vertices must be >= 4, got " + std::to_string(s.max_vertices));
  if (!(s.relative_error_bound > 0.0 && s.relative_error_bound < 0.1)) {
    bad("relative_error_bound must be in (0, 0.1), got " + Fmt(s.relative_error_bound));
  }
}

// Seeds: the field on a regular grid over the box (spacing ~facet_size, at most kMaxSeedCells
// cells per axis); every grid edge with a sign change is bisected onto the surface by the
// domain's own intersection construction (so the point carries the surface index CGAL
// expects). Points closer than one grid spacing to an accepted one are dropped (closer seeds
// only make short edges that refinement and perturbation then have to work around). Also checks
// that the solid is present in the box and does not reach its faces.
constexpr int kMaxSeedCells = 64;

std::vector<std::pair<Point, Domain::Index>> SeedPoints(const CompiledSolid& solid,
                                                        const Domain& domain,
                                                        const Eigen::AlignedBox3d& bounds,
                                                        const CgalMeshSettings& s) {
  const Eigen::Vector3d lo = bounds.min(), size = bounds.sizes();
  const double spacing = std::max(s.facet_size, size.maxCoeff() / kMaxSeedCells);
  Eigen::Vector3i n;
  for (int a = 0; a < 3; ++a)
    n[a] = std::clamp(static_cast<int>(std::ceil(size[a] / spacing)), 1, kMaxSeedCells);
  const Eigen::Vector3d step = size.cwiseQuotient(n.cast<double>());
  const Eigen::Vector3i m = n.array() + 1;
  auto node = [&](int i, int j, int k) -> Eigen::Vector3d {
    return lo + Eigen::Vector3d(i * step.x(), j * step.y(), k * step.z());
  };
  auto id = [&](int i, int j, int k) { return (static_cast<long>(k) * m.y() + j) * m.x() + i; };

  std::vector<double> values(static_cast<size_t>(m.prod()));
  long inside = 0;
  double min_value = std::numeric_limits<double>::infinity();
  Eigen::Vector3d min_at = lo;
  for (int k = 0; k < m.z(); ++k) {
    for (int j = 0; j < m.y(); ++j) {
      for (int i = 0; i < m.x(); ++i) {
        const Eigen::Vector3d p = node(i, j, k);
        const double v = solid.Value(p);
        values[id(i, j, k)] = v;
        if (v < 0.0) ++inside;
        if (v < min_value) min_value = v, min_at = p;
        const bool on_face = i == 0 || j == 0 || k == 0 || i == n.x() || j == n.y() || k == n.z();
        if (on_face && v < 0.0) {
          throw CgalMeshError("CGAL mesher: the solid reaches the face of the box " +
                              FmtBox(bounds) + " at " + FmtPoint(p) + " (value " + Fmt(v) +
                              " m): enlarge the bounds so that the solid lies strictly inside (pad "
                              "by a facet_size)");
        }
      }
    }
  }
  if (inside == 0) {
    throw CgalMeshError(
        "CGAL mesher: the solid is empty in the box " + FmtBox(bounds) +
        " (no grid point of spacing " + Fmt(spacing) + " m inside; smallest value " +
        Fmt(min_value) + " m at " + FmtPoint(min_at) +
        "): move or enlarge the bounds, or use a facet_size below the solid's thickness");
  }

  std::vector<std::pair<Point, Domain::Index>> seeds;
  const double cell = spacing;
  struct KeyHash {
    size_t operator()(const std::array<long, 3>& k) const {
      return static_cast<size_t>(k[0] * 73856093L ^ k[1] * 19349663L ^ k[2] * 83492791L);
    }
  };
  std::unordered_map<std::array<long, 3>, std::vector<Eigen::Vector3d>, KeyHash> accepted;
  auto key = [&](const Eigen::Vector3d& p) {
    const Eigen::Vector3d q = (p - lo) / cell;
    return std::array<long, 3>{static_cast<long>(std::floor(q.x())),
                               static_cast<long>(std::floor(q.y())),
                               static_cast<long>(std::floor(q.z()))};
  };
  auto far_enough = [&](const Eigen::Vector3d& p) {
    const auto k = key(p);
    for (long dz = -1; dz <= 1; ++dz) {
      for (long dy = -1; dy <= 1; ++dy) {
        for (long dx = -1; dx <= 1; ++dx) {
          const auto it = accepted.find({k[0] + dx, k[1] + dy, k[2] + dz});
          if (it == accepted.end()) continue;
          for (const Eigen::Vector3d& q : it->second) {
            if ((q - p).squaredNorm() < cell * cell) return false;
          }
        }
      }
    }
    return true;
  };
  const auto intersect = domain.construct_intersection_object();
  const std::array<Eigen::Vector3i, 3> axes = {Eigen::Vector3i(1, 0, 0), Eigen::Vector3i(0, 1, 0),
                                               Eigen::Vector3i(0, 0, 1)};
  for (int k = 0; k < m.z(); ++k) {
    for (int j = 0; j < m.y(); ++j) {
      for (int i = 0; i < m.x(); ++i) {
        const double v0 = values[id(i, j, k)];
        for (const Eigen::Vector3i& e : axes) {
          const int i1 = i + e.x(), j1 = j + e.y(), k1 = k + e.z();
          if (i1 >= m.x() || j1 >= m.y() || k1 >= m.z()) continue;
          const double v1 = values[id(i1, j1, k1)];
          if ((v0 < 0.0) == (v1 < 0.0)) continue;
          const Eigen::Vector3d a = node(i, j, k), b = node(i1, j1, k1);
          const auto hit =
              intersect(Kernel::Segment_3(Point(a.x(), a.y(), a.z()), Point(b.x(), b.y(), b.z())));
          if (std::get<2>(hit) == 0) continue;
          const Point& p = std::get<0>(hit);
          const Eigen::Vector3d q(p.x(), p.y(), p.z());
          if (!far_enough(q)) continue;
          accepted[key(q)].push_back(q);
          seeds.emplace_back(p, std::get<1>(hit));
        }
      }
    }
  }
  if (seeds.empty()) {
    throw CgalMeshError("CGAL mesher: no surface found in the box " + FmtBox(bounds) +
                        " on a grid of spacing " + Fmt(spacing) +
                        " m: the box lies wholly inside the solid? enlarge the bounds");
  }
  return seeds;
}

// Numbers the connected components of the tets (sharing a face) from 1.
Eigen::VectorXi ComponentRegions(const Eigen::Matrix4Xi& tets) {
  const Eigen::Index count = tets.cols();
  std::vector<int> parent(static_cast<size_t>(count));
  std::iota(parent.begin(), parent.end(), 0);
  auto find = [&](int x) {
    while (parent[x] != x) x = parent[x] = parent[parent[x]];
    return x;
  };
  std::map<std::array<int, 3>, int> first_tet;
  for (Eigen::Index t = 0; t < count; ++t) {
    for (int f = 0; f < 4; ++f) {
      std::array<int, 3> face;
      for (int c = 0, o = 0; c < 4; ++c) {
        if (c != f) face[o++] = tets(c, t);
      }
      std::sort(face.begin(), face.end());
      const auto [it, inserted] = first_tet.emplace(face, static_cast<int>(t));
      if (!inserted) parent[find(static_cast<int>(t))] = find(it->second);
    }
  }
  Eigen::VectorXi regions(count);
  std::map<int, int> number;
  for (Eigen::Index t = 0; t < count; ++t) {
    const auto [it, inserted] =
        number.emplace(find(static_cast<int>(t)), static_cast<int>(number.size()) + 1);
    regions[t] = it->second;
  }
  return regions;
}

// The C3t3's cells in the complex as a TetMesh, positively oriented.
TetMesh ToTetMesh(const C3t3& c3t3) {
  std::map<C3t3::Vertex_handle, int> index;
  std::vector<Eigen::Vector3d> nodes;
  std::vector<Eigen::Vector4i> tets;
  tets.reserve(c3t3.number_of_cells_in_complex());
  for (auto cell = c3t3.cells_in_complex_begin(); cell != c3t3.cells_in_complex_end(); ++cell) {
    Eigen::Vector4i tet;
    for (int c = 0; c < 4; ++c) {
      const C3t3::Vertex_handle v = cell->vertex(c);
      const auto [it, inserted] = index.emplace(v, static_cast<int>(nodes.size()));
      if (inserted) {
        const auto& p = v->point();
        nodes.emplace_back(CGAL::to_double(p.x()), CGAL::to_double(p.y()), CGAL::to_double(p.z()));
      }
      tet[c] = it->second;
    }
    tets.push_back(tet);
  }
  TetMesh mesh;
  mesh.nodes.resize(3, static_cast<Eigen::Index>(nodes.size()));
  for (size_t i = 0; i < nodes.size(); ++i) mesh.nodes.col(static_cast<Eigen::Index>(i)) = nodes[i];
  mesh.tets.resize(4, static_cast<Eigen::Index>(tets.size()));
  for (size_t t = 0; t < tets.size(); ++t) mesh.tets.col(static_cast<Eigen::Index>(t)) = tets[t];
  for (Eigen::Index t = 0; t < mesh.tets.cols(); ++t) {
    if (TetVolume(mesh, t) < 0.0) std::swap(mesh.tets(2, t), mesh.tets(3, t));
  }
  mesh.regions = ComponentRegions(mesh.tets);
  return mesh;
}

void Report(const CgalMeshSettings& s, double fraction) {
  if (s.progress) s.progress(std::clamp(fraction, 0.0, 1.0));
}

void PollCancel(const CgalMeshSettings& s) {
  if (s.cancel != nullptr && s.cancel->load(std::memory_order_relaxed)) throw CgalMeshCancelled();
}

TetMesh Run(const CompiledSolid& solid, const Eigen::AlignedBox3d& bounds,
            const CgalMeshSettings& s, CgalMeshStats& stats) {
  namespace params = CGAL::parameters;
  const auto start = Clock::now();
  CGAL::get_default_random() = CGAL::Random(s.seed);
  CGAL::Random domain_random(s.seed);
  Report(s, 0.0);
  PollCancel(s);

  if (solid.Classify(bounds) == BoxClass::kOutside) {
    throw CgalMeshError(
        "CGAL mesher: the solid is empty in the box " + FmtBox(bounds) +
        " (its interval bounds are > 0 on the whole box): move or enlarge the bounds");
  }
  if (solid.Classify(bounds) == BoxClass::kInside) {
    throw CgalMeshError(
        "CGAL mesher: the box " + FmtBox(bounds) +
        " lies wholly inside the solid: enlarge the bounds to contain the whole solid");
  }

  // The labeling function: subdomain 1 inside (value < 0), 0 outside. CompiledSolid::Value is
  // const and thread-safe.
  const std::function<int(const Point&)> label = [&solid](const Point& p) {
    return solid.Value(Eigen::Vector3d(p.x(), p.y(), p.z())) < 0.0 ? 1 : 0;
  };
  const CGAL::Bbox_3 bbox(bounds.min().x(), bounds.min().y(), bounds.min().z(), bounds.max().x(),
                          bounds.max().y(), bounds.max().z());
  const Domain domain(label, bbox, s.relative_error_bound, CGAL::Null_subdomain_index(),
                      &domain_random);

  auto phase_start = Clock::now();
  const auto seeds = SeedPoints(solid, domain, bounds, s);
  stats.seed_points = static_cast<long>(seeds.size());

  C3t3 c3t3;
  const auto weighted = c3t3.triangulation().geom_traits().construct_weighted_point_3_object();
  for (const auto& [p, index] : seeds) {
    const C3t3::Vertex_handle v = c3t3.triangulation().insert(weighted(p));
    if (v == C3t3::Vertex_handle()) continue;
    c3t3.set_dimension(v, 2);
    c3t3.set_index(v, index);
  }
  if (c3t3.triangulation().dimension() < 3) {
    throw CgalMeshError(
        "CGAL mesher: the " + std::to_string(seeds.size()) +
        " surface points found are coplanar; the solid is too thin or too small for facet_size " +
        Fmt(s.facet_size) + " m: reduce facet_size");
  }
  stats.seed_seconds = Since(phase_start);
  Report(s, 0.05);
  PollCancel(s);

  phase_start = Clock::now();
  Criteria criteria(params::facet_angle = s.facet_angle_deg, params::facet_size = s.facet_size,
                    params::facet_distance = s.facet_distance,
                    params::cell_radius_edge_ratio = s.cell_radius_edge_ratio,
                    params::cell_size = s.cell_size);
  {
    Mesher mesher(c3t3, domain, criteria);
    mesher.initialize();
    long steps = 0;
    // At least one step: when initialize() leaves no bad facet, is_algorithm_done() is already
    // true, but only one_step() moves on to scanning edges, vertices and then cells.
    do {
      mesher.one_step();
      ++steps;
      PollCancel(s);
      if ((steps & 255) == 0) {
        const long vertices = static_cast<long>(c3t3.triangulation().number_of_vertices());
        if (vertices > s.max_vertices) {
          throw CgalMeshError(
              "CGAL mesher: more than max_vertices = " + std::to_string(s.max_vertices) +
              " vertices; facet_size " + Fmt(s.facet_size) + " m / cell_size " + Fmt(s.cell_size) +
              " m are too small for the box " + FmtBox(bounds) + ": increase them");
        }
        // Progress: a monotone estimate (the final size is unknown in advance).
        Report(s, 0.05 + 0.65 * (1.0 - 1.0 / (1.0 + steps / 5000.0)));
      }
    } while (!mesher.is_algorithm_done());
    stats.refine_steps = steps;
  }
  stats.refine_seconds = Since(phase_start);
  if (c3t3.number_of_cells_in_complex() == 0) {
    throw CgalMeshError(
        "CGAL mesher: refinement gave no tetrahedra inside the solid; it is thinner than "
        "facet_size " +
        Fmt(s.facet_size) + " m or smaller than the seeds found: reduce facet_size and cell_size");
  }
  Report(s, 0.7);

  phase_start = Clock::now();
  const int optimizers = int{s.lloyd} + int{s.odt} + int{s.perturb} + int{s.exude};
  int done = 0;
  auto next = [&] {
    ++done;
    Report(s, 0.7 + 0.3 * done / std::max(optimizers, 1));
  };
  if (s.lloyd) {
    PollCancel(s);
    CGAL::lloyd_optimize_mesh_3(c3t3, domain, params::time_limit = s.optimizer_time_limit,
                                params::max_iteration_number = s.smoothing_iterations);
    next();
  }
  if (s.odt) {
    PollCancel(s);
    CGAL::odt_optimize_mesh_3(c3t3, domain, params::time_limit = s.optimizer_time_limit,
                              params::max_iteration_number = s.smoothing_iterations);
    next();
  }
  if (s.perturb) {
    PollCancel(s);
    CGAL::perturb_mesh_3(c3t3, domain, params::time_limit = s.optimizer_time_limit,
                         params::sliver_bound = s.sliver_bound_deg);
    next();
  }
  if (s.exude) {
    PollCancel(s);
    CGAL::exude_mesh_3(c3t3, params::time_limit = s.exude_time_limit,
                       params::sliver_bound = s.sliver_bound_deg);
    next();
  }
  PollCancel(s);
  stats.optimize_seconds = Since(phase_start);

  TetMesh mesh = ToTetMesh(c3t3);
  if (mesh.tets.cols() == 0) {
    throw CgalMeshError(
        "CGAL mesher: the optimised mesh has no tetrahedra: reduce facet_size and cell_size");
  }
  stats.boundary_facets = static_cast<long>(c3t3.number_of_facets_in_complex());
  stats.vertices = mesh.nodes.cols();
  stats.tets = mesh.tets.cols();
  stats.quality = MeasureTetQuality(mesh);
  stats.min_dihedral_deg = stats.quality.min_dihedral_deg;
  stats.seconds = Since(start);
  Report(s, 1.0);
  return mesh;
}

}  // namespace

CgalMeshSettings CgalMeshSettings::ForSize(double h) {
  CgalMeshSettings s;
  s.facet_size = h;
  s.cell_size = h;
  s.facet_distance = 0.1 * h;
  return s;
}

TetMesh MeshImplicitWithCgal(const CompiledSolid& solid, const Eigen::AlignedBox3d& bounds,
                             const CgalMeshSettings& settings, CgalMeshStats* stats) {
  CheckSettings(bounds, settings);
  CgalMeshStats local;
  CgalMeshStats& out = stats != nullptr ? *stats : local;
  out = CgalMeshStats{};
  try {
    return Run(solid, bounds, settings, out);
  } catch (const CgalMeshError&) {
    throw;
  } catch (const std::bad_alloc&) {
    throw CgalMeshError("CGAL mesher: out of memory; increase facet_size and cell_size");
  } catch (const std::exception& e) {
    throw CgalMeshError(std::string("CGAL Mesh_3 failed: ") + e.what() +
                        " (try other facet_size / cell_size, or check that the solid is closed and "
                        "inside the bounds)");
  }
}

}  // namespace spidarcad::modeling
