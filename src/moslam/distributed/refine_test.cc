// The distributed refinement (dgs_driver.h): Gauss-Newton on the SE(3) cost after the two DGS
// stages, each step solved by robot-by-robot sweeps, must reach the centralized Gauss-Newton
// optimum (NonlinearOptimizer, GN, from the chordal initialisation, the same gauge).
#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <map>
#include <random>
#include <set>
#include <string>

#include "moslam/common/errors.h"
#include "moslam/common/throws_naming_testing.h"
#include "moslam/distributed/centralized_two_stage.h"
#include "moslam/distributed/coarse_system.h"
#include "moslam/distributed/dgs_driver.h"
#include "moslam/distributed/dgs_test_util.h"
#include "moslam/distributed/messages.h"
#include "moslam/distributed/partition.h"
#include "moslam/distributed/robot_agent.h"
#include "moslam/graph/synthetic.h"
#include "moslam/solver/initialization.h"
#include "moslam/solver/optimizer.h"

namespace moslam {
namespace {

// "Done means" of the issue: the refined cost within 1e-4 relative of the centralized optimum.
// (Measured: 1e-11 or closer everywhere tested here; see the report.)
constexpr double kCostTolerance = 1e-4;

OptimizerResult CentralizedGaussNewton(const PoseGraph& g, const Values& initial) {
  const Key anchor = GaugeAnchor(g);
  const auto it = initial.find(anchor);
  return Optimize(g, ChordalInitialization(g, it != initial.end() ? it->second : SE3()));
}

DgsOptions Refined(SweepOrder order = SweepOrder::kGaussSeidel) {
  DgsOptions o;  // the paper's eta = 1e-2 for both stages
  o.order = order;
  o.refine = true;
  return o;
}

double Relative(double cost, double optimum) { return std::abs(cost - optimum) / optimum; }

// A graph of ../shared/datasets/pgo split into `robots` contiguous blocks, and the cost of its
// centralized Gauss-Newton optimum (which must converge).
struct SplitBenchmark {
  SplitGraph split;
  double optimum = 0.0;
};
SplitBenchmark SplitWithOptimum(const std::string& name, int robots) {
  const Dataset d = ReadG2oFile(std::string(MOSLAM_DATASETS_DIR) + "/pgo/" + name + ".g2o");
  SplitBenchmark b{SplitIntoRobots(d.graph, d.initial, robots), 0.0};
  const OptimizerResult gn = CentralizedGaussNewton(b.split.graph, b.split.initial);
  EXPECT_EQ(gn.termination, TerminationStatus::kConverged) << name;
  b.optimum = gn.final_cost;
  return b;
}

TEST(Refine, ReachesTheCentralizedOptimumOnEveryBlocksWorldFolder) {
  for (int n : test::kBlocksWorldRobots) {
    const Dataset d = ReadG2oFolder(test::BlocksWorldFolder(n));
    const OptimizerResult gn = CentralizedGaussNewton(d.graph, d.initial);
    ASSERT_EQ(gn.termination, TerminationStatus::kConverged);
    for (SweepOrder order : {SweepOrder::kGaussSeidel, SweepOrder::kJacobi}) {
      SCOPED_TRACE(std::to_string(n) + " robots, " + ToString(order));
      DgsDriver driver(d.graph, d.initial, Refined(order));
      driver.runRotationStage();
      driver.runPoseStage();
      const double two_stage = d.graph.cost(driver.result().values);
      const RefineReport& report = driver.runRefineStage();
      const DgsResult r = driver.result();
      const double refined = d.graph.cost(r.values);
      EXPECT_EQ(report.status, StageStatus::kConverged);
      // The two-stage estimate is a few percent above the optimum; the refinement removes it.
      EXPECT_GT(Relative(two_stage, gn.final_cost), 1e-2);
      EXPECT_LE(Relative(refined, gn.final_cost), kCostTolerance);
      // The robots' summed shares are the cost of the graph.
      EXPECT_NEAR(report.initial_cost, two_stage, 1e-9 * two_stage);
      EXPECT_NEAR(report.final_cost, refined, 1e-9 * refined);
      // Converged to the same estimate, in the common gauge (no alignment).
      const TrajectoryErrors e = CompareEstimates(r.values, gn.values);
      EXPECT_LE(e.poses.ate, 1e-3);
      EXPECT_LE(e.poses.are_deg, 1e-2);
      const Key anchor = GaugeAnchor(d.graph);
      EXPECT_EQ(r.values.at(anchor).translation(), d.initial.at(anchor).translation());
      // Every accepted step lowered the cost, by about what the conjugate gradients' model
      // predicted: F is nearly quadratic over these steps (gain ratios 0.77-1.03 measured, the
      // lowest on the first step from the two-stage estimate, down to gains of 1e-12 F).
      for (const RefineStepSummary& s : report.steps) {
        if (s.accepted) {
          EXPECT_LE(s.cost_candidate, s.cost_before);
        }
        ASSERT_GT(s.predicted_decrease, 0.0);
        const double gain_ratio = (s.cost_before - s.cost_candidate) / s.predicted_decrease;
        EXPECT_GT(gain_ratio, 0.7) << "step " << s.iteration;
        EXPECT_LT(gain_ratio, 1.1) << "step " << s.iteration;
      }
    }
  }
}

// sphere2500 and torus3D split into contiguous blocks. All of 4, 16 and 64 robots are in the
// benchmark (scripts/bench-dgs.sh); ctest runs the sphere at every size and the torus at 64
// (the slowest split, ~12 s), to stay fast.
class RefineSplit : public ::testing::TestWithParam<std::pair<const char*, int>> {};

TEST_P(RefineSplit, ReachesTheCentralizedOptimum) {
  const auto& [name, robots] = GetParam();
  const auto [s, optimum] = SplitWithOptimum(name, robots);
  const DgsResult r = RunDgs(s.graph, s.initial, Refined());
  EXPECT_EQ(r.refine.status, StageStatus::kConverged);
  EXPECT_LE(Relative(s.graph.cost(r.values), optimum), kCostTolerance);
  EXPECT_EQ(static_cast<int>(r.order.size()), robots);
}

INSTANTIATE_TEST_SUITE_P(Datasets, RefineSplit,
                         ::testing::Values(std::make_pair("sphere2500", 4),
                                           std::make_pair("sphere2500", 16),
                                           std::make_pair("sphere2500", 64),
                                           std::make_pair("torus3D", 64)),
                         [](const auto& param_info) {
                           return std::string(param_info.param.first) + "_" +
                                  std::to_string(param_info.param.second);
                         });

// A prior on a pose of a robot other than the gauge's enters both DGS stages (its rotation and
// pose terms, robot_agent.cc) and the refinement as it enters the centralized solves: the
// two-stage estimate is the centralized two-stage one, the refined one the optimum of the cost
// with the prior; and the prior moves the estimate (so the test could fail).
TEST(Refine, APriorOnAnotherRobotsPoseEntersEveryStage) {
  SyntheticGraphOptions so;
  so.num_robots = 3;
  so.poses_per_robot = 12;
  so.sigma_rotation = 0.03;
  so.sigma_translation = 0.08;
  so.seed = 8;
  const SyntheticGraph sg = MakeSyntheticGraph(so);
  PoseGraph with_prior = sg.graph;
  const Key held = Key::Pose(2, 6);
  const SE3 pulled = sg.ground_truth.at(held) *
                     SE3::Exp((Vector6() << 0.05, -0.04, 0.08, 0.3, -0.2, 0.25).finished());
  with_prior.add(PriorFactor(held, pulled, 400.0 * Matrix6::Identity()));

  const TwoStageResult central = CentralizedTwoStage(with_prior, sg.ground_truth);
  const TwoStageResult without = CentralizedTwoStage(sg.graph, sg.ground_truth);
  EXPECT_GT(CompareEstimates(without.values, central.values).poses.ate, 1e-3);
  DgsOptions tight;
  tight.eta_rotation = tight.eta_pose = 1e-10;
  tight.max_iterations = 20000;
  const DgsResult two_stage = RunDgs(with_prior, sg.ground_truth, tight);
  EXPECT_EQ(two_stage.pose.status, StageStatus::kConverged);
  EXPECT_LE(CompareEstimates(two_stage.values, central.values).poses.ate, 1e-6);

  const OptimizerResult gn = CentralizedGaussNewton(with_prior, sg.ground_truth);
  ASSERT_EQ(gn.termination, TerminationStatus::kConverged);
  const DgsResult refined = RunDgs(with_prior, sg.ground_truth, Refined());
  EXPECT_EQ(refined.refine.status, StageStatus::kConverged);
  EXPECT_LE(Relative(with_prior.cost(refined.values), gn.final_cost), kCostTolerance);
  EXPECT_LE(CompareEstimates(refined.values, gn.values).poses.ate, 1e-4);
}

// One robot owning everything: each step's sweeps solve the whole system exactly, so the
// refinement is centralized Gauss-Newton, iterate for iterate.
TEST(Refine, AloneItIsCentralizedGaussNewton) {
  SyntheticGraphOptions so;
  so.num_robots = 1;
  so.poses_per_robot = 40;
  so.sigma_rotation = 0.05;
  so.sigma_translation = 0.1;
  so.seed = 4;
  const SyntheticGraph sg = MakeSyntheticGraph(so);
  for (RefineSolver solver : {RefineSolver::kConjugateGradient, RefineSolver::kSweeps}) {
    SCOPED_TRACE(ToString(solver));
    DgsOptions o = Refined();
    o.refinement.solver = solver;
    DgsDriver driver(sg.graph, sg.ground_truth, o);
    driver.runRotationStage();
    driver.runPoseStage();
    const Values two_stage = driver.result().values;
    const RefineReport& report = driver.runRefineStage();
    const OptimizerResult gn = Optimize(sg.graph, two_stage);
    EXPECT_EQ(report.status, StageStatus::kConverged);
    EXPECT_EQ(report.rejected, 0);
    // Same iterates: the same number of steps (the last only confirms), the same estimate.
    EXPECT_EQ(report.iterations, gn.iterations);
    ASSERT_EQ(gn.history.size(), report.steps.size());
    for (std::size_t i = 0; i < gn.history.size(); ++i) {
      EXPECT_NEAR(report.steps[i].cost_candidate, gn.history[i].cost,
                  1e-9 * gn.history[i].cost);
    }
    const TrajectoryErrors e = CompareEstimates(driver.result().values, gn.values);
    EXPECT_LE(e.poses.ate, 1e-9);
    EXPECT_LE(e.poses.are_deg, 1e-8);
    // No neighbours: nothing crosses the network but the coordinator's own decisions (none).
    EXPECT_EQ(report.messages, 0);
  }
}

// The plain sweeps (no conjugate gradients) converge too, much more slowly; over-relaxation
// (SOR, gamma 1.9) is what makes them practical (measured: 9 robots, 7605 sweeps at gamma 1,
// 364 at 1.9).
TEST(Refine, PlainSweepsWithOverRelaxationReachTheOptimum) {
  const Dataset d = ReadG2oFolder(test::BlocksWorldFolder(4));
  const OptimizerResult gn = CentralizedGaussNewton(d.graph, d.initial);
  DgsOptions o = Refined();
  o.refinement.solver = RefineSolver::kSweeps;
  o.refinement.gamma = 1.9;
  o.refinement.sweep_tolerance = 1e-2;
  const DgsResult r = RunDgs(d.graph, d.initial, o);
  EXPECT_EQ(r.refine.status, StageStatus::kConverged);
  EXPECT_LE(Relative(d.graph.cost(r.values), gn.final_cost), kCostTolerance);
}

// Every message the refinement sends is serialized and counted: per sweep one increment
// message per (robot, neighbouring robot), 6 numbers per shared variable (as stage 2); plus the
// 32-byte control messages.
TEST(Refine, CountsIncrementControlAndCoarseMessages) {
  const Dataset d = ReadG2oFolder(test::BlocksWorldFolder(9));
  struct Case {
    RefineSolver solver;
    RefinePreconditioner preconditioner;
  };
  for (const Case c : {Case{RefineSolver::kConjugateGradient, RefinePreconditioner::kTwoLevel},
                       Case{RefineSolver::kConjugateGradient, RefinePreconditioner::kSweeps},
                       Case{RefineSolver::kSweeps, RefinePreconditioner::kSweeps}}) {
    const RefineSolver solver = c.solver;
    const bool two_level = c.preconditioner == RefinePreconditioner::kTwoLevel;
    SCOPED_TRACE(ToString(solver) + " " + ToString(c.preconditioner));
    DgsOptions o = Refined();
    o.refinement.solver = solver;
    o.refinement.preconditioner = c.preconditioner;
    o.refinement.gamma = solver == RefineSolver::kSweeps ? 1.9 : 1.0;
    DgsDriver driver(d.graph, d.initial, o);
    driver.runRotationStage();
    driver.runPoseStage();
    const DgsResult before = driver.result();
    driver.runRefineStage();
    const DgsResult r = driver.result();

    std::int64_t per_sweep = 0, bytes_per_sweep = 0;
    for (const RobotSubgraph& part : PartitionByRobot(d.graph)) {
      for (const auto& [to, keys] : driver.agent(part.robot).sharedWith()) {
        ++per_sweep;
        std::int64_t key_bytes = 0;
        for (const Key& k : keys) key_bytes += (k.index << 1) < 128 ? 1 : 2;
        bytes_per_sweep += static_cast<std::int64_t>(kMessageHeaderBytes) + key_bytes +
                           static_cast<std::int64_t>(keys.size()) * 6 * 8;
      }
    }
    const RefineReport& f = r.refine;
    ASSERT_GT(f.sweeps, 0);
    std::int64_t messages = 0, bytes = 0, control = 0, coarse = 0, coarse_bytes = 0, sweeps = 0;
    for (const DgsIterationStats& s : r.history) {
      if (s.stage != DgsStage::kRefine) continue;
      ++sweeps;
      EXPECT_EQ(s.messages - s.control_messages - s.coarse_messages, per_sweep);
      EXPECT_EQ(s.bytes - s.control_bytes - s.coarse_bytes, bytes_per_sweep);
      EXPECT_EQ(s.control_bytes, s.control_messages * 32);
      messages += s.messages;
      bytes += s.bytes;
      control += s.control_messages;
      coarse += s.coarse_messages;
      coarse_bytes += s.coarse_bytes;
    }
    EXPECT_EQ(sweeps, f.sweeps);
    EXPECT_EQ(messages, f.messages);
    EXPECT_EQ(bytes, f.bytes);
    EXPECT_EQ(control, f.control_messages);
    EXPECT_EQ(coarse, f.coarse_messages);
    EXPECT_EQ(coarse_bytes, f.coarse_bytes);
    EXPECT_EQ(f.control_bytes, 32 * f.control_messages);
    EXPECT_EQ(r.messages, before.messages + f.messages);
    EXPECT_EQ(r.bytes, before.bytes + f.bytes);
    // Control: the 8 other robots report to the coordinator and hear back, a fixed number of
    // times per sweep / iteration / step.
    const int others = driver.numAgents() - 1;
    std::int64_t expected = others;  // the initial cost reports
    for (const RefineStepSummary& s : f.steps) {
      expected += 2 * others;  // cost reports and the step decision
      if (solver == RefineSolver::kSweeps) {
        expected += 2 * others * s.sweeps;  // a report and a decision per sweep
      } else {
        // Two sweeps per conjugate-gradient iteration (forward, backward); per iteration a
        // curvature and a residual all-reduce, plus the initial residual one.
        const int cg_iterations = s.sweeps / 2 - 1;
        expected += 2 * others * (1 + 2 * cg_iterations);
      }
    }
    EXPECT_EQ(f.control_messages, expected);
    // Coarse: per step the 8 other robots send their rows of the coarse matrix; per coarse
    // correction (one per preconditioning) they send a residual and hear back a solution.
    if (two_level) {
      EXPECT_GT(f.coarse_corrections, 0);
      EXPECT_EQ(f.coarse_messages, others * (f.iterations + 2 * f.coarse_corrections));
      EXPECT_GT(f.coarse_bytes, 0);
    } else {
      EXPECT_EQ(f.coarse_corrections, 0);
      EXPECT_EQ(f.coarse_messages, 0);
    }
  }
}

// Too few sweeps in the two stages leave a poor start; the first full Gauss-Newton step raises
// the cost. The coordinator rejects it, the robots damp their blocks and retry, and the
// refinement still reaches the centralized optimum (here Levenberg-Marquardt's: GN from the
// chordal start converges too, to the same cost).
TEST(Refine, ARejectedStepIsRetriedWithDamping) {
  SyntheticGraphOptions so;
  so.num_robots = 3;
  so.poses_per_robot = 15;
  so.sigma_rotation = 0.3;
  so.sigma_translation = 0.3;
  so.loop_closure_radius = 2.0;
  so.max_loop_closures_per_pose = 3;
  so.seed = 1;
  const SyntheticGraph sg = MakeSyntheticGraph(so);
  DgsOptions o = Refined();
  o.max_iterations = 1;  // one sweep per stage
  o.refinement.max_backtracks = 0;  // rejected at once
  const DgsResult r = RunDgs(sg.graph, sg.ground_truth, o);
  EXPECT_EQ(r.refine.status, StageStatus::kConverged);
  ASSERT_GE(r.refine.rejected, 1);
  bool damped_after_rejection = false;
  for (std::size_t i = 0; i < r.refine.steps.size(); ++i) {
    const RefineStepSummary& s = r.refine.steps[i];
    if (!s.accepted) {
      EXPECT_GT(s.cost_candidate, s.cost_before);
      ASSERT_LT(i + 1, r.refine.steps.size());
      EXPECT_GT(r.refine.steps[i + 1].lambda, s.lambda);  // retried with more damping
      EXPECT_EQ(r.refine.steps[i + 1].cost_before, s.cost_before);  // from the same estimate
      damped_after_rejection = true;
    }
  }
  EXPECT_TRUE(damped_after_rejection);
  OptimizerOptions lm;
  lm.method = Method::kLevenbergMarquardt;
  const OptimizerResult central = Optimize(
      sg.graph, ChordalInitialization(sg.graph, sg.ground_truth.at(GaugeAnchor(sg.graph))), lm);
  EXPECT_LE(Relative(sg.graph.cost(r.values), central.final_cost), 1e-9);
}

// After an accepted damped step the damping decreases by 10 per step down to min_lambda; stopping
// it at once (min_lambda = initial_lambda, the rule before) made the refinement cycle on MIT split
// among 4 robots: the undamped step rejected, the damped one accepted, half the steps rejected
// and the estimate 9 % above the optimum after 100 (measured). The driver's default options
// (Gauss-Seidel, one-level stages, pose stage by sweeps).
TEST(Refine, DampingDecreasesGraduallyAfterARejectedStep) {
  const auto [s, optimum] = SplitWithOptimum("MIT", 4);
  DgsOptions o = Refined();
  o.refinement.max_backtracks = 0;  // the damping alone
  const DgsResult r = RunDgs(s.graph, s.initial, o);
  ASSERT_GE(r.refine.rejected, 1);
  EXPECT_EQ(r.refine.status, StageStatus::kConverged);
  EXPECT_LE(Relative(s.graph.cost(r.values), optimum), 1e-9);
  // Accepted damped steps divide lambda by 10 until it falls below min_lambda.
  for (std::size_t i = 0; i + 1 < r.refine.steps.size(); ++i) {
    const RefineStepSummary& step = r.refine.steps[i];
    if (!step.accepted || step.lambda == 0.0) continue;
    const double next = step.lambda / 10.0;
    EXPECT_DOUBLE_EQ(r.refine.steps[i + 1].lambda, next < o.refinement.min_lambda ? 0.0 : next);
  }

  DgsOptions before = o;
  before.refinement.min_lambda = before.refinement.initial_lambda;
  const DgsResult cycling = RunDgs(s.graph, s.initial, before);
  EXPECT_EQ(cycling.refine.status, StageStatus::kMaxIterations);
  EXPECT_GT(cycling.refine.rejected, 40);
  EXPECT_GT(Relative(s.graph.cost(cycling.values), optimum), 1e-2);
}

// A step that raises F is halved (one more cost report each, no new linear solve) before it is
// rejected and damped. INTEL split between 2 robots (`moslam dgs --refine`'s pipeline): without
// halving the damped steps crawl and the refinement stops at its step limit, 8e-6 above the
// optimum with 47 of 100 steps rejected (README, "The 2D benchmark graphs"); halved, its steps
// reach the optimum, none rejected.
TEST(Refine, AStepThatRaisesTheCostIsHalvedBeforeItIsRejected) {
  const auto [s, optimum] = SplitWithOptimum("input_INTEL_g2o", 2);
  DgsOptions o = Refined();
  o.coarse_correction = true;
  o.pose_solver = DgsOptions::PoseSolver::kConjugateGradient;
  const DgsResult r = RunDgs(s.graph, s.initial, o);
  EXPECT_EQ(r.refine.status, StageStatus::kConverged);
  EXPECT_LE(Relative(s.graph.cost(r.values), optimum), 1e-9);
  EXPECT_EQ(r.refine.rejected, 0);
  int halved = 0;
  for (const RefineStepSummary& step : r.refine.steps) {
    EXPECT_EQ(step.step_scale, std::ldexp(1.0, -step.backtracks));
    EXPECT_LE(step.backtracks, o.refinement.max_backtracks);
    if (step.backtracks == 0) continue;
    ++halved;
    // Accepted halved: F fell by the Armijo fraction of the model's decrease over the step.
    EXPECT_TRUE(step.accepted);
    EXPECT_GE(step.cost_before - step.cost_candidate,
              kArmijoFraction * step.step_scale * step.predicted_decrease);
  }
  EXPECT_GE(halved, 2);
  int total = 0;
  for (const RefineStepSummary& step : r.refine.steps) total += step.backtracks;
  EXPECT_EQ(r.refine.backtracks, total);

  o.refinement.max_backtracks = 0;
  const DgsResult damped = RunDgs(s.graph, s.initial, o);
  EXPECT_EQ(damped.refine.backtracks, 0);
  EXPECT_GT(damped.refine.rejected, 20);
  EXPECT_GT(Relative(s.graph.cost(damped.values), optimum), 1e-7);
}

// Step `iteration` of the refinement, whole, raising F from 100 to 120 where the model predicted
// a decrease of 10.
RefineStepSummary RaisingStep(int iteration) {
  RefineStepSummary s;
  s.iteration = iteration;
  s.cost_before = 100.0;
  s.cost_candidate = 120.0;
  s.predicted_decrease = 10.0;
  return s;
}

// The decision itself: a whole step that raises F is halved while halvings are left, a halved
// one needs the Armijo decrease, and a halved step's small gain is no convergence.
TEST(Refine, TheStepDecisionHalvesThenRejects) {
  DgsOptions::Refinement opt;
  opt.max_backtracks = 2;
  RefineReport report;
  RefineStepSummary s = RaisingStep(3);
  double lambda = 0.0;
  RefineDecision d = DecideRefineStep(s, opt, lambda, report);
  EXPECT_TRUE(d.backtrack);
  EXPECT_FALSE(d.accept || d.finished);
  EXPECT_EQ(report.backtracks, 1);
  EXPECT_EQ(report.rejected, 0);
  EXPECT_EQ(lambda, 0.0);
  s.backtracks = 1;
  s.step_scale = 0.5;
  s.cost_candidate = 100.0 - 0.5 * kArmijoFraction * 10.0 * 0.5;  // falls, by too little
  d = DecideRefineStep(s, opt, lambda, report);
  EXPECT_TRUE(d.backtrack);
  s.backtracks = 2;
  s.step_scale = 0.25;
  d = DecideRefineStep(s, opt, lambda, report);  // the last halving used: rejected, damped
  EXPECT_FALSE(d.backtrack || d.accept || d.finished);
  EXPECT_EQ(report.rejected, 1);
  EXPECT_EQ(lambda, opt.initial_lambda);
  s.cost_candidate = 100.0 - 1e-12;  // a gain below relative_cost_tolerance * F ...
  s.predicted_decrease = 0.0;        // ... by plain sweeps (no prediction)
  lambda = 0.0;
  d = DecideRefineStep(s, opt, lambda, report);
  EXPECT_TRUE(d.accept);
  EXPECT_FALSE(d.finished);  // ... of a halved step: not converged
  s.backtracks = 0;
  s.step_scale = 1.0;
  d = DecideRefineStep(s, opt, lambda, report);
  EXPECT_TRUE(d.accept && d.finished);  // of a whole step: converged
  EXPECT_EQ(report.status, StageStatus::kConverged);
  s.iteration = opt.max_iterations;  // the step limit does not cut a halving short
  s.cost_candidate = 120.0;
  d = DecideRefineStep(s, opt, lambda, report);
  EXPECT_TRUE(d.backtrack);
  EXPECT_FALSE(d.finished);
}

// Steps that keep raising F are rejected with the damping raised tenfold each time, from
// initial_lambda; once it passes max_lambda the refinement gives up: finished, not converged.
TEST(Refine, GivesUpWithNoDecreasingStepOnceTheDampingPassesItsBound) {
  DgsOptions::Refinement opt;
  opt.max_backtracks = 0;
  opt.initial_lambda = 1e-4;
  opt.max_lambda = 1e10;
  RefineReport report;
  report.status = StageStatus::kMaxIterations;  // as the stage starts it
  RefineStepSummary s = RaisingStep(1);
  double lambda = 0.0;
  int rejected = 0;
  for (RefineDecision d; !d.finished && rejected < 100; ++rejected) {
    d = DecideRefineStep(s, opt, lambda, report);
    EXPECT_FALSE(d.accept || d.backtrack);
    ++s.iteration;
  }
  // 1e-4 after the first rejection, x10 after each: 1e11 > 1e10 after the 16th.
  EXPECT_EQ(rejected, 16);
  EXPECT_EQ(report.rejected, 16);
  EXPECT_DOUBLE_EQ(lambda, 1e11);
  EXPECT_EQ(report.status, StageStatus::kNoDecreasingStep);
  EXPECT_EQ(ToString(report.status), "no decreasing step");
}

// A graph its measurements fit exactly (kitti_08: odometry alone, a tree) has F = 0 at the
// optimum; the steps bring F to rounding, where no gain is a fraction of F. The refinement stops
// there by the absolute tolerance, as the centralized optimizer does (without it, in 2 robots: 50
// steps, 27 of them rejected, gaining and losing rounding).
TEST(Refine, StopsWhenTheCostFallsToRounding) {
  const Dataset d = ReadG2oFile(std::string(MOSLAM_DATASETS_DIR) + "/pgo/kitti_08.g2o");
  ASSERT_EQ(d.graph.factors().size(), 4070u);  // 4071 poses (no vertex lines)
  const SplitGraph s = SplitIntoRobots(d.graph, d.initial, 2);
  DgsOptions o = Refined();
  const DgsResult r = RunDgs(s.graph, s.initial, o);
  EXPECT_EQ(r.refine.status, StageStatus::kConverged);
  EXPECT_GT(r.refine.initial_cost, 1e6 * o.refinement.absolute_cost_tolerance);
  EXPECT_LE(r.refine.final_cost, o.refinement.absolute_cost_tolerance);
  EXPECT_EQ(r.refine.rejected, 0);
  EXPECT_LE(r.refine.iterations, 6);

  o.refinement.absolute_cost_tolerance = 0.0;
  const DgsResult rounding = RunDgs(s.graph, s.initial, o);
  EXPECT_GT(rounding.refine.rejected, 10);
}

// Duplicated, replayed (stale) and shuffled messages are ignored by the agents: the refinement
// computes exactly the same estimate.
TEST(Refine, DuplicatedReorderedAndStaleMessagesLeaveTheResultUnchanged) {
  const Dataset d = ReadG2oFolder(test::BlocksWorldFolder(9));
  for (SweepOrder order : {SweepOrder::kGaussSeidel, SweepOrder::kJacobi}) {
    SCOPED_TRACE(ToString(order));
    const DgsResult clean = RunDgs(d.graph, d.initial, Refined(order));
    FaultInjection faults;
    faults.duplicate = true;
    faults.replay_stale = true;
    faults.shuffle = true;
    faults.seed = 7;
    const DgsResult noisy = RunDgs(d.graph, d.initial, Refined(order), faults);
    EXPECT_GT(noisy.duplicates_ignored, 0);
    EXPECT_GT(noisy.stale_ignored, 0);
    EXPECT_EQ(noisy.refine.sweeps, clean.refine.sweeps);
    ASSERT_EQ(noisy.values.size(), clean.values.size());
    for (const auto& [k, x] : clean.values) {
      EXPECT_EQ(noisy.values.at(k).translation(), x.translation()) << ToString(k);
      EXPECT_EQ(noisy.values.at(k).rotation().matrix(), x.rotation().matrix()) << ToString(k);
    }
  }
}

// A robot that stops answering at the start of refinement step 2 keeps its estimate after
// step 1; the others hold its variables fixed, count its separators and converge.
TEST(Refine, ARobotThatStopsAnsweringDoesNotStopTheOthers) {
  const Dataset d = ReadG2oFolder(test::BlocksWorldFolder(9));
  const int silent = 4;
  FaultInjection faults;
  faults.silent = {{silent, DgsStage::kRefine, 2}};
  DgsOptions one_step = Refined();
  one_step.refinement.max_iterations = 1;
  const DgsResult after_one = RunDgs(d.graph, d.initial, one_step);
  const DgsResult r = RunDgs(d.graph, d.initial, Refined(), faults);
  ASSERT_EQ(r.silent.size(), 1u);
  EXPECT_EQ(r.silent[0].robot, silent);
  EXPECT_EQ(r.silent[0].stage, DgsStage::kRefine);
  EXPECT_EQ(r.silent[0].iteration, 2);
  EXPECT_EQ(r.refine.status, StageStatus::kConverged);
  EXPECT_GT(r.refine.iterations, 2);
  std::size_t silent_variables = 0;
  for (const auto& [k, x] : after_one.values) {
    if (k.robot != silent) continue;
    ++silent_variables;
    EXPECT_EQ(r.values.at(k).translation(), x.translation());
  }
  EXPECT_GT(silent_variables, 0u);
  // Lower than after one step, and no live robot can improve further: the centralized GN
  // with the silent robot's poses fixed (a very strong prior) gains nothing.
  const double cost = d.graph.cost(r.values);
  EXPECT_LT(cost, d.graph.cost(after_one.values));
  PoseGraph pinned = d.graph;
  Matrix6 strong = Matrix6::Identity() * 1e12;
  for (const auto& [k, x] : r.values) {
    if (k.robot == silent) pinned.add(PriorFactor(k, x, strong));
  }
  const OptimizerResult polish = Optimize(pinned, r.values);
  EXPECT_LE(Relative(cost, d.graph.cost(polish.values)), kCostTolerance);
  EXPECT_LE(d.graph.cost(polish.values), cost * (1.0 + 1e-12));
}

// When every robot stops answering, nobody is left to coordinate: the refinement ends (no
// coordinator, nothing more to gain) with each robot's estimate as it stood, before any step
// when the team falls silent at step 1, after the first when at step 2.
TEST(Refine, ATeamThatFallsSilentEndsWithEachRobotsLastEstimate) {
  const Dataset d = ReadG2oFolder(test::BlocksWorldFolder(4));
  DgsOptions unrefined = Refined();
  unrefined.refine = false;
  DgsOptions one_step = Refined();
  one_step.refinement.max_iterations = 1;
  const DgsResult before = RunDgs(d.graph, d.initial, unrefined);
  const DgsResult after_one = RunDgs(d.graph, d.initial, one_step);
  ASSERT_LT(d.graph.cost(after_one.values), d.graph.cost(before.values));
  for (int step : {1, 2}) {
    SCOPED_TRACE("silent from step " + std::to_string(step));
    FaultInjection faults;
    for (int robot = 0; robot < 4; ++robot) {
      faults.silent.push_back({robot, DgsStage::kRefine, step});
    }
    const DgsResult r = RunDgs(d.graph, d.initial, Refined(), faults);
    EXPECT_EQ(r.refine.status, StageStatus::kConverged);
    EXPECT_EQ(r.refine.iterations, step - 1);
    EXPECT_EQ(r.silent.size(), 4u);
    const Values& expected = step == 1 ? before.values : after_one.values;
    ASSERT_EQ(r.values.size(), expected.size());
    for (const auto& [k, x] : expected) {
      EXPECT_EQ(r.values.at(k).translation(), x.translation()) << ToString(k);
      EXPECT_EQ(r.values.at(k).rotation().matrix(), x.rotation().matrix()) << ToString(k);
    }
  }
}

// Objects: object-pose edges are inner, object-object edges separators; the refinement reaches
// the centralized optimum of poses and objects.
TEST(Refine, HandlesObjectLandmarks) {
  PoseGraph g;
  Values gt;
  auto at = [](double x, double y, double yaw) {
    return SE3(SO3::Exp(Vector3(0, 0, yaw)), Vector3(x, y, 0.1 * x));
  };
  for (int r = 0; r < 3; ++r) {
    for (int i = 0; i < 8; ++i) {
      gt[Key::Pose(r, static_cast<std::uint64_t>(i))] = at(i, 3.0 * r, 0.2 * i + r);
    }
    for (int k = 0; k < 2; ++k) {
      gt[Key::Object(r, static_cast<std::uint64_t>(k))] = at(2.0 + 3 * k, 1.5, 0.5 * k);
    }
  }
  std::mt19937 rng(5);
  std::normal_distribution<double> noise(0.0, 0.05);
  auto edge = [&](Key a, Key b, const SE3& z) {
    Vector6 xi;
    for (int j = 0; j < 6; ++j) xi(j) = noise(rng);
    g.add(RelativePoseFactor(a, b, z.retract(xi), Matrix6::Identity()));
  };
  for (int r = 0; r < 3; ++r) {
    for (int i = 0; i < 7; ++i) {
      const Key a = Key::Pose(r, static_cast<std::uint64_t>(i));
      const Key b = Key::Pose(r, static_cast<std::uint64_t>(i + 1));
      edge(a, b, gt.at(a).between(gt.at(b)));
    }
    for (int k = 0; k < 2; ++k) {
      const Key o = Key::Object(r, static_cast<std::uint64_t>(k));
      for (int i : {2 * k, 2 * k + 4}) {
        const Key p = Key::Pose(r, static_cast<std::uint64_t>(i));
        edge(p, o, gt.at(p).between(gt.at(o)));
      }
    }
  }
  for (int r = 1; r < 3; ++r) {
    for (int k = 0; k < 2; ++k) {
      g.add(RelativePoseFactor(Key::Object(r, static_cast<std::uint64_t>(k)),
                               Key::Object(r - 1, static_cast<std::uint64_t>(k)), SE3(),
                               Matrix6::Identity()));
    }
  }
  const OptimizerResult gn = CentralizedGaussNewton(g, gt);
  const DgsResult r = RunDgs(g, gt, Refined());
  EXPECT_EQ(r.refine.status, StageStatus::kConverged);
  EXPECT_LE(Relative(g.cost(r.values), gn.final_cost), kCostTolerance);
  const TrajectoryErrors e = CompareEstimates(r.values, gn.values);
  EXPECT_EQ(e.objects.count, 6);
  EXPECT_LE(e.objects.ate, 1e-6);
  EXPECT_LE(e.poses.ate, 1e-6);
}

TEST(Refine, StateMachineAndOptions) {
  Values gt;
  const PoseGraph g = test::ChainOfRobots(2, 3, &gt);
  const std::vector<RobotSubgraph> parts = PartitionByRobot(g);
  RobotAgent a(0, parts[0].graph, gt, GaugeAnchor(g));
  EXPECT_THROW(a.startRefine(), InvalidInputError);  // kIdle
  EXPECT_THROW(a.beginStep(0.0), InvalidInputError);
  a.startRotation();
  EXPECT_THROW(a.startRefine(), InvalidInputError);
  a.startPose();
  EXPECT_THROW(a.startRefine(), InvalidInputError);
  EXPECT_THROW(a.costShare(false), InvalidInputError);
  a.finish();
  a.startRefine();
  EXPECT_EQ(a.state(), AgentState::kRefine);
  EXPECT_THROW(a.iterate(), InvalidInputError);  // before beginStep()
  EXPECT_THROW(a.beginStep(-1.0), InvalidInputError);
  a.beginStep(0.0);
  EXPECT_TRUE(a.iterate());
  EXPECT_EQ(a.outgoing().size(), 1u);
  EXPECT_EQ(a.outgoing()[0].message.stage, DgsStage::kRefine);
  EXPECT_THROW(a.scaleStep(0.0), InvalidInputError);
  EXPECT_THROW(a.scaleStep(1.5), InvalidInputError);
  EXPECT_THROW(a.scaleStep(std::nan("")), InvalidInputError);
  // A halved step: F at x Exp(delta / 2) on the robot's own factors, and what it accepts.
  const double whole = a.costShare(true);
  a.scaleStep(0.5);
  const double half = a.costShare(true);
  EXPECT_NE(half, whole);
  a.acceptStep();
  a.beginStep(0.0);
  EXPECT_EQ(a.costShare(false), half);  // at the accepted halved step
  EXPECT_TRUE(a.iterate());
  a.acceptStep();
  a.finishRefine();
  EXPECT_EQ(a.state(), AgentState::kDone);
  EXPECT_TRUE(a.refined());
  EXPECT_THROW(a.startRefine(), InvalidInputError);  // once

  DgsOptions o;
  auto rejects = [&](auto mutate) {
    DgsOptions bad = o;
    mutate(bad.refinement);
    EXPECT_THROW(bad.validate(), InvalidInputError);
  };
  rejects([](DgsOptions::Refinement& f) { f.max_iterations = 0; });
  rejects([](DgsOptions::Refinement& f) { f.max_sweeps = 0; });
  rejects([](DgsOptions::Refinement& f) { f.gamma = 2.0; });
  rejects([](DgsOptions::Refinement& f) { f.cg_tolerance = -1.0; });
  rejects([](DgsOptions::Refinement& f) { f.relative_cost_tolerance = std::nan(""); });
  rejects([](DgsOptions::Refinement& f) { f.absolute_cost_tolerance = -1e-20; });
  rejects([](DgsOptions::Refinement& f) { f.initial_lambda = 0.0; });
  rejects([](DgsOptions::Refinement& f) { f.min_lambda = 0.0; });
  rejects([](DgsOptions::Refinement& f) { f.min_lambda = 2.0 * f.initial_lambda; });
  rejects([](DgsOptions::Refinement& f) { f.max_backtracks = -1; });
  rejects([](DgsOptions::Refinement& f) { f.max_backtracks = 31; });

  // The refinement runs once, after the pose stage.
  DgsDriver driver(g, gt, o);
  EXPECT_THROW(driver.runRefineStage(), InvalidInputError);
  driver.runRotationStage();
  driver.runPoseStage();
  driver.runRefineStage();
  EXPECT_THROW(driver.runRefineStage(), InvalidInputError);
}

}  // namespace
}  // namespace moslam

