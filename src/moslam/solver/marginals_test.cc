#include "moslam/solver/marginals.h"

#include <gtest/gtest.h>

#include <Eigen/LU>

#include <random>

#include "moslam/common/errors.h"
#include "moslam/solver/optimizer.h"

namespace moslam {
namespace {

Matrix6 RandomInformation(std::mt19937& rng) {
  std::normal_distribution<double> n01;
  Matrix6 M;
  for (int i = 0; i < 6; ++i)
    for (int j = 0; j < 6; ++j) M(i, j) = n01(rng);
  return M * M.transpose() + 2.0 * Matrix6::Identity();
}

SE3 RandomPose(std::mt19937& rng, double angle) {
  std::normal_distribution<double> n01;
  Vector6 xi;
  for (int i = 0; i < 6; ++i) xi[i] = n01(rng);
  xi.head<3>() *= angle / xi.head<3>().norm();
  return SE3::Exp(xi);
}

// Noise-free chain x0 -> x1 -> x2: x2 = x1 z2, so x2's perturbation is Ad(z2^-1) d1 + d2.
TEST(Marginals, ChainMatchesClosedForm) {
  std::mt19937 rng(3);
  const Key k0 = Key::Pose(0, 0), k1 = Key::Pose(0, 1), k2 = Key::Pose(0, 2);
  const SE3 z1 = RandomPose(rng, 0.7), z2 = RandomPose(rng, 2.9);  // near pi too
  const Matrix6 O1 = RandomInformation(rng), O2 = RandomInformation(rng);
  PoseGraph g;
  g.add(RelativePoseFactor(k0, k1, z1, O1));
  g.add(RelativePoseFactor(k1, k2, z2, O2));
  Values v{{k0, SE3()}, {k1, z1}, {k2, z1 * z2}};
  const Marginals m(g, v);
  const Eigen::MatrixXd S = m.jointCovariance({k1, k2, k0});
  const Matrix6 S1 = O1.inverse(), Ad = z2.inverse().Adjoint();
  const Matrix6 S22 = Ad * S1 * Ad.transpose() + O2.inverse();
  EXPECT_LT((S.block<6, 6>(0, 0) - S1).norm(), 1e-9 * S1.norm());
  EXPECT_LT((S.block<6, 6>(6, 6) - S22).norm(), 1e-9 * S22.norm());
  EXPECT_LT((S.block<6, 6>(0, 6) - S1 * Ad.transpose()).norm(), 1e-9 * S22.norm());
  EXPECT_LT((S.block<6, 6>(6, 0) - Ad * S1).norm(), 1e-9 * S22.norm());
  EXPECT_EQ((S.block<6, 18>(12, 0).norm()), 0.0);  // the anchor: fixed
  EXPECT_LT((m.covariance(k2) - S22).norm(), 1e-9 * S22.norm());
}

// With a loop closure and residuals not zero: the inverse of J^T J from numerical Jacobians.
TEST(Marginals, LoopMatchesNumericalHessian) {
  std::mt19937 rng(5);
  const int n = 5;
  PoseGraph g;
  Values truth, v;
  SE3 x;
  for (int i = 0; i < n; ++i) {
    truth[Key::Pose(0, static_cast<std::uint64_t>(i))] = x;
    x = x * RandomPose(rng, 0.5);
  }
  auto key = [](int i) { return Key::Pose(0, static_cast<std::uint64_t>(i)); };
  auto noisy = [&](const SE3& z) { return z * RandomPose(rng, 0.05); };
  for (int i = 0; i + 1 < n; ++i) {
    g.add(RelativePoseFactor(key(i), key(i + 1), noisy(truth[key(i)].between(truth[key(i + 1)])),
                             RandomInformation(rng)));
  }
  g.add(RelativePoseFactor(key(0), key(n - 1), noisy(truth[key(0)].between(truth[key(n - 1)])),
                           RandomInformation(rng)));
  g.add(PriorFactor(key(2), noisy(truth[key(2)]), RandomInformation(rng)));
  v = Optimize(g, truth).values;
  // Dense J (whitened) by central differences over the free variables 1..n-1.
  const int rows = 6 * static_cast<int>(g.factors().size() + g.priors().size());
  Eigen::MatrixXd J = Eigen::MatrixXd::Zero(rows, 6 * (n - 1));
  auto whitened = [&](const Values& at) {
    Eigen::VectorXd r(rows);
    int row = 0;
    for (const auto& f : g.factors()) {
      r.segment<6>(row) = f.sqrtInformation() * f.residual(at.at(f.a()), at.at(f.b()));
      row += 6;
    }
    for (const auto& p : g.priors()) {
      r.segment<6>(row) = p.sqrtInformation() * p.residual(at.at(p.key()));
      row += 6;
    }
    return r;
  };
  const double h = 1e-6;
  for (int i = 1; i < n; ++i) {
    for (int c = 0; c < 6; ++c) {
      Values plus = v, minus = v;
      Vector6 d = Vector6::Zero();
      d[c] = h;
      plus[key(i)] = v.at(key(i)).retract(d);
      minus[key(i)] = v.at(key(i)).retract(-d);
      J.col(6 * (i - 1) + c) = (whitened(plus) - whitened(minus)) / (2 * h);
    }
  }
  const Eigen::MatrixXd expected = (J.transpose() * J).inverse();
  const Eigen::MatrixXd S = Marginals(g, v).jointCovariance({key(1), key(2), key(3), key(4)});
  EXPECT_LT((S - expected).norm(), 1e-6 * expected.norm());
}

TEST(Marginals, RejectsUnknownAndUnanchoredVariables) {
  PoseGraph g;
  g.add(RelativePoseFactor(Key::Pose(0, 0), Key::Pose(0, 1), SE3(), Matrix6::Identity()));
  Values v{{Key::Pose(0, 0), SE3()}, {Key::Pose(0, 1), SE3()}};
  EXPECT_THROW(Marginals(g, {{Key::Pose(0, 0), SE3()}}), InvalidInputError);
  const Marginals m(g, v);
  EXPECT_THROW(m.jointCovariance({Key::Pose(0, 7)}), InvalidInputError);
  g.add(RelativePoseFactor(Key::Pose(1, 0), Key::Pose(1, 1), SE3(), Matrix6::Identity()));
  v[Key::Pose(1, 0)] = v[Key::Pose(1, 1)] = SE3();
  EXPECT_THROW(Marginals(g, v), UnderdeterminedError);
}

}  // namespace
}  // namespace moslam
