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

// Nesting level of every face: 0 outside all curves, +1 across each edge `border` accepts.
template <class Border>
void MarkNesting(Cdt* cdt, const Border& border_edge) {
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
        if (border_edge(Cdt::Edge(f, i))) {
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

// Splits the triangles that cross the plane p[axis] = c, after moving the vertices within `snap`
// of it onto it. Triangles with select[t] true are split along the plane (into the pieces on
// either side); any other triangle that holds an edge a selected one split is split in two at
// that edge's crossing point (its other edges do not reach the plane's selected side: it is a
// triangle of a neighbouring slab with that edge on their shared plane). Crossing points are
// shared by the triangles on an edge, so a closed surface stays closed. `tag` is carried to the
// pieces. Throws std::invalid_argument naming `where` when a selected triangle lies in the plane.
void SplitByPlane(std::vector<Eigen::Vector3d>& v, std::vector<Triangle>& tris,
                  std::vector<int>& tag, const std::vector<char>& select, int axis, double c,
                  double snap, const std::string& where, SlabSurfaces* out) {
  std::vector<char> near(v.size(), 0);
  for (std::size_t t = 0; t < tris.size(); ++t)
    if (select[t])
      for (int j : tris[t]) near[j] = 1;
  for (std::size_t i = 0; i < near.size(); ++i) {
    Eigen::Vector3d& p = v[i];
    if (near[i] && p[axis] != c && std::abs(p[axis] - c) <= snap) {
      p[axis] = c;
      ++out->snapped_vertices;
    }
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
  std::vector<int> next_tag;
  next.reserve(tris.size());
  next_tag.reserve(tris.size());
  std::vector<char> kept(tris.size(), 0);  // an unselected triangle, for the second pass
  for (std::size_t f = 0; f < tris.size(); ++f) {
    const Triangle& t = tris[f];
    if (!select[f]) {
      kept[f] = 1;
      continue;
    }
    const int s[3] = {side(t[0]), side(t[1]), side(t[2])};
    if (s[0] == 0 && s[1] == 0 && s[2] == 0)
      throw std::invalid_argument("slab cut: a triangle lies in the plane " + where +
                                  " (a face of the solid on the plane); move the plane off the "
                                  "solid's faces");
    const bool pos = s[0] > 0 || s[1] > 0 || s[2] > 0, neg = s[0] < 0 || s[1] < 0 || s[2] < 0;
    if (!(pos && neg)) {
      next.push_back(t);
      next_tag.push_back(tag[f]);
      continue;
    }
    ++out->split_triangles;
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
        next_tag.push_back(tag[f]);
      } else if (p.size() == 4) {  // split the quad along its shorter diagonal
        if ((v[p[0]] - v[p[2]]).squaredNorm() <= (v[p[1]] - v[p[3]]).squaredNorm()) {
          next.push_back({p[0], p[1], p[2]});
          next.push_back({p[0], p[2], p[3]});
        } else {
          next.push_back({p[0], p[1], p[3]});
          next.push_back({p[1], p[2], p[3]});
        }
        next_tag.push_back(tag[f]);
        next_tag.push_back(tag[f]);
      }
    }
  }
  for (std::size_t f = 0; f < tris.size(); ++f) {
    if (!kept[f]) continue;
    const Triangle& t = tris[f];
    int j = 0;
    auto it = crossing.end();
    for (; j < 3 && it == crossing.end(); ++j)
      it = crossing.find({std::min(t[j], t[(j + 1) % 3]), std::max(t[j], t[(j + 1) % 3])});
    if (it == crossing.end()) {
      next.push_back(t);
      next_tag.push_back(tag[f]);
      continue;
    }
    --j;  // edge (t[j], t[j + 1]) is split at it->second
    const int m = it->second;
    next.push_back({t[j], m, t[(j + 2) % 3]});
    next.push_back({m, t[(j + 1) % 3], t[(j + 2) % 3]});
    next_tag.push_back(tag[f]);
    next_tag.push_back(tag[f]);
    ++out->split_triangles;
  }
  tris = std::move(next);
  tag = std::move(next_tag);
}

// The cross-section on the plane p[axis] = c bounded by the cut curves `curve` (directed edges,
// vertex ids into v, as they run in the triangles on the plane's lower side): CGAL's constrained
// Delaunay triangulation of the curve points, inside the curves (odd nesting), with
//  - on each line p[line_axis] = l (l in `lines`) through the section, a constrained path of
//    the curve points on it and points `spacing` apart between them (where they are half a
//    spacing or more from every curve edge), so that no triangle straddles a line: a section
//    shared by a slab and its strips;
//  - with spacing > 0, the interior points of a square grid of that spacing anchored at the
//    origin that lie inside and half a spacing or more from every curve edge and line.
// New points are appended to v. Triangles are counter-clockwise about +axis. Throws
// SurfaceDefectError naming `where` when the curves cannot be triangulated.
std::vector<Triangle> TriangulateSection(std::vector<Eigen::Vector3d>& v,
                                         const std::set<std::pair<int, int>>& curve, int axis,
                                         double c, double spacing, int line_axis,
                                         const std::vector<double>& lines,
                                         const std::string& where) {
  const auto [u_axis, v_axis] = PlaneAxes(axis);
  std::vector<int> points;
  std::set<std::pair<int, int>> curve_pairs;  // undirected
  for (const auto& [a, b] : curve) {
    points.push_back(a);
    points.push_back(b);
    curve_pairs.emplace(std::min(a, b), std::max(a, b));
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
      throw SurfaceDefectError("slab cut: two cut points coincide on the plane " + where);
    for (const auto& [a, b] : curve) cdt.insert_constraint(handle[a], handle[b]);
    if (cdt.number_of_vertices() != points.size())
      throw SurfaceDefectError("slab cut: the cut curves on the plane " + where +
                               " cross each other");
    if (cdt.dimension() < 2)
      throw SurfaceDefectError("slab cut: the cross-section on the plane " + where + " has " +
                               std::to_string(points.size()) +
                               " cut points, not enough for an area (the plane misses the "
                               "solid, or only touches it)");
    // The curves bound the section; the lines' constraints (line_pairs, each between two
    // consecutive points of a line's path) do not change the nesting. A curve constraint that
    // CGAL splits stays a border.
    std::set<std::pair<int, int>> line_pairs;
    auto border = [&](const Cdt::Edge& e) {
      if (!cdt.is_constrained(e)) return false;
      const int a = e.first->vertex(Cdt::cw(e.second))->info();
      const int b = e.first->vertex(Cdt::ccw(e.second))->info();
      return line_pairs.count({std::min(a, b), std::max(a, b)}) == 0;
    };
    MarkNesting(&cdt, border);
    auto inside = [&](double pu, double pv) {
      const Cdt::Face_handle f = cdt.locate(Kernel::Point_2(pu, pv));
      return !cdt.is_infinite(f) && f->info().nesting % 2 == 1;
    };
    auto far_from_curves = [&](double pu, double pv) {
      const double h = spacing;
      for (const auto& [a, b] : curve) {
        const Eigen::Vector2d pa(v[a][u_axis], v[a][v_axis]), pb(v[b][u_axis], v[b][v_axis]);
        const Eigen::Vector2d d = pb - pa, w = Eigen::Vector2d(pu, pv) - pa;
        const double t = std::clamp(w.dot(d) / std::max(d.squaredNorm(), 1e-300), 0.0, 1.0);
        if ((w - t * d).norm() < 0.5 * h) return false;
      }
      return true;
    };
    auto add_point = [&](double pu, double pv) {
      Eigen::Vector3d p3;
      p3[axis] = c;
      p3[u_axis] = pu;
      p3[v_axis] = pv;
      v.push_back(p3);
      const Cdt::Vertex_handle h3 = cdt.insert(Kernel::Point_2(pu, pv));
      h3->info() = static_cast<int>(v.size()) - 1;
      return h3;
    };
    // The lines' paths, all found on the curves' nesting before anything is inserted: the curve
    // points on each line in order along it, and between two of them that bound a stretch inside
    // the section (not a curve edge), points `spacing` apart, half a spacing or more from the
    // curves. A path is (first curve point, the points between as (u, v), last curve point).
    const bool line_is_u = line_axis == u_axis;  // the line fixes u; it runs along v
    const int along = line_is_u ? v_axis : u_axis;
    struct Path {
      int a, b;
      std::vector<Eigen::Vector2d> between;
    };
    std::vector<Path> paths;
    for (const double l : lines) {
      std::vector<int> on;
      for (int p : points)
        if (v[p][line_axis] == l) on.push_back(p);
      std::sort(on.begin(), on.end(), [&](int a, int b) { return v[a][along] < v[b][along]; });
      for (std::size_t i = 1; i < on.size(); ++i) {
        const int a = on[i - 1], b = on[i];
        if (curve_pairs.count({std::min(a, b), std::max(a, b)})) continue;  // a curve edge
        const double ta = v[a][along], tb = v[b][along], mid = 0.5 * (ta + tb);
        if (!(line_is_u ? inside(l, mid) : inside(mid, l))) continue;
        Path path{a, b, {}};
        if (spacing > 0.0) {
          for (double k = std::ceil(ta / spacing); k * spacing < tb; ++k) {
            const double t = k * spacing;
            if (t - ta < 0.5 * spacing || tb - t < 0.5 * spacing) continue;
            const Eigen::Vector2d q = line_is_u ? Eigen::Vector2d(l, t) : Eigen::Vector2d(t, l);
            if (far_from_curves(q.x(), q.y())) path.between.push_back(q);
          }
        }
        paths.push_back(std::move(path));
      }
    }
    std::vector<std::pair<Cdt::Vertex_handle, Cdt::Vertex_handle>> line_edges;
    for (const Path& path : paths) {
      std::vector<Cdt::Vertex_handle> chain{handle[path.a]};
      for (const Eigen::Vector2d& q : path.between) chain.push_back(add_point(q.x(), q.y()));
      chain.push_back(handle[path.b]);
      for (std::size_t q = 1; q < chain.size(); ++q) {
        const int a = chain[q - 1]->info(), b = chain[q]->info();
        line_pairs.emplace(std::min(a, b), std::max(a, b));
        line_edges.emplace_back(chain[q - 1], chain[q]);
      }
    }
    const std::size_t with_lines = cdt.number_of_vertices();
    for (const auto& [a, b] : line_edges) cdt.insert_constraint(a, b);
    if (cdt.number_of_vertices() != with_lines)
      throw SurfaceDefectError(
          "slab cut: a strip plane's line crosses the cut curves on the plane " + where);
    MarkNesting(&cdt, border);
    if (spacing > 0.0) {
      // Interior grid points inside the section, half a spacing or more from every cut edge
      // and line, found on the nesting with the lines and inserted after.
      const double h = spacing;
      double lo[2] = {1e300, 1e300}, hi[2] = {-1e300, -1e300};
      for (int q : points) {
        lo[0] = std::min(lo[0], v[q][u_axis]);
        hi[0] = std::max(hi[0], v[q][u_axis]);
        lo[1] = std::min(lo[1], v[q][v_axis]);
        hi[1] = std::max(hi[1], v[q][v_axis]);
      }
      std::vector<Eigen::Vector2d> interior;
      for (double iu = std::ceil(lo[0] / h); iu * h <= hi[0]; ++iu) {
        for (double iv = std::ceil(lo[1] / h); iv * h <= hi[1]; ++iv) {
          const double gu = iu * h, gv = iv * h;  // multiples of h: the grid anchored at 0
          const double across = line_is_u ? gu : gv;
          if (std::any_of(lines.begin(), lines.end(),
                          [&](double l) { return std::abs(across - l) < 0.5 * h; }))
            continue;
          if (inside(gu, gv) && far_from_curves(gu, gv)) interior.emplace_back(gu, gv);
        }
      }
      for (const Eigen::Vector2d& q : interior) add_point(q.x(), q.y());
    }
    MarkNesting(&cdt, border);
    for (auto f = cdt.finite_faces_begin(); f != cdt.finite_faces_end(); ++f) {
      if (f->info().nesting % 2 != 1) continue;
      // CGAL's faces are counter-clockwise in (u, v): normal +axis.
      section.push_back({f->vertex(0)->info(), f->vertex(1)->info(), f->vertex(2)->info()});
    }
  } catch (const SurfaceDefectError&) {
    throw;
  } catch (const std::exception& e) {
    throw SurfaceDefectError("slab cut: the cross-section on the plane " + where +
                             " cannot be triangulated (cut curves that cross): " + e.what());
  }
  return section;
}

}  // namespace

