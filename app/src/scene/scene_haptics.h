// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
// Scene objects as haptic force fields: the adapter between a loaded scene (modeling::Scene, a
// list of implicit solids in metres, W) and the haptic loop's immutable HapticScene.
//
// Tool models (SceneHapticsOptions::tool):
//  - kProxy: each solid becomes one ProxyField (god-object on the solid's SolidDistanceField)
//    acting on the grip centre p_WT; the proxies add up.
//  - kShell: the grip as a rigid six-DOF tool: one PointShellField whose shell is the cross grip
//    (two capsules, poles ±d, radius shell_radius, both scaled into W), against the union of
//    every solid (min of the values); torques are felt.
// Snap (either tool model): when the scene has a "snap" object (modeling::SceneSnap), one more
// field, a haptics::SnapField on the vertices, edges and faces of the solids that lie on the
// scene's surface (scene/snap_features.h), pulls the grip centre toward the feature nearest
// it; radii in W, the force as felt. No field is added when no feature survives.
//
// Device workspace to scene, X_WD (haptics::DeviceToWorld): p_W = s·p_D + p_WDo, no rotation.
// Fit (when the options give no scale or origin): every solid's box is found with
// modeling::FindBounds (interval bounds, search box ±10 m; solids that reach it, such as a bare
// half-space, are unbounded and left out of the fit); the union box B of the bounded solids is
// mapped into the device's reachable cube, ±device_half_side (0.1 m) around the device origin,
// filling fit_fraction (0.8) of it along B's largest side:
//     s = max side of B / (2 · device_half_side · fit_fraction),   p_WDo = centre of B.
// So the scene's centre sits at the device origin and its largest side spans 160 mm of grip
// motion. Stiffness and damping in the options are what the hand feels at the grip (N/m of grip
// motion, N·s/m of grip velocity): the fields get k/s and b/s in world units, because the loop
// displays world forces unscaled (LoopSettings::force_scale = 1) while a grip displacement δ is
// a world displacement s·δ. Moments are displayed as computed in W (no length rescaling).
//
// BuildHapticScene = compile + fit X_WD + BuildSolidFields. The window (scene/scene_model.h) has
// its solids compiled already and its own X_WD (ChooseDeviceToWorld), and calls BuildSolidFields
// directly, so `run` and the window feel the same fields.
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <atomic>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "scene/snap_features.h"
#include "spidarcad/haptics/device_to_world.h"
#include "spidarcad/haptics/distance_field.h"
#include "spidarcad/haptics/haptic_loop.h"
#include "spidarcad/haptics/point_shell_field.h"
#include "spidarcad/haptics/proxy_field.h"
#include "spidarcad/haptics/snap_field.h"
#include "spidarcad/modeling/implicit_evaluator.h"
#include "spidarcad/modeling/scene_io.h"

