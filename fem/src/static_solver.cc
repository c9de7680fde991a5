// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#include "spidarcad/fem/static_solver.h"

#include <chrono>
#include <cmath>
#include <sstream>
#include <stdexcept>

#include <Eigen/CholmodSupport>
#include <Eigen/Eigenvalues>
#include <Eigen/Geometry>

namespace spidarcad::fem {

struct StaticSolver::Factor {
  Eigen::CholmodSupernodalLLT<SparseMatrixd, Eigen::Lower> llt;
};

void CheckRigidModesConstrained(const Eigen::MatrixX3d& nodes, const BoundaryConditions& bcs) {
  if (bcs.prescribed().empty()) {
    throw std::invalid_argument(
        "no constraint: the stiffness is singular (all six rigid-body modes are free); fix or "
        "prescribe the displacement of some nodes");
  }
  const Eigen::RowVector3d centre = nodes.colwise().mean();
  const double size =
      std::max((nodes.colwise().maxCoeff() - nodes.colwise().minCoeff()).norm(), 1e-300);
  Eigen::Matrix<double, 6, 6> gram = Eigen::Matrix<double, 6, 6>::Zero();
  for (const auto& [dof, value] : bcs.prescribed()) {
    const int v = dof / 3, axis = dof % 3;
    const Eigen::Vector3d p = (nodes.row(v) - centre).transpose() / size;
    Eigen::Matrix<double, 6, 1> row = Eigen::Matrix<double, 6, 1>::Zero();
    row(axis) = 1.0;
    // Component `axis` of ω × p for unit ω along x, y, z.
    for (int k = 0; k < 3; ++k) row(3 + k) = Eigen::Vector3d::Unit(k).cross(p)(axis);
    gram += row * row.transpose();
  }
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix<double, 6, 6>> eig(gram);
  const double max_ev = eig.eigenvalues().maxCoeff();
  if (eig.eigenvalues()(0) <= 1e-10 * max_ev) {
    const Eigen::Matrix<double, 6, 1> m = eig.eigenvectors().col(0);
    std::ostringstream s;
    s.precision(3);
    s << "constraints leave a rigid-body mode free (translation (" << m(0) << ", " << m(1) << ", "
      << m(2) << "), rotation (" << m(3) << ", " << m(4) << ", " << m(5)
      << ")): the stiffness is singular; fix more nodes (at least three non-collinear)";
    throw std::invalid_argument(s.str());
  }
}

StaticSolver::StaticSolver(const TetMesh& mesh, const MaterialTable& materials,
                           const BoundaryConditions& bcs)
    : bcs_(bcs), factor_(std::make_unique<Factor>()) {
  using Clock = std::chrono::steady_clock;
  mesh.Validate();
  if (bcs.num_nodes() != mesh.num_nodes()) {
    throw std::invalid_argument("StaticSolver: boundary conditions are for " +
                                std::to_string(bcs.num_nodes()) + " nodes, mesh has " +
                                std::to_string(mesh.num_nodes()));
  }
  for (int e = 0; e < mesh.num_elements(); ++e) materials.Get(mesh.regions(e));
  CheckRigidModesConstrained(mesh.nodes, bcs);

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
  factor_->llt.compute(k_ff_);
  const auto t2 = Clock::now();
  stats_.num_free = num_free();
  stats_.stiffness_nonzeros = k_ff_.nonZeros();
  stats_.factor_nonzeros = factor_->llt.cholmod().lnz;
  stats_.factor_peak_bytes = static_cast<double>(factor_->llt.cholmod().memory_usage);
  stats_.assembly_seconds = std::chrono::duration<double>(t1 - t0).count();
  stats_.factor_seconds = std::chrono::duration<double>(t2 - t1).count();
  if (factor_->llt.info() != Eigen::Success) {
    factor_status_.converged = false;
    factor_status_.message =
        "Cholesky factorisation of the constrained stiffness failed: it is not positive "
        "definite (a part may be unconstrained or disconnected, or a rigid mode is free)";
  } else {
    factor_status_.converged = true;
  }
}

StaticSolver::~StaticSolver() = default;

SolveStatus StaticSolver::SolveFree(const Eigen::MatrixXd& rhs, Eigen::MatrixXd* x) const {
  SolveStatus status;
  if (!factor_status_.converged) {
    status.message = factor_status_.message;
    return status;
  }
  if (rhs.rows() != num_free()) {
    status.message = "SolveFree: right-hand side has " + std::to_string(rhs.rows()) +
                     " rows, expected " + std::to_string(num_free());
    return status;
  }
  *x = factor_->llt.solve(rhs);
  const Eigen::MatrixXd r = rhs - k_ff_ * (*x);
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
  for (size_t i = 0; i < prescribed_dofs_.size(); ++i) u_c(i) = bcs_.prescribed().at(prescribed_dofs_[i]);
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
  for (size_t i = 0; i < prescribed_dofs_.size(); ++i) sol.displacement(prescribed_dofs_[i]) = u_c(i);
  sol.reaction = k_ * sol.displacement - bcs_.loads();
  for (int d = 0; d < num_free(); ++d) sol.reaction(free_dofs_[d]) = 0.0;
  return sol;
}

}  // namespace spidarcad::fem
