// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#include "spidarcad/haptics/proxy_field.h"

#include <Eigen/LU>
#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <string>

namespace spidarcad::haptics {

namespace {
void Require(bool ok, const char* field, double value, const char* what) {
  if (!ok) {
    throw std::invalid_argument(std::string("ProxySettings.") + field + " = " +
                                std::to_string(value) + ": " + what);
  }
}
constexpr int kBisections = 24;
}  // namespace

void ProxySettings::Validate() const {
  Require(stiffness > 0 && std::isfinite(stiffness), "stiffness", stiffness,
          "must be finite and > 0");
  Require(damping >= 0 && std::isfinite(damping), "damping", damping, "must be finite and >= 0");
  Require(static_friction >= 0 && std::isfinite(static_friction), "static_friction",
          static_friction, "must be finite and >= 0");
  Require(dynamic_friction >= 0 && dynamic_friction <= static_friction, "dynamic_friction",
          dynamic_friction, "must be in [0, static_friction]");
  Require(tip_T.allFinite(), "tip_T", tip_T.norm(), "must be finite");
  Require(min_step > 0 && std::isfinite(min_step), "min_step", min_step, "must be finite and > 0");
  Require(max_sweep_steps >= 1, "max_sweep_steps", max_sweep_steps, "must be >= 1");
  Require(surface_tolerance > 0 && std::isfinite(surface_tolerance), "surface_tolerance",
          surface_tolerance, "must be finite and > 0");
}

ProxyField::ProxyField(std::shared_ptr<const DistanceField> environment,
                       const ProxySettings& settings)
    : env_(std::move(environment)), settings_(settings) {
  if (env_ == nullptr) throw std::invalid_argument("ProxyField: the environment field is null");
  settings_.Validate();
}

bool ProxyField::Sweep(const Eigen::Vector3d& from, const Eigen::Vector3d& to,
                       Eigen::Vector3d* stop, Eigen::Vector3d* blocked,
                       double* phi_to) const noexcept {
  // A sample is passable when φ >= −tol: in free space or on the surface, whose points the
  // projection only places within tol (a proxy a rounding error inside must slide on).
  const double passable = -settings_.surface_tolerance;
  const Eigen::Vector3d d = to - from;
  const double length = d.norm();
  if (!(length > 0)) {
    *stop = to;
    const double phi = env_->Evaluate(to, nullptr);
    if (phi_to != nullptr) *phi_to = phi;
    return phi >= passable;
  }
  const Eigen::Vector3d u = d / length;
  double t = 0.0;
  double phi = env_->Evaluate(from, nullptr);
  for (int step = 0; step < settings_.max_sweep_steps; ++step) {
    const double t_next = std::min(length, t + std::max(phi, settings_.min_step));
    const double phi_next = env_->Evaluate(from + t_next * u, nullptr);
    if (phi_next < passable) {
      // The path goes deeper than the surface in (t, t_next]: bisect, keeping the passable end.
      double lo = t, hi = t_next;
      for (int i = 0; i < kBisections; ++i) {
        const double mid = 0.5 * (lo + hi);
        if (env_->Evaluate(from + mid * u, nullptr) < passable) {
          hi = mid;
        } else {
          lo = mid;
        }
      }
      *stop = from + lo * u;
      if (blocked != nullptr) *blocked = from + hi * u;
      return false;
    }
    t = t_next;
    phi = phi_next;
    if (t >= length) {
      *stop = to;
      if (phi_to != nullptr) *phi_to = phi;
      return true;
    }
  }
  *stop = from + t * u;  // out of budget: stay short, on the free side
  sweep_exhausted_ = true;
  return false;
}

void ProxyField::Project(Eigen::Vector3d* x) const noexcept {
  Eigen::Vector3d g;
  for (int i = 0; i < 12; ++i) {
    const double phi = env_->Evaluate(*x, &g);
    const double g2 = g.squaredNorm();
    if (phi == 0.0 || !(g2 > 0)) return;
    *x -= (phi / g2) * g;  // one step even when within tolerance: exact fields land exactly
    if (std::abs(phi) <= settings_.surface_tolerance) return;
  }
}

void ProxyField::AddPlane(const Eigen::Vector3d& x, const Eigen::Vector3d& probe) noexcept {
  Eigen::Vector3d g;
  env_->Evaluate(probe, &g);
  const double n = g.norm();
  if (!(n > 0)) return;
  const Eigen::Vector3d normal = g / n;
  for (int i = 0; i < num_planes_; ++i) {
    if (planes_[i].normal.dot(normal) > 1.0 - 1e-6) {  // same surface: refresh it
      planes_[i].point = x;
      planes_[i].normal = normal;
      return;
    }
  }
  if (num_planes_ < kMaxPlanes) {
    planes_[num_planes_++] = Plane{x, normal};
  } else {
    planes_[oldest_plane_] = Plane{x, normal};
    oldest_plane_ = (oldest_plane_ + 1) % kMaxPlanes;
  }
}

Eigen::Vector3d ProxyField::ConstrainedGoal(const Eigen::Vector3d& p,
                                            const Eigen::Vector3d& fallback) const noexcept {
  constexpr double kFeasible = 1e-12;
  double best = std::numeric_limits<double>::infinity();
  Eigen::Vector3d best_point = fallback;
  for (int mask = 0; mask < (1 << num_planes_); ++mask) {
    int idx[kMaxPlanes];
    int m = 0;
    for (int i = 0; i < num_planes_; ++i) {
      if (mask & (1 << i)) idx[m++] = i;
    }
    // y = p − Σ λ_j n_j with n_j·y = n_j·q_j for j in the subset: (NᵀN) λ = Nᵀp − c.
    Eigen::Vector3d y = p;
    if (m > 0) {
      Eigen::Matrix3d gram = Eigen::Matrix3d::Identity();
      Eigen::Vector3d rhs = Eigen::Vector3d::Zero();
      for (int a = 0; a < m; ++a) {
        const Plane& pa = planes_[idx[a]];
        rhs(a) = pa.normal.dot(p - pa.point);
        for (int b = 0; b < m; ++b) gram(a, b) = pa.normal.dot(planes_[idx[b]].normal);
      }
      const double det = gram.determinant();
      if (std::abs(det) < 1e-10) continue;  // (nearly) parallel planes: another subset covers it
      const Eigen::Vector3d lambda = gram.inverse() * rhs;
      for (int a = 0; a < m; ++a) y -= lambda(a) * planes_[idx[a]].normal;
    }
    bool feasible = true;
    for (int i = 0; i < num_planes_ && feasible; ++i) {
      feasible = planes_[i].normal.dot(y - planes_[i].point) >= -kFeasible;
    }
    if (!feasible) continue;
    const double dist = (y - p).squaredNorm();
    if (dist < best) {
      best = dist;
      best_point = y;
    }
  }
  return best_point;
}

Eigen::Vector3d ProxyField::FrictionGoal(const Eigen::Vector3d& x, const Eigen::Vector3d& g0,
                                         const Eigen::Vector3d& x_t) noexcept {
  const double mu_s = settings_.static_friction, mu_d = settings_.dynamic_friction;
  if (mu_s <= 0) {
    sliding_ = true;
    return g0;
  }
  const double normal = (x_t - g0).norm();  // normal force / k
  const Eigen::Vector3d offset = g0 - x;    // tangential force / k, reversed
  const double tangential = offset.norm();
  const double limit = (sliding_ ? mu_d : mu_s) * normal;
  if (tangential <= limit) {
    sliding_ = false;
    return x;  // stick
  }
  sliding_ = true;
  return g0 - offset * (mu_d * normal / tangential);  // on the dynamic cone, lagging behind
}

ToolWrench ProxyField::Publish(const Eigen::Vector3d& x_t, const ToolWrench& w) noexcept {
  ProxyState& s = published_.WriteSlot();
  s.proxy_W = proxy_;
  s.tool_W = x_t;
  s.contact = contact_;
  published_.Publish();
  return w;
}

ToolWrench ProxyField::Evaluate(const ToolKinematics& tool) noexcept {
  const Eigen::Vector3d r_tip = tool.R_WT * settings_.tip_T;
  const Eigen::Vector3d x_t = tool.p_WT + r_tip;
  if (!x_t.allFinite()) return ToolWrench{};
  if (!initialized_) {
    // Start only once the tool point is in free space (no jolt when it starts inside).
    if (env_->Evaluate(x_t, nullptr) < 0) return Publish(x_t, ToolWrench{});
    initialized_ = true;
    proxy_ = x_t;
    contact_ = false;
  }

  Eigen::Vector3d x = proxy_;
  sweep_exhausted_ = false;
  num_planes_ = 0;
  oldest_plane_ = 0;
  if (!contact_) {
    Eigen::Vector3d stop;
    double phi_t = 0.0;
    const bool reached = Sweep(x, x_t, &stop, nullptr, &phi_t);
    if (reached && phi_t >= 0) {
      proxy_ = x_t;
      return Publish(x_t, ToolWrench{});
    }
    if (sweep_exhausted_) {  // stopped short in free space: catch up next tick
      proxy_ = stop;
      return Publish(x_t, ToolWrench{});
    }
    // Blocked, or the tool itself is inside by no more than the surface tolerance (then
    // stop = x_t): contact, with the proxy projected onto the surface.
    x = stop;
    Project(&x);
    contact_ = true;
    sliding_ = false;
  } else if (env_->Evaluate(x_t, nullptr) >= 0) {
    Eigen::Vector3d stop;
    if (Sweep(x, x_t, &stop)) {  // the tool left the solid along a free path
      proxy_ = x_t;
      contact_ = false;
      return Publish(x_t, ToolWrench{});
    }
    sweep_exhausted_ = false;  // blocked or short: stay in contact and constrain as usual
  }

  AddPlane(x, x);
  Eigen::Vector3d goal = FrictionGoal(x, ConstrainedGoal(x_t, x), x_t);
  bool free_goal = (goal - x_t).squaredNorm() == 0.0;
  double phi_goal = -1.0;  // φ at the goal when a sweep reached it
  for (int iteration = 0; iteration < kMaxIterations; ++iteration) {
    Eigen::Vector3d stop, blocked = goal;
    if (Sweep(x, goal, &stop, &blocked, &phi_goal)) {
      x = goal;
      break;
    }
    x = stop;
    if (sweep_exhausted_) break;  // short of the goal in free space: no plane to add
    Project(&x);
    AddPlane(x, x);
    // The surface met lies at the first sample inside: at a concave edge or corner the
    // gradient at x may still belong to the face the proxy slides on, and only there the
    // new face shows (without it the proxy stalls on the edge as if held by friction).
    Eigen::Vector3d g_x, g_blocked;
    env_->Evaluate(x, &g_x);
    env_->Evaluate(blocked, &g_blocked);
    constexpr double kNewFace = 0.99;  // normals more than ~8° apart: another face
    if (g_x.dot(g_blocked) < kNewFace * g_x.norm() * g_blocked.norm()) AddPlane(x, blocked);
    goal = ConstrainedGoal(x_t, x);  // later rounds without friction (see the header)
    free_goal = false;
  }
  // The proxy reached the tool itself: free only when the tool is outside the solid (the
  // sweep also passes a tool inside by no more than the surface tolerance).
  if (free_goal && (x - x_t).squaredNorm() == 0.0 && phi_goal >= 0) {
    proxy_ = x_t;
    contact_ = false;
    return Publish(x_t, ToolWrench{});
  }
  if (!sweep_exhausted_) Project(&x);  // (never jump onto the surface from free space)
  proxy_ = x;

  Eigen::Vector3d g;
  env_->Evaluate(x, &g);
  const double gn = g.norm();
  const Eigen::Vector3d n = gn > 0 ? Eigen::Vector3d(g / gn) : Eigen::Vector3d::Zero();
  const Eigen::Vector3d v_t = tool.v_WT + tool.w_WT.cross(r_tip);
  Eigen::Vector3d f = settings_.stiffness * (x - x_t) - settings_.damping * n.dot(v_t) * n;
  const double f_n = n.dot(f);
  if (f_n < 0) f -= f_n * n;  // never pull the tool into the solid
  ToolWrench w;
  w.f_T_W = f;
  w.m_T_W = r_tip.cross(f);
  return Publish(x_t, w);
}

}  // namespace spidarcad::haptics
