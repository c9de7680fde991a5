// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#include "scene/scene_haptics.h"

#include <algorithm>
#include <cmath>
#include <exception>
#include <sstream>
#include <stdexcept>
#include <utility>

#include "scene/snap_features.h"
#include "scene/solid_distance_field.h"
#include "spidarcad/modeling/cell_specialized_solid.h"
#include "spidarcad/modeling/surface_mesher.h"

namespace spidarcad::app {

namespace {

// Half side of the box searched for each solid, m: a solid reaching it is unbounded.
constexpr double kSearchHalfSide = 10.0;
// Cell of the coarse bounds search, m.
constexpr double kCoarseCell = 0.01;
// The shell's per-cell pruned tapes (modeling::CellSpecializedSolid, bit-identical to the
// full tape): cell edge and margin around each bounded solid's box, m (W), and a cap on the
// cells that bounds the build on every republish (the platform needs about 19,000 cells; the
// pruned-tapes note measured 8.8 ms for them; a larger solid gets larger cells).
constexpr double kShellCell = 0.01;
constexpr double kShellCellMargin = 0.02;
constexpr int kShellMaxCells = 1 << 15;

void Require(bool ok, const char* field, double value, const char* what) {
  if (ok) return;
  std::ostringstream os;
  os << "scene haptics option '" << field << "' = " << value << ": " << what;
  throw std::invalid_argument(os.str());
}

bool PositiveFinite(double v) { return std::isfinite(v) && v > 0.0; }

}  // namespace

Eigen::AlignedBox3d SolidBounds(const modeling::CompiledSolid& solid, bool* unbounded,
                                const std::atomic<bool>* cancel) {
  const Eigen::AlignedBox3d search(Eigen::Vector3d::Constant(-kSearchHalfSide),
                                   Eigen::Vector3d::Constant(kSearchHalfSide));
  const Eigen::AlignedBox3d rough = modeling::FindBounds(solid, search, kCoarseCell, cancel);
  *unbounded = false;
  if (rough.isEmpty()) return rough;
  for (int a = 0; a < 3; ++a) {
    if (rough.min()[a] <= -kSearchHalfSide + kCoarseCell ||
        rough.max()[a] >= kSearchHalfSide - kCoarseCell) {
      *unbounded = true;
      return Eigen::AlignedBox3d();
    }
  }
  return modeling::FindBounds(solid, rough, std::max(rough.sizes().maxCoeff() / 64.0, 1e-4),
                              cancel);
}

const char* ToolModelName(ToolModel model) {
  return model == ToolModel::kShell ? "shell" : "proxy";
}

void SceneHapticsOptions::Validate() const {
  Require(PositiveFinite(stiffness), "stiffness", stiffness, "must be finite and > 0 N/m");
  Require(std::isfinite(damping) && damping >= 0, "damping", damping,
          "must be finite and >= 0 N·s/m");
  Require(std::isfinite(static_friction) && static_friction >= 0, "static_friction",
          static_friction, "must be finite and >= 0");
  Require(std::isfinite(dynamic_friction) && dynamic_friction >= 0 &&
              dynamic_friction <= static_friction,
          "dynamic_friction", dynamic_friction, "must be in [0, static_friction]");
  Require(PositiveFinite(shell_radius), "shell_radius", shell_radius, "must be finite and > 0 m");
  Require(shell_rings >= 2, "shell_rings", shell_rings, "must be >= 2");
  Require(shell_around >= 3, "shell_around", shell_around, "must be >= 3");
  Require(PositiveFinite(coupling_stiffness), "coupling_stiffness", coupling_stiffness,
          "must be finite and > 0 N/m");
  Require(std::isfinite(coupling_damping) && coupling_damping >= 0, "coupling_damping",
          coupling_damping, "must be finite and >= 0 N·s/m");
  if (world_scale)
    Require(PositiveFinite(*world_scale), "world_scale", *world_scale, "must be finite and > 0");
  if (p_WDo) Require(p_WDo->allFinite(), "p_WDo", p_WDo->norm(), "must be finite");
  Require(PositiveFinite(device_half_side), "device_half_side", device_half_side,
          "must be finite and > 0 m");
  Require(PositiveFinite(fit_fraction) && fit_fraction <= 1.0, "fit_fraction", fit_fraction,
          "must be in (0, 1]");
  Require(PositiveFinite(grip_d), "grip_d", grip_d, "must be finite and > 0 m");
  Require(PositiveFinite(snap_tolerance), "snap_tolerance", snap_tolerance,
          "must be finite and > 0 m");
}

WorkspaceMap FitWorkspace(const Eigen::AlignedBox3d& bounds_W, double half_side, double fraction) {
  if (bounds_W.isEmpty()) throw std::invalid_argument("FitWorkspace: the scene's box is empty");
  Require(PositiveFinite(half_side), "device_half_side", half_side, "must be finite and > 0 m");
  Require(PositiveFinite(fraction) && fraction <= 1.0, "fit_fraction", fraction,
          "must be in (0, 1]");
  WorkspaceMap map;
  map.bounds_W = bounds_W;
  const double side = std::max(bounds_W.sizes().maxCoeff(), 1e-6);
  map.X_WD.world_scale = side / (2.0 * half_side * fraction);
  map.X_WD.p_WDo = bounds_W.center();
  map.scale_fitted = map.origin_fitted = true;
  return map;
}

void SceneHaptics::ApplyTo(haptics::LoopSettings* settings) const { settings->X_WD = map.X_WD; }

void SolidFields::MoveInto(haptics::HapticScene* scene) {
  for (auto& proxy : proxies) scene->Add(std::move(proxy));
  proxies.clear();
  if (shell) scene->Add(std::move(shell));
  if (snap) scene->Add(std::move(snap));
}

SolidFields BuildSolidFields(const std::vector<CompiledSceneSolid>& solids,
                             const SceneHapticsOptions& options, double world_scale,
                             const SnapInput* snap) {
  options.Validate();
  Require(PositiveFinite(world_scale), "world_scale", world_scale, "must be finite and > 0");
  SolidFields out;
  for (const CompiledSceneSolid& solid : solids) {
    if (solid.solid == nullptr) {
      throw std::invalid_argument("BuildSolidFields: solid '" + solid.name + "' is null");
    }
    out.distance.push_back(std::make_shared<const SolidDistanceField>(solid.solid));
  }
  const double s = world_scale;
  if (options.tool == ToolModel::kProxy) {
    haptics::ProxySettings proxy;
    proxy.stiffness = options.stiffness / s;
    proxy.damping = options.damping / s;
    proxy.static_friction = options.static_friction;
    proxy.dynamic_friction = options.dynamic_friction;
    proxy.min_step = 2e-4 * s;
    for (std::size_t i = 0; i < out.distance.size(); ++i) {
      out.proxies.push_back(std::make_unique<haptics::ProxyField>(out.distance[i], proxy));
      out.fields.push_back({"proxy", solids[i].name});
    }
  } else if (!out.distance.empty()) {
    // The shell's points go through each solid's pruned tapes (bit-identical, shorter near one
    // feature), several points at a time (DistanceField::EvaluateBatch).
    std::vector<std::shared_ptr<const haptics::DistanceField>> shell_fields = out.distance;
    for (std::size_t i = 0; i < solids.size(); ++i) {
      bool unbounded = false;
      const Eigen::AlignedBox3d box = SolidBounds(*solids[i].solid, &unbounded);
      if (box.isEmpty()) continue;
      const Eigen::Vector3d margin = Eigen::Vector3d::Constant(kShellCellMargin);
      modeling::CellSpecializationSettings cell;
      cell.cell_size = kShellCell;
      cell.max_cells = kShellMaxCells;
      shell_fields[i] = std::make_shared<const SolidDistanceField>(
          solids[i].solid,
          std::make_shared<const modeling::CellSpecializedSolid>(
              solids[i].solid, Eigen::AlignedBox3d(box.min() - margin, box.max() + margin), cell));
    }
    std::shared_ptr<const haptics::DistanceField> environment =
        shell_fields.size() == 1
            ? shell_fields.front()
            : std::make_shared<const haptics::UnionDistanceField>(shell_fields);
    haptics::PointShell shell = haptics::PointShell::CrossGrip(
        options.grip_d * s, options.shell_radius * s, options.shell_rings, options.shell_around);
    haptics::PointShellSettings settings;
    settings.coupling_stiffness = options.coupling_stiffness / s;
    settings.coupling_damping = options.coupling_damping / s;
    settings.contact_stiffness = options.coupling_stiffness / s;
    settings.contact_margin = 2e-3 * s;
    // Lengths of the coupling's soft zone (2 encoder quanta of grip jitter) and of the swept
    // step are grip lengths: map them into W. max_penetration stays 0.6 mm in W (it must stay
    // below half the thinnest wall of the scene, and the scenes' walls do not scale with s).
    settings.coupling_soft_zone = 5e-5 * s;
    settings.min_step = 2e-4 * s;
    settings.max_points = std::max(settings.max_points, shell.size());
    // Mass and inertia scale with the world so the virtual tool's dynamics (ω = √(k/m)) do not
    // change with s: m ∝ 1/s keeps k/m fixed; inertia keeps k_r/I fixed (k_r is not rescaled).
    settings.mass = settings.mass / s;
    out.shell = std::make_unique<haptics::PointShellField>(environment, std::move(shell), settings);
    out.shell_environment = environment;
    out.fields.push_back(
        {"point_shell", out.distance.size() == 1
                            ? solids.front().name
                            : "union of " + std::to_string(out.distance.size()) + " solids"});
  }
  if (snap != nullptr) {
    // Snap forces: the solids' features in W, radii in W, the force as felt (force_scale 1).
    const SnapFeatureCounts counts = CountSnapFeatures(snap->features);
    out.snap_counts = counts;
    if (counts.vertices + counts.edges + counts.faces > 0) {
      haptics::SnapSettings settings;
      settings.max_force = snap->settings.max_force;
      settings.vertex_radius = snap->settings.vertex_radius;
      settings.edge_radius = snap->settings.edge_radius;
      settings.face_radius = snap->settings.face_radius;
      out.snap = std::make_unique<haptics::SnapField>(snap->features, settings);
      out.fields.push_back({"snap", counts.ToString()});
    }
  }
  return out;
}

SceneHaptics BuildHapticScene(const modeling::Scene& scene, const SceneHapticsOptions& options) {
  options.Validate();
  if (scene.solids.empty() && options.extra_bounds_W.isEmpty()) {
    throw std::invalid_argument("the scene has no solids");
  }

  // Compile every solid and find its box (with the parts other fields render).
  std::vector<CompiledSceneSolid> solids;
  Eigen::AlignedBox3d bounds = options.extra_bounds_W;
  for (std::size_t i = 0; i < scene.solids.size(); ++i) {
    const modeling::Solid& solid = scene.solids[i];
    const std::string pointer = "/solids/" + std::to_string(i) + "/root";
    std::shared_ptr<const modeling::CompiledSolid> compiled;
    try {
      compiled = std::make_shared<const modeling::CompiledSolid>(
          modeling::CompiledSolid::Compile(solid.root, pointer));
    } catch (const std::exception& e) {
      throw std::invalid_argument("solid '" + solid.name + "' (" + pointer + "): " + e.what());
    }
    bool unbounded = false;
    const Eigen::AlignedBox3d box = SolidBounds(*compiled, &unbounded);
    if (!box.isEmpty()) bounds.extend(box);
    solids.push_back({solid.name, std::move(compiled)});
  }

  SceneHaptics out;
  if (!bounds.isEmpty()) {
    out.map = FitWorkspace(bounds, options.device_half_side, options.fit_fraction);
  } else {
    out.map.scale_fitted = out.map.origin_fitted = true;  // nothing bounded: identity
  }
  if (options.world_scale) {
    out.map.X_WD.world_scale = *options.world_scale;
    out.map.scale_fitted = false;
  }
  if (options.p_WDo) {
    out.map.X_WD.p_WDo = *options.p_WDo;
    out.map.origin_fitted = false;
  }

  if (solids.empty()) {  // only parts of other fields: nothing to touch here
    out.scene = std::make_unique<haptics::HapticScene>();
    return out;
  }
  std::optional<SnapInput> snap;
  if (scene.snap) snap = SnapInput{*scene.snap, ExtractSnapFeatures(scene, options.snap_tolerance)};
  SolidFields fields =
      BuildSolidFields(solids, options, out.map.X_WD.world_scale, snap ? &*snap : nullptr);
  out.scene = std::make_unique<haptics::HapticScene>();
  out.fields = fields.fields;
  out.snap = fields.snap_counts;
  fields.MoveInto(out.scene.get());
  return out;
}

}  // namespace spidarcad::app
