// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
// Force fields the window adds to its HapticScene besides those of the shared builder
// (scene/scene_haptics.h BuildSolidFields): the centring springs of the demo panel, and the
// wrappers that keep a contact (god-object proxy or six-DOF point shell) continuous when the
// window republishes its scene. All evaluate in W and are real-time safe.
//
// Continuity. The window rebuilds its HapticScene on every edit and setting change, but a proxy
// and a point shell keep state between ticks (where the god-object or the virtual tool is). The
// window therefore keeps, per solid (proxy) or per scene (shell), a ContactChannel that outlives
// the scenes, and wraps each new field in a Continuous*Field holding:
//  - `reuse`: the field of the previous scene when neither the solid(s) nor the settings changed
//    (null otherwise), and
//  - `fresh`: a newly built field with the current solid(s) and settings.
// On its first tick the wrapper reads the channel's hand-off (what the field that ran the
// previous tick wrote there, on this same haptic thread). It goes on with `reuse` when that is
// the field that ran the previous tick (exact continuity). Otherwise it uses `fresh`, and, when
// the hand-off is recent (written by the previous tick: loop time at most max_gap earlier, tool
// point at most max_move away; a scene built for an earlier loop or a stale one is ignored),
// warm-starts it from the hand-off through the field's public Evaluate (an initialising call
// at the handed-over proxy or virtual tool pose, then the real one); see the classes. Without a
// recent hand-off the field starts as a fresh one does, which never pushes on a tool that is
// inside a solid: the proxy starts only once the tool point is outside (ProxyField), and the
// shell wrapper holds the point shell back (zero force) until no shell point touches.
// The hand-off is written and read by the haptic thread only; the marker for the view goes to
// the main thread through a lock-free TripleBuffer.
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <memory>
#include <stdexcept>
#include <string>
#include <utility>

#include "scene/device_session.h"
#include "spidarcad/haptics/device_to_world.h"
#include "spidarcad/haptics/distance_field.h"
#include "spidarcad/haptics/force_field.h"
#include "spidarcad/haptics/point_shell_field.h"
#include "spidarcad/haptics/proxy_field.h"
#include "spidarcad/haptics/triple_buffer.h"

namespace spidarcad::app {

// The demo field's springs (DemoSpringWrench) toward the device centre, expressed in W for the
// loop's X_WD (p_W = s p_D + p_WDo, no rotation, force_scale 1): f_W = −k (p_WT − p_WDo) / s,
// m_W = −k_r φ u, g = 2 k_g (θ − π/2), so that the force felt in D is −k p_D.
class CentringSpringField final : public haptics::ForceField {
 public:
  // For the loop's X_WD (scale s > 0). Throws std::invalid_argument for s <= 0 or not finite.
  CentringSpringField(const DemoFieldSettings& field, const haptics::DeviceToWorld& X_WD);
  haptics::ToolWrench Evaluate(const haptics::ToolKinematics& tool) noexcept override;
  const char* name() const noexcept override { return "centring_springs"; }

 private:
  DemoFieldSettings field_;
  haptics::DeviceToWorld X_WD_;
};

// What a contact field shows in the view: the god-object (proxy) or the virtual tool's centre
// (shell) and the tool point, in W.
struct ContactMarker {
  double time = -1.0;                                // loop time of the tick, s (−1: never ran)
  Eigen::Vector3d p_W = Eigen::Vector3d::Zero();     // proxy / virtual tool centre, m
  Eigen::Vector3d tool_W = Eigen::Vector3d::Zero();  // tool point (grip centre), m
  bool contact = false;                              // held on a surface / shell touching
  const void* field = nullptr;                       // the field that wrote it (identity only)
};

// State handed from a contact field to the one that replaces it (haptic thread only), and the
// marker for the view (haptic thread writes, main thread reads). Shared by the window and the
// wrappers of successive scenes.
struct ContactChannel {
  struct Handoff {
    const void* writer = nullptr;  // the field that ran the latest tick (identity only)
    double time = 0.0;             // its loop time, s
    Eigen::Vector3d tool_W = Eigen::Vector3d::Zero();         // tool point at that tick, m
    Eigen::Vector3d p_W = Eigen::Vector3d::Zero();            // proxy / virtual tool position, m
    Eigen::Quaterniond q_W = Eigen::Quaterniond::Identity();  // virtual tool rotation (shell)
    Eigen::Vector3d v_W = Eigen::Vector3d::Zero();            // virtual tool velocity (shell), m/s
    Eigen::Vector3d w_W = Eigen::Vector3d::Zero();  // virtual tool angular velocity, rad/s
    Eigen::Vector3d f_W = Eigen::Vector3d::Zero();  // wrench the field gave that tick, N
    Eigen::Vector3d m_W = Eigen::Vector3d::Zero();  // and its moment about p_WT, N·m
    bool contact = false;
    bool seedable = false;  // p_W (and q_W) hold a state a successor may start from
  };
  Handoff handoff;                              // haptic thread only
  haptics::TripleBuffer<ContactMarker> marker;  // one writer (haptic), one reader (main)
};

// When a hand-off counts as recent, and how far a warm start may move it. Lengths in W.
struct ContinuitySettings {
  double max_gap = 0.02;         // s between the hand-off's tick and the first tick, > 0
  double max_move = 0.01;        // m the tool point may have moved since, > 0
  double max_seed_move = 2e-3;   // m a handed-over proxy may be projected onto a changed surface
  double seed_clearance = 1e-6;  // m the warm-start seed is put outside the surface
  // Throws std::invalid_argument naming the field when one is not finite and > 0.
  void Validate() const;
};

// What both continuous fields hold: the field of the previous scene to go on with (`reuse`, may
// be null), the fresh one, its environment (W), the channel and the settings; and the marker
// they publish each tick. The constructor throws std::invalid_argument, naming `who`, when
// fresh, environment or channel is null or a setting is bad.
template <typename Field>
class ContinuousField : public haptics::ForceField {
 protected:
  ContinuousField(const char* who, std::shared_ptr<Field> reuse, std::shared_ptr<Field> fresh,
                  std::shared_ptr<const haptics::DistanceField> environment,
                  std::shared_ptr<ContactChannel> channel, const ContinuitySettings& settings)
      : reuse_(std::move(reuse)),
        fresh_(std::move(fresh)),
        env_(std::move(environment)),
        channel_(std::move(channel)),
        settings_(settings) {
    if (!fresh_ || !env_ || !channel_) {
      throw std::invalid_argument(std::string(who) +
                                  ": the fresh field, environment and channel must not be null");
    }
    settings_.Validate();
  }
  // Publishes the tick's marker for the view (haptic thread).
  void PublishMarker(double time, const Eigen::Vector3d& p_W, const Eigen::Vector3d& tool_W,
                     bool contact, const void* field) noexcept {
    ContactMarker& m = channel_->marker.WriteSlot();
    m.time = time;
    m.p_W = p_W;
    m.tool_W = tool_W;
    m.contact = contact;
    m.field = field;
    channel_->marker.Publish();
  }

