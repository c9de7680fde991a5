// The surface mesher against its peers on the same signed distances at equal cell size:
//   dense MC:   the field sampled on the whole dense grid (CompiledSolid::Values, one z-slab at a
//               time), then VTK's vtkFlyingEdges3D (marching cubes) at level 0: the plain
//               dense-grid marching cubes every toolkit has;
//   raw:        MeshSurface with clean = false (marching tetrahedra, octree, regula falsi);
//   MeshSurface: the default settings (with the clean-up);
//   + sharpen:  MeshSurface then SharpenFeatures (`spidarcad mesh --sharp`);
//   snap 0.15:  MeshSurface with SurfaceMeshSettings::snap_cells = 0.15 (and + sharpen);
//   + repair:   the sharpening with the product's sliver repair (FeatureSettings::sliver_angle_deg
//               = 10 and its fallback, sliver_fallback_deviation_cells = 0.2), on the default and
//               on the snapped surface;
//   lattice:    MeshSurface with SurfaceMeshSettings::mesher = kLattice (body-centred cubic
//               lattice, vertices snapped onto the surface, no clean-up), also sharpened with
//               corner insertion and repaired (`spidarcad mesh --mesher lattice --sharp`).
// Solids: a sphere of radius 50 mm and a box 100 x 80 x 60 mm minus a cylinder of radius 20 mm
// (exact distances of the primitives, min/max of the boolean), both off the grid planes, and the
// platform of assets/scenes/platform.json (the 62 ms / 118 ms figure of the mesher's design
// note is its MeshSurface row at 4 mm). Columns: process CPU seconds (for dense MC: sampling +
// contouring), triangles, sampled two-sided Hausdorff distance (bench/surface_metrics.h: mesh to
// surface and surface to mesh, the larger), smallest triangle angle, triangles under 5° and
// 10°, closed-and-manifold with the Euler characteristic. A markdown table on stdout.
// (An app_ bench only because it links VTK through spidarcad_cli; it measures modeling code.)
// With --tetgen each row also gets TetrahedralizeSurface's figures on that surface (TetGen with
// its default radius-edge bound q = 2, the setting `spidarcad mesh --tets tetgen` uses): tets,
// worst (smallest and largest) dihedral angles, TetGen CPU seconds, or why the surface was refused;
// --tetgen-dihedral DEG also asks TetGen for dihedral angles of at least DEG (its `q`/DEG).
// --lattice-only prints dense MC and the lattice rows alone.
// Run: build/bench/app_surface_peers_bench [--quick] [--lattice-only] [--tetgen] [--tetgen-dihedral
// DEG]
//        [--only sphere|box-cylinder|platform] [--cells MM,MM,...]
// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#include <vtkCellArray.h>
#include <vtkDoubleArray.h>
#include <vtkFlyingEdges3D.h>
#include <vtkImageData.h>
#include <vtkNew.h>
#include <vtkPointData.h>
#include <vtkPolyData.h>

#include <cstdio>
#include <cstring>
#include <ctime>
#include <functional>
#include <sstream>
#include <string>
#include <vector>

#include "bench_paths.h"
#include "spidarcad/modeling/feature_sharpening.h"
#include "spidarcad/modeling/implicit_evaluator.h"
#include "spidarcad/modeling/scene_io.h"
#include "spidarcad/modeling/surface_mesher.h"
#include "spidarcad/modeling/tetgen_mesher.h"
#include "surface_metrics.h"

