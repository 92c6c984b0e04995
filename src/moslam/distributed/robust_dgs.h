// The robust distributed solve: GNC-TLS (robust/gnc.h) run by the robots themselves around the
// distributed solver (dgs_driver.h), beyond the paper (its conclusion: "a distributed algorithm
// for outlier rejection"), as Kimera-Multi distributes GNC.
//
//   RobustDgsResult r = RunRobustDgs(graph, initial, robust, options);
//
// Round 0: the least-squares solve, RunDgs with the refinement (the distributed optimum). Then
// every robot owns the weights of its robust factors: those between two of its own variables,
// and the separators to a robot of higher id (a separator's weight is owned by the lower robot
// id). Each robot computes the squared residuals of the factors it owns from its estimate and
// its neighbours' (which the solve left equal to their owners'), and the team runs GncSchedule:
//   - mu_0: every robot reports the largest residual it owns to the coordinator (the lowest robot
//     id), which broadcasts the maximum (control messages, 32 bytes each);
//   - a round: every robot sets the weights it owns; the owner of separators sends them to the
//     other robot (WeightMessage, messages.h); the weighted problem (each factor's information
//     times its weight) is solved again by RunDgs with the refinement: its two stages start from
//     the previous estimate but converge to the weighted graph's two-stage estimate, where the
//     refinement starts (a warm start, the refinement alone from the previous estimate, measured
//     worse: docs/robustness-log.md); every robot reports how many of its weights were undecided
//     (neither 0 nor 1) and the coordinator broadcasts whether to stop; else mu grows.
// Around it: before, the pairwise check of the separators (separator_consistency.h: the ones it
// rejects are left out); after, the rejected separators whose residual at the estimate is within
// c2 come back (GNC-TLS's own definition of an inlier), and the inliers alone are solved once
// more (the rounds keep min_weight of every rejected factor); with retest_left_out, the check's
// rejects with support are then re-tested one by one against that optimum, and then each robot
// pair's left together (see the options).
// Weights change only between solves; only estimates (inside the solves), weights and these
// scalars cross the network, all serialized and counted. Same schedule and weights as SolveGnc
// on the same graph where every solve reaches the same optimum; the estimates differ from the
// centralized GNC's by the solves' tolerance. Where the least-squares solves end in different
// minima, or a weighted solve stops at its step limit, the weights can differ (split among 4
// robots with wrong loop closures: INTEL at 30 %, 5 of 366, none with the refinement's conjugate
// gradients to 1e-3 instead of 1e-2; at 50 % 13 of 512 and 11; docs/robustness-log.md).
#pragma once

#include <cstdint>
#include <functional>
#include <vector>

#include "moslam/distributed/dgs_driver.h"
#include "moslam/distributed/separator_consistency.h"
#include "moslam/robust/gnc.h"

