// TetGen path vs CGAL path on the same solids, printed as a markdown table for the README:
//   TetGen: MeshSurface (marching tetrahedra, cell h) + TetrahedralizeSurface (q = 2),
//   CGAL:   MeshImplicitWithCgal (Mesh_3 from the function, CgalMeshSettings::ForSize(h),
//           radius-edge 2, perturb + exude).
// Solids: a sphere (r 50 mm), a box with a hole (100 x 60 x 40 mm minus a 12 mm radius bore:
// sharp edges) and the platform of assets/scenes/platform.json, each at three sizes h. Columns:
// CPU and wall time, nodes, tets, worst (smallest and largest) dihedral angle, surface error (max
// and rms of |f| sampled on the tet mesh's boundary: vertices, edge midpoints, centroids) and the
// volume (relative error against the closed form where there is one). One run each; a failure
// is printed in its row. Whole run: about a minute on the 2-core machine. Run:
//   build-dir/bench/modeling_mesh_compare_bench [--quick]   (--help: what it measures)
// (--quick: the coarsest size only.) Any other argument is an error (exit status 2).
// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <ctime>
#include <exception>
#include <functional>
#include <string>
#include <vector>

#include "bench_paths.h"
#include "spidarcad/modeling/cgal_mesher.h"
#include "spidarcad/modeling/implicit_evaluator.h"
#include "spidarcad/modeling/scene_io.h"
#include "spidarcad/modeling/surface_mesher.h"
#include "spidarcad/modeling/tet_mesh.h"
#include "spidarcad/modeling/tetgen_mesher.h"

namespace {

using namespace spidarcad::modeling;

struct Case {
  std::string name;
  CompiledSolid solid;
  Eigen::AlignedBox3d bounds;
  double exact_volume;  // m³, 0: no closed form
  std::vector<double> sizes;
};

struct Row {
  double seconds = 0.0;      // wall
  double cpu_seconds = 0.0;  // process CPU time (the machine may be shared: wall time varies)
  long nodes = 0, tets = 0;
  TetQuality quality;
  SurfaceError error;
  std::string failure;
};

Row Measure(const CompiledSolid& solid, const std::function<TetMesh()>& mesh) {
  Row row;
  try {
    const auto start = std::chrono::steady_clock::now();
    const std::clock_t cpu_start = std::clock();
    const TetMesh tets = mesh();
    row.cpu_seconds = static_cast<double>(std::clock() - cpu_start) / CLOCKS_PER_SEC;
    row.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    row.nodes = tets.nodes.cols();
    row.tets = tets.tets.cols();
    row.quality = MeasureTetQuality(tets);
    row.error = MeasureSurfaceError(solid, BoundarySurface(tets));
  } catch (const std::exception& e) {
    row.failure = e.what();
    if (row.failure.size() > 90) row.failure = row.failure.substr(0, 90) + "...";
  }
  return row;
}

void Print(const Case& c, double h, const char* path, const Row& r) {
  if (!r.failure.empty()) {
    std::printf("| %s | %.1f | %s | failed: %s | | | | | | |\n", c.name.c_str(), h * 1e3, path,
                r.failure.c_str());
    return;
  }
  char volume[64];
  if (c.exact_volume > 0) {
    std::snprintf(volume, sizeof volume, "%+.2f %%",
                  100.0 * (r.quality.total_volume - c.exact_volume) / c.exact_volume);
  } else {
    std::snprintf(volume, sizeof volume, "%.2f cm³", r.quality.total_volume * 1e6);
  }
  std::printf("| %s | %.1f | %s | %.2f | %.2f | %ld | %ld | %.1f / %.1f | %.3f / %.3f | %s |\n",
              c.name.c_str(), h * 1e3, path, r.cpu_seconds, r.seconds, r.nodes, r.tets,
              r.quality.min_dihedral_deg, r.quality.max_dihedral_deg, r.error.max * 1e3,
              r.error.rms * 1e3, volume);
  std::fflush(stdout);
}

// What this program measures (its --help).
constexpr const char* kDescription =
    "TetGen path vs CGAL path on the same solids, printed as a markdown table for the README:\n"
    "  TetGen: MeshSurface (marching tetrahedra, cell h) + TetrahedralizeSurface (q = 2),\n"
    "  CGAL:   MeshImplicitWithCgal (Mesh_3 from the function, CgalMeshSettings::ForSize(h),\n"
    "          radius-edge 2, perturb + exude).\n"
    "Solids: a sphere (r 50 mm), a box with a hole (100 x 60 x 40 mm minus a 12 mm radius bore:\n"
    "sharp edges) and the platform of assets/scenes/platform.json, each at three sizes h. "
    "Columns:\n"
    "CPU and wall time, nodes, tets, worst (smallest and largest) dihedral angle, surface error "
    "(max and\n"
    "rms of |f| sampled on the tet mesh's boundary: vertices, edge midpoints, centroids) and the\n"
    "volume (relative error against the closed form where there is one). One run each; a failure\n"
    "is printed in its row. Whole run: about a minute on the 2-core machine. Run:\n"
    "  build-dir/bench/modeling_mesh_compare_bench [--quick]   (--help: what it measures)\n"
    "(--quick: the coarsest size only.) Any other argument is an error (exit status 2).\n"
    "\n"
    "Options:\n"
    "  --quick   the coarsest size of each solid only\n"
    "  --help    this text\n"
    "This program is not a Google Benchmark: --benchmark_* flags are not taken.";

}  // namespace

