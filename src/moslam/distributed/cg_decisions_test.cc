#include "moslam/distributed/cg_decisions.h"

#include <gtest/gtest.h>

#include <Eigen/Cholesky>
#include <Eigen/Core>
#include <cmath>
#include <random>

namespace moslam {
namespace {

// A symmetric positive definite system of n unknowns: a chain of couplings and weak priors.
Eigen::MatrixXd ChainMatrix(int n, unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(0.5, 2.0);
  Eigen::MatrixXd H = Eigen::MatrixXd::Zero(n, n);
  for (int i = 0; i + 1 < n; ++i) {
    const double w = u(rng);
    H(i, i) += w;
    H(i + 1, i + 1) += w;
    H(i, i + 1) -= w;
    H(i + 1, i) -= w;
  }
  H(0, 0) += 1.0;               // the anchor
  H.diagonal().array() += 0.2;  // priors: fewer iterations than unknowns
  return H;
}

struct CgRun {
  Eigen::VectorXd delta;
  CgOutcome outcome;
  int iterations = 0;
};

// Preconditioned conjugate gradients on H delta = b driven by CgDecisions, with the Jacobi
// preconditioner (one "sweep" per application) and the team's sums as plain dot products.
CgRun Solve(const Eigen::MatrixXd& H, const Eigen::VectorXd& b, const CgGoal& goal) {
  const Eigen::VectorXd inverse_diagonal = H.diagonal().cwiseInverse();
  CgRun run;
  run.delta = Eigen::VectorXd::Zero(b.size());
  Eigen::VectorXd res = b, z, p;
  auto precondition = [&] {
    z = inverse_diagonal.cwiseProduct(res);
    ++run.outcome.sweeps;
  };
  CgDecisions cg(goal);
  precondition();
  if (cg.start(res.dot(z))) {
    p = z;
    while (true) {
      const Eigen::VectorXd q = H * p;
      const std::optional<double> alpha = cg.stepLength(p.dot(q), p.cwiseAbs().maxCoeff());
      if (!alpha) break;
      run.delta += *alpha * p;
      res -= *alpha * q;
      ++run.iterations;
      precondition();
      const CgDecisions::Next next = cg.next(res.dot(z), run.outcome.sweeps);
      if (next.stop) break;
      p = z + next.beta * p;
    }
  }
  run.outcome.converged = cg.converged();
  run.outcome.model_decrease = cg.modelDecrease();
  return run;
}

TEST(CgDecisions, ReachTheSolutionOfASymmetricPositiveDefiniteSystem) {
  const Eigen::MatrixXd H = ChainMatrix(40, 3);
  const Eigen::VectorXd b = Eigen::VectorXd::LinSpaced(40, -1.0, 2.0);
  const Eigen::VectorXd exact = H.ldlt().solve(b);
  CgGoal goal;
  goal.tolerance = 1e-12;
  const CgRun run = Solve(H, b, goal);
  EXPECT_TRUE(run.outcome.converged);
  EXPECT_LT((run.delta - exact).norm(), 1e-8 * exact.norm());
  // In exact arithmetic conjugate gradients end within n iterations; rounding costs a few more.
  EXPECT_LE(run.iterations, 60);
}

TEST(CgDecisions, StopAtTheGoalThatComesFirst) {
  const Eigen::MatrixXd H = ChainMatrix(40, 5);
  const Eigen::VectorXd b = Eigen::VectorXd::Ones(40);
  CgGoal loose;
  loose.tolerance = 1e-2;
  CgGoal tight;
  tight.tolerance = 1e-10;
  const CgRun a = Solve(H, b, loose), c = Solve(H, b, tight);
  EXPECT_TRUE(a.outcome.converged && c.outcome.converged);
  EXPECT_LT(a.iterations, c.iterations);
  // A sweep budget too small for the tolerance: stopped, not converged, within the budget.
  CgGoal budget = tight;
  budget.max_sweeps = 6;
  const CgRun d = Solve(H, b, budget);
  EXPECT_FALSE(d.outcome.converged);
  EXPECT_LE(d.outcome.sweeps, 6);
  // The change goal: the last iteration moved no unknown by more than eta.
  CgGoal change;
  change.eta_change = 1e-3;
  CgDecisions cg(change);
  ASSERT_TRUE(cg.start(1.0));
  ASSERT_TRUE(cg.stepLength(4.0, 2e-3).has_value());  // alpha 0.25: a change of 5e-4
  EXPECT_DOUBLE_EQ(cg.change(), 5e-4);
  const CgDecisions::Next next = cg.next(0.5, 2);
  EXPECT_TRUE(next.stop && cg.converged());
  EXPECT_DOUBLE_EQ(next.relative, std::sqrt(0.5));
}

// The model decrease summed from the team's numbers is m(0) - m(delta), m(d) = -b.d + d.H d / 2,
// for the delta each stopping point leaves; solved exactly, b.H^-1 b / 2.
TEST(CgDecisions, KeepTheDecreaseOfTheQuadraticModel) {
  const Eigen::MatrixXd H = ChainMatrix(40, 7);
  const Eigen::VectorXd b = Eigen::VectorXd::LinSpaced(40, 2.0, -1.0);
  auto decrease = [&](const Eigen::VectorXd& d) { return b.dot(d) - 0.5 * d.dot(H * d); };
  double previous = 0.0;
  for (double tolerance : {0.5, 1e-1, 1e-2, 1e-4, 1e-12}) {
    SCOPED_TRACE(tolerance);
    CgGoal goal;
    goal.tolerance = tolerance;
    const CgRun run = Solve(H, b, goal);
    ASSERT_GT(run.iterations, 0);
    const double expected = decrease(run.delta);
    EXPECT_NEAR(run.outcome.model_decrease, expected, 1e-12 * expected);
    // Each iteration lowers the model: a tighter goal, more iterations, a larger decrease.
    EXPECT_GE(run.outcome.model_decrease, previous);
    previous = run.outcome.model_decrease;
  }
  const double exact = 0.5 * b.dot(H.ldlt().solve(b));
  EXPECT_NEAR(previous, exact, 1e-12 * exact);
  EXPECT_EQ(CgDecisions(CgGoal{}).modelDecrease(), 0.0);
}

TEST(CgDecisions, AZeroGradientOrNoCurvatureKeepsTheIncrement) {
  CgDecisions zero(CgGoal{});
  EXPECT_FALSE(zero.start(0.0));
  EXPECT_TRUE(zero.converged());
  CgDecisions flat(CgGoal{});
  ASSERT_TRUE(flat.start(1.0));
  EXPECT_FALSE(flat.stepLength(0.0, 1.0).has_value());
  EXPECT_TRUE(flat.converged());
  const CgRun run = Solve(ChainMatrix(10, 1), Eigen::VectorXd::Zero(10), CgGoal{});
  EXPECT_TRUE(run.outcome.converged);
  EXPECT_EQ(run.iterations, 0);
  EXPECT_EQ(run.delta.norm(), 0.0);
  EXPECT_EQ(run.outcome.model_decrease, 0.0);
}

}  // namespace
}  // namespace moslam
