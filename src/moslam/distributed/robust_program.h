// One robot's side of the robust distributed solve (robust_dgs.h) as a program over the
// TeamChannel of robot_program.h: GNC-TLS rounds around the whole solver, run by the robots
// themselves with no coordinator, so that robot processes (transport/dgs_node.h) run it over a
// network. Every robot of the team runs the same program:
//
//   1. the least-squares solve: RunRobotProgram (with the refinement) on an agent of its
//      subgraph; afterwards it holds its estimate and its copies of its neighbours' variables
//      (equal to the owners' estimates at the end of the refinement; the tests: to 1e-9);
//   2. it owns the weights of its robust factors between two of its own variables and of its
//      robust separators to robots of higher id; it computes their squared residuals r2 from its
//      estimate and copies; one channel step reduces the largest r2 over the team (GncSchedule's
//      mu_0; every robot computes the maximum from the same reports);
//   3. a GNC round: it sets the weights it owns, sends each neighbour a WeightMessage (the weights
//      of the robust separators it owns toward that neighbour, in the order both subgraphs hold
//      them: empty toward a robot of lower id or without robust separators) and reports how
//      many of its weights are undecided, in one channel step; it takes the weights of the
//      separators its lower neighbours own from their messages, solves the weighted subgraph
//      (WeightedGraph) with RunRobotProgram from its current estimate and copies, and recomputes
//      r2; the schedule stops when the team's undecided count was 0 (or after max_iterations);
//   4. as RunRobustDgs: the rejected factors it owns whose r2 is within c2 come back (one step:
//      their weights to the neighbours, and the team's count of readmitted and not-one weights);
//      if some weight is not 1, the inliers alone (SubGraph of weight >= 0.5) are solved once
//      more, when every live robot is linked to robot 0 (or to a robot with a prior) through
//      separators of weight >= 0.5 (flooded over the team in channel steps, a robot's flag per
//      step); a variable no inlier touches keeps the rounds' estimate. One more step reduces the
//      inliers' cost before and after that solve (each robot the factors it owns): the solve is
//      kept only when it does not raise it (KeepInlierSolve), else the rounds' estimate stays.
//   5. with the check and retest_left_out, when that solve was kept, as RunRobustDgs: one step in
//      which the higher robot of each pair sends the lower its estimates of its variables, held
//      by inliers, in the robust separators the check left out and still rejected; the lower
//      robot's candidates are those with the check's support and both ends held. Then per
//      candidate: a step in which every robot offers its untried candidate of lowest r^T Omega r
//      (the team takes the lowest, ties to the lower robot id; none left: done), a weight step
//      (the owner's weight 1), the solve of the inliers with it, and a step reducing their cost
//      F1: it stays when 2 (F1 - F0) <= c2 (F0 the inliers' cost so far), else every robot puts
//      its weights and estimate back. Then, with retest_groups, the groups (RunRobustDgs's): a
//      step in which every robot offers the size of its next group of GroupMinimum or more
//      separators still left out (per neighbour of higher id, increasing: those of the pair's
//      runner-up set, PairConsistency::runner_up, with both ends held); the team takes the lowest
//      robot offering. The trial: every robot sets the robust
//      weights to 1 for an inlier, else 0, the group's owner its separators to 1, a weight step;
//      a step in which the higher robot of each pair sends the lower its estimates of its
//      variables in the factors it may use (all but the check's rejects still left out), for the
//      truncated cost before; then solves of those factors weighted (WeightedGraph), each followed
//      by a weight step with the weights it owns at the result (1 within c2, else 0) and the
//      team's count of changed ones, until none changed or after retest_group_solves; a step
//      reducing the truncated cost of those factors before and after: kept when it fell, else
//      every robot puts its weights and estimate back.
// Before step 1, with options.check_separators, the pairwise check of the separators
// (separator_consistency.h, PCM), as RunRobustDgs runs it:
//   C1. every robot builds its own map (its own factors solved alone, the robust ones by GNC-TLS,
//       and their marginal covariances) and sends each neighbour of lower id the map's estimates
//       of its variables in their separators (a DGS message) and their joint covariance (a
//       CovarianceMessage; none with map_uncertainty off); empty ones toward higher ids;
//   C2. the lower robot of each pair finds the largest pairwise-consistent set of their
//       separators (ConsistentSeparators) and sends the other its verdict (a WeightMessage: per
//       separator 1 kept / 0 not, then 1 if the pair confirms itself, min_support); every robot
//       reports its id as its label;
//   C3. the robots linked through confirmed pairs: each takes the lowest label among itself and
//       its confirmed partners, step after step, until no report changes (the groups of
//       ConnectedRobots);
//   C4. the final verdict: a pair below min_support keeps the separators of its largest sets
//       (PairConsistency::kept) when its two robots share a label and those sets have
//       linked_min_support separators, else none; the same step sums the
//       separators left out over the team. If some were, the robots flood whether each still
//       reaches robot 0 through the kept separators (as for the inliers' solve, step 4); if one
//       does not, every robot stops there (RobustProgramResult::unlinked).
// With RobustRobotProblem::checked, the maps of C1 are made of the checked factors only and only
// checked separators are tested (the others are kept). Only robust separators are tested (a
// least-squares one is kept).
//   C5, run first: each robot checks its own loop closures (the robust factors between two of its
//       poses, checked ones only with `checked`) through its own odometry, as RunRobustDgs does
//       (CheckEachRobotsLoopClosures): nothing crosses the network. The map of C1 then holds
//       none of its loop closures along its odometry (OdometryCheckResult::along_odometry) nor
//       those this check rejected; those it kept stay for GNC, but do not bend the map the
//       separators are judged on (RunRobustDgs's CheckSeparators). Object SLAM marks none (its
//       robust factors touch objects); a single robot's file split among robots marks its loop
//       closures (LoopClosureFactors). Those it rejects are not in C4's team sum and C4's flood
//       does not see them: a robot whose own loop closures alone link some of its poses (a gap in
//       its odometry) and that loses them here is not stopped there (RunRobustDgs throws
//       UnderdeterminedError).
// The separators it leaves out are left out of every solve; after GNC, before the readmission,
// the higher robot of each pair sends the lower its estimates of their variables in the
// separators left out, so that those whose residual is within c2 come back as in RunRobustDgs.
// Weights change only between solves; only estimates, weights, the check's covariances and the
// reports' scalars cross the network. The program makes the agent calls of RunRobustDgs (the
// check's local solves, the solves of its kept graph) with the solver in Jacobi order, on the
// same numbers, so a team of programs reproduces it (to the solves' rounding; the tests: 1e-9).
// The inlier solve's condition is the robots' link graph where RunRobustDgs asks every variable
// to be reached from robot 0: the two differ only for landmarks that no inlier observation holds
// and that only inlier separators to such landmarks of other robots reach (then the agent of that
// robot fails).
// The code by job: robust_program.cc the check's call, GNC, the readmission and the inliers'
// solve; separator_check_program.h the check (C1-C4); retest_program.h the re-tests (step 5);
// robust_robot.h the robot's estimate and weights and the team steps all of them share.
#pragma once

