// Rigid grab of a node set ("patch"): every grabbed node is displaced rigidly and the wrench
// that holds the patch there is reported.
//
// Motion: u_v = (R − I)(x_v − c) + t for each grabbed node v, with x_v its rest position (m),
// c the centroid (plain mean) of the grabbed nodes' rest positions, t the translation (m) and
// R = exp([r]×) the rotation of rotation vector r (rad; axis r/|r|, angle |r|; Rodrigues).
//
// Wrench: the forces the grip applies ON the body at the grabbed nodes to hold them there,
// f_v = (K u − f_ext)_v (N; the reactions of the grabbed dofs), summed: force F = Σ f_v (N) and
// moment M = Σ (x_v − c) × f_v about c (N·m), with rest positions x_v (linear theory).
//
// Two ways to the same numbers:
//  - SolveGrab: the reference. The grabbed dofs become Dirichlet conditions next to the
//    model's own, one sparse factorisation (StaticSolver), reactions read off K u − f.
//  - CondensedGrab: through a precomputed condensation (Compliance, condensation.h). With G_gg
//    the 3n by 3n compliance block of the n grabbed nodes and u0_g their displacement under
//    the model's own loads, f = G_gg⁻¹ (u_g − u0_g). G_gg is factored once (O(n³)); each
//    Solve is two triangular sweeps (O(n²)) plus O(n) for the targets and the wrench, with no
//    allocation, lock or exception: the kernel of a haptic grab on a fixed patch (the same
//    GrabPatch::Displacements / Wrench around a CachedContactSolver gives it on a ColumnCache).
// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#pragma once

#include <Eigen/Core>
#include <vector>

#include "spidarcad/fem/boundary.h"
#include "spidarcad/fem/condensation.h"
#include "spidarcad/fem/material.h"
#include "spidarcad/fem/mesh.h"
#include "spidarcad/fem/static_solver.h"

namespace spidarcad::fem {

// R = exp([r]×) for a rotation vector r (rad): Rodrigues' formula, with its Taylor series
// below |r| = 1e-4 rad. Real-time safe.
Eigen::Matrix3d RotationFromVector(const Eigen::Vector3d& r);

// Force (N) and moment (N·m, about the patch centroid c) applied ON the body by the grab.
struct GrabWrench {
  Eigen::Vector3d force = Eigen::Vector3d::Zero();
  Eigen::Vector3d moment = Eigen::Vector3d::Zero();
};

// The grabbed nodes and their rest geometry.
class GrabPatch {
 public:
  // Patch of mesh nodes `nodes` (indices into `positions`, #V by 3, m). Throws
  // std::invalid_argument when the list is empty, holds an index out of range or a node twice.
  GrabPatch(const Eigen::MatrixX3d& positions, const std::vector<int>& nodes);

  // Number of grabbed nodes n.
  int size() const { return static_cast<int>(nodes_.size()); }
  // Grabbed mesh nodes, in the order given (the order of every 3n vector below).
  const std::vector<int>& nodes() const { return nodes_; }
  // Centroid c of the grabbed nodes' rest positions, m.
  const Eigen::Vector3d& centroid() const { return centroid_; }
  // Rest offsets x_v − c, 3 by n, m.
  const Eigen::Matrix3Xd& offsets() const { return offsets_; }

  // Displacements u_v = (R − I)(x_v − c) + t of the grabbed nodes, written to out (3n, m,
  // node-major). t in m, r in rad. Real-time safe.
  void Displacements(const Eigen::Vector3d& t, const Eigen::Vector3d& r, double* out) const;
  // Wrench of nodal forces on the body at the grabbed nodes (forces: 3n, N, node-major).
  // Real-time safe.
  GrabWrench Wrench(const double* forces) const;
  // Wrench of the grabbed nodes' entries of a full reaction vector (3·#V, N).
  GrabWrench WrenchOfReaction(const Eigen::VectorXd& reaction) const;
  // Prescribes the grab's displacements on bcs. Throws std::invalid_argument, naming the node
  // and its position, when a grabbed node already has a prescribed dof (clamped or pushed);
  // bcs is then unchanged.
  void Prescribe(const Eigen::Vector3d& t, const Eigen::Vector3d& r, BoundaryConditions* bcs) const;

 private:
  std::vector<int> nodes_;
  Eigen::Vector3d centroid_ = Eigen::Vector3d::Zero();
  Eigen::Matrix3Xd offsets_;
};

// Result of SolveGrab.
struct GrabSolution {
  // Displacement of every node, 3·#V, m.
  Eigen::VectorXd displacement;
  // Reactions K u − f_ext, 3·#V, N (nonzero at clamped, pushed and grabbed dofs).
  Eigen::VectorXd reaction;
  // The grab's wrench (from the reactions of the grabbed dofs).
  GrabWrench wrench;
  SolveStatus status;
};

// Reference grab: the model (mesh, materials, its clamps, pushes and loads in bcs) with the
// patch moved by (t, r) as Dirichlet conditions, one sparse solve. Throws std::invalid_argument
// as GrabPatch::Prescribe and StaticSolver do; a failed factorisation or solve lands in status.
GrabSolution SolveGrab(const TetMesh& mesh, const MaterialTable& materials,
                       const BoundaryConditions& bcs, const GrabPatch& patch,
                       const Eigen::Vector3d& t, const Eigen::Vector3d& r);

// Grab through a precomputed condensation: a fixed patch, its block G_gg factored once, then
// any number of real-time Solve calls (see the file comment).
class CondensedGrab {
 public:
  // Grab of `patch` on `compliance` (which must outlive this; computed on the model WITHOUT
  // the grab: its clamps, pushes and loads only). Every grabbed node must be a condensed node
  // of it and have no prescribed dof. Allocates and factors G_gg (3n by 3n). Throws
  // std::invalid_argument naming the node when one is not condensed or is prescribed, or when
  // G_gg is not positive definite (a node whose columns duplicate others').
  CondensedGrab(const Compliance& compliance, const GrabPatch& patch);

  // The patch.
  const GrabPatch& patch() const { return patch_; }
  // Forces f on the body at the grabbed nodes (3n, N, patch order) that hold the patch at
  // (t, r), and their wrench. Real-time safe: no allocation, lock or exception.
  GrabWrench Solve(const Eigen::Vector3d& t, const Eigen::Vector3d& r);
  // Forces of the last Solve (3n, N, patch order; zero before the first).
  const Eigen::VectorXd& forces() const { return forces_; }
  // Displacement of the compliance's output nodes under the last Solve's forces:
  // u = u0 + G(:, grabbed) f (3·#output, m). u_out must already have size 3·#output; no
  // allocation then.
  void OutputDisplacement(Eigen::VectorXd* u_out) const;

 private:
  GrabPatch patch_;
  ContactSolver contacts_;
  Eigen::VectorXd target_, forces_;
};

}  // namespace spidarcad::fem
