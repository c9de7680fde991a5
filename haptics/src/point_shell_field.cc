// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#include "spidarcad/haptics/point_shell_field.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>

namespace spidarcad::haptics {

namespace {
void Require(bool ok, const char* where, const char* field, double value, const char* what) {
  if (!ok) {
    throw std::invalid_argument(std::string(where) + "." + field + " = " + std::to_string(value) +
                                ": " + what);
  }
}
bool PositiveFinite(double v) { return v > 0 && std::isfinite(v); }

// Rotation vector of the rotation q (angle·axis, angle in [0, π]).
Eigen::Vector3d RotationVector(Eigen::Quaterniond q) {
  if (q.w() < 0) q.coeffs() *= -1;
  const double s = q.vec().norm();
  if (s < 1e-12) return 2.0 * q.vec();
  return (2.0 * std::atan2(s, q.w()) / s) * q.vec();
}
}  // namespace

PointShell PointShell::FromPoints(const std::vector<Eigen::Vector3d>& points_T,
                                  const std::vector<Eigen::Vector3d>& normals_T) {
  if (points_T.size() != normals_T.size()) {
    throw std::invalid_argument("PointShell: " + std::to_string(points_T.size()) + " points but " +
                                std::to_string(normals_T.size()) + " normals");
  }
  PointShell shell;
  shell.points_T = points_T;
  shell.normals_T.reserve(normals_T.size());
  for (std::size_t i = 0; i < points_T.size(); ++i) {
    const double n = normals_T[i].norm();
    if (!points_T[i].allFinite()) {
      throw std::invalid_argument("PointShell: point " + std::to_string(i) + " is not finite");
    }
    if (!(n > 0 && std::isfinite(n))) {
      throw std::invalid_argument("PointShell: normal " + std::to_string(i) + " is zero or not finite");
    }
    shell.normals_T.push_back(normals_T[i] / n);
  }
  return shell;
}

PointShell PointShell::Sphere(double radius, int count) {
  Require(PositiveFinite(radius), "PointShell::Sphere", "radius", radius, "must be finite and > 0");
  Require(count >= 1, "PointShell::Sphere", "count", count, "must be >= 1");
  PointShell shell;
  const double golden = M_PI * (3.0 - std::sqrt(5.0));
  for (int i = 0; i < count; ++i) {
    const double z = 1.0 - (2.0 * i + 1.0) / count;
    const double r = std::sqrt(std::max(0.0, 1.0 - z * z));
    const Eigen::Vector3d u(r * std::cos(golden * i), r * std::sin(golden * i), z);
    shell.points_T.push_back(radius * u);
    shell.normals_T.push_back(-u);
  }
  return shell;
}

PointShell PointShell::Box(const Eigen::Vector3d& half_sides, double spacing) {
  Require(half_sides.allFinite() && (half_sides.array() > 0).all(), "PointShell::Box", "half_sides",
          half_sides.minCoeff(), "must be finite and > 0");
  Require(PositiveFinite(spacing), "PointShell::Box", "spacing", spacing, "must be finite and > 0");
  PointShell shell;
  for (int axis = 0; axis < 3; ++axis) {
    const int u = (axis + 1) % 3, v = (axis + 2) % 3;
    const int nu = std::max(1, static_cast<int>(std::lround(2 * half_sides(u) / spacing)));
    const int nv = std::max(1, static_cast<int>(std::lround(2 * half_sides(v) / spacing)));
    for (int side = -1; side <= 1; side += 2) {
      for (int i = 0; i < nu; ++i) {
        for (int j = 0; j < nv; ++j) {
          Eigen::Vector3d p;
          p(axis) = side * half_sides(axis);
          p(u) = -half_sides(u) + (i + 0.5) * 2 * half_sides(u) / nu;
          p(v) = -half_sides(v) + (j + 0.5) * 2 * half_sides(v) / nv;
          Eigen::Vector3d n = Eigen::Vector3d::Zero();
          n(axis) = -side;
          shell.points_T.push_back(p);
          shell.normals_T.push_back(n);
        }
      }
    }
  }
  return shell;
}

PointShell PointShell::CrossGrip(double d, double radius, int rings, int around) {
  Require(PositiveFinite(d), "PointShell::CrossGrip", "d", d, "must be finite and > 0");
  Require(PositiveFinite(radius), "PointShell::CrossGrip", "radius", radius, "must be finite and > 0");
  Require(rings >= 2, "PointShell::CrossGrip", "rings", rings, "must be >= 2");
  Require(around >= 3, "PointShell::CrossGrip", "around", around, "must be >= 3");
  PointShell shell;
  const Eigen::Vector3d axes[2] = {Eigen::Vector3d::UnitY(), Eigen::Vector3d::UnitX()};
  for (const Eigen::Vector3d& axis : axes) {
    const Eigen::Vector3d e1 = Eigen::Vector3d::UnitZ();
    const Eigen::Vector3d e2 = axis.cross(e1);
    for (int i = 0; i < rings; ++i) {
      const double t = -d + 2 * d * i / (rings - 1);
      for (int j = 0; j < around; ++j) {
        const double a = 2 * M_PI * j / around;
        const Eigen::Vector3d radial = std::cos(a) * e1 + std::sin(a) * e2;
        shell.points_T.push_back(t * axis + radius * radial);
        shell.normals_T.push_back(-radial);
      }
    }
    for (int side = -1; side <= 1; side += 2) {
      shell.points_T.push_back(side * (d + radius) * axis);
      shell.normals_T.push_back(-side * axis);
    }
  }
  return shell;
}

double PointShell::Radius() const noexcept {
  double r = 0;
  for (const auto& p : points_T) r = std::max(r, p.norm());
  return r;
}

void PointShellSettings::Validate() const {
  const char* w = "PointShellSettings";
  Require(PositiveFinite(mass), w, "mass", mass, "must be finite and > 0");
  Require(inertia.allFinite() && (inertia.array() > 0).all(), w, "inertia", inertia.minCoeff(),
          "must be finite and > 0");
  Require(PositiveFinite(coupling_stiffness), w, "coupling_stiffness", coupling_stiffness, "must be finite and > 0");
  Require(coupling_damping >= 0 && std::isfinite(coupling_damping), w, "coupling_damping", coupling_damping,
          "must be finite and >= 0");
  Require(PositiveFinite(rot_coupling_stiffness), w, "rot_coupling_stiffness", rot_coupling_stiffness,
          "must be finite and > 0");
  Require(rot_coupling_damping >= 0 && std::isfinite(rot_coupling_damping), w, "rot_coupling_damping",
          rot_coupling_damping, "must be finite and >= 0");
  Require(PositiveFinite(contact_stiffness), w, "contact_stiffness", contact_stiffness, "must be finite and > 0");
  Require(contact_damping >= 0 && std::isfinite(contact_damping), w, "contact_damping", contact_damping,
          "must be finite and >= 0");
  Require(reference_contacts >= 1, w, "reference_contacts", reference_contacts, "must be >= 1");
  Require(substeps >= 1 && substeps <= 1000, w, "substeps", substeps, "must be in [1, 1000]");
  Require(contact_margin >= 0 && std::isfinite(contact_margin), w, "contact_margin", contact_margin,
          "must be finite and >= 0");
  Require(max_points >= 1, w, "max_points", max_points, "must be >= 1");
  Require(PositiveFinite(max_dt), w, "max_dt", max_dt, "must be finite and > 0");
}

PointShellField::PointShellField(std::shared_ptr<const DistanceField> environment, PointShell shell,
                                 const PointShellSettings& settings)
    : env_(std::move(environment)), shell_(std::move(shell)), settings_(settings) {
  if (env_ == nullptr) throw std::invalid_argument("PointShellField: the environment field is null");
  settings_.Validate();
  if (shell_.size() == 0) throw std::invalid_argument("PointShellField: the point shell is empty");
  if (shell_.points_T.size() != shell_.normals_T.size()) {
    throw std::invalid_argument("PointShellField: shell points and normals differ in number");
  }
  if (shell_.size() > settings_.max_points) {
    throw std::invalid_argument("PointShellField: the shell has " + std::to_string(shell_.size()) +
                                " points, more than max_points = " +
                                std::to_string(settings_.max_points));
  }
  shell_radius_ = shell_.Radius();
  candidates_.assign(shell_.points_T.size(), 0);
}

ShellContact PointShellField::ContactAt(const Eigen::Isometry3d& X_WV) const noexcept {
  ShellContact c;
  const Eigen::Vector3d p = X_WV.translation();
  const Eigen::Matrix3d R = X_WV.linear();
  Eigen::Vector3d g;
  for (const Eigen::Vector3d& r_T : shell_.points_T) {
    const Eigen::Vector3d r = R * r_T;
    const double phi = env_->Evaluate(p + r, &g);
    const double gn = g.norm();
    if (!(phi < 0) || !(gn > 0)) continue;
    const Eigen::Vector3d f = settings_.contact_stiffness * (-phi) * (g / gn);
    c.force_W += f;
    c.torque_W += r.cross(f);
    ++c.contacts;
  }
  const double s = std::min(1.0, settings_.reference_contacts / std::max(1.0, double(c.contacts)));
  c.force_W *= s;
  c.torque_W *= s;
  return c;
}

ShellContact PointShellField::CandidateContact(const Eigen::Matrix3d& R_WV) noexcept {
  ShellContact c;
  Eigen::Vector3d g;
  for (int k = 0; k < num_candidates_; ++k) {
    const int i = candidates_[k];
    const Eigen::Vector3d r = R_WV * shell_.points_T[i];
    const double phi = env_->Evaluate(p_ + r, &g);
    const double gn = g.norm();
    if (!(phi < 0) || !(gn > 0)) continue;
    const Eigen::Vector3d n = g / gn;
    const double v_n = n.dot(v_ + w_.cross(r));
    const double magnitude = std::max(0.0, settings_.contact_stiffness * (-phi) - settings_.contact_damping * v_n);
    const Eigen::Vector3d f = magnitude * n;
    c.force_W += f;
    c.torque_W += r.cross(f);
    ++c.contacts;
  }
  const double s = std::min(1.0, settings_.reference_contacts / std::max(1.0, double(c.contacts)));
  c.force_W *= s;
  c.torque_W *= s;
  return c;
}

ToolWrench PointShellField::Evaluate(const ToolKinematics& tool) noexcept {
  const PointShellSettings& s = settings_;
  const Eigen::Quaterniond q_T(tool.R_WT);
  if (!initialized_) {
    initialized_ = true;
    p_ = tool.p_WT;
    q_ = q_T.normalized();
    v_ = tool.v_WT;
    w_ = tool.w_WT;
    last_time_ = tool.time;
  }
  double dt = tool.time - last_time_;
  last_time_ = tool.time;
  if (!(dt > 0)) dt = 1e-3;
  dt = std::min(dt, s.max_dt);

  // Broad and narrow phase at the start of the tick: the candidate points.
  num_candidates_ = 0;
  {
    const double reach = s.contact_margin + 2.0 * dt * (v_.norm() + w_.norm() * shell_radius_ +
                                                        tool.v_WT.norm() + tool.w_WT.norm() * shell_radius_);
    if (env_->Evaluate(p_, nullptr) < shell_radius_ + reach) {
      const Eigen::Matrix3d R = q_.toRotationMatrix();
      for (int i = 0; i < shell_.size(); ++i) {
        if (env_->Evaluate(p_ + R * shell_.points_T[i], nullptr) < reach) candidates_[num_candidates_++] = i;
      }
    }
  }

  const double h = dt / s.substeps;
  Eigen::Vector3d f_c = Eigen::Vector3d::Zero(), tau_c = Eigen::Vector3d::Zero();
  const Eigen::Vector3d inv_inertia = s.inertia.cwiseInverse();
  for (int step = 0; step < s.substeps; ++step) {
    const Eigen::Matrix3d R = q_.toRotationMatrix();
    const ShellContact contact = CandidateContact(R);
    contacts_ = contact.contacts;
    f_c = s.coupling_stiffness * (tool.p_WT - p_) + s.coupling_damping * (tool.v_WT - v_);
    tau_c = s.rot_coupling_stiffness * RotationVector(q_T * q_.conjugate()) +
            s.rot_coupling_damping * (tool.w_WT - w_);
    v_ += (h / s.mass) * (f_c + contact.force_W);
    // ω̇ = R I⁻¹ Rᵀ τ (body inertia, gyroscopic term neglected).
    w_ += h * (R * inv_inertia.asDiagonal() * (R.transpose() * (tau_c + contact.torque_W)));
    p_ += h * v_;
    const double angle = w_.norm() * h;
    if (angle > 0) q_ = Eigen::Quaterniond(Eigen::AngleAxisd(angle, w_ / w_.norm())) * q_;
    q_.normalize();
  }
  // The coupling's reaction at the end of the tick is what the user feels.
  f_c = s.coupling_stiffness * (tool.p_WT - p_) + s.coupling_damping * (tool.v_WT - v_);
  tau_c = s.rot_coupling_stiffness * RotationVector(q_T * q_.conjugate()) +
          s.rot_coupling_damping * (tool.w_WT - w_);
  if (!(p_.allFinite() && q_.coeffs().allFinite() && v_.allFinite() && w_.allFinite())) {
    // Recover: restart on the grip next tick (the loop zeroes this tick's NaN wrench).
    initialized_ = false;
  }
  PointShellState& out = published_.WriteSlot();
  out.p_WV = p_;
  out.q_WV = q_;
  out.contacts = contacts_;
  published_.Publish();
  ToolWrench w;
  w.f_T_W = -f_c;
  w.m_T_W = -tau_c;
  return w;
}

}  // namespace spidarcad::haptics