SlabSurfaces CutSurfaceIntoSlabs(const TriangleMesh& surface, const SlabCut& cut) {
  if (cut.axis < 0 || cut.axis > 2)
    throw std::invalid_argument("slab cut: axis must be 0, 1 or 2, got " +
                                std::to_string(cut.axis));
  for (std::size_t i = 1; i < cut.planes.size(); ++i)
    if (!(cut.planes[i] > cut.planes[i - 1]))
      throw std::invalid_argument("slab cut: the planes must be strictly increasing");
  const int num_slabs = static_cast<int>(cut.planes.size()) + 1;
  const bool strips = !cut.strip_planes.empty();
  if (strips) {
    if (cut.strip_axis < 0 || cut.strip_axis > 2 || cut.strip_axis == cut.axis)
      throw std::invalid_argument("slab cut: strip_axis must be 0, 1 or 2 and not the axis, got " +
                                  std::to_string(cut.strip_axis));
    if (static_cast<int>(cut.strip_planes.size()) != num_slabs)
      throw std::invalid_argument("slab cut: strip_planes must hold a list per slab (" +
                                  std::to_string(num_slabs) + "), got " +
                                  std::to_string(cut.strip_planes.size()));
    // Strictly increasing, and (the snap moves vertices onto each in turn) more than two snaps
    // apart within a slab, and from a different plane of a neighbouring slab, whose lines meet
    // on their shared section.
    for (std::size_t k = 0; k < cut.strip_planes.size(); ++k) {
      const std::vector<double>& p = cut.strip_planes[k];
      for (std::size_t i = 1; i < p.size(); ++i)
        if (!(p[i] > p[i - 1] + 2.0 * cut.snap))
          throw std::invalid_argument(
              "slab cut: each slab's strip planes must be increasing, "
              "more than two snaps apart");
      if (k == 0) continue;
      for (double a : p)
        for (double b : cut.strip_planes[k - 1])
          if (a != b && std::abs(a - b) <= 2.0 * cut.snap)
            throw std::invalid_argument(
                "slab cut: strip planes of neighbouring slabs must be equal or more than two "
                "snaps apart");
    }
  }
  if (!(cut.snap >= 0.0)) throw std::invalid_argument("slab cut: snap must be >= 0");
  if (!(cut.section_spacing >= 0.0))
    throw std::invalid_argument("slab cut: section_spacing must be >= 0 (0: no interior points)");
  if (cut.section_spacing > 0.0 && surface.vertices.cols() > 0) {
    // The sections lie in the surface's box: bound their grid before cutting.
    const Eigen::Vector3d extent =
        surface.vertices.rowwise().maxCoeff() - surface.vertices.rowwise().minCoeff();
    for (int a : strips ? std::vector<int>{cut.axis, cut.strip_axis} : std::vector<int>{cut.axis}) {
      const auto [u, w] = PlaneAxes(a);
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
  }
  const int axis = cut.axis, saxis = cut.strip_axis;
  SlabSurfaces out;
  std::vector<Eigen::Vector3d> v(surface.vertices.cols());
  for (Eigen::Index i = 0; i < surface.vertices.cols(); ++i) v[i] = surface.vertices.col(i);
  std::vector<Triangle> tris(surface.triangles.cols());
  for (Eigen::Index f = 0; f < surface.triangles.cols(); ++f)
    tris[f] = {surface.triangles(0, f), surface.triangles(1, f), surface.triangles(2, f)};
  std::vector<int> slab_of(tris.size(), 0);

  auto where_plane = [&](int a, double c) {
    return std::string("at ") + "xyz"[a] + " = " + std::to_string(c) + " m";
  };
  for (const double c : cut.planes) {
    const std::vector<char> all(tris.size(), 1);
    SplitByPlane(v, tris, slab_of, all, axis, c, cut.snap, where_plane(axis, c), &out);
  }
  auto centroid = [&](const Triangle& t, int a) {
    return (v[t[0]][a] + v[t[1]][a] + v[t[2]][a]) / 3.0;
  };
  auto slab_at = [&](double x) {
    return static_cast<int>(std::lower_bound(cut.planes.begin(), cut.planes.end(), x) -
                            cut.planes.begin());
  };
  for (std::size_t f = 0; f < tris.size(); ++f) slab_of[f] = slab_at(centroid(tris[f], axis));

  // Strips: each slab's own planes across the strip axis, splitting its triangles (and, at the
  // crossing points on its slab planes, those of its neighbours).
  std::vector<int> first_piece(num_slabs + 1, 0);
  for (int k = 0; k < num_slabs; ++k)
    first_piece[k + 1] =
        first_piece[k] + 1 + (strips ? static_cast<int>(cut.strip_planes[k].size()) : 0);
  const int num_pieces = first_piece[num_slabs];
  const std::vector<double> none;
  auto strips_of = [&](int k) -> const std::vector<double>& {
    return strips ? cut.strip_planes[k] : none;
  };
  for (int k = 0; k < num_slabs; ++k) {
    for (const double c : strips_of(k)) {
      std::vector<char> mine(tris.size());
      for (std::size_t f = 0; f < tris.size(); ++f) mine[f] = slab_of[f] == k;
      SplitByPlane(v, tris, slab_of, mine, saxis, c, cut.snap,
                   where_plane(saxis, c) + " in slab " + std::to_string(k), &out);
    }
  }
  auto piece_at = [&](int k, double s) {
    const std::vector<double>& p = strips_of(k);
    return first_piece[k] + static_cast<int>(std::lower_bound(p.begin(), p.end(), s) - p.begin());
  };

  // Triangles by piece (centroid), and each plane's cut curve: the edges on the plane of the
  // triangles just below it (a pair of opposite edges, where the surface only touches the plane,
  // cancels).
  std::vector<std::vector<Triangle>> piece_tris(num_pieces);
  std::vector<std::set<std::pair<int, int>>> curve(cut.planes.size());
  auto add_curve_edges = [&v](const Triangle& t, int a, double c,
                              std::set<std::pair<int, int>>* edges) {
    for (int j = 0; j < 3; ++j) {
      const int p = t[j], q = t[(j + 1) % 3];
      if (v[p][a] != c || v[q][a] != c) continue;
      if (!edges->erase({q, p})) edges->insert({p, q});
    }
  };
  for (std::size_t f = 0; f < tris.size(); ++f) {
    const Triangle& t = tris[f];
    const int k = slab_of[f];
    piece_tris[piece_at(k, strips ? centroid(t, saxis) : 0.0)].push_back(t);
    if (k < num_slabs - 1) add_curve_edges(t, axis, cut.planes[k], &curve[k]);
  }

  for (std::size_t k = 0; k < cut.planes.size(); ++k) {
    // The strip planes of the slabs on both sides cross this section as lines.
    std::vector<double> lines = strips_of(static_cast<int>(k));
    const std::vector<double>& above = strips_of(static_cast<int>(k) + 1);
    lines.insert(lines.end(), above.begin(), above.end());
    std::sort(lines.begin(), lines.end());
    lines.erase(std::unique(lines.begin(), lines.end()), lines.end());
    const std::vector<Triangle> section =
        TriangulateSection(v, curve[k], axis, cut.planes[k], cut.section_spacing, saxis, lines,
                           where_plane(axis, cut.planes[k]));
    for (const Triangle& t : section) {
      const double s = strips ? centroid(t, saxis) : 0.0;
      piece_tris[piece_at(static_cast<int>(k), s)].push_back(t);  // below: outward is +axis
      piece_tris[piece_at(static_cast<int>(k) + 1, s)].push_back({t[0], t[2], t[1]});
    }
    out.sections.push_back(Canonical(v, section));
  }
  for (int k = 0; k < num_slabs; ++k) {
    const std::vector<double>& p = strips_of(k);
    for (std::size_t j = 0; j < p.size(); ++j) {
      // The strip below the plane is piece first_piece[k] + j: its triangles (surface and slab
      // sections) on the plane give the curve.
      const int below = first_piece[k] + static_cast<int>(j);
      std::set<std::pair<int, int>> strip_curve;
      for (const Triangle& t : piece_tris[below]) add_curve_edges(t, saxis, p[j], &strip_curve);
      const std::vector<Triangle> section =
          TriangulateSection(v, strip_curve, saxis, p[j], cut.section_spacing, axis, {},
                             where_plane(saxis, p[j]) + " in slab " + std::to_string(k));
      for (const Triangle& t : section) {
        piece_tris[below].push_back(t);
        piece_tris[below + 1].push_back({t[0], t[2], t[1]});
      }
      out.sections.push_back(Canonical(v, section));
    }
  }
  for (const std::vector<Triangle>& t : piece_tris) out.slabs.push_back(Canonical(v, t));
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
