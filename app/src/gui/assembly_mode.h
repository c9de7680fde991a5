// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
// Assembly mode (issue 5): the window's view of an assembly scene (a scene file with `parts`,
// e.g. assets/scenes/assembly.json). The logic is haptics::AssemblyField (built once by
// BuildAssemblyField, scene/assembly_scene.h, on the main thread, never on the 1 kHz one); the
// window keeps it in a shared_ptr and puts a SharedField to it into every HapticScene it
// publishes. This class only draws: one actor per part, its surface meshed once per solid in the
// part's own frame P (MeshSurface), placed each frame at the pose X_WP the field published last
// (AssemblyField::LatestState, read here: the main thread is its one reader), coloured by state
// (fixed, free, carried, seated), plus a translucent ghost of the carried part at the seat it is
// nearest to. A panel section lists the parts and resets them.
//
// Frames: the field works in W; the actors are placed in the view frame D by the inverse of
// X_WD (p_D = (p_W − p_WDo) / s), set with SetWorldToView: part i's actor matrix is
// X_DW · X_WP(i). The window uses X_WD = identity for assembly scenes, as `spidarcad run` does,
// so that one trajectory file works in both.
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <array>
#include <memory>
#include <string>
#include <vector>

#include "scene/assembly_scene.h"
#include "spidarcad/haptics/assembly_field.h"
#include "spidarcad/haptics/device_to_world.h"
#include "spidarcad/modeling/scene_io.h"

class vtkRenderer;
class vtkActor;

namespace spidarcad::app {

// Part colours (RGB in [0, 1]).
inline constexpr std::array<double, 3> kAssemblyFixedColour = {0.55, 0.60, 0.70};    // slate
inline constexpr std::array<double, 3> kAssemblyFreeColour = {0.85, 0.72, 0.50};     // sand
inline constexpr std::array<double, 3> kAssemblyCarriedColour = {0.96, 0.55, 0.12};  // orange
inline constexpr std::array<double, 3> kAssemblySeatedColour = {0.30, 0.72, 0.38};   // green

// What a part is doing, for colours, the panel and the summary.
enum class AssemblyPartState { kFixed, kFree, kCarried, kSeated };

// The assembly scene's actors and panel around a shared AssemblyField.
class AssemblyMode {
 public:
  // Adds its actors to `renderer` (may be null: no drawing, for tests of the logic); the
  // renderer must outlive this mode.
  explicit AssemblyMode(vtkRenderer* renderer);
  ~AssemblyMode();
  AssemblyMode(const AssemblyMode&) = delete;
  AssemblyMode& operator=(const AssemblyMode&) = delete;

  // Takes the parts of `scene`: builds the field (BuildAssemblyField with `settings`) and meshes
  // each solid the parts use once, in P, at a cell of 1/40 of its box's largest side (at most
  // `display_cell` m). A scene without parts empties the mode (has_parts() false, no field).
  // Throws std::invalid_argument naming the part or solid when the field or a mesh cannot be
  // made; the mode is then unchanged.
  void Load(const modeling::Scene& scene, const AssemblySceneSettings& settings = {},
            double display_cell = 0.001);
  // True when the loaded scene has parts.
  bool has_parts() const { return field_ != nullptr; }
  // The field (null without parts). The window puts a SharedField to it into its HapticScenes.
  const std::shared_ptr<haptics::AssemblyField>& field() const { return field_; }
  // True once after Load or Reset made a new field (the HapticScene must then be republished).
  bool TakeFieldChanged();
  // Rebuilds the field from the loaded scene: every part back at its initial pose, none
  // carried or seated. Throws like Load (it cannot fail when Load succeeded).
  void Reset();

  // Main thread, once per frame: reads the field's latest published state (the initial poses
  // before its first tick) and places and colours the actors (Show).
  void OnFrame();
  // Places part i's actor at X_DW · state.X_WP[i] and colours it by its state; shows the ghost
  // of the carried part at its nearest seat. `state.count` must be size() (else ignored).
  void Show(const haptics::AssemblyState& state);

  // Places the actors in the view frame: p_D = (p_W − p_WDo) / s (s > 0).
  void SetWorldToView(const haptics::DeviceToWorld& X_WD);
  // ImGui widgets of the panel section (no Begin/End): the parts and their states, how many are
  // seated, what is carried, and "Reset parts" (which calls Reset).
  void DrawPanel();

  // Parts: count, names, fixed or graspable, state in the last shown state.
  int size() const { return static_cast<int>(parts_.size()); }
  const std::string& part_name(int i) const { return parts_[i].name; }
  bool part_fixed(int i) const { return parts_[i].fixed; }
  AssemblyPartState part_state(int i) const;
  // Graspable parts, and how many of them are seated, in the last shown state.
  int graspable_count() const;
  int seated_count() const;
  // The last state shown (count 0 before the first Show).
  const haptics::AssemblyState& state() const { return state_; }
  // Names of the scene solids the parts are made of: the window hides their static actors (the
  // solids sit at their own frame origins; the parts draw them where they are).
  std::vector<std::string> part_solids() const;
  // Part i's actor and the ghost actor (tests); null without a renderer.
  vtkActor* actor(int i) const;
  vtkActor* ghost() const;
  // The matrix X_DW · X_WP placing a part's P coordinates in D (4×4 homogeneous).
  Eigen::Matrix4d ViewMatrix(const Eigen::Isometry3d& X_WP) const;

 private:
  struct Vtk;
  struct Part {
    std::string name;
    std::string solid;
    bool fixed = false;
    int mesh = -1;  // index of the part's solid's mesh in vtk_
  };
  void UpdateGhost();

  vtkRenderer* renderer_;
  std::unique_ptr<Vtk> vtk_;
  modeling::Scene scene_;  // the loaded scene (for Reset)
  AssemblySceneSettings settings_;
  std::shared_ptr<haptics::AssemblyField> field_;
  std::vector<Part> parts_;
  haptics::AssemblyState state_;
  bool field_changed_ = false;
  haptics::DeviceToWorld X_WD_;
  std::string message_;
};

// One line for stdout, e.g. "assembly: 1 of 5 parts seated (right_arm), carried: none\n", of the
// last shown state (the text of FormatAssemblySummary in scene/assembly_scene.h, as `run`).
std::string FormatAssemblySummary(const AssemblyMode& mode);

// Reads the scene file `source` (not "demo" or "none") and returns true when it has parts,
// filling *scene. False for the built-in names, a file without parts, or a file that cannot be
// read (the SceneModel reports that one).
bool LoadAssemblyScene(const std::string& source, modeling::Scene* scene);

}  // namespace spidarcad::app
