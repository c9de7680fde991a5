// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#include "spidarcad/fem/bordered_cholesky.h"

#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <random>
#include <stdexcept>
#include <vector>

#include "support/malloc_counter.h"

namespace spidarcad::fem {
namespace {

// Random symmetric positive definite n by n matrix with eigenvalues spread log-uniformly over
// [lambda_min, 1]: Q diag(λ) Qᵀ with Q from the QR of a Gaussian matrix.
Eigen::MatrixXd RandomSpd(int n, double lambda_min, std::mt19937* rng) {
  std::normal_distribution<double> normal;
  Eigen::MatrixXd g(n, n);
  for (int i = 0; i < n; ++i)
    for (int j = 0; j < n; ++j) g(i, j) = normal(*rng);
  const Eigen::MatrixXd q = Eigen::HouseholderQR<Eigen::MatrixXd>(g).householderQ();
  Eigen::VectorXd lambda(n);
  for (int i = 0; i < n; ++i)
    lambda(i) = n == 1 ? 1.0 : std::pow(lambda_min, static_cast<double>(i) / (n - 1));
  const Eigen::MatrixXd a = q * lambda.asDiagonal() * q.transpose();
  return 0.5 * (a + a.transpose());
}

// Appends block b of `a` (rows and columns 3b .. 3b+2, against the blocks already in `chol`).
bool Append(const Eigen::MatrixXd& a, int b, BorderedCholesky* chol) {
  const int n = chol->size();
  for (int j = 0; j < 3; ++j)
    for (int c = 0; c < n; ++c) chol->BorderRow(j)[c] = a(3 * b + j, c);
  return chol->AppendBlock(a.block<3, 3>(3 * b, 3 * b));
}

// The dense L Lᵀ of the factor's current size.
Eigen::MatrixXd Product(const BorderedCholesky& chol) {
  const int n = chol.size();
  const Eigen::MatrixXd l = chol.factor().topLeftCorner(n, n).triangularView<Eigen::Lower>();
  return l * l.transpose();
}

// x = A⁻¹ b through the factor.
Eigen::VectorXd SolveWith(const BorderedCholesky& chol, const Eigen::VectorXd& b) {
  Eigen::VectorXd x = b;
  chol.Solve(x.data());
  return x;
}

TEST(BorderedCholesky, MatchesDenseLdltWhenGrownBlockByBlockToSixtyFourBlocks) {
  std::mt19937 rng(7);
  const int k_max = 64;
  const Eigen::MatrixXd a = RandomSpd(3 * k_max, 1e-3, &rng);
  BorderedCholesky chol(k_max);
  std::normal_distribution<double> normal;
  for (int k = 1; k <= k_max; ++k) {
    ASSERT_TRUE(Append(a, k - 1, &chol)) << "k = " << k;
    ASSERT_EQ(chol.num_blocks(), k);
    if (k % 7 != 0 && k != 1 && k != k_max) continue;
    const int n = 3 * k;
    const Eigen::MatrixXd a_k = a.topLeftCorner(n, n);
    EXPECT_LT((Product(chol) - a_k).norm(), 1e-13 * a_k.norm()) << "k = " << k;
    Eigen::VectorXd b(n);
    for (int i = 0; i < n; ++i) b(i) = normal(rng);
    const Eigen::VectorXd x_ref = a_k.ldlt().solve(b);
    EXPECT_LT((SolveWith(chol, b) - x_ref).norm(), 1e-10 * x_ref.norm()) << "k = " << k;
  }
  // Full: one more block is refused.
  EXPECT_FALSE(chol.AppendBlock(Eigen::Matrix3d::Identity()));
  EXPECT_EQ(chol.num_blocks(), k_max);
}

TEST(BorderedCholesky, RemovedBlockGivesTheFactorOfTheMatrixWithoutItsRowsAndColumns) {
  std::mt19937 rng(11);
  const int k = 12;
  const Eigen::MatrixXd a = RandomSpd(3 * k, 1e-2, &rng);
  BorderedCholesky chol(k);
  for (int b = 0; b < k; ++b) ASSERT_TRUE(Append(a, b, &chol));
  // Remove blocks 4, then 0, then the last: keep the list of the original blocks left.
  std::vector<int> left;
  for (int b = 0; b < k; ++b) left.push_back(b);
  for (const int slot : {4, 0, 9}) {
    chol.RemoveBlock(slot);
    left.erase(left.begin() + slot);
    ASSERT_EQ(chol.num_blocks(), static_cast<int>(left.size()));
    const int n = 3 * static_cast<int>(left.size());
    Eigen::MatrixXd a_left(n, n);
    for (int i = 0; i < static_cast<int>(left.size()); ++i)
      for (int j = 0; j < static_cast<int>(left.size()); ++j)
        a_left.block<3, 3>(3 * i, 3 * j) = a.block<3, 3>(3 * left[i], 3 * left[j]);
    EXPECT_LT((Product(chol) - a_left).norm(), 1e-13 * a_left.norm()) << "slot " << slot;
    const Eigen::VectorXd b = Eigen::VectorXd::LinSpaced(n, -1.0, 2.0);
    const Eigen::VectorXd x_ref = a_left.ldlt().solve(b);
    EXPECT_LT((SolveWith(chol, b) - x_ref).norm(), 1e-10 * x_ref.norm()) << "slot " << slot;
  }
  // Out of range: nothing happens.
  chol.RemoveBlock(-1);
  chol.RemoveBlock(chol.num_blocks());
  EXPECT_EQ(chol.num_blocks(), k - 3);
}

TEST(BorderedCholesky, TruncateThenAppendFactorsTheNewTrailingBlocks) {
  std::mt19937 rng(5);
  const int k = 10;
  const Eigen::MatrixXd a = RandomSpd(3 * k, 1e-2, &rng);
  const Eigen::MatrixXd other = RandomSpd(3 * k, 1e-2, &rng);
  BorderedCholesky chol(k);
  for (int b = 0; b < k; ++b) ASSERT_TRUE(Append(a, b, &chol));
  // Re-border from block 6 on with the trailing rows of a different SPD matrix whose leading
  // block is a's (the matrix [a_66, c; cᵀ, d] with c, d from `other`, made SPD by construction).
  chol.Truncate(6);
  ASSERT_EQ(chol.num_blocks(), 6);
  Eigen::MatrixXd mixed = a;
  const Eigen::MatrixXd s = other.bottomRightCorner(12, 12);
  const Eigen::MatrixXd l6 = a.topLeftCorner(18, 18).llt().matrixL();
  const Eigen::MatrixXd c = 0.3 * l6 * other.topRightCorner(18, 12) / other.norm();
  // Schur complement of the new matrix: s + cᵀ a⁻¹ c − cᵀ a⁻¹ c = s > 0, so it is SPD.
  mixed.topRightCorner(18, 12) = c;
  mixed.bottomLeftCorner(12, 18) = c.transpose();
  mixed.bottomRightCorner(12, 12) = s + c.transpose() * a.topLeftCorner(18, 18).ldlt().solve(c);
  mixed = 0.5 * (mixed + mixed.transpose()).eval();
  for (int b = 6; b < k; ++b) ASSERT_TRUE(Append(mixed, b, &chol)) << b;
  EXPECT_LT((Product(chol) - mixed).norm(), 1e-12 * mixed.norm());
  const Eigen::VectorXd rhs = Eigen::VectorXd::Ones(3 * k);
  const Eigen::VectorXd x_ref = mixed.ldlt().solve(rhs);
  EXPECT_LT((SolveWith(chol, rhs) - x_ref).norm(), 1e-9 * x_ref.norm());
  chol.Truncate(99);  // clamped to k
  EXPECT_EQ(chol.num_blocks(), k);
  chol.Truncate(0);
  EXPECT_EQ(chol.num_blocks(), 0);
}

// Condition number 1e10: the factor still solves to the accuracy the conditioning allows
// (forward error against LDLT below 1e4 · cond · ε) and backward stably (small residual).
TEST(BorderedCholesky, SolvesANearlySingularBlockToItsConditionBound) {
  std::mt19937 rng(3);
  const int k = 16;
  const double lambda_min = 1e-10;
  const Eigen::MatrixXd a = RandomSpd(3 * k, lambda_min, &rng);
  BorderedCholesky chol(k);
  for (int b = 0; b < k; ++b) ASSERT_TRUE(Append(a, b, &chol)) << b;
  std::normal_distribution<double> normal;
  Eigen::VectorXd rhs(3 * k);
  for (int i = 0; i < 3 * k; ++i) rhs(i) = normal(rng);
  const Eigen::VectorXd x = SolveWith(chol, rhs);
  const Eigen::VectorXd x_ref = a.ldlt().solve(rhs);
  const double eps = std::numeric_limits<double>::epsilon();
  EXPECT_LT((x - x_ref).norm(), 1e4 * (1.0 / lambda_min) * eps * x_ref.norm());
  EXPECT_LT((a * x - rhs).norm(), 1e3 * eps * a.norm() * x.norm());
}

// A node that duplicates one already in (same rows of A): D − Y Yᵀ = 0, refused, and the
// factor of the earlier blocks is intact.
TEST(BorderedCholesky, RefusesASingularBlockAndKeepsTheFactor) {
  std::mt19937 rng(9);
  const int k = 5;
  Eigen::MatrixXd a = RandomSpd(3 * (k + 1), 1e-2, &rng);
  // Block k copies block 2 (rows and columns): A is then singular.
  a.middleRows<3>(3 * k) = a.middleRows<3>(6);
  a.middleCols<3>(3 * k) = a.middleCols<3>(6);
  BorderedCholesky chol(k + 1);
  for (int b = 0; b < k; ++b) ASSERT_TRUE(Append(a, b, &chol));
  const Eigen::MatrixXd before = chol.factor().topLeftCorner(3 * k, 3 * k);
  EXPECT_FALSE(Append(a, k, &chol));
  EXPECT_EQ(chol.num_blocks(), k);
  EXPECT_EQ(Eigen::MatrixXd(chol.factor().topLeftCorner(3 * k, 3 * k)), before);
  // A non-positive diagonal block is refused too.
  for (int j = 0; j < 3; ++j)
    for (int c = 0; c < 3 * k; ++c) chol.BorderRow(j)[c] = 0.0;
  EXPECT_FALSE(chol.AppendBlock(-Eigen::Matrix3d::Identity()));
  EXPECT_EQ(chol.num_blocks(), k);
  const Eigen::MatrixXd a_k = a.topLeftCorner(3 * k, 3 * k);
  const Eigen::VectorXd rhs = Eigen::VectorXd::Ones(3 * k);
  EXPECT_LT((SolveWith(chol, rhs) - a_k.ldlt().solve(rhs)).norm(),
            1e-10 * a_k.ldlt().solve(rhs).norm());
}

TEST(BorderedCholesky, AppendRemoveAndSolveAllocateNothing) {
  ASSERT_TRUE(test_support::MallocCounterActive());
  std::mt19937 rng(1);
  const int k = 32;
  const Eigen::MatrixXd a = RandomSpd(3 * k, 1e-3, &rng);
  BorderedCholesky chol(k);
  std::vector<double> x(3 * k, 1.0);
  int ok = 0;
  long allocations = 0;
  {
    test_support::MallocCounter counter;
    for (int round = 0; round < 4; ++round) {
      for (int b = 0; b < k; ++b) ok += Append(a, b, &chol);
      chol.Solve(x.data());
      chol.RemoveBlock(round);
      chol.Solve(x.data());
      chol.Truncate(k / 2);
      chol.Truncate(0);
    }
    allocations = counter.count();
  }
  EXPECT_EQ(allocations, 0);
  EXPECT_EQ(ok, 4 * k);
}

TEST(BorderedCholesky, ThrowsForNoRoom) {
  EXPECT_THROW(BorderedCholesky(0), std::invalid_argument);
}

}  // namespace
}  // namespace spidarcad::fem
