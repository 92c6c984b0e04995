#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <cmath>
#include <random>

#include "moslam/common/errors.h"
#include "moslam/common/throws_naming_testing.h"
#include "moslam/distributed/centralized_two_stage.h"
#include "moslam/distributed/two_stage_terms.h"
#include "moslam/graph/synthetic.h"
#include "moslam/solver/initialization.h"

namespace moslam {
namespace {

Matrix3 RandomRotation(std::mt19937& rng) {
  std::normal_distribution<double> n01;
  return SO3::Exp(Vector3(n01(rng), n01(rng), n01(rng))).matrix();
}

Matrix6 RandomInformation(std::mt19937& rng) {
  std::normal_distribution<double> n01;
  Matrix6 L = Matrix6::Zero();
  for (int i = 0; i < 6; ++i) {
    for (int j = 0; j <= i; ++j) L(i, j) = n01(rng);
    L(i, i) = 1.0 + std::abs(L(i, i));
  }
  return L * L.transpose();
}

// The exact 12-D stage-2 residual at R = R_hat Exp(dtheta), t = dt.
Eigen::VectorXd ExactPoseResidual(const RelativePoseFactor& f, const Matrix3& Ra_hat,
                                  const Matrix3& Rb_hat, const Vector6& da, const Vector6& db) {
  const Matrix3 Ra = Ra_hat * SO3::Exp(da.head<3>()).matrix();
  const Matrix3 Rb = Rb_hat * SO3::Exp(db.head<3>()).matrix();
  const Matrix3 E = Ra * f.measured().rotation().matrix() - Rb;
  Eigen::VectorXd r(12);
  for (int k = 0; k < 3; ++k) r.segment<3>(3 * k) = E.row(k).transpose();
  r.tail<3>() = db.tail<3>() - da.tail<3>() - Ra * f.measured().translation();
  return r;
}

TEST(TwoStageTerms, PoseTermIsTheLinearisationOfTheChordalResidual) {
  std::mt19937 rng(7);
  std::normal_distribution<double> n01;
  for (int trial = 0; trial < 5; ++trial) {
    const SE3 z(SO3(RandomRotation(rng)), Vector3(n01(rng), n01(rng), n01(rng)));
    const RelativePoseFactor f(Key::Pose(0, 1), Key::Pose(1, 2), z, Matrix6::Identity());
    const Matrix3 Ra = RandomRotation(rng), Rb = RandomRotation(rng);
    const LinearTerm t = PoseTerm(f, Ra, Rb, false);
    const Vector6 zero = Vector6::Zero();
    EXPECT_LT((t.C - ExactPoseResidual(f, Ra, Rb, zero, zero)).norm(), 1e-14);
    const double h = 1e-6;
    for (int j = 0; j < 6; ++j) {
      Vector6 e = Vector6::Zero();
      e(j) = h;
      const Eigen::VectorXd dA =
          (ExactPoseResidual(f, Ra, Rb, e, zero) - ExactPoseResidual(f, Ra, Rb, -e, zero)) /
          (2 * h);
      const Eigen::VectorXd dB =
          (ExactPoseResidual(f, Ra, Rb, zero, e) - ExactPoseResidual(f, Ra, Rb, zero, -e)) /
          (2 * h);
      EXPECT_LT((dA - t.A_a.col(j)).norm(), 1e-8) << "a column " << j;
      EXPECT_LT((dB - t.A_b.col(j)).norm(), 1e-8) << "b column " << j;
    }
    EXPECT_TRUE(t.W.isApprox(Eigen::MatrixXd::Identity(12, 12)));
  }
}

TEST(TwoStageTerms, PosePriorIsTheLinearisationOfItsResidual) {
  std::mt19937 rng(8);
  std::normal_distribution<double> n01;
  const SE3 z(SO3(RandomRotation(rng)), Vector3(n01(rng), n01(rng), n01(rng)));
  const Matrix6 info = RandomInformation(rng);
  const PriorFactor p(Key::Pose(0, 1), z, info);
  const Matrix3 R_hat = RandomRotation(rng);
  auto exact = [&](const Vector6& d) {
    const Matrix3 E = R_hat * SO3::Exp(d.head<3>()).matrix() - z.rotation().matrix();
    Eigen::VectorXd r(12);
    for (int k = 0; k < 3; ++k) r.segment<3>(3 * k) = E.row(k).transpose();
    r.tail<3>() = d.tail<3>() - z.translation();
    return r;
  };
  const LinearTerm t = PosePriorTerm(p, R_hat, true);
  EXPECT_LT((t.C - exact(Vector6::Zero())).norm(), 1e-14);
  for (int j = 0; j < 6; ++j) {
    Vector6 e = Vector6::Zero();
    e(j) = 1e-6;
    EXPECT_LT(((exact(e) - exact(-e)) / 2e-6 - t.A_a.col(j)).norm(), 1e-8);
  }
  // Weighted: trace/3 on the rotation rows, the translation information in the world frame.
  const double rotation_weight = info.topLeftCorner<3, 3>().trace() / 3;
  EXPECT_NEAR(t.W(0, 0), rotation_weight, 1e-12);
  EXPECT_LT((t.W.bottomRightCorner(3, 3) -
             R_hat * info.bottomRightCorner<3, 3>() * R_hat.transpose())
                .norm(),
            1e-12);
}

TEST(TwoStageTerms, RotationTermIsTheTransposedChordalResidual) {
  std::mt19937 rng(9);
  const SE3 z(SO3(RandomRotation(rng)), Vector3::Zero());
  const RelativePoseFactor f(Key::Pose(0, 1), Key::Pose(0, 2), z, Matrix6::Identity());
  const LinearTerm t = RotationTerm(f, false);
  const Matrix3 Ra = RandomRotation(rng), Rb = RandomRotation(rng);
  const Eigen::MatrixXd E =
      t.A_a * RotationUnknown(Ra) + t.A_b * RotationUnknown(Rb) + t.C;
  EXPECT_LT((E - (Ra * z.rotation().matrix() - Rb).transpose()).norm(), 1e-14);
  // r (row by row) is the column-major flattening of X = R^T.
  const Eigen::Matrix3d X = RotationUnknown(Ra);
  EXPECT_TRUE(RowMajor(Ra).isApprox(Eigen::Map<const Eigen::VectorXd>(X.data(), 9)));
  EXPECT_TRUE(FromRowMajor(RowMajor(Ra)).isApprox(Ra));
}

TEST(TwoStageTerms, ProjectionIsTheNearestRotation) {
  std::mt19937 rng(10);
  const Matrix3 R = RandomRotation(rng);
  Matrix3 noisy = 1.7 * R;
  noisy(0, 1) += 0.05;
  const Matrix3 P = ProjectToRotation(RowMajor(noisy));
  EXPECT_NEAR(P.determinant(), 1.0, 1e-12);
  EXPECT_LT((P * P.transpose() - Matrix3::Identity()).norm(), 1e-12);
  EXPECT_LT((P - R).norm(), 0.05);
  // A reflection projects to a proper rotation (det +1).
  EXPECT_NEAR(ProjectToRotation(RowMajor(-R)).determinant(), 1.0, 1e-12);
}

SyntheticGraph Synthetic(int robots, double sigma, unsigned seed) {
  SyntheticGraphOptions o;
  o.num_robots = robots;
  o.poses_per_robot = 15;
  o.sigma_rotation = sigma;
  o.sigma_translation = sigma;
  o.seed = seed;
  return MakeSyntheticGraph(o);
}

TEST(CentralizedTwoStage, RecoversNoiseFreeGroundTruthExactly) {
  const SyntheticGraph s = Synthetic(3, 0.0, 3);
  // Only the anchor's initial value matters; the others start far away.
  Values initial;
  const Key anchor = GaugeAnchor(s.graph);
  initial[anchor] = s.ground_truth.at(anchor);
  const TwoStageResult r = CentralizedTwoStage(s.graph, initial);
  ASSERT_EQ(r.values.size(), s.ground_truth.size());
  for (const auto& [k, x] : s.ground_truth) {
    const SE3& e = r.values.at(k);
    EXPECT_LT((e.translation() - x.translation()).norm(), 1e-9) << ToString(k);
    EXPECT_LT((e.rotation().matrix() - x.rotation().matrix()).norm(), 1e-9) << ToString(k);
  }
  // The anchor is exactly its initial value.
  EXPECT_EQ(r.values.at(anchor).translation(), s.ground_truth.at(anchor).translation());
  EXPECT_EQ(r.values.at(anchor).rotation().matrix(), s.ground_truth.at(anchor).rotation().matrix());
}

TEST(CentralizedTwoStage, StageOneMatchesTheChordalInitialisation) {
  const SyntheticGraph s = Synthetic(2, 0.1, 4);
  const Key anchor = GaugeAnchor(s.graph);
  Values initial{{anchor, s.ground_truth.at(anchor)}};
  const TwoStageResult r = CentralizedTwoStage(s.graph, initial);
  ChordalOptions chordal;
  chordal.weight_by_information = false;
  const auto rotations = ChordalRotations(s.graph, s.ground_truth.at(anchor).rotation(), chordal);
  ASSERT_EQ(rotations.size(), r.rotations.size());
  for (const auto& [k, R] : rotations) {
    EXPECT_LT((R.matrix() - r.rotations.at(k)).norm(), 1e-10) << ToString(k);
  }
}

// The stage-2 estimate zeroes the gradient of its linear least-squares cost (computed here term
// by term, independently of the sparse assembly).
void ExpectStageTwoOptimal(const PoseGraph& graph, const TwoStageResult& r, bool weighted) {
  const Key anchor = GaugeAnchor(graph);
  std::map<Key, Eigen::VectorXd> delta, gradient;
  for (const auto& [k, x] : r.values) {
    Eigen::VectorXd d(6);
    d.head<3>() = SO3::Log(SO3(r.rotations.at(k).transpose() * x.rotation().matrix()));
    d.tail<3>() = x.translation();
    delta[k] = d;
    gradient[k] = Eigen::VectorXd::Zero(6);
  }
  double scale = 0.0;
  for (const RelativePoseFactor& f : graph.factors()) {
    const LinearTerm t = PoseTerm(f, r.rotations.at(f.a()), r.rotations.at(f.b()), weighted);
    const Eigen::VectorXd E = t.A_a * delta[f.a()] + t.A_b * delta[f.b()] + t.C;
    gradient[f.a()] += t.A_a.transpose() * t.W * E;
    gradient[f.b()] += t.A_b.transpose() * t.W * E;
    scale = std::max(scale, (t.A_a.transpose() * t.W * t.C).norm());
  }
  ASSERT_GT(scale, 1e-3);
  for (const auto& [k, g] : gradient) {
    if (k == anchor) continue;
    EXPECT_LT(g.norm(), 1e-9 * scale) << ToString(k);
  }
}

TEST(CentralizedTwoStage, StageTwoSolvesItsLeastSquaresProblem) {
  const SyntheticGraph s = Synthetic(3, 0.05, 5);
  const TwoStageResult r = CentralizedTwoStage(s.graph, s.ground_truth);
  ExpectStageTwoOptimal(s.graph, r, false);
  TwoStageOptions weighted;
  weighted.weight_by_information = true;
  const TwoStageResult rw = CentralizedTwoStage(s.graph, s.ground_truth, weighted);
  ExpectStageTwoOptimal(s.graph, rw, true);
}

TEST(CentralizedTwoStage, RejectsDisconnectedGraphs) {
  PoseGraph g;
  g.add(RelativePoseFactor(Key::Pose(0, 0), Key::Pose(0, 1), SE3(), Matrix6::Identity()));
  g.add(RelativePoseFactor(Key::Pose(1, 0), Key::Pose(1, 1), SE3(), Matrix6::Identity()));
  EXPECT_THROW(CentralizedTwoStage(g, {}), UnderdeterminedError);
}

// BlockLeastSquares against the stacked problem solved directly: a chain of n unknowns of
// block size bs with binary terms between neighbours, a unary term on each, and a term to a
// fixed variable (its value given); min sum ||A_a x_a + A_b x_b + C||_W^2 is
// x = -(J^T W J)^-1 J^T W c. Small systems take the dense path, larger ones CHOLMOD's.
TEST(BlockLeastSquares, SolvesTheStackedLeastSquaresOnTheDenseAndTheSparsePath) {
  std::mt19937 rng(7);
  std::normal_distribution<double> n01;
  auto random = [&](int rows, int cols) {
    Eigen::MatrixXd M(rows, cols);
    for (Eigen::Index i = 0; i < M.size(); ++i) M.data()[i] = n01(rng);
    return M;
  };
  for (const int n : {4, 20}) {  // 4 x 6 = 24 unknowns (dense), 20 x 6 = 120 (sparse)
    SCOPED_TRACE(n);
    const int bs = 6, ncols = 2, m = 6;
    std::vector<Key> unknowns;
    std::vector<std::pair<Key, Key>> coupled;
    for (int i = 0; i < n; ++i) unknowns.push_back(Key::Pose(1, static_cast<std::uint64_t>(i)));
    for (int i = 0; i + 1 < n; ++i) coupled.emplace_back(unknowns[i], unknowns[i + 1]);
    const Key fixed = Key::Pose(0, 0);
    const Eigen::MatrixXd x_fixed = random(bs, ncols);
    std::vector<LinearTerm> terms;
    auto term = [&](Key a, Key b, bool unary) {
      LinearTerm t;
      t.a = a;
      t.b = b;
      t.unary = unary;
      t.A_a = random(m, bs);
      if (!unary) t.A_b = random(m, bs);
      t.C = random(m, ncols);
      const Eigen::MatrixXd L = random(m, m);
      t.W = L * L.transpose() + Eigen::MatrixXd::Identity(m, m);
      terms.push_back(t);
    };
    for (int i = 0; i < n; ++i) term(unknowns[i], Key(), true);
    for (int i = 0; i + 1 < n; ++i) term(unknowns[i], unknowns[i + 1], false);
    term(fixed, unknowns[n / 2], false);

    BlockLeastSquares ls(unknowns, bs, ncols, coupled);
    ls.setZero();
    for (const LinearTerm& t : terms) ls.add(t, &x_fixed, &x_fixed);
    const std::vector<Eigen::MatrixXd> x = ls.solve();

    // The same problem stacked: J x + c with the fixed end's A x_fixed moved into c.
    const int rows = static_cast<int>(terms.size()) * m, dim = n * bs;
    Eigen::MatrixXd J = Eigen::MatrixXd::Zero(rows, dim), c(rows, ncols);
    Eigen::MatrixXd W = Eigen::MatrixXd::Zero(rows, rows);
    for (std::size_t k = 0; k < terms.size(); ++k) {
      const LinearTerm& t = terms[k];
      const int r = static_cast<int>(k) * m;
      c.middleRows(r, m) = t.C;
      W.block(r, r, m, m) = t.W;
      auto place = [&](const Key& key, const Eigen::MatrixXd& A) {
        if (key == fixed) {
          c.middleRows(r, m) += A * x_fixed;
        } else {
          J.block(r, static_cast<int>(key.index) * bs, m, bs) = A;
        }
      };
      place(t.a, t.A_a);
      if (!t.unary) place(t.b, t.A_b);
    }
    const Eigen::MatrixXd H = J.transpose() * W * J;
    const Eigen::MatrixXd expected = -H.ldlt().solve(J.transpose() * W * c);
    ASSERT_EQ(x.size(), static_cast<std::size_t>(n));
    for (int i = 0; i < n; ++i) {
      EXPECT_LT((x[i] - expected.middleRows(i * bs, bs)).norm(), 1e-9 * (1.0 + expected.norm()))
          << i;
    }
    EXPECT_LT((ls.rhs() + J.transpose() * W * c).norm(), 1e-9 * (1.0 + ls.rhs().norm()));
    const Eigen::VectorXd v = random(dim, 1);
    EXPECT_LT((ls.multiply(v) - H * v).norm(), 1e-9 * (H * v).norm());
    EXPECT_EQ(ls.row(unknowns[3]), 3 * bs);
    // backSolve with one factorization for another right-hand side.
    ls.factorize();
    const std::vector<Eigen::MatrixXd> y = ls.backSolve(H * expected);
    for (int i = 0; i < n; ++i) {
      EXPECT_LT((y[i] - expected.middleRows(i * bs, bs)).norm(), 1e-8 * (1.0 + expected.norm()));
    }

    // Refusals, named: a vector of the wrong size, a key that is not an unknown, a fixed end
    // without its value, an unknown listed twice.
    EXPECT_TRUE(test::ThrowsNaming(
        [&] { ls.multiply(Eigen::VectorXd::Zero(dim + 1)); },
        "vector of size " + std::to_string(dim + 1) + ", expected " + std::to_string(dim)));
    EXPECT_TRUE(test::ThrowsNaming([&] { ls.row(fixed); }, "is not an unknown"));
    EXPECT_TRUE(test::ThrowsNaming([&] { ls.add(terms.back(), nullptr, nullptr); },
                                   "no value for the fixed variable"));
    std::vector<Key> twice = unknowns;
    twice.push_back(unknowns[1]);
    EXPECT_TRUE(test::ThrowsNaming(
        [&] { BlockLeastSquares listed_twice(twice, bs, ncols, coupled); }, "listed twice"));
  }
  // An unknown no term anchors: the normal matrix is singular, NumericalError saying so.
  BlockLeastSquares lonely({Key::Pose(1, 0), Key::Pose(1, 1)}, 3, 1, {});
  LinearTerm t;
  t.a = Key::Pose(1, 0);
  t.unary = true;
  t.A_a = Eigen::MatrixXd::Identity(3, 3);
  t.C = Eigen::MatrixXd::Ones(3, 1);
  t.W = Eigen::MatrixXd::Identity(3, 3);
  lonely.add(t, nullptr, nullptr);
  EXPECT_TRUE(
      test::ThrowsNaming<NumericalError>([&] { lonely.solve(); }, "not anchored by any term"));
}

}  // namespace
}  // namespace moslam