int main(int argc, char** argv) {
  bool quick = false;
  for (int i = 1; i < argc; ++i) {
    if (std::strcmp(argv[i], "--help") == 0 || std::strcmp(argv[i], "-h") == 0) {
      std::printf("%s\n", kDescription);
      return 0;
    }
    if (std::strcmp(argv[i], "--quick") == 0) {
      quick = true;
      continue;
    }
    std::fprintf(stderr, "%s: unknown argument '%s' (this program takes --quick and --help)\n",
                 argv[0], argv[i]);
    return 2;
  }
  std::vector<Case> cases;
  {
    const double r = 0.05;
    cases.push_back(
        {"sphere r 50 mm",
         CompiledSolid::Compile(ImplicitNode(SphereParams{r})),
         Eigen::AlignedBox3d(Eigen::Vector3d::Constant(-0.06), Eigen::Vector3d::Constant(0.06)),
         4.0 / 3.0 * M_PI * r * r * r,
         {0.01, 0.006, 0.004}});
  }
  {
    const Eigen::Vector3d size(0.1, 0.06, 0.04);
    const double bore = 0.012;
    const ImplicitNode root(DifferenceParams{}, {ImplicitNode(BoxParams{size}),
                                                 ImplicitNode(CylinderParams{bore, 0.06})});
    cases.push_back({"box with bore",
                     CompiledSolid::Compile(root),
                     Eigen::AlignedBox3d(Eigen::Vector3d(-0.06, -0.04, -0.03),
                                         Eigen::Vector3d(0.06, 0.04, 0.03)),
                     size.prod() - M_PI * bore * bore * size.z(),
                     {0.008, 0.005, 0.0035}});
  }
  {
    const Scene scene = LoadScene(spidarcad::bench::RepoPath("assets/scenes/platform.json"));
    cases.push_back({"platform",
                     CompiledSolid::Compile(scene.solids[0].root),
                     Eigen::AlignedBox3d(Eigen::Vector3d(-0.01, -0.11, -0.16),
                                         Eigen::Vector3d(0.31, 0.11, 0.02)),
                     0.0,
                     {0.008, 0.006, 0.004}});
  }

  std::printf(
      "| solid | h (mm) | path | CPU (s) | wall (s) | nodes | tets | dihedral min / max (deg) | "
      "surface error max / rms (mm) | volume |\n");
  std::printf("|---|---|---|---|---|---|---|---|---|---|\n");
  for (const Case& c : cases) {
    for (const double h : c.sizes) {
      const Row tetgen = Measure(c.solid, [&] {
        SurfaceMeshSettings surface_settings;
        surface_settings.bounds = c.bounds;
        surface_settings.cell_size = h;
        const TriangleMesh surface = MeshSurface(c.solid, surface_settings);
        TetMeshSettings settings;
        settings.max_radius_edge = 2.0;
        return TetrahedralizeSurface(surface, settings);
      });
      Print(c, h, "TetGen", tetgen);
      const Row cgal = Measure(c.solid, [&] {
        CgalMeshSettings settings = CgalMeshSettings::ForSize(h);
        settings.cell_radius_edge_ratio = 2.0;
        return MeshImplicitWithCgal(c.solid, c.bounds, settings);
      });
      Print(c, h, "CGAL", cgal);
      if (quick) break;
    }
  }
  return 0;
}
