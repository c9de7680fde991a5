// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#include "scene/scene_fields.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>
#include <utility>

namespace spidarcad::app {

namespace {
constexpr double kHalfPi = 0.5 * 3.14159265358979323846;

// True when `h` was written by the tick just before `tool` (same loop, tool point nearby).
bool Recent(const ContactChannel::Handoff& h, const haptics::ToolKinematics& tool,
            const Eigen::Vector3d& x_t, const ContinuitySettings& s) noexcept {
  if (h.writer == nullptr) return false;
  const double gap = tool.time - h.time;
  return gap > 0.0 && gap <= s.max_gap && (x_t - h.tool_W).norm() <= s.max_move;
}

void RequirePositive(double value, const char* name) {
  if (!(value > 0.0) || !std::isfinite(value)) {
    throw std::invalid_argument(std::string("ContinuitySettings.") + name +
                                " must be finite and > 0, got " + std::to_string(value));
  }
}
}  // namespace

CentringSpringField::CentringSpringField(const DemoFieldSettings& field,
                                         const haptics::DeviceToWorld& X_WD)
    : field_(field), X_WD_(X_WD) {
  if (!(X_WD.world_scale > 0.0) || !std::isfinite(X_WD.world_scale)) {
    throw std::invalid_argument("CentringSpringField: world_scale must be > 0, got " +
                                std::to_string(X_WD.world_scale));
  }
}

haptics::ToolWrench CentringSpringField::Evaluate(const haptics::ToolKinematics& tool) noexcept {
  haptics::ToolWrench w;
  if (!field_.enabled) return w;
  w.f_T_W = -field_.k_translation * (tool.p_WT - X_WD_.p_WDo) / X_WD_.world_scale;
  const Eigen::AngleAxisd aa(tool.R_WT);
  w.m_T_W = -field_.k_rotation * aa.angle() * aa.axis();
  w.g = 2.0 * field_.k_grasp * (tool.grasp - kHalfPi);
  return w;
}

void ContinuitySettings::Validate() const {
  RequirePositive(max_gap, "max_gap");
  RequirePositive(max_move, "max_move");
  RequirePositive(max_seed_move, "max_seed_move");
  RequirePositive(seed_clearance, "seed_clearance");
}

// ---- proxy ----

ContinuousProxyField::ContinuousProxyField(
    std::shared_ptr<haptics::ProxyField> reuse, std::shared_ptr<haptics::ProxyField> fresh,
    std::shared_ptr<const haptics::DistanceField> environment,
    std::shared_ptr<ContactChannel> channel, const ContinuitySettings& settings)
    : ContinuousField("ContinuousProxyField", std::move(reuse), std::move(fresh),
                      std::move(environment), std::move(channel), settings) {}

void ContinuousProxyField::WarmStart(const ContactChannel::Handoff& h,
                                     const haptics::ToolKinematics& tool) noexcept {
  // The handed-over proxy, projected onto the (possibly changed) surface when it is inside.
  Eigen::Vector3d seed = h.p_W;
  Eigen::Vector3d g;
  double phi = env_->Evaluate(seed, &g);
  for (int i = 0; i < 8 && phi < 0.0; ++i) {
    const double g2 = g.squaredNorm();
    if (!(g2 > 0.0)) return;
    seed -= (phi / g2) * g;
    phi = env_->Evaluate(seed, &g);
  }
  if (!std::isfinite(phi) || (seed - h.p_W).norm() > settings_.max_seed_move) return;
  // Just outside, so that the proxy initialises there (ProxyField starts only in free space).
  if (phi < settings_.seed_clearance) {
    const double g2 = g.squaredNorm();
    if (!(g2 > 0.0)) return;
    seed += ((settings_.seed_clearance - phi) / g2) * g;
    if (!(env_->Evaluate(seed, nullptr) >= 0.0)) return;
  }
  haptics::ToolKinematics at_seed = tool;
  at_seed.p_WT = seed - tool.R_WT * fresh_->settings().tip_T;
  at_seed.v_WT.setZero();
  at_seed.w_WT.setZero();
  fresh_->Evaluate(at_seed);  // no force: the tool point is at the free proxy
  warm_started_ = true;
}

haptics::ToolWrench ContinuousProxyField::Evaluate(const haptics::ToolKinematics& tool) noexcept {
  const Eigen::Vector3d x_t = tool.p_WT + tool.R_WT * fresh_->settings().tip_T;
  ContactChannel::Handoff& h = channel_->handoff;
  if (active_ == nullptr) {
    const bool recent = Recent(h, tool, x_t, settings_);
    if (reuse_ && recent && h.writer == reuse_.get()) {
      active_ = reuse_.get();
    } else {
      active_ = fresh_.get();
      if (recent && h.seedable) WarmStart(h, tool);
    }
  }
  const haptics::ToolWrench w = active_->Evaluate(tool);
  const Eigen::Vector3d& proxy = active_->proxy_W();
  const bool contact = active_->in_contact();
  h.writer = active_;
  h.time = tool.time;
  h.tool_W = x_t;
  h.p_W = proxy;
  h.contact = contact;
  // A free proxy sits on the tool point; one that does not has not started (the tool point was
  // inside since the field began) or stopped short: nothing a successor should start from.
  h.seedable = contact || proxy == x_t;
  PublishMarker(tool.time, proxy, x_t, contact, active_);
  return w;
}

// ---- point shell ----

ContinuousShellField::ContinuousShellField(
    std::shared_ptr<haptics::PointShellField> reuse,
    std::shared_ptr<haptics::PointShellField> fresh,
    std::shared_ptr<const haptics::DistanceField> environment,
    std::shared_ptr<ContactChannel> channel, const ContinuitySettings& settings)
    : ContinuousField("ContinuousShellField", std::move(reuse), std::move(fresh),
                      std::move(environment), std::move(channel), settings) {}

bool ContinuousShellField::WarmStart(const ContactChannel::Handoff& h,
                                     const haptics::ToolKinematics& tool) noexcept {
  const Eigen::Matrix3d R_WV = h.q_W.normalized().toRotationMatrix();
  const haptics::PointShell& shell = fresh_->shell();
  for (const Eigen::Vector3d& r : shell.points_T) {
    const double phi = env_->Evaluate(h.p_W + R_WV * r, nullptr);
    if (!(phi >= -settings_.max_seed_move)) return false;  // deep in a changed solid (or NaN)
  }
  // The initialising call integrates one tick with the coupling at rest, so the contact acts
  // alone on V: start V with the velocity that this tick's contact impulse (≈ the felt wrench,
  // which balanced the contact in the old field) brings back to the handed-over one.
  const haptics::PointShellSettings& ps = fresh_->settings();
  const double dt = 1e-3;
  const Eigen::Matrix3d inv_inertia_W =
      R_WV * ps.inertia.cwiseInverse().asDiagonal() * R_WV.transpose();
  haptics::ToolKinematics at_v = tool;
  at_v.time = tool.time - dt;
  at_v.p_WT = h.p_W;
  at_v.R_WT = R_WV;
  at_v.v_WT = h.v_W - dt / ps.mass * h.f_W;
  at_v.w_WT = h.w_W - dt * (inv_inertia_W * h.m_W);
  fresh_->Evaluate(at_v);  // initialises V at the handed-over state
  warm_started_ = true;
  return true;
}

haptics::ToolWrench ContinuousShellField::Evaluate(const haptics::ToolKinematics& tool) noexcept {
  ContactChannel::Handoff& h = channel_->handoff;
  if (!decided_) {
    decided_ = true;
    const bool recent = Recent(h, tool, tool.p_WT, settings_);
    if (reuse_ && recent && h.writer == reuse_.get() && h.seedable) {  // seedable: it had started
      active_ = reuse_.get();
      started_ = true;
    } else {
      active_ = fresh_.get();
      started_ = recent && h.seedable && WarmStart(h, tool);
    }
  }
  if (!started_) {
    // Held back until the shell at the grip's pose touches nothing (no jolt from inside).
    Eigen::Isometry3d X_WT = Eigen::Isometry3d::Identity();
    X_WT.linear() = tool.R_WT;
    X_WT.translation() = tool.p_WT;
    started_ =
        tool.p_WT.allFinite() && tool.R_WT.allFinite() && active_->ContactAt(X_WT).contacts == 0;
  }
  haptics::ToolWrench w;
  if (started_) w = active_->Evaluate(tool);
  h.writer = active_;
  h.time = tool.time;
  h.tool_W = tool.p_WT;
  h.p_W = active_->p_WV();
  h.q_W = active_->q_WV();
  h.v_W = active_->v_WV();
  h.w_W = active_->w_WV();
  h.f_W = w.f_T_W;
  h.m_W = w.m_T_W;
  h.contact = started_ && active_->contacts() > 0;
  h.seedable = started_;
  PublishMarker(tool.time, started_ ? active_->p_WV() : tool.p_WT, tool.p_WT, h.contact, active_);
  return w;
}

}  // namespace spidarcad::app
