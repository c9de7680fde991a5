// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
// CholeskyFactor: the factor's flat form rebuilds a factor that solves bit for bit as the
// original (the window moves it from a child process, app/scene/worker_process.h), a bad block
// is refused with a reason rather than read out of bounds, and a failed factorisation keeps its
// failed column. The solves are checked against the matrix itself (residuals), not only against
// each other.
#include "spidarcad/fem/cholesky_factor.h"

#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <atomic>
#include <cstdint>
#include <cstring>
#include <random>
#include <stdexcept>
#include <string>
#include <vector>

#include "spidarcad/fem/static_solver.h"

namespace spidarcad::fem {
namespace {

// The clamped stiffness K_ff of a box mesh (3D elasticity: supernodes of many columns).
SparseMatrixd BoxStiffness(int cells, int order, BoundaryConditions* bcs_out = nullptr,
                           TetMesh* mesh_out = nullptr) {
  BoxMeshSettings s;
  s.nx = 2 * cells;
  s.ny = cells;
  s.nz = cells;
  s.order = order;
  s.upper = Eigen::Vector3d(0.2, 0.1, 0.1);
  const TetMesh mesh = MakeBoxMesh(s);
  BoundaryConditions bcs(mesh.num_nodes());
  bcs.FixNodes(NodesInBox(mesh, Eigen::Vector3d(-1, -1, -1), Eigen::Vector3d(1e-9, 1, 1)));
  for (int v : NodesInBox(mesh, Eigen::Vector3d(0.2 - 1e-9, -1, -1), Eigen::Vector3d(1, 1, 1)))
    bcs.AddPointLoad(v, Eigen::Vector3d(0.0, 0.0, -10.0));
  const StaticSolver solver(mesh, MaterialTable(Material{70e9, 0.33}), bcs);
  if (bcs_out != nullptr) *bcs_out = bcs;
  if (mesh_out != nullptr) *mesh_out = mesh;
  return solver.free_stiffness();
}

Eigen::MatrixXd RandomRhs(int n, int m, unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  Eigen::MatrixXd b(n, m);
  for (int j = 0; j < m; ++j)
    for (int i = 0; i < n; ++i) b(i, j) = u(rng);
  return b;
}

bool SameBits(const Eigen::MatrixXd& a, const Eigen::MatrixXd& b) {
  return a.rows() == b.rows() && a.cols() == b.cols() &&
         std::memcmp(a.data(), b.data(), sizeof(double) * a.size()) == 0;
}

std::vector<char> Flat(const CholeskyFactor& f) {
  std::vector<char> bytes(f.FlatBytes());
  f.WriteFlat(bytes.data());
  return bytes;
}

TEST(CholeskyFactor, FlatFormSolvesBitForBitAsTheOriginal) {
  for (int order : {1, 2}) {
    const SparseMatrixd a = BoxStiffness(4, order);
    const int n = static_cast<int>(a.rows());
    CholeskyFactor original;
    ASSERT_TRUE(original.Compute(a));
    EXPECT_EQ(original.size(), n);
    EXPECT_EQ(original.failed_column(), -1);
    EXPECT_GT(original.nonzeros(), a.nonZeros() / 2);
    const std::vector<char> bytes = Flat(original);
    // Misaligned on purpose: the reader must not assume the block's alignment.
    std::vector<char> shifted(bytes.size() + 1);
    std::memcpy(shifted.data() + 1, bytes.data(), bytes.size());
    const std::unique_ptr<CholeskyFactor> copy =
        CholeskyFactor::ReadFlat(shifted.data() + 1, bytes.size(), n);
    ASSERT_TRUE(copy != nullptr);
    ASSERT_TRUE(copy->ok());
    EXPECT_EQ(copy->nonzeros(), original.nonzeros());
    EXPECT_EQ(copy->peak_bytes(), original.peak_bytes());
    // The copy writes the same block again.
    EXPECT_TRUE(Flat(*copy) == bytes);
    const Eigen::MatrixXd b = RandomRhs(n, 7, 11u + order);
    const Eigen::MatrixXd x = original.Solve(b);
    EXPECT_TRUE(SameBits(copy->Solve(b), x)) << "order " << order;
    // And the solve is one of A (an independent check of what was compared).
    const double residual = (a.selfadjointView<Eigen::Lower>() * x - b).norm() / b.norm();
    EXPECT_LT(residual, 1e-9) << "order " << order;
  }
}

TEST(CholeskyFactor, ReadFlatRefusesABadBlockWithAReason) {
  const SparseMatrixd a = BoxStiffness(2, 1);
  const int n = static_cast<int>(a.rows());
  CholeskyFactor f;
  ASSERT_TRUE(f.Compute(a));
  const std::vector<char> good = Flat(f);
  const auto message = [&](const std::vector<char>& block, int size) -> std::string {
    try {
      CholeskyFactor::ReadFlat(block.data(), block.size(), size);
    } catch (const std::invalid_argument& e) {
      return e.what();
    }
    return "";
  };
  EXPECT_EQ(message(good, n), "");
  EXPECT_NE(message(good, n + 1).find("size"), std::string::npos);
  std::vector<char> cut(good.begin(), good.end() - 8);
  EXPECT_NE(message(cut, n).find("bytes"), std::string::npos);
  std::vector<char> header(good.begin(), good.begin() + 40);
  EXPECT_NE(message(header, n).find("header"), std::string::npos);
  std::vector<char> magic = good;
  magic[0] ^= 1;
  EXPECT_NE(message(magic, n).find("magic"), std::string::npos);
  // Perm's first entry (just after the header) made a repeat of its second.
  std::vector<char> perm = good;
  const std::size_t perm_at = CholeskyFactor::kFlatHeaderWords * 8;
  std::memcpy(perm.data() + perm_at, perm.data() + perm_at + 4, 4);
  EXPECT_NE(message(perm, n).find("permutation"), std::string::npos);
  // Every int32 past the permutation arrays set to n, one at a time (a row index, pointer or
  // supernode out of range): refused or, where that word is not read by a solve, still a
  // factor; never a crash. Bounded to the first 4096 words.
  int refused = 0;
  const std::size_t arrays = perm_at + 4 * static_cast<std::size_t>(n);
  for (std::size_t at = arrays; at + 4 <= good.size() && at < arrays + 4 * 4096; at += 4) {
    std::vector<char> bad = good;
    const std::int32_t big = n;
    std::memcpy(bad.data() + at, &big, 4);
    if (!message(bad, n).empty()) ++refused;
  }
  EXPECT_GT(refused, 100);
}

TEST(CholeskyFactor, NotPositiveDefiniteKeepsItsFailedColumnThroughTheFlatForm) {
  // Diagonal with one negative entry at column 7: the only non-positive pivot there is.
  const int n = 20;
  SparseMatrixd a(n, n);
  for (int i = 0; i < n; ++i) a.insert(i, i) = i == 7 ? -1.0 : 1.0 + i;
  a.makeCompressed();
  CholeskyFactor f;
  EXPECT_FALSE(f.Compute(a));
  EXPECT_EQ(f.failed_column(), 7);
  const std::vector<char> bytes = Flat(f);
  EXPECT_EQ(bytes.size(), CholeskyFactor::kFlatHeaderWords * 8);
  const std::unique_ptr<CholeskyFactor> copy =
      CholeskyFactor::ReadFlat(bytes.data(), bytes.size(), n);
  ASSERT_TRUE(copy != nullptr);
  EXPECT_FALSE(copy->ok());
  EXPECT_EQ(copy->failed_column(), 7);
  EXPECT_THROW(copy->Solve(Eigen::MatrixXd::Ones(n, 1)), std::logic_error);
}

TEST(CholeskyFactor, ReadFlatStopsWhenCancelled) {
  const SparseMatrixd a = BoxStiffness(2, 1);
  CholeskyFactor f;
  ASSERT_TRUE(f.Compute(a));
  const std::vector<char> bytes = Flat(f);
  const std::atomic<bool> cancel{true};
  EXPECT_EQ(CholeskyFactor::ReadFlat(bytes.data(), bytes.size(), f.size(), &cancel), nullptr);
  EXPECT_THROW(CholeskyFactor().WriteFlat(nullptr), std::logic_error);
}

TEST(CholeskyFactor, StaticSolverWithAFactorizerSolvesBitForBit) {
  BoundaryConditions bcs(0);
  TetMesh mesh;
  BoxStiffness(3, 2, &bcs, &mesh);
  const MaterialTable materials(Material{70e9, 0.33});
  const StaticSolver here(mesh, materials, bcs);
  int calls = 0;
  // The flat form's round trip, as the window's child process does it.
  const StaticSolver::Factorizer through_flat = [&calls](const SparseMatrixd& k_ff) {
    ++calls;
    CholeskyFactor f;
    f.Compute(k_ff);
    const std::vector<char> bytes = Flat(f);
    return CholeskyFactor::ReadFlat(bytes.data(), bytes.size(), static_cast<int>(k_ff.rows()));
  };
  const StaticSolver there(mesh, materials, bcs, through_flat);
  EXPECT_EQ(calls, 1);
  ASSERT_TRUE(there.factor_status().converged);
  const StaticSolution a = here.Solve(), b = there.Solve();
  EXPECT_TRUE(SameBits(a.displacement, b.displacement));
  EXPECT_TRUE(SameBits(a.reaction, b.reaction));
  EXPECT_EQ(here.stats().factor_nonzeros, there.stats().factor_nonzeros);
  Eigen::MatrixXd xa, xb;
  const Eigen::MatrixXd rhs = RandomRhs(here.num_free(), 5, 3u);
  here.SolveFree(rhs, &xa);
  there.SolveFree(rhs, &xb);
  EXPECT_TRUE(SameBits(xa, xb));
  // A factorizer that gives nothing, or the wrong size, is an error, not a crash.
  EXPECT_THROW(StaticSolver(mesh, materials, bcs,
                            [](const SparseMatrixd&) { return std::unique_ptr<CholeskyFactor>(); }),
               std::runtime_error);
  EXPECT_THROW(
      StaticSolver(mesh, materials, bcs,
                   [](const SparseMatrixd&) { return std::make_unique<CholeskyFactor>(); }),
      std::runtime_error);
}

}  // namespace
}  // namespace spidarcad::fem
