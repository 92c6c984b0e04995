// Graduated non-convexity with a truncated least-squares cost (GNC-TLS; Yang, Antonante, Tzoumas
// and Carlone, "Graduated Non-Convexity for Robust Spatial Perception", RA-L 2020), on the
// SE(3) pose-graph cost of graph/factors.h.
//
// The robust factors f (those the caller marks: inter-robot factors, object measurements) cost
//   rho(r2_f) = min(r2_f, c2) / 2,   r2_f = r_f^T Omega_f r_f (the squared whitened residual),
// so a factor whose residual exceeds the threshold c2 costs a constant and pulls nothing; the
// others (odometry) keep the least-squares cost. GNC minimises the surrogate rho_mu, convex for
// mu -> 0 and equal to rho for mu -> inf, by alternating a weighted least-squares solve with the
// closed-form weights
//   w_f = 1                                 r2_f <= mu / (mu + 1) c2
//       = sqrt(c2 mu (mu + 1) / r2_f) - mu  in between
//       = 0                                 r2_f >= (mu + 1) / mu c2,
// starting from mu_0 = c2 / (2 max_f r2_f - c2) at the least-squares estimate and multiplying mu
// by mu_step after every solve, until every weight is 0 or 1 (within weight_tolerance) or
// max_iterations solves. What it promises (and what not): no global optimality certificate; the
// paper reports the right inlier set up to 70-80 % outliers on pose graphs, and failure beyond,
// where the least-squares start is too far off; measured here in the README's robust tables.
//
// GncSchedule is the state machine (weights from residuals, the mu schedule, the stopping rule),
// independent of who solves: SolveGnc runs it around the centralized solver; the distributed
// driver (distributed/robust_dgs.h) runs it with each robot computing the weights it owns.
#pragma once

#include <functional>
#include <string>
#include <vector>

#include "moslam/graph/pose_graph.h"
#include "moslam/solver/optimizer.h"

namespace moslam {

struct GncOptions {
  // c2: the squared whitened residual (r^T Omega r, twice the factor's cost) beyond which a
  // factor is an outlier. 0: the 0.999 quantile of chi-square with 6 degrees of freedom, 22.46
  // (an inlier whose information is right passes with probability 0.999).
  double threshold = 0.0;
  double mu_step = 1.4;          // mu grows by this factor per solve (> 1)
  int max_iterations = 100;      // weighted solves after the least-squares one
  double weight_tolerance = 1e-6;  // a weight this close to 0 or 1 counts as decided
  // The information a factor of weight w keeps is max(w, min_weight) times its own, so that a
  // robot all of whose links are rejected stays determined (its frame is then arbitrary).
  double min_weight = 1e-4;
  double threshold2() const { return threshold > 0.0 ? threshold : 22.4577; }
  // Throws InvalidInputError naming the first bad field.
  void validate() const;
};

// The GNC-TLS weight of a factor with squared whitened residual r2 (see the top).
double TlsWeight(double r2, double mu, double c2);

enum class GncStatus {
  kAllInliers,     // every residual of the least-squares estimate was below c2: nothing to do
  kConverged,      // every weight is 0 or 1
  kMaxIterations,  // max_iterations weighted solves
};
std::string ToString(GncStatus status);

class GncSchedule {
 public:
  explicit GncSchedule(const GncOptions& options);
  // Called with the squared residuals of the robust factors at the least-squares estimate.
  // False when every one is below c2 (kAllInliers: done, weights all 1).
  bool start(double max_r2);
  // The weight of a robust factor with this squared residual at the current mu.
  double weight(double r2) const { return TlsWeight(r2, mu_, c2_); }
  // After a weighted solve whose weights were `decided` (all 0 or 1 within tolerance) or not:
  // true when the schedule is done (then status()); else mu grows for the next round.
  bool next(bool decided);
  bool decided(double w) const {
    return w <= options_.weight_tolerance || w >= 1.0 - options_.weight_tolerance;
  }
  double mu() const { return mu_; }
  double c2() const { return c2_; }
  int iterations() const { return iterations_; }
  GncStatus status() const { return status_; }

 private:
  GncOptions options_;
  double c2_, mu_ = 0.0;
  int iterations_ = 0;
  GncStatus status_ = GncStatus::kMaxIterations;
};

// The squared whitened residual r^T Omega r of every factor at `values`.
std::vector<double> SquaredResiduals(const PoseGraph& graph, const Values& values);

// The graph with factor i's information scaled by max(weights[i], min_weight).
PoseGraph WeightedGraph(const PoseGraph& graph, const std::vector<double>& weights,
                        double min_weight);

// The graph of the factors with keep[i] (and every prior); index (optional) receives, per factor
// of the result, the factor of `graph` behind it.
PoseGraph SubGraph(const PoseGraph& graph, const std::vector<bool>& keep,
                   std::vector<std::size_t>* index = nullptr);
// The factors of weight >= 0.5 (the inliers of a GNC result).
std::vector<bool> Inliers(const std::vector<double>& weights);
bool AllWeightsOne(const std::vector<double>& weights);
// Robust factors of weight < 0.5.
int CountOutliers(const std::vector<bool>& robust, const std::vector<double>& weights);

// The factors between two robots (inter-robot loop closures, shared objects).
std::vector<bool> SeparatorFactors(const PoseGraph& graph);
// The loop closures of a chain of poses: every factor but those between two poses of consecutive
// indices, whatever their robots (SplitIntoRobots keeps the pose indices, so on a single robot's
// file split among robots these are the file's loop closures, in a block or between blocks, and
// each robot finds its own in its own factors).
std::vector<bool> LoopClosureFactors(const PoseGraph& graph);
// The factors robust by default: those between two robots (inter-robot loop closures, shared
// objects); in a single-robot graph, the loop closures (LoopClosureFactors).
std::vector<bool> DefaultRobustFactors(const PoseGraph& graph);
// The factors robust in object SLAM: every factor that touches an object landmark (the shared
// objects' object-object factors between robots, the robots' object measurements, and their own
// loop closures by object constellations, object-object factors within one robot). Odometry and
// pose-pose loop closures stay least squares. The simulation, the robot processes and the online
// group solves take their robust factors from it (online without the held team factors).
std::vector<bool> ObjectFactors(const PoseGraph& graph);

struct GncResult {
  Values values;
  GncStatus status = GncStatus::kAllInliers;
  std::vector<double> weights;  // per factor of the graph (1 for the non-robust ones)
  int iterations = 0;           // weighted solves after the least-squares one
  double final_mu = 0.0;
  int outliers = 0;             // robust factors with weight < 0.5
  double least_squares_cost = 0.0;  // F of the least-squares estimate
  double seconds = 0.0;
};

// Centralized GNC-TLS: the factors with robust[i] are robust (robust.size() must equal the number
// of factors), the others and the priors least squares. Every solve is NonlinearOptimizer with
// `solver`, from the previous estimate; the last one solves the factors of weight >= 0.5 alone
// (unless that leaves part of the graph unanchored). Throws InvalidInputError (bad options, a mask of the
// wrong size) and whatever the optimizer throws.
GncResult SolveGnc(const PoseGraph& graph, const Values& initial, const std::vector<bool>& robust,
                   const GncOptions& options = {}, const OptimizerOptions& solver = {});

}  // namespace moslam