namespace moslam {
namespace {

// The refinement's coarse correction is the Galerkin correction over the robots' rigid motions:
// after it the residual projected on that space is zero, which holds only if every robot moved
// its copies of the neighbours' variables exactly as their owners moved them (basis, centres,
// coupling blocks and the coordinator's solve all consistent). Driven by hand: z = 0, one
// correction, projected residual before and after.
// The two stages, then every robot at the start of the first refinement step's conjugate
// gradients (z = 0: the residual is -g), driven by hand; the robots' ids.
std::vector<int> AtTheFirstRefinementStep(DgsDriver& driver) {
  driver.runRotationStage();
  driver.runPoseStage();
  std::vector<int> robots;
  for (int r = 0; r < driver.numAgents(); ++r) {
    robots.push_back(r);
    RobotAgent& a = driver.agent(r);
    a.startRefine();
    a.beginStep(0.0);
    a.startPreconditioner();
    EXPECT_TRUE(a.refineCoarseReady()) << "robot " << r;
  }
  return robots;
}

TEST(RefineTwoLevel, CoarseCorrectionZeroesTheProjectedResidual) {
  const Dataset d = ReadG2oFolder(test::BlocksWorldFolder(9));
  DgsDriver driver(d.graph, d.initial, Refined());
  const std::vector<int> robots = AtTheFirstRefinementStep(driver);
  CoarseSystem coarse(robots, 6);
  Eigen::MatrixXd B(coarse.rows(), 1);
  for (int r : robots) {
    const CoarseShare share = driver.agent(r).refineCoarseMatrix();
    CoarseMessage m;
    m.kind = CoarseKind::kMatrix;
    m.stage = DgsStage::kRefine;
    m.sender = r;
    m.k = 6;
    m.ncols = 1;
    m.center = FlattenMatrix(share.center);
    m.diagonal = FlattenMatrix(share.diagonal);
    for (const auto& [s, block] : share.coupling) m.blocks.emplace_back(s, FlattenMatrix(block));
    coarse.addShare(DecodeCoarseMessage(EncodeCoarseMessage(m)));
    B.middleRows(coarse.index(r), 6) = driver.agent(r).refineCoarseResidual();
  }
  ASSERT_TRUE(coarse.factorize());
  Eigen::MatrixXd Y;
  ASSERT_TRUE(coarse.solve(B, &Y));
  double before = 0.0, after = 0.0;
  for (int r : robots) before = std::max(before, B.middleRows(coarse.index(r), 6).norm());
  for (int r : robots) {
    RobotAgent& a = driver.agent(r);
    const CoarseMessage got = DecodeCoarseMessage(EncodeCoarseMessage(
        coarse.solutionFor(r, a.neighbourRobots(), Y, DgsStage::kRefine, 0, 1)));
    std::map<int, Eigen::MatrixXd> y;
    for (const auto& [s, block] : got.blocks) y[s] = UnflattenMatrix(block, 6, 1);
    a.applyRefineCoarse(y);
  }
  for (int r : robots) after = std::max(after, driver.agent(r).refineCoarseResidual().norm());
  EXPECT_GT(before, 1e-3);
  EXPECT_LT(after, 1e-9 * before);
}

// The second level is what keeps the refinement's sweeps from growing with the team: on
// blocks_world from 2 to 49 robots the two-level preconditioner needs at most twice the sweeps of
// its smallest team and far fewer than the sweeps alone (README, the refinement table: 40-54
// against 126-876 at eta 1e-2); both reach the optimum.
TEST(RefineTwoLevel, KeepsTheSweepsFlatAsTheTeamGrows) {
  int fewest = 1 << 30, most = 0;
  for (int n : test::kBlocksWorldRobots) {
    SCOPED_TRACE(std::to_string(n) + " robots");
    const Dataset d = ReadG2oFolder(test::BlocksWorldFolder(n));
    const OptimizerResult gn = CentralizedGaussNewton(d.graph, d.initial);
    std::map<RefinePreconditioner, int> sweeps;
    for (RefinePreconditioner p : {RefinePreconditioner::kTwoLevel, RefinePreconditioner::kSweeps}) {
      DgsOptions o = Refined();
      o.refinement.preconditioner = p;
      const DgsResult r = RunDgs(d.graph, d.initial, o);
      EXPECT_EQ(r.refine.status, StageStatus::kConverged);
      EXPECT_LE(Relative(d.graph.cost(r.values), gn.final_cost), 1e-9);
      sweeps[p] = r.refine.sweeps;
    }
    EXPECT_LT(sweeps[RefinePreconditioner::kTwoLevel], sweeps[RefinePreconditioner::kSweeps]);
    if (n >= 9) {
      EXPECT_LT(4 * sweeps[RefinePreconditioner::kTwoLevel],
                sweeps[RefinePreconditioner::kSweeps]);
    }
    fewest = std::min(fewest, sweeps[RefinePreconditioner::kTwoLevel]);
    most = std::max(most, sweeps[RefinePreconditioner::kTwoLevel]);
  }
  EXPECT_LE(most, 2 * fewest);
}

// By pieces (DgsOptions::Refinement::coarse_piece_poses): the Galerkin correction over the
// pieces' rigid motions zeroes the residual projected on every piece, which holds only if each
// robot moved its copies of a neighbour's variables with the piece their owner moved them with
// (the piece from the key), and the coordinator moved every block to the right centres. sphere2500
// split in 4 robots of 625 poses with pieces of 100: the pieces 6, 12 and 18 straddle two robots.
// With one piece per robot the piece matrix is the robots' coarse matrix.
TEST(RefineByPieces, CoarseCorrectionZeroesTheProjectedResidualOfEveryPiece) {
  const auto [s, optimum] = SplitWithOptimum("sphere2500", 4);
  DgsDriver driver(s.graph, s.initial, Refined());
  const std::vector<int> robots = AtTheFirstRefinementStep(driver);
  auto residuals = [&] {
    std::vector<CoarseMessage> out;
    for (int r : robots) out.push_back(driver.agent(r).refinePieceResidual(1));
    return out;
  };
  auto largest = [](const std::vector<CoarseMessage>& rs) {
    double m = 0.0;
    for (const CoarseMessage& r : rs) {
      for (const CoarsePiece& p : r.pieces) {
        m = std::max(m, Eigen::Map<const Eigen::VectorXd>(p.values.data(), 6).norm());
      }
    }
    return m;
  };
  PieceCoarseSystem coarse;
  int straddling = 0;
  std::set<std::uint32_t> seen;
  for (int r : robots) {
    const CoarseMessage m = driver.agent(r).refinePieceMatrix(100, 0);
    for (const CoarsePiece& p : m.pieces) straddling += seen.insert(p.id).second ? 0 : 1;
    coarse.addMatrix(DecodeCoarseMessage(EncodeCoarseMessage(m)));
  }
  EXPECT_EQ(straddling, 3);
  EXPECT_EQ(coarse.rows(), 0);  // indexed by factorize()
  ASSERT_TRUE(coarse.factorize());
  EXPECT_EQ(coarse.rows(), 6 * 28);  // 25 pieces, 3 of them in two robots
  const std::vector<CoarseMessage> before = residuals();
  Eigen::VectorXd Y;
  ASSERT_TRUE(coarse.solve(before, &Y));
  for (int r : robots) {
    RobotAgent& a = driver.agent(r);
    a.applyRefinePieces(DecodeCoarseMessage(
        EncodeCoarseMessage(coarse.solutionFor(r, a.neighbourRobots(), Y, 0, 1))));
  }
  EXPECT_GT(largest(before), 1e-3);
  EXPECT_LT(largest(residuals()), 1e-9 * largest(before));

  // One piece per robot: the robots' coarse matrix, diagonal and couplings.
  for (int r : robots) {
    const CoarseShare robot = driver.agent(r).refineCoarseMatrix();
    const CoarseMessage one = driver.agent(r).refinePieceMatrix(1u << 20, 0);
    ASSERT_EQ(one.pieces.size(), 1u);
    EXPECT_EQ(one.pieces[0].id, 0u);
    EXPECT_EQ(Eigen::Vector3d(one.center.data()), robot.center);
    EXPECT_EQ(Eigen::Vector3d(one.pieces[0].values.data()), robot.center);
    ASSERT_EQ(one.piece_blocks.size(), 1 + robot.coupling.size());
    for (const CoarsePieceBlock& b : one.piece_blocks) {
      const Eigen::MatrixXd block = UnflattenMatrix(b.values, 6, 6);
      const Eigen::MatrixXd& expected = b.robot == r ? robot.diagonal : robot.coupling.at(b.robot);
      EXPECT_LE((block - expected).norm(), 1e-9 * expected.norm()) << "robot " << b.robot;
    }
  }
  EXPECT_THROW(driver.agent(0).refinePieceMatrix(0, 0), InvalidInputError);
  // A matrix twice, a malformed one, a team of too many pieces: refused by name.
  const CoarseMessage m0 = driver.agent(0).refinePieceMatrix(100, 0);
  PieceCoarseSystem refusing;
  refusing.addMatrix(m0);
  EXPECT_THROW(refusing.addMatrix(m0), InvalidInputError);
  CoarseMessage bad = driver.agent(1).refinePieceMatrix(100, 0);
  bad.center.pop_back();
  EXPECT_THROW(refusing.addMatrix(bad), InvalidInputError);
  PieceCoarseSystem many;
  auto pieces = [](int robot, std::uint32_t n) {  // n pieces of a robot, no blocks
    CoarseMessage m = PieceMessage(CoarseKind::kPieceMatrix, robot, 0);
    m.center = {0.0, 0.0, 0.0};
    for (std::uint32_t id = 0; id < n; ++id) m.pieces.push_back({id, {0.0, 0.0, 0.0}});
    return m;
  };
  const auto half = static_cast<std::uint32_t>(PieceCoarseSystem::kMaxPieces / 2);
  try {
    many.addMatrix(pieces(0, half));
    many.addMatrix(pieces(1, half));  // exactly the most
    many.addMatrix(pieces(2, 1));
    ADD_FAILURE() << "more than " << PieceCoarseSystem::kMaxPieces << " pieces accepted";
  } catch (const InvalidInputError& e) {
    EXPECT_NE(std::string(e.what()).find("--refine-coarse-piece-poses"), std::string::npos)
        << e.what();
  }

  // Pieces of one pose: a motion per pose, so the coarse solve is the exact one and leaves no
  // residual at all. 2499 pieces, 14994 unknowns (a dense system refused them before).
  PieceCoarseSystem exact;
  for (int r : robots) exact.addMatrix(driver.agent(r).refinePieceMatrix(1, 0));
  ASSERT_TRUE(exact.factorize());
  EXPECT_EQ(exact.rows(), 6 * 2499);
  const std::vector<CoarseMessage> start = residuals();
  ASSERT_TRUE(exact.solve(start, &Y));
  for (int r : robots) {
    RobotAgent& a = driver.agent(r);
    a.applyRefinePieces(exact.solutionFor(r, a.neighbourRobots(), Y, 0, 1));
  }
  EXPECT_GT(largest(start), 1e-3);
  EXPECT_LT(largest(residuals()), 1e-9 * largest(start));
}

// A hand-made system of one robot's two pieces about its reference (so no shift): [I C; C I]
// with C = c I is positive definite for |c| < 1, and then the solve is the exact A^-1 b; with
// c = 2 it is not, and factorize() and solve() say so (no correction) rather than throwing. A
// residual that is not finite gives no correction either; one of a robot outside the system, or
// of another kind, is refused by name.
TEST(RefineByPieces, AnIndefiniteMatrixGivesNoCorrectionAndAForeignResidualIsRefused) {
  auto matrix = [](double c) {
    CoarseMessage m = PieceMessage(CoarseKind::kPieceMatrix, 0, 0);
    m.center = {0.0, 0.0, 0.0};
    m.pieces = {{0, {0.0, 0.0, 0.0}}, {1, {0.0, 0.0, 0.0}}};
    const Eigen::MatrixXd I = Eigen::MatrixXd::Identity(6, 6);
    m.piece_blocks = {{0, 0, 0, FlattenMatrix(I)},
                      {0, 0, 1, FlattenMatrix(c * I)},
                      {1, 0, 0, FlattenMatrix(c * I)},
                      {1, 0, 1, FlattenMatrix(I)}};
    return m;
  };
  CoarseMessage residual = PieceMessage(CoarseKind::kPieceResidual, 0, 0);
  Eigen::VectorXd b(12);
  for (int i = 0; i < 12; ++i) b(i) = 1.0 + i;
  residual.pieces = {{0, std::vector<double>(b.data(), b.data() + 6)},
                     {1, std::vector<double>(b.data() + 6, b.data() + 12)}};

  PieceCoarseSystem definite;
  definite.addMatrix(matrix(0.5));
  ASSERT_TRUE(definite.factorize());
  Eigen::VectorXd Y;
  ASSERT_TRUE(definite.solve({residual}, &Y));
  Eigen::MatrixXd A = Eigen::MatrixXd::Identity(12, 12);
  A.topRightCorner(6, 6) = 0.5 * Eigen::MatrixXd::Identity(6, 6);
  A.bottomLeftCorner(6, 6) = 0.5 * Eigen::MatrixXd::Identity(6, 6);
  EXPECT_LT((Y - A.ldlt().solve(b)).norm(), 1e-12 * b.norm());

  CoarseMessage not_finite = residual;
  not_finite.pieces[1].values[2] = std::numeric_limits<double>::infinity();
  EXPECT_FALSE(definite.solve({not_finite}, &Y));
  CoarseMessage foreign = residual;
  foreign.sender = 3;
  EXPECT_THROW(definite.solve({foreign}, &Y), InvalidInputError);
  EXPECT_TRUE(test::ThrowsNaming([&] { definite.solve({matrix(0.5)}, &Y); }, "not a residual"));

  PieceCoarseSystem indefinite;
  indefinite.addMatrix(matrix(2.0));
  EXPECT_FALSE(indefinite.factorize());
  EXPECT_FALSE(indefinite.solve({residual}, &Y));
  EXPECT_THROW(indefinite.addMatrix(residual), InvalidInputError);
}

// Long 2D chains: pieces of 50 poses let a run of the chain turn against the rest, which one
// motion per robot leaves to the sweeps. CSAIL split in 4 robots: measured 878 sweeps with one
// motion per robot, 300 with pieces (commit of this test); both at the optimum.
TEST(RefineByPieces, TakesFewerSweepsOnALongChainAndReachesTheOptimum) {
  const auto [s, optimum] = SplitWithOptimum("CSAIL", 4);
  std::map<std::uint64_t, DgsResult> runs;
  for (std::uint64_t pieces : {0u, 50u}) {
    DgsOptions o = Refined();
    o.coarse_correction = true;
    o.pose_solver = DgsOptions::PoseSolver::kConjugateGradient;
    o.refinement.coarse_piece_poses = pieces;
    runs[pieces] = RunDgs(s.graph, s.initial, o);
    EXPECT_EQ(runs[pieces].refine.status, StageStatus::kConverged);
    EXPECT_LE(Relative(s.graph.cost(runs[pieces].values), optimum), 1e-9);
    EXPECT_GT(runs[pieces].refine.coarse_corrections, 0);
  }
  EXPECT_LT(2 * runs[50].refine.sweeps, runs[0].refine.sweeps);
  // The pieces need the two-level conjugate gradients they are the coarse space of.
  DgsOptions bad = Refined();
  bad.refinement.coarse_piece_poses = 50;
  bad.refinement.preconditioner = RefinePreconditioner::kSweeps;
  EXPECT_THROW(bad.validate(), InvalidInputError);
  bad.refinement.preconditioner = RefinePreconditioner::kTwoLevel;
  bad.refinement.solver = RefineSolver::kSweeps;
  EXPECT_THROW(bad.validate(), InvalidInputError);
}

}  // namespace
}  // namespace moslam
