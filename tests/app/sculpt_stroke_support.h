// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
// Sculpts for the slab tests (slab_fe_mesh_test.cc, fe_setup_test.cc, fe_mode_test.cc): the
// platform's grid surface as a sculpt made from the solid holds it, and one stroke at full
// strength. Header-only: tests/app globs only *_test.cc files.
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>

#include "scene/fe_model.h"
#include "scene/scene_solid.h"
#include "spidarcad/modeling/sculpt.h"
#include "spidarcad/modeling/surface_mesher.h"

namespace spidarcad::test_support {

// The platform's grid surface at `cell` (m), snapped as the product meshes.
inline modeling::TriangleMesh PlatformGridSurface(double cell) {
  const app::SceneSolidGrid grid =
      app::PrepareSceneSolid(app::PlatformScenePath(), "platform", cell);
  modeling::SurfaceMeshSettings ss;
  ss.bounds = grid.bounds;
  ss.cell_size = cell;
  ss.snap_cells = modeling::kProductSnapCells;
  return modeling::MeshSurface(grid.compiled, ss);
}

// One stroke of `tool` at full strength, no refinement, radius 15 mm, the grip at `at` (m, W)
// moved by `move` (m); returns the edit.
inline modeling::SculptEdit Stroke(modeling::SculptMesh* clay, modeling::SculptTool tool,
                                   const Eigen::Vector3d& at, const Eigen::Vector3d& move) {
  modeling::SculptToolSettings settings;
  settings.tool = tool;
  settings.radius = 0.015;
  settings.grasp_controls_strength = false;
  Eigen::Isometry3d X = Eigen::Isometry3d::Identity();
  X.translation() = at;
  clay->BeginStroke(settings, X, 0.0);
  X.translation() += move;
  clay->UpdateStroke(X, 0.0);
  return clay->EndStroke();
}

}  // namespace spidarcad::test_support