namespace {

using namespace spidarcad::modeling;
using spidarcad::bench::Vec;

struct Case {
  std::string name;
  CompiledSolid solid;
  Eigen::AlignedBox3d bounds;
  std::vector<double> cells;  // m
};

std::vector<Case> Cases() {
  std::vector<Case> c;
  const Vec offset(0.0013, -0.0021, 0.0007);
  c.push_back({"sphere",
               CompiledSolid::Compile(
                   ImplicitNode(TranslateParams{offset}, {ImplicitNode(SphereParams{0.05})})),
               Eigen::AlignedBox3d(offset - Vec::Constant(0.06), offset + Vec::Constant(0.06)),
               {0.004, 0.002, 0.001}});
  const Vec size(0.1, 0.08, 0.06);
  ImplicitNode holed(DifferenceParams{},
                     {ImplicitNode(BoxParams{size}), ImplicitNode(CylinderParams{0.02, 0.2})});
  c.push_back({"box-cylinder",
               CompiledSolid::Compile(ImplicitNode(TranslateParams{offset}, {holed})),
               Eigen::AlignedBox3d(offset - size / 2 - Vec(0.0107, 0.0113, 0.0109),
                                   offset + size / 2 + Vec::Constant(0.01)),
               {0.004, 0.002, 0.001}});
  const Scene scene = LoadScene(spidarcad::bench::RepoPath("assets/scenes/platform.json"));
  c.push_back({"platform",
               CompiledSolid::Compile(scene.solids.at(0).root),
               Eigen::AlignedBox3d(Vec(-0.01, -0.11, -0.16), Vec(0.31, 0.11, 0.02)),
               {0.008, 0.004}});
  return c;
}

double CpuSeconds() { return static_cast<double>(std::clock()) / CLOCKS_PER_SEC; }

// Dense marching cubes: samples the field at every vertex of the grid MeshSurface would use
// (same cell, same centring on the bounds) and contours it with vtkFlyingEdges3D.
TriangleMesh DenseMarchingCubes(const CompiledSolid& solid, const Eigen::AlignedBox3d& bounds,
                                double cell, double* sample_s, double* contour_s) {
  const double t0 = CpuSeconds();
  int n[3];
  for (int a = 0; a < 3; ++a)
    n[a] = std::max(1, static_cast<int>(std::ceil(bounds.sizes()[a] / cell - 1e-9)));
  const Vec origin = bounds.center() - 0.5 * cell * Vec(n[0], n[1], n[2]);
  const long nx = n[0] + 1, ny = n[1] + 1, nz = n[2] + 1;
  vtkNew<vtkDoubleArray> values;
  values->SetNumberOfTuples(nx * ny * nz);
  Eigen::Matrix3Xd slab(3, nx * ny);
  Eigen::VectorXd slab_values(nx * ny);
  for (long k = 0; k < nz; ++k) {
    for (long j = 0; j < ny; ++j)
      for (long i = 0; i < nx; ++i)
        slab.col(i + nx * j) = origin + cell * Vec(double(i), double(j), double(k));
    solid.Values(slab, slab_values);
    // Values on the bounds count as outside so that the contour closes there (as MeshSurface).
    for (long j = 0; j < ny; ++j)
      for (long i = 0; i < nx; ++i) {
        double f = slab_values[i + nx * j];
        if (i == 0 || j == 0 || k == 0 || i == nx - 1 || j == ny - 1 || k == nz - 1)
          f = std::max(f, 1e-12);
        values->SetValue(i + nx * (j + ny * k), f);
      }
  }
  vtkNew<vtkImageData> image;
  image->SetDimensions(static_cast<int>(nx), static_cast<int>(ny), static_cast<int>(nz));
  image->SetOrigin(origin.x(), origin.y(), origin.z());
  image->SetSpacing(cell, cell, cell);
  values->SetName("f");
  image->GetPointData()->SetScalars(values);
  const double t1 = CpuSeconds();
  vtkNew<vtkFlyingEdges3D> contour;
  contour->SetInputData(image);
  contour->SetValue(0, 0.0);
  contour->ComputeNormalsOff();
  contour->ComputeGradientsOff();
  contour->ComputeScalarsOff();
  contour->Update();
  vtkPolyData* out = contour->GetOutput();
  const double t2 = CpuSeconds();
  TriangleMesh mesh;
  mesh.vertices.resize(3, out->GetNumberOfPoints());
  for (vtkIdType i = 0; i < out->GetNumberOfPoints(); ++i) {
    double p[3];
    out->GetPoint(i, p);
    mesh.vertices.col(i) = Vec(p[0], p[1], p[2]);
  }
  vtkCellArray* polys = out->GetPolys();
  mesh.triangles.resize(3, polys->GetNumberOfCells());
  vtkIdType count = 0;
  const vtkIdType* ids = nullptr;
  Eigen::Index t = 0;
  for (polys->InitTraversal(); polys->GetNextCell(count, ids);) {
    if (count != 3) continue;
    for (int k = 0; k < 3; ++k) mesh.triangles(k, t) = static_cast<int>(ids[k]);
    ++t;
  }
  mesh.triangles.conservativeResize(3, t);
  *sample_s = t1 - t0;
  *contour_s = t2 - t1;
  return mesh;
}

// TetGen's figures on `surface` as table cells: tets, min and max dihedral angle, seconds.
// min_dihedral_deg: TetMeshSettings::min_dihedral_deg (0: TetGen's default, no bound). A surface
// whose triangles face inward (VTK's contour of a field negative inside) is turned over first.
std::string TetgenCells(TriangleMesh surface, double min_dihedral_deg) {
  char text[160];
  try {
    if (MeshVolume(surface) < 0.0) surface.triangles.row(1).swap(surface.triangles.row(2));
    TetMeshSettings settings;
    settings.min_dihedral_deg = min_dihedral_deg;
    TetMeshStats stats;
    const double t0 = CpuSeconds();
    const TetMesh tets = TetrahedralizeSurface(surface, settings, &stats);
    std::snprintf(text, sizeof text, " %ld | %.2f | %.1f | %.2f |",
                  static_cast<long>(tets.tets.cols()), stats.quality.min_dihedral_deg,
                  stats.quality.max_dihedral_deg, CpuSeconds() - t0);
  } catch (const std::exception& e) {
    std::snprintf(text, sizeof text, " refused: %.60s | | | |", e.what());
  }
  return text;
}

void PrintRow(const Case& c, double cell, const std::string& method, double seconds,
              const std::string& time_note, const TriangleMesh& mesh,
              const std::vector<Vec>& samples, bool tetgen, double min_dihedral_deg) {
  const spidarcad::bench::HausdorffError e =
      spidarcad::bench::MeasureHausdorff(c.solid, samples, mesh, cell);
  const TriangleAngleStats a5 = MeasureTriangleAngles(mesh, 5.0);
  const TriangleAngleStats a10 = MeasureTriangleAngles(mesh, 10.0);
  long euler = 0;
  const bool manifold = spidarcad::bench::IsClosedManifold(mesh, &euler);
  std::printf("| %s | %g | %s | %.3f%s | %ld | %.4f | %.4f | %.4f | %.3f | %ld | %ld | %s |%s\n",
              c.name.c_str(), cell * 1e3, method.c_str(), seconds, time_note.c_str(),
              static_cast<long>(mesh.triangles.cols()), e.out_max * 1e3, e.in_max * 1e3,
              e.TwoSided() * 1e3, a5.min_angle_deg, a5.small_angle, a10.small_angle,
              manifold ? ("yes, χ " + std::to_string(euler)).c_str() : "no",
              tetgen ? TetgenCells(mesh, min_dihedral_deg).c_str() : "");
  std::fflush(stdout);
}

}  // namespace

