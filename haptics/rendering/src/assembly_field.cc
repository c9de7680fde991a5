// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#include "spidarcad/haptics/assembly_field.h"

#include <algorithm>
#include <array>
#include <bit>
#include <cmath>
#include <cstdint>
#include <stdexcept>
#include <string>

#include "spidarcad/haptics/geometry.h"
#include "spidarcad/haptics/rotation.h"

namespace spidarcad::haptics {

namespace {
void Require(bool ok, const char* field, double value, const char* what) {
  if (!ok) {
    throw std::invalid_argument(std::string("AssemblySettings.") + field + " = " +
                                std::to_string(value) + ": " + what);
  }
}
bool PositiveFinite(double v) { return v > 0 && std::isfinite(v); }
bool NonNegativeFinite(double v) { return v >= 0 && std::isfinite(v); }

bool IsRigid(const Eigen::Isometry3d& X) {
  const Eigen::Matrix3d R = X.linear();
  return X.matrix().allFinite() &&
         (R.transpose() * R - Eigen::Matrix3d::Identity()).norm() < 1e-9 && R.determinant() > 0;
}

Eigen::Isometry3d Pose(const Eigen::Vector3d& p, const Eigen::Matrix3d& R) {
  Eigen::Isometry3d X = Eigen::Isometry3d::Identity();
  X.linear() = R;
  X.translation() = p;
  return X;
}
}  // namespace

void AssemblySettings::Validate() const {
  grasp.Validate();
  Require(PositiveFinite(mass), "mass", mass, "must be finite and > 0");
  Require(inertia.allFinite() && (inertia.array() > 0).all(), "inertia", inertia.minCoeff(),
          "must be finite and > 0");
  Require(NonNegativeFinite(coupling_stiffness), "coupling_stiffness", coupling_stiffness,
          "must be finite and >= 0");
  Require(NonNegativeFinite(coupling_damping), "coupling_damping", coupling_damping,
          "must be finite and >= 0");
  Require(NonNegativeFinite(rot_coupling_stiffness), "rot_coupling_stiffness",
          rot_coupling_stiffness, "must be finite and >= 0");
  Require(NonNegativeFinite(rot_coupling_damping), "rot_coupling_damping", rot_coupling_damping,
          "must be finite and >= 0");
  Require(NonNegativeFinite(contact_stiffness), "contact_stiffness", contact_stiffness,
          "must be finite and >= 0");
  Require(NonNegativeFinite(contact_damping), "contact_damping", contact_damping,
          "must be finite and >= 0");
  Require(reference_contacts >= 1, "reference_contacts", reference_contacts, "must be >= 1");
  Require(substeps >= 1 && substeps <= 1000, "substeps", substeps, "must be in [1, 1000]");
  Require(NonNegativeFinite(contact_margin), "contact_margin", contact_margin,
          "must be finite and >= 0");
  Require(max_points >= 1, "max_points", max_points, "must be >= 1");
  Require(PositiveFinite(max_dt), "max_dt", max_dt, "must be finite and > 0");
  Require(PositiveFinite(align.capture_distance), "align.capture_distance", align.capture_distance,
          "must be finite and > 0");
  Require(align.capture_angle > 0 && align.capture_angle < 3.0, "align.capture_angle",
          align.capture_angle, "must be in (0, 3) rad");
  Require(NonNegativeFinite(align.stiffness), "align.stiffness", align.stiffness,
          "must be finite and >= 0");
  Require(NonNegativeFinite(align.rot_stiffness), "align.rot_stiffness", align.rot_stiffness,
          "must be finite and >= 0");
  Require(NonNegativeFinite(align.max_force), "align.max_force", align.max_force,
          "must be finite and >= 0");
  Require(NonNegativeFinite(align.max_torque), "align.max_torque", align.max_torque,
          "must be finite and >= 0");
}

AssemblyField::AssemblyField(std::vector<AssemblyPart> parts, PointShell tool_shell,
                             const AssemblySettings& settings)
    : parts_(std::move(parts)), tool_shell_(std::move(tool_shell)), settings_(settings) {
  settings_.Validate();
  const int n = static_cast<int>(parts_.size());
  if (n < 1 || n > kMaxAssemblyParts) {
    throw std::invalid_argument("AssemblyField: " + std::to_string(n) + " parts, need 1.." +
                                std::to_string(kMaxAssemblyParts));
  }
  std::size_t max_shell = 0;
  for (int i = 0; i < n; ++i) {
    const AssemblyPart& p = parts_[i];
    const std::string where = "AssemblyField: part " + std::to_string(i) + " ('" + p.name + "')";
    if (p.field_P == nullptr) throw std::invalid_argument(where + ": field_P is null");
    if (!IsRigid(p.X_WP)) throw std::invalid_argument(where + ": X_WP is not a rigid transform");
    if (p.shell_P.points_T.size() != p.shell_P.normals_T.size()) {
      throw std::invalid_argument(where + ": shell has different numbers of points and normals");
    }
    if (p.shell_P.size() > settings_.max_points) {
      throw std::invalid_argument(
          where + ": shell has " + std::to_string(p.shell_P.size()) +
          " points, more than max_points = " + std::to_string(settings_.max_points));
    }
    if (!p.fixed && p.shell_P.size() == 0)
      throw std::invalid_argument(where + ": graspable part has an empty shell");
    for (std::size_t k = 0; k < p.seats.size(); ++k) {
      const AssemblySeat& s = p.seats[k];
      const std::string sw = where + ": seats[" + std::to_string(k) + "]";
      if (s.other < 0 || s.other >= n || s.other == i) {
        throw std::invalid_argument(sw + ".other = " + std::to_string(s.other) +
                                    " is not another part");
      }
      if (!IsRigid(s.X_OS)) throw std::invalid_argument(sw + ".X_OS is not a rigid transform");
      if (!NonNegativeFinite(s.position_tolerance)) {
        throw std::invalid_argument(
            sw + ".position_tolerance = " + std::to_string(s.position_tolerance) +
            " must be finite and >= 0");
      }
      if (!NonNegativeFinite(s.angle_tolerance)) {
        throw std::invalid_argument(sw + ".angle_tolerance = " + std::to_string(s.angle_tolerance) +
                                    " must be finite and >= 0");
      }
    }
    max_shell = std::max(max_shell, p.shell_P.points_T.size());
    poses_.push_back(p.X_WP);
    inverse_.push_back(p.X_WP.inverse(Eigen::Isometry));
    radius_.push_back(p.shell_P.size() > 0 ? p.shell_P.Radius() : 0.0);
    seated_.push_back(0);
  }
  for (const Eigen::Vector3d& r : tool_shell_.points_T) {
    if (!r.allFinite()) throw std::invalid_argument("AssemblyField: tool shell point not finite");
  }
  // Shell clusters: points grouped by their cell of kClusterCell in P.
  clusters_.resize(n);
  cluster_points_.resize(n);
  cluster_point_offset_.resize(n);
  for (int j = 0; j < n; ++j) {
    const std::vector<Eigen::Vector3d>& r = parts_[j].shell_P.points_T;
    std::vector<std::array<long, 3>> cell(r.size());
    for (std::size_t i = 0; i < r.size(); ++i) {
      for (int a = 0; a < 3; ++a)
        cell[i][a] = static_cast<long>(std::floor(r[i](a) / kClusterCell));
    }
    std::vector<int>& order = cluster_points_[j];
    order.resize(r.size());
    cluster_point_offset_[j].assign(r.size(), 0.0);
    for (std::size_t i = 0; i < r.size(); ++i) order[i] = static_cast<int>(i);
    std::stable_sort(order.begin(), order.end(), [&](int a, int b) { return cell[a] < cell[b]; });
    for (std::size_t begin = 0; begin < order.size();) {
      std::size_t end = begin;
      Eigen::AlignedBox3d box;
      while (end < order.size() && cell[order[end]] == cell[order[begin]])
        box.extend(r[order[end++]]);
      ShellCluster cluster;
      cluster.centre_P = box.center();
      for (std::size_t k = begin; k < end; ++k) {
        cluster_point_offset_[j][k] = (r[order[k]] - cluster.centre_P).norm();
        cluster.radius = std::max(cluster.radius, cluster_point_offset_[j][k]);
      }
      cluster.begin = static_cast<int>(begin);
      cluster.end = static_cast<int>(end);
      clusters_[j].push_back(cluster);
      begin = end;
    }
  }
  near_.assign((max_shell + 63) / 64, 0);
  candidate_point_.assign(max_shell * n, 0);
  candidate_phi_.assign(max_shell * n, 0.0);
  candidate_grad_.assign(max_shell * n, Eigen::Vector3d::Zero());
  candidate_x0_.assign(max_shell * n, Eigen::Vector3d::Zero());
  candidate_grad_norm_.assign(max_shell * n, 0.0);
  candidate_reach_.assign(max_shell * n, 0.0);
  shell_point_norm_.resize(n);
  for (int j = 0; j < n; ++j) {
    for (const Eigen::Vector3d& r : parts_[j].shell_P.points_T)
      shell_point_norm_[j].push_back(r.norm());
  }
  for (std::vector<double>* b :
       {&batch_x_, &batch_y_, &batch_z_, &batch_phi_, &batch_gx_, &batch_gy_, &batch_gz_})
    b->assign(std::max(max_shell, tool_shell_.points_T.size()), 0.0);
  batch_point_.assign(max_shell, 0);
  batch_x_W_.assign(max_shell, Eigen::Vector3d::Zero());
  last_phi_.assign(max_shell * n, 0.0);
  last_x_.assign(max_shell * n, Eigen::Vector3d::Zero());
  last_epoch_.assign(max_shell * n, 0);
  // Parts built in a seat start seated (the other parts at their initial poses).
  for (int i = 0; i < n; ++i) seated_[i] = !parts_[i].fixed && FindSeat(i, poses_[i], nullptr);
  Publish();
}

double AssemblyField::Phi(int j, const Eigen::Vector3d& p_W,
                          Eigen::Vector3d* gradient_W) const noexcept {
  if (gradient_W == nullptr) return parts_[j].field_P->Evaluate(inverse_[j] * p_W, nullptr);
  Eigen::Vector3d g_P;
  const double v = parts_[j].field_P->Evaluate(inverse_[j] * p_W, &g_P);
  *gradient_W = poses_[j].linear() * g_P;
  return v;
}

void AssemblyField::Gather(int j, int m, const Eigen::Vector3d& p_W) noexcept {
  const Eigen::Vector3d p_P = inverse_[j] * p_W;  // as Phi maps it
  batch_x_[m] = p_P.x();
  batch_y_[m] = p_P.y();
  batch_z_[m] = p_P.z();
}

Eigen::Vector3d AssemblyField::GatheredGradient_W(int j, int k) const noexcept {
  return poses_[j].linear() * Eigen::Vector3d(batch_gx_[k], batch_gy_[k], batch_gz_[k]);
}

void AssemblyField::EvaluateGathered(int j, int m, bool gradient) noexcept {
  const DistanceField& field = *parts_[j].field_P;
  if (settings_.batch_evaluation) {
    field.EvaluateBatch(batch_x_.data(), batch_y_.data(), batch_z_.data(), m, batch_phi_.data(),
                        gradient ? batch_gx_.data() : nullptr, batch_gy_.data(), batch_gz_.data());
    return;
  }
  Eigen::Vector3d g;
  for (int k = 0; k < m; ++k) {
    const Eigen::Vector3d p(batch_x_[k], batch_y_[k], batch_z_[k]);
    batch_phi_[k] = field.Evaluate(p, gradient ? &g : nullptr);
    if (gradient) {
      batch_gx_[k] = g.x();
      batch_gy_[k] = g.y();
      batch_gz_[k] = g.z();
    }
  }
}

bool AssemblyField::FindSeat(int i, const Eigen::Isometry3d& X_WP,
                             Eigen::Isometry3d* X_WS) const noexcept {
  for (const AssemblySeat& s : parts_[i].seats) {
    const Eigen::Isometry3d seat = poses_[s.other] * s.X_OS;
    const double dp = (X_WP.translation() - seat.translation()).norm();
    const Eigen::Quaterniond dq(Eigen::Matrix3d(seat.linear().transpose() * X_WP.linear()));
    const double angle = RotationVector(dq.normalized()).norm();
    if (dp <= s.position_tolerance && angle <= s.angle_tolerance) {
      if (X_WS != nullptr) *X_WS = seat;
      return true;
    }
  }
  return false;
}

bool AssemblyField::AlignmentWrench(int i, const Eigen::Isometry3d& X_WP, Eigen::Vector3d* f_W,
                                    Eigen::Vector3d* tau_W) const noexcept {
  const AlignmentSnapSettings& s = settings_.align;
  Eigen::Vector3d f = Eigen::Vector3d::Zero(), tau = Eigen::Vector3d::Zero();
  bool captured = false;
  // S(x) = x²(3 − 2x) on [0, 1]: 0 with zero slope at the capture boundary.
  const auto smooth = [](double x) { return x <= 0 ? 0.0 : x >= 1 ? 1.0 : x * x * (3 - 2 * x); };
  if (s.enabled) {
    const Eigen::Vector3d z = X_WP.linear().col(2);
    for (const AssemblySeat& seat : parts_[i].seats) {
      const Eigen::Isometry3d X_WS = poses_[seat.other] * seat.X_OS;
      const Eigen::Vector3d a = X_WS.linear().col(2);
      const Eigen::Vector3d e = X_WP.translation() - X_WS.translation();
      const Eigen::Vector3d c = z.cross(a);
      const double sin_angle = c.norm();
      const double angle = std::atan2(sin_angle, z.dot(a));
      const double w =
          smooth(1.0 - e.norm() / s.capture_distance) * smooth(1.0 - angle / s.capture_angle);
      if (!(w > 0)) continue;
      captured = true;
      f -= s.stiffness * w * (e - e.dot(a) * a);
      // ρ = α c/|c| (≈ c for tiny angles, where α/sin α → 1).
      tau += s.rot_stiffness * w * (sin_angle > 1e-12 ? (angle / sin_angle) * c : c);
    }
    const double fn = f.norm(), tn = tau.norm();
    if (fn > s.max_force) f *= s.max_force / fn;
    if (tn > s.max_torque) tau *= s.max_torque / tn;
  }
  *f_W = f;
  *tau_W = tau;
  return captured;
}

double AssemblyField::PoleGrasp(int j, const Eigen::Isometry3d& X_WPj, const ToolKinematics& tool,
                                bool* both_pushing, double depths[2]) const noexcept {
  const GraspSettings& s = settings_.grasp;
  const Eigen::Isometry3d X_PW = X_WPj.inverse(Eigen::Isometry);
  const DistanceField& field = *parts_[j].field_P;
  // φ of the part in W, its gradient turned into W.
  auto phi_W = [&](const Eigen::Vector3d& p_W, Eigen::Vector3d* gradient_W) {
    if (gradient_W == nullptr) return field.Evaluate(X_PW * p_W, nullptr);
    Eigen::Vector3d g_P;
    const double v = field.Evaluate(X_PW * p_W, &g_P);
    *gradient_W = X_WPj.linear() * g_P;
    return v;
  };
  const PoleDirections poles = GripPoleDirections(tool.grasp);
  PoleContact contact[2];
  depths[0] = depths[1] = 0.0;
  *both_pushing = false;
  for (int k = 0; k < 2; ++k) {
    // Unrefined when the pole cannot reach inside (its depth is 0 either way).
    contact[k] = FindPoleContact(phi_W, tool.p_WT, tool.R_WT, poles, k, s.pole_length, s.samples,
                                 s.refine_iterations, 0.0);
    depths[k] = contact[k].depth;
    // A pole that does not push into the part: no grasp whatever the other does (the squeeze
    // and the depths are used only when both push), so the other is not searched.
    if (!contact[k].pushing) return 0.0;
  }
  *both_pushing = true;
  return SqueezeOf(contact[0], contact[1], tool.grasp_rate, s);
}

ToolWrench AssemblyField::ToolContact(const ToolKinematics& tool) noexcept {
  ToolWrench w;
  const int n = size();
  const double tool_radius = tool_shell_.size() > 0 ? tool_shell_.Radius() : 0.0;
  int contacts = 0;
  Eigen::Vector3d g;
  const int m = tool_shell_.size();
  for (int j = 0; j < n; ++j) {
    if (m == 0 || Phi(j, tool.p_WT, nullptr) > tool_radius) continue;
    for (int i = 0; i < m; ++i) {
      const Eigen::Vector3d r = tool.R_WT * tool_shell_.points_T[i];
      Gather(j, i, tool.p_WT + r);  // as the scalar field saw it
    }
    EvaluateGathered(j, m, true);
    for (int i = 0; i < m; ++i) {
      const Eigen::Vector3d r = tool.R_WT * tool_shell_.points_T[i];
      const double phi = batch_phi_[i];
      g = GatheredGradient_W(j, i);
      const double gn = g.norm();
      if (!(phi < 0) || !(gn > 0)) continue;
      const Eigen::Vector3d f = settings_.contact_stiffness * (-phi) * (g / gn);
      w.f_T_W += f;
      w.m_T_W += r.cross(f);
      ++contacts;
    }
  }
  const double s = std::min(1.0, settings_.reference_contacts / std::max(1.0, double(contacts)));
  w.f_T_W *= s;
  w.m_T_W *= s;
  contacts_ = contacts;
  return w;
}

ToolWrench AssemblyField::CarryStep(const ToolKinematics& tool, double dt) noexcept {
  const AssemblySettings& s = settings_;
  const int c = carried_;
  const int n = size();
  const PointShell& shell = parts_[c].shell_P;
  const double radius = radius_[c];
  const Eigen::Isometry3d X_WT = Pose(tool.p_WT, tool.R_WT);
  const Eigen::Isometry3d X_Wtarget = X_WT * X_TP_;
  const Eigen::Vector3d p_target = X_Wtarget.translation();
  const Eigen::Quaterniond q_target(Eigen::Matrix3d(X_Wtarget.linear()));
  const Eigen::Vector3d v_target = tool.v_WT + tool.w_WT.cross(p_target - tool.p_WT);
  Eigen::Vector3d p = poses_[c].translation();

  // Candidates (point, part) at the start of the tick.
  num_candidates_ = 0;
  {
    const double reach =
        s.contact_margin +
        2.0 * dt * (v_.norm() + w_.norm() * radius + v_target.norm() + tool.w_WT.norm() * radius);
    const Eigen::Matrix3d R = q_.toRotationMatrix();
    for (int j = 0; j < n; ++j) {
      if (j == c || Phi(j, p, nullptr) >= radius + reach) continue;
      // Clusters near part j mark their points; the points are then tested in shell order (so
      // the candidates, and every sum over them, come in the same order as without clusters).
      const std::size_t words = (shell.size() + 63) / 64;
      std::fill(near_.begin(), near_.begin() + words, std::uint64_t{0});
      const std::vector<ShellCluster>& clusters = clusters_[c];
      const int num_clusters = static_cast<int>(clusters.size());
      if (s.cull_shell_search) {
        for (int k = 0; k < num_clusters; ++k) Gather(j, k, p + R * clusters[k].centre_P);
        EvaluateGathered(j, num_clusters, false);
      }
      // Within a cluster, a point at d_i from its centre has φ_j >= φ_j(centre) − d_i: it is
      // tested only when that bound is below the reach (the slack covers rounding).
      for (int q = 0; q < num_clusters; ++q) {
        const ShellCluster& cluster = clusters[q];
        const double phi_centre = s.cull_shell_search ? batch_phi_[q] : -1e300;
        if (phi_centre >= cluster.radius + reach) continue;
        for (int k = cluster.begin; k < cluster.end; ++k) {
          if (phi_centre - cluster_point_offset_[c][k] < reach + 1e-9)
            near_[cluster_points_[c][k] >> 6] |= std::uint64_t{1} << (cluster_points_[c][k] & 63);
        }
      }
      // φ_j at the marked points, then φ_j and ∇φ_j at those within reach (the candidates).
      // A marked point whose φ_j was evaluated at x_last earlier in this carry (part j has not
      // moved since) has φ_j(x) >= φ_j(x_last) − |x − x_last|; it is not evaluated again while
      // that bound is beyond the reach.
      int m = 0;
      const std::size_t last = static_cast<std::size_t>(j) * batch_point_.size();  // max shell
      for (std::size_t word = 0; word < words; ++word) {
        for (std::uint64_t bits = near_[word]; bits != 0; bits &= bits - 1) {
          const int i = static_cast<int>(64 * word) + std::countr_zero(bits);
          const Eigen::Vector3d x = p + R * shell.points_T[i];
          if (s.cull_shell_search && last_epoch_[last + i] == search_epoch_) {
            const double bound = last_phi_[last + i] - reach - 1e-9;
            if (bound >= 0 && bound * bound >= (x - last_x_[last + i]).squaredNorm()) continue;
          }
          batch_point_[m] = i;
          batch_x_W_[m] = x;
          Gather(j, m++, x);
        }
      }
      EvaluateGathered(j, m, true);
      for (int k = 0; k < m; ++k) {
        const std::size_t e = last + batch_point_[k];
        last_phi_[e] = batch_phi_[k];
        last_x_[e] = batch_x_W_[k];
        last_epoch_[e] = search_epoch_;
      }
      for (int k = 0; k < m; ++k) {
        if (!(batch_phi_[k] < reach)) continue;
        const int i = batch_point_[k];
        candidate_point_[num_candidates_] = i;
        candidate_x0_[num_candidates_] = batch_x_W_[k];
        candidate_phi_[num_candidates_] = batch_phi_[k];
        candidate_grad_[num_candidates_] = GatheredGradient_W(j, k);
        ++num_candidates_;
      }
    }
  }

  // A candidate's expansion φ0 + ∇φ·(x − x0) is at least φ0 − |∇φ| |x − x0|, and the point
  // has moved |x − x0| <= |p − p0| + ‖R − R0‖_F |r| since the tick's start: candidates whose
  // bound stays above kSkipSlack (far above the rounding of the expansion, ~1e-16 m) would get
  // φ > 0 and no force, so they are not expanded (the sums are the same, bit for bit).
  constexpr double kSkipSlack = 1e-12;  // m
  const Eigen::Vector3d p0 = p;
  const Eigen::Matrix3d R0 = q_.toRotationMatrix();
  for (int k = 0; k < num_candidates_; ++k) {
    candidate_grad_norm_[k] = candidate_grad_[k].norm();
    candidate_reach_[k] = candidate_grad_norm_[k] * shell_point_norm_[c][candidate_point_[k]];
  }
  const double h = dt / s.substeps;
  const Eigen::Vector3d inv_inertia = s.inertia.cwiseInverse();
  Eigen::Vector3d g;
  for (int step = 0; step < s.substeps; ++step) {
    const Eigen::Matrix3d R = q_.toRotationMatrix();
    const double dp = (p - p0).norm(), dR = (R - R0).norm();
    Eigen::Vector3d f_contact = Eigen::Vector3d::Zero(), t_contact = Eigen::Vector3d::Zero();
    int contacts = 0;
    for (int k = 0; k < num_candidates_; ++k) {
      if (s.skip_far_candidates &&
          candidate_phi_[k] - candidate_grad_norm_[k] * dp - candidate_reach_[k] * dR > kSkipSlack)
        continue;
      const Eigen::Vector3d r = R * shell.points_T[candidate_point_[k]];
      g = candidate_grad_[k];
      const double phi = candidate_phi_[k] + g.dot(p + r - candidate_x0_[k]);
      const double gn = candidate_grad_norm_[k];
      if (!(phi < 0) || !(gn > 0)) continue;
      const Eigen::Vector3d nrm = g / gn;
      const double v_n = nrm.dot(v_ + w_.cross(r));
      const double magnitude =
          std::max(0.0, s.contact_stiffness * (-phi) - s.contact_damping * v_n);
      const Eigen::Vector3d f = magnitude * nrm;
      f_contact += f;
      t_contact += r.cross(f);
      ++contacts;
    }
    const double scale = std::min(1.0, s.reference_contacts / std::max(1.0, double(contacts)));
    contacts_ = contacts;
    Eigen::Vector3d f_align = Eigen::Vector3d::Zero(), t_align = Eigen::Vector3d::Zero();
    if (s.align.enabled) AlignmentWrench(c, Pose(p, R), &f_align, &t_align);
    const Eigen::Vector3d f_c =
        s.coupling_stiffness * (p_target - p) + s.coupling_damping * (v_target - v_);
    const Eigen::Vector3d tau_c =
        s.rot_coupling_stiffness * RotationVector(q_target * q_.conjugate()) +
        s.rot_coupling_damping * (tool.w_WT - w_);
    v_ += (h / s.mass) * (f_c + scale * f_contact + f_align);
    w_ += h *
          (R * inv_inertia.asDiagonal() * (R.transpose() * (tau_c + scale * t_contact + t_align)));
    p += h * v_;
    q_ = IntegrateRotation(q_, w_, h);
  }
  const Eigen::Vector3d f_c =
      s.coupling_stiffness * (p_target - p) + s.coupling_damping * (v_target - v_);
  const Eigen::Vector3d tau_c =
      s.rot_coupling_stiffness * RotationVector(q_target * q_.conjugate()) +
      s.rot_coupling_damping * (tool.w_WT - w_);
  if (!(p.allFinite() && q_.coeffs().allFinite() && v_.allFinite() && w_.allFinite())) {
    // Recover on the target pose (the loop zeroes this tick's NaN wrench).
    p = p_target;
    q_ = q_target;
    v_.setZero();
    w_.setZero();
  }
  poses_[c] = Pose(p, q_.toRotationMatrix());
  inverse_[c] = poses_[c].inverse(Eigen::Isometry);
  ToolWrench w;
  w.f_T_W = -f_c;
  w.m_T_W = (p_target - tool.p_WT).cross(-f_c) - tau_c;
  return w;
}

ToolWrench AssemblyField::Evaluate(const ToolKinematics& tool) noexcept {
  if (!initialized_) {
    initialized_ = true;
    last_time_ = tool.time;
  }
  double dt = tool.time - last_time_;
  last_time_ = tool.time;
  if (!(dt > 0)) dt = 1e-3;
  dt = std::min(dt, settings_.max_dt);

  ToolWrench w;
  double depths[2];
  bool both = false;
  if (carried_ >= 0) {
    const Eigen::Isometry3d X_Wtarget = Pose(tool.p_WT, tool.R_WT) * X_TP_;
    const double q = PoleGrasp(carried_, X_Wtarget, tool, &both, depths);
    if (both) {
      w = CarryStep(tool, dt);
      w.g = -2.0 * q;
    } else {
      // Released where it is; seated if it fits.
      const int c = carried_;
      carried_ = -1;
      released_ = c;
      v_.setZero();
      w_.setZero();
      Eigen::Isometry3d X_WS;
      if (FindSeat(c, poses_[c], &X_WS)) {
        poses_[c] = X_WS;
        inverse_[c] = X_WS.inverse(Eigen::Isometry);
        seated_[c] = 1;
      }
    }
  }
  if (carried_ < 0) {
    w = ToolContact(tool);
    const double reach = settings_.grasp.pole_length;
    for (int j = 0; j < size(); ++j) {
      if (parts_[j].fixed) continue;
      if (Phi(j, tool.p_WT, nullptr) > reach) {
        if (j == released_) released_ = -1;
        continue;
      }
      const double q = PoleGrasp(j, poses_[j], tool, &both, depths);
      if (!both) {
        if (j == released_) released_ = -1;
        continue;
      }
      w.g = -2.0 * q;
      const double grab = settings_.grasp.grab_depth;
      if (j != released_ && depths[0] >= grab && depths[1] >= grab) {
        carried_ = j;
        ++search_epoch_;  // the bounds of the last carry's search do not hold for this one
        seated_[j] = 0;
        X_TP_ = Pose(tool.p_WT, tool.R_WT).inverse(Eigen::Isometry) * poses_[j];
        q_ = Eigen::Quaterniond(Eigen::Matrix3d(poses_[j].linear())).normalized();
        v_ = tool.v_WT + tool.w_WT.cross(poses_[j].translation() - tool.p_WT);
        w_ = tool.w_WT;
      }
      break;
    }
  }
  Publish();
  return w;
}

void AssemblyField::Publish() noexcept {
  AssemblyState& out = published_.WriteSlot();
  const int n = size();
  out.count = n;
  out.carried = carried_;
  out.contacts = contacts_;
  for (int i = 0; i < n; ++i) {
    out.X_WP[i] = poses_[i];
    out.seated[i] = seated_[i] != 0;
  }
  published_.Publish();
}

}  // namespace spidarcad::haptics
