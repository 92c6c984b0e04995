#include "moslam/online/group_solve.h"

#include <gtest/gtest.h>

#include <random>
#include <set>

#include "moslam/common/errors.h"
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
// pairs between robots 0 and 2 are left out so that the robot out of range is a partner of one
// robot in range only: each holder keeps its own copy of a partner's landmarks (group_solve.h),
// so with two holders the copies do not tie the holders to each other as the joint graph does.
TEST(GroupProblem, WithThePartnerHeldAtTheJointOptimumSolvesToIt) {
  const SimulationData data = Simulation(3, 40, 3);
  const MultiRobotSlamConfig config = MultiRobotSlamConfigForNoise(SensingConfig{});
  const MultiRobotSlamResult slam = RunMultiRobotObjectSlam(data, config);
  const Matrix6 lambda = config.rendezvous.lambda();
  std::vector<SharedObject> shared;
  for (const auto& s : slam.shared) {
    const std::set<int> robots = {s.alpha_object.robot, s.beta_object.robot};
    if (robots != std::set<int>{0, 2}) shared.push_back(s);
  }
  const JointProblem joint = AssembleJointProblem(slam.robots, shared, lambda);
  ASSERT_TRUE(joint.unanchored_robots.empty());
  const Values optimum =
      Optimize(joint.graph, CentralizedTwoStage(joint.graph, joint.initial).values).values;
  int groups = 0;
  for (const std::vector<int>& in_range : {std::vector<int>{0, 1}, std::vector<int>{1, 2}}) {
    ASSERT_EQ(LinkedGroups(in_range, shared).size(), 1u);
    ++groups;
    std::map<int, HeldEstimates> held;
    for (int r : in_range) {
      const SE3 to_own = optimum.at(Key::Pose(r, 0)).inverse();
      for (const auto& s : shared) {
        for (const auto& [mine, other] : {std::pair{s.alpha_object, s.beta_object},
                                          std::pair{s.beta_object, s.alpha_object}}) {
          if (mine.robot == r && other.robot != r) held[r][other] = to_own * optimum.at(other);
        }
      }
    }
    std::vector<const ObjectSlam*> group;
    for (int r : in_range) group.push_back(&slam.robots[static_cast<std::size_t>(r)]);
    const GroupProblem p = BuildGroupProblem(group, shared, held, lambda);
    EXPECT_GT(p.object_object, 0);
    EXPECT_GT(p.team_factors, 0);
    const Values solved = Optimize(p.graph, CentralizedTwoStage(p.graph, p.initial).values).values;
    for (const GroupUpdate& u : SplitGroupSolution(p, solved, shared)) {
      EXPECT_LT(MaxPoseDifference(u.estimate, InOwnFrame(optimum, u.robot)), 1e-6)
          << "robot " << u.robot << " of {" << in_range[0] << ", " << in_range[1] << "}";
      EXPECT_EQ(u.estimate.at(Key::Pose(u.robot, 0)).translation().norm(), 0.0);
      for (const auto& [k, y] : u.held) {
        ASSERT_NE(std::find(in_range.begin(), in_range.end(), k.robot), in_range.end());
        const SE3 expected = optimum.at(Key::Pose(u.robot, 0)).inverse() * optimum.at(k);
        EXPECT_LT(SE3::Log(expected.between(y)).norm(), 1e-6);
      }
    }
  }
  EXPECT_EQ(groups, 2);
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

}  // namespace
}  // namespace moslam
