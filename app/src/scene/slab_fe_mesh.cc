// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#include "scene/slab_fe_mesh.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <stdexcept>

#include "scene/vtu_io.h"
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

}  // namespace

int SlabFeMesh::num_remeshed() const {
  return static_cast<int>(std::count(remeshed.begin(), remeshed.end(), 1));
}

std::vector<double> SlabPlanes(const Eigen::AlignedBox3d& grid_bounds, double cell, int slabs) {
  std::vector<double> planes;
  const double lo = grid_bounds.min().x(), hi = grid_bounds.max().x();
  for (int k = 1; k < slabs; ++k) {
    const double x = lo + (hi - lo) * k / slabs;
    const double p = lo + cell * (std::floor((x - lo) / cell) + 0.5);
    if (planes.empty() || p > planes.back()) planes.push_back(p);
  }
  return planes;
}

SlabFeMesh MeshSolidInSlabs(const modeling::CompiledSolid& solid,
                            const Eigen::AlignedBox3d& grid_bounds, double cell,
                            const std::vector<double>& planes, double max_radius_edge,
                            const SlabFeMesh* previous) {
  SlabFeMesh out;
  out.planes = planes;
  out.grid_bounds = grid_bounds;
  out.cell = cell;
  if (previous != nullptr && (previous->planes != planes || previous->cell != cell ||
                              !previous->grid_bounds.isApprox(grid_bounds, 0.0)))
    previous = nullptr;

  auto t = Clock::now();
  modeling::SurfaceMeshSettings ss;
  ss.bounds = grid_bounds;
  ss.cell_size = cell;
  const modeling::TriangleMesh surface = modeling::MeshSurface(solid, ss);
  out.surface_seconds = Seconds(t);

  t = Clock::now();
  modeling::SlabCut cut;
  cut.axis = 0;
  cut.planes = planes;
  cut.snap = 0.1 * cell;
  cut.section_spacing = cell;
  modeling::SlabSurfaces slabs = modeling::CutSurfaceIntoSlabs(surface, cut);
  out.cut_seconds = Seconds(t);

  modeling::TetMeshSettings ts;
  ts.max_radius_edge = max_radius_edge;
  const std::size_t n = slabs.slabs.size();
  out.slab_surfaces = std::move(slabs.slabs);
  out.slab_tets.resize(n);
  out.remeshed.assign(n, 0);
  for (std::size_t k = 0; k < n; ++k) {
    const modeling::TriangleMesh& s = out.slab_surfaces[k];
    if (previous != nullptr && k < previous->slab_surfaces.size() &&
        modeling::SurfaceHash(s) == modeling::SurfaceHash(previous->slab_surfaces[k]) &&
        SameSurface(s, previous->slab_surfaces[k])) {
      out.slab_tets[k] = previous->slab_tets[k];
      continue;
    }
    t = Clock::now();
    out.slab_tets[k] = modeling::TetrahedralizeSlab(s, ts);
    out.tetgen_seconds += Seconds(t);
    out.remeshed[k] = 1;
  }

  t = Clock::now();
  const modeling::SlabTetMesh joined = modeling::JoinSlabs(out.slab_tets);
  out.mesh = ToFemMesh(joined.mesh);
  out.mesh.regions.setZero(out.mesh.num_elements());
  out.slab = joined.slab;
  out.join_seconds = Seconds(t);
  return out;
}

}  // namespace spidarcad::app
