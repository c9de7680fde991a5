// FindSelfIntersections (mesh_repair.h): CGAL Polygon_mesh_processing::self_intersections on a
// Surface_mesh built from the triangles in order. The only CGAL translation unit besides
// cgal_mesher.cc (compiled with -frounding-math, see modeling/CMakeLists.txt).
// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#include <CGAL/Exact_predicates_inexact_constructions_kernel.h>
#include <CGAL/Polygon_mesh_processing/orient_polygon_soup.h>
#include <CGAL/Polygon_mesh_processing/polygon_soup_to_polygon_mesh.h>
#include <CGAL/Polygon_mesh_processing/self_intersections.h>
#include <CGAL/Surface_mesh.h>

#include <algorithm>
#include <array>
#include <iterator>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include "spidarcad/modeling/mesh_repair.h"
#include "triangle_predicates.h"

namespace spidarcad::modeling {

namespace {

using Kernel = CGAL::Exact_predicates_inexact_constructions_kernel;
using Point = Kernel::Point_3;
using Mesh = CGAL::Surface_mesh<Point>;
namespace pmp = CGAL::Polygon_mesh_processing;

// Whether triangles f and g of mesh share a vertex index.
bool ShareVertex(const TriangleMesh& mesh, int f, int g) {
  for (int i = 0; i < 3; ++i)
    for (int k = 0; k < 3; ++k)
      if (mesh.triangles(i, f) == mesh.triangles(k, g)) return true;
  return false;
}

// Whether polygons f and g share a point index.
bool ShareVertex(const std::vector<std::array<std::size_t, 3>>& polygons, int f, int g) {
  for (std::size_t i : polygons[f])
    for (std::size_t k : polygons[g])
      if (i == k) return true;
  return false;
}

}  // namespace

std::vector<std::pair<int, int>> FindSelfIntersections(const TriangleMesh& mesh) {
  const Eigen::Index nv = mesh.vertices.cols(), nf = mesh.triangles.cols();
  std::vector<Point> points;
  points.reserve(nv);
  for (Eigen::Index i = 0; i < nv; ++i)
    points.emplace_back(mesh.vertices(0, i), mesh.vertices(1, i), mesh.vertices(2, i));
  std::vector<std::array<std::size_t, 3>> polygons(nf);
  for (Eigen::Index f = 0; f < nf; ++f)
    for (int k = 0; k < 3; ++k) {
      const int v = mesh.triangles(k, f);
      if (v < 0 || v >= nv)
        throw std::invalid_argument("FindSelfIntersections: triangle " + std::to_string(f) +
                                    " has a vertex index out of range");
      polygons[f][k] = static_cast<std::size_t>(v);
    }
  std::vector<std::pair<Mesh::Face_index, Mesh::Face_index>> pairs;
  try {
    // A vertex where several fans meet (two solids touching at a point) cannot be one halfedge
    // vertex: orient_polygon_soup gives each fan a copy. It keeps the polygons' order.
    pmp::orient_polygon_soup(points, polygons);
    if (!pmp::is_polygon_soup_a_polygon_mesh(polygons))
      throw std::invalid_argument(
          "FindSelfIntersections: the triangles do not form a polygon mesh (open or "
          "non-manifold)");
    Mesh cgal_mesh;
    pmp::polygon_soup_to_polygon_mesh(points, polygons, cgal_mesh);
    if (static_cast<Eigen::Index>(cgal_mesh.number_of_faces()) != nf)
      throw std::invalid_argument("FindSelfIntersections: CGAL built " +
                                  std::to_string(cgal_mesh.number_of_faces()) + " faces of " +
                                  std::to_string(nf) + " triangles");
    pmp::self_intersections(cgal_mesh, std::back_inserter(pairs));
  } catch (const CGAL::Failure_exception& e) {
    throw std::invalid_argument(std::string("FindSelfIntersections: CGAL failed: ") + e.what());
  }
  // Faces were added in the triangles' order, so a face's index is its triangle's.
  std::vector<std::pair<int, int>> out;
  out.reserve(pairs.size());
  for (const auto& [a, b] : pairs) {
    int f = static_cast<int>(a.idx()), g = static_cast<int>(b.idx());
    if (f > g) std::swap(f, g);
    // Two triangles of different fans of one vertex touch there; CGAL, which sees two copies of
    // the vertex, calls that an intersection. They intersect only if they meet elsewhere.
    if (ShareVertex(mesh, f, g) && !ShareVertex(polygons, f, g)) {
      std::array<int, 3> ia, ib;
      std::array<Eigen::Vector3d, 3> pa, pb;
      for (int k = 0; k < 3; ++k) {
        ia[k] = mesh.triangles(k, f);
        ib[k] = mesh.triangles(k, g);
        pa[k] = mesh.vertices.col(ia[k]);
        pb[k] = mesh.vertices.col(ib[k]);
      }
      if (!internal::TrianglesMeet(ia, pa, ib, pb)) continue;
    }
    out.emplace_back(f, g);
  }
  std::sort(out.begin(), out.end());
  return out;
}

}  // namespace spidarcad::modeling
