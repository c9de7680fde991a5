// A linear tetrahedral mesh (for FE) with its quality figures and file input/output: VTU (VTK
// XML unstructured grid, readable by ParaView) with point and cell data, and TetGen's
// .node/.ele text files.
//
// VTU is read and written here only (the app's fem command uses these functions too), without
// VTK. The reader takes the encodings VTK and ParaView write: ascii, inline binary (base64),
// appended raw or base64, each uncompressed or zlib-compressed (vtkZLibDataCompressor),
// UInt32 or UInt64 headers, either byte order; cells VTK_TETRA (4 nodes) or
// VTK_QUADRATIC_TETRA (10 nodes), one kind per file, in a single Piece. It checks every count,
// offset, size and index against the data before using it and refuses anything else with a
// VtuError that names the source, the byte offset, the XML element or array and the value.
// Data arrays have ONE orientation everywhere: k by N, one column per point (or cell), one
// row per component, i.e. VTK's interleaved tuple order in Eigen's column-major storage.
// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#pragma once

#include <Eigen/Core>
#include <cstddef>
#include <map>
#include <stdexcept>
#include <string>
#include <string_view>

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
double RadiusEdgeRatio(const Eigen::Vector3d& p0, const Eigen::Vector3d& p1,
                       const Eigen::Vector3d& p2, const Eigen::Vector3d& p3);

// Quality figures of a whole mesh.
struct TetQuality {
  double min_dihedral_deg = 0.0;  // worst (smallest) dihedral angle, degrees
  double max_dihedral_deg = 0.0;  // worst (largest) dihedral angle, degrees
  double max_radius_edge = 0.0;   // worst radius-edge ratio
  double min_volume = 0.0;        // smallest signed tet volume, m³
  double total_volume = 0.0;      // m³
};

// Measures TetQuality over all tets (zeros for an empty mesh).
TetQuality MeasureTetQuality(const TetMesh& mesh);

// Checks the mesh's shape (nodes 3×V, tets 4×T, regions T or empty, indices in range, no repeated
// node in a tet); throws std::invalid_argument naming the first problem.
void ValidateTetMesh(const TetMesh& mesh);

// Data arrays of a VTU file: name -> values, k by N, one column per point (or per cell). Rows
// are components (1 for a scalar, 3 for a vector).
using VtuArrays = std::map<std::string, Eigen::MatrixXd>;

// Writes mesh as a VTK XML UnstructuredGrid (.vtu, ASCII, through WriteVtuGrid) with cell
// data "region" (Int32), "volume" and "min_dihedral_deg" (Float64) and the given extra point
// and cell arrays (k by V, k by T).
// Throws std::invalid_argument for a bad mesh or array (wrong column count, name clash) and
// std::runtime_error naming the file when it cannot be written.
void WriteVtu(const TetMesh& mesh, const std::string& path, const VtuArrays& point_data = {},
              const VtuArrays& cell_data = {});

// A tetrahedral grid as held in a .vtu file.
struct VtuGrid {
  // Point positions, 3 by V, m.
  Eigen::Matrix3Xd points;
  // Cells, 4 by T (VTK_TETRA) or 10 by T (VTK_QUADRATIC_TETRA: corners, then the midside
  // nodes of edges 01, 12, 02, 03, 13, 23), 0-based point indices, as in the file (orientation
  // not checked).
  Eigen::MatrixXi cells;
  // Cell array "region" (integral values), T; empty when the file has none.
  Eigen::VectorXi regions;
  // Other numeric point arrays, k by V, and cell arrays, k by T (values as in the file).
  VtuArrays point_data;
  VtuArrays cell_data;
};

// A .vtu that cannot be read: what() is "<source>: byte <offset>: <what is wrong>".
class VtuError : public std::runtime_error {
 public:
  // Error in `source` (a path or a label) at byte `offset` of it.
  VtuError(const std::string& source, std::size_t offset, const std::string& message);
  // The path or label of the input.
  const std::string& source() const { return source_; }
  // Byte offset in the input where the problem was found.
  std::size_t offset() const { return offset_; }

 private:
  std::string source_;
  std::size_t offset_;
};

// Parses the bytes of a .vtu file (see the header comment for what is accepted). `source`
// names the input in messages. Never reads outside `bytes`; memory use is bounded by a
// multiple of bytes.size() (zlib's maximum ratio for compressed data). Throws VtuError only.
// This is the entry point for fuzzing the reader.
VtuGrid ParseVtuGrid(std::string_view bytes, const std::string& source = "<memory>");

// Reads a .vtu file: ParseVtuGrid on its bytes. Throws VtuError (offset 0) when the file
// cannot be opened or read.
VtuGrid ReadVtuGrid(const std::string& path);

// How WriteVtuGrid stores arrays.
enum class VtuEncoding {
  kAscii,        // decimal text (%.17g for reals: round-trips exactly)
  kAppendedRaw,  // raw little-endian binary after the XML (UInt64 headers), compact
};

// Writes a grid as a .vtu readable by ParaView and by ReadVtuGrid: points (Float64), cells
// (Int64 connectivity and offsets, UInt8 types), cell array "region" (Int32) when regions is
// not empty, then point_data and cell_data (Float64). The file is written under a temporary
// name and renamed, so a reader never sees half a file. Throws std::invalid_argument for a
// bad grid (shape, index out of range, repeated node, array size or name, non-finite value)
// and std::runtime_error naming the file when it cannot be written.
void WriteVtuGrid(const VtuGrid& grid, const std::string& path,
                  VtuEncoding encoding = VtuEncoding::kAppendedRaw);

// Writes TetGen's text files base + ".node" (index x y z, 0-based, no attributes) and
// base + ".ele" (index n0 n1 n2 n3 region). Throws like WriteVtu.
void WriteTetgenFiles(const TetMesh& mesh, const std::string& base);

}  // namespace spidarcad::modeling
