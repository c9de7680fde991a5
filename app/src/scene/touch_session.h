// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
// Modelling by touch, frame by frame, without a window: the part of model mode (gui/modes.h)
// that both the window and the scripted run (`spidarcad run --place KIND`, scene/scripted_run.h)
// drive, so that they place, align and pull alike. A TouchSession keeps the features the ghost
// aligns to (the document's solids, one grabbed node left out), the ghost of the primitive
// being placed (its pose aligned by AlignToFeatures, its size by PlaceSize, the history the
// squeeze looks back into), the felt snap field that pulls the grip toward where the ghost
// would align (haptics::SnapField, FeltSnapFeatures), and places the ghost as one command.
// The window adds the VTK ghost and highlight and the grab of a selected node on top; the run
// adds the felt field to its loop's scene through TouchSnapSlotField (one thread).
//
// Frames and units: W the world, D the device; X_WD's scale s (W metres per D metre) scales
// the capture distances and the grasp's size (touch_modelling.h). Main thread only (the run's:
// the thread that steps it).
#pragma once

#include <Eigen/Geometry>
#include <cstdint>
#include <deque>
#include <limits>
#include <memory>
#include <optional>
#include <string>
#include <utility>

#include "doc/document.h"
#include "scene/touch_modelling.h"
#include "spidarcad/haptics/force_field.h"
#include "spidarcad/haptics/haptic_loop.h"

namespace spidarcad::app {

// Detects a short squeeze of the grasp: from where the closing began, the angle closes by at
// least kDepth and opens again by at least kDepth, the whole gesture within kWindow seconds.
class SqueezeDetector {
 public:
  static constexpr double kWindow = 0.4;                                 // s
  static constexpr double kDepth = 10.0 * 3.14159265358979323846 / 180;  // rad (10°)
  static constexpr double kNoise = 0.5 * 3.14159265358979323846 / 180;   // rad of jitter ignored
  static constexpr double kHistory = 2.0;                                // s of samples kept
  // Adds the grasp angle θ (rad) at time t (s, increasing); true when this sample completes a
  // squeeze (once per squeeze: the history restarts after one).
  bool Update(double t, double grasp);
  // When the latest squeeze began closing (s; −inf before the first).
  double last_start() const { return last_start_; }

 private:
  std::deque<std::pair<double, double>> samples_;  // (t, θ) within the last kHistory s
  double last_start_ = -std::numeric_limits<double>::infinity();
};

// The kind of an alignment as a CSV number (`run --place`'s touch_feature column): 0 none,
// 1 face, 2 edge, 3 axis, 4 vertex.
int AlignKindNumber(AlignKind kind);

// The modelling-by-touch state of one document (see the file comment).
class TouchSession {
 public:
  // `pole_length`: d, the grip's pole half-length, m in D (PlaceSize).
  explicit TouchSession(double pole_length);

  // X_WD's world scale s (> 0; others are ignored): the capture distances and sizes scale by it.
  void SetWorldScale(double world_scale);
  double world_scale() const { return world_scale_; }
  // The alignment's capture distances and the felt pull (used from the next felt rebuild).
  TouchSnapSettings& snap_settings() { return settings_; }
  const TouchSnapSettings& snap_settings() const { return settings_; }

  // Arms placing a primitive of `kind` (nullopt disarms): the ghost and its history restart;
  // disarming drops the felt field. True when the felt field changed (the scene must be rebuilt).
  bool SetPlacing(std::optional<PlaceKind> kind);
  const std::optional<PlaceKind>& placing() const { return placing_; }

  // The features the ghost aligns to: the solids of `doc` (the node at `excluded_path` of object
  // `excluded` replaced by nothing; excluded 0: none). Recomputed only when the document, its
  // revision, `generation` (the caller's count of documents opened) or the exclusion changed. A
  // tree that does not evaluate, or too many features, leaves no features and says so in
  // message().
  void UpdateFeatures(const Document& doc, int generation, ObjectId excluded = 0,
                      const NodePath& excluded_path = {});
  const TouchSnapFeatures& features() const { return features_; }

  // Aligns the pose X_WN of a body of extent `box_N` (its frame N) to the features: the ghost.
  const Alignment& Align(const Eigen::Isometry3d& X_WN, const Eigen::AlignedBox3d& box_N);
  // The ghost at the latest Align or UpdatePlacing (its pose in W) and the size placed with it.
  const Alignment& ghost() const { return ghost_; }
  double ghost_size() const { return ghost_size_; }

