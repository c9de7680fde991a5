// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#include "spidarcad/fem/grab.h"

#include <Eigen/Geometry>
#include <cmath>
#include <sstream>
#include <stdexcept>
#include <string>

namespace spidarcad::fem {

namespace {

std::string NodeAt(const Eigen::Vector3d& p) {
  std::ostringstream s;
  s.precision(6);
  s << "(" << p.x() << ", " << p.y() << ", " << p.z() << ")";
  return s.str();
}

}  // namespace

Eigen::Matrix3d RotationFromVector(const Eigen::Vector3d& r) {
  const double theta2 = r.squaredNorm();
  // R = I + a [r]× + b [r]×², a = sin θ / θ, b = (1 − cos θ) / θ².
  double a = 0.0, b = 0.0;
  if (theta2 < 1e-8) {
    // |r| < 1e-4: the series to θ⁴ (truncation below 1e-20, relative).
    a = 1.0 - theta2 / 6.0 + theta2 * theta2 / 120.0;
    b = 0.5 - theta2 / 24.0 + theta2 * theta2 / 720.0;
  } else {
    const double theta = std::sqrt(theta2);
    a = std::sin(theta) / theta;
    b = (1.0 - std::cos(theta)) / theta2;
  }
  Eigen::Matrix3d k;
  k << 0.0, -r.z(), r.y(), r.z(), 0.0, -r.x(), -r.y(), r.x(), 0.0;
  return Eigen::Matrix3d::Identity() + a * k + b * (k * k);
}

GrabPatch::GrabPatch(const Eigen::MatrixX3d& positions, const std::vector<int>& nodes)
    : nodes_(nodes) {
  const int num_nodes = static_cast<int>(positions.rows());
  if (nodes.empty()) throw std::invalid_argument("GrabPatch: no node to grab");
  std::vector<char> seen(num_nodes, 0);
  for (const int v : nodes) {
    if (v < 0 || v >= num_nodes) {
      throw std::invalid_argument("GrabPatch: node " + std::to_string(v) + " is out of range [0, " +
                                  std::to_string(num_nodes) + ")");
    }
    if (seen[v]) {
      throw std::invalid_argument("GrabPatch: node " + std::to_string(v) + " is listed twice");
    }
    seen[v] = 1;
    centroid_ += positions.row(v).transpose();
  }
  centroid_ /= static_cast<double>(nodes.size());
  offsets_.resize(3, size());
  for (int i = 0; i < size(); ++i)
    offsets_.col(i) = positions.row(nodes[i]).transpose() - centroid_;
}

void GrabPatch::Displacements(const Eigen::Vector3d& t, const Eigen::Vector3d& r,
                              double* out) const {
  const Eigen::Matrix3d r_minus_i = RotationFromVector(r) - Eigen::Matrix3d::Identity();
  for (int i = 0; i < size(); ++i) {
    Eigen::Map<Eigen::Vector3d>(out + 3 * i) = r_minus_i * offsets_.col(i) + t;
  }
}

GrabWrench GrabPatch::Wrench(const double* forces) const {
  GrabWrench w;
  for (int i = 0; i < size(); ++i) {
    const Eigen::Map<const Eigen::Vector3d> f(forces + 3 * i);
    w.force += f;
    w.moment += offsets_.col(i).cross(f);
  }
  return w;
}

GrabWrench GrabPatch::WrenchOfReaction(const Eigen::VectorXd& reaction) const {
  Eigen::VectorXd f(3 * size());
  for (int i = 0; i < size(); ++i) f.segment<3>(3 * i) = reaction.segment<3>(3 * nodes_[i]);
  return Wrench(f.data());
}

void GrabPatch::Prescribe(const Eigen::Vector3d& t, const Eigen::Vector3d& r,
                          BoundaryConditions* bcs) const {
  for (int i = 0; i < size(); ++i) {
    const int v = nodes_[i];
    if (v >= bcs->num_nodes()) {
      throw std::invalid_argument("GrabPatch::Prescribe: node " + std::to_string(v) +
                                  " is out of range of the boundary conditions (" +
                                  std::to_string(bcs->num_nodes()) + " nodes)");
    }
    for (int axis = 0; axis < 3; ++axis) {
      if (bcs->prescribed().count(3 * v + axis)) {
        throw std::invalid_argument(
            "grabbed node " + std::to_string(v) + " at " + NodeAt(offsets_.col(i) + centroid_) +
            " already has a prescribed displacement (clamped or pushed): a node cannot be both "
            "held and grabbed");
      }
    }
  }
  Eigen::VectorXd u(3 * size());
  Displacements(t, r, u.data());
  if (!u.allFinite()) {
    throw std::invalid_argument("GrabPatch::Prescribe: the grab displacement is not finite");
  }
  for (int i = 0; i < size(); ++i) bcs->PrescribeNode(nodes_[i], u.segment<3>(3 * i));
}

GrabSolution SolveGrab(const TetMesh& mesh, const MaterialTable& materials,
                       const BoundaryConditions& bcs, const GrabPatch& patch,
                       const Eigen::Vector3d& t, const Eigen::Vector3d& r) {
  BoundaryConditions grabbed = bcs;
  patch.Prescribe(t, r, &grabbed);
  const StaticSolver solver(mesh, materials, grabbed);
  GrabSolution out;
  if (!solver.factor_status().converged) {
    out.status = solver.factor_status();
    return out;
  }
  StaticSolution s = solver.Solve();
  out.displacement = std::move(s.displacement);
  out.reaction = std::move(s.reaction);
  out.status = s.status;
  out.wrench = patch.WrenchOfReaction(out.reaction);
  return out;
}

CondensedGrab::CondensedGrab(const Compliance& compliance, const GrabPatch& patch)
    : patch_(patch), contacts_(compliance, patch.size()) {
  for (int i = 0; i < patch.size(); ++i) {
    const int v = patch.nodes()[i];
    const int b = compliance.CondensedIndexOfNode(v);
    const std::string where = "CondensedGrab: grabbed node " + std::to_string(v);
    if (b < 0) throw std::invalid_argument(where + " is not a condensed node of the compliance");
    const ContactStatus status = contacts_.Add(b);
    if (status == ContactStatus::kFixedNode) {
      throw std::invalid_argument(where +
                                  " has a prescribed displacement in the condensed model "
                                  "(clamped or pushed): it cannot be grabbed");
    }
    if (status == ContactStatus::kNotPositiveDefinite) {
      throw std::invalid_argument(where +
                                  ": the compliance block of the grabbed nodes is not positive "
                                  "definite (its columns add nothing to the other nodes')");
    }
    if (status != ContactStatus::kOk) {
      throw std::invalid_argument(where + " could not be added to the grab (listed twice?)");
    }
  }
  target_ = Eigen::VectorXd::Zero(3 * patch.size());
  forces_ = Eigen::VectorXd::Zero(3 * patch.size());
}

GrabWrench CondensedGrab::Solve(const Eigen::Vector3d& t, const Eigen::Vector3d& r) {
  patch_.Displacements(t, r, target_.data());
  contacts_.Solve(target_.data(), forces_.data());
  return patch_.Wrench(forces_.data());
}

void CondensedGrab::OutputDisplacement(Eigen::VectorXd* u_out) const {
  contacts_.OutputDisplacement(forces_.data(), u_out);
}

}  // namespace spidarcad::fem
