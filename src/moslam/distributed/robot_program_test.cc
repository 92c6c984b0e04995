// The robot program (robot_program.h): a team of programs, one thread per robot over a shared
// in-memory channel, reproduces the in-process driver in Jacobi order for every solver option
// (two-level, error-bound rule, pose stage and refinement by conjugate gradients or sweeps).
#include "moslam/distributed/robot_program.h"

#include <gtest/gtest.h>

#include <map>
#include <memory>
#include <mutex>
#include <string>
#include <thread>

#include "moslam/common/errors.h"
#include "moslam/distributed/board_channel_test_util.h"
#include "moslam/distributed/dgs_test_util.h"
#include "moslam/distributed/partition.h"
#include "moslam/io/g2o.h"
#include "moslam/metrics/metrics.h"

namespace moslam {
namespace {

using test::BoardChannel;
using test::SharedBoard;

struct TeamOutcome {
  Values values;
  std::map<int, RobotProgramResult> results;
  std::string error;  // the first robot's program that threw, what it threw
};

// A robot's link that fails at its step `fail_at` (counted from 0).
class FailingChannel : public TeamChannel {
 public:
  FailingChannel(SharedBoard& board, int robot, std::size_t fail_at)
      : board_(board, robot), fail_at_(fail_at) {}
  TeamStep step(DgsStage stage, const std::vector<OutgoingMessage>& estimates,
                const TeamReport& report, const CoarseMessage* share,
                const std::vector<WeightMessage>& weights,
                const std::vector<CovarianceMessage>& covariances) override {
    if (board_.steps() == fail_at_) throw Error("the link failed");
    return board_.step(stage, estimates, report, share, weights, covariances);
  }
  std::set<int> absent() const override { return {}; }

