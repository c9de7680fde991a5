// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#include "spidarcad/fem/precompute_cache.h"

#include <gtest/gtest.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <memory>
#include <string>
#include <vector>

#include "spidarcad/fem/column_cache.h"

namespace spidarcad::fem {
namespace {

namespace fs = std::filesystem;

// A fresh directory under the test output folder, named after the running test.
fs::path ScratchDir() {
  const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
  const fs::path dir = fs::path(SPIDARCAD_TEST_OUTPUT_DIR) / "precompute_cache" / info->name();
  fs::remove_all(dir);
  return dir;
}

struct Model {
  TetMesh mesh;
  MaterialTable materials{Material{7.0e10, 0.33}};
  std::unique_ptr<BoundaryConditions> bcs;
  std::vector<int> outputs, candidates;

  Model() {
    BoxMeshSettings s;
    s.upper = Eigen::Vector3d(0.2, 0.05, 0.05);
    s.nx = 4;
    mesh = MakeBoxMesh(s);
    bcs = std::make_unique<BoundaryConditions>(mesh.num_nodes());
    FixNodesInBox(mesh, Eigen::Vector3d(-1, -1, -1), Eigen::Vector3d(1e-9, 1, 1), bcs.get());
    bcs->AddPointLoad(mesh.num_nodes() - 1, Eigen::Vector3d(0, 0, -10));
    outputs = ExtractSurface(mesh).nodes;
    candidates = NodesInBox(mesh, Eigen::Vector3d(-1, -1, 0.05), Eigen::Vector3d(1, 1, 1));
  }
  std::uint64_t Key(ColumnPrecision p = ColumnPrecision::kDouble) const {
    return PrecomputeKey(mesh, materials, *bcs, outputs, p);
  }
};

TEST(Fnv1a64, MatchesTheReferenceTestVectors) {
  // Published FNV-1a 64 values (Fowler/Noll/Vo test suite).
  EXPECT_EQ(Fnv1a64("", 0), 0xcbf29ce484222325ull);
  EXPECT_EQ(Fnv1a64("a", 1), 0xaf63dc4c8601ec8cull);
  EXPECT_EQ(Fnv1a64("foobar", 6), 0x85944171f73967e8ull);
  // Continuing a hash equals hashing the concatenation.
  EXPECT_EQ(Fnv1a64("bar", 3, Fnv1a64("foo", 3)), Fnv1a64("foobar", 6));
}

TEST(PrecomputeKey, ChangesWhenMaterialConstraintLoadMeshOrPrecisionChange) {
  const Model m;
  const std::uint64_t key = m.Key();
  EXPECT_EQ(key, Model().Key());  // deterministic

  Model stiffer;
  stiffer.materials = MaterialTable(Material{7.1e10, 0.33});
  EXPECT_NE(stiffer.Key(), key);
  Model poisson;
  poisson.materials = MaterialTable(Material{7.0e10, 0.3});
  EXPECT_NE(poisson.Key(), key);
  Model region;  // a material set on a region no element uses does not matter...
  region.materials.Set(5, Material{1e6, 0.2});
  EXPECT_EQ(region.Key(), key);
  LabelRegionInBox(Eigen::Vector3d(0.1, -1, -1), Eigen::Vector3d(1, 1, 1), 5, &region.mesh);
  EXPECT_NE(region.Key(), key);  // ...until elements use it

  Model more_fixed;
  more_fixed.bcs->FixNode(more_fixed.mesh.num_nodes() - 2);
  EXPECT_NE(more_fixed.Key(), key);
  Model prescribed;
  prescribed.bcs->PrescribeDof(prescribed.mesh.num_nodes() - 2, 2, 1e-6);
  EXPECT_NE(prescribed.Key(), key);
  Model loaded;
  loaded.bcs->AddPointLoad(3, Eigen::Vector3d(1, 0, 0));
  EXPECT_NE(loaded.Key(), key);
  Model moved;
  moved.mesh.nodes(7, 1) += 1e-9;
  EXPECT_NE(moved.Key(), key);
  Model quadratic;
  quadratic.mesh = MakeQuadratic(quadratic.mesh);
  EXPECT_NE(PrecomputeKey(quadratic.mesh, quadratic.materials,
                          BoundaryConditions(quadratic.mesh.num_nodes()), quadratic.outputs,
                          ColumnPrecision::kDouble),
            PrecomputeKey(m.mesh, m.materials, BoundaryConditions(m.mesh.num_nodes()), m.outputs,
                          ColumnPrecision::kDouble));
  EXPECT_NE(m.Key(ColumnPrecision::kFloat), key);
  Model fewer_outputs;
  fewer_outputs.outputs.pop_back();
  EXPECT_NE(fewer_outputs.Key(), key);
}

TEST(PrecomputeCache, RoundTripRestoresTheColumnsExactly) {
  for (ColumnPrecision precision : {ColumnPrecision::kDouble, ColumnPrecision::kFloat}) {
    const Model m;
    const StaticSolver solver(m.mesh, m.materials, *m.bcs);
    ColumnCacheSettings settings;
    settings.start_worker = false;
    settings.precision = precision;
    ColumnCache cache(solver, m.mesh.nodes, m.outputs, m.candidates, settings);
    cache.ComputeNodes({1, 2, 4, 7});
    const std::uint64_t key = m.Key(precision);
    const ColumnSet saved = cache.Export(key);
    ASSERT_EQ(saved.nodes.size(), 4u);
    const PrecomputeCache disk(ScratchDir() / (precision == ColumnPrecision::kFloat ? "f" : "d"));
    std::string error;
    ASSERT_TRUE(disk.Save(saved, &error)) << error;
    std::string reason;
    const std::optional<ColumnSet> loaded = disk.Load(key, &reason);
    ASSERT_TRUE(loaded) << reason;
    EXPECT_EQ(loaded->nodes, saved.nodes);
    EXPECT_EQ(loaded->output_nodes, saved.output_nodes);
    EXPECT_EQ(loaded->precision, precision);
    EXPECT_EQ(loaded->baseline, saved.baseline);
    EXPECT_EQ(loaded->columns, saved.columns);
    // No temporary file is left behind.
    int files = 0;
    for (const auto& entry : fs::directory_iterator(disk.directory())) {
      ++files;
      EXPECT_EQ(entry.path().extension(), ".cols") << entry.path();
    }
    EXPECT_EQ(files, 1);
    // The file size says the precision: 4 or 8 bytes per value.
    const double values = 9.0 * m.outputs.size() * 4;
    EXPECT_GT(static_cast<double>(fs::file_size(disk.PathFor(key))),
              values * BytesPerValue(precision));
    EXPECT_LT(static_cast<double>(fs::file_size(disk.PathFor(key))),
              values * BytesPerValue(precision) + 8.0 * 3 * m.outputs.size() + 4096);

    // Imported into a fresh cache, the columns read back as computed.
    ColumnCache fresh(solver, m.mesh.nodes, m.outputs, m.candidates, settings);
    EXPECT_EQ(fresh.Import(*loaded), 4);
    for (int b : {1, 2, 4, 7}) {
      ASSERT_TRUE(fresh.Pin(b));
      ASSERT_TRUE(cache.Pin(b));
      for (int j = 0; j < 3; ++j)
        for (int r = 0; r < 3 * fresh.num_outputs(); ++r)
          ASSERT_EQ(fresh.Value(r, b, j), cache.Value(r, b, j));
      fresh.Unpin(b);
      cache.Unpin(b);
    }
    EXPECT_FALSE(fresh.IsReady(3));
  }
}

// Saves a small valid set and returns the path of its file.
fs::path SaveSample(const PrecomputeCache& disk, std::uint64_t key) {
  ColumnSet set;
  set.key = key;
  set.output_nodes = {0, 3, 5};
  set.nodes = {3};
  set.baseline = Eigen::VectorXd::LinSpaced(9, -1.0, 1.0);
  set.columns = Eigen::MatrixXd::Constant(9, 3, 0.25);
  std::string error;
  EXPECT_TRUE(disk.Save(set, &error)) << error;
  return disk.PathFor(key);
}

std::string LoadReason(const PrecomputeCache& disk, std::uint64_t key) {
  std::string reason;
  EXPECT_FALSE(disk.Load(key, &reason));
  return reason;
}

TEST(PrecomputeCache, IgnoresCorruptTruncatedForeignOrMissingFilesWithAReason) {
  const PrecomputeCache disk(ScratchDir());
  const std::uint64_t key = 0x1234abcdull;
  EXPECT_NE(LoadReason(disk, key).find("absent"), std::string::npos);

  fs::path path = SaveSample(disk, key);
  ASSERT_TRUE(disk.Load(key));
  const auto size = fs::file_size(path);
  auto patch_byte = [&](std::size_t offset, char value) {
    std::fstream f(path, std::ios::in | std::ios::out | std::ios::binary);
    f.seekp(static_cast<std::streamoff>(offset));
    f.put(value);
  };
  // A flipped bit in the columns: the checksum catches it.
  patch_byte(size - 20, 0x7f);
  EXPECT_NE(LoadReason(disk, key).find("checksum"), std::string::npos);
  // Truncated.
  path = SaveSample(disk, key);
  fs::resize_file(path, size - 9);
  EXPECT_NE(LoadReason(disk, key).find("size"), std::string::npos);
  fs::resize_file(path, 5);
  EXPECT_NE(LoadReason(disk, key).find("truncated"), std::string::npos);
  // Another format version (bytes 8..11).
  path = SaveSample(disk, key);
  patch_byte(8, 99);
  EXPECT_NE(LoadReason(disk, key).find("format version 99"), std::string::npos);
  // Not ours at all.
  path = SaveSample(disk, key);
  patch_byte(0, 'X');
  EXPECT_NE(LoadReason(disk, key).find("magic"), std::string::npos);
  // A file for another key under this key's name (copied by hand).
  const fs::path other = SaveSample(disk, key + 1);
  fs::copy_file(other, disk.PathFor(key), fs::copy_options::overwrite_existing);
  EXPECT_NE(LoadReason(disk, key).find("holds key"), std::string::npos);
  // And a good file loads again after being rewritten.
  SaveSample(disk, key);
  EXPECT_TRUE(disk.Load(key));
}

TEST(PrecomputeCache, RefusesToSaveAnInconsistentSet) {
  const PrecomputeCache disk(ScratchDir());
  ColumnSet set;
  set.output_nodes = {0, 1};
  set.nodes = {1};
  set.baseline = Eigen::VectorXd::Zero(6);
  set.columns = Eigen::MatrixXd::Zero(6, 2);  // should be 6 by 3
  std::string error;
  EXPECT_FALSE(disk.Save(set, &error));
  EXPECT_NE(error.find("inconsistent"), std::string::npos) << error;
}

TEST(DefaultCacheDirectory, HonoursOverrideThenXdgThenHome) {
  auto keep = [](const char* name) {
    const char* v = std::getenv(name);
    return v ? std::optional<std::string>(v) : std::nullopt;
  };
  const auto own = keep("SPIDARCAD_CACHE_DIR"), xdg = keep("XDG_CACHE_HOME"), home = keep("HOME");
  ::setenv("SPIDARCAD_CACHE_DIR", "/tmp/own-cache", 1);
  ::setenv("XDG_CACHE_HOME", "/tmp/xdg", 1);
  ::setenv("HOME", "/tmp/home", 1);
  EXPECT_EQ(DefaultCacheDirectory(), fs::path("/tmp/own-cache"));
  ::unsetenv("SPIDARCAD_CACHE_DIR");
  EXPECT_EQ(DefaultCacheDirectory(), fs::path("/tmp/xdg/spidarcad"));
  ::unsetenv("XDG_CACHE_HOME");
  EXPECT_EQ(DefaultCacheDirectory(), fs::path("/tmp/home/.cache/spidarcad"));
  auto restore = [](const char* name, const std::optional<std::string>& v) {
    if (v)
      ::setenv(name, v->c_str(), 1);
    else
      ::unsetenv(name);
  };
  restore("SPIDARCAD_CACHE_DIR", own);
  restore("XDG_CACHE_HOME", xdg);
  restore("HOME", home);
}

}  // namespace
}  // namespace spidarcad::fem
