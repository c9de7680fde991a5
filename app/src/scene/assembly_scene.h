// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
// The assembly scene (issue 5): builds a haptics::AssemblyField from a scene file's "parts"
// (docs/scene-format.md): each part's solid is compiled, seen through SolidDistanceField in the
// part's own frame P, and given a point shell sampled from a MeshSurface of the solid.
//
// Part i of the field is scene.parts[i]; seats name their other part by index. Fixed parts get
// no shell (they never move, so only the carried part's shell is tested against them).
#pragma once

#include <Eigen/Geometry>
#include <map>
#include <memory>
#include <string>
#include <vector>

#include "doc/document.h"
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

// One part of an assembly as the field builder takes it: from a version 1 scene's "parts" or from
// a Document's rigid_part objects.
struct AssemblyPartInput {
  std::string name;                                        // part name (seats name parts by it)
  std::string solid;                                       // what the solid is called in errors
  const modeling::ImplicitNode* root = nullptr;            // the solid's tree in P (not null)
  Eigen::Isometry3d X_WP = Eigen::Isometry3d::Identity();  // pose, m (W from P)
  bool fixed = false;                                      // never grasped
  std::vector<modeling::SceneSeat> seats;                  // seats on other parts (by name)
};

// The compiled geometry (distance field and point shell) of the part solids of the latest build,
// keyed by the tree's JSON text and the settings that shape it, so that a rebuild after a pose
// change or an undo compiles and samples only the trees that changed. Main thread only.
class AssemblyGeometryCache {
 public:
  // Trees whose geometry is held.
  int size() const { return static_cast<int>(entries_.size()); }
  // Trees compiled by the latest build (not found in the cache).
  int compiled_last() const { return compiled_last_; }

 private:
  friend std::unique_ptr<haptics::AssemblyField> BuildAssemblyField(
      const std::vector<AssemblyPartInput>& parts, const AssemblySceneSettings& settings,
      AssemblyGeometryCache* cache);
  struct Entry;
  std::map<std::string, std::shared_ptr<Entry>> entries_;
  int compiled_last_ = 0;
};

// An AssemblyField for `parts` (part i of the field is parts[i]; seats name their other part by
// name). Parts whose trees are equal share one compiled solid and shell. `cache` (may be null)
// supplies the geometry of trees built before and keeps that of this build. Throws
// std::invalid_argument naming the part and solid like the scene overload; the cache is then
// unchanged.
std::unique_ptr<haptics::AssemblyField> BuildAssemblyField(
    const std::vector<AssemblyPartInput>& parts, const AssemblySceneSettings& settings,
    AssemblyGeometryCache* cache);

// The parts of a version 1 scene as field input (root: the named solid's tree, pointing into
// `scene`; null when the scene has no such solid, which BuildAssemblyField reports; X_WP =
// PartPose(position, rotation)).
std::vector<AssemblyPartInput> ScenePartInputs(const modeling::Scene& scene);

// The rigid_part objects of `doc` as field input, in document order (name: the object's name,
// root: its tree, pointing into doc, valid until doc changes). `ids` (may be null) receives each
// part's object id.
std::vector<AssemblyPartInput> RigidPartInputs(const Document& doc, std::vector<ObjectId>* ids);

// Turns the version 1 assembly parts of `doc` (Document::parts(): parts made of named solids,
// e.g. assets/scenes/assembly.json) into rigid_part objects, so that part poses are document
// content that commands change and undo: each part becomes a rigid_part named after it with a
// copy of its solid's tree (node ids of a second copy get "_<part>" appended), its pose
// X_WP = PartPose(position, rotation), fixed flag and seats; the solids that only parts used are
// removed; every other object stays, in order. The content is replaced as a file load does
// (fresh ids, empty history, clean) and the file path is kept. Returns false, changing nothing,
// when the document has no such parts. Throws modeling::SceneError (the document unchanged)
// when the result does not validate.
bool AdoptScenePartsAsRigidParts(Document* doc);

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