 private:
  BoardChannel board_;
  std::size_t fail_at_;
};

// A subgraph listing the factors and priors of `graph` in reverse order.
PoseGraph Reversed(const PoseGraph& graph) {
  PoseGraph out;
  for (auto f = graph.factors().rbegin(); f != graph.factors().rend(); ++f) out.add(*f);
  for (auto p = graph.priors().rbegin(); p != graph.priors().rend(); ++p) out.add(*p);
  return out;
}

// `reversed`: every robot gets its subgraph in reverse order, as a robot reading its own file
// can list its factors in another order than the driver's partition of the whole graph.
// `failing_robot` (when not -1): that robot's link fails at its step 5.
TeamOutcome RunPrograms(const PoseGraph& graph, const Values& initial, const DgsOptions& options,
                        bool reversed = false, int failing_robot = -1) {
  std::vector<RobotSubgraph> parts = PartitionByRobot(graph);
  if (reversed) {
    for (RobotSubgraph& part : parts) part.graph = Reversed(part.graph);
  }
  const Key anchor = GaugeAnchor(graph);
  SharedBoard board(static_cast<int>(parts.size()));
  TeamOutcome outcome;
  std::mutex mutex;
  std::vector<std::thread> threads;
  for (const RobotSubgraph& part : parts) {
    threads.emplace_back([&, part]() {
      AgentOptions ao;
      ao.gamma = options.gamma;
      ao.refine_gamma = options.refinement.gamma;
      ao.flagged_initialisation = options.flagged_initialisation;
      ao.weight_by_information = options.weight_by_information;
      RobotAgent agent(part.robot, part.graph, initial, anchor, ao);
      std::unique_ptr<TeamChannel> channel;
      if (part.robot == failing_robot) {
        channel = std::make_unique<FailingChannel>(board, part.robot, 5);
      } else {
        channel = std::make_unique<BoardChannel>(board, part.robot);
      }
      try {
        RobotProgramResult r = RunRobotProgram(agent, options, *channel);
        std::lock_guard<std::mutex> lock(mutex);
        const Values v = agent.estimate();
        outcome.values.insert(v.begin(), v.end());
        outcome.results[part.robot] = std::move(r);
      } catch (const test::TeamAborted&) {
        // Another robot failed; its error is the one reported.
      } catch (const std::exception& e) {
        board.abort(e.what());
      }
    });
  }
  for (std::thread& t : threads) t.join();
  outcome.error = board.failure();
  return outcome;
}

// `driver` (optional) receives the driver's result.
void ExpectSameAsDriver(const Dataset& data, const DgsOptions& options,
                        DgsResult* driver = nullptr) {
  const DgsResult reference = RunDgs(data.graph, data.initial, options);
  if (driver) *driver = reference;
  const TeamOutcome team = RunPrograms(data.graph, data.initial, options);
  EXPECT_EQ(team.error, "");
  ASSERT_FALSE(team.results.empty());
  // The options at work in the reference (so that equal counts mean something).
  EXPECT_GT(reference.rotation.iterations, 1);
  if (options.coarse_correction) {
    EXPECT_GT(reference.rotation.coarse_corrections, 0);
  }
  if (options.refine) {
    EXPECT_GT(reference.refine.iterations, 0);
  }
  if (options.refine && options.refinement.solver == RefineSolver::kConjugateGradient &&
      options.refinement.preconditioner == RefinePreconditioner::kTwoLevel) {
    EXPECT_GT(reference.refine.coarse_corrections, 0);
  }
  EXPECT_LE(MaxPoseDifference(team.values, reference.values), 1e-9);
  for (const auto& [robot, r] : team.results) {
    SCOPED_TRACE("robot " + std::to_string(robot));
    EXPECT_EQ(r.rotation.iterations, reference.rotation.iterations);
    EXPECT_EQ(r.rotation.status, reference.rotation.status);
    EXPECT_EQ(r.rotation.coarse_corrections, reference.rotation.coarse_corrections);
    EXPECT_EQ(r.pose.iterations, reference.pose.iterations);
    EXPECT_EQ(r.pose.status, reference.pose.status);
    EXPECT_EQ(r.pose.coarse_corrections, reference.pose.coarse_corrections);
    EXPECT_EQ(r.refine.iterations, reference.refine.iterations);
    EXPECT_EQ(r.refine.sweeps, reference.refine.sweeps);
    EXPECT_EQ(r.refine.rejected, reference.refine.rejected);
    EXPECT_EQ(r.refine.backtracks, reference.refine.backtracks);
    EXPECT_EQ(r.refine.status, reference.refine.status);
    EXPECT_EQ(r.refine.coarse_corrections, reference.refine.coarse_corrections);
    ASSERT_EQ(r.refine.steps.size(), reference.refine.steps.size());
    for (std::size_t i = 0; i < r.refine.steps.size(); ++i) {
      const double predicted = reference.refine.steps[i].predicted_decrease;
      EXPECT_NEAR(r.refine.steps[i].predicted_decrease, predicted, 1e-9 * predicted);
      EXPECT_EQ(r.refine.steps[i].backtracks, reference.refine.steps[i].backtracks);
      EXPECT_EQ(r.refine.steps[i].step_scale, reference.refine.steps[i].step_scale);
    }
    if (options.refine) {
      EXPECT_NEAR(r.refine.final_cost, reference.refine.final_cost,
                  1e-12 * reference.refine.final_cost);
    }
  }
}

DgsOptions Jacobi() {
  DgsOptions o;
  o.order = SweepOrder::kJacobi;
  return o;
}

TEST(RobotProgram, TwoLevelErrorBoundAndRefinementEqualTheDriver) {
  const Dataset data = ReadG2oFolder(test::BlocksWorldFolder(4));
  DgsOptions o = Jacobi();
  o.coarse_correction = true;
  o.stopping = StageStopping::kErrorBound;
  o.refine = true;
  ExpectSameAsDriver(data, o);
}

TEST(RobotProgram, OneLevelChangeRuleEqualsTheDriver) {
  const Dataset data = ReadG2oFolder(test::BlocksWorldFolder(4));
  for (bool flagged : {true, false}) {
    SCOPED_TRACE(flagged ? "flagged" : "initial exchange");
    DgsOptions o = Jacobi();
    o.flagged_initialisation = flagged;
    ExpectSameAsDriver(data, o);
  }
}

TEST(RobotProgram, PoseStageAndRefinementVariantsEqualTheDriver) {
  const Dataset data = ReadG2oFolder(test::BlocksWorldFolder(4));
  DgsOptions cg = Jacobi();
  cg.pose_solver = DgsOptions::PoseSolver::kConjugateGradient;
  cg.refine = true;
  cg.refinement.preconditioner = RefinePreconditioner::kSweeps;
  ExpectSameAsDriver(data, cg);
  DgsOptions sweeps = Jacobi();
  sweeps.coarse_correction = true;
  sweeps.refine = true;
  sweeps.refinement.solver = RefineSolver::kSweeps;
  sweeps.refinement.max_iterations = 3;
  sweeps.refinement.max_sweeps = 200;
  ExpectSameAsDriver(data, sweeps);
}

// MIT split among 4 robots of 202 poses, and the two-level pipeline with the refinement.
Dataset MitInFourRobots() {
  Dataset d = ReadG2oFile(std::string(MOSLAM_DATASETS_DIR) + "/pgo/MIT.g2o");
  SplitGraph s = SplitIntoRobots(d.graph, d.initial, 4);
  d.graph = std::move(s.graph);
  d.initial = std::move(s.initial);
  return d;
}

DgsOptions TwoLevelRefined() {
  DgsOptions o = Jacobi();
  o.coarse_correction = true;
  o.refine = true;
  return o;
}

// Halved, rejected and damped refinement steps decided alike by every robot: MIT split among 4
// robots halves steps in Jacobi order too, and without halving rejects them.
TEST(RobotProgram, HalvedAndDampedRefinementStepsEqualTheDriver) {
  const Dataset d = MitInFourRobots();
  DgsOptions o = TwoLevelRefined();
  DgsResult driver;
  ExpectSameAsDriver(d, o, &driver);
  EXPECT_GE(driver.refine.backtracks, 1);
  o.refinement.max_backtracks = 0;
  ExpectSameAsDriver(d, o, &driver);
  EXPECT_GE(driver.refine.rejected, 1);
  EXPECT_EQ(driver.refine.backtracks, 0);
}

// The refinement's coarse space by pieces: every robot assembles the same piece system from the
// matrices shared and applies its own rows of the solution, as the driver's coordinator sends
// them. MIT split among 4 robots of 202 poses, pieces of 50 (pieces 4, 8 and 12 in two robots).
TEST(RobotProgram, RefinementByPiecesEqualsTheDriver) {
  DgsOptions o = TwoLevelRefined();
  o.refinement.coarse_piece_poses = 50;
  DgsResult driver;
  ExpectSameAsDriver(MitInFourRobots(), o, &driver);
  EXPECT_EQ(driver.refine.status, StageStatus::kConverged);
  EXPECT_GT(driver.refine.coarse_corrections, 0);
}

// Each robot's sums run over its factors in one canonical order (local_graph.h), so a robot
// whose subgraph lists them in another order reaches the driver's estimate to the last bit: over
// the pose stage, the refinement and its coarse space by pieces.
TEST(RobotProgram, TheOrderOfARobotsFactorsDoesNotChangeOneBit) {
  const Dataset d = MitInFourRobots();
  DgsOptions o = TwoLevelRefined();
  o.refinement.coarse_piece_poses = 50;
  const DgsResult reference = RunDgs(d.graph, d.initial, o);
  const TeamOutcome team = RunPrograms(d.graph, d.initial, o, true);
  EXPECT_EQ(team.error, "");
  ASSERT_EQ(team.values.size(), reference.values.size());
  for (const auto& [key, x] : reference.values) {
    SCOPED_TRACE(ToString(key));
    EXPECT_EQ(team.values.at(key).translation(), x.translation());
    EXPECT_EQ(team.values.at(key).rotation().matrix(), x.rotation().matrix());
  }
  for (const auto& [robot, r] : team.results) {
    EXPECT_EQ(r.refine.final_cost, reference.refine.final_cost) << "robot " << robot;
  }
}

// A robot whose program throws stops the test team with its error (the others' waits end)
// rather than leaving it waiting for that robot's step forever.
TEST(RobotProgram, ATeamWhoseRobotFailsEndsWithItsError) {
  const Dataset d = MitInFourRobots();
  const TeamOutcome team = RunPrograms(d.graph, d.initial, TwoLevelRefined(), false, 2);
  EXPECT_EQ(team.error, "the link failed");
  EXPECT_TRUE(team.results.empty());
}

TEST(RobotProgram, RefusesGaussSeidelOrderAndAUsedAgent) {
  const Dataset data = ReadG2oFolder(test::BlocksWorldFolder(2));
  const std::vector<RobotSubgraph> parts = PartitionByRobot(data.graph);
  RobotAgent agent(parts[0].robot, parts[0].graph, data.initial, GaugeAnchor(data.graph));
  SharedBoard board(1);
  BoardChannel channel(board, parts[0].robot);
  DgsOptions gs;  // Gauss-Seidel by default
  EXPECT_THROW(RunRobotProgram(agent, gs, channel), InvalidInputError);
  agent.startRotation();
  EXPECT_THROW(RunRobotProgram(agent, Jacobi(), channel), InvalidInputError);
}

}  // namespace
}  // namespace moslam
