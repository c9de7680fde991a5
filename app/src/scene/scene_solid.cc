// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#include "scene/scene_solid.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <exception>

#include "doc/input_error.h"
#include "doc/number_format.h"
#include "spidarcad/modeling/scene_io.h"
#include "spidarcad/modeling/surface_mesher.h"

namespace spidarcad::app {

namespace {
// Half-side of the box searched for the solid, m: anything reaching it is taken as unbounded.
constexpr double kSearchHalfSide = 10.0;
}  // namespace

SceneSolidGrid PrepareSceneSolid(const std::string& scene_path, const std::string& solid_name,
                                 double resolution, double cells_across, double max_grid_cells,
                                 const std::string& cells_option) {
  modeling::Scene scene;
  try {
    scene = modeling::LoadScene(scene_path);
  } catch (const modeling::SceneError& e) {
    throw InputError(e.what());
  }
  if (scene.solids.empty()) throw InputError(scene_path + ": the scene has no solids");
  const modeling::Solid* solid = &scene.solids.front();
  if (!solid_name.empty()) {
    solid = nullptr;
    std::string names;
    for (const modeling::Solid& s : scene.solids) {
      if (s.name == solid_name) solid = &s;
      names += (names.empty() ? "" : ", ") + ("'" + s.name + "'");
    }
    if (solid == nullptr) {
      throw InputError("--solid '" + solid_name + "': no such solid in " + scene_path +
                       " (it has " + names + ")");
    }
  }
  SceneSolidGrid grid;
  grid.solid_name = solid->name;
  try {
    grid.compiled = modeling::CompiledSolid::Compile(
        solid->root, "/solids/" + std::to_string(solid - scene.solids.data()) + "/root");
  } catch (const std::exception& e) {
    throw InputError(scene_path + ": solid '" + solid->name + "': " + e.what());
  }

  // Where the solid is: a coarse search, then the box on the meshing grid.
  const Eigen::AlignedBox3d search(Eigen::Vector3d::Constant(-kSearchHalfSide),
                                   Eigen::Vector3d::Constant(kSearchHalfSide));
  const double coarse = resolution > 0.0 ? std::max(resolution, 0.005) : 0.01;
  const Eigen::AlignedBox3d rough = modeling::FindBounds(grid.compiled, search, coarse);
  if (rough.isEmpty()) {
    throw InputError(scene_path + ": solid '" + solid->name +
                     "' is empty (nothing inside the search box)");
  }
  for (int a = 0; a < 3; ++a) {
    if (rough.min()[a] <= -kSearchHalfSide + coarse || rough.max()[a] >= kSearchHalfSide - coarse) {
      throw InputError(
          scene_path + ": solid '" + solid->name + "' reaches the " +
          FormatNumber(2 * kSearchHalfSide) +
          " m search box (unbounded, e.g. a bare half-space): intersect it with a box");
    }
  }
  grid.cell = resolution > 0.0 ? resolution : rough.sizes().maxCoeff() / cells_across;
  // The grid over the coarse box (padded as below) bounds the fine grid's: refuse before the
  // fine search, which costs about as much as meshing.
  double cells = 1.0;
  for (int a = 0; a < 3; ++a) cells *= std::max(1.0, std::ceil(rough.sizes()[a] / grid.cell + 4.0));
  if (!(cells <= max_grid_cells)) {
    char figures[160];
    std::snprintf(figures, sizeof figures,
                  "%.3g x %.3g x %.3g m box at %.3g m cells is %.3g grid cells", rough.sizes().x(),
                  rough.sizes().y(), rough.sizes().z(), grid.cell, cells);
    char limit[32];
    std::snprintf(limit, sizeof limit, "%.6g", max_grid_cells);
    const double suggested = std::cbrt(cells / max_grid_cells) * grid.cell;
    char coarser[32];
    std::snprintf(coarser, sizeof coarser, "%.3g", suggested);
    throw InputError(
        "--resolution " + FormatNumber(grid.cell) + ": solid '" + solid->name + "' of " +
        scene_path + ": the " + figures + ", more than the limit of " + limit +
        " (docs/limits.md); use a coarser --resolution (about " + coarser + " m fits)" +
        (cells_option.empty() ? std::string("") : " or raise the limit with " + cells_option));
  }
  grid.bounds = modeling::FindBounds(grid.compiled, rough, grid.cell);
  grid.bounds.min().array() -= 2.0 * grid.cell;
  grid.bounds.max().array() += 2.0 * grid.cell;
  return grid;
}

}  // namespace spidarcad::app
