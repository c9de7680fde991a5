// Precomputed compliance columns cached on disk, keyed by a hash of everything they depend on.
//
// Key: FNV-1a 64 over the file format version, the storage precision, the element order, the
// node positions, the connectivity and region labels, the material (E, ν, and the formulation
// unless kDisplacement) of every region the mesh uses, the prescribed dofs with their values, the
// nodal loads (they set the baseline) and the output node list. Change any of these and the key
// changes, so a stale file is never used.
//
// File (little-endian, as written by this machine): magic "SPDCOLS1", u32 format version, u64 key,
// u32 precision (0 double, 1 float), u64 #output, u64 #nodes, i32[#output] output nodes,
// i32[#nodes] column nodes, f64[3·#output] baseline, then the columns (3·#output rows by
// 3·#nodes, column-major) as f64 or f32, and a trailing u64 FNV-1a of every byte before it.
// Files are written under a temporary name and renamed, so a reader never sees half a file; a
// file that is truncated, corrupt, of another version or for another key is ignored with a
// reason and recomputed, never trusted.
// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#pragma once

#include <Eigen/Core>
#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include "spidarcad/fem/boundary.h"
#include "spidarcad/fem/material.h"
#include "spidarcad/fem/mesh.h"

namespace spidarcad::fem {

// How compliance columns are stored (in memory by ColumnCache and on disk).
enum class ColumnPrecision {
  kDouble,  // 8 bytes per value, exact
  kFloat,   // 4 bytes per value, each entry rounded to nearest: relative error <= 2^-24
};

// Bytes per stored value of a precision (8 or 4).
inline int BytesPerValue(ColumnPrecision p) { return p == ColumnPrecision::kFloat ? 4 : 8; }

// Version of the on-disk format (part of the key and of the header).
inline constexpr std::uint32_t kPrecomputeFormatVersion = 1;

// FNV-1a 64 offset basis (the hash of nothing).
inline constexpr std::uint64_t kFnvOffsetBasis = 14695981039346656037ull;

// FNV-1a 64 of `size` bytes at `data`, continuing from hash h.
std::uint64_t Fnv1a64(const void* data, std::size_t size, std::uint64_t h = kFnvOffsetBasis);

// Cache key of compliance columns of a model observed at output_nodes, stored with precision.
// Throws std::invalid_argument (naming the region) when a region of the mesh has no material.
std::uint64_t PrecomputeKey(const TetMesh& mesh, const MaterialTable& materials,
                            const BoundaryConditions& bcs, const std::vector<int>& output_nodes,
                            ColumnPrecision precision);

// A set of compliance columns as stored on disk: for each node in `nodes`, its three columns
// (unit force along x, y, z) observed at the output nodes.
struct ColumnSet {
  // Key of the inputs (PrecomputeKey).
  std::uint64_t key = 0;
  // Precision of the stored values (values below are always held in double in memory; with
  // kFloat they are exactly representable in float).
  ColumnPrecision precision = ColumnPrecision::kDouble;
  // Output nodes (mesh indices): row blocks of `columns` and `baseline`.
  std::vector<int> output_nodes;
  // Mesh nodes whose columns are held: column blocks of `columns`.
  std::vector<int> nodes;
  // Displacement of the output nodes under the model's own loads, 3·#output, m.
  Eigen::VectorXd baseline;
  // Columns, 3·#output by 3·#nodes, m/N: entry (3a + i, 3b + j) is the displacement of output
  // node a along i under a unit force on node nodes[b] along j.
  Eigen::MatrixXd columns;
};

// Cache directory: $SPIDARCAD_CACHE_DIR if set, else $XDG_CACHE_HOME/spidarcad, else
// $HOME/.cache/spidarcad, else a "spidarcad-cache" folder in the system temporary directory.
std::filesystem::path DefaultCacheDirectory();

// A directory of column-set files named by key.
class PrecomputeCache {
 public:
  // Cache in `directory` (created on the first Save).
  explicit PrecomputeCache(std::filesystem::path directory = DefaultCacheDirectory());

  // The directory.
  const std::filesystem::path& directory() const { return directory_; }
  // File that holds the columns of `key`: <directory>/<16 hex digits>.cols.
  std::filesystem::path PathFor(std::uint64_t key) const;

  // Writes `set` under its key (temporary file, then rename). Returns false and says why in
  // *error (when given) if the directory or file cannot be written or the set is inconsistent.
  bool Save(const ColumnSet& set, std::string* error = nullptr) const;
  // Reads the columns of `key`. Returns nothing, with the reason in *reason (when given), when
  // there is no file or it is truncated, corrupt (checksum), of another format version, for
  // another key, or inconsistent (sizes, node indices, non-finite values).
  std::optional<ColumnSet> Load(std::uint64_t key, std::string* reason = nullptr) const;

 private:
  std::filesystem::path directory_;
};

}  // namespace spidarcad::fem