namespace moslam {

struct RobustDgsOptions {
  DgsOptions dgs;  // every solve (the refinement is forced on)
  GncOptions gnc;
  // Before GNC, the pairwise consistency of the inter-robot loop closures of every robot pair
  // (separator_consistency.h); the separators it rejects are left out of every solve. Its
  // threshold 0: GNC's c2 (both are chi-square quantiles of a 6-vector).
  bool check_separators = true;
  SeparatorConsistencyOptions consistency{0.0, 3, 2};
  // After the inliers' solve, each separator the check left out that passes its pairwise test with
  // at least consistency.min_support of the kept separators of its robot pair (the support of
  // SeparatorConsistencyResult), both of its variables held by inliers, is tested once more against
  // the joint estimate: the inliers are solved with it, and it comes back when that raises their
  // optimal cost F by at most c2 / 2, in increasing order of its r^T Omega r at the estimate. For
  // a linear model 2 dF is r^T (Sigma_z + J Sigma_x J^T)^-1 r, the chi-square of the measurement
  // against the estimate and its uncertainty; the pairwise test is first order in each robot's own
  // map, and the readmission's r^T Omega r <= c2 ignores the estimate's uncertainty, so a right
  // separator on a weakly held part of two maps could pass neither (generated, 4 robots, unknown
  // initial poses, seed 4: two of 14 right separators of robots 0 and 1 left out by the check,
  // r^T Omega r 121 and 162 at the estimate without them, which sat 1.2 m from the outlier-free
  // one; with them back, 9e-7 m; each raised F by 5-6). Each candidate costs one solve, one
  // reduction of F over the team (the coordinator's control messages) and a weight message, and
  // before them the higher robot of each pair sends the lower its estimates of its variables in
  // the separators left out (counted with the check). Without the check: nothing to re-test.
  // Failure mode: a wrong separator on parts of two maps that bend easily raises F little too,
  // and comes back.
  bool retest_left_out = true;
  // With retest_left_out, after the one-by-one re-test: per robot pair the check kept (in
  // increasing ids), the largest pairwise-consistent set of the separators it left out (the
  // runner-up, SeparatorConsistencyResult::runner_up), those still rejected with both variables
  // held by inliers, re-tested together when there are at least min_support of them (GroupMinimum).
  // Where GNC left a robot's map bent by wrong factors it kept, the check rejects right
  // separators that disagree with the bent map; each alone bends the two maps more than it is
  // worth (the one-by-one re-test's dF beyond c2 / 2), where together they align the maps and show
  // the wrong factors for what they are (chairs25, sampled, the robots' loop closures, no injected
  // pair: three runs 0.5-1.2 m from the outlier-free estimate; README "Robustness"). The trial:
  // the group's separators join the inliers (weight 1), the factors it may use (all but the
  // check's other rejects) are solved with these weights (WeightedGraph), the robust weights are
  // set to the truncated cost's own (1 where r^T Omega r <= c2, else 0) and it is solved again,
  // until no weight changes or after retest_group_solves solves; it is kept when the truncated
  // cost of the factors it may use (a robust factor's term at most c2 / 2) is lower than before:
  // that cost never rises. The robots run it as GNC's rounds: weights between solves, the changes
  // counted and the cost reduced over the team by the coordinator. Without the runner-up and
  // min_support conditions, every pair's rejects were tried on spoiled blocks_world, where the
  // check rejects exactly the wrong ones: up to 26 trials, none kept, 1.3 -> 125 MB for
  // `moslam dgs --robust` at 9 robots and P = 0.7; with them, none. Failure mode: a group with a
  // wrong member may cost more than its right members save (all stay out), or reach a wrong
  // minimum of lower truncated cost.
  bool retest_groups = true;
  int retest_group_solves = 10;  // per group trial, at most
  // The check's one-to-one rule (SeparatorConsistencyOptions::one_to_one_objects) kept after GNC
  // as well (KeepOneToOne): the readmission's verdicts and those GNC kept settled by r^T Omega r
  // at the estimate, the smallest first, so that no landmark stays paired with two landmarks of
  // one robot; a re-test candidate that would break it is not tried, and a group re-test's weights
  // obey it after every solve. Without it the readmission brings back a separator the check left
  // out for pairing a landmark twice whenever it fits within c2: on house at P = 0.7 (seeds
  // 11-20), 162 of the 189 wrong pairs kept at 4 robots (README, Robustness). Failure modes: the
  // residual of the wrong one of two chairs 0.8 m apart can be the smaller, and a robot that
  // mapped one object twice keeps one of its two right pairs to the other's landmark.
  bool one_to_one_after_gnc = false;
  // Throws InvalidInputError naming the first bad field.
  void validate() const;
};

struct RobustDgsRound {
  int round = 0;               // 0: least squares
  double mu = 0.0;             // of the weights this round solved with (0 in round 0)
  int undecided = 0;           // weights neither 0 nor 1 in this round
  int outliers = 0;            // robust factors of weight < 0.5
  std::int64_t solve_bytes = 0;
  double cost = 0.0;           // F of the estimate under the round's weights
};

struct RobustDgsResult {
  Values values;
  GncStatus status = GncStatus::kAllInliers;
  std::vector<double> weights;  // per factor of the graph (1 for the non-robust ones)
  int iterations = 0;           // weighted solves after the least-squares one
  int outliers = 0;
  std::vector<RobustDgsRound> rounds;
  std::int64_t solve_bytes = 0;    // all DGS solves (estimates, coarse and control messages)
  std::int64_t weight_bytes = 0;   // WeightMessages
  std::int64_t weight_messages = 0;
  std::int64_t control_bytes = 0;  // the GNC's reports and broadcasts
  std::int64_t consistency_bytes = 0;  // the separator check's local estimates and covariances
  int consistency_rejected = 0;        // separators the check left out
  int consistency_deferred = 0;        // too few to confirm themselves, left to GNC
  int readmitted = 0;   // of those, back after GNC: their residual at the estimate within c2
  int retests = 0;      // separators re-tested against the joint estimate (retest_left_out)
  int retest_readmitted = 0;  // ... and back
  int group_retests = 0;      // robot pairs' groups re-tested together (retest_groups), and
  int group_readmitted = 0;   // the separators of those back
  bool polished = false;  // a last solve of the inliers alone (weights not all 1)
  bool polish_refused = false;  // ... that raised their cost (KeepInlierSolve): not used
  std::int64_t bytes() const {
    return solve_bytes + weight_bytes + control_bytes + consistency_bytes;
  }
  int sweeps = 0;                  // all stages of all solves
  double seconds = 0.0;
};

// The pairwise check as the robust solves apply it: its threshold from GNC's when 0, each
// robot's map robust in the intra-robot factors `robust` marks. A graph whose poses are one
// robot's has no separator: its loop closures `robust` marks are checked through its odometry
// instead (robust/loop_consistency.h, with the check's threshold, min_support and map_uncertainty
// as odometry_uncertainty). In a team's graph, the loop closures `robust` marks between two poses
// of one robot are checked so too, each robot through its own odometry
// (CheckEachRobotsLoopClosures), first: the maps the separators are judged on then hold none of
// the robots' own loop closures along their odometry (OdometryCheckResult::along_odometry: the
// maps' covariances carry the odometry's drift; a wrong loop closure in a map, even one that check
// confirmed, would bend it), nor those that check rejected; the loop closures it kept stay for
// GNC. `separators` and `rejected` count both.
SeparatorConsistencyResult CheckSeparators(const PoseGraph& graph, const RobustDgsOptions& options,
                                           const std::vector<bool>& robust = {});

// The centralized reference of RunRobustDgs: the same separator check, then SolveGnc on the
// factors it kept (weights 0 for the others), from initialize(kept graph) (e.g. its chordal
// initialisation: that of the whole graph would carry the rejected factors' pull). `check`
// (optional) receives what the check found (untouched without options.check_separators).
GncResult SolveRobustCentralized(const PoseGraph& graph,
                                 const std::function<Values(const PoseGraph&)>& initialize,
                                 const std::vector<bool>& robust, const RobustDgsOptions& options,
                                 const OptimizerOptions& solver = {},
                                 SeparatorConsistencyResult* check = nullptr);

// robust[i]: whether factor i of `graph` is robust (size = number of factors). checked (empty:
// every factor): the factors the separator check sees, its robots' maps and separators; the others
// are kept by it and are in none of its maps (online/online_team.h: a group's held factors, which
// pin a robot's landmarks to copies of earlier solves, out of the maps the pairs are tested in).
// Throws InvalidInputError (bad options, a mask of the wrong size) and whatever RunDgs throws.
RobustDgsResult RunRobustDgs(const PoseGraph& graph, const Values& initial,
                             const std::vector<bool>& robust, const RobustDgsOptions& options = {},
                             const std::vector<bool>& checked = {});

}  // namespace moslam