#include <algorithm>
#include <cstdint>
#include <functional>
#include <memory>
#include <vector>

#include "moslam/distributed/dgs_driver.h"
#include "moslam/distributed/robot_program.h"
#include "moslam/distributed/separator_consistency.h"
#include "moslam/robust/gnc.h"

namespace moslam {

// Whether the inliers' solve (step 4; RunRobustDgs alike) is kept: when it does not raise their
// cost F beyond rounding (relative 1e-6). It starts at the rounds' estimate, so a higher cost means
// that its DGS did not solve. Seen (house, 4 robots, rendered perception, 30 % wrong pairs) while
// an agent solved only once every variable of it was tied down: stage 1 ran to max_iterations
// without any robot solving, each waiting (flagged initialisation) for a landmark whose only
// inlier factors are separators to robots that waited too; every translation came back 0 and F
// went from 401 to 2.9e6. The agents now solve the groups tied down first (robot_agent.h); a
// solve that still fails (a robot or landmark the inliers do not tie to robot 0 at all, though
// the robots are linked) is what this turns away.
bool KeepInlierSolve(double cost_before, double cost_after);

// The fewest separators a group of the re-test (RobustDgsOptions::retest_groups) tries: as many
// as confirm a robot pair (min_support; two agree by chance), and at least two (one alone is the
// one-by-one re-test's).
inline std::size_t GroupMinimum(int min_support) {
  return static_cast<std::size_t>(std::max(2, min_support));
}

struct RobustProgramOptions {
  DgsOptions solver;  // every solve (the refinement is forced on; Jacobi order required)
  GncOptions gnc;
  // Before GNC, the pairwise check of the separators (see the top; RobustDgsOptions alike): its
  // threshold 0 means GNC's c2.
  bool check_separators = true;
  SeparatorConsistencyOptions consistency{0.0, 3, 2};
  // After the inliers' solve, the check's rejects re-tested against the joint estimate, as
  // RobustDgsOptions::retest_left_out (step 5 at the top; without the check, nothing to re-test).
  bool retest_left_out = true;
  // Then the robot pairs' groups of the check's rejects, as RobustDgsOptions::retest_groups.
  bool retest_groups = true;
  int retest_group_solves = 10;
  // The check's one-to-one rule kept after GNC too, as RobustDgsOptions::one_to_one_after_gnc:
  // each robot settles the separators it owns (all of a landmark's pairs with one robot).
  bool one_to_one_after_gnc = false;
  // Throws InvalidInputError naming the first bad field.
  void validate() const;
};

// One robot's part: its subgraph (every factor touching its variables, separators in the order
// the other robot's subgraph holds them), its initial estimate (at least its own variables) and
// which factors are robust (one flag per factor of the subgraph).
struct RobustRobotProblem {
  int robot = 0;
  PoseGraph subgraph;
  Values initial;
  std::vector<bool> robust;
  // The factors the separator check sees (RunRobustDgs's `checked`; empty: every factor): its
  // map is made of the checked factors between two of its variables, and it tests the checked
  // separators; the others are kept. Both robots of a separator must agree on its flag.
  std::vector<bool> checked;
};

struct RobustProgramResult {
  Values estimate;    // its own variables, final
  Values neighbours;  // its copies of the neighbours' variables, from the last solve that held
                      // them (the inliers' solve holds none that only rejected factors touch)
  // Per factor of the subgraph: the weight of its last weighted solve after the readmission
  // (owned: computed here; separators owned by a lower neighbour: as received; 1 if not robust).
  std::vector<double> weights;
  GncStatus status = GncStatus::kAllInliers;
  int iterations = 0;   // weighted solves after the least-squares one
  int readmitted = 0;   // owned factors back after GNC (r2 within c2)
  int retests = 0;            // candidates re-tested by the team (retest_left_out), and of those
  int retest_readmitted = 0;  // it owns, the ones back
  int group_retests = 0;      // groups re-tested by the team (retest_groups), and of the
  int group_readmitted = 0;   // separators it owns in them, the ones back
  bool polished = false;  // the inliers were solved alone
  bool polish_refused = false;  // ... but that solve raised their cost: the rounds' estimate kept
  int outliers = 0;     // robust factors of the subgraph with weight < 0.5
  std::vector<RobotProgramResult> solves;  // least squares, the rounds, the inlier solve
  std::int64_t weight_messages = 0;  // WeightMessages sent (the check's verdicts included), and
  std::int64_t weight_bytes = 0;     // their binary size
  // The separator check: the separators to robots of higher id it left out (and its own loop
  // closures, C5), and of those, the ones of pairs too small to confirm themselves kept for GNC
  // (their largest sets); the messages it sent for it (map estimates, covariances, the estimates
  // for the readmission) and their bytes.
  int check_rejected = 0;
  int check_deferred = 0;
  std::int64_t check_messages = 0;
  std::int64_t check_bytes = 0;
  int channel_steps = 0;  // all of them, the solves' included
  // The check left some live robot without a kept separator path to robot 0 (or to a robot with
  // a prior): RunRobustDgs throws UnderdeterminedError there. Every robot of the team finds it
  // alike (a flood over the team, as for the inliers' solve) and stops before any solve: its
  // estimate is its initial one, its weights the check's verdicts (1 kept, 0 left out), no
  // neighbour copies, `solves` empty. Only when the check left some separator out.
  bool unlinked = false;
};

// Makes the agent of one solve: `subgraph` (the weighted or the inlier subgraph) from `initial`;
// the factory owns it, and keeps it at least until its next call. The first call is for the
// whole subgraph from problem.initial. With the separator check, an agent of the whole subgraph
// is also made, not solved, for the steps that reach every neighbour (the check's and the
// readmission's): a channel's neighbours may be those of the agent at work (dgs_node.h).
using AgentFactory = std::function<RobotAgent&(const PoseGraph& subgraph, const Values& initial)>;

// Throws InvalidInputError (bad options, a mask of the wrong size, a neighbour's weights that do
// not match the separators shared with it) and what the solves throw. See `unlinked`.
RobustProgramResult RunRobustRobotProgram(const RobustRobotProblem& problem,
                                          const RobustProgramOptions& options,
                                          const AgentFactory& make_agent, TeamChannel& channel);

}  // namespace moslam
