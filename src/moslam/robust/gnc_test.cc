#include "moslam/robust/gnc.h"

#include <gtest/gtest.h>

#include <cmath>
#include <string>

#include "moslam/common/errors.h"
#include "moslam/io/datasets_testing.h"
#include "moslam/io/g2o.h"
#include "moslam/metrics/metrics.h"
#include "moslam/robust/spoil.h"
#include "moslam/robust/spoil_testing.h"
#include "moslam/solver/initialization.h"

namespace moslam {
namespace {

TEST(TlsWeight, OneBelowZeroAboveContinuousBetween) {
  const double c2 = 10.0;
  for (double mu : {0.01, 0.5, 3.0, 100.0}) {
    const double lo = mu / (mu + 1.0) * c2, hi = (mu + 1.0) / mu * c2;
    EXPECT_EQ(TlsWeight(0.5 * lo, mu, c2), 1.0);
    EXPECT_EQ(TlsWeight(1.01 * hi, mu, c2), 0.0);
    EXPECT_NEAR(TlsWeight(lo * (1 + 1e-9), mu, c2), 1.0, 1e-6);
    EXPECT_NEAR(TlsWeight(hi * (1 - 1e-9), mu, c2), 0.0, 1e-6);
    double previous = 1.0;
    for (int i = 1; i < 100; ++i) {  // non-increasing across the band
      const double w = TlsWeight(lo + (hi - lo) * i / 100.0, mu, c2);
      EXPECT_LE(w, previous + 1e-15);
      EXPECT_GE(w, 0.0);
      previous = w;
    }
  }
}

TEST(GncSchedule, StartsAtTheLargestResidualAndGrowsMu) {
  GncOptions o;
  o.threshold = 4.0;
  o.max_iterations = 3;
  GncSchedule s(o);
  EXPECT_FALSE(s.start(3.9));
  EXPECT_EQ(s.status(), GncStatus::kAllInliers);
  ASSERT_TRUE(s.start(10.0));
  EXPECT_DOUBLE_EQ(s.mu(), 4.0 / 16.0);
  // At mu_0 the largest residual sits inside the band: weight strictly between 0 and 1.
  EXPECT_GT(s.weight(10.0), 0.0);
  EXPECT_LT(s.weight(10.0), 1.0);
  EXPECT_FALSE(s.next(false));
  EXPECT_DOUBLE_EQ(s.mu(), 4.0 / 16.0 * 1.4);
  EXPECT_FALSE(s.next(false));
  EXPECT_TRUE(s.next(false));
  EXPECT_EQ(s.status(), GncStatus::kMaxIterations);
  ASSERT_TRUE(s.start(10.0));
  EXPECT_TRUE(s.next(true));
  EXPECT_EQ(s.status(), GncStatus::kConverged);
}

TEST(GncOptions, RejectsBadFields) {
  GncOptions o;
  o.mu_step = 1.0;
  EXPECT_THROW(o.validate(), InvalidInputError);
  o = {};
  o.threshold = -1.0;
  EXPECT_THROW(o.validate(), InvalidInputError);
  o = {};
  o.weight_tolerance = 0.5;
  EXPECT_THROW(o.validate(), InvalidInputError);
}

TEST(Spoil, AddsTheFractionDeterministically) {
  const Dataset data = ReadG2oFolder(test::BlocksWorldFolder(4));
  SpoilOptions o;
  o.fraction = 0.7;
  o.seed = 3;
  const SpoiledGraph a = SpoilSeparators(data.graph, o), b = SpoilSeparators(data.graph, o);
  ASSERT_GT(a.separators, 0);
  EXPECT_NEAR(static_cast<double>(a.added) / (a.added + a.separators), 0.7, 0.02);
  ASSERT_EQ(a.graph.factors().size(), data.graph.factors().size() + a.added);
  for (std::size_t i = 0; i < a.graph.factors().size(); ++i) {
    EXPECT_EQ(a.outlier[i], i >= data.graph.factors().size());
    EXPECT_EQ(a.graph.factors()[i].measured().translation(),
              b.graph.factors()[i].measured().translation());
    if (a.outlier[i]) {
      EXPECT_NE(a.graph.factors()[i].a().robot, a.graph.factors()[i].b().robot);
    }
  }
  o.fraction = 1.0;
  EXPECT_THROW(SpoilSeparators(data.graph, o), InvalidInputError);
}

// The robust solve on a graph with known outliers: blocks_world in 4 robots, 70 % of its
// separators wrong. GNC-TLS rejects exactly the wrong ones and lands on the clean optimum.
// blocks_world's information is the identity, but its factors fit far better (at the clean
// optimum the separators' r^T Omega r is at most 0.15, the outliers' at least 4.9): the threshold
// is set to 1, as a user sets it for data whose information is not its noise.
TEST(SolveGnc, RejectsKnownOutliersAndReachesTheCleanOptimum) {
  const Dataset data = ReadG2oFolder(test::BlocksWorldFolder(4));
  const Key anchor = GaugeAnchor(data.graph);
  const SE3 anchor_pose = data.initial.count(anchor) ? data.initial.at(anchor) : SE3();
  const OptimizerResult clean =
      Optimize(data.graph, ChordalInitialization(data.graph, anchor_pose));
  SpoilOptions spoil;
  spoil.fraction = 0.7;
  const SpoiledGraph spoiled = SpoilSeparators(data.graph, spoil);
  const Values initial = ChordalInitialization(spoiled.graph, anchor_pose);
  GncOptions gnc;
  gnc.threshold = 1.0;
  const GncResult r = SolveGnc(spoiled.graph, initial, DefaultRobustFactors(spoiled.graph), gnc);
  EXPECT_EQ(r.status, GncStatus::kConverged);
  int false_rejections = 0, missed = 0;
  for (std::size_t i = 0; i < r.weights.size(); ++i) {
    if (spoiled.outlier[i] && r.weights[i] >= 0.5) ++missed;
    if (!spoiled.outlier[i] && r.weights[i] < 0.5) ++false_rejections;
  }
  EXPECT_EQ(missed, 0);
  EXPECT_EQ(false_rejections, 0);
  EXPECT_EQ(r.outliers, spoiled.added);
  EXPECT_LT(MaxPoseDifference(r.values, clean.values), 1e-3);
  EXPECT_NEAR(data.graph.cost(r.values), clean.final_cost, 1e-4 * clean.final_cost);
  // The least-squares estimate, for contrast, is bent by the outliers.
  EXPECT_GT(r.least_squares_cost, 10.0 * clean.final_cost);
}

// One robot (CSAIL, a 2D file: a planar graph): the wrong factors are loop closures between two
// of its poses that are not consecutive, in the plane; at 10 % the robust solve, which makes
// the loop closures robust, rejects exactly them and lands on the clean optimum (6.8e-9 m).
TEST(SolveGnc, OneRobotsWrongLoopClosuresAreRejected) {
  const auto [data, spoiled] = test::SpoilPgoFile("CSAIL.g2o", 0.1);
  ASSERT_TRUE(data.planar);
  EXPECT_TRUE(spoiled.single_robot);
  EXPECT_EQ(spoiled.separators, 128);  // CSAIL's loop closures
  EXPECT_EQ(spoiled.added, 14);        // round(0.1 / 0.9 * 128)
  const std::vector<bool> robust = DefaultRobustFactors(spoiled.graph);
  for (std::size_t i = 0; i < spoiled.graph.factors().size(); ++i) {
    if (!spoiled.outlier[i]) continue;
    const RelativePoseFactor& f = spoiled.graph.factors()[i];
    EXPECT_TRUE(f.a().isPose() && f.b().isPose() && f.a().robot == 0 && f.b().robot == 0);
    EXPECT_GT(std::abs(static_cast<double>(f.a().index) - static_cast<double>(f.b().index)), 1.0);
    EXPECT_TRUE(robust[i]);
    EXPECT_EQ(f.measured().translation().z(), 0.0);
    EXPECT_LT(SO3::Log(f.measured().rotation()).head<2>().norm(), 1e-12);
  }
  const Values initial = ChordalInitialization(spoiled.graph, SE3());
  const GncResult r = SolveGnc(spoiled.graph, initial, robust, GncOptions());
  std::size_t wrong_kept = 0, right_rejected = 0;
  for (std::size_t i = 0; i < r.weights.size(); ++i) {
    wrong_kept += spoiled.outlier[i] && r.weights[i] >= 0.5;
    right_rejected += !spoiled.outlier[i] && r.weights[i] < 0.5;
  }
  EXPECT_EQ(wrong_kept, 0u);
  EXPECT_EQ(right_rejected, 0u);
  const OptimizerResult clean = Optimize(data.graph, ChordalInitialization(data.graph, SE3()));
  EXPECT_LT(MaxPoseDifference(r.values, clean.values), 1e-6);
  // A graph without a pose has nothing to spoil.
  EXPECT_THROW(SpoilSeparators(PoseGraph(), SpoilOptions()), InvalidInputError);
}

// Without outliers (blocks_world's residuals all below the threshold) GNC changes nothing.
TEST(SolveGnc, WithoutOutliersReturnsTheLeastSquaresEstimate) {
  const Dataset data = ReadG2oFolder(test::BlocksWorldFolder(4));
  const Values initial = ChordalInitialization(data.graph, SE3());
  const OptimizerResult ls = Optimize(data.graph, initial);
  GncOptions gnc;
  gnc.threshold = 1.0;
  const GncResult r = SolveGnc(data.graph, initial, DefaultRobustFactors(data.graph), gnc);
  EXPECT_EQ(r.status, GncStatus::kAllInliers);
  EXPECT_EQ(r.outliers, 0);
  EXPECT_LT(MaxPoseDifference(r.values, ls.values), 1e-9);
}

// A landmark whose only factor is rejected keeps an estimate (the rounds'), though the inliers'
// last solve does not hold it: before, it fell out of the result (a robot's own map in the
// separator check then had no estimate for it).
TEST(SolveGnc, AVariableOnlyRejectedFactorsTouchKeepsTheRoundsEstimate) {
  PoseGraph g;
  const Matrix6 info = 100.0 * Matrix6::Identity();
  const SE3 step(SO3::Exp(Vector3(0.0, 0.0, 0.1)), Vector3(1.0, 0.0, 0.0));
  std::vector<SE3> x{SE3()};
  for (std::uint64_t i = 0; i + 1 < 6; ++i) {
    g.add(RelativePoseFactor(Key::Pose(0, i), Key::Pose(0, i + 1), step, info));
    x.push_back(x.back() * step);
  }
  const Key lonely = Key::Object(0, 0), seen = Key::Object(0, 1);
  const SE3 object(SO3(), Vector3(2.0, 1.0, 0.0));
  for (std::uint64_t i : {0, 2, 4}) {  // three right views of `seen`, one 9 m off
    g.add(RelativePoseFactor(Key::Pose(0, i), seen, x[i].between(object), info));
  }
  g.add(RelativePoseFactor(Key::Pose(0, 5), seen,
                           x[5].between(object) * SE3(SO3(), Vector3(0.0, 9.0, 0.0)), info));
  // `lonely`: two views that contradict each other (one from a pose, one against `seen`).
  g.add(RelativePoseFactor(Key::Pose(0, 1), lonely, SE3(), info));
  g.add(RelativePoseFactor(lonely, seen, SE3(SO3(), Vector3(0.0, -7.0, 0.0)), info));
  std::vector<bool> robust(g.factors().size(), false);
  for (std::size_t i = 5; i < robust.size(); ++i) robust[i] = true;  // every object factor
  const GncResult r = SolveGnc(g, ChordalInitialization(g, SE3()), robust, GncOptions());
  const std::size_t n = r.weights.size();
  ASSERT_LT(r.weights[n - 1], 0.5);  // both of lonely's factors rejected
  ASSERT_LT(r.weights[n - 2], 0.5);
  EXPECT_LT(r.weights[n - 3], 0.5);  // the wrong view of `seen`
  EXPECT_EQ(r.values.size(), g.keys().size());
  EXPECT_EQ(r.values.count(lonely), 1u);
  EXPECT_LT((r.values.at(seen).translation() - object.translation()).norm(), 1e-6);
}

// Object SLAM's robust factors: every factor that touches an object, whoever owns it; odometry and
// pose-pose loop closures stay least squares.
TEST(ObjectFactors, MarksEveryFactorThatTouchesAnObject) {
  PoseGraph g;
  const Matrix6 info = Matrix6::Identity();
  g.add(RelativePoseFactor(Key::Pose(0, 0), Key::Pose(0, 1), SE3(), info));      // odometry
  g.add(RelativePoseFactor(Key::Pose(0, 0), Key::Pose(0, 5), SE3(), info));      // pose loop
  g.add(RelativePoseFactor(Key::Pose(0, 1), Key::Object(0, 0), SE3(), info));    // measurement
  g.add(RelativePoseFactor(Key::Object(0, 0), Key::Object(0, 3), SE3(), info));  // own loop closure
  g.add(RelativePoseFactor(Key::Object(0, 3), Key::Object(1, 2), SE3(), info));  // shared object
  g.add(RelativePoseFactor(Key::Pose(0, 5), Key::Pose(1, 0), SE3(), info));      // pose separator
  EXPECT_EQ(ObjectFactors(g), (std::vector<bool>{false, false, true, true, true, false}));
  EXPECT_TRUE(ObjectFactors(PoseGraph()).empty());
}

// A chain of poses split among robots keeps its indices: the factors between consecutive poses
// are its odometry whatever their robots (the one between two blocks too), every other factor a
// loop closure, objects' factors included. DefaultRobustFactors takes them for one robot.
TEST(LoopClosureFactors, AreTheFactorsNotBetweenConsecutivePoses) {
  PoseGraph g;
  const Matrix6 info = Matrix6::Identity();
  g.add(RelativePoseFactor(Key::Pose(0, 3), Key::Pose(0, 4), SE3(), info));  // odometry
  g.add(RelativePoseFactor(Key::Pose(1, 6), Key::Pose(1, 5), SE3(), info));  // odometry, reversed
  g.add(RelativePoseFactor(Key::Pose(0, 4), Key::Pose(1, 5), SE3(), info));  // between blocks
  g.add(RelativePoseFactor(Key::Pose(0, 0), Key::Pose(0, 4), SE3(), info));  // in a block
  g.add(RelativePoseFactor(Key::Pose(0, 2), Key::Pose(1, 6), SE3(), info));  // across blocks
  g.add(RelativePoseFactor(Key::Object(0, 0), Key::Object(0, 1), SE3(), info));  // objects
  g.add(RelativePoseFactor(Key::Pose(0, 0), Key::Object(0, 1), SE3(), info));
  EXPECT_EQ(LoopClosureFactors(g),
            (std::vector<bool>{false, false, false, true, true, true, true}));
  EXPECT_EQ(SeparatorFactors(g),
            (std::vector<bool>{false, false, true, false, true, false, false}));
  PoseGraph one;
  for (std::size_t i : {0, 3, 5, 6}) one.add(g.factors()[i]);
  EXPECT_EQ(DefaultRobustFactors(one), (std::vector<bool>{false, true, true, true}));
}

// Two robots, each a chain of 4 poses, joined only by two links from the same pose that put
// robot 1 5 m to either side of robot 0: the least-squares estimate sits between them, where the
// two residuals are equal, so their weights fall together and GNC rejects both. The inliers then
// leave robot 1 unanchored, and the result keeps the rounds' estimate rather than throwing (the
// header's "unless that leaves part of the graph unanchored"). With one solve allowed, the same
// graph stops at kMaxIterations with the weights still undecided.
struct TwoRobotsJoinedByTwoContradictingLinks {
  PoseGraph graph;
  std::vector<bool> robust;
  SE3 step{SO3::Exp(Vector3(0.0, 0.0, 0.2)), Vector3(1.0, 0.0, 0.0)};
  TwoRobotsJoinedByTwoContradictingLinks() {
    const Matrix6 info = 100.0 * Matrix6::Identity();
    for (int robot : {0, 1}) {
      for (std::uint64_t i = 0; i + 1 < 4; ++i) {
        graph.add(RelativePoseFactor(Key::Pose(robot, i), Key::Pose(robot, i + 1), step, info));
      }
    }
    for (double y : {5.0, -5.0}) {
      graph.add(RelativePoseFactor(Key::Pose(0, 1), Key::Pose(1, 0),
                                   SE3(SO3(), Vector3(0.0, y, 0.0)), info));
    }
    robust = SeparatorFactors(graph);
  }
};

TEST(SolveGnc, InliersThatLeaveARobotUnanchoredKeepTheRoundsEstimate) {
  const TwoRobotsJoinedByTwoContradictingLinks t;
  ASSERT_EQ(t.robust, (std::vector<bool>{false, false, false, false, false, false, true, true}));
  const Values initial = ChordalInitialization(t.graph, SE3());
  const GncResult r = SolveGnc(t.graph, initial, t.robust);
  EXPECT_EQ(r.status, GncStatus::kConverged);
  EXPECT_EQ(r.outliers, 2);
  EXPECT_LT(r.weights[6], 1e-6);
  EXPECT_LT(r.weights[7], 1e-6);
  ASSERT_EQ(r.values.size(), t.graph.keys().size());
  // The inliers alone would leave robot 1 without an anchor.
  EXPECT_THROW(Optimize(SubGraph(t.graph, Inliers(r.weights)), r.values), UnderdeterminedError);
  // Each chain keeps its odometry; robot 1 stays where the rounds put it, between the two links.
  for (int robot : {0, 1}) {
    for (std::uint64_t i = 0; i + 1 < 4; ++i) {
      const Vector6 e = r.values.at(Key::Pose(robot, i + 1))
                            .localCoordinates(r.values.at(Key::Pose(robot, i)) * t.step);
      EXPECT_LT(e.norm(), 1e-6) << robot << " " << i;
    }
  }
  EXPECT_LT(SE3::Log(r.values.at(Key::Pose(0, 1)).between(r.values.at(Key::Pose(1, 0)))).norm(),
            1e-6);
}

TEST(SolveGnc, StopsAtMaxIterationsWithTheWeightsUndecided) {
  const TwoRobotsJoinedByTwoContradictingLinks t;
  GncOptions o;
  o.max_iterations = 1;
  const GncResult r = SolveGnc(t.graph, ChordalInitialization(t.graph, SE3()), t.robust, o);
  EXPECT_EQ(r.status, GncStatus::kMaxIterations);
  EXPECT_EQ(ToString(r.status), "max iterations");
  EXPECT_EQ(r.iterations, 1);
  EXPECT_GT(r.weights[6], o.weight_tolerance);  // undecided: strictly between 0 and 1
  EXPECT_LT(r.weights[6], 1.0 - o.weight_tolerance);
  EXPECT_EQ(r.outliers, 2);  // both below 0.5 all the same
}

TEST(SolveGnc, RejectsAMaskOfTheWrongSize) {
  const Dataset data = ReadG2oFolder(test::BlocksWorldFolder(2));
  EXPECT_THROW(SolveGnc(data.graph, ChordalInitialization(data.graph, SE3()), {true}),
               InvalidInputError);
}

}  // namespace
}  // namespace moslam
