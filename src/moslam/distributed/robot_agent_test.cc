#include "moslam/distributed/robot_agent.h"

#include <gtest/gtest.h>

#include <cmath>
#include <functional>
#include <limits>
#include <map>

#include "moslam/common/errors.h"
#include "moslam/common/throws_naming_testing.h"
#include "moslam/distributed/centralized_two_stage.h"
#include "moslam/distributed/dgs_test_util.h"
#include "moslam/distributed/partition.h"
#include "moslam/distributed/two_stage_terms.h"
#include "moslam/graph/synthetic.h"

namespace moslam {
namespace {

SyntheticGraph Noisy(int robots, unsigned seed) {
  SyntheticGraphOptions o;
  o.num_robots = robots;
  o.poses_per_robot = 12;
  o.sigma_rotation = 0.05;
  o.sigma_translation = 0.1;
  o.seed = seed;
  return MakeSyntheticGraph(o);
}

// The estimate of `key` as the stage-2 unknown (dtheta w.r.t. R_hat, t).
Eigen::VectorXd PoseDelta(const SE3& x, const Matrix3& R_hat) {
  Eigen::VectorXd d(6);
  d.head<3>() = SO3::Log(SO3(R_hat.transpose() * x.rotation().matrix()));
  d.tail<3>() = x.translation();
  return d;
}

Message MessageFrom(int sender, DgsStage stage, std::uint32_t iteration, bool initialised,
                    const std::vector<Key>& keys,
                    const std::function<Eigen::VectorXd(const Key&)>& value) {
  Message m;
  m.stage = stage;
  m.iteration = iteration;
  m.sender = sender;
  m.initialised = initialised;
  m.keys = keys;
  for (const Key& k : keys) {
    const Eigen::VectorXd v = value(k);
    m.values.insert(m.values.end(), v.data(), v.data() + v.size());
  }
  return m;
}

// Gives `agent` the estimates `value` of every neighbour variable, one message per owner.
void Feed(RobotAgent& agent, DgsStage stage, std::uint32_t iteration,
          const std::function<Eigen::VectorXd(const Key&)>& value) {
  std::map<int, std::vector<Key>> by_owner;
  for (const Key& k : agent.neighbourVariables()) by_owner[k.robot].push_back(k);
  for (const auto& [owner, keys] : by_owner) {
    EXPECT_EQ(agent.receive(MessageFrom(owner, stage, iteration, true, keys, value)),
              ReceiveStatus::kAccepted);
  }
}

TEST(RobotAgent, AloneItSolvesTheCentralizedProblemInOneIterationPerStage) {
  const SyntheticGraph s = Noisy(1, 11);
  const TwoStageResult c = CentralizedTwoStage(s.graph, s.ground_truth);
  RobotAgent agent(0, s.graph, s.ground_truth, GaugeAnchor(s.graph));
  EXPECT_EQ(agent.state(), AgentState::kIdle);
  EXPECT_TRUE(agent.neighbourVariables().empty());
  agent.startRotation();
  EXPECT_EQ(agent.state(), AgentState::kRotation);
  ASSERT_TRUE(agent.iterate());
  for (const auto& [k, r] : agent.relaxedRotations()) {
    EXPECT_LT((r - c.relaxed_rotations.at(k)).norm(), 1e-10) << ToString(k);
  }
  agent.startPose();
  ASSERT_TRUE(agent.iterate());
  agent.finish();
  EXPECT_EQ(agent.state(), AgentState::kDone);
  const Values v = agent.estimate();
  ASSERT_EQ(v.size(), c.values.size());
  for (const auto& [k, x] : c.values) {
    EXPECT_LT((v.at(k).translation() - x.translation()).norm(), 1e-9) << ToString(k);
    EXPECT_LT((v.at(k).rotation().matrix() - x.rotation().matrix()).norm(), 1e-9);
  }
}

TEST(RobotAgent, NeighbourTablesAndSharedVariables) {
  Values gt;
  const PoseGraph g = test::ChainOfRobots(3, 4, &gt);
  const std::vector<RobotSubgraph> parts = PartitionByRobot(g);
  ASSERT_EQ(parts.size(), 3u);
  RobotAgent middle(1, parts[1].graph, gt, GaugeAnchor(g));
  EXPECT_EQ(middle.ownVariables().size(), 4u);
  EXPECT_EQ(middle.neighbourVariables(), (std::set<Key>{Key::Pose(0, 3), Key::Pose(2, 0)}));
  EXPECT_EQ(middle.neighbourRobots(), (std::set<int>{0, 2}));
  EXPECT_EQ(middle.neighbourLinks(), (std::map<int, int>{{0, 1}, {2, 1}}));
  EXPECT_EQ(middle.sharedWith().at(0), std::vector<Key>{Key::Pose(1, 0)});
  EXPECT_EQ(middle.sharedWith().at(2), std::vector<Key>{Key::Pose(1, 3)});
  // Outgoing: one message per neighbouring robot with the variables it needs.
  EXPECT_TRUE(middle.outgoing().empty());  // no stage running
  middle.startRotation();
  const std::vector<OutgoingMessage> out = middle.outgoing();
  ASSERT_EQ(out.size(), 2u);
  EXPECT_EQ(out[0].to, 0);
  EXPECT_EQ(out[0].message.keys, std::vector<Key>{Key::Pose(1, 0)});
  EXPECT_EQ(out[0].message.iteration, 0u);
  EXPECT_FALSE(out[0].message.initialised);
  EXPECT_EQ(out[0].message.values.size(), 9u);
  // Before solving, the estimate sent is the initial rotation, row by row.
  EXPECT_LT((Eigen::Map<const Eigen::VectorXd>(out[0].message.values.data(), 9) -
             RowMajor(gt.at(Key::Pose(1, 0)).rotation().matrix()))
                .norm(),
            1e-15);
}

TEST(RobotAgent, FlaggedInitialisationWaitsForAnInitialisedNeighbour) {
  Values gt;
  const PoseGraph g = test::ChainOfRobots(2, 4, &gt);
  const std::vector<RobotSubgraph> parts = PartitionByRobot(g);
  RobotAgent robot1(1, parts[1].graph, gt, GaugeAnchor(g));
  robot1.startRotation();
  EXPECT_FALSE(robot1.iterate());  // nothing received: no anchor, no separator
  EXPECT_FALSE(robot1.initialised());
  EXPECT_EQ(robot1.iteration(), 0);
  // An estimate from robot 0 that has not solved yet is not used either.
  const Key k03 = Key::Pose(0, 3);
  const Eigen::VectorXd r03 = RowMajor(gt.at(k03).rotation().matrix());
  EXPECT_EQ(robot1.receive(MessageFrom(0, DgsStage::kRotation, 0, false, {k03},
                                       [&](const Key&) { return r03; })),
            ReceiveStatus::kAccepted);
  EXPECT_FALSE(robot1.iterate());
  EXPECT_EQ(robot1.receive(MessageFrom(0, DgsStage::kRotation, 1, true, {k03},
                                       [&](const Key&) { return r03; })),
            ReceiveStatus::kAccepted);
  EXPECT_TRUE(robot1.iterate());
  EXPECT_TRUE(robot1.initialised());
  // Noise-free chain: robot 1's rotations are exact given robot 0's.
  for (const auto& [k, r] : robot1.relaxedRotations()) {
    EXPECT_LT((r - RowMajor(gt.at(k).rotation().matrix())).norm(), 1e-12) << ToString(k);
  }

  // Without flagged initialisation the uninitialised estimate is used as soon as it arrives.
  AgentOptions unflagged;
  unflagged.flagged_initialisation = false;
  RobotAgent eager(1, parts[1].graph, gt, GaugeAnchor(g), unflagged);
  eager.startRotation();
  EXPECT_FALSE(eager.iterate());
  eager.receive(MessageFrom(0, DgsStage::kRotation, 0, false, {k03},
                            [&](const Key&) { return r03; }));
  EXPECT_TRUE(eager.iterate());
}

// Robot 0's landmark B has no factor of its own left (the robust solve rejected its
// observation), only its separator to robot 1's copy, and robot 1 reaches robot 0 only through
// separators. Robot 0 solves what is tied down and sends only that; robot 1 solves from it
// (never from B's unsolved value) and robot 0 then solves B. Waiting for every group to be tied
// down, as one flag per robot would, deadlocked the two.
TEST(RobotAgent, FlaggedInitialisationSolvesTheGroupsTiedDownAndSendsOnlyThose) {
  const SE3 frame1(SO3::Exp(Vector3(0.0, 0.0, 0.7)), Vector3(3.0, 2.0, 0.0));
  const SE3 step(SO3(), Vector3(1.0, 0.0, 0.0));
  const SE3 a(SO3::Exp(Vector3(0.0, 0.0, 0.3)), Vector3(2.0, 1.0, 0.0));
  const SE3 b(SO3::Exp(Vector3(0.0, 0.0, -0.4)), Vector3(2.0, -1.0, 0.5));
  const Values gt = {{Key::Pose(0, 0), SE3()},  {Key::Pose(0, 1), step},
                     {Key::Pose(1, 0), frame1}, {Key::Pose(1, 1), frame1 * step},
                     {Key::Object(0, 0), a},    {Key::Object(0, 1), b},
                     {Key::Object(1, 0), a},    {Key::Object(1, 1), b}};
  PoseGraph g;
  auto add = [&](Key x, Key y) {
    g.add(RelativePoseFactor(x, y, gt.at(x).between(gt.at(y)), Matrix6::Identity()));
  };
  for (int r = 0; r < 2; ++r) {
    add(Key::Pose(r, 0), Key::Pose(r, 1));
    add(Key::Pose(r, 0), Key::Object(r, 0));
  }
  add(Key::Pose(1, 1), Key::Object(1, 1));
  add(Key::Object(0, 0), Key::Object(1, 0));
  add(Key::Object(0, 1), Key::Object(1, 1));
  const std::vector<RobotSubgraph> parts = PartitionByRobot(g);
  Values initial = gt;  // B starts far off: a receiver using it would not be exact
  initial[Key::Object(0, 1)] = SE3(SO3::Exp(Vector3(1.0, 0.5, 0.0)), Vector3(9.0, 9.0, 9.0));
  RobotAgent robot0(0, parts[0].graph, initial, GaugeAnchor(g));
  RobotAgent robot1(1, parts[1].graph, initial, GaugeAnchor(g));
  const Key kb = Key::Object(0, 1);
  auto keysTo1 = [&]() {
    const std::vector<OutgoingMessage> out = robot0.outgoing();
    EXPECT_EQ(out.size(), 1u);
    return out.empty() ? std::vector<Key>{} : out[0].message.keys;
  };
  robot0.startRotation();
  robot1.startRotation();
  // Before any solve: every shared variable, not flagged (a receiver does not use them).
  EXPECT_EQ(keysTo1(), (std::vector<Key>{Key::Object(0, 0), kb}));
  ASSERT_EQ(robot1.receive(robot0.outgoing()[0].message), ReceiveStatus::kAccepted);
  EXPECT_FALSE(robot1.iterate());
  // Robot 0 solves the group tied to the anchor and holds B; not converged while B waits.
  ASSERT_TRUE(robot0.iterate());
  EXPECT_TRUE(robot0.initialised());
  EXPECT_EQ(robot0.lastChange(), std::numeric_limits<double>::infinity());
  EXPECT_EQ(keysTo1(), std::vector<Key>{Key::Object(0, 0)});
  ASSERT_TRUE(robot0.outgoing()[0].message.initialised);
  ASSERT_EQ(robot1.receive(robot0.outgoing()[0].message), ReceiveStatus::kAccepted);
  ASSERT_TRUE(robot1.iterate());
  for (const auto& [k, r] : robot1.relaxedRotations()) {
    EXPECT_LT((r - RowMajor(gt.at(k).rotation().matrix())).norm(), 1e-12) << ToString(k);
  }
  ASSERT_EQ(robot0.receive(robot1.outgoing()[0].message), ReceiveStatus::kAccepted);
  ASSERT_TRUE(robot0.iterate());
  EXPECT_TRUE(std::isfinite(robot0.lastChange()));
  EXPECT_EQ(keysTo1(), (std::vector<Key>{Key::Object(0, 0), kb}));
  EXPECT_LT((robot0.relaxedRotations().at(kb) - RowMajor(b.rotation().matrix())).norm(), 1e-12);
}

TEST(RobotAgent, ReceiveKeepsOnlyNewerMessages) {
  Values gt;
  const PoseGraph g = test::ChainOfRobots(2, 3, &gt);
  const std::vector<RobotSubgraph> parts = PartitionByRobot(g);
  RobotAgent robot1(1, parts[1].graph, gt, GaugeAnchor(g));
  robot1.startRotation();
  const Key k = Key::Pose(0, 2);
  auto with = [&](std::uint32_t iteration, double v) {
    return MessageFrom(0, DgsStage::kRotation, iteration, true, {k},
                       [&](const Key&) { return Eigen::VectorXd::Constant(9, v); });
  };
  EXPECT_EQ(robot1.receive(with(5, 5.0)), ReceiveStatus::kAccepted);
  EXPECT_EQ(robot1.receive(with(5, 5.0)), ReceiveStatus::kDuplicate);
  EXPECT_EQ(robot1.receive(with(3, 3.0)), ReceiveStatus::kStale);  // reordered: older
  EXPECT_EQ(robot1.receive(with(7, 7.0)), ReceiveStatus::kAccepted);
  EXPECT_EQ(robot1.receive(with(6, 6.0)), ReceiveStatus::kStale);
  EXPECT_EQ(robot1.duplicatesIgnored(), 1);
  EXPECT_EQ(robot1.staleIgnored(), 2);
  // The estimate used is the newest: solving with robot 0's r = 7 * ones.
  ASSERT_TRUE(robot1.iterate());
  RobotAgent reference(1, parts[1].graph, gt, GaugeAnchor(g));
  reference.startRotation();
  reference.receive(with(1, 7.0));
  ASSERT_TRUE(reference.iterate());
  EXPECT_EQ(robot1.relaxedRotations().at(Key::Pose(1, 0)),
            reference.relaxedRotations().at(Key::Pose(1, 0)));
  // A pose-stage message may arrive early; once in the pose stage, rotation messages are stale.
  robot1.startPose();
  EXPECT_EQ(robot1.receive(with(8, 8.0)), ReceiveStatus::kStale);
  // Messages that are not for this robot's neighbour table are rejected loudly.
  Message self = with(9, 1.0);
  self.sender = 1;
  self.keys = {Key::Pose(1, 0)};
  EXPECT_THROW(robot1.receive(self), InvalidInputError);
  Message foreign = with(9, 1.0);
  foreign.keys = {Key::Pose(2, 0)};
  EXPECT_THROW(robot1.receive(foreign), InvalidInputError);
}

TEST(RobotAgent, StateMachineRejectsOutOfOrderCalls) {
  Values gt;
  const PoseGraph g = test::ChainOfRobots(2, 3, &gt);
  const std::vector<RobotSubgraph> parts = PartitionByRobot(g);
  RobotAgent a(0, parts[0].graph, gt, GaugeAnchor(g));
  EXPECT_THROW(a.iterate(), InvalidInputError);
  EXPECT_THROW(a.startPose(), InvalidInputError);
  EXPECT_THROW(a.finish(), InvalidInputError);
  a.startRotation();
  EXPECT_THROW(a.startRotation(), InvalidInputError);
  EXPECT_THROW(a.finish(), InvalidInputError);
  a.startPose();
  a.finish();
  EXPECT_THROW(a.iterate(), InvalidInputError);
  EXPECT_THROW(RobotAgent(2, parts[0].graph, gt, GaugeAnchor(g)), InvalidInputError);
  AgentOptions bad;
  bad.gamma = 2.0;
  EXPECT_THROW(RobotAgent(0, parts[0].graph, gt, GaugeAnchor(g), bad), InvalidInputError);
}

// The calls of the two-level correction and of conjugate gradients, each made where the agent
// cannot answer it: refused, naming the call and what must come first.
TEST(RobotAgent, CoarseAndConjugateGradientCallsOutOfOrderAreRefused) {
  Values gt;
  const PoseGraph g = test::ChainOfRobots(2, 3, &gt);
  const std::vector<RobotSubgraph> parts = PartitionByRobot(g);
  RobotAgent a(0, parts[0].graph, gt, GaugeAnchor(g));
  using test::ThrowsNaming;
  const std::map<int, Eigen::MatrixXd> none;
  EXPECT_TRUE(ThrowsNaming([&] { a.coarseShare(); }, "coarseShare() before a solve"));
  EXPECT_TRUE(ThrowsNaming([&] { a.applyCoarse(none); }, "applyCoarse() in state idle"));
  a.startRotation();
  EXPECT_TRUE(ThrowsNaming([&] { a.coarseShare(); }, "coarseShare() before a solve"));
  a.startPose();
  EXPECT_TRUE(ThrowsNaming([&] { a.applyCoarse(none); }, "in stage 2 before coarseShare()"));
  EXPECT_TRUE(ThrowsNaming([&] { a.firstDirection(); }, "before startPreconditioner()"));
  EXPECT_TRUE(ThrowsNaming([&] { a.refineCoarseMatrix(); }, "outside a conjugate-gradient"));
  EXPECT_TRUE(ThrowsNaming([&] { a.refineCoarseResidual(); }, "before refineCoarseMatrix()"));
  EXPECT_TRUE(ThrowsNaming([&] { a.applyRefineCoarse(none); }, "before refineCoarseMatrix()"));
  a.finish();
  a.startRefine();
  EXPECT_TRUE(ThrowsNaming([&] { a.startPreconditioner(); }, "before beginStep()"));
  EXPECT_TRUE(ThrowsNaming([&] { a.curvature(); }, "curvature() before beginStep()"));
  a.beginStep(0.0);
  a.startPreconditioner();
  EXPECT_TRUE(ThrowsNaming([&] { a.refineCoarseResidual(); }, "before refineCoarseMatrix()"));
  EXPECT_NO_THROW(a.refineCoarseMatrix());
  EXPECT_NO_THROW(a.refineCoarseResidual());
  // The coarse space by pieces: its residual and solution before its matrix of the step.
  EXPECT_TRUE(ThrowsNaming([&] { a.refinePieceResidual(0); },
                           "refinePieceResidual() before refinePieceMatrix() of the step"));
  CoarseMessage pieces;
  EXPECT_TRUE(ThrowsNaming([&] { a.applyRefinePieces(pieces); },
                           "applyRefinePieces() before refinePieceMatrix() of the step"));
  EXPECT_TRUE(
      ThrowsNaming([&] { a.errorBound(0); }, "error-bound window must be in [1, 64], got 0"));
}

// The centralized two-stage estimate is a fixed point of every robot's local solves: given the
// centralized estimates of its neighbours, each robot returns the centralized estimate of its own
// variables, in both stages. (With convergence of the sweeps, DGS therefore converges to it.)
TEST(RobotAgent, CentralizedTwoStageIsTheFixedPointOnEveryBlocksWorldFolder) {
  for (int n : test::kBlocksWorldRobots) {
    SCOPED_TRACE(std::to_string(n) + " robots");
    const Dataset d = ReadG2oFolder(test::BlocksWorldFolder(n));
    const TwoStageResult c = CentralizedTwoStage(d.graph, d.initial);
    const Key anchor = GaugeAnchor(d.graph);
    double worst_r = 0.0, worst_t = 0.0, worst_theta = 0.0;
    for (const RobotSubgraph& part : PartitionByRobot(d.graph)) {
      RobotAgent agent(part.robot, part.graph, d.initial, anchor);
      agent.startRotation();
      Feed(agent, DgsStage::kRotation, 1,
           [&](const Key& k) { return c.relaxed_rotations.at(k); });
      ASSERT_TRUE(agent.iterate());
      for (const auto& [k, r] : agent.relaxedRotations()) {
        worst_r = std::max(worst_r, (r - c.relaxed_rotations.at(k)).norm());
      }
      agent.startPose();
      Feed(agent, DgsStage::kPose, 1,
           [&](const Key& k) { return PoseDelta(c.values.at(k), c.rotations.at(k)); });
      ASSERT_TRUE(agent.iterate());
      for (const auto& [k, x] : agent.estimate()) {
        worst_t = std::max(worst_t, (x.translation() - c.values.at(k).translation()).norm());
        worst_theta = std::max(
            worst_theta,
            SO3::Log(SO3(c.values.at(k).rotation().matrix().transpose() * x.rotation().matrix()))
                .norm());
      }
    }
    EXPECT_LT(worst_r, 1e-10);
    EXPECT_LT(worst_t, 1e-9);
    EXPECT_LT(worst_theta, 1e-10);
  }
}

TEST(RobotAgent, BadOptionsNameTheField) {
  using A = AgentOptions;
  EXPECT_TRUE(test::EachChangeIsRefused<A>({
      {"gamma must be in (0, 2)", [](A& o) { o.gamma = 0.0; }},
      {"gamma must be in (0, 2)", [](A& o) { o.gamma = 2.0; }},
      {"refine_gamma", [](A& o) { o.refine_gamma = std::nan(""); }},
      {"refine_gamma", [](A& o) { o.refine_gamma = 2.0; }},
  }));
}

}  // namespace
}  // namespace moslam
