// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#include "spidarcad/fem/condensation.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <sstream>
#include <stdexcept>

#include "node_lists.h"

namespace spidarcad::fem {

Compliance::Compliance(const StaticSolver& solver, const std::vector<int>& output_nodes,
                       const std::vector<int>& condensed_nodes,
                       const CondensationSettings& settings)
    : output_nodes_(output_nodes), condensed_nodes_(condensed_nodes) {
  const int n = solver.bcs().num_nodes();
  const detail::NodeListIndex index =
      detail::IndexNodeLists("Compliance", "condensed", n, output_nodes, condensed_nodes);
  node_to_condensed_ = index.subset_index;
  condensed_row_ = index.subset_row;
  for (const int v : condensed_nodes) {
    bool fixed = false;
    for (int i = 0; i < 3; ++i) fixed = fixed || solver.FreeIndex(3 * v + i) < 0;
    fixed_.push_back(fixed ? 1 : 0);
  }
  const int num_out = static_cast<int>(output_nodes.size());
  const int num_cond = static_cast<int>(condensed_nodes.size());
  g_ = Eigen::MatrixXd::Zero(3 * num_out, 3 * num_cond);

  const auto t0 = std::chrono::steady_clock::now();
  const StaticSolution base = solver.Solve();
  u0_.resize(3 * num_out);
  for (int a = 0; a < num_out; ++a)
    u0_.segment<3>(3 * a) = base.displacement.segment<3>(3 * output_nodes[a]);
  status_ = base.status;
  if (!solver.factor_status().converged) return;
  status_.converged = true;
  status_.message.clear();

  const int block = std::max(1, settings.block_nodes);
  Eigen::MatrixXd rhs, x;
  for (int start = 0; start < num_cond; start += block) {
    if (settings.cancel && settings.cancel->load()) {
      status_.converged = false;
      status_.message = "cancelled";
      return;
    }
    const int count = std::min(block, num_cond - start);
    rhs.setZero(solver.num_free(), 3 * count);
    for (int c = 0; c < count; ++c)
      for (int j = 0; j < 3; ++j) {
        const int fi = solver.FreeIndex(3 * condensed_nodes[start + c] + j);
        if (fi >= 0) rhs(fi, 3 * c + j) = 1.0;
      }
    const SolveStatus s = solver.SolveFree(rhs, &x);
    status_.residual = std::max(status_.residual, s.residual);
    if (!s.converged) {
      status_.converged = false;
      status_.message = s.message;
      return;
    }
    for (int a = 0; a < num_out; ++a)
      for (int i = 0; i < 3; ++i) {
        const int fi = solver.FreeIndex(3 * output_nodes[a] + i);
        if (fi < 0) continue;
        g_.block(3 * a + i, 3 * start, 1, 3 * count) = x.row(fi);
      }
    if (settings.progress) settings.progress(static_cast<double>(start + count) / num_cond);
  }
  compute_seconds_ = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

int Compliance::CondensedIndexOfNode(int v) const {
  if (v < 0 || v >= static_cast<int>(node_to_condensed_.size())) return -1;
  return node_to_condensed_[v];
}

ContactSolver::ContactSolver(const Compliance& compliance, int max_contacts)
    : c_(compliance), max_contacts_(max_contacts), chol_(std::max(1, max_contacts)) {
  if (max_contacts < 1) {
    throw std::invalid_argument("ContactSolver: max_contacts must be >= 1, got " +
                                std::to_string(max_contacts));
  }
  work_ = Eigen::VectorXd::Zero(3 * max_contacts);
  slots_.assign(max_contacts, -1);
  slot_of_.assign(compliance.condensed_nodes().size(), -1);
}

ContactStatus ContactSolver::Add(int b) {
  if (b < 0 || b >= static_cast<int>(slot_of_.size())) return ContactStatus::kBadIndex;
  if (slot_of_[b] >= 0) return ContactStatus::kAlreadyInContact;
  if (c_.IsFixed(b)) return ContactStatus::kFixedNode;
  if (k_ >= max_contacts_) return ContactStatus::kFull;
  const int n3 = 3 * k_;
  const Eigen::MatrixXd& g = c_.matrix();
  // Border: G(b, contacts) = G(contacts, b)ᵀ, read from the three columns of node b.
  for (int j = 0; j < 3; ++j) {
    double* border = chol_.BorderRow(j);
    const int col = 3 * b + j;
    for (int i = 0; i < n3; ++i)
      border[i] = g(3 * c_.OutputIndexOfCondensed(slots_[i / 3]) + i % 3, col);
  }
  // Diagonal block G_bb, symmetrised.
  const int rb = 3 * c_.OutputIndexOfCondensed(b);
  const Eigen::Matrix3d g_bb = g.block<3, 3>(rb, 3 * b);
  if (!chol_.AppendBlock(0.5 * (g_bb + g_bb.transpose()))) {
    return ContactStatus::kNotPositiveDefinite;
  }
  slots_[k_] = b;
  slot_of_[b] = k_;
  ++k_;
  return ContactStatus::kOk;
}

ContactStatus ContactSolver::Remove(int b) {
  if (b < 0 || b >= static_cast<int>(slot_of_.size())) return ContactStatus::kBadIndex;
  const int s = slot_of_[b];
  if (s < 0) return ContactStatus::kNotInContact;
  chol_.RemoveBlock(s);
  for (int t = s; t + 1 < k_; ++t) {
    slots_[t] = slots_[t + 1];
    slot_of_[slots_[t]] = t;
  }
  slots_[k_ - 1] = -1;
  slot_of_[b] = -1;
  --k_;
  return ContactStatus::kOk;
}

void ContactSolver::Clear() {
  for (int t = 0; t < k_; ++t) {
    slot_of_[slots_[t]] = -1;
    slots_[t] = -1;
  }
  k_ = 0;
  chol_.Truncate(0);
}

bool ContactSolver::Solve(const double* target, double* forces) {
  if (k_ == 0) return false;
  const int n3 = 3 * k_;
  const Eigen::VectorXd& u0 = c_.baseline();
  for (int i = 0; i < n3; ++i) {
    const int row = 3 * c_.OutputIndexOfCondensed(slots_[i / 3]) + i % 3;
    work_(i) = target[i] - u0(row);
  }
  chol_.Solve(work_.data());
  for (int i = 0; i < n3; ++i) forces[i] = work_(i);
  return true;
}

void ContactSolver::OutputDisplacement(const double* forces, Eigen::VectorXd* u_out) const {
  *u_out = c_.baseline();
  const Eigen::MatrixXd& g = c_.matrix();
  for (int s = 0; s < k_; ++s)
    for (int j = 0; j < 3; ++j) u_out->noalias() += forces[3 * s + j] * g.col(3 * slots_[s] + j);
}

Eigen::MatrixXd ContactSolver::ContactBlock() const {
  Eigen::MatrixXd m(3 * k_, 3 * k_);
  for (int a = 0; a < k_; ++a)
    for (int b = 0; b < k_; ++b) m.block<3, 3>(3 * a, 3 * b) = c_.Block(slots_[a], slots_[b]);
  return m;
}

}  // namespace spidarcad::fem
