// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#include "spidarcad/haptics/point_shell_field.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <string>

#include "spidarcad/haptics/rotation.h"

namespace spidarcad::haptics {

namespace {
void Require(bool ok, const char* where, const char* field, double value, const char* what) {
  if (!ok) {
    throw std::invalid_argument(std::string(where) + "." + field + " = " + std::to_string(value) +
                                ": " + what);
  }
}
bool PositiveFinite(double v) { return v > 0 && std::isfinite(v); }
bool NonNegativeFinite(double v) { return v >= 0 && std::isfinite(v); }

constexpr int kImpulsePasses = 4;
// Slack of the narrow phase's motion bounds, m: far above the rounding of φ and of the point
// positions, far below any reach.
constexpr double kCullMargin = 1e-9;
// Points per sphere cluster of the shell (BuildClusters), about.
constexpr int kPointsPerCluster = 24;

// g / |g|, or zero when |g| is zero or not finite.
Eigen::Vector3d UnitOrZero(const Eigen::Vector3d& g) {
  const double n = g.norm();
  return n > 0 && std::isfinite(n) ? Eigen::Vector3d(g / n) : Eigen::Vector3d::Zero();
}

// Spring-damper with a soft zone (see the header): stretch x (3), relative velocity dx (3),
// stiffness k, damping b, zone radius zone (0: off), ratio eps. Returns k·x + b·dx inside the
// law: ε(k x + b dx) for |x| ≤ δ; beyond, spring (k|x| − (1 − ε) k δ) x/|x| and damping
// b (ε + (1 − ε) min(1, (|x| − δ)/δ)) dx.
Eigen::Vector3d SoftCoupling(const Eigen::Vector3d& x, const Eigen::Vector3d& dx, double k,
                             double b, double zone, double eps) {
  if (!(zone > 0)) return k * x + b * dx;
  const double r = x.norm();
  if (r <= zone) return eps * (k * x + b * dx);
  const double spring = k * r - (1.0 - eps) * k * zone;
  const double ramp = std::min(1.0, (r - zone) / zone);
  return (spring / r) * x + (b * (eps + (1.0 - eps) * ramp)) * dx;
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
      throw std::invalid_argument("PointShell: normal " + std::to_string(i) +
                                  " is zero or not finite");
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
  Require(PositiveFinite(radius), "PointShell::CrossGrip", "radius", radius,
          "must be finite and > 0");
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
  Require(PositiveFinite(coupling_stiffness), w, "coupling_stiffness", coupling_stiffness,
          "must be finite and > 0");
  Require(coupling_damping >= 0 && std::isfinite(coupling_damping), w, "coupling_damping",
          coupling_damping, "must be finite and >= 0");
  Require(PositiveFinite(rot_coupling_stiffness), w, "rot_coupling_stiffness",
          rot_coupling_stiffness, "must be finite and > 0");
  Require(rot_coupling_damping >= 0 && std::isfinite(rot_coupling_damping), w,
          "rot_coupling_damping", rot_coupling_damping, "must be finite and >= 0");
  Require(PositiveFinite(contact_stiffness), w, "contact_stiffness", contact_stiffness,
          "must be finite and > 0");
  Require(contact_damping >= 0 && std::isfinite(contact_damping), w, "contact_damping",
          contact_damping, "must be finite and >= 0");
  Require(reference_contacts >= 1, w, "reference_contacts", reference_contacts, "must be >= 1");
  Require(substeps >= 1 && substeps <= 1000, w, "substeps", substeps, "must be in [1, 1000]");
  Require(contact_margin >= 0 && std::isfinite(contact_margin), w, "contact_margin", contact_margin,
          "must be finite and >= 0");
  Require(max_points >= 1, w, "max_points", max_points, "must be >= 1");
  Require(PositiveFinite(max_dt), w, "max_dt", max_dt, "must be finite and > 0");
  Require(NonNegativeFinite(coupling_soft_zone), w, "coupling_soft_zone", coupling_soft_zone,
          "must be finite and >= 0");
  Require(NonNegativeFinite(rot_coupling_soft_zone), w, "rot_coupling_soft_zone",
          rot_coupling_soft_zone, "must be finite and >= 0");
  Require(soft_zone_ratio >= 0 && soft_zone_ratio <= 1, w, "soft_zone_ratio", soft_zone_ratio,
          "must be in [0, 1]");
  Require(NonNegativeFinite(max_penetration), w, "max_penetration", max_penetration,
          "must be finite and >= 0");
  Require(PositiveFinite(min_step), w, "min_step", min_step, "must be finite and > 0");
}

PointShellField::PointShellField(std::shared_ptr<const DistanceField> environment, PointShell shell,
                                 const PointShellSettings& settings)
    : env_(std::move(environment)), shell_(std::move(shell)), settings_(settings) {
  if (env_ == nullptr)
    throw std::invalid_argument("PointShellField: the environment field is null");
  settings_.Validate();
  if (shell_.size() == 0) throw std::invalid_argument("PointShellField: the point shell is empty");
  if (shell_.points_T.size() != shell_.normals_T.size()) {
    throw std::invalid_argument("PointShellField: shell points and normals differ in number");
  }
  if (shell_.size() > settings_.max_points) {
    throw std::invalid_argument(
        "PointShellField: the shell has " + std::to_string(shell_.size()) +
        " points, more than max_points = " + std::to_string(settings_.max_points));
  }
  shell_radius_ = shell_.Radius();
  candidates_.assign(shell_.points_T.size(), 0);
  candidate_phi_.assign(shell_.points_T.size(), 0.0);
  candidate_g_.assign(shell_.points_T.size(), Eigen::Vector3d::Zero());
  candidate_r_.assign(shell_.points_T.size(), Eigen::Vector3d::Zero());
  for (std::vector<double>* buffer :
       {&batch_x_, &batch_y_, &batch_z_, &batch_phi_, &batch_gx_, &batch_gy_, &batch_gz_}) {
    buffer->assign(shell_.points_T.size(), 0.0);
  }
  batch_index_.assign(shell_.points_T.size(), 0);
  last_phi_.assign(shell_.points_T.size(), -std::numeric_limits<double>::infinity());
  last_travel_p_.assign(shell_.points_T.size(), 0.0);
  last_travel_theta_.assign(shell_.points_T.size(), 0.0);
  candidate_exact_.assign(shell_.points_T.size(), 1);
  point_radius_.resize(shell_.points_T.size());
  for (int i = 0; i < shell_.size(); ++i) point_radius_[i] = shell_.points_T[i].norm();
  BuildClusters();
}

void PointShellField::BuildClusters() {
  // Bins on a g×g×g grid over the shell's box, g chosen for about kPointsPerCluster points per
  // occupied bin on a surface-like shell; a shell too small to gain from it has none.
  const int n = shell_.size();
  cluster_centre_T_.clear();
  cluster_radius_.clear();
  point_cluster_.assign(n, 0);
  if (!settings_.cull_by_motion || n < 4 * kPointsPerCluster) return;
  Eigen::AlignedBox3d box;
  for (const Eigen::Vector3d& r : shell_.points_T) box.extend(r);
  // A surface-like shell of n points occupies about 3g² of the g³ bins.
  const int g =
      std::clamp(int(std::lround(std::sqrt(double(n) / (3.0 * kPointsPerCluster)))), 2, 16);
  const Eigen::Vector3d size = box.sizes().cwiseMax(1e-12);
  std::vector<int> bin_cluster(g * g * g, -1);
  std::vector<int> count;
  for (int i = 0; i < n; ++i) {
    const Eigen::Vector3d u = (shell_.points_T[i] - box.min()).cwiseQuotient(size) * double(g);
    int b = 0;
    for (int a = 2; a >= 0; --a) b = b * g + std::clamp(int(u[a]), 0, g - 1);
    if (bin_cluster[b] < 0) {
      bin_cluster[b] = int(cluster_centre_T_.size());
      cluster_centre_T_.push_back(Eigen::Vector3d::Zero());
      count.push_back(0);
    }
    point_cluster_[i] = bin_cluster[b];
    cluster_centre_T_[bin_cluster[b]] += shell_.points_T[i];
    ++count[bin_cluster[b]];
  }
  cluster_radius_.assign(cluster_centre_T_.size(), 0.0);
  for (std::size_t c = 0; c < cluster_centre_T_.size(); ++c) cluster_centre_T_[c] /= count[c];
  for (int i = 0; i < n; ++i) {
    const int c = point_cluster_[i];
    cluster_radius_[c] =
        std::max(cluster_radius_[c], (shell_.points_T[i] - cluster_centre_T_[c]).norm());
  }
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

double PointShellField::PhiLowerBound(int i) const noexcept {
  const double moved =
      (travel_p_ - last_travel_p_[i]) + (travel_theta_ - last_travel_theta_[i]) * point_radius_[i];
  return last_phi_[i] - moved - kCullMargin;
}

void PointShellField::MakeExact(int k) noexcept {
  if (candidate_exact_[k]) return;
  const int i = candidates_[k];
  Eigen::Vector3d g;
  candidate_phi_[k] = env_->Evaluate(p_ + candidate_r_[k], &g);
  candidate_g_[k] = g;
  candidate_exact_[k] = 1;
  last_phi_[i] = candidate_phi_[k];
  last_travel_p_[i] = travel_p_;
  last_travel_theta_[i] = travel_theta_;
}

ShellContact PointShellField::CandidateContact(const Eigen::Matrix3d& R_WV) noexcept {
  ShellContact c;
  // The candidates' φ and gradients in one batch (SIMD across points in the solids' tapes);
  // with cull_by_motion, a candidate whose lower bound is >= 0 gets no force and keeps the
  // bound (MakeExact evaluates it if the advancement needs it).
  int m = 0;
  for (int k = 0; k < num_candidates_; ++k) {
    const int i = candidates_[k];
    const Eigen::Vector3d r = R_WV * shell_.points_T[i];
    candidate_r_[k] = r;
    if (settings_.cull_by_motion) {
      const double bound = PhiLowerBound(i);
      if (bound >= 0.0) {
        candidate_phi_[k] = bound;
        candidate_exact_[k] = 0;
        continue;
      }
    }
    const Eigen::Vector3d x = p_ + r;
    candidate_exact_[k] = 1;
    batch_index_[m] = k;
    batch_x_[m] = x.x();
    batch_y_[m] = x.y();
    batch_z_[m] = x.z();
    ++m;
  }
  env_->EvaluateBatch(batch_x_.data(), batch_y_.data(), batch_z_.data(), m, batch_phi_.data(),
                      batch_gx_.data(), batch_gy_.data(), batch_gz_.data());
  for (int j = 0; j < m; ++j) {
    const int k = batch_index_[j], i = candidates_[k];
    candidate_phi_[k] = batch_phi_[j];
    candidate_g_[k] = Eigen::Vector3d(batch_gx_[j], batch_gy_[j], batch_gz_[j]);
    last_phi_[i] = batch_phi_[j];
    last_travel_p_[i] = travel_p_;
    last_travel_theta_[i] = travel_theta_;
  }
  for (int k = 0; k < num_candidates_; ++k) {
    if (!candidate_exact_[k]) continue;  // φ >= its bound >= 0: no force
    const Eigen::Vector3d& r = candidate_r_[k];
    const double phi = candidate_phi_[k];
    const Eigen::Vector3d& g = candidate_g_[k];
    const double gn = g.norm();
    if (!(phi < 0) || !(gn > 0)) continue;
    const Eigen::Vector3d n = g / gn;
    const double v_n = n.dot(v_ + w_.cross(r));
    const double magnitude =
        std::max(0.0, settings_.contact_stiffness * (-phi) - settings_.contact_damping * v_n);
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

void PointShellField::Coupling(const ToolKinematics& tool, const Eigen::Quaterniond& q_T,
                               Eigen::Vector3d* f_c, Eigen::Vector3d* tau_c) const noexcept {
  const PointShellSettings& s = settings_;
  *f_c = SoftCoupling(tool.p_WT - p_, tool.v_WT - v_, s.coupling_stiffness, s.coupling_damping,
                      s.coupling_soft_zone, s.soft_zone_ratio);
  *tau_c =
      SoftCoupling(RotationVector(q_T * q_.conjugate()), tool.w_WT - w_, s.rot_coupling_stiffness,
                   s.rot_coupling_damping, s.rot_coupling_soft_zone, s.soft_zone_ratio);
}

void PointShellField::ConstrainMotion(double h, double budget, double travelled,
                                      const Eigen::Matrix3d& inv_inertia_W) noexcept {
  const double d_max = settings_.max_penetration;
  // Sequential inelastic impulses λ n_i at the points whose local plane says they would pass the
  // depth limit in this substep: each point's inward speed drops to what just reaches it.
  for (int pass = 0; pass < kImpulsePasses; ++pass) {
    bool applied = false;
    const double reach_h = h * (v_.norm() + w_.norm() * shell_radius_);  // no point moves further
    for (int k = 0; k < num_candidates_; ++k) {
      if (candidate_phi_[k] + d_max >= reach_h) continue;  // so is the exact φ if this is a bound
      MakeExact(k);
      if (candidate_phi_[k] + d_max >= reach_h) continue;
      const Eigen::Vector3d n = UnitOrZero(candidate_g_[k]);
      if (n.squaredNorm() == 0.0) continue;
      const Eigen::Vector3d& r = candidate_r_[k];
      const double u_n = n.dot(v_ + w_.cross(r));
      const double u_min = -std::max(0.0, candidate_phi_[k] + d_max) / h;
      if (u_n >= u_min) continue;
      const Eigen::Vector3d rn = r.cross(n);
      const Eigen::Vector3d dw = inv_inertia_W * rn;  // Δω per unit impulse
      const double lambda = (u_min - u_n) / (1.0 / settings_.mass + rn.dot(dw));
      v_ += (lambda / settings_.mass) * n;
      w_ += lambda * dw;
      applied = true;
    }
    if (!applied) break;
  }
  // The safe fraction t of the substep's motion: the travel budget of the non-candidates, and
  // per candidate the Lipschitz bound or (for moves up to min_step) its local plane.
  const Eigen::Vector3d dp = h * v_, dtheta = h * w_;
  const double move = dp.norm(), turn = dtheta.norm();
  double t = 1.0;
  const double bound = move + turn * shell_radius_;
  if (bound > 0 && travelled + bound > budget) t = std::max(0.0, budget - travelled) / bound;
  for (int k = 0; k < num_candidates_; ++k) {
    if (candidate_phi_[k] + d_max >= t * bound) continue;  // cannot limit t (μ_k ≤ bound)
    MakeExact(k);
    if (candidate_phi_[k] + d_max >= t * bound) continue;
    const double mu = move + turn * point_radius_[candidates_[k]];
    if (!(mu > 0)) continue;
    const double room = std::max(0.0, candidate_phi_[k] + d_max);  // distance to the depth limit
    const Eigen::Vector3d n = UnitOrZero(candidate_g_[k]);
    if (room == 0.0 && n.squaredNorm() == 0.0) continue;  // past the limit, no direction to guard
    double t_k = room / mu;                               // φ is 1-Lipschitz
    if (t_k >= t) continue;
    if (n.squaredNorm() > 0) {
      const double inward = -n.dot(dp + dtheta.cross(candidate_r_[k]));
      const double t_plane =
          inward > 1e-9 * mu ? room / inward : std::numeric_limits<double>::infinity();
      t_k = std::max(t_k, std::min(t_plane, settings_.min_step / mu));
    }
    t = std::min(t, t_k);
  }
  if (t < 1.0) {
    // Still blocked (budget, a far point, a tangential move beyond min_step, or impulses that
    // did not settle): move only the safe fraction.
    v_ *= t;
    w_ *= t;
  }
}

ToolWrench PointShellField::Evaluate(const ToolKinematics& tool) noexcept {
  const PointShellSettings& s = settings_;
  const Eigen::Quaterniond q_T(tool.R_WT);
  if (!initialized_) {
    initialized_ = true;
    // V jumps to the grip: no earlier φ bounds anything now.
    std::fill(last_phi_.begin(), last_phi_.end(), -std::numeric_limits<double>::infinity());
    travel_p_ = travel_theta_ = 0.0;
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

  // Broad and narrow phase at the start of the tick: the candidate points. Points beyond
  // `reach` stay free as long as V travels less than `reach` in this tick (ConstrainMotion).
  num_candidates_ = 0;
  const double reach = s.contact_margin + 2.0 * dt *
                                              (v_.norm() + w_.norm() * shell_radius_ +
                                               tool.v_WT.norm() + tool.w_WT.norm() * shell_radius_);
  // How far V may travel this tick with the non-candidates still free: the reach, or, when the
  // broad phase finds the whole shell clear, its clearance.
  double budget = reach;
  const double phi_centre = env_->Evaluate(p_, nullptr);
  if (phi_centre >= shell_radius_ + reach) {
    budget = phi_centre - shell_radius_;
  } else {
    const Eigen::Matrix3d R = q_.toRotationMatrix();
    const int n = shell_.size();
    int m = 0;  // points to evaluate, in increasing order
    for (int i = 0; i < n; ++i) {
      // φ now >= φ then − (how far the point can have moved since): out of reach, not a
      // candidate (a margin far above rounding keeps the decision the exhaustive one's).
      if (s.cull_by_motion && PhiLowerBound(i) >= reach) continue;
      batch_index_[m++] = i;
    }
    const int clusters = int(cluster_radius_.size());
    if (clusters > 0 && m > 2 * clusters) {
      // Many points without a useful bound (the first tick near a part, or after a jump):
      // bound them by their clusters' centres, φ(x) >= φ(c) − ρ (φ is 1-Lipschitz, as the
      // broad phase above assumes), and keep that bound as the point's last φ.
      for (int c = 0; c < clusters; ++c) {
        const Eigen::Vector3d x = p_ + R * cluster_centre_T_[c];
        batch_x_[c] = x.x();
        batch_y_[c] = x.y();
        batch_z_[c] = x.z();
      }
      env_->EvaluateBatch(batch_x_.data(), batch_y_.data(), batch_z_.data(), clusters,
                          batch_phi_.data(), nullptr, nullptr, nullptr);
      int kept = 0;
      for (int k = 0; k < m; ++k) {
        const int i = batch_index_[k];
        const int c = point_cluster_[i];
        const double bound = batch_phi_[c] - cluster_radius_[c];
        if (bound - kCullMargin >= reach) {
          last_phi_[i] = bound;
          last_travel_p_[i] = travel_p_;
          last_travel_theta_[i] = travel_theta_;
          continue;
        }
        batch_index_[kept++] = i;
      }
      m = kept;
    }
    for (int k = 0; k < m; ++k) {
      const Eigen::Vector3d x = p_ + R * shell_.points_T[batch_index_[k]];
      batch_x_[k] = x.x();
      batch_y_[k] = x.y();
      batch_z_[k] = x.z();
    }
    env_->EvaluateBatch(batch_x_.data(), batch_y_.data(), batch_z_.data(), m, batch_phi_.data(),
                        nullptr, nullptr, nullptr);
    for (int k = 0; k < m; ++k) {
      const int i = batch_index_[k];
      last_phi_[i] = batch_phi_[k];
      last_travel_p_[i] = travel_p_;
      last_travel_theta_[i] = travel_theta_;
      if (batch_phi_[k] < reach) candidates_[num_candidates_++] = i;
    }
  }

  const double h = dt / s.substeps;
  Eigen::Vector3d f_c = Eigen::Vector3d::Zero(), tau_c = Eigen::Vector3d::Zero();
  const Eigen::Vector3d inv_inertia = s.inertia.cwiseInverse();
  double travelled = 0.0;  // bound on any point's motion so far in this tick, m
  for (int step = 0; step < s.substeps; ++step) {
    const Eigen::Matrix3d R = q_.toRotationMatrix();
    const ShellContact contact = CandidateContact(R);
    contacts_ = contact.contacts;
    Coupling(tool, q_T, &f_c, &tau_c);
    // ω̇ = R I⁻¹ Rᵀ τ (body inertia, gyroscopic term neglected).
    const Eigen::Matrix3d inv_inertia_W = R * inv_inertia.asDiagonal() * R.transpose();
    v_ += (h / s.mass) * (f_c + contact.force_W);
    w_ += h * (inv_inertia_W * (tau_c + contact.torque_W));
    ConstrainMotion(h, budget, travelled, inv_inertia_W);
    p_ += h * v_;
    const double angle = w_.norm() * h;
    travelled += h * v_.norm() + angle * shell_radius_;
    travel_p_ += h * v_.norm();
    travel_theta_ += angle;
    q_ = IntegrateRotation(q_, w_, h);
  }
  // The coupling's reaction at the end of the tick is what the user feels.
  Coupling(tool, q_T, &f_c, &tau_c);
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
