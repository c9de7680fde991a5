// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#include "spidarcad/haptics/haptic_loop.h"

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>

namespace spidarcad::haptics {

namespace {

void Require(bool ok, const char* field, double value, const char* what) {
  if (!ok) {
    throw std::invalid_argument(std::string("LoopSettings.") + field + " = " +
                                std::to_string(value) + ": " + what);
  }
}

// Scales v down so that |v| <= limit; returns true if it did.
bool LimitNorm(Eigen::Ref<Eigen::Vector3d> v, double limit) noexcept {
  const double n = v.norm();
  if (n > limit) {
    v *= limit / n;
    return true;
  }
  return false;
}

}  // namespace

SpringField::SpringField(const Eigen::Vector3d& p_WA, double stiffness, double damping)
    : p_WA_(p_WA), stiffness_(stiffness), damping_(damping) {
  if (!p_WA.allFinite()) throw std::invalid_argument("SpringField: anchor is not finite");
  if (!(stiffness >= 0 && std::isfinite(stiffness))) {
    throw std::invalid_argument("SpringField: stiffness " + std::to_string(stiffness) +
                                " N/m is not finite and >= 0");
  }
  if (!(damping >= 0 && std::isfinite(damping))) {
    throw std::invalid_argument("SpringField: damping " + std::to_string(damping) +
                                " N·s/m is not finite and >= 0");
  }
}

ToolWrench SpringField::Evaluate(const ToolKinematics& tool) noexcept {
  ToolWrench w;
  w.f_T_W = -stiffness_ * (tool.p_WT - p_WA_) - damping_ * tool.v_WT;
  return w;
}

PlaneWallField::PlaneWallField(const Eigen::Vector3d& p_WP, const Eigen::Vector3d& n_W,
                               double stiffness, double damping)
    : p_WP_(p_WP), n_W_(n_W), stiffness_(stiffness), damping_(damping) {
  if (!p_WP.allFinite()) throw std::invalid_argument("PlaneWallField: point is not finite");
  if (!n_W.allFinite() || n_W.norm() < 1e-12) {
    throw std::invalid_argument("PlaneWallField: normal is zero or not finite");
  }
  n_W_.normalize();
  if (!(stiffness >= 0 && std::isfinite(stiffness))) {
    throw std::invalid_argument("PlaneWallField: stiffness " + std::to_string(stiffness) +
                                " N/m is not finite and >= 0");
  }
  if (!(damping >= 0 && std::isfinite(damping))) {
    throw std::invalid_argument("PlaneWallField: damping " + std::to_string(damping) +
                                " N·s/m is not finite and >= 0");
  }
}

ToolWrench PlaneWallField::Evaluate(const ToolKinematics& tool) noexcept {
  ToolWrench w;
  const double depth = -n_W_.dot(tool.p_WT - p_WP_);
  if (depth > 0) {
    const double push = stiffness_ * depth - damping_ * n_W_.dot(tool.v_WT);
    if (push > 0) w.f_T_W = push * n_W_;
  }
  return w;
}

ToolWrench HapticScene::Evaluate(const ToolKinematics& tool) const noexcept {
  ToolWrench sum;
  for (const auto& field : fields_) sum += field->Evaluate(tool);
  return sum;
}

std::unique_ptr<HapticScene> MakeDemoScene() {
  auto scene = std::make_unique<HapticScene>();
  scene->Add(std::make_unique<PlaneWallField>(Eigen::Vector3d(0, 0, -0.03),
                                              Eigen::Vector3d::UnitZ(), 2000.0, 5.0));
  scene->Add(std::make_unique<SpringField>(Eigen::Vector3d(0.05, 0, 0), 20.0, 0.5));
  return scene;
}

const char* SafetyEventName(int index) {
  static constexpr const char* kNames[kNumSafetyEvents] = {
      "nan",    "fk_refused",     "device_error",      "deadline_missed", "emergency_stop",
      "bad_dt", "wrench_limited", "tension_saturated", "ramping",         "energy_limited",
      "slack"};
  return index >= 0 && index < kNumSafetyEvents ? kNames[index] : "unknown";
}

void LoopSettings::Validate() const {
  Require(X_WD.world_scale > 0 && std::isfinite(X_WD.world_scale), "world_scale", X_WD.world_scale,
          "must be finite and > 0");
  Require(X_WD.p_WDo.allFinite(), "p_WDo", X_WD.p_WDo.norm(), "must be finite");
  Require(std::isfinite(force_scale) && force_scale >= 0, "force_scale", force_scale,
          "must be finite and >= 0");
  Require(velocity_cutoff > 0 && std::isfinite(velocity_cutoff), "velocity_cutoff", velocity_cutoff,
          "must be finite and > 0 (Hz)");
  Require(linear_damping >= 0 && std::isfinite(linear_damping), "linear_damping", linear_damping,
          "must be finite and >= 0");
  Require(angular_damping >= 0 && std::isfinite(angular_damping), "angular_damping",
          angular_damping, "must be finite and >= 0");
  Require(grasp_damping >= 0 && std::isfinite(grasp_damping), "grasp_damping", grasp_damping,
          "must be finite and >= 0");
  Require(max_force >= 0 && std::isfinite(max_force), "max_force", max_force,
          "must be finite and >= 0");
  Require(max_moment >= 0 && std::isfinite(max_moment), "max_moment", max_moment,
          "must be finite and >= 0");
  Require(max_grasp_torque >= 0 && std::isfinite(max_grasp_torque), "max_grasp_torque",
          max_grasp_torque, "must be finite and >= 0");
  Require(ramp_time >= 0 && std::isfinite(ramp_time), "ramp_time", ramp_time,
          "must be finite and >= 0");
  Require(max_observer_damping >= 0 && std::isfinite(max_observer_damping), "max_observer_damping",
          max_observer_damping, "must be finite and >= 0");
  Require(max_lateness > 0, "max_lateness", max_lateness, "must be > 0");
  Require(max_dt > 0 && std::isfinite(max_dt), "max_dt", max_dt, "must be finite and > 0");
  tension.Validate();
}

HapticLoop::HapticLoop(const DeviceInfo& info, const EncoderCalibration& calibration,
                       const LoopSettings& settings)
    : info_(info),
      calibration_(calibration),
      settings_(settings),
      fk_((info.geometry.Validate(), info.geometry), settings.fk),
      solver_([&] {
        settings.Validate();
        TensionSettings t = settings.tension;
        t.tau_min = std::max(t.tau_min, info.tension_min);
        t.tau_max = std::min(t.tau_max, info.tension_max);
        t.Validate();
        return t;
      }()) {
  calibration_.Validate();
  last_tau_ = Vector8d::Constant(solver_.settings().tau_min);
  previous_pose_ = info.home_pose;
  ToolState initial;
  initial.tau = last_tau_;
  for (int i = 0; i < 3; ++i) tool_state_.Write(initial);
}

HapticLoop::~HapticLoop() = default;

void HapticLoop::Publish(std::unique_ptr<HapticScene> scene) { scenes_.Offer(std::move(scene)); }

bool HapticLoop::CollectRetired() { return scenes_.Collect(); }

void HapticLoop::ZeroForce(ToolState* out) noexcept {
  out->wrench_D.setZero();
  out->tau = Vector8d::Constant(solver_.settings().tau_min);
  ramp_ = 0.0;
  energy_ = 0.0;
}

TickOutputs HapticLoop::Step(const TickInputs& inputs, double dt) noexcept {
  ToolState out;
  out.tick = tick_++;
  HapticScene* const scene = scenes_.Acquire();
  std::uint32_t events = 0;
  const bool dt_ok = std::isfinite(dt) && dt > 0 && dt <= settings_.max_dt;
  if (dt_ok) {
    time_ += dt;
  } else {
    events |= kEventBadDt;
  }
  out.time = time_;
  if (stop_.load(std::memory_order_acquire) || inputs.emergency_stop) events |= kEventEmergencyStop;
  if (inputs.reading.status != DeviceStatus::kOk) events |= kEventDeviceError;
  if (!(inputs.lateness <= settings_.max_lateness)) events |= kEventDeadlineMissed;
  if (inputs.reading.slack_mask != 0) events |= kEventSlack;

  // Sensing: counts -> lengths (stretch under the last commanded tensions) -> pose.
  const Vector8d lengths = calibration_.Lengths(inputs.reading.counts, last_tau_);
  bool have_pose = false;
  if (!lengths.allFinite()) {
    events |= kEventNan;
  } else {
    const FkResult fk = fk_.Solve(lengths);
    out.fk_status = fk.status;
    if (fk.status == FkStatus::kOk) {
      have_pose = true;
      out.pose_D = fk.pose;
    } else {
      events |= kEventFkRefused;
    }
  }

  if (have_pose) {
    const GripPose& pose = out.pose_D;
    const Eigen::Matrix3d R_DT = pose.Rotation();
    const double grasp = pose.Grasp();
    // Velocities: finite differences through a first-order low-pass.
    if (has_previous_ && dt_ok) {
      const double tau_f = 1.0 / (2.0 * M_PI * settings_.velocity_cutoff);
      const double alpha = dt / (dt + tau_f);
      const Eigen::Vector3d v_raw = (pose.p0 - previous_pose_.p0) / dt;
      const Eigen::AngleAxisd rel(R_DT * previous_pose_.Rotation().transpose());
      const Eigen::Vector3d w_raw = rel.angle() * rel.axis() / dt;
      const double g_raw = (grasp - previous_pose_.Grasp()) / dt;
      v_D_ += alpha * (v_raw - v_D_);
      w_D_ += alpha * (w_raw - w_D_);
      grasp_rate_ += alpha * (g_raw - grasp_rate_);
    } else if (!has_previous_) {
      v_D_.setZero();
      w_D_.setZero();
      grasp_rate_ = 0.0;
    }
    previous_pose_ = pose;
    has_previous_ = true;

    ToolKinematics& tool = out.tool_W;
    tool.time = time_;
    tool.p_WT = settings_.X_WD.PointToWorld(pose.p0);
    tool.R_WT = R_DT;
    tool.grasp = grasp;
    tool.v_WT = settings_.X_WD.VectorToWorld(v_D_);
    tool.w_WT = w_D_;
    tool.grasp_rate = grasp_rate_;

    ToolWrench w_W;
    if (scene != nullptr) w_W = scene->Evaluate(tool);
    if (!w_W.f_T_W.allFinite() || !w_W.m_T_W.allFinite() || !std::isfinite(w_W.g)) {
      events |= kEventNan;
    } else {
      Vector7d q;
      q.head<3>() = settings_.force_scale * w_W.f_T_W - settings_.linear_damping * v_D_;
      q.segment<3>(3) = settings_.force_scale * w_W.m_T_W - settings_.angular_damping * w_D_;
      q(6) = w_W.g + settings_.grasp_damping * grasp_rate_;  // g > 0 closes: opposes opening
      out.wrench_D = q;
    }
  } else {
    has_previous_ = false;
  }

  if (IsZeroForceEvent(events)) {
    ZeroForce(&out);
  } else {
    // Force ramp.
    ramp_ = settings_.ramp_time > 0 ? std::min(1.0, ramp_ + dt / settings_.ramp_time) : 1.0;
    if (ramp_ < 1.0) events |= kEventRamping;
    Vector7d q = ramp_ * out.wrench_D;
    // Wrench limit.
    bool limited = LimitNorm(q.head<3>(), settings_.max_force);
    limited |= LimitNorm(q.segment<3>(3), settings_.max_moment);
    if (std::abs(q(6)) > settings_.max_grasp_torque) {
      q(6) = std::copysign(settings_.max_grasp_torque, q(6));
      limited = true;
    }
    // Passivity observer on the translational port: energy absorbed by the scene from the
    // user. f is the force on the grip, so the user puts −f·v into the scene.
    if (settings_.passivity_observer) {
      double energy = energy_ - q.head<3>().dot(v_D_) * dt;
      const double v2 = v_D_.squaredNorm();
      if (energy < 0 && v2 > 1e-12) {
        const double alpha = std::min(-energy / (v2 * dt), settings_.max_observer_damping);
        q.head<3>() -= alpha * v_D_;
        limited |= LimitNorm(q.head<3>(), settings_.max_force);
        energy = energy_ - q.head<3>().dot(v_D_) * dt;
        events |= kEventEnergyLimited;
      }
      energy_ = energy;
    }
    if (limited) events |= kEventWrenchLimited;
    out.wrench_D = q;

    const Matrix78d A = WrenchMatrix(info_.geometry, out.pose_D);
    const TensionResult r = solver_.Solve(A, q);
    out.tension_status = r.status;
    if (r.status == TensionStatus::kInvalidInput || !r.tau.allFinite()) {
      events |= kEventNan;
      ZeroForce(&out);
    } else {
      if (r.status == TensionStatus::kSaturated) events |= kEventTensionSaturated;
      // Tension bounds hold whatever the solver returned.
      out.tau = r.tau.cwiseMax(solver_.settings().tau_min).cwiseMin(solver_.settings().tau_max);
      out.displayed_D = A * out.tau;
    }
  }
  out.events = events;
  out.ramp = ramp_;
  out.energy = energy_;
  last_tau_ = out.tau;
  for (int i = 0; i < kNumSafetyEvents; ++i) {
    if (events & (1u << i)) ++event_counts_[i];
  }
  tool_state_.Write(out);
  return out;
}

}  // namespace spidarcad::haptics