  std::shared_ptr<Field> reuse_;
  std::shared_ptr<Field> fresh_;
  std::shared_ptr<const haptics::DistanceField> env_;
  std::shared_ptr<ContactChannel> channel_;
  ContinuitySettings settings_;
  Field* active_ = nullptr;
  bool warm_started_ = false;
};

// A ProxyField kept continuous across republishes (see the file comment). Warm start: the
// handed-over proxy x_h (when inside the new solid it is first projected onto its surface, at
// most max_seed_move away, else no warm start) is put seed_clearance outside the surface; the
// fresh proxy is initialised there by one Evaluate with the tool point at the seed, then the
// real Evaluate sweeps it from the seed toward the tool point and holds it on the surface where
// the sweep meets it (within about seed_clearance of x_h when x_h was in contact). Friction
// restarts as sticking.
class ContinuousProxyField final : public ContinuousField<haptics::ProxyField> {
 public:
  // `fresh` and `environment` (the proxy's solid, W) and `channel` not null; `reuse` may be
  // null. Throws std::invalid_argument otherwise or for bad settings.
  ContinuousProxyField(std::shared_ptr<haptics::ProxyField> reuse,
                       std::shared_ptr<haptics::ProxyField> fresh,
                       std::shared_ptr<const haptics::DistanceField> environment,
                       std::shared_ptr<ContactChannel> channel,
                       const ContinuitySettings& settings = {});
  haptics::ToolWrench Evaluate(const haptics::ToolKinematics& tool) noexcept override;
  const char* name() const noexcept override { return "proxy"; }
  // Haptic thread (or tests): the field in use, null before the first tick.
  const haptics::ProxyField* active() const noexcept { return active_; }
  // True when the first tick warm-started `fresh` from the hand-off.
  bool warm_started() const noexcept { return warm_started_; }

 private:
  void WarmStart(const ContactChannel::Handoff& h, const haptics::ToolKinematics& tool) noexcept;
};

// A PointShellField kept continuous across republishes (see the file comment). Warm start: the
// fresh virtual tool is initialised by one Evaluate with the grip at the handed-over pose of V,
// 1 ms before the real tick, unless a shell point at that pose lies deeper than max_seed_move
// in the (changed) environment. That call integrates one tick with the coupling at rest, the
// contact acting alone; V therefore starts with the handed-over velocity less the impulse the
// contact gives it in that tick (≈ the handed-over felt wrench, which balanced the contact:
// Δv = f dt / m, Δω = I_W⁻¹ m dt), and ends it close to the handed-over state. Not warm-started,
// the shell is held back (zero force, no Evaluate) while any shell point at the grip's pose touches
// the environment.
class ContinuousShellField final : public ContinuousField<haptics::PointShellField> {
 public:
  // `fresh`, `environment` (the union of the solids, W) and `channel` not null; `reuse` may be
  // null. Throws std::invalid_argument otherwise or for bad settings.
  ContinuousShellField(std::shared_ptr<haptics::PointShellField> reuse,
                       std::shared_ptr<haptics::PointShellField> fresh,
                       std::shared_ptr<const haptics::DistanceField> environment,
                       std::shared_ptr<ContactChannel> channel,
                       const ContinuitySettings& settings = {});
  haptics::ToolWrench Evaluate(const haptics::ToolKinematics& tool) noexcept override;
  const char* name() const noexcept override { return "point_shell"; }
  // Haptic thread (or tests): the field in use, null before the first tick.
  const haptics::PointShellField* active() const noexcept { return active_; }
  bool warm_started() const noexcept { return warm_started_; }

 private:
  bool WarmStart(const ContactChannel::Handoff& h, const haptics::ToolKinematics& tool) noexcept;

  bool decided_ = false;
  bool started_ = false;  // fresh: Evaluate has run (held back while the shell touched)
};

}  // namespace spidarcad::app
