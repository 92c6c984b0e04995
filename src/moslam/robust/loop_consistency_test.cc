#include "moslam/robust/loop_consistency.h"

#include <gtest/gtest.h>

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>
#include <random>
#include <string>

#include "moslam/common/errors.h"
#include "moslam/common/throws_naming_testing.h"
#include "moslam/io/datasets_testing.h"
#include "moslam/io/g2o.h"
#include "moslam/robust/spoil.h"
#include "moslam/robust/spoil_testing.h"
#include "moslam/solver/marginals.h"

namespace moslam {
namespace {

// A random positive definite information matrix.
Matrix6 RandomInformation(std::mt19937& rng) {
  std::normal_distribution<double> n(0.0, 1.0);
  Matrix6 A;
  for (int r = 0; r < 6; ++r) {
    for (int c = 0; c < 6; ++c) A(r, c) = n(rng);
  }
  return A * A.transpose() + 6.0 * Matrix6::Identity();
}

SE3 RandomStep(std::mt19937& rng) {
  std::normal_distribution<double> n(0.0, 1.0);
  return SE3(SO3::Exp(0.3 * Vector3(n(rng), n(rng), n(rng))),
             Vector3(1.0 + n(rng), n(rng), 0.2 * n(rng)));
}

// A robot's odometry of `poses` poses (every third step stored backwards), with random
// informations; its estimate chained from the identity.
PoseGraph Odometry(int poses, std::mt19937& rng, Values* chained) {
  PoseGraph g;
  SE3 x;
  chained->emplace(Key::Pose(0, 0), x);
  for (int k = 0; k + 1 < poses; ++k) {
    const SE3 o = RandomStep(rng);
    const Key a = Key::Pose(0, static_cast<std::uint64_t>(k)), b = Key::Pose(0, k + 1ull);
    if (k % 3 == 2) {
      g.add(RelativePoseFactor(b, a, o.inverse(), RandomInformation(rng)));
    } else {
      g.add(RelativePoseFactor(a, b, o, RandomInformation(rng)));
    }
    x = x * o;
    chained->emplace(b, x);
  }
  return g;
}

// The chain's poses are the odometry chained, and its joint covariances those of the
// odometry-only graph's marginals (its first pose fixed), for poses in either order.
TEST(OdometryChain, JointCovariancesAreTheOdometryGraphsMarginals) {
  std::mt19937 rng(3);
  Values chained;
  const PoseGraph g = Odometry(12, rng, &chained);
  const OdometryChain chain(g, true);
  const Marginals marginals(g, chained);
  for (const auto& [p, q] : {std::pair<int, int>{2, 9}, {9, 2}, {0, 11}, {5, 5}, {7, 8}}) {
    const Key a = Key::Pose(0, static_cast<std::uint64_t>(p));
    const Key b = Key::Pose(0, static_cast<std::uint64_t>(q));
    EXPECT_LT((chain.pose(a).matrix() - chained.at(a).matrix()).norm(), 1e-12);
    const Eigen::MatrixXd expected = marginals.jointCovariance({a, b});
    EXPECT_LT((chain.joint(a, b) - expected).norm(), 1e-9 * expected.norm()) << p << ", " << q;
  }
  EXPECT_EQ(OdometryChain(g, false).joint(Key::Pose(0, 2), Key::Pose(0, 9)), Matrix12::Zero());
}

// A pose whose odometry factor is missing starts a new stretch: poses on two stretches have no
// joint covariance; a graph of two robots, or a key not in it, is refused.
TEST(OdometryChain, AGapStartsAStretchAndBadKeysAreRefused) {
  std::mt19937 rng(4);
  Values chained;
  PoseGraph g = Odometry(5, rng, &chained);
  g.add(RelativePoseFactor(Key::Pose(0, 6), Key::Pose(0, 7), RandomStep(rng), Matrix6::Identity()));
  const OdometryChain chain(g, true);
  EXPECT_EQ(chain.stretch(Key::Pose(0, 4)), 0);
  EXPECT_EQ(chain.stretch(Key::Pose(0, 6)), 1);
  EXPECT_EQ(chain.pose(Key::Pose(0, 6)).matrix(), SE3().matrix());
  EXPECT_TRUE(
      test::ThrowsNaming([&] { chain.joint(Key::Pose(0, 1), Key::Pose(0, 7)); }, "two stretches"));
  EXPECT_TRUE(test::ThrowsNaming([&] { chain.pose(Key::Pose(0, 5)); }, "no pose"));
  EXPECT_FALSE(chain.has(Key::Object(0, 1)));
  EXPECT_FALSE(chain.has(Key::Pose(1, 1)));  // another robot's
  EXPECT_TRUE(test::ThrowsNaming([&] { chain.pose(Key::Pose(1, 1)); }, "no pose"));
  g.add(RelativePoseFactor(Key::Pose(0, 0), Key::Pose(1, 0), SE3(), Matrix6::Identity()));
  EXPECT_TRUE(test::ThrowsNaming([&] { OdometryChain(g, true); }, "more than one robot"));
}

// A factor under test is no odometry: where one comes before the odometry between two poses the
// chain takes the odometry, and where one is the only factor between two poses it leaves a gap.
// Without the flags the chain takes either as odometry; flags of the wrong count are refused.
TEST(OdometryChain, FactorsUnderTestAreNotOdometry) {
  std::mt19937 rng(6);
  Values chained;
  const PoseGraph odometry = Odometry(8, rng, &chained);
  const Key p3 = Key::Pose(0, 3), p5 = Key::Pose(0, 5), p6 = Key::Pose(0, 6);
  PoseGraph g;
  std::vector<bool> under_test;
  g.add(RelativePoseFactor(Key::Pose(0, 2), p3, RandomStep(rng), Matrix6::Identity()));
  under_test.push_back(true);
  for (const RelativePoseFactor& f : odometry.factors()) {
    const bool sole = std::min(f.a().index, f.b().index) == 5;  // the step from p5 to p6
    g.add(sole ? RelativePoseFactor(p5, p6, RandomStep(rng), Matrix6::Identity()) : f);
    under_test.push_back(sole);
  }
  const OdometryChain chain(g, true, under_test);
  EXPECT_LT((chain.pose(p3).matrix() - chained.at(p3).matrix()).norm(), 1e-12);
  EXPECT_EQ(chain.stretch(p5), 0);
  EXPECT_EQ(chain.stretch(p6), 1);
  EXPECT_EQ(chain.pose(p6).matrix(), SE3().matrix());
  const OdometryChain unflagged(g, true);
  EXPECT_GT((unflagged.pose(p3).matrix() - chained.at(p3).matrix()).norm(), 1e-3);
  EXPECT_EQ(unflagged.stretch(p6), 0);
  EXPECT_TRUE(test::ThrowsNaming([&] { OdometryChain(g, true, std::vector<bool>(3, true)); },
                                 "not odometry"));
}

// The loop of two right loop closures is the identity: statistic 0. Moving one loop closure by
// a perturbation of d sigma along its covariance's eigenvector gives d^2 when the maps are exact.
TEST(LoopStatistic, IsZeroForAClosedLoopAndTheMahalanobisDistanceOfAnError) {
  std::mt19937 rng(5);
  const SE3 Ai = RandomStep(rng), Aj = RandomStep(rng), Bi = RandomStep(rng), Bj = RandomStep(rng);
  const Matrix6 info = RandomInformation(rng);
  const Matrix6 sigma = info.inverse();
  LoopEnd i{Ai.inverse() * Bi, sigma, Ai, Bi};
  const LoopEnd j{Aj.inverse() * Bj, Matrix6::Zero(), Aj, Bj};
  EXPECT_LT(LoopStatistic(i, j, Matrix12::Zero(), Matrix12::Zero()), 1e-20);
  const Eigen::SelfAdjointEigenSolver<Matrix6> eigen(sigma);
  const Vector6 d = 3.0 * std::sqrt(eigen.eigenvalues()(2)) * eigen.eigenvectors().col(2);
  i.z = i.z * SE3::Exp(d);
  EXPECT_NEAR(LoopStatistic(i, j, Matrix12::Zero(), Matrix12::Zero()), 9.0, 1e-6);
}

// CSAIL (one robot, 2D) with 30 % wrong loop closures, where GNC alone fails (README,
// scripts/robust-single.sh): at threshold 5 (CSAIL's information is far larger than its noise:
// its optimum costs 20 over 1172 factors) the check through the odometry keeps exactly the right
// loop closures; at the chi-square threshold it rejects no right one and 53 of the 55 wrong ones
// (the two it keeps span long stretches of odometry, whose covariance lets them agree).
TEST(CheckLoopClosuresByOdometry, KeepsExactlyTheRightLoopClosuresOfSpoiledCsail) {
  const auto [data, spoiled] = test::SpoilPgoFile("CSAIL.g2o", 0.3);
  ASSERT_TRUE(data.planar);
  std::vector<bool> robust(spoiled.graph.factors().size(), false);
  for (std::size_t i = 0; i < robust.size(); ++i) {
    const RelativePoseFactor& f = spoiled.graph.factors()[i];
    robust[i] = f.a().index + 1 != f.b().index && f.b().index + 1 != f.a().index;
  }
  OdometryCheckOptions at5;
  at5.threshold = 5.0;
  const OdometryCheckResult r = CheckLoopClosuresByOdometry(spoiled.graph, robust, at5);
  EXPECT_EQ(r.loop_closures, spoiled.separators + spoiled.added);
  EXPECT_EQ(r.rejected, spoiled.added);
  EXPECT_EQ(r.largest, spoiled.separators);
  EXPECT_TRUE(r.exact);
  EXPECT_EQ(r.untestable, 0);
  for (std::size_t i = 0; i < robust.size(); ++i) EXPECT_EQ(r.kept[i], !spoiled.outlier[i]) << i;
  const OdometryCheckResult chi2 = CheckLoopClosuresByOdometry(spoiled.graph, robust);
  int right_rejected = 0;
  for (std::size_t i = 0; i < robust.size(); ++i)
    right_rejected += !chi2.kept[i] && !spoiled.outlier[i];
  EXPECT_EQ(right_rejected, 0);
  EXPECT_EQ(chi2.rejected, 53);

  EXPECT_TRUE(test::ThrowsNaming(
      [&] { CheckLoopClosuresByOdometry(spoiled.graph, std::vector<bool>(3, true)); },
      "robust flags"));
  OdometryCheckOptions bad;
  bad.min_support = 0;
  EXPECT_TRUE(test::ThrowsNaming([&] { CheckLoopClosuresByOdometry(spoiled.graph, robust, bad); },
                                 "min_support"));
}

// Fewer loop closures agreeing than min_support confirm nothing: every one is kept for GNC.
TEST(CheckLoopClosuresByOdometry, TooFewAgreeingLoopClosuresDecideNothing) {
  std::mt19937 rng(6);
  Values chained;
  PoseGraph g = Odometry(10, rng, &chained);
  const auto between = [&](int a, int b) {
    const Key ka = Key::Pose(0, static_cast<std::uint64_t>(a));
    const Key kb = Key::Pose(0, static_cast<std::uint64_t>(b));
    return chained.at(ka).inverse() * chained.at(kb);
  };
  g.add(RelativePoseFactor(Key::Pose(0, 1), Key::Pose(0, 8), between(1, 8), Matrix6::Identity()));
  g.add(RelativePoseFactor(Key::Pose(0, 2), Key::Pose(0, 9), between(2, 9), Matrix6::Identity()));
  std::vector<bool> robust(g.factors().size(), false);
  robust[robust.size() - 1] = robust[robust.size() - 2] = true;
  const OdometryCheckResult r = CheckLoopClosuresByOdometry(g, robust);
  EXPECT_EQ(r.loop_closures, 2);
  EXPECT_EQ(r.largest, 2);
  EXPECT_EQ(r.rejected, 0);
  OdometryCheckOptions two;
  two.min_support = 2;
  // A wrong one, 20 m off: with min_support 2 the two right ones confirm each other.
  g.add(RelativePoseFactor(Key::Pose(0, 0), Key::Pose(0, 5),
                           between(0, 5) * SE3(SO3(), Vector3(20.0, 0.0, 0.0)),
                           Matrix6::Identity()));
  robust.push_back(true);
  const OdometryCheckResult confirmed = CheckLoopClosuresByOdometry(g, robust, two);
  EXPECT_EQ(confirmed.rejected, 1);
  EXPECT_FALSE(confirmed.kept.back());
}

// Each robot checks its own loop closures through its own odometry: robot 1's wrong one is
// rejected, robot 0's right ones kept, and a separator (even a wrong one) is not this check's to
// judge. The result is each robot's own check, put back in the graph's order.
TEST(CheckEachRobotsLoopClosures, EachRobotChecksItsOwnThroughItsOwnOdometry) {
  std::mt19937 rng(9);
  PoseGraph team;
  std::vector<bool> robust;
  PoseGraph robot1;  // robot 1's factors alone, as it holds them
  std::vector<bool> robot1_robust;
  const auto pose = [](int robot, int index) {
    return Key::Pose(robot, static_cast<std::uint64_t>(index));
  };
  for (int robot = 0; robot < 2; ++robot) {
    Values chained;
    const PoseGraph odometry = Odometry(12, rng, &chained);
    std::vector<RelativePoseFactor> own;
    for (const RelativePoseFactor& f : odometry.factors()) {
      own.emplace_back(pose(robot, static_cast<int>(f.a().index)),
                       pose(robot, static_cast<int>(f.b().index)), f.measured(), f.information());
    }
    const auto loop = [&](int a, int b, const SE3& error) {
      const SE3 z = chained.at(pose(0, a)).inverse() * chained.at(pose(0, b)) * error;
      return RelativePoseFactor(pose(robot, a), pose(robot, b), z, Matrix6::Identity());
    };
    const std::size_t odometry_factors = own.size();
    for (const auto& [a, b] : {std::pair{0, 6}, {2, 9}, {4, 11}}) own.push_back(loop(a, b, SE3()));
    if (robot == 1) own.push_back(loop(1, 7, SE3(SO3(), Vector3(20.0, 0.0, 0.0))));
    for (std::size_t i = 0; i < own.size(); ++i) {
      team.add(own[i]);
      robust.push_back(i >= odometry_factors);
      if (robot == 1) {
        robot1.add(own[i]);
        robot1_robust.push_back(i >= odometry_factors);
      }
    }
  }
  // A wrong separator: kept here.
  team.add(RelativePoseFactor(pose(0, 3), pose(1, 4), SE3(SO3(), Vector3(50.0, 0.0, 0.0)),
                              Matrix6::Identity()));
  robust.push_back(true);

  const OdometryCheckResult r = CheckEachRobotsLoopClosures(team, robust);
  EXPECT_EQ(r.loop_closures, 7);
  EXPECT_EQ(r.rejected, 1);
  EXPECT_EQ(r.largest, 3);
  EXPECT_TRUE(r.exact);
  EXPECT_EQ(r.pairs, 3 + 6);
  const OdometryCheckResult alone = CheckLoopClosuresByOdometry(robot1, robot1_robust);
  ASSERT_EQ(alone.rejected, 1);
  const std::size_t robot0_factors = team.factors().size() - robot1.factors().size() - 1;
  for (std::size_t i = 0; i < team.factors().size(); ++i) {
    const bool expected =
        i < robot0_factors || i + 1 == team.factors().size() || alone.kept[i - robot0_factors];
    EXPECT_EQ(r.kept[i], expected) << i;
  }
  EXPECT_FALSE(r.kept[team.factors().size() - 2]);  // robot 1's wrong loop closure

  // Robot 1's four with a larger min_support: none confirmed, and none rejected (GNC decides).
  OdometryCheckOptions strict;
  strict.min_support = 4;
  const OdometryCheckResult undecided = CheckLoopClosuresByOdometry(robot1, robot1_robust, strict);
  EXPECT_EQ(undecided.rejected, 0);
  EXPECT_EQ(undecided.largest, 3);
  for (std::size_t i = 0; i < robot1_robust.size(); ++i) {
    EXPECT_TRUE(undecided.kept[i]) << i;
  }

  // No loop closure of a robot's own: nothing checked.
  std::vector<bool> separators_only(robust.size(), false);
  separators_only.back() = true;
  const OdometryCheckResult none = CheckEachRobotsLoopClosures(team, separators_only);
  EXPECT_EQ(none.loop_closures, 0);
  EXPECT_EQ(none.pairs, 0);
  EXPECT_TRUE(test::ThrowsNaming(
      [&] { CheckEachRobotsLoopClosures(team, std::vector<bool>(3, true)); }, "robust flags"));
}

// What the maps of the separator check leave out (along_odometry): a robot's own loop closures
// whose two poses its odometry joins. One across a gap in its odometry (robot 1 has no odometry
// from pose 4 to 5, only a factor `robust` marks, which is no odometry) is the only link between
// the two stretches and stays; so do the odometry, a separator, a factor `robust` does not mark,
// and an observation of an object. A marked factor beside the odometry between two consecutive
// poses is along it.
TEST(CheckEachRobotsLoopClosures, TellsTheLoopClosuresAlongTheOdometry) {
  const auto pose = [](int robot, int index) {
    return Key::Pose(robot, static_cast<std::uint64_t>(index));
  };
  const SE3 step(SO3(), Vector3(1.0, 0.0, 0.0));
  PoseGraph g;
  std::vector<bool> robust, expected;
  const auto add = [&](const Key& a, const Key& b, bool is_robust, bool left_out) {
    g.add(RelativePoseFactor(a, b, step, Matrix6::Identity()));
    robust.push_back(is_robust);
    expected.push_back(left_out);
  };
  for (int robot = 0; robot < 2; ++robot) {
    for (int i = 0; i + 1 < 8; ++i) {
      if (robot != 1 || i != 4) add(pose(robot, i), pose(robot, i + 1), false, false);
    }
  }
  add(pose(0, 0), pose(0, 6), true, true);          // along robot 0's odometry
  add(pose(0, 3), pose(0, 4), true, true);          // beside a step of it
  add(pose(1, 4), pose(1, 5), true, false);         // the only factor across robot 1's gap
  add(pose(1, 0), pose(1, 3), true, true);          // along robot 1's first stretch
  add(pose(1, 7), pose(1, 5), true, true);          // along robot 1's second stretch
  add(pose(1, 2), pose(1, 7), true, false);         // across robot 1's gap
  add(pose(1, 6), pose(1, 1), true, false);         // across it, the other way round
  add(pose(0, 2), pose(0, 5), false, false);        // not robust
  add(pose(0, 3), pose(1, 3), true, false);         // a separator
  add(pose(0, 4), Key::Object(0, 1), true, false);  // an observation
  EXPECT_EQ(CheckEachRobotsLoopClosures(g, robust).along_odometry, expected);
}

TEST(CheckLoopClosuresByOdometry, BadOptionsNameTheField) {
  using O = OdometryCheckOptions;
  EXPECT_TRUE(test::EachChangeIsRefused<O>({
      {"threshold", [](O& o) { o.threshold = 0.0; }},
      {"threshold", [](O& o) { o.threshold = INFINITY; }},
      {"min_support", [](O& o) { o.min_support = 0; }},
  }));
}

}  // namespace
}  // namespace moslam
