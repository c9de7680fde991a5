// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
// What the compliance columns need of a factored model (ColumnCache): its constraints, the
// numbering of its free dofs, solves K_ff X = B, and the static solution under its own loads.
// StaticSolver (one sparse Cholesky, seen through StaticSolverView) and SubstructuredSolver (by
// blocks) both provide it, with the same free-dof numbering and the same numbers to rounding.
// Units and signs as static_solver.h.
#pragma once

#include <Eigen/Core>
#include <vector>

#include "spidarcad/fem/boundary.h"
#include "spidarcad/fem/static_solver.h"

namespace spidarcad::fem {

// A factored linear-elastic model.
class FreeDofSolver {
 public:
  virtual ~FreeDofSolver() = default;
  // Status of the factorisation.
  virtual const SolveStatus& factor_status() const = 0;
  // The model's constraints and loads.
  virtual const BoundaryConditions& bcs() const = 0;
  // Index of global dof d (3v + axis) among the free dofs (increasing global dof), or −1.
  virtual int FreeIndex(int dof) const = 0;
  // Number of free dofs.
  virtual int num_free() const = 0;
  // Solves K_ff X = B (#free by m); X is resized.
  virtual SolveStatus SolveFree(const Eigen::MatrixXd& rhs, Eigen::MatrixXd* x) const = 0;
  // Displacement and reactions under the model's own loads and prescribed displacements.
  virtual StaticSolution Solve() const = 0;

  // Row groups: a model whose solves can give the displacements of some nodes before the rest
  // (SubstructuredSolver: its blocks; ColumnCacheSettings::near_rows_first). Number of groups
  // (0: none, the defaults below are then never needed).
  virtual int num_row_groups() const { return 0; }
  // Group of node v, or −1 when SolveFreeInGroups always gives its rows.
  virtual int RowGroupOfNode(int /*v*/) const { return -1; }
  // X (#free by m) at the free dofs of the nodes of `groups` and of group −1; other rows zero.
  // No residual is checked (converged when the factorisation was).
  virtual SolveStatus SolveFreeInGroups(const Eigen::MatrixXd& rhs,
                                        const std::vector<int>& /*groups*/,
                                        Eigen::MatrixXd* x) const {
    return SolveFree(rhs, x);
  }
  // Completes X from SolveFreeInGroups(rhs, groups, x): the other rows, then the residual check
  // of SolveFree; X then equals SolveFree's bit for bit.
  virtual SolveStatus CompleteSolveFree(const Eigen::MatrixXd& rhs,
                                        const std::vector<int>& /*groups*/,
                                        Eigen::MatrixXd* x) const {
    return SolveFree(rhs, x);
  }
};

// A StaticSolver seen as a FreeDofSolver (it must outlive the view).
class StaticSolverView final : public FreeDofSolver {
 public:
  explicit StaticSolverView(const StaticSolver& solver) : solver_(solver) {}
  const SolveStatus& factor_status() const override { return solver_.factor_status(); }
  const BoundaryConditions& bcs() const override { return solver_.bcs(); }
  int FreeIndex(int dof) const override { return solver_.FreeIndex(dof); }
  int num_free() const override { return solver_.num_free(); }
  SolveStatus SolveFree(const Eigen::MatrixXd& rhs, Eigen::MatrixXd* x) const override {
    return solver_.SolveFree(rhs, x);
  }
  StaticSolution Solve() const override { return solver_.Solve(); }

 private:
  const StaticSolver& solver_;
};

}  // namespace spidarcad::fem
