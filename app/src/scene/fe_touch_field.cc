// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#include "scene/fe_touch_field.h"

#include <algorithm>
#include <cmath>
#include <sstream>
#include <stdexcept>

#include "scene/grip_poles.h"
#include "spidarcad/haptics/geometry.h"

namespace spidarcad::app {
namespace {

[[noreturn]] void BadSetting(const char* field, double value, const char* rule) {
  std::ostringstream msg;
  msg << "FE touch field: " << field << " = " << value << " (" << rule << ")";
  throw std::invalid_argument(msg.str());
}

constexpr int kMaxGridCellsPerAxis = 128;
// Active-set passes per tick (each: targets, solve, release the pulling nodes).
constexpr int kActiveSetPasses = 4;

// The contact point (sphere) through which candidate b was found (0 when it was not).
int SphereOfFound(const std::array<int, kMaxFeContacts>& found,
                  const std::array<int, kMaxFeContacts>& sphere, int num_found, int b) {
  int at = 0;
  for (int j = 0; j < num_found; ++j)
    if (found[j] == b) at = sphere[j];
  return at;
}

}  // namespace

FeTouchField::FeTouchField(std::shared_ptr<FeModel> model, const FeTouchSettings& settings,
                           std::shared_ptr<FeContactChannel> channel)
    : model_(std::move(model)), cache_(nullptr), settings_(settings), channel_(std::move(channel)) {
  if (!model_) throw std::invalid_argument("FE touch field: no model");
  if (!(settings_.tool_radius > 0.0) || !std::isfinite(settings_.tool_radius))
    BadSetting("tool_radius", settings_.tool_radius, "must be > 0 m");
  if (settings_.max_contacts < 1 || settings_.max_contacts > kMaxFeContacts)
    BadSetting("max_contacts", settings_.max_contacts, "must be in 1..kMaxFeContacts (64)");
  if (!(settings_.force_scale >= 0.0) || !std::isfinite(settings_.force_scale))
    BadSetting("force_scale", settings_.force_scale, "must be >= 0");
  if (!(settings_.max_force > 0.0)) BadSetting("max_force", settings_.max_force, "must be > 0 N");
  if (!(settings_.coupling_stiffness >= 0.0) || !std::isfinite(settings_.coupling_stiffness))
    BadSetting("coupling_stiffness", settings_.coupling_stiffness, "must be >= 0 N/m");
  if (settings_.grasp && !(settings_.pole_length > 0.0))
    BadSetting("pole_length", settings_.pole_length, "must be > 0 m");
  if (!(settings_.focus_radius > 0.0)) settings_.focus_radius = 3.0 * settings_.tool_radius;

  cache_ = &model_->cache();
  solver_ = std::make_unique<fem::CachedContactSolver>(cache_, settings_.max_contacts);
  const int n = cache_->num_candidates();
  const Eigen::MatrixX3d& nodes = model_->mesh().nodes;
  positions_.resize(n);
  fixed_.resize(n);
  Eigen::Vector3d lo = Eigen::Vector3d::Constant(1e300), hi = Eigen::Vector3d::Constant(-1e300);
  for (int b = 0; b < n; ++b) {
    positions_[b] = nodes.row(cache_->candidate_node(b)).transpose();
    fixed_[b] = cache_->IsFixed(b) ? 1 : 0;
    lo = lo.cwiseMin(positions_[b]);
    hi = hi.cwiseMax(positions_[b]);
  }
  if (n == 0) lo = hi = Eigen::Vector3d::Zero();
  const double extent = (hi - lo).maxCoeff();
  cell_ = std::max(settings_.tool_radius, extent / kMaxGridCellsPerAxis);
  grid_min_ = lo;
  for (int i = 0; i < 3; ++i) dims_(i) = static_cast<int>(std::floor((hi(i) - lo(i)) / cell_)) + 1;
  const long cells = static_cast<long>(dims_(0)) * dims_(1) * dims_(2);
  cell_start_.assign(cells + 1, 0);
  std::vector<long> cell_of(n);
  for (int b = 0; b < n; ++b) {
    const Eigen::Vector3i ijk = ((positions_[b] - grid_min_) / cell_)
                                    .array()
                                    .floor()
                                    .cast<int>()
                                    .cwiseMin(dims_.array() - 1);
    cell_of[b] = (static_cast<long>(ijk(2)) * dims_(1) + ijk(1)) * dims_(0) + ijk(0);
    ++cell_start_[cell_of[b] + 1];
  }
  for (long c = 0; c < cells; ++c) cell_start_[c + 1] += cell_start_[c];
  cell_items_.resize(n);
  std::vector<int> fill(cell_start_.begin(), cell_start_.end() - 1);
  for (int b = 0; b < n; ++b) cell_items_[fill[cell_of[b]]++] = b;
}

FeTouchField::~FeTouchField() = default;

Eigen::Vector3d FeTouchField::PoleTip(const haptics::ToolKinematics& tool, int i) const {
  return GripPoleTip(tool, settings_.pole_length, i);
}

template <typename Visit>
bool FeTouchField::ForEachFreeCandidate(const Eigen::Vector3d& lo_p, const Eigen::Vector3d& hi_p,
                                        Visit visit) const {
  Eigen::Vector3i lo, hi;
  for (int i = 0; i < 3; ++i) {
    const double a = std::floor((lo_p(i) - grid_min_(i)) / cell_),
                 z = std::floor((hi_p(i) - grid_min_(i)) / cell_);
    if (z < 0.0 || a > dims_(i) - 1) return false;
    lo(i) = static_cast<int>(std::max(0.0, a));
    hi(i) = static_cast<int>(std::min<double>(dims_(i) - 1, z));
  }
  for (int z = lo(2); z <= hi(2); ++z)
    for (int y = lo(1); y <= hi(1); ++y)
      for (int x = lo(0); x <= hi(0); ++x) {
        const long cell = (static_cast<long>(z) * dims_(1) + y) * dims_(0) + x;
        for (int it = cell_start_[cell]; it < cell_start_[cell + 1]; ++it) {
          const int b = cell_items_[it];
          if (!fixed_[b]) visit(b);
        }
      }
  return true;
}

void FeTouchField::InsertFound(int b, double dist, int sphere) {
  // Already found through the other sphere: keep the nearer.
  int at = -1;
  for (int j = 0; j < num_found_; ++j)
    if (found_[j] == b) at = j;
  if (at >= 0) {
    if (dist >= found_dist_[at]) return;
    for (int j = at; j + 1 < num_found_; ++j) {
      found_[j] = found_[j + 1];
      found_dist_[j] = found_dist_[j + 1];
      found_sphere_[j] = found_sphere_[j + 1];
    }
    --num_found_;
  }
  if (num_found_ == settings_.max_contacts && dist >= found_dist_[num_found_ - 1]) return;
  int j = std::min(num_found_, settings_.max_contacts - 1);
  while (j > 0 && found_dist_[j - 1] > dist) {
    found_[j] = found_[j - 1];
    found_dist_[j] = found_dist_[j - 1];
    found_sphere_[j] = found_sphere_[j - 1];
    --j;
  }
  found_[j] = b;
  found_dist_[j] = dist;
  found_sphere_[j] = sphere;
  num_found_ = std::min(num_found_ + 1, settings_.max_contacts);
}

int FeTouchField::Collect(const Eigen::Vector3d& c, int sphere) {
  const double r = settings_.tool_radius;
  int inside = 0;
  ForEachFreeCandidate(c.array() - r, c.array() + r, [&](int b) {
    const double dist = (positions_[b] - c).norm();
    if (!(dist < r)) return;
    ++inside;
    InsertFound(b, dist, sphere);
  });
  return inside;
}

Eigen::Vector3d FeTouchField::Baseline(int b) const {
  return cache_->baseline().segment<3>(3 * cache_->OutputIndexOfCandidate(b));
}

bool FeTouchField::FitPatch(const Eigen::Vector3d& c, const PatchFit* prior, PatchFit* fit) const {
  const double r = settings_.tool_radius;
  Eigen::Vector3d n, p;
  if (prior != nullptr) {
    n = prior->normal;
    p = c - (c - prior->point).dot(n) * n;
  } else {
    int nearest = -1;
    double best = 2.0 * r;
    ForEachFreeCandidate(c.array() - 2.0 * r, c.array() + 2.0 * r, [&](int b) {
      const double dist = (positions_[b] - c).norm();
      if (dist < best) {
        best = dist;
        nearest = b;
      }
    });
    if (nearest < 0) return false;
    n = model_->design_normals().row(nearest).transpose();
    const Eigen::Vector3d x = positions_[nearest] + Baseline(nearest);
    p = c - (c - x).dot(n) * n;
  }
  // Two passes over the facing free nodes within R of p (mesh normal n_b·n > 0; the
  // kMaxFeContacts nearest p). The plane's normal n is the patch's dominant design normal
  // (FeModel::design_normals: the design's where the model has it, else the mesh's): the one that
  // the most patch nodes' design normals agree with (score Σ_i (n_i·n_j)^1024). On a flat face
  // that is the face's normal exactly; a mean, or the normal of a coarse mesh's facets next to a
  // rounded edge, would push the patch partly in its plane, where the part is stiffer by orders of
  // magnitude. The height h = (c − q)·n is the mean over the nodes weighted by (n_i·n)^1024 (q the
  // loaded positions X + u0); then p = c − h n.
  const Eigen::MatrixX3d& facing = model_->candidate_normals();
  const Eigen::MatrixX3d& normals = model_->design_normals();
  auto sharp = [](double x) {  // max(0, x)^1024
    x = std::max(0.0, x);
    for (int i = 0; i < 10; ++i) x *= x;
    return x;
  };
  for (int pass = 0; pass < 2; ++pass) {
    std::array<int, kMaxFeContacts> near{};
    std::array<double, kMaxFeContacts> near_dist{};
    int m = 0;
    ForEachFreeCandidate(p.array() - r, p.array() + r, [&](int b) {
      const double dist = (positions_[b] - p).norm();
      if (!(dist < r) || !(facing.row(b).dot(n) > 0.0)) return;
      if (m == kMaxFeContacts && dist >= near_dist[m - 1]) return;
      int j = std::min(m, kMaxFeContacts - 1);
      while (j > 0 && near_dist[j - 1] > dist) {
        near[j] = near[j - 1];
        near_dist[j] = near_dist[j - 1];
        --j;
      }
      near[j] = b;
      near_dist[j] = dist;
      m = std::min(m + 1, kMaxFeContacts);
    });
    if (m == 0) return false;
    int best = 0;
    double best_score = -1.0;
    for (int j = 0; j < m; ++j) {
      double score = 0.0;
      for (int i = 0; i < m; ++i) score += sharp(normals.row(near[i]).dot(normals.row(near[j])));
      if (score > best_score) {
        best_score = score;
        best = j;
      }
    }
    n = normals.row(near[best]).transpose();
    double weight = 0.0, height = 0.0;
    Eigen::Vector3d q = Eigen::Vector3d::Zero();
    for (int i = 0; i < m; ++i) {
      const int b = near[i];
      const double w = sharp(normals.row(b).dot(n));
      const Eigen::Vector3d x = positions_[b] + Baseline(b);
      weight += w;
      height += w * (c - x).dot(n);
      q += w * x;
    }
    const double h = height / weight;
    fit->centroid = q / weight;
    p = c - h * n;
    fit->depth = r - h;
  }
  fit->normal = n;
  fit->point = p;
  return fit->normal.allFinite() && std::isfinite(fit->depth);
}

int FeTouchField::PatchContacts(const Eigen::Vector3d* centre, int spheres, int* inside,
                                bool* solved) {
  FeContactState& st = state_;
  const double r = settings_.tool_radius;
  num_found_ = 0;
  *inside = 0;
  *solved = false;
  bool active[2] = {false, false};
  for (int i = 0; i < spheres; ++i) {
    PatchFit fit;
    active[i] =
        FitPatch(centre[i], patch_valid_[i] ? &patch_[i] : nullptr, &fit) && fit.depth > 0.0;
    patch_valid_[i] = active[i];
    if (!active[i]) continue;
    patch_[i] = fit;
    ForEachFreeCandidate(fit.point.array() - r, fit.point.array() + r, [&](int b) {
      const double dist = (positions_[b] - fit.point).norm();
      if (!(dist < r) || !(model_->candidate_normals().row(b).dot(fit.normal) > 0.0)) return;
      ++*inside;
      InsertFound(b, dist, i);
    });
  }
  if (spheres > 0 && active[0]) {
    st.depth = patch_[0].depth;
    st.normal = patch_[0].normal;
  }
  // Up to two passes: a contact point whose patch would pull the tool in is released.
  int k = 0;
  for (int pass = 0; pass < 2; ++pass) {
    // Contact set: the found nodes of the active points, in found order.
    for (int s = solver_->num_contacts() - 1; s >= 0; --s) {
      const int b = solver_->contact(s);
      bool keep = false;
      for (int j = 0; j < num_found_; ++j)
        keep = keep || (found_[j] == b && active[found_sphere_[j]]);
      if (!keep) solver_->Remove(b);
    }
    for (int j = 0; j < num_found_; ++j) {
      if (!active[found_sphere_[j]]) continue;
      bool have = false;
      for (int s = 0; s < solver_->num_contacts(); ++s)
        have = have || solver_->contact(s) == found_[j];
      if (have) continue;
      if (solver_->Add(found_[j]) == fem::CachedContactStatus::kNoColumnReady)
        st.waiting_for_columns = true;
    }
    solver_->Refresh();
    k = solver_->num_contacts();
    if (k == 0) break;
    for (int s = 0; s < k; ++s) {
      const int b = solver_->contact(s);
      const int sphere = SphereOfFound(found_, found_sphere_, num_found_, b);
      sphere_of_slot_[s] = sphere;
      const Eigen::Vector3d& n = patch_[sphere].normal;
      const Eigen::Vector3d target = Baseline(b) - patch_[sphere].depth * n;
      st.candidate[s] = b;
      st.substitute[s] = solver_->substitute(s);
      normal_[s] = n;
      for (int i = 0; i < 3; ++i) {
        st.target[3 * s + i] = target(i);
        normal_flat_[3 * s + i] = n(i);
      }
    }
    *solved = settings_.frictionless && solver_->SolveNormal(normal_flat_.data(), st.target.data(),
                                                             st.force.data(), st.target.data());
    if (!*solved) *solved = solver_->Solve(st.target.data(), st.force.data());
    if (!*solved || spheres < 2) break;
    bool released = false;
    for (int i = 0; i < spheres; ++i) {
      if (!active[i]) continue;
      double push = 0.0;  // force on the tool along n_i
      for (int s = 0; s < k; ++s)
        if (sphere_of_slot_[s] == i)
          push -= patch_[i].normal.dot(
              Eigen::Vector3d(st.force[3 * s], st.force[3 * s + 1], st.force[3 * s + 2]));
      if (push < 0.0) {
        active[i] = false;
        patch_valid_[i] = false;
        released = true;
      }
    }
    if (!released) break;
    *solved = false;
  }
  return k;
}

haptics::ToolWrench FeTouchField::Evaluate(const haptics::ToolKinematics& tool) noexcept {
  haptics::ToolWrench w;
  FeContactState& st = state_;
  st.time = tool.time;
  st.p_WT = tool.p_WT;
  st.f_tool_W.setZero();
  st.felt_normal_W.setZero();
  st.refused = 0;
  st.stiffness = 0.0;
  st.stiffness_normal.setZero();
  st.waiting_for_columns = false;
  if (!tool.p_WT.allFinite() || !tool.R_WT.allFinite() || !std::isfinite(tool.grasp)) {
    coupled_valid_ = false;
    patch_valid_ = {false, false};
    solver_->Clear();
    st.num_contacts = 0;
    st.num_substituted = 0;
    if (channel_) channel_->buffer.Write(st);
    return w;
  }

  // Focus of the column worker (this thread is its single producer).
  if ((tool.p_WT - focus_).norm() > 0.25 * settings_.focus_radius) {
    focus_ = tool.p_WT;
    cache_->RequestNear(focus_, settings_.focus_radius);
  }

  // Nodes inside the sphere(s), nearest first.
  const int spheres = settings_.grasp ? 2 : 1;
  const bool coupled = !settings_.grasp && settings_.coupling_stiffness > 0.0;
  if (coupled && !coupled_valid_) {
    coupled_ = tool.p_WT;
    coupled_valid_ = true;
  }
  Eigen::Vector3d centre[2];
  if (settings_.grasp) {
    centre[0] = PoleTip(tool, 0);
    centre[1] = PoleTip(tool, 1);
  } else {
    centre[0] = coupled ? coupled_ : tool.p_WT;
  }
  st.p_WC = centre[0];
  int inside = 0, k = 0;
  bool solved = false;
  st.depth = 0.0;
  st.normal.setZero();
  if (settings_.patch_contact) {
    k = PatchContacts(centre, spheres, &inside, &solved);
  } else {
    num_found_ = 0;
    for (int i = 0; i < spheres; ++i) inside += Collect(centre[i], i);

    // Admission on the deformed surface: a found node that is not in contact is taken only if
    // the sphere reaches it where the current contact forces have moved it, i.e. its predicted
    // normal displacement n·u (u = u0 + Σ Ĝ(node, slot) f, last tick's forces and still pinned
    // columns) has not gone past the sphere: n·u > −t. This keeps released (pulling) nodes out
    // and avoids adding and releasing them every tick.
    const double r = settings_.tool_radius;
    const int k_prev = solver_->num_contacts() == st.num_contacts ? st.num_contacts : 0;
    for (int j = 0; j < num_found_; ++j) {
      admit_[j] = 1;
      const int a = found_[j];
      bool have = false;
      for (int s = 0; s < solver_->num_contacts(); ++s) have = have || solver_->contact(s) == a;
      if (have || k_prev == 0) continue;
      const Eigen::Vector3d n = model_->candidate_normals().row(a).transpose();
      const Eigen::Vector3d q = positions_[a] - centre[found_sphere_[j]];
      const double qn = q.dot(n);
      const double t = qn + std::sqrt(std::max(0.0, qn * qn - q.squaredNorm() + r * r));
      Eigen::Vector3d u = cache_->baseline().segment<3>(3 * cache_->OutputIndexOfCandidate(a));
      for (int s = 0; s < k_prev; ++s) {
        const int b = st.candidate[s], sub = st.substitute[s];
        if (solver_->contact(s) != b || solver_->substitute(s) != sub)
          continue;  // not pinned as read
        const int row_node = sub == b ? a : cache_->ShiftedCandidate(a, b, sub);
        const int row = cache_->OutputIndexOfCandidate(row_node);
        if (!cache_->RowReady(row, sub)) continue;  // not computed yet: no prediction
        u += cache_->Block(row, sub) *
             Eigen::Vector3d(st.force[3 * s], st.force[3 * s + 1], st.force[3 * s + 2]);
      }
      if (n.dot(u) <= -t) admit_[j] = 0;
    }

    // Contact set update: remove the nodes that left, then add the new ones (nearest first).
    if (num_found_ == 0) {
      solver_->Clear();
    } else {
      for (int s = solver_->num_contacts() - 1; s >= 0; --s) {
        const int b = solver_->contact(s);
        bool keep = false;
        for (int j = 0; j < num_found_; ++j) keep = keep || found_[j] == b;
        if (!keep) solver_->Remove(b);
      }
      for (int j = 0; j < num_found_; ++j) {
        if (!admit_[j]) continue;
        bool have = false;
        for (int s = 0; s < solver_->num_contacts(); ++s)
          have = have || solver_->contact(s) == found_[j];
        if (have) continue;
        const fem::CachedContactStatus status = solver_->Add(found_[j]);
        if (status == fem::CachedContactStatus::kNoColumnReady) st.waiting_for_columns = true;
      }
      solver_->Refresh();
    }

    // Targets and forces, then release the nodes that would pull the body (n·f > 0: adhesion),
    // a few passes of the active set per tick.
    k = solver_->num_contacts();
    for (int pass = 0; pass < kActiveSetPasses && k > 0; ++pass) {
      // Each contact node pushed along its inward normal −n until it leaves the sphere:
      // |X − t n − c| = r, t = q·n + sqrt((q·n)² − |q|² + r²) > 0 with q = X − c.
      for (int s = 0; s < k; ++s) {
        const int b = solver_->contact(s);
        const int sphere = SphereOfFound(found_, found_sphere_, num_found_, b);
        sphere_of_slot_[s] = sphere;
        const Eigen::Vector3d q = positions_[b] - centre[sphere];
        const Eigen::Vector3d n = model_->candidate_normals().row(b).transpose();
        const double qn = q.dot(n);
        const double t = qn + std::sqrt(std::max(0.0, qn * qn - q.squaredNorm() + r * r));
        st.candidate[s] = b;
        st.substitute[s] = solver_->substitute(s);
        normal_[s] = n;
        for (int i = 0; i < 3; ++i) {
          st.target[3 * s + i] = -t * n(i);
          normal_flat_[3 * s + i] = n(i);
        }
      }
      // Frictionless: normal forces only, the tangential displacements follow (the targets become
      // the resulting displacements); sticking, or if that fails: the full displacement prescribed.
      solved = settings_.frictionless && solver_->SolveNormal(normal_flat_.data(), st.target.data(),
                                                              st.force.data(), st.target.data());
      if (!solved) solved = solver_->Solve(st.target.data(), st.force.data());
      if (!solved || pass + 1 == kActiveSetPasses) break;
      int pulling = 0;
      for (int s = k - 1; s >= 0; --s) {
        const double fn = normal_[s].x() * st.force[3 * s] + normal_[s].y() * st.force[3 * s + 1] +
                          normal_[s].z() * st.force[3 * s + 2];
        if (fn > 0.0) {
          solver_->Remove(solver_->contact(s));
          ++pulling;
        }
      }
      if (pulling == 0) break;
      k = solver_->num_contacts();
      solved = false;
    }
  }
  st.refused = inside - k;
  st.num_contacts = k;
  st.num_substituted = solver_->num_substituted();
  if (k > 0 && solved) {
    Eigen::Vector3d f_sphere[2] = {Eigen::Vector3d::Zero(), Eigen::Vector3d::Zero()};
    Eigen::Vector3d m = Eigen::Vector3d::Zero();
    for (int s = 0; s < k; ++s) {
      const Eigen::Vector3d f_body(st.force[3 * s], st.force[3 * s + 1], st.force[3 * s + 2]);
      f_sphere[sphere_of_slot_[s]] -= f_body;
      const Eigen::Vector3d x =
          positions_[st.candidate[s]] +
          Eigen::Vector3d(st.target[3 * s], st.target[3 * s + 1], st.target[3 * s + 2]);
      m += (x - tool.p_WT).cross(-f_body);
    }
    st.f_tool_W = f_sphere[0] + f_sphere[1];
    if (settings_.patch_contact) {
      // The tool slides over the patch it pushes: only each patch's normal force is felt (the
      // component that defines K), not the tangential reaction that holds the patch rigid.
      m.setZero();
      for (int i = 0; i < spheres; ++i) {
        if (!patch_valid_[i]) {
          f_sphere[i].setZero();
          continue;
        }
        f_sphere[i] = patch_[i].normal * patch_[i].normal.dot(f_sphere[i]);
        m += (patch_[i].point - tool.p_WT).cross(f_sphere[i]);
      }
    }
    st.felt_normal_W = f_sphere[0] + f_sphere[1];
    w.f_T_W = st.felt_normal_W;
    if (settings_.grasp) {
      w.m_T_W = m;
      // g = −Σ F_i · ∂tip_i/∂θ, ∂p̂_i/∂θ = (−sin(θ/2) b ∓ cos(θ/2) a)/2.
      const haptics::PoleDirections poles = haptics::GripPoleDirections(tool.grasp);
      double g = 0.0;
      for (int i = 0; i < 2; ++i)
        g -= f_sphere[i].dot(settings_.pole_length * (tool.R_WT * poles.du_T[i]));
      w.g = g;
    }
  }
  if (coupled) CoupledStep(tool.p_WT, k > 0 && solved ? k : 0, &w);
  if (!coupled && k > 0 && solved) {
    // Felt wrench: scaled, magnitude of the force bounded.
    double scale = settings_.force_scale;
    const double felt = scale * w.f_T_W.norm();
    if (felt > settings_.max_force) scale *= settings_.max_force / felt;
    w.f_T_W *= scale;
    w.m_T_W *= scale;
    w.g *= scale;
  }
  if (channel_) channel_->buffer.Write(st);
  return w;
}

void FeTouchField::CoupledStep(const Eigen::Vector3d& p_WT, int k, haptics::ToolWrench* w) {
  // See the header: one Newton step on r(x_c) = k_c (x_t − x_c) + σF(x_c) while in contact,
  // conservative advancement toward x_t while not.
  const double kc = settings_.coupling_stiffness, sigma = settings_.force_scale;
  const Eigen::Vector3d force = k > 0 ? state_.felt_normal_W : Eigen::Vector3d::Zero();
  const Eigen::Vector3d r = kc * (p_WT - coupled_) + sigma * force;
  Eigen::Vector3d step = r / kc;
  if (k > 0) {
    Eigen::Vector3d n = force;
    if (!(n.norm() > 0.0)) {
      n.setZero();
      for (int s = 0; s < k; ++s) n += normal_[s];
    }
    if (n.norm() > 0.0) {
      n.normalize();
      // Stiffness of the contact set along n: forces for the contact nodes moved rigidly by 1 m
      // along −n on top of the baseline, sticking (the patch stiffness of felt_stiffness.h).
      const Eigen::Vector3d d = -n;
      for (int s = 0; s < k; ++s) {
        for (int i = 0; i < 3; ++i)
          probe_target_[3 * s + i] =
              cache_->baseline()(3 * cache_->OutputIndexOfCandidate(state_.candidate[s]) + i) +
              d(i);
      }
      double stiffness = 0.0;
      if (solver_->Solve(probe_target_.data(), probe_force_.data())) {
        Eigen::Vector3d f_tool = Eigen::Vector3d::Zero();
        for (int s = 0; s < k; ++s)
          f_tool -= Eigen::Vector3d(probe_force_[3 * s], probe_force_[3 * s + 1],
                                    probe_force_[3 * s + 2]);
        stiffness = std::max(0.0, n.dot(f_tool));
      }
      state_.stiffness = stiffness;
      state_.stiffness_normal = n;
      const double sk = sigma * stiffness;
      step -= (sk / (kc + sk)) * n.dot(step) * n;
    }
  } else {
    // Free: move toward x_t, but stop just past where the first node would enter the sphere
    // (so a fast move cannot carry the sphere through a thin wall, and the next tick starts
    // contact at a vanishing depth instead of deep inside).
    double length = step.norm();
    if (length > 0.0) {
      const Eigen::Vector3d d = step / length;
      length = std::min(length, 4.0 * settings_.tool_radius);
      const double entry = FirstEntry(coupled_, d, length);
      length = std::min(length, entry + 1e-3 * settings_.tool_radius);
      // Tool patch: stop where the plane of the patch ahead is reached (h = R, δ = 0), so that
      // contact begins at a vanishing depth even between nodes.
      PatchFit ahead;
      if (settings_.patch_contact && FitPatch(coupled_ + d * length, nullptr, &ahead) &&
          ahead.depth > 0.0) {
        const double dn = d.dot(ahead.normal);
        const double h0 = (coupled_ - ahead.centroid).dot(ahead.normal);
        if (dn < 0.0)
          length = std::min(length, std::max(0.0, (h0 - settings_.tool_radius) / -dn) +
                                        1e-3 * settings_.tool_radius);
      }
      step = d * length;
    }
  }
  coupled_ += step;
  if (!coupled_.allFinite()) coupled_ = p_WT;
  w->f_T_W = kc * (coupled_ - p_WT);
  const double felt = w->f_T_W.norm();
  if (felt > settings_.max_force) w->f_T_W *= settings_.max_force / felt;
}

double FeTouchField::FirstEntry(const Eigen::Vector3d& c, const Eigen::Vector3d& d,
                                double length) const {
  const double r = settings_.tool_radius;
  double first = length;
  ForEachFreeCandidate(c.cwiseMin(c + length * d).array() - r,
                       c.cwiseMax(c + length * d).array() + r, [&](int b) {
                         // |X − c − λ d| = r: λ = q·d − sqrt((q·d)² − |q|² + r²), q = X − c; nodes
                         // already inside (not admitted as contacts) do not stop the sphere.
                         const Eigen::Vector3d q = positions_[b] - c;
                         const double qd = q.dot(d), cc = q.squaredNorm() - r * r;
                         if (cc <= 0.0) return;
                         const double disc = qd * qd - cc;
                         if (disc < 0.0) return;
                         const double lambda = qd - std::sqrt(disc);
                         if (lambda >= 0.0 && lambda < first) first = lambda;
                       });
  return first;
}

int ContactDisplacement(fem::ColumnCache* cache, const FeContactState& state,
                        Eigen::VectorXd* u_out) {
  *u_out = cache->baseline();
  return AddSlotForcesDisplacement(cache, state.num_contacts, state.candidate.data(),
                                   state.substitute.data(), state.force.data(), u_out->data());
}

}  // namespace spidarcad::app
