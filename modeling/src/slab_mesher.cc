// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#include "spidarcad/modeling/slab_mesher.h"

#include <CGAL/Constrained_Delaunay_triangulation_2.h>
#include <CGAL/Exact_predicates_inexact_constructions_kernel.h>
#include <CGAL/Triangulation_face_base_with_info_2.h>
#include <CGAL/Triangulation_vertex_base_with_info_2.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <list>
#include <map>
#include <set>
#include <stdexcept>
#include <string>
#include <utility>

namespace spidarcad::modeling {
namespace {

using Triangle = std::array<int, 3>;

struct FaceInfo {
  int nesting = -1;
};
using Kernel = CGAL::Exact_predicates_inexact_constructions_kernel;
using Vb = CGAL::Triangulation_vertex_base_with_info_2<int, Kernel>;
using Fbb = CGAL::Triangulation_face_base_with_info_2<FaceInfo, Kernel>;
using Fb = CGAL::Constrained_triangulation_face_base_2<Kernel, Fbb>;
using Tds = CGAL::Triangulation_data_structure_2<Vb, Fb>;
using Cdt = CGAL::Constrained_Delaunay_triangulation_2<Kernel, Tds, CGAL::Exact_predicates_tag>;

// Nesting level of every face: 0 outside all curves, +1 across each constraint.
void MarkNesting(Cdt* cdt) {
  for (auto f = cdt->all_faces_begin(); f != cdt->all_faces_end(); ++f) f->info().nesting = -1;
  std::list<Cdt::Edge> border;
  auto flood = [&](Cdt::Face_handle start, int level) {
    if (start->info().nesting != -1) return;
    std::list<Cdt::Face_handle> queue{start};
    while (!queue.empty()) {
      const Cdt::Face_handle f = queue.front();
      queue.pop_front();
      if (f->info().nesting != -1) continue;
      f->info().nesting = level;
      for (int i = 0; i < 3; ++i) {
        const Cdt::Face_handle n = f->neighbor(i);
        if (n->info().nesting != -1) continue;
        if (cdt->is_constrained(Cdt::Edge(f, i))) {
          border.emplace_back(f, i);
        } else {
          queue.push_back(n);
        }
      }
    }
  };
  flood(cdt->infinite_face(), 0);
  while (!border.empty()) {
    const Cdt::Edge e = border.front();
    border.pop_front();
    const Cdt::Face_handle n = e.first->neighbor(e.second);
    if (n->info().nesting == -1) flood(n, e.first->info().nesting + 1);
  }
}

// The two in-plane axes (u, v) with e_u × e_v = e_axis.
std::pair<int, int> PlaneAxes(int axis) { return {(axis + 1) % 3, (axis + 2) % 3}; }

bool LessPosition(const Eigen::Vector3d& a, const Eigen::Vector3d& b) {
  return std::lexicographical_compare(a.data(), a.data() + 3, b.data(), b.data() + 3);
}

// The triangles in canonical order: vertices sorted by position, each triangle rotated to start
// at its smallest vertex, triangles sorted.
TriangleMesh Canonical(const std::vector<Eigen::Vector3d>& v, const std::vector<Triangle>& tris) {
  std::vector<int> used;
  for (const Triangle& t : tris) used.insert(used.end(), t.begin(), t.end());
  std::sort(used.begin(), used.end());
  used.erase(std::unique(used.begin(), used.end()), used.end());
  std::sort(used.begin(), used.end(), [&](int a, int b) { return LessPosition(v[a], v[b]); });
  std::map<int, int> index;
  for (std::size_t i = 0; i < used.size(); ++i) index[used[i]] = static_cast<int>(i);
  std::vector<Triangle> out;
  out.reserve(tris.size());
  for (const Triangle& t : tris) {
    Triangle r = {index[t[0]], index[t[1]], index[t[2]]};
    while (r[0] > r[1] || r[0] > r[2]) r = {r[1], r[2], r[0]};
    out.push_back(r);
  }
  std::sort(out.begin(), out.end());
  TriangleMesh mesh;
  mesh.vertices.resize(3, static_cast<Eigen::Index>(used.size()));
  for (std::size_t i = 0; i < used.size(); ++i) mesh.vertices.col(i) = v[used[i]];
  mesh.triangles.resize(3, static_cast<Eigen::Index>(out.size()));
  for (std::size_t f = 0; f < out.size(); ++f)
    for (int j = 0; j < 3; ++j) mesh.triangles(j, f) = out[f][j];
  return mesh;
}

}  // namespace

SlabSurfaces CutSurfaceIntoSlabs(const TriangleMesh& surface, const SlabCut& cut) {
  if (cut.axis < 0 || cut.axis > 2)
    throw std::invalid_argument("slab cut: axis must be 0, 1 or 2, got " +
                                std::to_string(cut.axis));
  for (std::size_t i = 1; i < cut.planes.size(); ++i)
    if (!(cut.planes[i] > cut.planes[i - 1]))
      throw std::invalid_argument("slab cut: the planes must be strictly increasing");
  if (!(cut.snap >= 0.0)) throw std::invalid_argument("slab cut: snap must be >= 0");
  if (!(cut.section_spacing >= 0.0))
    throw std::invalid_argument("slab cut: section_spacing must be >= 0 (0: no interior points)");
  if (cut.section_spacing > 0.0 && surface.vertices.cols() > 0) {
    // The sections lie in the surface's box: bound their grid before cutting.
    const auto [u, w] = PlaneAxes(cut.axis);
    const Eigen::Vector3d extent =
        surface.vertices.rowwise().maxCoeff() - surface.vertices.rowwise().minCoeff();
    const double points =
        (extent[u] / cut.section_spacing + 1) * (extent[w] / cut.section_spacing + 1);
    if (points > 1e7) {
      char what[200];
      std::snprintf(what, sizeof what,
                    "slab cut: section_spacing %g m gives up to %.3g grid points per section "
                    "(over 1e7) on a surface %g by %g m across; use a spacing near its cell",
                    cut.section_spacing, points, extent[u], extent[w]);
      throw std::invalid_argument(what);
    }
  }
  const int axis = cut.axis;
  SlabSurfaces out;
  std::vector<Eigen::Vector3d> v(surface.vertices.cols());
  for (Eigen::Index i = 0; i < surface.vertices.cols(); ++i) v[i] = surface.vertices.col(i);
  std::vector<Triangle> tris(surface.triangles.cols());
  for (Eigen::Index f = 0; f < surface.triangles.cols(); ++f)
    tris[f] = {surface.triangles(0, f), surface.triangles(1, f), surface.triangles(2, f)};

  for (const double c : cut.planes) {
    for (Eigen::Vector3d& p : v)
      if (p[axis] != c && std::abs(p[axis] - c) <= cut.snap) {
        p[axis] = c;
        ++out.snapped_vertices;
      }
    auto side = [&](int i) { return v[i][axis] > c ? 1 : (v[i][axis] < c ? -1 : 0); };
    std::map<std::pair<int, int>, int> crossing;
    auto cross = [&](int a, int b) {
      const std::pair<int, int> key(std::min(a, b), std::max(a, b));
      const auto it = crossing.find(key);
      if (it != crossing.end()) return it->second;
      const Eigen::Vector3d& pa = v[key.first];
      const Eigen::Vector3d& pb = v[key.second];
      const double t = (pa[axis] - c) / (pa[axis] - pb[axis]);
      Eigen::Vector3d p = pa + t * (pb - pa);
      p[axis] = c;
      v.push_back(p);
      const int id = static_cast<int>(v.size()) - 1;
      crossing.emplace(key, id);
      return id;
    };
    std::vector<Triangle> next;
    next.reserve(tris.size());
    for (const Triangle& t : tris) {
      const int s[3] = {side(t[0]), side(t[1]), side(t[2])};
      if (s[0] == 0 && s[1] == 0 && s[2] == 0) {
        throw std::invalid_argument(
            "slab cut: a triangle lies in the plane at " + std::to_string(c) +
            " m (a face of the solid on the plane); move the plane off the solid's faces");
      }
      const bool pos = s[0] > 0 || s[1] > 0 || s[2] > 0, neg = s[0] < 0 || s[1] < 0 || s[2] < 0;
      if (!(pos && neg)) {
        next.push_back(t);
        continue;
      }
      ++out.split_triangles;
      // Walk the edges, building the polygon on each side (vertices on the plane go to both).
      std::vector<int> poly[2];
      for (int j = 0; j < 3; ++j) {
        const int a = t[j], b = t[(j + 1) % 3], sa = s[j], sb = s[(j + 1) % 3];
        if (sa <= 0) poly[0].push_back(a);
        if (sa >= 0) poly[1].push_back(a);
        if (sa * sb < 0) {
          const int x = cross(a, b);
          poly[0].push_back(x);
          poly[1].push_back(x);
        }
      }
      for (const std::vector<int>& p : poly) {
        if (p.size() == 3) {
          next.push_back({p[0], p[1], p[2]});
        } else if (p.size() == 4) {  // split the quad along its shorter diagonal
          if ((v[p[0]] - v[p[2]]).squaredNorm() <= (v[p[1]] - v[p[3]]).squaredNorm()) {
            next.push_back({p[0], p[1], p[2]});
            next.push_back({p[0], p[2], p[3]});
          } else {
            next.push_back({p[0], p[1], p[3]});
            next.push_back({p[1], p[2], p[3]});
          }
        }
      }
    }
    tris = std::move(next);
  }

  // Triangles by slab (centroid), and each plane's cut curve: the edges on the plane of the
  // triangles just below it (a pair of opposite edges, where the surface only touches the plane,
  // cancels).
  const int num_slabs = static_cast<int>(cut.planes.size()) + 1;
  std::vector<std::vector<Triangle>> slab_tris(num_slabs);
  std::vector<std::set<std::pair<int, int>>> curve(cut.planes.size());
  for (const Triangle& t : tris) {
    const double centroid = (v[t[0]][axis] + v[t[1]][axis] + v[t[2]][axis]) / 3.0;
    const int k = static_cast<int>(
        std::lower_bound(cut.planes.begin(), cut.planes.end(), centroid) - cut.planes.begin());
    slab_tris[k].push_back(t);
    if (k == num_slabs - 1) continue;
    const double c = cut.planes[k];
    for (int j = 0; j < 3; ++j) {
      const int a = t[j], b = t[(j + 1) % 3];
      if (v[a][axis] != c || v[b][axis] != c) continue;
      if (!curve[k].erase({b, a})) curve[k].insert({a, b});
    }
  }

  const auto [u_axis, v_axis] = PlaneAxes(axis);
  for (std::size_t k = 0; k < cut.planes.size(); ++k) {
    std::vector<int> points;
    for (const auto& [a, b] : curve[k]) {
      points.push_back(a);
      points.push_back(b);
    }
    std::sort(points.begin(), points.end());
    points.erase(std::unique(points.begin(), points.end()), points.end());
    std::sort(points.begin(), points.end(), [&](int a, int b) { return LessPosition(v[a], v[b]); });
    std::vector<Triangle> section;
    try {
      Cdt cdt;
      std::map<int, Cdt::Vertex_handle> handle;
      for (int p : points) {
        const Cdt::Vertex_handle h = cdt.insert(Kernel::Point_2(v[p][u_axis], v[p][v_axis]));
        h->info() = p;
        handle[p] = h;
      }
      if (cdt.number_of_vertices() != points.size())
        throw SurfaceDefectError("slab cut: two cut points coincide on the plane at " +
                                 std::to_string(cut.planes[k]) + " m");
      for (const auto& [a, b] : curve[k]) cdt.insert_constraint(handle[a], handle[b]);
      if (cdt.number_of_vertices() != points.size())
        throw SurfaceDefectError("slab cut: the cut curves on the plane at " +
                                 std::to_string(cut.planes[k]) + " m cross each other");
      if (cdt.dimension() < 2)
        throw SurfaceDefectError("slab cut: the cross-section on the plane at " +
                                 std::to_string(cut.planes[k]) + " m has " +
                                 std::to_string(points.size()) +
                                 " cut points, not enough for an area (the plane misses the "
                                 "solid, or only touches it)");
      MarkNesting(&cdt);
      if (cut.section_spacing > 0.0) {
        // Interior grid points inside the section, half a spacing or more from every cut edge.
        const double h = cut.section_spacing;
        double lo[2] = {1e300, 1e300}, hi[2] = {-1e300, -1e300};
        for (int q : points) {
          lo[0] = std::min(lo[0], v[q][u_axis]);
          hi[0] = std::max(hi[0], v[q][u_axis]);
          lo[1] = std::min(lo[1], v[q][v_axis]);
          hi[1] = std::max(hi[1], v[q][v_axis]);
        }
        auto far_from_curves = [&](double pu, double pv) {
          for (const auto& [a, b] : curve[k]) {
            const Eigen::Vector2d pa(v[a][u_axis], v[a][v_axis]), pb(v[b][u_axis], v[b][v_axis]);
            const Eigen::Vector2d d = pb - pa, w = Eigen::Vector2d(pu, pv) - pa;
            const double t = std::clamp(w.dot(d) / std::max(d.squaredNorm(), 1e-300), 0.0, 1.0);
            if ((w - t * d).norm() < 0.5 * h) return false;
          }
          return true;
        };
        std::vector<Eigen::Vector2d> interior;
        for (double iu = std::ceil(lo[0] / h); iu * h <= hi[0]; ++iu) {
          for (double iv = std::ceil(lo[1] / h); iv * h <= hi[1]; ++iv) {
            const double gu = iu * h, gv = iv * h;  // multiples of h: the grid anchored at 0
            const Cdt::Face_handle f = cdt.locate(Kernel::Point_2(gu, gv));
            if (cdt.is_infinite(f) || f->info().nesting % 2 != 1) continue;
            if (far_from_curves(gu, gv)) interior.emplace_back(gu, gv);
          }
        }
        for (const Eigen::Vector2d& q : interior) {
          Eigen::Vector3d p3;
          p3[axis] = cut.planes[k];
          p3[u_axis] = q.x();
          p3[v_axis] = q.y();
          v.push_back(p3);
          const Cdt::Vertex_handle h3 = cdt.insert(Kernel::Point_2(q.x(), q.y()));
          h3->info() = static_cast<int>(v.size()) - 1;
        }
        if (!interior.empty()) MarkNesting(&cdt);
      }
      for (auto f = cdt.finite_faces_begin(); f != cdt.finite_faces_end(); ++f) {
        if (f->info().nesting % 2 != 1) continue;
        // CGAL's faces are counter-clockwise in (u, v): normal +axis.
        section.push_back({f->vertex(0)->info(), f->vertex(1)->info(), f->vertex(2)->info()});
      }
    } catch (const SurfaceDefectError&) {
      throw;
    } catch (const std::exception& e) {
      throw SurfaceDefectError("slab cut: the cross-section on the plane at " +
                               std::to_string(cut.planes[k]) +
                               " m cannot be triangulated (cut curves that cross): " + e.what());
    }
    for (const Triangle& t : section) {
      slab_tris[k].push_back(t);                       // below: outward is +axis
      slab_tris[k + 1].push_back({t[0], t[2], t[1]});  // above: outward is −axis
    }
    out.sections.push_back(Canonical(v, section));
  }
  for (const std::vector<Triangle>& t : slab_tris) out.slabs.push_back(Canonical(v, t));
  return out;
}

std::uint64_t SurfaceHash(const TriangleMesh& surface) {
  std::uint64_t h = 14695981039346656037ull;
  auto add = [&h](const void* data, std::size_t size) {
    const auto* p = static_cast<const unsigned char*>(data);
    for (std::size_t i = 0; i < size; ++i) {
      h ^= p[i];
      h *= 1099511628211ull;
    }
  };
  const std::int64_t sizes[2] = {surface.vertices.cols(), surface.triangles.cols()};
  add(sizes, sizeof(sizes));
  add(surface.vertices.data(), sizeof(double) * surface.vertices.size());
  add(surface.triangles.data(), sizeof(int) * surface.triangles.size());
  return h;
}

TetMesh TetrahedralizeSlab(const TriangleMesh& slab_surface, TetMeshSettings settings,
                           TetMeshStats* stats) {
  settings.preserve_surface = true;
  settings.keep_facets = true;
  // No welding: the slab's vertices on its planes must stay exactly those its neighbours have.
  settings.weld_tolerance = -1.0;
  // The cut curves and flat faces hold many degenerate point sets (TetMeshSettings).
  settings.perturb_from_triangles = kSlabPerturbFromTriangles;
  return TetrahedralizeSurface(slab_surface, settings, stats);
}

SlabTetMesh JoinSlabs(const std::vector<TetMesh>& slabs) {
  SlabTetMesh out;
  std::map<std::array<double, 3>, int> id_of;
  std::vector<Eigen::Vector3d> nodes;
  std::vector<std::array<int, 4>> tets;
  std::vector<int> regions, slab_of;
  for (std::size_t k = 0; k < slabs.size(); ++k) {
    const TetMesh& s = slabs[k];
    std::vector<int> map(s.nodes.cols());
    for (Eigen::Index i = 0; i < s.nodes.cols(); ++i) {
      const std::array<double, 3> key = {s.nodes(0, i), s.nodes(1, i), s.nodes(2, i)};
      const auto [it, added] = id_of.emplace(key, static_cast<int>(nodes.size()));
      if (added) nodes.push_back(s.nodes.col(i));
      map[i] = it->second;
    }
    for (Eigen::Index t = 0; t < s.tets.cols(); ++t) {
      tets.push_back({map[s.tets(0, t)], map[s.tets(1, t)], map[s.tets(2, t)], map[s.tets(3, t)]});
      regions.push_back(s.regions.size() == s.tets.cols() ? s.regions(t) : 0);
      slab_of.push_back(static_cast<int>(k));
    }
  }
  out.mesh.nodes.resize(3, static_cast<Eigen::Index>(nodes.size()));
  for (std::size_t i = 0; i < nodes.size(); ++i) out.mesh.nodes.col(i) = nodes[i];
  out.mesh.tets.resize(4, static_cast<Eigen::Index>(tets.size()));
  out.mesh.regions.resize(static_cast<Eigen::Index>(tets.size()));
  out.slab.resize(static_cast<Eigen::Index>(tets.size()));
  for (std::size_t t = 0; t < tets.size(); ++t) {
    for (int j = 0; j < 4; ++j) out.mesh.tets(j, t) = tets[t][j];
    out.mesh.regions(t) = regions[t];
    out.slab(t) = slab_of[t];
  }
  return out;
}

}  // namespace spidarcad::modeling
