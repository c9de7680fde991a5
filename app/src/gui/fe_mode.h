// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
// FE mode of the window (modes.md contract): pick a meshed part, set its material, clamped
// region and element order, precompute (a Job with progress and cancel), then push it with the
// grip: the reaction force is felt (FeTouchField) and shown as numbers, and the deformed
// surface is drawn coloured by von Mises stress with a legend (MPa), the displacement
// magnified by a slider.
//
// The logic lives in scene/fe_model.h and scene/fe_touch_field.h (no VTK, no ImGui, tested
// headless in tests/app/fe_mode_test.cc); this class is the thin VTK/ImGui layer. Main thread
// only. The haptic thread is the single producer of the column focus (FeTouchField::Evaluate).
#pragma once

#include <vtkSmartPointer.h>

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <cmath>
#include <memory>
#include <string>

#include "doc/job.h"
#include "scene/fe_model.h"
#include "scene/fe_touch_field.h"
#include "spidarcad/fem/mesh.h"
#include "spidarcad/haptics/device_to_world.h"
#include "spidarcad/haptics/force_field.h"
#include "spidarcad/haptics/haptic_loop.h"

class vtkRenderer;
class vtkActor;
class vtkPolyData;
class vtkLookupTable;
class vtkScalarBarActor;
class vtkSphereSource;
class vtkDoubleArray;

namespace spidarcad::app {

// Figures of the live FE state shown in the panel (and read by tests/demos).
struct FeLiveFigures {
  // FE force on the tool (unscaled), N, in W.
  Eigen::Vector3d f_tool_W = Eigen::Vector3d::Zero();
  // Contact nodes, and how many still read a substitute column.
  int contacts = 0;
  int substituted = 0;
  // Largest displacement magnitude of a surface node, m.
  double max_displacement = 0.0;
  // Largest nodal von Mises stress on the surface, Pa.
  double max_von_mises = 0.0;
  // Columns ready in the cache.
  int ready_columns = 0;
};

// The FE mode.
class FeMode {
 public:
  // Adds the mode's actors (deformed part, legend, tool sphere) to `renderer`, hidden until the
  // mode is active and a model is ready. `jobs` runs meshing and precomputation. Both must
  // outlive the mode.
  FeMode(vtkRenderer* renderer, JobQueue* jobs);
  ~FeMode();
  FeMode(const FeMode&) = delete;
  FeMode& operator=(const FeMode&) = delete;

  // Shows or hides the actors. Activating with a ready model queues a field for TakeField;
  // deactivating saves the ready columns to the disk cache (a Job) and publishes nothing.
  void SetActive(bool active);
  // True while active.
  bool active() const { return active_; }
  // ImGui widgets of the panel (no Begin/End).
  void DrawPanel();
  // Per frame: reads the latest contact state and updates the deformed surface and figures.
  void OnFrame(const haptics::ToolState& tool);
  // The force field to publish when it changed since the last call (new model, new tool
  // settings, activation), else nullptr. Inactive: nullptr.
  std::unique_ptr<haptics::ForceField> TakeField();

  // Places the actors in the view frame: p_D = (p_W − p_WDo) / s (s > 0), as SculptMode does.
  void SetWorldToView(const haptics::DeviceToWorld& X_WD);
  // The part to work on (tetrahedra in W, m); drops the current model (precompute again).
  void SetMesh(fem::TetMesh mesh, std::string name);
  // Meshes assets/scenes/platform.json at `resolution` m (TetGen) in a Job; its finisher calls
  // SetMesh(mesh, "platform").
  void MeshPlatform(double resolution = 0.012);
  // Starts the precomputation Job with the panel's settings (material, clamps, order).
  void Precompute();

