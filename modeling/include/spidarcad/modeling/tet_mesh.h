// A linear tetrahedral mesh (for FE) with its quality figures and file output: VTU (VTK XML
// unstructured grid, ASCII, readable by ParaView) with point and cell data, and TetGen's
// .node/.ele text files.
// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#pragma once

#include <map>
#include <string>

#include <Eigen/Core>

namespace spidarcad::modeling {

// A tetrahedral mesh. nodes: 3 by V (m), one column per node (same layout as
// TriangleMesh::vertices). tets: 4 by T node indices (0-based), each tetrahedron positively
// oriented: (n1 - n0) · ((n2 - n0) × (n3 - n0)) > 0. regions: T region numbers (TetGen's region
// attribute: tets of one connected subdomain share a number; 0 when unknown).
struct TetMesh {
  Eigen::Matrix3Xd nodes;
  Eigen::Matrix4Xi tets;
  Eigen::VectorXi regions;
};

// Signed volume of tet t (m³): positive for the orientation above.
double TetVolume(const TetMesh& mesh, Eigen::Index t);

// Sum of the signed volumes of all tets (m³).
double TotalVolume(const TetMesh& mesh);

// The six dihedral angles of a tetrahedron (rad), at edges 01, 02, 03, 12, 13, 23.
Eigen::Matrix<double, 6, 1> DihedralAngles(const Eigen::Vector3d& p0, const Eigen::Vector3d& p1,
                                           const Eigen::Vector3d& p2, const Eigen::Vector3d& p3);

// Circumradius over shortest edge (TetGen's radius-edge ratio, the bound of its `q` switch):
// sqrt(6)/4 ≈ 0.612 for the regular tetrahedron, unbounded for slivers' cousins (caps, needles).
double RadiusEdgeRatio(const Eigen::Vector3d& p0, const Eigen::Vector3d& p1, const Eigen::Vector3d& p2,
                       const Eigen::Vector3d& p3);

// Quality figures of a whole mesh.
struct TetQuality {
  double min_dihedral_deg = 0.0;   // worst (smallest) dihedral angle, degrees
  double max_dihedral_deg = 0.0;   // worst (largest) dihedral angle, degrees
  double max_radius_edge = 0.0;    // worst radius-edge ratio
  double min_volume = 0.0;         // smallest signed tet volume, m³
  double total_volume = 0.0;       // m³
};

// Measures TetQuality over all tets (zeros for an empty mesh).
TetQuality MeasureTetQuality(const TetMesh& mesh);

// Checks the mesh's shape (nodes 3×V, tets 4×T, regions T or empty, indices in range, no repeated
// node in a tet); throws std::invalid_argument naming the first problem.
void ValidateTetMesh(const TetMesh& mesh);

// Extra data arrays for WriteVtu: name -> values, one column per point (or per cell). Rows are
// components (1 for a scalar, 3 for a vector).
using VtuArrays = std::map<std::string, Eigen::MatrixXd>;

// Writes mesh as a VTK XML UnstructuredGrid (.vtu, ASCII) with cell data "region" (Int32),
// "volume" and "min_dihedral_deg" (Float64) and the given extra point and cell arrays.
// Throws std::invalid_argument for a bad mesh or array (wrong column count, name clash) and
// std::runtime_error naming the file when it cannot be written.
void WriteVtu(const TetMesh& mesh, const std::string& path, const VtuArrays& point_data = {},
              const VtuArrays& cell_data = {});

// Writes TetGen's text files base + ".node" (index x y z, 0-based, no attributes) and
// base + ".ele" (index n0 n1 n2 n3 region). Throws like WriteVtu.
void WriteTetgenFiles(const TetMesh& mesh, const std::string& base);

}  // namespace spidarcad::modeling
