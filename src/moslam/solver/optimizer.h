// Centralized nonlinear least squares on the SE(3) pose-graph cost
//   F(x) = sum_f 1/2 r_f^T Omega_f r_f      (graph/factors.h)
// by Gauss-Newton or Levenberg-Marquardt, every linear step a sparse Cholesky (CHOLMOD).
// Gauge: the anchor (first pose of robot 0) is held at its initial value (CONVENTIONS.md).
//
//   NonlinearOptimizer opt(graph, initial, options);   // validates; throws on bad input
//   while (!opt.done()) opt.iterate();                  // or: OptimizerResult r = opt.optimize();
#pragma once

#include <memory>
#include <string>
#include <vector>

#include "moslam/graph/pose_graph.h"

namespace moslam {

enum class Method { kGaussNewton, kLevenbergMarquardt };

struct OptimizerOptions {
  // LM by default: with lm_initial_lambda = 1e-10 it takes the Gauss-Newton step wherever that
  // step lowers the cost (same iteration counts as GN on sphere2500, torus3D, smallGrid3D,
  // sphere_bignoise_vertex3), and damps it where the full step overshoots (cubicle, where plain
  // GN's first step raises the cost from 6.7e4 to 2.6e5).
  Method method = Method::kLevenbergMarquardt;
  int max_iterations = 100;
  // Converged when an accepted step lowers the cost by less than this fraction of it ...
  double relative_cost_tolerance = 1e-10;
  // ... or the cost falls below this (noise-free graphs) ...
  double absolute_cost_tolerance = 1e-20;
  // ... or the largest update component is below this.
  double step_tolerance = 1e-12;
  // Levenberg-Marquardt: damping H + lambda * diag(H), adapted by the gain ratio (Nielsen).
  double lm_initial_lambda = 1e-10;
  double lm_max_lambda = 1e12;
  bool verbose = false;  // one line per iteration on stderr

  // Throws InvalidInputError naming the first bad field.
  void validate() const;
};

enum class TerminationStatus {
  kNotStarted,
  kConverged,         // a tolerance was met
  kMaxIterations,     // max_iterations reached first
  kCostIncreased,     // Gauss-Newton: the full step raised the cost (kept the previous estimate)
  kNoDecreasingStep,  // Levenberg-Marquardt: lambda reached lm_max_lambda without a decrease
};
std::string ToString(TerminationStatus status);

struct IterationSummary {
  int iteration = 0;         // 1-based
  double cost = 0.0;         // after the iteration
  double cost_change = 0.0;  // previous cost - cost (>= 0 for accepted LM steps)
  double step_norm = 0.0;    // max |delta|
  double lambda = 0.0;       // LM damping used for the accepted step (0 for GN)
  int linear_solves = 0;     // factorizations this iteration (LM may retry)
  double seconds = 0.0;
};

struct OptimizerResult {
  Values values;
  TerminationStatus termination = TerminationStatus::kNotStarted;
  double initial_cost = 0.0;
  double final_cost = 0.0;
  int iterations = 0;
  std::vector<IterationSummary> history;
  double seconds = 0.0;            // total, including setup
  double linearize_seconds = 0.0;  // building J^T Omega J and J^T Omega r
  double solve_seconds = 0.0;      // Cholesky factorization and solves
};

class NonlinearOptimizer {
 public:
  // `graph` is not copied: it must outlive the optimizer (as a Ceres Problem's cost functions).
  // Throws InvalidInputError (a variable without an initial estimate, non-finite values, bad
  // options) or UnderdeterminedError (no anchor, a part of the graph nothing anchors).
  NonlinearOptimizer(const PoseGraph& graph, const Values& initial,
                     const OptimizerOptions& options = {});
  ~NonlinearOptimizer();
  NonlinearOptimizer(const NonlinearOptimizer&) = delete;
  NonlinearOptimizer& operator=(const NonlinearOptimizer&) = delete;

  // One iteration; afterwards done() tells whether a stopping rule fired.
  IterationSummary iterate();
  // Iterates until done() and returns the whole result.
  OptimizerResult optimize();

  bool done() const;
  const Values& values() const;
  double cost() const;
  TerminationStatus termination() const;
  const OptimizerResult& result() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

// Convenience: NonlinearOptimizer(graph, initial, options).optimize().
OptimizerResult Optimize(const PoseGraph& graph, const Values& initial,
                         const OptimizerOptions& options = {});

}  // namespace moslam