  // Model settings the next Precompute uses (editable by code as by the panel).
  FeModelSettings& model_settings() { return model_settings_; }
  // Touch settings of the next field (tool_radius <= 0: the mesh's mean edge length).
  FeTouchSettings& touch_settings() { return touch_settings_; }
  // The ready model (null before the first precomputation finished).
  const std::shared_ptr<FeModel>& model() const { return model_; }
  // Live figures of the last OnFrame.
  const FeLiveFigures& figures() const { return figures_; }
  // True when a screenshot of the mode may be taken: the mode is off; or nothing is running
  // and there is no model (a job failed or nothing was asked); or the live field has run for
  // kSettleSeconds of loop time since it was published and the column worker has caught up
  // with the tool.
  bool Settled() const;
  // Loop time the live field runs before Settled(), s.
  static constexpr double kSettleSeconds = 0.5;
  // Name of the part (the mesh given to SetMesh; "" before one).
  const std::string& mesh_name() const { return mesh_name_; }
  // Status line (what is happening or went wrong).
  const std::string& status() const { return status_; }

 private:
  void BuildSurfaceActor();
  void UpdateSurface(const FeContactState* state);
  void QueueField();
  Job* RunningJob() const;

  vtkRenderer* renderer_;
  JobQueue* jobs_;
  bool active_ = false;
  std::string mesh_name_;
  std::shared_ptr<const fem::TetMesh> mesh_;
  std::shared_ptr<FeModel> model_;
  std::shared_ptr<FeContactChannel> channel_;
  std::unique_ptr<haptics::ForceField> pending_field_;
  FeModelSettings model_settings_;
  FeTouchSettings touch_settings_;
  FeLiveFigures figures_;
  std::string status_ = "no part: mesh the platform or pick a meshed object";
  std::string job_title_;
  // Panel state.
  int preset_ = 0;
  bool box_fixed_ = false;
  float box_[6] = {-1.0f, -1.0f, -1.0f, 0.001f, 1.0f, 1.0f};
  float magnify_ = 100.0f;
  float log_force_scale_ = static_cast<float>(std::log10(kDefaultFeForceScale));
  float resolution_mm_ = 12.0f;
  bool auto_range_ = true;
  float range_mpa_ = 100.0f;
  double magnify_shown_ = -1.0;
  haptics::DeviceToWorld X_WD_;
  // VTK.
  vtkSmartPointer<vtkPolyData> poly_;
  vtkSmartPointer<vtkDoubleArray> scalars_;
  vtkSmartPointer<vtkActor> actor_;
  vtkSmartPointer<vtkLookupTable> lut_;
  vtkSmartPointer<vtkScalarBarActor> legend_;
  vtkSmartPointer<vtkSphereSource> sphere_source_;
  vtkSmartPointer<vtkActor> sphere_actor_;
  FeContactState last_state_;
  // A field was handed out by TakeField; loop time of its first published state (−1: none yet).
  bool field_taken_ = false;
  // Title of the mesh or precompute Job whose finisher has not run yet (empty: none).
  std::string awaiting_title_;
  double field_start_time_ = -1.0;
  // Finishers of this mode's Jobs run only while the mode lives (they hold a weak_ptr to this).
  std::shared_ptr<int> alive_ = std::make_shared<int>(0);
};

// The settings of the field FeMode publishes from the panel's: the felt force scale and the
// coupling stiffness are divided by the world scale of X_WD (p_W = s·p_D + p_WDo, forces
// displayed as they are), so that a grip displacement δ in D, which moves the tool s·δ in W, is
// felt as force_scale · K · δ (and at most coupling · δ) whatever s is: the stiffness felt in
// the hand does not depend on how big the scene is drawn.
FeTouchSettings FieldTouchSettings(const FeTouchSettings& panel, double world_scale);

// Two lines for the end of a scripted run (--frames, --screenshot): the FE part's state (columns
// ready, contacts, FE force on the tool) and the tool's position and the wrench the loop
// commanded at the last tick (D, N).
std::string FormatFeSummary(const FeMode& mode, const haptics::ToolState& tool);

}  // namespace spidarcad::app
