// Tetrahedral meshes for linear elasticity: storage, a structured box generator, the
// quadratic (10-node) upgrade and boundary surface extraction.
//
// Node numbering of a 10-node tetrahedron follows VTK (VTK_QUADRATIC_TETRA): corners 0..3,
// then the midside nodes of edges (0,1), (1,2), (0,2), (0,3), (1,3), (2,3).
// Corner order is positive: det[x1 - x0, x2 - x0, x3 - x0] > 0.
// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#pragma once

#include <Eigen/Core>
#include <array>
#include <vector>

namespace spidarcad::fem {

// Row-major integer matrix used for element connectivity (one element per row).
using MatrixXiR = Eigen::Matrix<int, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;

// Local corner pairs of the six edges of a tetrahedron, in VTK midside-node order.
inline constexpr std::array<std::array<int, 2>, 6> kTetEdges = {
    {{0, 1}, {1, 2}, {0, 2}, {0, 3}, {1, 3}, {2, 3}}};

// Local corners of the four faces of a tetrahedron, ordered so that the normal
// (x1 - x0) × (x2 - x0) points out of a positively oriented element. Faces are opposite
// corners 3, 2, 0, 1 respectively.
inline constexpr std::array<std::array<int, 3>, 4> kTetFaces = {
    {{0, 2, 1}, {0, 1, 3}, {1, 2, 3}, {0, 3, 2}}};

// Local midside node (4..9) of the edge between local corners a and b of a 10-node tetrahedron.
int TetEdgeNode(int a, int b);

// A tetrahedral mesh.
struct TetMesh {
  // Node positions, #V by 3, in m.
  Eigen::MatrixX3d nodes;
  // Connectivity, #T by 4 (linear) or #T by 10 (quadratic), 0-based node indices.
  MatrixXiR elements;
  // Region label of each element, #T (materials are looked up by label).
  Eigen::VectorXi regions;

  // Number of nodes per element: 4 or 10.
  int NodesPerElement() const { return static_cast<int>(elements.cols()); }
  // Element order: 1 for 4-node, 2 for 10-node tetrahedra.
  int Order() const { return NodesPerElement() == 10 ? 2 : 1; }
  // Number of nodes #V.
  int num_nodes() const { return static_cast<int>(nodes.rows()); }
  // Number of elements #T.
  int num_elements() const { return static_cast<int>(elements.rows()); }

  // Throws std::invalid_argument (naming element, field and value) when the connectivity has
  // a width other than 4 or 10, an index is out of range, regions has the wrong size, or an
  // element's corner volume is not positive.
  void Validate() const;
  // Signed volume of the corner tetrahedron of element e, in m^3.
  double CornerVolume(int e) const;
};

// How each hexahedral cell of a box mesh is split.
enum class HexSplit { kFive, kSix };

// Settings of MakeBoxMesh.
struct BoxMeshSettings {
  // Opposite corners of the box, in m (lower < upper component-wise).
  Eigen::Vector3d lower = Eigen::Vector3d::Zero();
  Eigen::Vector3d upper = Eigen::Vector3d::Ones();
  // Number of hexahedral cells along x, y, z (each >= 1).
  int nx = 1, ny = 1, nz = 1;
  // Five tetrahedra per cell (alternating orientation, conforming) or six (Kuhn split).
  HexSplit split = HexSplit::kSix;
  // 1 for 4-node, 2 for 10-node tetrahedra.
  int order = 1;
};

// Structured tetrahedral mesh of an axis-aligned box; all regions 0. Throws
// std::invalid_argument on bad settings.
TetMesh MakeBoxMesh(const BoxMeshSettings& settings);

// 10-node mesh from a 4-node one: one new node at the midpoint of every edge (shared between
// elements). Node indices of the input are kept; midside nodes are appended.
TetMesh MakeQuadratic(const TetMesh& linear);

// Sets the region of every element whose corner centroid lies in the box [lower, upper].
void LabelRegionInBox(const Eigen::Vector3d& lower, const Eigen::Vector3d& upper, int label,
                      TetMesh* mesh);

// Boundary of a tetrahedral mesh.
struct Surface {
  // Boundary faces, #F by 3 corner nodes, counter-clockwise seen from outside (outward normal).
  MatrixXiR faces;
  // For 10-node meshes, #F by 6: corners then midside nodes of edges (0,1), (1,2), (2,0);
  // empty for 4-node meshes.
  MatrixXiR faces6;
  // Element that owns each face, #F.
  Eigen::VectorXi face_element;
  // Sorted list of every node on the boundary (corner and midside).
  std::vector<int> nodes;
};

// Faces that belong to exactly one element, and the nodes on them.
Surface ExtractSurface(const TetMesh& mesh);

}  // namespace spidarcad::fem
