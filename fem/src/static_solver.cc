// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#include "spidarcad/fem/static_solver.h"

#include <Eigen/Eigenvalues>
#include <Eigen/Geometry>
#include <Eigen/QR>
#include <Eigen/SVD>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <map>
#include <sstream>
#include <stdexcept>
#include <vector>

#include "solve_checks.h"

namespace spidarcad::fem {

namespace {

std::string FormatPoint(const Eigen::Vector3d& p) {
  // Rounding noise (e.g. 1e-18 for a coordinate that is 0) is shown as 0.
  const double scale = p.cwiseAbs().maxCoeff();
  Eigen::Vector3d q = p;
  for (int i = 0; i < 3; ++i)
    if (std::abs(q(i)) <= 1e-9 * scale) q(i) = 0.0;
  std::ostringstream s;
  s.precision(4);
  s << "(" << q.x() << ", " << q.y() << ", " << q.z() << ")";
  return s.str();
}

const char* const kAxisNames[3] = {"x", "y", "z"};

// Name of a direction: "x", "y", "z" when it is one of the axes, else its components.
std::string DirectionName(const Eigen::Vector3d& d) {
  const Eigen::Vector3d n = d.normalized();
  for (int i = 0; i < 3; ++i)
    if (std::abs(n(i)) > 1.0 - 1e-6) return kAxisNames[i];
  return FormatPoint(n);
}

// Rigid-mode null space of one part (its nodes and the prescribed dofs on them): columns
// (t, ω') with u(x) = t + ω' × (x − c) / size. Empty when the part is held.
struct PartModes {
  Eigen::RowVector3d centre;
  double size = 1.0;
  Eigen::MatrixXd null;  // 6 by k, orthonormal
};

PartModes RigidNullSpace(const Eigen::MatrixX3d& nodes, const std::vector<int>& part,
                         const BoundaryConditions& bcs) {
  PartModes modes;
  Eigen::RowVector3d lo = nodes.row(part[0]), hi = lo;
  Eigen::RowVector3d sum = Eigen::RowVector3d::Zero();
  for (int v : part) {
    lo = lo.cwiseMin(nodes.row(v));
    hi = hi.cwiseMax(nodes.row(v));
    sum += nodes.row(v);
  }
  modes.centre = sum / static_cast<double>(part.size());
  modes.size = std::max((hi - lo).norm(), 1e-300);
  Eigen::Matrix<double, 6, 6> gram = Eigen::Matrix<double, 6, 6>::Zero();
  for (int v : part) {
    const Eigen::Vector3d p = (nodes.row(v) - modes.centre).transpose() / modes.size;
    for (int axis = 0; axis < 3; ++axis) {
      if (!bcs.prescribed().count(3 * v + axis)) continue;
      Eigen::Matrix<double, 6, 1> row = Eigen::Matrix<double, 6, 1>::Zero();
      row(axis) = 1.0;
      // Component `axis` of ω × p for unit ω along x, y, z.
      for (int k = 0; k < 3; ++k) row(3 + k) = Eigen::Vector3d::Unit(k).cross(p)(axis);
      gram += row * row.transpose();
    }
  }
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix<double, 6, 6>> eig(gram);
  const double max_ev = std::max(eig.eigenvalues().maxCoeff(), 0.0);
  int k = 0;
  while (k < 6 && eig.eigenvalues()(k) <= 1e-10 * max_ev) ++k;
  modes.null = eig.eigenvectors().leftCols(k);
  return modes;
}

// The free modes in words: translations along the axes, rotations about axis-parallel lines
// (with a point on the line), and what remains as general screw motions.
std::string DescribeModes(const PartModes& modes) {
  const Eigen::MatrixXd& n = modes.null;
  const Eigen::Matrix<double, 6, 6> outside =
      Eigen::Matrix<double, 6, 6>::Identity() - n * n.transpose();
  std::vector<std::string> names;
  Eigen::MatrixXd named(6, 0);
  auto add = [&](const Eigen::Matrix<double, 6, 1>& m, const std::string& name) {
    Eigen::MatrixXd grown(6, named.cols() + 1);
    grown << named, m.normalized();
    // Keep only modes independent of those already named.
    Eigen::JacobiSVD<Eigen::MatrixXd> svd(grown);
    if (svd.singularValues().minCoeff() < 1e-6) return;
    named = grown;
    names.push_back(name);
  };
  for (int i = 0; i < 3; ++i) {
    Eigen::Matrix<double, 6, 1> m = Eigen::Matrix<double, 6, 1>::Zero();
    m(i) = 1.0;
    if ((outside * m).norm() < 1e-6) add(m, std::string("free translation along ") + kAxisNames[i]);
  }
  for (int i = 0; i < 3; ++i) {
    // Rotation about the line along axis i through p: t = a × (c − p), ω' = a (scaled).
    // Least squares for t (3 unknowns) so that (t, a) lies in the null space.
    const Eigen::Vector3d a = Eigen::Vector3d::Unit(i);
    const Eigen::Matrix<double, 6, 3> lhs = outside.leftCols<3>();
    const Eigen::Matrix<double, 6, 1> rhs = -outside.col(3 + i);
    const Eigen::Vector3d t = lhs.colPivHouseholderQr().solve(rhs);
    Eigen::Matrix<double, 6, 1> m;
    m << t, a;
    if ((outside * m).norm() >= 1e-6 * m.norm()) continue;
    // Point on the axis nearest the centre: p = c + a × t (t scaled back to metres).
    const Eigen::Vector3d p = modes.centre.transpose() + a.cross(t) * modes.size;
    add(m, std::string("free rotation about ") + kAxisNames[i] + " through " + FormatPoint(p));
  }
  for (int j = 0; j < n.cols() && static_cast<int>(names.size()) < n.cols(); ++j) {
    const Eigen::Matrix<double, 6, 1> m = n.col(j);
    const Eigen::Vector3d t = m.head<3>(), w = m.tail<3>();
    if (w.norm() < 1e-6 * t.norm()) {
      add(m, "free translation along " + DirectionName(t));
    } else {
      const Eigen::Vector3d p =
          modes.centre.transpose() + w.cross(t) / w.squaredNorm() * modes.size;
      add(m, "free rotation about " + DirectionName(w) + " through " + FormatPoint(p));
    }
  }
  std::string text;
  for (const std::string& name : names) text += (text.empty() ? "" : ", ") + name;
  return text;
}

// Nodes of each part (elements connected through shared nodes), and the nodes in no element.
std::vector<std::vector<int>> ConnectedParts(const TetMesh& mesh, std::vector<int>* orphans) {
  std::vector<int> parent(mesh.num_nodes());
  for (int v = 0; v < mesh.num_nodes(); ++v) parent[v] = v;
  auto find = [&](int v) {
    while (parent[v] != v) v = parent[v] = parent[parent[v]];
    return v;
  };
  std::vector<char> used(mesh.num_nodes(), 0);
  for (int e = 0; e < mesh.num_elements(); ++e) {
    const int a = find(mesh.elements(e, 0));
    for (int j = 0; j < mesh.elements.cols(); ++j) {
      used[mesh.elements(e, j)] = 1;
      parent[find(mesh.elements(e, j))] = a;
    }
  }
  std::map<int, std::vector<int>> by_root;
  for (int v = 0; v < mesh.num_nodes(); ++v) {
    if (used[v]) {
      by_root[find(v)].push_back(v);
    } else if (orphans) {
      orphans->push_back(v);
    }
  }
  std::vector<std::vector<int>> parts;
  for (auto& [root, nodes] : by_root) parts.push_back(std::move(nodes));
  std::sort(parts.begin(), parts.end(),
            [](const auto& a, const auto& b) { return a.front() < b.front(); });
  return parts;
}

}  // namespace

void CheckRigidModesConstrained(const Eigen::MatrixX3d& nodes, const BoundaryConditions& bcs) {
  if (bcs.prescribed().empty()) {
    throw std::invalid_argument(
        "no constraint: the stiffness is singular (all six rigid-body modes are free); fix or "
        "prescribe the displacement of some nodes");
  }
  std::vector<int> all(nodes.rows());
  for (int v = 0; v < nodes.rows(); ++v) all[v] = v;
  const PartModes modes = RigidNullSpace(nodes, all, bcs);
  if (modes.null.cols() > 0) {
    throw std::invalid_argument(
        "constraints leave a rigid-body mode free (" + std::to_string(modes.null.cols()) +
        " of 6: " + DescribeModes(modes) +
        "): the stiffness is singular; fix more nodes (at least three non-collinear)");
  }
}

void CheckModelConstrained(const TetMesh& mesh, const BoundaryConditions& bcs) {
  if (bcs.prescribed().empty()) {
    throw std::invalid_argument(
        "no constraint: the stiffness is singular (all six rigid-body modes are free); fix or "
        "prescribe the displacement of some nodes");
  }
  if (static_cast<int>(bcs.prescribed().size()) == 3 * mesh.num_nodes()) {
    throw std::invalid_argument(
        "every displacement is prescribed (all " + std::to_string(mesh.num_nodes()) +
        " nodes fixed or pushed): nothing is left to solve; clamp only part of the model");
  }
  std::vector<int> orphans;
  const std::vector<std::vector<int>> parts = ConnectedParts(mesh, &orphans);
  for (int v : orphans) {
    for (int axis = 0; axis < 3; ++axis) {
      if (bcs.prescribed().count(3 * v + axis)) continue;
      throw std::invalid_argument(
          "node " + std::to_string(v) + " at " + FormatPoint(mesh.nodes.row(v).transpose()) +
          " belongs to no element: its displacement is undetermined (free translation along " +
          kAxisNames[axis] + "); remove unused points from the mesh");
    }
  }
  for (size_t i = 0; i < parts.size(); ++i) {
    const PartModes modes = RigidNullSpace(mesh.nodes, parts[i], bcs);
    if (modes.null.cols() == 0) continue;
    std::string where = "the model";
    if (parts.size() > 1) {
      where = "part " + std::to_string(i + 1) + " of " + std::to_string(parts.size()) + " (" +
              std::to_string(parts[i].size()) + " nodes around " +
              FormatPoint(modes.centre.transpose()) + ")";
    }
    throw std::invalid_argument(
        "constraints leave a rigid-body mode free in " + where + " (" +
        std::to_string(modes.null.cols()) + " of 6: " + DescribeModes(modes) +
        "): the stiffness is singular; fix more nodes of it (at least three non-collinear)");
  }
}

StaticSolver::StaticSolver(const TetMesh& mesh, const MaterialTable& materials,
                           const BoundaryConditions& bcs, const Factorizer& factorize)
    : bcs_(bcs) {
  using Clock = std::chrono::steady_clock;
  mesh.Validate();
  if (bcs.num_nodes() != mesh.num_nodes()) {
    throw std::invalid_argument("StaticSolver: boundary conditions are for " +
                                std::to_string(bcs.num_nodes()) + " nodes, mesh has " +
                                std::to_string(mesh.num_nodes()));
  }
  for (int e = 0; e < mesh.num_elements(); ++e) materials.Get(mesh.regions(e));
  CheckModelConstrained(mesh, bcs);

  const auto t0 = Clock::now();
  k_ = AssembleStiffness(mesh, materials);
  const int ndof = 3 * mesh.num_nodes();
  free_index_.assign(ndof, -1);
  std::vector<int> prescribed_index(ndof, -1);
  for (int d = 0; d < ndof; ++d) {
    if (bcs.prescribed().count(d)) {
      prescribed_index[d] = static_cast<int>(prescribed_dofs_.size());
      prescribed_dofs_.push_back(d);
    } else {
      free_index_[d] = static_cast<int>(free_dofs_.size());
      free_dofs_.push_back(d);
    }
  }
  std::vector<Eigen::Triplet<double, int>> tff, tfc;
  tff.reserve(k_.nonZeros());
  for (int c = 0; c < k_.outerSize(); ++c) {
    for (SparseMatrixd::InnerIterator it(k_, c); it; ++it) {
      const int fr = free_index_[it.row()];
      if (fr < 0) continue;
      if (free_index_[c] >= 0) {
        tff.emplace_back(fr, free_index_[c], it.value());
      } else {
        tfc.emplace_back(fr, prescribed_index[c], it.value());
      }
    }
  }
  k_ff_.resize(num_free(), num_free());
  k_ff_.setFromTriplets(tff.begin(), tff.end());
  k_fc_.resize(num_free(), static_cast<int>(prescribed_dofs_.size()));
  k_fc_.setFromTriplets(tfc.begin(), tfc.end());
  const auto t1 = Clock::now();

  k_norm_ = k_ff_.norm();
  if (factorize) {
    factor_ = factorize(k_ff_);
    if (factor_ == nullptr || factor_->size() != num_free())
      throw std::runtime_error("StaticSolver: the factorizer gave no factor of K_ff's size");
  } else {
    factor_ = std::make_unique<CholeskyFactor>();
    factor_->Compute(k_ff_);
  }
  const auto t2 = Clock::now();
  stats_.num_free = num_free();
  stats_.stiffness_nonzeros = k_ff_.nonZeros();
  stats_.factor_nonzeros = factor_->nonzeros();
  stats_.factor_peak_bytes = factor_->peak_bytes();
  stats_.assembly_seconds = std::chrono::duration<double>(t1 - t0).count();
  stats_.factor_seconds = std::chrono::duration<double>(t2 - t1).count();
  if (!factor_->ok()) {
    factor_status_.converged = false;
    std::ostringstream m;
    m << "Cholesky factorisation of the constrained stiffness failed: it is not positive "
         "definite (a mechanism: parts joined only at an edge or a node, or a material that "
         "makes it singular)";
    const int column = factor_->failed_column();
    if (column >= 0 && column < num_free()) {
      const int dof = free_dofs_[column];
      m << "; the first zero pivot is the " << kAxisNames[dof % 3] << " displacement of node "
        << dof / 3 << " at " << FormatPoint(mesh.nodes.row(dof / 3).transpose());
    }
    factor_status_.message = m.str();
  } else {
    factor_status_.converged = true;
  }
}

StaticSolver::~StaticSolver() = default;

namespace {

// b − K x, each entry accumulated in long double (64-bit mantissa on x86) and rounded once.
Eigen::MatrixXd ExtendedResidual(const SparseMatrixd& k, const Eigen::MatrixXd& b,
                                 const Eigen::MatrixXd& x) {
  Eigen::MatrixXd r(b.rows(), b.cols());
  std::vector<long double> acc(static_cast<size_t>(b.rows()));
  for (Eigen::Index j = 0; j < b.cols(); ++j) {
    for (Eigen::Index i = 0; i < b.rows(); ++i) acc[i] = b(i, j);
    for (int c = 0; c < k.outerSize(); ++c) {
      const long double xc = x(c, j);
      for (SparseMatrixd::InnerIterator it(k, c); it; ++it)
        acc[it.row()] -= static_cast<long double>(it.value()) * xc;
    }
    for (Eigen::Index i = 0; i < b.rows(); ++i) r(i, j) = static_cast<double>(acc[i]);
  }
  return r;
}

}  // namespace

SolveStatus StaticSolver::SolveFree(const Eigen::MatrixXd& rhs, Eigen::MatrixXd* x) const {
  SolveStatus status;
  if (!detail::CanSolve(factor_status_, rhs.rows(), num_free(), &status)) return status;
  *x = factor_->Solve(rhs);
  const Eigen::MatrixXd r = ExtendedResidual(k_ff_, rhs, *x);
  // Normwise backward error ||b − K x|| / (||K|| ||x|| + ||b||): meaningful also when
  // regions differ in stiffness by many orders of magnitude.
  const double denom = k_norm_ * x->norm() + rhs.norm();
  status.residual = denom > 0.0 ? r.norm() / denom : 0.0;
  status.converged = std::isfinite(status.residual) && status.residual < kResidualTolerance;
  if (!status.converged) {
    std::ostringstream s;
    s << "backward error " << status.residual << " above " << kResidualTolerance;
    status.message = s.str();
  }
  return status;
}

StaticSolution StaticSolver::Solve() const {
  StaticSolution sol;
  const int ndof = static_cast<int>(k_.rows());
  Eigen::VectorXd u_c(prescribed_dofs_.size());
  for (size_t i = 0; i < prescribed_dofs_.size(); ++i)
    u_c(i) = bcs_.prescribed().at(prescribed_dofs_[i]);
  Eigen::VectorXd rhs(num_free());
  for (int i = 0; i < num_free(); ++i) rhs(i) = bcs_.loads()(free_dofs_[i]);
  rhs -= k_fc_ * u_c;
  sol.displacement = Eigen::VectorXd::Zero(ndof);
  if (rhs.norm() == 0.0) {
    sol.status.converged = factor_status_.converged;
    sol.status.message = factor_status_.message;
  } else {
    Eigen::MatrixXd x;
    sol.status = SolveFree(rhs, &x);
    if (x.size() == num_free())
      for (int i = 0; i < num_free(); ++i) sol.displacement(free_dofs_[i]) = x(i, 0);
  }
  for (size_t i = 0; i < prescribed_dofs_.size(); ++i)
    sol.displacement(prescribed_dofs_[i]) = u_c(i);
  sol.reaction = k_ * sol.displacement - bcs_.loads();
  for (int d = 0; d < num_free(); ++d) sol.reaction(free_dofs_[d]) = 0.0;
  return sol;
}

}  // namespace spidarcad::fem
