#include "moslam/online/group_solve.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <random>
#include <set>
#include <vector>

#include "moslam/common/errors.h"
#include "moslam/common/throws_naming_testing.h"
#include "moslam/distributed/centralized_two_stage.h"
#include "moslam/metrics/metrics.h"
#include "moslam/online/online_team.h"
#include "moslam/sim/world.h"
#include "moslam/slam/multi_robot.h"
#include "moslam/solver/optimizer.h"

namespace moslam {
namespace {

SE3 RandomPose(std::mt19937& rng, double scale) {
  std::normal_distribution<double> n(0.0, 1.0);
  Vector6 xi;
  for (int i = 0; i < 6; ++i) xi[i] = scale * n(rng);
  return SE3::Exp(xi);
}

Matrix6 RandomInformation(std::mt19937& rng) {
  std::normal_distribution<double> n(0.0, 1.0);
  Matrix6 a;
  for (int i = 0; i < 36; ++i) a(i / 6, i % 6) = n(rng);
  return a * a.transpose() + Matrix6::Identity();
}

// The held factor has the cost of the object-object factor with the partner landmark at
// x0 * held, for any first pose x0, whichever end the robot owns and whatever the measurement.
TEST(HeldFactor, HasTheCostOfTheSharedFactorWithThePartnerFixed) {
  std::mt19937 rng(7);
  for (int trial = 0; trial < 20; ++trial) {
    const SE3 z = trial % 2 == 0 ? SE3() : RandomPose(rng, 0.8);
    const Matrix6 info = RandomInformation(rng);
    const SE3 x0 = RandomPose(rng, 1.5), mine = RandomPose(rng, 1.5), partner = RandomPose(rng, 1.5);
    const SE3 held = x0.inverse() * partner;
    for (bool robot_is_b : {true, false}) {
      const Key own = Key::Object(1, 3), other = Key::Object(2, 5);
      const RelativePoseFactor shared = robot_is_b ? RelativePoseFactor(other, own, z, info)
                                                   : RelativePoseFactor(own, other, z, info);
      const double expected = robot_is_b ? shared.cost(partner, mine) : shared.cost(mine, partner);
      const RelativePoseFactor f = HeldFactor(shared, 1, held);
      EXPECT_EQ(f.a(), Key::Pose(1, 0));
      EXPECT_EQ(f.b(), own);
      EXPECT_NEAR(f.cost(x0, mine), expected, 1e-9 * (1.0 + expected)) << trial;
    }
  }
  const RelativePoseFactor same_robot(Key::Object(1, 0), Key::Object(1, 1), SE3(),
                                      Matrix6::Identity());
  EXPECT_THROW(HeldFactor(same_robot, 1, SE3()), InvalidInputError);
  EXPECT_THROW(HeldFactor(same_robot, 3, SE3()), InvalidInputError);
}

TEST(LinkedGroups, SplitsRobotsBySharedPairsAmongThem) {
  const std::vector<SharedObject> shared = {{Key::Object(1, 0), Key::Object(3, 0)},
                                            {Key::Object(4, 0), Key::Object(0, 2)},
                                            {Key::Object(2, 0), Key::Object(5, 1)}};
  // 2-5 is a pair with a robot out of range: it does not link 2 to anything.
  const auto groups = LinkedGroups({4, 3, 2, 1, 0}, shared);
  ASSERT_EQ(groups.size(), 3u);
  EXPECT_EQ(groups[0], (std::vector<int>{0, 4}));
  EXPECT_EQ(groups[1], (std::vector<int>{1, 3}));
  EXPECT_EQ(groups[2], (std::vector<int>{2}));
}

// A robot's update takes its own variables in its own frame and the landmarks of its partners
// in the group; of a partner that left during the solve, only those the solution holds (it sent
// them before it left): a missing one keeps the robot's earlier copy, where a missing landmark of
// a partner that did not leave is an error.
TEST(RobotGroupUpdate, TakesWhatASolutionHoldsOfAPartnerThatLeftTheSolve) {
  const std::vector<int> robots = {2, 4, 7};  // group ids 0, 1, 2
  const std::vector<SharedObject> shared = {{Key::Object(4, 1), Key::Object(2, 3)},
                                            {Key::Object(7, 0), Key::Object(4, 2)},
                                            {Key::Object(7, 5), Key::Object(4, 1)}};
  const SE3 first(SO3::Exp(Vector3(0.0, 0.0, 0.5)), Vector3(1.0, 2.0, 0.0));
  const SE3 landmark(SO3(), Vector3(3.0, 0.0, 0.0)), partner(SO3(), Vector3(0.0, 1.0, 0.0));
  Values solution;  // re-labelled: robot 4 is 1; of robot 7 (2), only its landmark 5
  solution[Key::Pose(1, 0)] = first;
  solution[Key::Object(1, 1)] = landmark;
  solution[Key::Object(1, 2)] = landmark;
  solution[Key::Object(0, 3)] = partner;
  solution[Key::Object(2, 5)] = partner;
  EXPECT_THROW(RobotGroupUpdate(robots, 4, solution, shared, 5), InvalidInputError);
  const GroupUpdate u = RobotGroupUpdate(robots, 4, solution, shared, 5, {7});
  EXPECT_EQ(u.estimate.size(), 3u);
  EXPECT_LT(SE3::Log(u.estimate.at(Key::Pose(4, 0))).norm(), 1e-15);
  EXPECT_LT(SE3::Log((first.inverse() * landmark).between(u.estimate.at(Key::Object(4, 1)))).norm(),
            1e-12);
  ASSERT_EQ(u.held.size(), 2u);  // robot 2's landmark 3 and robot 7's landmark 5, not its 0
  EXPECT_EQ(u.held.count(Key::Object(7, 0)), 0u);
  for (const Key k : {Key::Object(2, 3), Key::Object(7, 5)}) {
    ASSERT_EQ(u.held.count(k), 1u);
    EXPECT_EQ(u.held.at(k).step, 5);
    EXPECT_LT(SE3::Log((first.inverse() * partner).between(u.held.at(k).pose)).norm(), 1e-12);
  }
  solution.erase(Key::Object(0, 3));  // robot 2 did not leave
  EXPECT_THROW(RobotGroupUpdate(robots, 4, solution, shared, 5, {7}), InvalidInputError);
}

SimulationData Simulation(int robots, int poses, unsigned seed) {
  SimulationConfig c;
  c.trajectory.num_robots = robots;
  c.trajectory.poses_per_robot = poses;
  c.trajectory.seed = seed;
  c.sensing.seed = seed;
  return Simulate(MakeScenarioWorld("chairs25", seed, robots), c);
}

// Restricts `values` to `robot`'s variables, in its own frame (its first pose the identity).
Values InOwnFrame(const Values& values, int robot) {
  const SE3 to_own = values.at(Key::Pose(robot, 0)).inverse();
  Values out;
  for (const auto& [k, x] : values) {
    if (k.robot == robot) out.emplace(k, to_own * x);
  }
  return out;
}

// With the robot out of range held at the joint optimum, the optimum of the group is the joint
// optimum (block-coordinate optimality), in every robot's own frame: this checks the held
// factors, the re-labelling and the split back, with robot 0 in the group and without it. The
// robot out of range is a partner of both robots in range: one holds stale copies of its
// landmarks (moved, from an earlier solve), the other the joint optimum, from a later one, and
// the group takes them from the later (GroupTeamFactors). Marked later, the stale copies move the
// group off the joint optimum. (The stale holder's pairs with landmarks the other does not pair
// with are left out: those would be anchored at the stale holder's frame, group_solve.h.)
TEST(GroupProblem, WithThePartnerHeldAtTheJointOptimumSolvesToIt) {
  const SimulationData data = Simulation(3, 40, 3);
  const MultiRobotSlamConfig config = MultiRobotSlamConfigForNoise(SensingConfig{});
  const MultiRobotSlamResult slam = RunMultiRobotObjectSlam(data, config);
  const Matrix6 lambda = config.rendezvous.lambda();
  OptimizerOptions tight;
  tight.relative_cost_tolerance = 1e-14;
  const SE3 stale_offset(SO3::Exp(Vector3(0.0, 0.0, 0.2)), Vector3(0.5, -0.3, 0.1));
  int groups = 0;
  for (const std::vector<int>& in_range : {std::vector<int>{0, 1}, std::vector<int>{1, 2}}) {
    const int out = in_range[0] == 0 ? 2 : 0;
    const int stale_holder = in_range[0] == 0 ? 0 : 2, fresh_holder = 1;
    const auto ends = [&](const SharedObject& s, int robot) {
      return s.alpha_object.robot == robot ? std::pair{s.alpha_object, s.beta_object}
                                           : std::pair{s.beta_object, s.alpha_object};
    };
    std::set<Key> fresh_pairs;  // the landmarks out of range the fresh holder pairs with
    for (const auto& s : slam.shared) {
      const auto [mine, other] = ends(s, fresh_holder);
      if (mine.robot == fresh_holder && other.robot == out) fresh_pairs.insert(other);
    }
    std::vector<SharedObject> shared;
    for (const auto& s : slam.shared) {
      const auto [mine, other] = ends(s, stale_holder);
      if (mine.robot != stale_holder || other.robot != out || fresh_pairs.count(other)) {
        shared.push_back(s);
      }
    }
    const JointProblem joint = AssembleJointProblem(slam.robots, shared, lambda);
    ASSERT_TRUE(joint.unanchored_robots.empty());
    const Values optimum =
        Optimize(joint.graph, CentralizedTwoStage(joint.graph, joint.initial).values, tight)
            .values;
    ASSERT_EQ(LinkedGroups(in_range, shared).size(), 1u);
    ++groups;
    for (bool stale_is_later : {false, true}) {
      std::map<int, HeldEstimates> held;
      for (int r : in_range) {
        const SE3 to_own = optimum.at(Key::Pose(r, 0)).inverse();
        const bool stale = r == stale_holder;
        for (const auto& s : shared) {
          const auto [mine, other] = ends(s, r);
          if (mine.robot != r || other.robot == r) continue;
          held[r][other] = {to_own * optimum.at(other) * (stale ? stale_offset : SE3()),
                            stale == stale_is_later ? 2 : 1};
        }
      }
      std::vector<const ObjectSlam*> group;
      for (int r : in_range) group.push_back(&slam.robots[static_cast<std::size_t>(r)]);
      const GroupProblem p = BuildGroupProblem(group, shared, held, lambda);
      EXPECT_GT(p.object_object, 0);
      EXPECT_GT(p.team_factors, 0);
      EXPECT_GT(p.borrowed, 0);  // both robots in range pair with the robot out of range
      const Values solved =
          Optimize(p.graph, CentralizedTwoStage(p.graph, p.initial).values, tight).values;
      double worst = 0.0;
      for (const GroupUpdate& u : SplitGroupSolution(p, solved, shared, 3)) {
        worst = std::max(worst, MaxPoseDifference(u.estimate, InOwnFrame(optimum, u.robot)));
        EXPECT_EQ(u.estimate.at(Key::Pose(u.robot, 0)).translation().norm(), 0.0);
        for (const auto& [k, y] : u.held) {
          ASSERT_NE(std::find(in_range.begin(), in_range.end(), k.robot), in_range.end());
          EXPECT_EQ(y.step, 3);
          if (stale_is_later) continue;
          const SE3 expected = optimum.at(Key::Pose(u.robot, 0)).inverse() * optimum.at(k);
          EXPECT_LT(SE3::Log(expected.between(y.pose)).norm(), 1e-6);
        }
      }
      if (stale_is_later) {
        EXPECT_GT(worst, 1e-3) << "{" << in_range[0] << ", " << in_range[1] << "}";
      } else {
        EXPECT_LT(worst, 1e-6) << "{" << in_range[0] << ", " << in_range[1] << "}";
      }
    }
  }
  EXPECT_EQ(groups, 2);
}

// Each partner robot's landmarks are taken from the holder that met it last; a tie goes to the
// pair's own robot, then to the lowest holder; a landmark only another robot holds is taken from
// it; pairs of a landmark nobody holds give no factor.
TEST(GroupTeamFactors, AnchorsEachPairAtTheLatestHolder) {
  const Matrix6 lambda = Matrix6::Identity();
  const SE3 a(SO3(), Vector3(1.0, 0.0, 0.0)), b(SO3(), Vector3(0.0, 2.0, 0.0));
  const Key c = Key::Object(5, 7), c2 = Key::Object(5, 9), d = Key::Object(6, 8);
  const std::vector<TeamPair> pairs = {
      {Key::Object(2, 1), c, false, true, {b, 4}},  // robot 2 met robot 5 last (step 4)
      {Key::Object(1, 3), c, true, true, {a, 3}},
      {Key::Object(1, 5), c2, false, true, {a, 3}},  // only robot 1 holds c2
      {Key::Object(3, 0), c, false, false, {}},     // robot 3 pairs with c, holds none
      {Key::Object(1, 4), d, false, true, {a, 6}},  // robot 6: robots 1 and 2 met it at step 6
      {Key::Object(2, 2), d, false, true, {b, 6}},
      {Key::Object(3, 6), d, false, false, {}},
      {Key::Object(3, 5), Key::Object(4, 0), false, false, {}},  // nobody holds it
  };
  std::vector<int> holders;
  const auto f = GroupTeamFactors(pairs, lambda, &holders);
  ASSERT_EQ(f.size(), 7u);
  // Sorted by (mine, other): 1:3-c, 1:4-d, 1:5-c2, 2:1-c, 2:2-d, 3:0-c, 3:6-d.
  EXPECT_EQ(f[0].b(), Key::Object(1, 3));
  EXPECT_EQ(f[2].b(), Key::Object(1, 5));
  EXPECT_EQ(holders, (std::vector<int>{2, 1, 1, 2, 2, 2, 1}));
  for (std::size_t i = 0; i < f.size(); ++i) EXPECT_EQ(f[i].a(), Key::Pose(holders[i], 0));
  // The factor has the cost of the pair with c at x_{holder,0} * copy.
  const SE3 x0(SO3::Exp(Vector3(0.1, 0.2, 0.3)), Vector3(1.0, 2.0, 3.0));
  const SE3 l(SO3::Exp(Vector3(-0.2, 0.1, 0.0)), Vector3(0.5, 0.5, 0.5));
  const RelativePoseFactor pair13 = ObjectObjectFactor({c, Key::Object(1, 3)}, lambda);
  EXPECT_NEAR(f[0].cost(x0, l), pair13.cost(x0 * b, l), 1e-12);
  EXPECT_THROW(GroupTeamFactors({pairs[0], pairs[0]}, lambda), InvalidInputError);
  EXPECT_THROW(GroupTeamFactors({{c, c2, false, false, {}}}, lambda), InvalidInputError);
}

TEST(GroupProblem, RefusesGroupsThatCannotBeSolved) {
  const SimulationData data = Simulation(3, 40, 3);
  const MultiRobotSlamConfig config = MultiRobotSlamConfigForNoise(SensingConfig{});
  const MultiRobotSlamResult slam = RunMultiRobotObjectSlam(data, config);
  const Matrix6 lambda = config.rendezvous.lambda();
  const ObjectSlam& r0 = slam.robots[0];
  EXPECT_THROW(BuildGroupProblem({&r0}, slam.shared, {}, lambda), InvalidInputError);
  EXPECT_THROW(BuildGroupProblem({&r0, &r0}, slam.shared, {}, lambda), InvalidInputError);
  EXPECT_THROW(BuildGroupProblem({&r0, &slam.robots[1]}, {}, {}, lambda), InvalidInputError);

  // One robot's part of a group (a robot process's): the group and the team pairs are checked,
  // each refusal naming what is wrong.
  const auto part = [&](const std::vector<int>& robots, const std::vector<TeamPair>& team) {
    return [&, robots, team] { BuildRobotGroupPart(r0, robots, slam.shared, team, lambda); };
  };
  const std::string order = "a group is two or more distinct robots in increasing order";
  EXPECT_TRUE(test::ThrowsNaming(part({0}, {}), order));
  EXPECT_TRUE(test::ThrowsNaming(part({1, 0}, {}), order));
  EXPECT_TRUE(test::ThrowsNaming(part({0, 0}, {}), order));
  EXPECT_TRUE(test::ThrowsNaming(part({1, 2}, {}), "robot 0 is not in the group"));
  // A team pair stands for a partner out of range: one with both ends in the group is refused.
  const TeamPair inside{Key::Object(0, 0), Key::Object(1, 0), true, false, {}};
  EXPECT_TRUE(test::ThrowsNaming(part({0, 1}, {inside}),
                                 "is not one of a robot of the group with a robot outside it"));
  EXPECT_NO_THROW(part({0, 1}, {})());

  // A solution that lacks a variable of the problem.
  const GroupProblem problem = BuildGroupProblem({&r0, &slam.robots[1]}, slam.shared, {}, lambda);
  Values partial = problem.initial;
  partial.erase(partial.begin());
  EXPECT_THROW(SplitGroupSolution(problem, partial, slam.shared, 1), InvalidInputError);
  EXPECT_EQ(SplitGroupSolution(problem, problem.initial, slam.shared, 1).size(), 2u);
}

TEST(ObjectSlamOnline, TeamFactorsAndEstimatesAreValidated) {
  const SimulationData data = Simulation(2, 20, 3);
  const MultiRobotSlamResult slam =
      RunMultiRobotObjectSlam(data, MultiRobotSlamConfigForNoise(SensingConfig{}));
  ObjectSlam robot = slam.robots[1];
  ASSERT_FALSE(robot.landmarks().empty());
  const Matrix6 info = Matrix6::Identity();
  const Values before = robot.estimate();
  EXPECT_THROW(robot.setTeamFactors({RelativePoseFactor(Key::Pose(1, 1), Key::Object(1, 0), SE3(), info)}),
               InvalidInputError);
  EXPECT_THROW(robot.setTeamFactors({RelativePoseFactor(Key::Pose(1, 0), Key::Object(1, 999), SE3(), info)}),
               InvalidInputError);
  EXPECT_THROW(robot.setTeamFactors({RelativePoseFactor(Key::Pose(0, 0), Key::Object(0, 0), SE3(), info)}),
               InvalidInputError);
  EXPECT_TRUE(robot.teamFactors().empty());
  Values moved = before;
  moved[Key::Pose(1, 0)] = SE3(SO3(), Vector3(1.0, 0.0, 0.0));
  EXPECT_THROW(robot.setEstimate(moved), InvalidInputError);
  Values missing = before;
  missing.erase(Key::Object(1, 0));
  EXPECT_THROW(robot.setEstimate(missing), InvalidInputError);
  EXPECT_EQ(MaxPoseDifference(robot.estimate(), before), 0.0);

  // A team factor pulls the landmark: optimize() with it moves the landmark toward the held pose.
  const SE3 target = robot.landmarkPose(0) * SE3(SO3(), Vector3(0.5, 0.0, 0.0));
  robot.setTeamFactors({RelativePoseFactor(Key::Pose(1, 0), Key::Object(1, 0), target, 1e4 * info)});
  robot.refresh(10);
  EXPECT_LT((robot.landmarkPose(0).translation() - target.translation()).norm(), 0.05);
  EXPECT_EQ(robot.graph().factors().size(), slam.robots[1].graph().factors().size());
}

// Factor weights scale the information of the robot's own factors in its optimisation (the cost
// it reports is the weighted one), factors beyond the weights weigh 1, graph() stays unweighted;
// bad weights change nothing.
TEST(ObjectSlamOnline, FactorWeightsScaleItsOwnFactors) {
  const SimulationData data = Simulation(2, 20, 3);
  const MultiRobotSlamResult slam =
      RunMultiRobotObjectSlam(data, MultiRobotSlamConfigForNoise(SensingConfig{}));
  ObjectSlam robot = slam.robots[1];
  const PoseGraph graph = robot.graph();
  const std::size_t n = graph.factors().size();
  ASSERT_GE(n, 4u);
  const double full = robot.optimize(0);
  ASSERT_GT(full, 0.0);
  EXPECT_NEAR(full, graph.cost(robot.estimate()), 1e-9 * full);
  robot.setFactorWeights(std::vector<double>(n, 0.5));
  EXPECT_NEAR(robot.optimize(0), 0.5 * full, 1e-9 * full);
  // The first factor alone at a tenth: the cost loses 0.9 of its term.
  const PoseGraph first({graph.factors().front()});
  robot.setFactorWeights({0.1});
  EXPECT_NEAR(robot.optimize(0), full - 0.9 * first.cost(robot.estimate()), 1e-9 * full);
  EXPECT_EQ(robot.graph().factors().size(), n);
  EXPECT_EQ(robot.graph().factors().front().information(), graph.factors().front().information());
  EXPECT_THROW(robot.setFactorWeights(std::vector<double>(n + 1, 1.0)), InvalidInputError);
  EXPECT_THROW(robot.setFactorWeights({0.0}), InvalidInputError);
  EXPECT_THROW(robot.setFactorWeights({1.5}), InvalidInputError);
  EXPECT_THROW(robot.setFactorWeights({std::nan("")}), InvalidInputError);
  EXPECT_EQ(robot.factorWeights(), std::vector<double>{0.1});
}

// The twin: a mission with a group solve at every rendezvous; every solve lowers the group's cost
// and leaves every robot in its own frame, and the groups are the robots in range.
TEST(OnlineTeam, SolvesAtEveryRendezvousAndKeepsEachRobotInItsFrame) {
  const SimulationData data = Simulation(3, 40, 3);
  MultiRobotSlamConfig config = MultiRobotSlamConfigForNoise(SensingConfig{});
  OnlineOptions options;
  options.lambda = config.rendezvous.lambda();
  OnlineTeam team(options);
  std::vector<RendezvousGroup> groups;
  config.on_rendezvous = team.hook([&](const RendezvousGroup& g, const MultiRobotSlamResult& s) {
    groups.push_back(g);
    for (const ObjectSlam& r : s.robots) {
      EXPECT_LT(SE3::Log(r.pose(0)).norm(), 1e-12);
    }
  });
  const MultiRobotSlamResult slam = RunMultiRobotObjectSlam(data, config);
  ASSERT_FALSE(team.solves().empty());
  EXPECT_FALSE(groups.empty());
  std::set<int> steps;
  for (const auto& e : data.rendezvous) steps.insert(e.step);
  for (const RendezvousGroup& g : groups) {
    EXPECT_GE(g.robots.size(), 2u);
    EXPECT_EQ(steps.count(g.step), 1u);
  }
  for (const GroupSolveRecord& s : team.solves()) {
    EXPECT_LE(s.final_cost, s.initial_cost * (1.0 + 1e-9));
    EXPECT_EQ(s.refine_status, StageStatus::kConverged);
    EXPECT_GT(s.bytes, 0);
  }
  // Every robot that took part holds its partners' landmarks and has team factors for them.
  for (const auto& [robot, held] : team.held()) {
    EXPECT_FALSE(held.empty());
    EXPECT_EQ(slam.robots[static_cast<std::size_t>(robot)].teamFactors().size(),
              TeamFactors(robot, slam.shared, held, options.lambda).size());
  }
}

// When the only rendezvous joins the whole team at the last step, the online maps are the batch
// optimum of the same factors (the group solve refines to the group's optimum; each robot's own
// Gauss-Newton afterwards, with its partners held there, stays at it).
TEST(OnlineTeam, OneRendezvousOfTheWholeTeamAtTheEndGivesTheBatchOptimum) {
  SimulationData data = Simulation(3, 40, 3);
  const int last = data.numSteps() - 1;
  data.rendezvous = {{last, 0, 1}, {last, 1, 2}, {last, 0, 2}};
  MultiRobotSlamConfig config = MultiRobotSlamConfigForNoise(SensingConfig{});
  OnlineOptions options;
  options.lambda = config.rendezvous.lambda();
  OnlineTeam team(options);
  config.on_rendezvous = team.hook();
  const MultiRobotSlamResult slam = RunMultiRobotObjectSlam(data, config);
  ASSERT_EQ(team.solves().size(), 1u);
  ASSERT_EQ(team.solves()[0].robots, (std::vector<int>{0, 1, 2}));
  const JointProblem joint = AssembleJointProblem(slam.robots, slam.shared, options.lambda);
  ASSERT_TRUE(joint.unanchored_robots.empty());
  OptimizerOptions tight;
  tight.relative_cost_tolerance = 1e-14;
  const Values optimum =
      Optimize(joint.graph, CentralizedTwoStage(joint.graph, joint.initial).values, tight).values;
  for (const ObjectSlam& r : slam.robots) {
    EXPECT_LT(MaxPoseDifference(r.estimate(), InOwnFrame(optimum, r.robot())), 1e-6)
        << "robot " << r.robot();
  }
}

// The robust online team's options for `config`: its object-object information, the robust
// solve's defaults.
OnlineOptions RobustOnlineOptions(const MultiRobotSlamConfig& config) {
  OnlineOptions options;
  options.lambda = config.rendezvous.lambda();
  options.robust = RobustDgsOptions{};
  return options;
}

// Robust: with the only rendezvous joining the whole team at the last step and wrong pairs
// injected there, the group solve is the batch robust solve (RunRobustDgs of the joint graph, the
// object-object and object-pose factors robust, the same solver): the pairs it sets aside are the
// ones that solve rejects, every injected pair among them, the robots' factor weights are its
// verdicts on their factors, and the maps are its estimate, with the pairs set aside left out of
// every robot's held factors.
TEST(OnlineTeam, RobustWholeTeamAtTheEndIsTheBatchRobustSolve) {
  SimulationData data = Simulation(3, 60, 3);
  const int last = data.numSteps() - 1;
  data.rendezvous = {{last, 0, 1}, {last, 1, 2}, {last, 0, 2}};
  MultiRobotSlamConfig config = MultiRobotSlamConfigForNoise(SensingConfig{});
  config.outlier_fraction = 0.3;
  const OnlineOptions options = RobustOnlineOptions(config);
  OnlineTeam team(options);
  config.on_rendezvous = team.hook();
  const MultiRobotSlamResult slam = RunMultiRobotObjectSlam(data, config);
  ASSERT_EQ(team.solves().size(), 1u);
  ASSERT_FALSE(team.solves()[0].unlinked);
  ASSERT_GE(slam.injected, 3);

  const JointProblem joint = AssembleJointProblem(slam.robots, slam.shared, options.lambda);
  std::vector<bool> robust(joint.graph.factors().size(), false);
  for (std::size_t i = 0; i < robust.size(); ++i) {
    const RelativePoseFactor& f = joint.graph.factors()[i];
    robust[i] = (f.a().isObject() && f.b().isObject() && f.a().robot != f.b().robot) ||
                (f.a().isPose() && f.b().isObject());
  }
  RobustDgsOptions batch_options;
  batch_options.dgs = options.solver;
  const RobustDgsResult batch = RunRobustDgs(joint.graph, joint.initial, robust, batch_options);
  std::set<std::pair<Key, Key>> rejected, aside;
  for (std::size_t i = 0; i < robust.size(); ++i) {
    const RelativePoseFactor& f = joint.graph.factors()[i];
    if (robust[i] && f.a().isObject() && batch.weights[i] < 0.5) {
      rejected.insert(std::minmax(f.a(), f.b()));
    }
  }
  for (const SharedObject& s : team.setAside()) {
    aside.insert(std::minmax(s.alpha_object, s.beta_object));
  }
  EXPECT_EQ(aside, rejected);
  EXPECT_EQ(team.solves()[0].rejected, static_cast<int>(aside.size()));
  // Every injected pair joins two landmarks of different objects: all of them set aside.
  int wrong_aside = 0;
  for (const SharedObject& s : team.setAside()) {
    const Landmark& a = slam.robots[static_cast<std::size_t>(s.alpha_object.robot)]
                            .landmarks()[s.alpha_object.index];
    const Landmark& b = slam.robots[static_cast<std::size_t>(s.beta_object.robot)]
                            .landmarks()[s.beta_object.index];
    wrong_aside += a.true_object != b.true_object ? 1 : 0;
  }
  EXPECT_GE(wrong_aside, slam.injected);
  const std::vector<SharedObject> accepted = AcceptedPairs(slam.shared, team.setAside());
  EXPECT_EQ(accepted.size(), slam.shared.size() - aside.size());
  std::size_t first = 0;  // the joint graph: each robot's own graph in turn, then the pairs
  int observations_rejected = 0;
  std::vector<int> rejected_of(slam.robots.size(), 0);
  for (const ObjectSlam& r : slam.robots) {
    const std::size_t n = r.graph().factors().size();
    ASSERT_EQ(r.factorWeights().size(), n);
    for (std::size_t j = 0; j < n; ++j) {
      EXPECT_EQ(r.factorWeights()[j] < 0.5, batch.weights[first + j] < 0.5);
      rejected_of[static_cast<std::size_t>(r.robot())] += batch.weights[first + j] < 0.5 ? 1 : 0;
    }
    observations_rejected += rejected_of[static_cast<std::size_t>(r.robot())];
    first += n;
  }
  EXPECT_GE(observations_rejected, 1);  // 2 in this run: the verdicts on a robot's own factors
  EXPECT_EQ(team.solves()[0].observation_outliers, observations_rejected);
  for (const ObjectSlam& r : slam.robots) {
    // A robot keeps a rejected object-pose factor at GNC's min_weight (1e-4) in its own last
    // Gauss-Newton, where the batch's inlier solve leaves it out: its pull (measured 7.5e-5 m)
    // is what separates the two then.
    const double tolerance = rejected_of[static_cast<std::size_t>(r.robot())] > 0 ? 1e-3 : 1e-6;
    EXPECT_LT(MaxPoseDifference(r.estimate(), InOwnFrame(batch.values, r.robot())), tolerance)
        << "robot " << r.robot();
    EXPECT_EQ(r.teamFactors().size(),
              TeamFactors(r.robot(), accepted, team.held().at(r.robot()), options.lambda).size());
  }
}

// Unknown initial poses and wrong pairs: a later rendezvous removes earlier pairs that its
// alignment contradicts (the messages then remove several pairs of one landmark: a wrong pair
// beside a right one); a removed pair is no longer set aside, and no set-aside pair is outside the
// team's list.
TEST(OnlineTeam, RobustPairsRemovedByARendezvousAreNoLongerSetAside) {
  const SimulationData data = Simulation(3, 40, 3);
  MultiRobotSlamConfig config = MultiRobotSlamConfigForNoise(SensingConfig{});
  config.known_initial_poses = false;
  config.outlier_fraction = 0.3;
  const OnlineOptions options = RobustOnlineOptions(config);
  OnlineTeam team(options);
  config.on_rendezvous = team.hook();
  const MultiRobotSlamResult slam = RunMultiRobotObjectSlam(data, config);
  int removed = 0;
  for (const RendezvousRecord& r : slam.rendezvous) removed += r.removed;
  ASSERT_GE(removed, 1);
  int rejected = 0;
  for (const GroupSolveRecord& s : team.solves()) rejected += s.rejected;
  ASSERT_GE(rejected, 1);
  std::set<std::pair<Key, Key>> listed;
  for (const SharedObject& s : slam.shared) listed.insert(std::minmax(s.alpha_object, s.beta_object));
  for (const SharedObject& s : team.setAside()) {
    EXPECT_EQ(listed.count(std::minmax(s.alpha_object, s.beta_object)), 1u);
  }
}

// The pairs set aside are matched in either direction; the others keep their order.
TEST(AcceptedPairs, LeavesOutThePairsSetAsideInEitherDirection) {
  const SharedObject p{Key::Object(1, 0), Key::Object(0, 2)};
  const SharedObject q{Key::Object(2, 1), Key::Object(0, 3)};
  const SharedObject r{Key::Object(2, 4), Key::Object(1, 5)};
  const SharedObject q_reversed{Key::Object(0, 3), Key::Object(2, 1)};
  const std::vector<SharedObject> kept = AcceptedPairs({p, q, r}, {q_reversed});
  ASSERT_EQ(kept.size(), 2u);
  EXPECT_EQ(kept[0].alpha_object, p.alpha_object);
  EXPECT_EQ(kept[1].alpha_object, r.alpha_object);
  EXPECT_EQ(AcceptedPairs({p, q, r}, {}).size(), 3u);
}

// A robot's own factors rejected: indices from its first factor in the solve, weights below 0.5
// only; a range beyond the weights is refused.
TEST(RejectedOwnFactors, ListsTheRobotsFactorsBelowHalfWeight) {
  const std::vector<double> w = {0.1, 1.0, 0.49, 0.5, 1e-6, 0.9};
  EXPECT_EQ(RejectedOwnFactors(w, 1, 4), (std::vector<std::uint32_t>{1, 3}));
  EXPECT_EQ(RejectedOwnFactors(w, 0, 6), (std::vector<std::uint32_t>{0, 2, 4}));
  EXPECT_TRUE(RejectedOwnFactors(w, 6, 0).empty());
  EXPECT_THROW(RejectedOwnFactors(w, 3, 4), InvalidInputError);
  EXPECT_THROW(RejectedOwnFactors(w, 7, 0), InvalidInputError);
}

// A robot that leaves the team (MultiRobotSlamConfig::leave_after): its later rendezvous are
// skipped with nothing exchanged, the groups in range still list it (as gone), and no solve
// includes it; before it leaves, everything is as without the departure.
TEST(OnlineTeam, ARobotThatLeftTakesPartInNoRendezvousAndNoSolve) {
  const SimulationData data = Simulation(3, 40, 3);
  ASSERT_FALSE(data.rendezvous.empty());
  const int leaves = data.rendezvous.front().alpha;
  const int last = data.rendezvous.front().step;
  MultiRobotSlamConfig config = MultiRobotSlamConfigForNoise(SensingConfig{});
  OnlineOptions options;
  options.lambda = config.rendezvous.lambda();
  const MultiRobotSlamResult all = RunMultiRobotObjectSlam(data, config);
  config.leave_after[leaves] = last;
  OnlineTeam team(options);
  int gone_listed = 0;
  config.on_rendezvous = team.hook([&](const RendezvousGroup& g, const MultiRobotSlamResult&) {
    const bool in_range = std::count(g.robots.begin(), g.robots.end(), leaves) > 0;
    EXPECT_EQ(g.gone, in_range && g.step > last ? std::vector<int>{leaves} : std::vector<int>{});
    gone_listed += g.gone.empty() ? 0 : 1;
  });
  const MultiRobotSlamResult slam = RunMultiRobotObjectSlam(data, config);
  EXPECT_GT(gone_listed, 0);
  ASSERT_EQ(slam.rendezvous.size(), all.rendezvous.size());
  int skipped = 0;
  for (std::size_t i = 0; i < slam.rendezvous.size(); ++i) {
    const RendezvousRecord& e = slam.rendezvous[i];
    const bool with = e.event.alpha == leaves || e.event.beta == leaves;
    EXPECT_EQ(e.skipped, with && e.event.step > last) << "event " << i;
    if (e.skipped) {
      ++skipped;
      EXPECT_EQ(e.new_shared + e.injected + e.objects_sent, 0);
    }
    if (e.event.step <= last) {
      EXPECT_EQ(e.new_shared, all.rendezvous[i].new_shared);
    }
  }
  EXPECT_GT(skipped, 0);
  for (const GroupSolveRecord& s : team.solves()) {
    if (s.step > last) {
      EXPECT_EQ(std::count(s.robots.begin(), s.robots.end(), leaves), 0);
    }
  }
  config.leave_after = {{-1, 3}};
  EXPECT_THROW(config.validate(), InvalidInputError);
  config.leave_after = {{7, 3}};  // robot 7 of 3
  EXPECT_THROW(RunMultiRobotObjectSlam(data, config), InvalidInputError);
}

}  // namespace
}  // namespace moslam
