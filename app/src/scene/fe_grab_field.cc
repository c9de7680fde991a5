// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#include "scene/fe_grab_field.h"

#include <Eigen/Geometry>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <sstream>
#include <stdexcept>

#include "scene/grip_poles.h"
#include "spidarcad/fem/grab.h"

namespace spidarcad::app {
namespace {

[[noreturn]] void BadSetting(const char* field, double value, const char* rule) {
  std::ostringstream msg;
  msg << "FE grab field: " << field << " = " << value << " (" << rule << ")";
  throw std::invalid_argument(msg.str());
}

// Scales v to magnitude at most `bound`.
Eigen::Vector3d Clamped(const Eigen::Vector3d& v, double bound) {
  const double n = v.norm();
  return n > bound ? Eigen::Vector3d(v * (bound / n)) : v;
}

// Worker's poll period while idle or waiting for columns.
constexpr auto kWorkerPoll = std::chrono::microseconds(500);

}  // namespace

FeGrabField::FeGrabField(std::shared_ptr<FeModel> model, const FeGrabSettings& settings,
                         std::shared_ptr<FeGrabChannel> channel)
    : model_(std::move(model)), cache_(nullptr), settings_(settings), channel_(std::move(channel)) {
  if (!model_) throw std::invalid_argument("FE grab field: no model");
  if (!(settings_.tool_radius > 0.0) || !std::isfinite(settings_.tool_radius))
    BadSetting("tool_radius", settings_.tool_radius, "must be > 0 m");
  if (settings_.max_patch < 1 || settings_.max_patch > kMaxFeGrabNodes)
    BadSetting("max_patch", settings_.max_patch, "must be in 1..64");
  if (!(settings_.force_scale >= 0.0) || !std::isfinite(settings_.force_scale))
    BadSetting("force_scale", settings_.force_scale, "must be >= 0");
  if (!(settings_.max_force > 0.0)) BadSetting("max_force", settings_.max_force, "must be > 0 N");
  if (!(settings_.max_torque > 0.0))
    BadSetting("max_torque", settings_.max_torque, "must be > 0 N·m");
  if (!(settings_.coupling_stiffness >= 0.0) || !std::isfinite(settings_.coupling_stiffness))
    BadSetting("coupling_stiffness", settings_.coupling_stiffness, "must be >= 0 N/m");
  if (settings_.coupling_stiffness > 0.0 && (!(settings_.coupling_rot_stiffness > 0.0) ||
                                             !std::isfinite(settings_.coupling_rot_stiffness)))
    BadSetting("coupling_rot_stiffness", settings_.coupling_rot_stiffness,
               "must be > 0 N·m/rad with a coupling");
  if (!(settings_.close_angle > 0.0))
    BadSetting("close_angle", settings_.close_angle, "must be > 0 rad");
  if (!(settings_.open_angle >= settings_.close_angle) || !std::isfinite(settings_.open_angle))
    BadSetting("open_angle", settings_.open_angle, "must be >= close_angle, finite");
  if (settings_.grasp && !(settings_.pole_length > 0.0))
    BadSetting("pole_length", settings_.pole_length, "must be > 0 m");
  if (!(settings_.ramp_seconds >= 0.0) || !std::isfinite(settings_.ramp_seconds))
    BadSetting("ramp_seconds", settings_.ramp_seconds, "must be >= 0 s");
  if (!(settings_.column_wait_seconds >= 0.0))
    BadSetting("column_wait_seconds", settings_.column_wait_seconds, "must be >= 0 s");

  cache_ = &model_->cache();
  solver_ = std::make_unique<fem::CachedContactSolver>(cache_, settings_.max_patch);
  const int n = cache_->num_candidates();
  const Eigen::MatrixX3d& nodes = model_->mesh().nodes;
  positions_.resize(n);
  for (int b = 0; b < n; ++b) positions_[b] = nodes.row(cache_->candidate_node(b)).transpose();
  if (settings_.worker) worker_ = std::thread([this] { WorkerLoop(); });
}

FeGrabField::~FeGrabField() {
  stop_.store(true);
  if (worker_.joinable()) worker_.join();
}

Eigen::Vector3d FeGrabField::PoleTip(const haptics::ToolKinematics& tool, int i) const {
  return GripPoleTip(tool, settings_.pole_length, i);
}

int FeGrabField::CollectPatch(const haptics::ToolKinematics& tool) {
  Eigen::Vector3d centre[2] = {tool.p_WT, tool.p_WT};
  const int spheres = settings_.grasp ? 2 : 1;
  if (settings_.grasp) {
    centre[0] = PoleTip(tool, 0);
    centre[1] = PoleTip(tool, 1);
  }
  const double r = settings_.tool_radius;
  const int max_n = settings_.max_patch;
  int count = 0;
  // A scan of the candidates (once per grab, not per tick): keep the max_n nearest to a centre.
  for (int b = 0; b < static_cast<int>(positions_.size()); ++b) {
    if (cache_->IsFixed(b)) continue;
    double dist = 1e300;
    for (int i = 0; i < spheres; ++i) dist = std::min(dist, (positions_[b] - centre[i]).norm());
    if (!(dist < r)) continue;
    if (count == max_n && dist >= pending_dist_[count - 1]) continue;
    int j = std::min(count, max_n - 1);
    while (j > 0 && pending_dist_[j - 1] > dist) {
      pending_nodes_[j] = pending_nodes_[j - 1];
      pending_dist_[j] = pending_dist_[j - 1];
      --j;
    }
    pending_nodes_[j] = b;
    pending_dist_[j] = dist;
    count = std::min(count + 1, max_n);
  }
  pending_count_ = count;
  return count;
}

void FeGrabField::BuildSolver() {
  solver_->Clear();
  for (int i = 0; i < request_count_; ++i) solver_->Add(request_[i]);  // refused nodes are left out
  couple_.setIdentity();
  const int n = solver_->num_contacts();
  centroid_.setZero();
  for (int s = 0; s < n; ++s) centroid_ += positions_[solver_->contact(s)];
  if (n > 0) centroid_ /= n;
  if (!(settings_.coupling_stiffness > 0.0) || n == 0) return;
  // K₆: the wrench (F; M about c) of the unit motions u_v = t + r × (x_v − c), from u0.
  const Eigen::Vector3d c = centroid_;
  Eigen::Matrix<double, 6, 6> k6;
  for (int j = 0; j < 6; ++j) {
    for (int s = 0; s < n; ++s) {
      const int b = solver_->contact(s);
      Eigen::Vector3d u = Eigen::Vector3d::Zero();
      if (j < 3) {
        u(j) = 1.0;
      } else {
        u = Eigen::Vector3d::Unit(j - 3).cross(positions_[b] - c);
      }
      u += cache_->baseline().segment<3>(3 * cache_->OutputIndexOfCandidate(b));
      for (int i = 0; i < 3; ++i) probe_target_[3 * s + i] = u(i);
    }
    if (!solver_->Solve(probe_target_.data(), probe_force_.data())) return;
    Eigen::Vector3d f_sum = Eigen::Vector3d::Zero(), m_sum = Eigen::Vector3d::Zero();
    for (int s = 0; s < n; ++s) {
      const Eigen::Vector3d f(probe_force_[3 * s], probe_force_[3 * s + 1],
                              probe_force_[3 * s + 2]);
      f_sum += f;
      m_sum += (positions_[solver_->contact(s)] - c).cross(f);
    }
    k6.col(j) << f_sum, m_sum;
  }
  Eigen::Matrix<double, 6, 6> kc = Eigen::Matrix<double, 6, 6>::Zero();
  kc.diagonal() << Eigen::Vector3d::Constant(settings_.coupling_stiffness),
      Eigen::Vector3d::Constant(settings_.coupling_rot_stiffness);
  // ξ_c = (K_c + σK₆)⁻¹ K_c ξ; K₆ is symmetrised (it is symmetric up to round-off).
  const Eigen::Matrix<double, 6, 6> a = kc + settings_.force_scale * 0.5 * (k6 + k6.transpose());
  couple_ = a.partialPivLu().solve(kc);
}

void FeGrabField::WorkerLoop() {
  unsigned built = built_gen_.load(std::memory_order_relaxed);
  while (!stop_.load(std::memory_order_relaxed)) {
    const unsigned gen = request_gen_.load(std::memory_order_acquire);
    if (gen == built) {
      std::this_thread::sleep_for(kWorkerPoll);
      continue;
    }
    // Wait (bounded) for the patch's own columns; the haptic thread focuses the cache on it.
    const auto until = std::chrono::steady_clock::now() +
                       std::chrono::duration<double>(settings_.column_wait_seconds);
    for (;;) {
      bool all = true;
      for (int i = 0; i < request_count_ && all; ++i) all = cache_->IsReady(request_[i]);
      if (all || stop_.load(std::memory_order_relaxed) || std::chrono::steady_clock::now() > until)
        break;
      std::this_thread::sleep_for(kWorkerPoll);
    }
    BuildSolver();
    built = gen;
    built_gen_.store(gen, std::memory_order_release);
  }
}

haptics::ToolWrench FeGrabField::Evaluate(const haptics::ToolKinematics& tool) noexcept {
  haptics::ToolWrench w;
  FeGrabState& st = state_;
  st.time = tool.time;
  st.p_WT = tool.p_WT;
  st.ready = false;
  st.ramp = 0.0;
  st.force_body.setZero();
  st.moment_body.setZero();
  st.f_tool_W.setZero();
  st.m_tool_W.setZero();
  const bool finite = tool.p_WT.allFinite() && tool.R_WT.allFinite() && std::isfinite(tool.grasp);

  // Grip state (hysteresis); a non-finite tool state lets go.
  bool just_closed = false;
  if (!finite) {
    closed_ = false;
  } else if (!closed_ && tool.grasp < settings_.close_angle) {
    closed_ = just_closed = true;
  } else if (closed_ && tool.grasp > settings_.open_angle) {
    closed_ = false;
  }
  if (!closed_) {
    pending_ = false;
    held_gen_ = 0;
    was_ready_ = false;
  }
  if (just_closed && CollectPatch(tool) > 0) {
    pending_ = true;
    p0_ = tool.p_WT;
    R0_ = tool.R_WT;
    st.num_nodes = pending_count_;
    for (int i = 0; i < pending_count_; ++i) {
      st.candidate[i] = pending_nodes_[i];
      st.substitute[i] = -1;
    }
  }
  // Issue the patch once the worker is idle (it never touches request_ or solver_ then).
  if (pending_ &&
      built_gen_.load(std::memory_order_acquire) == request_gen_.load(std::memory_order_relaxed)) {
    request_count_ = pending_count_;
    for (int i = 0; i < pending_count_; ++i) request_[i] = pending_nodes_[i];
    const unsigned gen = request_gen_.load(std::memory_order_relaxed) + 1;
    if (settings_.worker) {
      request_gen_.store(gen, std::memory_order_release);
    } else {
      request_gen_.store(gen, std::memory_order_relaxed);
      BuildSolver();
      built_gen_.store(gen, std::memory_order_release);
    }
    held_gen_ = gen;
    pending_ = false;
  }
  st.closed = closed_;
  st.held = closed_ && (pending_ || held_gen_ != 0);
  if (!st.held) {
    st.num_nodes = 0;
    st.num_substituted = 0;
    if (channel_) channel_->buffer.Write(st);
    return w;
  }
  const bool ready = held_gen_ != 0 && built_gen_.load(std::memory_order_acquire) == held_gen_;
  if (!ready) {
    // Columns of the patch wanted: focus the cache there (this thread is its single producer).
    const double reach = settings_.tool_radius + (settings_.grasp ? settings_.pole_length : 0.0);
    cache_->RequestNear(p0_, reach);
    std::fill(st.force.begin(), st.force.begin() + 3 * st.num_nodes, 0.0);
    if (channel_) channel_->buffer.Write(st);
    return w;
  }
  if (!was_ready_) {
    was_ready_ = true;
    ready_time_ = tool.time;
  }

  // The grip's motion since the grab, and the patch's targets.
  const int n = solver_->num_contacts();
  st.num_nodes = n;
  st.num_substituted = solver_->num_substituted();
  const Eigen::Matrix3d R_rel = tool.R_WT * R0_.transpose();
  const Eigen::Matrix3d A = R_rel - Eigen::Matrix3d::Identity();
  const Eigen::Vector3d dp = tool.p_WT - p0_;
  const Eigen::Vector3d c = centroid_;
  st.centroid = c;
  // The grip's motion as a motion about c, then the FE state's (coupled) motion.
  const Eigen::AngleAxisd aa(R_rel);
  st.r_grip = aa.angle() * aa.axis();
  st.t_grip = dp + A * (c - p0_);
  Eigen::Matrix<double, 6, 1> xi;
  xi << st.t_grip, st.r_grip;
  const Eigen::Matrix<double, 6, 1> xi_c = couple_ * xi;
  st.t = xi_c.head<3>();
  st.r = xi_c.tail<3>();
  const Eigen::Matrix3d A_c = fem::RotationFromVector(st.r) - Eigen::Matrix3d::Identity();
  for (int s = 0; s < n; ++s) {
    const int b = solver_->contact(s);
    st.candidate[s] = b;
    st.substitute[s] = solver_->substitute(s);
    const Eigen::Vector3d u = cache_->baseline().segment<3>(3 * cache_->OutputIndexOfCandidate(b)) +
                              A_c * (positions_[b] - c) + st.t;
    for (int i = 0; i < 3; ++i) st.target[3 * s + i] = u(i);
  }
  if (n == 0 || !solver_->Solve(st.target.data(), st.force.data())) {
    if (channel_) channel_->buffer.Write(st);
    return w;
  }
  st.ready = true;
  for (int s = 0; s < n; ++s) {
    const Eigen::Vector3d f(st.force[3 * s], st.force[3 * s + 1], st.force[3 * s + 2]);
    const Eigen::Vector3d x = positions_[st.candidate[s]];
    const Eigen::Vector3d u(st.target[3 * s], st.target[3 * s + 1], st.target[3 * s + 2]);
    st.force_body += f;
    st.moment_body += (x - c).cross(f);
    st.m_tool_W -= (x + u - tool.p_WT).cross(f);
  }
  st.f_tool_W = -st.force_body;
  st.ramp = settings_.ramp_seconds > 0.0
                ? std::clamp((tool.time - ready_time_) / settings_.ramp_seconds, 0.0, 1.0)
                : 1.0;
  const double scale = settings_.force_scale * st.ramp;
  w.f_T_W = Clamped(scale * st.f_tool_W, settings_.max_force);
  w.m_T_W = Clamped(scale * st.m_tool_W, settings_.max_torque);
  if (channel_) channel_->buffer.Write(st);
  return w;
}

int GrabDisplacement(fem::ColumnCache* cache, const FeGrabState& state, Eigen::VectorXd* u_out) {
  *u_out = cache->baseline();
  if (!state.ready) return 0;
  return AddSlotForcesDisplacement(cache, state.num_nodes, state.candidate.data(),
                                   state.substitute.data(), state.force.data(), u_out->data());
}

}  // namespace spidarcad::app
