#include "moslam/solver/optimizer.h"

#include <gtest/gtest.h>

#include <iterator>
#include <map>
#include <random>

#include "moslam/common/errors.h"
#include "moslam/common/throws_naming_testing.h"
#include "moslam/graph/synthetic.h"
#include "moslam/solver/initialization.h"

namespace moslam {
namespace {

double MaxPoseError(const Values& a, const Values& b) {
  double worst = 0.0;
  for (const auto& [k, x] : b) {
    const Vector6 d = SE3::Log(a.at(k).between(x));
    worst = std::max(worst, d.cwiseAbs().maxCoeff());
  }
  return worst;
}

// Ground truth moved by a random error on every variable but the anchor.
Values Perturbed(const Values& truth, double sigma, unsigned seed) {
  std::mt19937 rng(seed);
  std::normal_distribution<double> n01;
  Values out = truth;
  bool first = true;
  for (auto& [k, x] : out) {
    if (first) {  // the anchor (first key of robot 0) stays
      first = false;
      continue;
    }
    Vector6 xi;
    for (int i = 0; i < 6; ++i) xi(i) = sigma * n01(rng);
    x = x.retract(xi);
  }
  return out;
}

SyntheticGraph NoisyGraph(int robots = 2, unsigned seed = 4) {
  SyntheticGraphOptions o;
  o.num_robots = robots;
  o.poses_per_robot = 40;
  o.sigma_rotation = 0.05;
  o.sigma_translation = 0.1;
  o.seed = seed;
  return MakeSyntheticGraph(o);
}

TEST(Optimizer, NoiseFreeGraphRecoveredTo1e9) {
  SyntheticGraphOptions o;
  o.num_robots = 3;
  o.poses_per_robot = 40;
  const SyntheticGraph s = MakeSyntheticGraph(o);
  for (Method m : {Method::kGaussNewton, Method::kLevenbergMarquardt}) {
    OptimizerOptions opt;
    opt.method = m;
    const OptimizerResult r = Optimize(s.graph, Perturbed(s.ground_truth, 0.1, 9), opt);
    EXPECT_EQ(r.termination, TerminationStatus::kConverged);
    EXPECT_LT(MaxPoseError(r.values, s.ground_truth), 1e-9);
    EXPECT_LT(r.final_cost, 1e-12);
  }
}

TEST(Optimizer, ChordalInitialisationIsExactOnNoiseFreeGraphs) {
  SyntheticGraphOptions o;
  o.num_robots = 2;
  const SyntheticGraph s = MakeSyntheticGraph(o);
  const SE3 anchor = s.ground_truth.begin()->second;
  for (bool weighted : {true, false}) {
    ChordalOptions c;
    c.weight_by_information = weighted;
    EXPECT_LT(MaxPoseError(ChordalInitialization(s.graph, anchor, c), s.ground_truth), 1e-9);
  }
  EXPECT_LT(MaxPoseError(OdometryInitialization(s.graph, anchor), s.ground_truth), 1e-9);
}

// Stage 2 alone: given the true rotations, the translations of a noise-free graph are exact (the
// anchor's translation as given); a rotation missing for a variable is an input error.
TEST(Optimizer, TranslationsGivenTheTrueRotationsAreExact) {
  SyntheticGraphOptions o;
  o.num_robots = 2;
  const SyntheticGraph s = MakeSyntheticGraph(o);
  std::map<Key, SO3> rotations;
  for (const auto& [key, pose] : s.ground_truth) rotations.emplace(key, pose.rotation());
  const Key anchor = GaugeAnchor(s.graph);
  const Values t =
      TranslationsGivenRotations(s.graph, rotations, s.ground_truth.at(anchor).translation());
  EXPECT_LT(MaxPoseError(t, s.ground_truth), 1e-9);
  rotations.erase(std::prev(rotations.end()));
  EXPECT_THROW(TranslationsGivenRotations(s.graph, rotations), InvalidInputError);
}

TEST(Optimizer, GaussNewtonAndLevenbergMarquardtReachTheSameMinimum) {
  const SyntheticGraph s = NoisyGraph();
  const Values init = ChordalInitialization(s.graph, s.ground_truth.begin()->second);
  OptimizerOptions gn, lm;
  gn.method = Method::kGaussNewton;
  lm.method = Method::kLevenbergMarquardt;
  const OptimizerResult a = Optimize(s.graph, init, gn);
  const OptimizerResult b = Optimize(s.graph, init, lm);
  EXPECT_EQ(a.termination, TerminationStatus::kConverged);
  EXPECT_EQ(b.termination, TerminationStatus::kConverged);
  EXPECT_LT(a.final_cost, a.initial_cost);
  EXPECT_NEAR(a.final_cost, b.final_cost, 1e-8 * a.final_cost);
  EXPECT_LT(MaxPoseError(a.values, b.values), 1e-6);
}

TEST(Optimizer, OptimumHasZeroGradient) {
  // Independent of the solver's own Jacobians: central differences of the cost itself.
  const SyntheticGraph s = NoisyGraph(1, 7);
  const OptimizerResult r = Optimize(s.graph, ChordalInitialization(s.graph));
  const Key anchor = GaugeAnchor(s.graph);
  double worst = 0.0;
  for (const auto& [k, x] : r.values) {
    if (k == anchor) continue;
    for (int i = 0; i < 6; ++i) {
      Values plus = r.values, minus = r.values;
      Vector6 d = Vector6::Zero();
      d(i) = 1e-6;
      plus[k] = x.retract(d);
      minus[k] = x.retract(-d);
      worst = std::max(worst, std::abs(s.graph.cost(plus) - s.graph.cost(minus)) / 2e-6);
    }
  }
  EXPECT_LT(worst, 1e-4);
  EXPECT_NEAR(s.graph.cost(r.values), r.final_cost, 1e-12 * r.final_cost);
}

TEST(Optimizer, LevenbergMarquardtCostNeverIncreases) {
  // From dead reckoning on a noisy graph, far from the optimum: LM must only ever go down.
  const SyntheticGraph s = NoisyGraph(3, 11);
  OptimizerOptions lm;
  lm.method = Method::kLevenbergMarquardt;
  lm.lm_initial_lambda = 1e-8;  // start almost Gauss-Newton so rejections do happen
  NonlinearOptimizer opt(s.graph, OdometryInitialization(s.graph), lm);
  double previous = opt.cost();
  int total_solves = 0;
  while (!opt.done()) {
    const IterationSummary it = opt.iterate();
    EXPECT_LE(it.cost, previous);
    previous = it.cost;
    total_solves += it.linear_solves;
  }
  EXPECT_EQ(opt.termination(), TerminationStatus::kConverged);
  EXPECT_GE(total_solves, opt.result().iterations);
}

TEST(Optimizer, AnchorStaysAtItsInitialValue) {
  const SyntheticGraph s = NoisyGraph();
  Values init = ChordalInitialization(s.graph);
  const Key anchor = GaugeAnchor(s.graph);
  const OptimizerResult r = Optimize(s.graph, init);
  EXPECT_EQ((r.values.at(anchor).matrix() - init.at(anchor).matrix()).norm(), 0.0);
}

TEST(Optimizer, BadOptionsNameTheField) {
  using O = OptimizerOptions;
  EXPECT_TRUE(test::EachChangeIsRefused<O>({
      {"max_iterations", [](O& o) { o.max_iterations = -1; }},
      {"relative_cost_tolerance", [](O& o) { o.relative_cost_tolerance = NAN; }},
      {"absolute_cost_tolerance", [](O& o) { o.absolute_cost_tolerance = -1.0; }},
      {"step_tolerance", [](O& o) { o.step_tolerance = NAN; }},
      {"lm_initial_lambda", [](O& o) { o.lm_initial_lambda = 0.0; }},
      {"lm_initial_lambda", [](O& o) { o.lm_initial_lambda = INFINITY; }},
      {"lm_max_lambda", [](O& o) { o.lm_max_lambda = o.lm_initial_lambda; }},
  }));
}

TEST(Optimizer, RejectsBadInputWithExplanations) {
  const SyntheticGraph s = NoisyGraph(2);
  Values missing = s.ground_truth;
  missing.erase(std::prev(missing.end()));
  EXPECT_THROW(Optimize(s.graph, missing), InvalidInputError);

  Values nan = s.ground_truth;
  nan.begin()->second = SE3(SO3(), Vector3(NAN, 0, 0));
  EXPECT_THROW(Optimize(s.graph, nan), InvalidInputError);

  OptimizerOptions bad;
  bad.max_iterations = -1;
  EXPECT_THROW(Optimize(s.graph, s.ground_truth, bad), InvalidInputError);
  bad = OptimizerOptions();
  bad.relative_cost_tolerance = NAN;
  EXPECT_THROW(Optimize(s.graph, s.ground_truth, bad), InvalidInputError);

  // Two robots with no edge between them: robot 1's gauge is free.
  PoseGraph split;
  for (const auto& f : s.graph.factors()) {
    if (f.a().robot == f.b().robot) split.add(f);
  }
  try {
    Optimize(split, s.ground_truth);
    FAIL() << "expected UnderdeterminedError";
  } catch (const UnderdeterminedError& e) {
    EXPECT_NE(std::string(e.what()).find("disconnected"), std::string::npos) << e.what();
  }
  EXPECT_THROW(ChordalInitialization(split), UnderdeterminedError);
  // ... and a prior on robot 1 makes it well posed.
  split.add(PriorFactor(Key::Pose(1, 0), s.ground_truth.at(Key::Pose(1, 0)), Matrix6::Identity() * 1e4));
  const OptimizerResult r = Optimize(split, ChordalInitialization(split, s.ground_truth.begin()->second));
  EXPECT_EQ(r.termination, TerminationStatus::kConverged);
}

TEST(Optimizer, IterateStepsOneAtATime) {
  const SyntheticGraph s = NoisyGraph();
  NonlinearOptimizer opt(s.graph, OdometryInitialization(s.graph));
  const double c0 = opt.cost();
  const IterationSummary first = opt.iterate();
  EXPECT_EQ(first.iteration, 1);
  EXPECT_LT(first.cost, c0);
  EXPECT_EQ(opt.result().history.size(), 1u);
  const OptimizerResult r = opt.optimize();
  EXPECT_GT(r.iterations, 1);
  EXPECT_EQ(r.history.size(), static_cast<size_t>(r.iterations));
  // Once done, a step is no step: the summary reports where it stopped and nothing moves.
  ASSERT_TRUE(opt.done());
  const IterationSummary after = opt.iterate();
  EXPECT_EQ(after.iteration, r.iterations);
  EXPECT_EQ(after.cost, r.final_cost);
  EXPECT_EQ(after.linear_solves, 0);
  EXPECT_EQ(opt.result().history.size(), r.history.size());
  EXPECT_EQ(opt.result().termination, r.termination);
}

TEST(Optimizer, MaxIterationsIsReported) {
  const SyntheticGraph s = NoisyGraph();
  OptimizerOptions o;
  o.max_iterations = 1;
  const OptimizerResult r = Optimize(s.graph, OdometryInitialization(s.graph), o);
  EXPECT_EQ(r.termination, TerminationStatus::kMaxIterations);
  EXPECT_EQ(r.iterations, 1);
}

// The names `solve --json` prints for each termination status, one per status.
TEST(Optimizer, EveryTerminationStatusHasItsOwnName) {
  EXPECT_EQ(ToString(TerminationStatus::kNotStarted), "not_started");
  EXPECT_EQ(ToString(TerminationStatus::kConverged), "converged");
  EXPECT_EQ(ToString(TerminationStatus::kMaxIterations), "max_iterations");
  EXPECT_EQ(ToString(TerminationStatus::kCostIncreased), "cost_increased");
  EXPECT_EQ(ToString(TerminationStatus::kNoDecreasingStep), "no_decreasing_step");
}

}  // namespace
}  // namespace moslam
