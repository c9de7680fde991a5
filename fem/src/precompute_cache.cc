// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#include "spidarcad/fem/precompute_cache.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <iterator>
#include <set>
#include <stdexcept>
#include <system_error>

#include "spidarcad/fem/cache_file.h"

namespace spidarcad::fem {
namespace {

constexpr char kMagic[8] = {'S', 'P', 'D', 'C', 'O', 'L', 'S', '1'};
constexpr std::uint64_t kFnvPrime = 1099511628211ull;

template <typename T>
std::uint64_t HashValue(const T& v, std::uint64_t h) {
  return Fnv1a64(&v, sizeof(T), h);
}

}  // namespace

std::uint64_t Fnv1a64(const void* data, std::size_t size, std::uint64_t h) {
  const auto* p = static_cast<const unsigned char*>(data);
  for (std::size_t i = 0; i < size; ++i) {
    h ^= p[i];
    h *= kFnvPrime;
  }
  return h;
}

std::uint64_t PrecomputeKey(const TetMesh& mesh, const MaterialTable& materials,
                            const BoundaryConditions& bcs, const std::vector<int>& output_nodes,
                            ColumnPrecision precision) {
  std::uint64_t h = kFnvOffsetBasis;
  h = HashValue(kPrecomputeFormatVersion, h);
  h = HashValue(static_cast<std::int32_t>(precision), h);
  h = HashValue(static_cast<std::int32_t>(mesh.Order()), h);
  // Node positions row by row (the storage order of MatrixX3d is column-major; hash by value).
  h = HashValue(static_cast<std::int64_t>(mesh.num_nodes()), h);
  for (int v = 0; v < mesh.num_nodes(); ++v)
    for (int i = 0; i < 3; ++i) h = HashValue(mesh.nodes(v, i), h);
  h = HashValue(static_cast<std::int64_t>(mesh.num_elements()), h);
  h = HashValue(static_cast<std::int64_t>(mesh.elements.cols()), h);
  for (int e = 0; e < mesh.num_elements(); ++e)
    for (int c = 0; c < mesh.elements.cols(); ++c) h = HashValue(mesh.elements(e, c), h);
  h = HashValue(static_cast<std::int64_t>(mesh.regions.size()), h);
  std::set<int> labels;
  for (int e = 0; e < mesh.regions.size(); ++e) {
    h = HashValue(mesh.regions(e), h);
    labels.insert(mesh.regions(e));
  }
  for (int label : labels) {
    const Material& m = materials.Get(label);
    h = HashValue(label, h);
    h = HashValue(m.youngs_modulus, h);
    h = HashValue(m.poisson_ratio, h);
    // Hashed only when not the default, so that keys of older files stay valid.
    if (m.formulation != Formulation::kDisplacement)
      h = HashValue(static_cast<std::int32_t>(m.formulation), h);
  }
  h = HashValue(static_cast<std::int64_t>(bcs.prescribed().size()), h);
  for (const auto& [dof, value] : bcs.prescribed()) {
    h = HashValue(dof, h);
    h = HashValue(value, h);
  }
  h = HashValue(static_cast<std::int64_t>(bcs.loads().size()), h);
  h = Fnv1a64(bcs.loads().data(), sizeof(double) * bcs.loads().size(), h);
  h = HashValue(static_cast<std::int64_t>(output_nodes.size()), h);
  h = Fnv1a64(output_nodes.data(), sizeof(int) * output_nodes.size(), h);
  return h;
}

std::filesystem::path DefaultCacheDirectory() {
  if (const char* dir = std::getenv("SPIDARCAD_CACHE_DIR"); dir && *dir) return dir;
  if (const char* xdg = std::getenv("XDG_CACHE_HOME"); xdg && *xdg)
    return std::filesystem::path(xdg) / "spidarcad";
  if (const char* home = std::getenv("HOME"); home && *home)
    return std::filesystem::path(home) / ".cache" / "spidarcad";
  std::error_code ec;
  return std::filesystem::temp_directory_path(ec) / "spidarcad-cache";
}

PrecomputeCache::PrecomputeCache(std::filesystem::path directory)
    : directory_(std::move(directory)) {}

std::filesystem::path PrecomputeCache::PathFor(std::uint64_t key) const {
  return directory_ / (HexKey(key) + ".cols");
}

bool PrecomputeCache::Save(const ColumnSet& set, std::string* error) const {
  auto fail = [&](const std::string& why) {
    if (error) *error = why;
    return false;
  };
  const std::size_t num_out = set.output_nodes.size(), num_nodes = set.nodes.size();
  if (set.baseline.size() != static_cast<Eigen::Index>(3 * num_out) ||
      set.columns.rows() != static_cast<Eigen::Index>(3 * num_out) ||
      set.columns.cols() != static_cast<Eigen::Index>(3 * num_nodes)) {
    return fail("column set of key " + HexKey(set.key) + " is inconsistent: baseline " +
                std::to_string(set.baseline.size()) + ", columns " +
                std::to_string(set.columns.rows()) + " by " + std::to_string(set.columns.cols()) +
                " for " + std::to_string(num_out) + " output and " + std::to_string(num_nodes) +
                " column nodes");
  }
  ByteWriter w;
  w.PutArray(kMagic, 8);
  w.Put(kPrecomputeFormatVersion);
  w.Put(set.key);
  w.Put(static_cast<std::uint32_t>(set.precision == ColumnPrecision::kFloat ? 1 : 0));
  w.Put(static_cast<std::uint64_t>(num_out));
  w.Put(static_cast<std::uint64_t>(num_nodes));
  for (int v : set.output_nodes) w.Put(static_cast<std::int32_t>(v));
  for (int v : set.nodes) w.Put(static_cast<std::int32_t>(v));
  w.PutArray(set.baseline.data(), set.baseline.size());
  if (set.precision == ColumnPrecision::kFloat) {
    const Eigen::MatrixXf f = set.columns.cast<float>();
    w.PutArray(f.data(), f.size());
  } else {
    w.PutArray(set.columns.data(), set.columns.size());
  }
  const std::uint64_t checksum = Fnv1a64(w.bytes().data(), w.bytes().size());
  w.Put(checksum);

  return WriteFileAtomically(PathFor(set.key), {{w.bytes().data(), w.bytes().size()}}, error);
}

std::optional<ColumnSet> PrecomputeCache::Load(std::uint64_t key, std::string* reason) const {
  const std::filesystem::path path = PathFor(key);
  auto fail = [&](const std::string& why) -> std::optional<ColumnSet> {
    if (reason) *reason = path.string() + ": " + why;
    return std::nullopt;
  };
  std::ifstream in(path, std::ios::binary);
  if (!in) return fail("no cached columns (file absent or unreadable)");
  const std::vector<unsigned char> bytes((std::istreambuf_iterator<char>(in)),
                                         std::istreambuf_iterator<char>());
  if (bytes.size() < 8 + sizeof(std::uint64_t))
    return fail("truncated (" + std::to_string(bytes.size()) + " bytes)");
  ByteReader r(bytes.data(), bytes.size() - sizeof(std::uint64_t));
  char magic[8];
  r.GetArray(magic, 8);
  if (std::memcmp(magic, kMagic, 8) != 0) return fail("not a spidarcad column file (bad magic)");
  std::uint32_t version = 0, precision = 0;
  std::uint64_t file_key = 0, num_out = 0, num_nodes = 0;
  if (!r.Get(&version)) return fail("truncated header");
  if (version != kPrecomputeFormatVersion) {
    return fail("format version " + std::to_string(version) + ", expected " +
                std::to_string(kPrecomputeFormatVersion));
  }
  if (!r.Get(&file_key) || !r.Get(&precision) || !r.Get(&num_out) || !r.Get(&num_nodes))
    return fail("truncated header");
  if (file_key != key) return fail("holds key " + HexKey(file_key) + ", expected " + HexKey(key));
  if (precision > 1) return fail("unknown precision code " + std::to_string(precision));
  const std::size_t value_bytes = precision == 1 ? 4 : 8;
  // Expected size, checked before allocating anything of the sizes read.
  const long double expected = 8.0L + 4 + 8 + 4 + 8 + 8 + 4.0L * (num_out + num_nodes) +
                               8.0L * 3 * num_out + value_bytes * 9.0L * num_out * num_nodes + 8;
  if (expected != static_cast<long double>(bytes.size())) {
    return fail("size " + std::to_string(bytes.size()) + " bytes does not match its header (" +
                std::to_string(static_cast<double>(expected)) + " expected): truncated or corrupt");
  }
  std::uint64_t stored_checksum = 0;
  std::memcpy(&stored_checksum, bytes.data() + bytes.size() - sizeof(std::uint64_t),
              sizeof(std::uint64_t));
  if (Fnv1a64(bytes.data(), bytes.size() - sizeof(std::uint64_t)) != stored_checksum)
    return fail("checksum mismatch: corrupt");
  ColumnSet set;
  set.key = file_key;
  set.precision = precision == 1 ? ColumnPrecision::kFloat : ColumnPrecision::kDouble;
  std::vector<std::int32_t> out32(num_out), nodes32(num_nodes);
  r.GetArray(out32.data(), num_out);
  r.GetArray(nodes32.data(), num_nodes);
  set.output_nodes.assign(out32.begin(), out32.end());
  set.nodes.assign(nodes32.begin(), nodes32.end());
  std::vector<char> is_output;
  for (int v : set.output_nodes) {
    if (v < 0) return fail("negative output node index " + std::to_string(v));
    if (static_cast<std::size_t>(v) >= is_output.size()) is_output.resize(v + 1, 0);
    is_output[v] = 1;
  }
  for (int v : set.nodes)
    if (v < 0 || static_cast<std::size_t>(v) >= is_output.size() || !is_output[v])
      return fail("column node " + std::to_string(v) + " is not an output node");
  set.baseline.resize(3 * num_out);
  r.GetArray(set.baseline.data(), 3 * num_out);
  set.columns.resize(3 * num_out, 3 * num_nodes);
  if (precision == 1) {
    Eigen::MatrixXf f(3 * num_out, 3 * num_nodes);
    r.GetArray(f.data(), f.size());
    set.columns = f.cast<double>();
  } else {
    r.GetArray(set.columns.data(), set.columns.size());
  }
  if (!set.baseline.allFinite() || !set.columns.allFinite()) return fail("non-finite values");
  return set;
}

}  // namespace spidarcad::fem
