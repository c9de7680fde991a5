// The window's scene: the implicit solids of a scene file (or the built-in demo), where they sit
// in the device workspace (X_WD), their meshes (a preview surface meshed in the background at
// load, and the surface / tetrahedra of the Mesh action, kept for export), the HapticScene
// built from them, and export. Meshing runs as Jobs (doc/job.h); a job's result lands on the
// main thread through its finisher, a failed or cancelled job changes nothing.
// Main thread only (except what the jobs' work functions capture: immutable copies).
// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#pragma once

#include <array>
#include <filesystem>
#include <memory>
#include <string>
#include <vector>

#include <Eigen/Geometry>

#include "doc/job.h"
#include "gui/device_session.h"
#include "spidarcad/haptics/geometry.h"
#include "spidarcad/haptics/haptic_loop.h"
#include "spidarcad/modeling/implicit_evaluator.h"
#include "spidarcad/modeling/surface_mesher.h"
#include "spidarcad/modeling/tet_mesh.h"

namespace spidarcad::app {

// The scene name of the built-in demo scene (a bracket part and a knob within the device's reach).
inline constexpr const char* kDemoSceneName = "demo";
// The scene name of the empty scene.
inline constexpr const char* kNoSceneName = "none";
// Text of the built-in demo scene (spidarcad-scene JSON, version 1).
const char* DemoSceneJson();

// X_WD of the loop: p_W = world_scale · p_D + p_WDo.
struct DeviceToWorld {
  double world_scale = 1.0;
  Eigen::Vector3d p_WDo = Eigen::Vector3d::Zero();
};

// Places `bounds_W` (the scene's solids, m) in reach of the grip: the scale is the smallest
// s >= 1 for which the box fits 80 % of the grip's travel across x and y and the lower part of
// its travel in z; the device centre maps to 6 cm (in D) above the middle of the box's top, so
// the grip starts outside every solid with the solids below it. The identity for an empty box.
// `travel` is the largest |p0| per axis the grip reaches in D (GripControl::limits()).
DeviceToWorld ChooseDeviceToWorld(const Eigen::AlignedBox3d& bounds_W,
                                  const Eigen::Vector3d& travel);

// Which mesh the Mesh action makes.
enum class MeshKind { kSurface, kTetrahedra };

// One solid of the scene and its meshes.
struct SceneObject {
  std::string name;
  std::shared_ptr<const modeling::CompiledSolid> solid;
  Eigen::AlignedBox3d bounds_W;      // box of the solid, m
  std::array<double, 3> colour{};    // RGB in [0, 1] in the view
  modeling::TriangleMesh preview;    // background preview surface (empty until meshed)
  double preview_cell = 0.0;         // its grid cell, m
  modeling::TriangleMesh surface;    // the Mesh action's surface (empty until made)
  double surface_cell = 0.0;
  modeling::TetMesh tets;            // the Mesh action's tetrahedra (empty until made)
  int revision = 0;                  // bumped whenever the displayed mesh changes
  // The mesh to show: the Mesh action's surface when there is one, else the preview.
  const modeling::TriangleMesh& shown() const { return surface.triangles.cols() > 0 ? surface : preview; }
};

// The scene of the window.
class SceneModel {
 public:
  // Colours given to the solids in order (cycled).
  static const std::array<std::array<double, 3>, 3> kColours;

  // Loads `source`: kDemoSceneName, kNoSceneName or a scene file path. Compiles every solid and
  // finds its box; places the scene with ChooseDeviceToWorld(travel), or keeps `*keep` when
  // given (a reload: the running loop's X_WD cannot change). Throws std::runtime_error (or
  // modeling::SceneError) naming the file and solid when that fails; the model is then unchanged.
  void Load(const std::string& source, const Eigen::Vector3d& travel,
            const DeviceToWorld* keep = nullptr);
  // Starts a preview-surface job per solid (cell = largest side / cells_across).
  void StartPreviewJobs(JobQueue* jobs, double cells_across = 48.0);
  // Starts the Mesh action on object `index`: surface at `cell` m and, for kTetrahedra, TetGen
  // (radius-edge bound 2) on it. Returns the job. Throws std::out_of_range for a bad index.
  Job& StartMeshJob(JobQueue* jobs, int index, MeshKind kind, double cell);
  // True once the scene file changed on disk since it was loaded (checked by mtime).
  bool SourceChanged() const;

  // The haptic scene of the solids (penalty contact, stiffness felt in D `stiffness_D` N/m and
  // damping `damping_D` N·s/m) plus the centring springs when field.enabled.
  std::unique_ptr<haptics::HapticScene> BuildHapticScene(const DemoFieldSettings& field,
                                                         double stiffness_D = 1000.0,
                                                         double damping_D = 3.0) const;

  const std::vector<SceneObject>& objects() const { return objects_; }
  const DeviceToWorld& device_to_world() const { return x_wd_; }
  const std::string& source() const { return source_; }
  const std::string& description() const { return description_; }
  // Incremented by every Load (jobs of an older scene are dropped when they finish).
  int generation() const { return generation_; }

 private:
  std::vector<SceneObject> objects_;
  DeviceToWorld x_wd_;
  std::string source_;
  std::string description_;
  std::filesystem::file_time_type mtime_{};
  int generation_ = 0;
};

// Writes `mesh` to `path` (.stl binary, .obj, .ply binary by extension). Returns "" on success,
// else the error text (empty mesh, unknown extension, unwritable file).
std::string ExportSurface(const modeling::TriangleMesh& mesh, const std::string& path);
// Writes `mesh` to `path`: .vtu (VTK XML), or TetGen's .node/.ele (path ending in .node, .ele
// or without extension gives base.node and base.ele). Returns "" or the error text.
std::string ExportTetrahedra(const modeling::TetMesh& mesh, const std::string& path);

}  // namespace spidarcad::app
