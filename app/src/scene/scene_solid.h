// One solid of a scene file, compiled and located, ready to mesh: shared by `spidarcad mesh`
// and `spidarcad fem`.
// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#pragma once

#include <Eigen/Geometry>
#include <cstdint>
#include <string>

#include "spidarcad/modeling/implicit_evaluator.h"

namespace spidarcad::app {

struct DocObject;       // doc/document.h
struct OpenedDocument;  // scene/document_file.h

// A compiled solid with the grid it will be meshed on.
struct SceneSolidGrid {
  std::string solid_name;            // the solid's name in the scene
  std::uint64_t object = 0;          // its object's id (ObjectId) in the document
  modeling::CompiledSolid compiled;  // its evaluator
  Eigen::AlignedBox3d bounds;        // grid box in m, the solid's box padded by two cells
  double cell = 0.0;                 // grid cell size, m
};

// Grid cells PrepareSceneSolid allows by default: MeshSurface's own ceiling, 2^30.
inline constexpr double kDefaultMaxGridCells = 1073741824.0;

// Loads `scene_path`, picks the solid named `solid_name` (empty: the first), compiles it and
// finds its box on a grid of `resolution` m (<= 0: the solid's largest side / `cells_across`).
// Throws InputError naming the file, the solid or the option when the scene does not load, the
// solid is missing, empty or unbounded (reaches 10 m from the origin), or when the grid over
// the solid's coarse box would have more than `max_grid_cells` cells (checked before the fine
// search for the box, whose cost grows with the grid); `cells_option` names the option that
// raises that limit in the message (empty: none).
// Version 2 documents are read as well (OpenDocumentFile); `solid_name` is then looked up with
// the option name "--solid" in messages.
SceneSolidGrid PrepareSceneSolid(const std::string& scene_path, const std::string& solid_name,
                                 double resolution, double cells_across = 80.0,
                                 double max_grid_cells = kDefaultMaxGridCells,
                                 const std::string& cells_option = "");

// The solid object of an opened file named `solid_name` (empty: the first solid). Throws
// InputError naming `option` (e.g. "--object"), the file and the solids it has when there is no
// such solid, or when the name is an object of another kind (saying which).
const DocObject& PickSolid(const OpenedDocument& opened, const std::string& solid_name,
                           const std::string& option);

// PrepareSceneSolid for an already opened file: the solid PickSolid finds, compiled and located.
SceneSolidGrid PrepareDocumentSolid(const OpenedDocument& opened, const std::string& solid_name,
                                    const std::string& option, double resolution,
                                    double cells_across = 80.0,
                                    double max_grid_cells = kDefaultMaxGridCells,
                                    const std::string& cells_option = "");

}  // namespace spidarcad::app
