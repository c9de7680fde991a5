// Linear static solve K u = f with prescribed displacements, factored once with CHOLMOD
// (supernodal Cholesky on OpenBLAS), reusable for many right-hand sides.
//
// Dofs are split into free (f) and prescribed (c): K_ff u_f = f_f − K_fc u_c.
// Reactions r = K u − f_ext are the forces the supports apply ON the body (N), nonzero only
// at prescribed dofs.
// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#pragma once

#include <Eigen/Core>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "spidarcad/fem/boundary.h"
#include "spidarcad/fem/cholesky_factor.h"
#include "spidarcad/fem/material.h"
#include "spidarcad/fem/mesh.h"
#include "spidarcad/fem/stiffness.h"

namespace spidarcad::fem {

// Outcome of a factorisation or solve.
struct SolveStatus {
  // True when the factorisation succeeded and the relative residual is below tolerance.
  bool converged = false;
  // Normwise backward error ||K_ff x − b|| / (||K_ff|| ||x|| + ||b||) (Frobenius norms);
  // converged requires it below StaticSolver::kResidualTolerance.
  double residual = 0.0;
  // Empty on success, otherwise what went wrong.
  std::string message;
  // Reserved, always 0: iterative refinement (long double residual) was tried on thin plates
  // and did not reduce the forward error (docs/fem.md); to be removed with the next ABI change.
  int refinement_steps = 0;
};

// Result of StaticSolver::Solve.
struct StaticSolution {
  // Displacement, 3·#V, in m (prescribed values at prescribed dofs).
  Eigen::VectorXd displacement;
  // Reaction forces on the body, 3·#V, in N (zero at free dofs).
  Eigen::VectorXd reaction;
  SolveStatus status;
};

// Figures of the factorisation.
struct FactorStats {
  // Number of free dofs (size of K_ff).
  int num_free = 0;
  // Nonzeros of K_ff (both triangles).
  long long stiffness_nonzeros = 0;
  // Nonzeros of the Cholesky factor L (CHOLMOD's count).
  double factor_nonzeros = 0.0;
  // Peak memory of CHOLMOD during factorisation, in bytes.
  double factor_peak_bytes = 0.0;
  // Wall time of assembly, and of symbolic plus numeric factorisation (with a Factorizer: the
  // whole call, e.g. a child process's start-up and the factor's transfer), in s.
  double assembly_seconds = 0.0;
  double factor_seconds = 0.0;
};

// Assembles and factors a model once; then solves for its loads or any free-dof right-hand side.
class StaticSolver {
 public:
  // Factorises K_ff (#free by #free, both triangles stored) somewhere else, e.g. in a child
  // process (app/scene/worker_process.h), and returns its factor; it may throw (the constructor
  // passes the exception on). For the solves to be the in-process ones bit for bit, the factor
  // must be CholeskyFactor::Compute(k_ff)'s (carried over by WriteFlat and ReadFlat).
  using Factorizer = std::function<std::unique_ptr<CholeskyFactor>(const SparseMatrixd& k_ff)>;

  // Validates mesh, materials and constraints, assembles K and factors K_ff. Throws
  // std::invalid_argument when the input is bad, when nothing is constrained ("no constraint:
  // the stiffness is singular"), when nothing is free, or when the constraints leave a
  // rigid-body mode of the model or of one of its parts free (CheckModelConstrained, the mode
  // named). A factorisation failure (a mechanism the rigid-mode check cannot see, such as
  // parts hinged at an edge) is reported through factor_status(), naming the node of the first
  // zero pivot, not thrown. K_ff is factorised by `factorize` when given (std::runtime_error
  // when it returns no factor or one of another size), else on this thread.
  StaticSolver(const TetMesh& mesh, const MaterialTable& materials, const BoundaryConditions& bcs,
               const Factorizer& factorize = {});
  ~StaticSolver();
  StaticSolver(const StaticSolver&) = delete;
  StaticSolver& operator=(const StaticSolver&) = delete;

  // Status of the factorisation of K_ff.
  const SolveStatus& factor_status() const { return factor_status_; }
  // Figures of assembly and factorisation.
  const FactorStats& stats() const { return stats_; }

  // Displacement and reactions under the loads and prescribed displacements of the
  // BoundaryConditions given at construction.
  StaticSolution Solve() const;
  // Backward error above which a solve is reported not converged.
  static constexpr double kResidualTolerance = 1e-12;

  // Solves K_ff X = B for free-dof right-hand sides B (#free by m); X is resized. The
  // residual is accumulated in long double; when it is large against B (an ill-conditioned
  // model) the forward error can still exceed it by cond(K_ff).
  SolveStatus SolveFree(const Eigen::MatrixXd& rhs, Eigen::MatrixXd* x) const;

  // Index of global dof d (3v + axis) among the free dofs, or −1 if it is prescribed.
  int FreeIndex(int dof) const { return free_index_[dof]; }
  // Global dof of free index i.
  int FreeDof(int i) const { return free_dofs_[i]; }
  // Number of free dofs.
  int num_free() const { return static_cast<int>(free_dofs_.size()); }
  // Full stiffness K (3·#V by 3·#V) before constraints.
  const SparseMatrixd& stiffness() const { return k_; }
  // Stiffness of the free dofs K_ff (#free by #free).
  const SparseMatrixd& free_stiffness() const { return k_ff_; }
  // The model's boundary conditions.
  const BoundaryConditions& bcs() const { return bcs_; }

 private:
  BoundaryConditions bcs_;
  SparseMatrixd k_, k_ff_, k_fc_;
  std::vector<int> free_index_, free_dofs_, prescribed_dofs_;
  std::unique_ptr<CholeskyFactor> factor_;
  SolveStatus factor_status_;
  FactorStats stats_;
  double k_norm_ = 0.0;
};

// Throws std::invalid_argument unless the prescribed dofs remove all six rigid-body modes of
// the nodes (checked on the 6 by 6 Gram matrix of the modes restricted to prescribed dofs).
// The message names each free mode: "free translation along y", "free rotation about x
// through (x, y, z)" (a point on the axis, m), or a general direction.
void CheckRigidModesConstrained(const Eigen::MatrixX3d& nodes, const BoundaryConditions& bcs);

// The checks StaticSolver runs before assembly, throwing std::invalid_argument with the
// reason: nothing prescribed; every dof prescribed (nothing to solve); a node in no element
// with a free dof; a part of the mesh (elements connected through shared nodes) whose
// prescribed dofs leave a rigid-body mode free (the part and the mode named as above).
void CheckModelConstrained(const TetMesh& mesh, const BoundaryConditions& bcs);

}  // namespace spidarcad::fem
