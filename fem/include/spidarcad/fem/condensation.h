// Precomputed condensation onto surface nodes (compliance / Green's function columns) and the
// real-time contact solve on it.
//
// Compliance G: G(3a + i, 3b + j) is the displacement (m) of output node a along axis i due to
// a unit force (1 N, applied ON the body) at condensed node b along axis j, with the model's
// constraints in place. By linearity the displacement of the output nodes under forces f_c at
// the condensed nodes is u = u0 + G f_c, where u0 is the static response to the model's own
// loads and prescribed displacements.
//
// Contact: the tool prescribes the total displacement d_s of k contact nodes. The forces on the
// body are f = G_cc⁻¹ (d − u0_c) (G_cc: the 3k by 3k block of G at the contact nodes); the
// force the body applies on the tool is −f.
// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#pragma once

#include <Eigen/Core>
#include <atomic>
#include <functional>
#include <vector>

#include "spidarcad/fem/bordered_cholesky.h"
#include "spidarcad/fem/static_solver.h"

namespace spidarcad::fem {

// Settings of Compliance::Compute.
struct CondensationSettings {
  // Condensed nodes per multi-right-hand-side solve (3 columns each).
  int block_nodes = 32;
  // Called after each block with the fraction done in [0, 1]; may be empty.
  std::function<void(double)> progress;
  // When not null and set, computation stops after the current block (status not converged).
  const std::atomic<bool>* cancel = nullptr;
};

// Dense compliance columns for a set of condensed nodes, observed at a set of output nodes.
class Compliance {
 public:
  // Computes the columns with the solver's factorisation. output_nodes: nodes whose
  // displacement is stored (e.g. the surface nodes); condensed_nodes: nodes where the tool can
  // push (each must also be an output node). A condensed node with a prescribed dof is kept
  // but marked fixed (no contact can be made there). Throws std::invalid_argument on bad
  // node lists; solver failures land in status().
  Compliance(const StaticSolver& solver, const std::vector<int>& output_nodes,
             const std::vector<int>& condensed_nodes, const CondensationSettings& settings = {});

  // Outcome of the precomputation (worst block residual).
  const SolveStatus& status() const { return status_; }
  // G, 3·#output by 3·#condensed, in m/N.
  const Eigen::MatrixXd& matrix() const { return g_; }
  // Displacement of the output nodes under the model's own loads, 3·#output, in m.
  const Eigen::VectorXd& baseline() const { return u0_; }
  // Output node list as given (row blocks of G).
  const std::vector<int>& output_nodes() const { return output_nodes_; }
  // Condensed node list as given (column blocks of G).
  const std::vector<int>& condensed_nodes() const { return condensed_nodes_; }
  // Position of condensed node b in the output list.
  int OutputIndexOfCondensed(int b) const { return condensed_row_[b]; }
  // Index of mesh node v in the condensed list, or −1.
  int CondensedIndexOfNode(int v) const;
  // True if condensed node b has a prescribed dof (its column is not usable for contact).
  bool IsFixed(int b) const { return fixed_[b] != 0; }
  // 3 by 3 block G_ab between condensed nodes a (row) and b (column).
  Eigen::Matrix3d Block(int a, int b) const { return g_.block<3, 3>(3 * condensed_row_[a], 3 * b); }
  // Bytes held by G and the baseline.
  double MemoryBytes() const { return 8.0 * (g_.size() + u0_.size()); }
  // Wall time of the column solves, in s.
  double compute_seconds() const { return compute_seconds_; }

 private:
  std::vector<int> output_nodes_, condensed_nodes_, condensed_row_;
  std::vector<char> fixed_;
  std::vector<int> node_to_condensed_;
  Eigen::MatrixXd g_;
  Eigen::VectorXd u0_;
  SolveStatus status_;
  double compute_seconds_ = 0.0;
};

// What a contact update did.
enum class ContactStatus {
  kOk,
  kFull,                 // max_contacts already in contact
  kAlreadyInContact,     // Add of a node in contact
  kNotInContact,         // Remove of a node not in contact
  kFixedNode,            // the node is constrained: no contact there
  kNotPositiveDefinite,  // the bordered block was not positive definite (node refused)
  kBadIndex,             // not a condensed node index
};

// Real-time contact solve on a Compliance. All buffers are sized at construction for
// max_contacts; Add, Remove, Solve and the accessors never allocate, lock or throw.
//
// The Cholesky factor L of G_cc (lower, 3k by 3k, contacts in slot order; a BorderedCholesky)
// is updated incrementally: Add borders it with one 3-row block (O(k²)); Remove deletes a block
// and restores the trailing part with three rank-one updates (O(k²)).
class ContactSolver {
 public:
  // Solver for up to max_contacts simultaneous contact nodes (>= 1). The compliance must
  // outlive the solver.
  ContactSolver(const Compliance& compliance, int max_contacts);

  // Puts condensed node b in contact (appended as the last slot).
  ContactStatus Add(int b);
  // Takes condensed node b out of contact; later slots move down by one.
  ContactStatus Remove(int b);
  // Takes every node out of contact.
  void Clear();

  // Number of nodes in contact, k.
  int num_contacts() const { return k_; }
  // Condensed node index in slot s (0 <= s < k).
  int contact(int s) const { return slots_[s]; }
  // Slot of condensed node b, or −1 if it is not in contact.
  int SlotOf(int b) const { return slot_of_[b]; }

  // Forces on the body f (3k, N, slot order) such that each contact node's total displacement
  // equals target (3k, m, slot order). Returns false (forces untouched) when k = 0.
  bool Solve(const double* target, double* forces);
  // Displacement of all output nodes (3·#output, m) for contact forces f (3k, slot order):
  // u = u0 + Σ_s G(:, slot s) f_s. u_out must already have size 3·#output.
  void OutputDisplacement(const double* forces, Eigen::VectorXd* u_out) const;

  // Row-major dense matrix of the factor (rows are contiguous for both triangular sweeps).
  using FactorMatrix = BorderedCholesky::FactorMatrix;
  // Current factor: the lower triangle of the top-left 3k by 3k block.
  const FactorMatrix& factor() const { return chol_.factor(); }
  // The dense block G_cc (3k by 3k) of the current contacts, slot order (allocates; not RT).
  Eigen::MatrixXd ContactBlock() const;

 private:
  const Compliance& c_;
  int max_contacts_;
  int k_ = 0;
  BorderedCholesky chol_;  // factor of G_cc, 3·max square
  Eigen::VectorXd work_;
  std::vector<int> slots_;
  std::vector<int> slot_of_;
};

}  // namespace spidarcad::fem