  // Makes the felt snap field pull toward a body resting `rest_height` m (W) above the faces
  // (and onto the vertices, edges and axes), rebuilt when the features changed or the height
  // moved by more than 2 %. True when the field changed.
  bool UpdateFeltSnap(double rest_height);
  // The rest height the felt field was built for (m, W: the lift of its faces); 0 without one.
  double felt_rest_height() const { return felt_snap_ != nullptr ? felt_rest_height_ : 0.0; }
  // Drops the felt field. True when there was one.
  bool DropFeltSnap();
  // The felt field (null: none). Evaluated by one thread at a time.
  const std::shared_ptr<haptics::ForceField>& felt_snap() const { return felt_snap_; }

  // What one frame of placing did.
  struct PlaceFrame {
    bool placed = false;        // a solid was added (one command)
    bool felt_changed = false;  // the felt field changed (the scene must be rebuilt)
    ObjectId placed_id = 0;     // the solid added (0: none)
  };
  // The felt field follows the ghost's size only while the grasp is steady: every size of the
  // last kSteadyTime s within kSteadyTolerance of the latest. So a squeeze (or a quick change of
  // the grasp) does not move the lifted faces under the grip, which would pull with a jolt.
  static constexpr double kSteadyTime = 0.1;        // s
  static constexpr double kSteadyTolerance = 0.02;  // relative
  // One frame of placing (nothing unless placing()): the ghost is the grip's pose W (tool.tool_W)
  // sized by the measured grasp (tool.pose_D), aligned to the features of `doc`; the felt field
  // follows its rest height (half its size) while the grasp is steady. `squeezed`: a squeeze ended
  // this frame, which began at `squeeze_start` (s; SqueezeDetector): the ghost as it was then is
  // placed. `place_key`: the ghost as it is now is placed.
  PlaceFrame UpdatePlacing(const haptics::ToolState& tool, Document* doc, int generation,
                           bool squeezed, double squeeze_start, bool place_key);
  // Places the ghost as it is now: one command adding the solid "KIND" (made unique). True when
  // placed (placed_id() says which); message() says what happened.
  bool Place(Document* doc);

  // What the latest place (or a failed feature extraction) said ("" before any).
  const std::string& message() const { return message_; }
  // Solids placed so far, and the latest (0: none).
  int placed_count() const { return placed_count_; }
  ObjectId placed_id() const { return placed_id_; }

 private:
  struct GhostSample {
    double time;
    Alignment pose;
    double size;
  };
  double pole_length_;
  double world_scale_ = 1.0;
  TouchSnapSettings settings_;
  std::optional<PlaceKind> placing_;
  // The features and what they were made from.
  TouchSnapFeatures features_;
  const Document* features_doc_ = nullptr;
  std::uint64_t features_revision_ = ~std::uint64_t{0};
  int features_generation_ = -1;
  ObjectId excluded_ = 0;
  NodePath excluded_path_;
  std::uint64_t features_count_ = 0;  // bumped at each recomputation (the felt field's key)
  Alignment ghost_;
  double ghost_size_ = 0.0;
  std::deque<GhostSample> history_;
  std::shared_ptr<haptics::ForceField> felt_snap_;
  double felt_rest_height_ = -1.0;
  std::uint64_t felt_features_ = ~std::uint64_t{0};
  std::string message_;
  int placed_count_ = 0;
  ObjectId placed_id_ = 0;
};

// A force field forwarding to the felt field a TouchSession holds (zero wrench while it has
// none), for a loop stepped on the thread that updates the session: the scripted run adds one
// to its scene before the first tick and the session swaps the field between ticks. Real-time
// safe when the target is (no reference count changes in Evaluate).
class TouchSnapSlotField final : public haptics::ForceField {
 public:
  // `session` must outlive the field.
  explicit TouchSnapSlotField(const TouchSession* session) : session_(session) {}
  haptics::ToolWrench Evaluate(const haptics::ToolKinematics& tool) noexcept override;
  const char* name() const noexcept override { return "touch_snap"; }

 private:
  const TouchSession* session_;
};

}  // namespace spidarcad::app
