// Element stiffness of 4- and 10-node tetrahedra, global sparse assembly and stress recovery.
//
// Degrees of freedom: node v has displacement dofs 3v, 3v + 1, 3v + 2 (x, y, z), in m.
// Strain and stress use the engineering (Voigt) order xx, yy, zz, yz, xz, xy.
// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#pragma once

#include <Eigen/Core>
#include <Eigen/SparseCore>

#include "spidarcad/fem/material.h"
#include "spidarcad/fem/mesh.h"

namespace spidarcad::fem {

// Sparse matrix type of the global stiffness (column-major, int indices).
using SparseMatrixd = Eigen::SparseMatrix<double, Eigen::ColMajor, int>;
// Element node positions: #nodes-per-element (4 or 10) by 3, in m.
using ElementNodes = Eigen::Matrix<double, Eigen::Dynamic, 3>;

// Strain-displacement matrix B (6 by 3·npe) of a 4- or 10-node tetrahedron at barycentric
// point (L0, L1, L2, L3) (sum 1), so that strain = B·u_e with u_e = (u0x, u0y, u0z, u1x, ...).
// Also returns det J (6 × the local volume scale) through det_j when not null.
Eigen::MatrixXd StrainDisplacement(const ElementNodes& x, const Eigen::Vector4d& barycentric,
                                   double* det_j = nullptr);

// Element stiffness K_e = ∫ Bᵀ D B dV (12 by 12 or 30 by 30), symmetric. Linear elements use
// the exact one-point rule; quadratic ones the 4-point rule of degree 2 (exact for
// straight-edged elements, whose B is linear). With Formulation::kMeanDilatation (10-node
// only; 4-node elements throw std::invalid_argument) the λ part of D acts on the mean
// dilatation: K_e = ∫ Bᵀ D_μ B dV + λ V_e θ̄ᵀ θ̄ (D_μ = D with λ = 0, θ̄ = MeanDilatation).
Eigen::MatrixXd ElementStiffness(const ElementNodes& x, const Material& material);

// Mean dilatation operator θ̄ (1 by 3·npe, 1/m) of a 4- or 10-node element:
// θ̄ u_e = (1/V_e) ∫ div u dV (exact for straight-edged elements). The element volume V_e
// (m^3) goes to *volume when not null.
Eigen::RowVectorXd MeanDilatation(const ElementNodes& x, double* volume = nullptr);

// Positions of the nodes of element e of a mesh (npe by 3).
ElementNodes GetElementNodes(const TetMesh& mesh, int e);

// Global stiffness K (3·#V by 3·#V), symmetric, both triangles stored, compressed. Throws
// std::invalid_argument if a region has no material. Before constraints its null space holds
// the six rigid-body modes.
SparseMatrixd AssembleStiffness(const TetMesh& mesh, const MaterialTable& materials);

// Rigid-body modes of a mesh: 3·#V by 6, columns translation x, y, z then rotation about
// x, y, z through the centroid of the nodes (rotation columns scaled by 1 / bounding-box size).
Eigen::MatrixXd RigidBodyModes(const Eigen::MatrixX3d& nodes);

// Stress of element e at its centroid (6: σxx, σyy, σzz, σyz, σxz, σxy, in Pa) for global
// displacement u (3·#V). Mean-dilatation elements: D_μ ε at the centroid plus the element
// pressure λ θ̄ on σxx, σyy, σzz.
Eigen::Matrix<double, 6, 1> ElementStress(const TetMesh& mesh, const MaterialTable& materials,
                                          const Eigen::VectorXd& u, int e);

// Von Mises equivalent of a Voigt stress, in Pa.
double VonMises(const Eigen::Matrix<double, 6, 1>& stress);

// Von Mises stress of every element at its centroid (#T), in Pa.
Eigen::VectorXd ElementVonMises(const TetMesh& mesh, const MaterialTable& materials,
                                const Eigen::VectorXd& u);

// Element values averaged to the nodes, weighted by element volume (#V). Nodes in no element
// get 0.
Eigen::VectorXd AverageToNodes(const TetMesh& mesh, const Eigen::VectorXd& element_values);

}  // namespace spidarcad::fem
