#include "moslam/solver/block_sparse_system.h"

#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <random>

#include "moslam/common/errors.h"

namespace moslam {
namespace {

// Assembles a random SPD block system through the slot API and compares with a dense solve.
TEST(BlockSparseSystem, MatchesDenseSolve) {
  const int nb = 7, bs = 3;
  const std::vector<std::pair<int, int>> pairs{{0, 1}, {2, 1}, {3, 5}, {6, 0}, {4, 6}, {1, 2}};
  BlockSparseSystem sys(nb, bs, pairs);
  Eigen::MatrixXd dense = Eigen::MatrixXd::Zero(nb * bs, nb * bs);
  std::mt19937 rng(3);
  std::normal_distribution<double> n01;
  auto random_block = [&] {
    Eigen::MatrixXd M(bs, bs);
    for (int i = 0; i < bs * bs; ++i) M(i) = n01(rng);
    return M;
  };
  for (const auto& [i, j] : pairs) {
    const Eigen::MatrixXd M = random_block();
    sys.add(sys.slot(i, j), M);
    dense.block(i * bs, j * bs, bs, bs) += M;
    dense.block(j * bs, i * bs, bs, bs) += M.transpose();
  }
  for (int k = 0; k < nb; ++k) {
    const Eigen::MatrixXd A = random_block();
    const Eigen::MatrixXd D = A * A.transpose() + 20.0 * Eigen::MatrixXd::Identity(bs, bs);
    sys.addDiagonal(k, D);
    dense.block(k * bs, k * bs, bs, bs) += D;
  }
  for (int k = 0; k < nb * bs; ++k) sys.rhs()(k) = n01(rng);
  const Eigen::VectorXd expected = dense.ldlt().solve(sys.rhs());
  EXPECT_LT((sys.solve() - expected).norm(), 1e-10);
  EXPECT_LT((sys.multiply(expected) - dense * expected).norm(), 1e-10);
  EXPECT_LT((sys.diagonal() - dense.diagonal()).norm(), 1e-12);

  // Damping is applied for one factorization only.
  const Eigen::VectorXd damping = Eigen::VectorXd::Constant(nb * bs, 2.5);
  const Eigen::MatrixXd damped = dense + Eigen::MatrixXd(damping.asDiagonal());
  EXPECT_LT((sys.solve(damping) - damped.ldlt().solve(sys.rhs())).norm(), 1e-10);
  EXPECT_LT((sys.solve() - expected).norm(), 1e-10);

  // Several right-hand sides with one factorization; reassembly after setZero.
  Eigen::MatrixXd B = Eigen::MatrixXd::Random(nb * bs, 3);
  sys.factorize();
  EXPECT_LT((sys.backSolve(B) - dense.ldlt().solve(B)).norm(), 1e-10);
  sys.setZero();
  EXPECT_EQ(sys.diagonal().norm(), 0.0);
}

TEST(BlockSparseSystem, SingularSystemThrowsNumericalError) {
  BlockSparseSystem sys(2, 2, {{0, 1}});
  sys.addDiagonal(0, Eigen::Matrix2d::Identity());  // block 1 stays zero: singular
  sys.rhs().setOnes();
  EXPECT_THROW(sys.solve(), NumericalError);
  EXPECT_THROW(sys.slot(1, 5), std::out_of_range);  // not in the pattern
}

}  // namespace
}  // namespace moslam
