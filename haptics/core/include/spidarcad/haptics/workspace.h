// Deliverable wrench across the workspace (the paper's Sec. 6 experiment): the largest force,
// moment or grasp torque the strings can display in a given direction at a given pose, with the
// other six wrench components held exactly at zero and every tension in [τ_min, τ_max].
// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "spidarcad/haptics/geometry.h"

namespace spidarcad::haptics {

// Why MaxWrenchAlong gave the answer it gave.
enum class DeliverableStatus : std::uint8_t {
  kOk = 0,      // s_max is exact; may be negative when e itself cannot be displayed at all
  kInfeasible,  // no tensions in [τ_min, τ_max] give A τ on the line s·e (not even s = 0)
  kSingular,    // rank(A) < 7 or non-finite input: the pose is degenerate
};

// Result of MaxWrenchAlong.
struct DeliverableWrench {
  double s_max = 0;                 // largest s with A τ = s e, in the units of e (N or N·m)
  Vector8d tau = Vector8d::Zero();  // tensions that achieve it, N
  DeliverableStatus status = DeliverableStatus::kSingular;
};

// Solves  max s  s.t.  A τ = s e,  τ_min ≤ τ_i ≤ τ_max  exactly. With rank(A) = 7 every τ on the
// constraint is τ = s A⁺e + α n (n the unit null vector of A), so this is a 2-variable LP in
// (s, α) over 16 half-planes, solved by enumerating the vertices of the feasible polygon.
// A is 7 by 8 (WrenchMatrix), e a 7-vector (e.g. (1,0,0,0,0,0,0) for force along +x).
// Fixed-size Eigen types only (SVD of A, 120 candidate vertices); not meant for the 1 kHz tick.
DeliverableWrench MaxWrenchAlong(const Matrix78d& A, const Vector7d& e, double tau_min,
                                 double tau_max);

// Settings of the workspace sweep.
struct WorkspaceSweepSettings {
  double step = 0.01;           // m between grip positions along each axis
  double angle_step_deg = 5.0;  // degrees between grip rotations at the centre
  double max_angle_deg = 90.0;  // largest rotation at the centre
  double tau_min = 0.2;         // N
  double tau_max = 8.0;         // N

  // Throws std::invalid_argument naming the field when a setting is out of range.
  void Validate() const;
};

// One sample of the sweep. Translation sweeps ("translate"): the grip at rest orientation is
// moved by `distance` along sign·axis; `force` is the deliverable force along sign·axis (the
// direction of expected deterioration). Rotation sweeps ("rotate"): the grip at the centre is
// rotated by sign·angle about axis; `force` is NaN. For both, `force_min` is the smallest
// deliverable force over ±x, ±y, ±z, `moment_pos`/`moment_neg` the deliverable moment about
// +axis / −axis, `grasp_close`/`grasp_open` the deliverable grasp torque g > 0 / g < 0 (as a
// positive magnitude). Units N and N·m; a value is 0 when the direction cannot be displayed.
struct WorkspaceSample {
  std::string sweep;     // "translate" or "rotate"
  char axis = 'x';       // 'x', 'y' or 'z'
  int sign = +1;         // +1 or -1
  double distance = 0;   // m from the centre (translate), 0 for rotate
  double angle_deg = 0;  // rotation angle (rotate), 0 for translate
  double force = 0;
  double force_min = 0;
  double moment_pos = 0;
  double moment_neg = 0;
  double grasp_close = 0;
  double grasp_open = 0;
};

// Runs the sweep: six translation sweeps (±x, ±y, ±z) from the centre until an attachment point
// reaches a frame face, and six rotation sweeps (±x, ±y, ±z) at the centre up to max_angle_deg.
std::vector<WorkspaceSample> SweepWorkspace(const SpidarGeometry& geometry,
                                            const WorkspaceSweepSettings& settings);

// Where the deliverable wrench of one sweep falls off. "Full" is the value at the centre, or a
// rated value when one is given and the centre delivers more.
struct SweepFalloff {
  char axis = 'x';
  int sign = +1;
  double centre = 0;      // value at the centre (N for translate, N·m for rotate)
  double full = 0;        // min(centre, rated) when rated > 0, else centre
  double last_full = 0;   // largest distance (m) / angle (deg) with value >= 95 % of full
  double first_zero = 0;  // smallest distance / angle with value <= 1 % of full (NaN: never)
};

// Fall-off of each translation sweep (force) and rotation sweep (min of moment_pos, moment_neg).
// `rated` (N or N·m, 0 for none) caps "full", like a device rated below its peak capacity.
std::vector<SweepFalloff> SummarizeSweep(const std::vector<WorkspaceSample>& samples,
                                         const std::string& sweep, double rated = 0.0);

}  // namespace spidarcad::haptics
