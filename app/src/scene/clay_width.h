// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
// Clay width under the grasp (issue 13 §4): closing the grip on the clay stops the fingers at its
// surface and they feel it push back; how hard they squeeze sets how strongly the grab holds.
//
// Poles: as haptics::GraspField sees an object (grasp_field.h): per pole k the deepest point of
// the clay along it (haptics::FindPoleContact: FindPoleMinimum's samples and golden-section
// refinement), its depth δ_k, and a_k = n_k·w_k (m/rad), the rate at which closing the grasp
// drives that point along the clay's outward normal; pole k pushes when δ_k > 0 and a_k < 0.
//
// Squeeze depth m = min(δ_1, δ_2) over pushing poles (0 unless both push: one finger alone in
// the clay is a push, which the sculpt tool renders, not a squeeze). Energy E = k_n m², so the
// generalised force on θ is
//   Q = 2 k_n m (−a_j) − b_n r min(θ̇, 0),   j the shallower pole, r = min(1, m / grab_depth),
// and the grasp torque g = −2Q ≤ 0 (tension.h: the generalised force on θ is −g/2). Where both
// poles sink equally (a ball on the grip's bisector) this is GraspField's ½ k_n (δ_1² + δ_2²)
// and its closed form: a sphere of radius r at distance L on the bisector meets both poles at
// θ* = 2 asin(r/L), and Q(θ) = k_n (r − L sin θ/2) L cos θ/2 for θ < θ* (no damping). Unlike
// GraspField's sum, Q is continuous when the second pole touches: the clay is not pushed away
// by the first finger as a free rigid object is, so that finger may already be deep in it, and
// the sum would jump by k_n δ_1 (−a_1) there. The damping is ramped in over grab_depth for the
// same reason.
//
// Squeeze strength S = clamp(m / full_squeeze_depth, 0, 1): 0 with the fingers open or one
// pole touching, 1 from full_squeeze_depth of squeeze on (see SculptSession for how strokes use
// it).
//
// The clay moves: its distance field is a ClayDistanceGrid (clay_grid.h) rebuilt after every
// stroke off the haptic thread and handed over through a ClayGridChannel. While a stroke is under
// way the grabbed clay moves with the grip, so the grid (built before the stroke) is placed by
// X_WC = X_WT · X_WT_start⁻¹, as GraspField carries a grasped object with the grip.
//
// Frames and units: W, m, N, N·m, rad.
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <memory>

#include "scene/clay_grid.h"
#include "spidarcad/haptics/distance_field.h"
#include "spidarcad/haptics/force_field.h"
#include "spidarcad/haptics/grasp_field.h"
#include "spidarcad/haptics/handover.h"

namespace spidarcad::app {

// Settings of the clay width.
struct ClayWidthSettings {
  bool enabled = true;
  // pole_length d (m in W: the device's d × world scale), samples, refine_iterations, stiffness
  // k_n (N/m), damping b_n (N·m·s/rad) and grab_depth (m: the squeeze depth at which a squeeze
  // stroke begins, and over which the damping ramps in), as GraspField's.
  haptics::GraspSettings grasp;
  // Squeeze depth (m, > 0) at which the squeeze strength reaches 1.
  double full_squeeze_depth = 1e-3;
  // How the clay's grid is sampled.
  ClayGridSettings grid;
  // Throws std::invalid_argument naming the field and value when out of range.
  void Validate() const;
};

// What the poles feel of the clay at one tool state.
struct ClaySqueeze {
  haptics::PoleContact pole[2];  // per pole: depth δ (m), a (m/rad), pushing, ...
  double squeeze = 0.0;          // m = min(δ_1, δ_2) when both push, else 0 (m)
  double g = 0.0;                // grasp torque (N·m, <= 0)
  // Where the shallower and the deeper pole are deepest in the clay (W, m): the pinch.
  Eigen::Vector3d contact_W[2] = {Eigen::Vector3d::Zero(), Eigen::Vector3d::Zero()};
};

// The squeeze of the grip `tool` (W) on the clay whose field is `clay` (in the clay's frame C,
// placed by X_WC), per the file comment. Real-time safe.
ClaySqueeze ComputeClaySqueeze(const haptics::DistanceField& clay, const Eigen::Isometry3d& X_WC,
                               const haptics::ToolKinematics& tool,
                               const ClayWidthSettings& settings) noexcept;

// Squeeze strength S = clamp(m / full_depth, 0, 1) (0 for a non-finite m).
double SqueezeStrength(double squeeze, double full_depth) noexcept;

// The hand-over of rebuilt clay grids from the app to the haptic thread (haptics::Handover, as
// HapticLoop hands scenes over): the app offers a grid, the haptic thread takes it at its next
// Acquire and retires the one it used, and the app frees retired grids (Offer, Collect). No lock,
// no allocation and no free on the haptic thread. One reader (the haptic thread: one field reads
// it at a time).
class ClayGridChannel {
 public:
  // App side: offers `grid` (null: no clay) for the haptic thread's next Acquire, replacing one
  // it has not taken yet, and frees the grid it retired.
  void Offer(std::shared_ptr<const ClayDistanceGrid> grid) {
    grids_.Offer(std::make_unique<Slot>(Slot{std::move(grid)}));
  }
  // App side: frees the grid the haptic thread retired, if any; true when one was freed.
  bool Collect() { return grids_.Collect(); }
  // Haptic thread: the grid to use (the newest offered once the retired slot is free); null
  // before the first offer or after a null one. Real-time safe.
  const ClayDistanceGrid* Acquire() noexcept {
    const Slot* slot = grids_.Acquire();
    return slot != nullptr ? slot->grid.get() : nullptr;
  }

 private:
  struct Slot {
    std::shared_ptr<const ClayDistanceGrid> grid;
  };
  haptics::Handover<Slot> grids_;
};

}  // namespace spidarcad::app
