// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
// The assembly scene (issue 5): builds a haptics::AssemblyField from a scene file's "parts"
// (docs/scene-format.md): each part's solid is compiled, seen through SolidDistanceField in the
// part's own frame P, and given a point shell sampled from a MeshSurface of the solid.
//
// Part i of the field is scene.parts[i]; seats name their other part by index. Fixed parts get
// no shell (they never move, so only the carried part's shell is tested against them).
#pragma once

#include <memory>
#include <string>
#include <vector>

#include "spidarcad/haptics/assembly_field.h"
#include "spidarcad/haptics/point_shell_field.h"
#include "spidarcad/modeling/implicit_evaluator.h"
#include "spidarcad/modeling/scene_io.h"

namespace spidarcad::app {

// How an assembly scene becomes a field. SI units.
struct AssemblySceneSettings {
  double shell_spacing =
      0.0035;                  // surface sampling cell, m (about the spacing of shell points;
                               // 3.5 mm: the leg has ~330 points, carrying ticks stay near 100 µs)
  double tool_radius = 0.003;  // the bare tool's sphere shell radius, m (0: no tool shell)
  int tool_points = 40;        // points on that sphere
  double search_half_extent =
      0.5;  // parts are looked for in a cube of this half side about P's origin, m
  double specialization_cell = 0.005;  // cell of the per-cell pruned tapes of each part's field
                                       // (modeling::CellSpecializedSolid), m; 0: the full tape only
  haptics::AssemblySettings field;     // the field's parameters
};

// A point shell sampled on the surface of `solid` (in the solid's frame): the vertices of a
// MeshSurface with cells of `spacing`, with inward unit normals −∇φ/|∇φ|. Throws
// std::invalid_argument when the solid is empty inside the search cube or spacing <= 0.
haptics::PointShell SampleSurfaceShell(const modeling::CompiledSolid& solid, double spacing,
                                       double search_half_extent = 0.5);

// The pose X_WP of a scene part (or X_OS of a seat): translation and rotation.
Eigen::Isometry3d PartPose(const Eigen::Vector3d& position, const Eigen::Quaterniond& rotation);

// An AssemblyField for the scene's parts. Throws std::invalid_argument when the scene has no
// parts, more than haptics::kMaxAssemblyParts, or a part's solid cannot be compiled or sampled
// (the message names the part).
std::unique_ptr<haptics::AssemblyField> BuildAssemblyField(
    const modeling::Scene& scene, const AssemblySceneSettings& settings = {});

// One line for stdout, shared by the window (AssemblyMode) and `spidarcad run`:
// "assembly: 1 of 5 parts seated (right_leg), carried: none\n". Part i is named names[i] and is
// fixed when fixed[i] (fixed parts are neither counted nor listed); `state` is a state the field
// published. While state.count != names.size() (nothing published yet) no part is seated or
// carried. names and fixed must have the same size.
std::string FormatAssemblySummary(const std::vector<std::string>& names,
                                  const std::vector<bool>& fixed,
                                  const haptics::AssemblyState& state);
// The same for the parts of `field` (their names and fixed flags).
std::string FormatAssemblySummary(const haptics::AssemblyField& field,
                                  const haptics::AssemblyState& state);

}  // namespace spidarcad::app
