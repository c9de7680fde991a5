// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#include "scene/scene_solid.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <exception>
#include <variant>

#include "doc/document.h"
#include "doc/input_error.h"
#include "doc/number_format.h"
#include "scene/document_file.h"
#include "spidarcad/modeling/scene_io.h"
#include "spidarcad/modeling/surface_mesher.h"

namespace spidarcad::app {

namespace {
// Half-side of the box searched for the solid, m: anything reaching it is taken as unbounded.
constexpr double kSearchHalfSide = 10.0;
}  // namespace

const DocObject& PickSolid(const OpenedDocument& opened, const std::string& solid_name,
                           const std::string& option) {
  const Document& doc = *opened.doc;
  const std::string& path = opened.path;
  const DocObject* first = nullptr;
  for (const DocObject& o : doc.objects()) {
    if (std::holds_alternative<SolidData>(o.data)) {
      first = &o;
      break;
    }
  }
  if (first == nullptr) {
    if (opened.version == 1) throw InputError(path + ": the scene has no solids");
    throw InputError(path + ": the document has no solid (its objects: " + ObjectNames(doc, {}) +
                     ")");
  }
  if (solid_name.empty()) return *first;
  const std::string solids = ObjectNames(doc, {"solid"});
  for (const DocObject& o : doc.objects()) {
    if (o.name != solid_name) continue;
    if (std::holds_alternative<SolidData>(o.data)) return o;
    throw InputError(option + " '" + solid_name + "': in " + path + " that is a " +
                     ObjectKindName(o.data) + " object, not a solid (its solids: " + solids + ")");
  }
  throw InputError(option + " '" + solid_name + "': no such solid in " + path + " (it has " +
                   solids + ")");
}

SceneSolidGrid PrepareSceneSolid(const std::string& scene_path, const std::string& solid_name,
                                 double resolution, double cells_across, double max_grid_cells,
                                 const std::string& cells_option) {
  const OpenedDocument opened = OpenDocumentFile(scene_path);
  return PrepareDocumentSolid(opened, solid_name, "--solid", resolution, cells_across,
                              max_grid_cells, cells_option);
}

SceneSolidGrid PrepareDocumentSolid(const OpenedDocument& opened, const std::string& solid_name,
                                    const std::string& option, double resolution,
                                    double cells_across, double max_grid_cells,
                                    const std::string& cells_option) {
  const std::string& scene_path = opened.path;
  const DocObject& object = PickSolid(opened, solid_name, option);
  const std::string& name = object.name;
  const modeling::ImplicitNode& root = std::get<SolidData>(object.data).root;
  SceneSolidGrid grid;
  grid.solid_name = name;
  grid.object = object.id;
  try {
    grid.compiled =
        modeling::CompiledSolid::Compile(root, ObjectPointer(opened, object.id) + "/root");
  } catch (const std::exception& e) {
    throw InputError(scene_path + ": solid '" + name + "': " + e.what());
  }

  // Where the solid is: a coarse search, then the box on the meshing grid.
  const Eigen::AlignedBox3d search(Eigen::Vector3d::Constant(-kSearchHalfSide),
                                   Eigen::Vector3d::Constant(kSearchHalfSide));
  const double coarse = resolution > 0.0 ? std::max(resolution, 0.005) : 0.01;
  const Eigen::AlignedBox3d rough = modeling::FindBounds(grid.compiled, search, coarse);
  if (rough.isEmpty()) {
    throw InputError(scene_path + ": solid '" + name +
                     "' is empty (nothing inside the search box)");
  }
  for (int a = 0; a < 3; ++a) {
    if (rough.min()[a] <= -kSearchHalfSide + coarse || rough.max()[a] >= kSearchHalfSide - coarse) {
      throw InputError(
          scene_path + ": solid '" + name + "' reaches the " + FormatNumber(2 * kSearchHalfSide) +
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
        "--resolution " + FormatNumber(grid.cell) + ": solid '" + name + "' of " + scene_path +
        ": the " + figures + ", more than the limit of " + limit +
        " (docs/limits.md); use a coarser --resolution (about " + coarser + " m fits)" +
        (cells_option.empty() ? std::string("") : " or raise the limit with " + cells_option));
  }
  grid.bounds = modeling::FindBounds(grid.compiled, rough, grid.cell);
  grid.bounds.min().array() -= 2.0 * grid.cell;
  grid.bounds.max().array() += 2.0 * grid.cell;
  return grid;
}

}  // namespace spidarcad::app