int main(int argc, char** argv) {
  bool quick = false, tetgen = false, lattice_only = false;
  double min_dihedral_deg = 0.0;
  std::string only;
  std::vector<double> cells;
  for (int i = 1; i < argc; ++i) {
    if (std::strcmp(argv[i], "--quick") == 0) {
      quick = true;
    } else if (std::strcmp(argv[i], "--lattice-only") == 0) {
      lattice_only = true;
    } else if (std::strcmp(argv[i], "--tetgen") == 0) {
      tetgen = true;
    } else if (std::strcmp(argv[i], "--tetgen-dihedral") == 0 && i + 1 < argc) {
      tetgen = true;
      min_dihedral_deg = std::stod(argv[++i]);
    } else if (std::strcmp(argv[i], "--only") == 0 && i + 1 < argc) {
      only = argv[++i];
    } else if (std::strcmp(argv[i], "--cells") == 0 && i + 1 < argc) {
      std::stringstream list(argv[++i]);
      std::string item;
      while (std::getline(list, item, ',')) cells.push_back(std::stod(item) * 1e-3);
    } else {
      std::fprintf(stderr,
                   "usage: %s [--quick] [--lattice-only] [--tetgen] [--tetgen-dihedral DEG] "
                   "[--only sphere|box-cylinder|platform] "
                   "[--cells MM,...]\n"
                   "MeshSurface (raw, default, sharpened) against dense marching cubes (VTK "
                   "flying edges) on the same fields; a markdown table.\n",
                   argv[0]);
      return std::strcmp(argv[i], "--help") == 0 ? 0 : 2;
    }
  }
  std::printf(
      "| solid | cell mm | method | CPU s | triangles | mesh→surface mm | surface→mesh mm | "
      "Hausdorff mm | min angle ° | < 5° | < 10° | closed manifold |%s\n"
      "|---|---|---|---|---|---|---|---|---|---|---|---|%s\n",
      tetgen ? " tets | min dihedral ° | max dihedral ° | TetGen CPU s |" : "",
      tetgen ? "---|---|---|---|" : "");
  for (const Case& c : Cases()) {
    if (!only.empty() && c.name != only) continue;
    const std::vector<Vec> samples = spidarcad::bench::SurfaceSamples(c.solid, c.bounds);
    std::vector<double> sizes = cells.empty() ? c.cells : cells;
    if (quick) sizes = {sizes.front()};
    for (double cell : sizes) {
      double sample_s = 0, contour_s = 0;
      const TriangleMesh mc = DenseMarchingCubes(c.solid, c.bounds, cell, &sample_s, &contour_s);
      char note[64];
      std::snprintf(note, sizeof note, " (%.3f + %.3f)", sample_s, contour_s);
      PrintRow(c, cell, "dense MC", sample_s + contour_s, note, mc, samples, tetgen,
               min_dihedral_deg);
      SurfaceMeshSettings settings;
      settings.bounds = c.bounds;
      settings.cell_size = cell;
      // raw, default, default + sharpen, snap 0.15, snap 0.15 + sharpen, and the two sharpened
      // ones with the sliver repair.
      const char* names[] = {"raw",
                             "MeshSurface",
                             "+ sharpen",
                             "snap 0.15",
                             "snap 0.15 + sharpen",
                             "+ sharpen + repair",
                             "snap 0.15 + sharpen + repair",
                             "lattice",
                             "lattice + sharpen + corners + repair"};
      for (int variant = 0; variant < 9; ++variant) {
        if (lattice_only && variant < 7) continue;
        settings.clean = variant != 0;
        settings.snap_cells = variant == 3 || variant == 4 || variant == 6 ? 0.15 : 0.0;
        settings.mesher =
            variant >= 7 ? SurfaceMesher::kLattice : SurfaceMesher::kMarchingTetrahedra;
        const bool sharpen = variant == 2 || (variant >= 4 && variant != 7);
        const double t0 = CpuSeconds();
        TriangleMesh mesh = MeshSurface(c.solid, settings);
        const double t1 = CpuSeconds();
        double sharpen_s = 0;
        if (sharpen) {
          FeatureSettings f;
          f.cell_size = cell;
          if (variant == 5 || variant == 6 || variant == 8) {
            f.sliver_angle_deg = kProductSliverAngleDeg;
            f.sliver_fallback_deviation_cells = kProductSliverFallbackCells;
          }
          f.insert_corners = variant == 8;
          mesh = SharpenFeatures(c.solid, std::move(mesh), f);
          sharpen_s = CpuSeconds() - t1;
        }
        char split[64] = "";
        if (sharpen) std::snprintf(split, sizeof split, " (%.3f + %.3f)", t1 - t0, sharpen_s);
        // TetGen on the raw surface takes minutes (1.3 M tets for the sphere at 2 mm): left out.
        PrintRow(c, cell, names[variant], t1 - t0 + sharpen_s, split, mesh, samples,
                 tetgen && variant != 0, min_dihedral_deg);
      }
    }
  }
  return 0;
}