namespace spidarcad::app {

// How the grip touches the scene.
enum class ToolModel {
  kProxy,  // a god-object point per solid (three DOF force)
  kShell,  // the cross grip as a point shell with virtual coupling (six DOF)
};

// "proxy" or "shell".
const char* ToolModelName(ToolModel model);

// Settings of BuildHapticScene. SI units; stiffness and damping as felt at the grip (device).
struct SceneHapticsOptions {
  ToolModel tool = ToolModel::kProxy;
  // Proxy: wall stiffness k [N/m] and normal damping b [N·s/m] at the grip; 1500 N/m and
  // 1 N·s/m are passive at 1 kHz with a hand's damping (see proxy_field.h).
  double stiffness = 1500.0;
  double damping = 1.0;
  // Proxy Coulomb friction, static μs >= dynamic μd >= 0.
  double static_friction = 0.3;
  double dynamic_friction = 0.2;
  // Shell: capsule radius of the grip's poles at the grip, m; points per ring, rings per pole.
  double shell_radius = 0.006;
  int shell_rings = 12;
  int shell_around = 8;
  // Shell: coupling stiffness at the grip [N/m] (the contact per point is the same value, see
  // point_shell_field.h), coupling damping [N·s/m].
  double coupling_stiffness = 1000.0;
  double coupling_damping = 3.0;
  // X_WD: the scale s and the world position of the device origin; each one not given is fitted.
  std::optional<double> world_scale;
  std::optional<Eigen::Vector3d> p_WDo;
  // The device's reachable cube, half side [m], and the fraction of it the scene fills.
  double device_half_side = 0.1;
  double fit_fraction = 0.8;
  // Box (W, m) of parts that other fields render (a document's FE parts) and that the fitted
  // map must hold beside the solids; empty (the default): none. With it, a scene of no solids is
  // allowed: its haptic scene is empty and its map is this box's.
  Eigen::AlignedBox3d extra_bounds_W;
  // Pole half-length d of the grip [m] (the device's geometry.d), for the shell.
  double grip_d = 0.04;
  // Snap features: how far off the scene's surface (m, W) a primitive's feature may lie and
  // still count as on it (see ExtractSnapFeatures).
  double snap_tolerance = 1e-5;
  // Throws std::invalid_argument naming the field and value when out of range.
  void Validate() const;
};

// The device-to-scene map chosen for a scene, and where it came from.
struct WorkspaceMap {
  haptics::DeviceToWorld X_WD;   // s (world metres per grip metre) and p_WDo (m)
  Eigen::AlignedBox3d bounds_W;  // union box of the bounded solids (may be empty)
  bool scale_fitted = false;     // s came from the fit
  bool origin_fitted = false;    // p_WDo came from the fit
};

// The map that puts `bounds_W` (non-empty) at the centre of the cube ±half_side, filling
// `fraction` of it along its largest side (see the file comment). Throws std::invalid_argument
// for an empty box or a non-positive half side or fraction.
WorkspaceMap FitWorkspace(const Eigen::AlignedBox3d& bounds_W, double half_side, double fraction);

// The box of a compiled solid (W, m): found on 1 cm cells inside a ±10 m search cube, then refined
// on cells of 1/64 of its largest side (at least 0.1 mm). Empty when the solid is empty, and
// empty with *unbounded set when it reaches the search cube (a half-space, say). Throws
// modeling::MeshingCancelled when `cancel` (may be null) is raised (modeling::FindBounds).
Eigen::AlignedBox3d SolidBounds(const modeling::CompiledSolid& solid, bool* unbounded,
                                const std::atomic<bool>* cancel = nullptr);

// One field of a built scene, for summaries.
struct FieldInfo {
  std::string kind;   // "proxy", "point_shell", "snap"
  std::string solid;  // the solid's name, "union of N solids", or (snap) the feature counts
};

// A HapticScene built from a scene, with the X_WD it was built for.
struct SceneHaptics {
  std::unique_ptr<haptics::HapticScene> scene;
  WorkspaceMap map;
  std::vector<FieldInfo> fields;
  // The snap features found (all zero when the scene has no "snap" or none survived).
  SnapFeatureCounts snap;
  // Copies map.X_WD into `settings` (the loop that renders the scene).
  void ApplyTo(haptics::LoopSettings* settings) const;
};

// One compiled solid of a scene, in W (metres), as BuildSolidFields takes it.
struct CompiledSceneSolid {
  std::string name;                                      // for summaries
  std::shared_ptr<const modeling::CompiledSolid> solid;  // not null
};

// The snap forces of a scene: its "snap" settings and the features found on its surface
// (ExtractSnapFeatures), both in W.
struct SnapInput {
  modeling::SceneSnap settings;
  haptics::SnapFeatures features;
};

// The force fields of a list of compiled solids, typed so that a caller may keep them (the window
// keeps them across republishes, scene/scene_model.h). Every pointer is owned here until moved out.
struct SolidFields {
  // Per input solid, in order: its SolidDistanceField (W).
  std::vector<std::shared_ptr<const haptics::DistanceField>> distance;
  // kProxy: one ProxyField per input solid, in order (empty for kShell).
  std::vector<std::unique_ptr<haptics::ProxyField>> proxies;
  // kShell: the point shell against the union of the solids (null for kProxy or no solids),
  // and that environment (the one solid's field, or their UnionDistanceField).
  std::unique_ptr<haptics::PointShellField> shell;
  std::shared_ptr<const haptics::DistanceField> shell_environment;
  // The snap field (null without snap input or when no feature survived).
  std::unique_ptr<haptics::SnapField> snap;
  // Summaries of the fields above, in the order MoveInto adds them.
  std::vector<FieldInfo> fields;
  // The snap features given (all zero without snap input).
  SnapFeatureCounts snap_counts;
  // Adds the fields to `scene` in the order proxies, shell, snap (and releases them here).
  void MoveInto(haptics::HapticScene* scene);
};

// The one builder of contact fields, used by `spidarcad run` (BuildHapticScene below) and by the
// window (SceneModel::BuildHapticScene): turns compiled solids into fields for the tool model,
// stiffness, damping, friction and shell settings of `options` (as felt at the grip) and the
// world scale s of X_WD (world metres per grip metre, > 0; options.world_scale and p_WDo are not
// read): stiffness and damping k/s, b/s; proxy sweep floor 0.2 mm·s; shell radius, pole length,
// soft zone, margin and swept step times s, virtual mass / s (see the file comment). `snap`
// (optional) adds the snap field. No solids give no contact field. Throws std::invalid_argument
// for bad options, a non-positive scale, a null solid or bad snap features.
SolidFields BuildSolidFields(const std::vector<CompiledSceneSolid>& solids,
                             const SceneHapticsOptions& options, double world_scale,
                             const SnapInput* snap = nullptr);

// Builds the force fields of `scene` (see the file comment). Compiles every solid (the tape is
// shared by the field and nothing else). Throws std::invalid_argument naming the solid (its
// name and JSON pointer /solids/i/root) when it does not compile, or the option when the
// options are bad, or when the scene has no solids, or (snap) too many features.
SceneHaptics BuildHapticScene(const modeling::Scene& scene, const SceneHapticsOptions& options);

}  // namespace spidarcad::app
