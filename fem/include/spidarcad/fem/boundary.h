// Boundary conditions: prescribed (fixed) displacements and nodal, point and surface loads.
//
// Sign convention: loads are forces applied ON the body, in N, expressed in the mesh frame.
// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#pragma once

#include <Eigen/Core>
#include <map>
#include <vector>

#include "spidarcad/fem/mesh.h"

namespace spidarcad::fem {

// Prescribed displacements and external nodal forces of a model with #V nodes.
class BoundaryConditions {
 public:
  // Conditions for a mesh of num_nodes nodes: nothing fixed, no load.
  explicit BoundaryConditions(int num_nodes);

  // Clamps node v (all three displacements zero). Throws std::invalid_argument on a bad index.
  void FixNode(int v);
  // Clamps every node of a list.
  void FixNodes(const std::vector<int>& nodes);
  // Prescribes the displacement of node v (m, all three components).
  void PrescribeNode(int v, const Eigen::Vector3d& displacement);
  // Prescribes one component (axis 0, 1, 2 = x, y, z) of node v's displacement, in m.
  void PrescribeDof(int v, int axis, double displacement);
  // Adds a force (N) applied on the body at node v.
  void AddPointLoad(int v, const Eigen::Vector3d& force);

  // Number of nodes of the model.
  int num_nodes() const { return num_nodes_; }
  // Prescribed dofs (3v + axis) and their displacement (m), sorted by dof.
  const std::map<int, double>& prescribed() const { return prescribed_; }
  // External nodal forces, 3·#V, in N.
  const Eigen::VectorXd& loads() const { return loads_; }

 private:
  void CheckNode(int v, const char* what) const;
  int num_nodes_;
  std::map<int, double> prescribed_;
  Eigen::VectorXd loads_;
};

// Nodes whose position lies in the closed box [lower, upper], sorted.
std::vector<int> NodesInBox(const TetMesh& mesh, const Eigen::Vector3d& lower,
                            const Eigen::Vector3d& upper);

// Clamps every node in the box; returns how many were fixed.
int FixNodesInBox(const TetMesh& mesh, const Eigen::Vector3d& lower, const Eigen::Vector3d& upper,
                  BoundaryConditions* bcs);

// Adds a uniform traction t (Pa, force per area, on the body) over every boundary face whose
// corners all lie in the box, as consistent nodal loads (linear faces: A/3 per corner;
// quadratic flat faces: A/3 per midside node, none at corners). Returns the loaded area in m^2.
double AddTractionInBox(const TetMesh& mesh, const Surface& surface, const Eigen::Vector3d& lower,
                        const Eigen::Vector3d& upper, const Eigen::Vector3d& traction,
                        BoundaryConditions* bcs);

}  // namespace spidarcad::fem
