// One robot of the distributed solve over a Transport (transport.h): the protocol between robot
// processes, with no central server. It runs the robot program (distributed/robot_program.h:
// the two DGS stages with the change or error-bound rule, the two-level correction, the
// refinement) on a RobotAgent, as a TeamChannel over the transport, with a persistent journal;
// with options.gnc, the robust program around it (distributed/robust_program.h: GNC-TLS rounds,
// one agent per solve, weights to the neighbours in WeightsPackets).
//
// Protocol (every robot runs the same program on the same information, so all decide alike):
//   1. Join: publish a status listing its neighbours (the robots its separators reach); collect
//      statuses until every robot of the closure (itself, its neighbours, theirs, ...) has been
//      heard. That closure is the team; robot 0 (owner of the gauge anchor) must be in it. With
//      options.team (a robot session formed it from its joining statuses) there is no wait.
//   2. Steps: the program's channel steps, numbered 1, 2, ... over the whole solve (the `round`
//      of the packets). At step s the robot sends its estimates to its neighbours, its coarse
//      share (if any) and its status (the program's TeamReport) to every robot, then waits until
//      it holds the status of step s of every live team robot, the step-s estimates of every
//      neighbour whose status says it sent some, the step-s share of every robot whose status
//      says it has one and the step-s weights of every neighbour whose status says weights. Only
//      step-s packets are used: the result is the in-process driver's with SweepOrder::kJacobi
//      (dgs_driver.h; robust: RunRobustDgs, with the separator check when separator_check is
//      set), whatever the timing.
//   3. After the program: save, publish `done`, wait (bounded) until every live robot is done or
//      gone, return.
// Leaving: a team robot whose liveliness is lost for leave_timeout while it is waited for has
// left: the others drop it (its last estimates stay in use, as a silent robot of the driver;
// the program's absent()) and never wait for it again.
//
// Persistence (state_dir): the journal (journal.h) records the team, every completed step
// (the reports, estimates and shares it returned to the program), the robots that left and the
// end. A restarted process replays the program on the journal (the agent and the program are
// deterministic: the same state, bit for bit, with nothing sent), re-sends its last step's
// packets (duplicates are ignored by the receivers) and continues; the peers wait for it
// meanwhile (lock-step), and their transports deliver the recent history it missed. Snapshots:
// estimate.g2o (the robot's variables and subgraph, at most once a second and at every stage
// end), result.g2o when done. A journal written for other data or options is refused
// (InvalidInputError). Snapshots of a subgraph with object landmarks are written with
// KeyScheme::kWithObjects (robots 0..25 only: io/g2o.h).
#pragma once

#include <chrono>
#include <cstdint>
#include <functional>
#include <optional>
#include <string>
#include <vector>

#include "moslam/common/errors.h"
#include "moslam/distributed/dgs_driver.h"
#include "moslam/distributed/robot_program.h"
#include "moslam/distributed/robust_program.h"
#include "moslam/graph/pose_graph.h"
#include "moslam/transport/transport.h"

namespace moslam {

// Progress: once when the solve starts (round 0, stage_round 0: the team is formed), then after
// every protocol step.
struct DgsNodeRound {
  DgsStage stage = DgsStage::kRotation;
  std::uint32_t round = 0;  // the protocol step (1-based, over the whole solve)
  int stage_round = 0;      // the step's number within its stage (1-based)
  bool sent = false;        // this robot sent estimates in it
  double change = 0.0;      // its report: lastChange() (+inf before a solve of the stage)
  bool replayed = false;    // restored from the journal rather than computed now
};

struct DgsNodeOptions {
  // The solver (dgs_driver.h); the robots solve in parallel, so `order` is ignored (Jacobi).
  DgsOptions solver;

  std::chrono::milliseconds join_timeout{60000};    // forming the team
  std::chrono::milliseconds leave_timeout{15000};   // a waited-for robot not alive this long left
  std::chrono::milliseconds stall_timeout{300000};  // no step completed for this long: fail
  std::chrono::milliseconds finish_timeout{10000};  // waiting for the others to be done
  std::string state_dir;  // journal.bin, estimate.g2o, result.g2o; empty: nothing persisted
  // The solve its packets carry (transport.h): 0, the batch solve; packets of other solves are
  // ignored (online mapping runs one solve per rendezvous over the same transport).
  std::uint32_t solve = 0;
  // The robust solve (distributed/robust_program.h: GNC-TLS rounds around the solver, weights
  // exchanged in WeightsPackets; the refinement is forced on); none: least squares.
  std::optional<GncOptions> gnc;
  // With gnc: which factors of the subgraph are robust (one flag each); empty: the separators.
  // Robust factors between two of the robot's own poses are checked through its odometry
  // (robust_program.h, C5) when separator_check is set.
  std::vector<bool> robust;
  // With separator_check: the factors the check sees (RobustRobotProblem::checked; one flag
  // each); empty: all. A check that leaves a robot unlinked ends the solve with
  // DgsNodeResult::robust->unlinked and no solve (robust_program.h).
  std::vector<bool> checked;
  // With gnc: the pairwise check of the separators before GNC (robust_program.h, C1-C4; the map
  // covariances in CovariancePackets); none: GNC alone. Its threshold 0: GNC's c2.
  std::optional<SeparatorConsistencyOptions> separator_check;
  // With separator_check: its rejects re-tested after the inliers' solve (robust_program.h).
  bool retest_left_out = true;
  bool retest_groups = true;  // and then the robot pairs' groups of them (robust_program.h)
  // With gnc: the check's one-to-one rule kept after GNC too (RobustDgsOptions::
  // one_to_one_after_gnc).
  bool one_to_one_after_gnc = false;
  // The team, when the caller formed it already (a robot session, from the joining statuses of
  // its robots: robot_session.h): the node then does not wait for a status of each robot before
  // its first step. A robot of it found gone (the leave rule) at the first step, before any
  // status of a step of it arrived (it died after it joined), stops the solve: run() throws
  // TeamChangedError naming it, and the caller forms the team again without it. (Taking it as
  // silent from the first step instead leaves its variables at nothing: with the gauge's owner,
  // or a robot that links the others, the rest of the team has no anchor and its estimate
  // collapses.) Every robot of the
  // team waits for it at the same first step, so all stop alike. Increasing ids, this robot,
  // robot 0 and its neighbours among them. Empty: the node forms the team from the statuses
  // (step 1 of the protocol above).
  std::vector<int> team;
  std::function<void(const DgsNodeRound&)> on_round;  // after every step (also replayed ones)
  std::function<void(const std::string&)> log;  // team, leaves, failures; default: stderr

  // Throws InvalidInputError naming the first bad field.
  void validate() const;
};

// The in-process driver options that give the same result (solver with Jacobi order).
DgsOptions DriverOptions(const DgsNodeOptions& options);

struct DgsNodeResult {
  Values estimate;              // the robot's own variables, final
  Values neighbours;            // its copies of the neighbours' variables after the refinement
                                // (RobotAgent::neighbourEstimates; empty without it)
  int rotation_rounds = 0;      // sweeps of each stage (as DgsStageReport::iterations)
  int pose_rounds = 0;
  bool rotation_converged = false;
  bool pose_converged = false;
  RobotProgramResult program;   // the stages and the refinement as this robot saw them (robust:
                                // of the least-squares solve)
  std::optional<RobustProgramResult> robust;  // with options.gnc: the GNC rounds, weights, ...
  std::vector<int> team;        // robots of the solve, this one included
  std::vector<int> left;        // robots that left during the solve
  std::uint32_t incarnation = 0;  // earlier starts of this robot found in the journal
  int replayed_rounds = 0;      // channel steps replayed from the journal
  std::int64_t journal_truncated_bytes = 0;
  std::int64_t estimate_messages = 0;      // DGS estimates sent by this process
  std::int64_t estimate_binary_bytes = 0;  // their size in the binary encoding (messages.h)
  std::int64_t coarse_messages = 0;        // coarse shares published by this process
  std::int64_t coarse_binary_bytes = 0;    // their size in the binary encoding
  std::int64_t weight_messages = 0;        // robust solve: weight messages sent by this process
  std::int64_t weight_binary_bytes = 0;    // their size in the binary encoding
  std::int64_t covariance_messages = 0;    // the separator check's covariances sent
  std::int64_t covariance_binary_bytes = 0;  // their size in the binary encoding
  std::int64_t rejected_estimates = 0;     // valid samples the protocol refused (not a neighbour,
                                           // keys it does not need)
  TransportStats transport;
  double seconds = 0.0;
};

// DgsNode::run with DgsNodeOptions::team: robots of the team left before their first step.
class TeamChangedError : public Error {
 public:
  TeamChangedError(std::vector<int> robots, const std::string& what)
      : Error(what), robots_(std::move(robots)) {}
  const std::vector<int>& robots() const { return robots_; }  // the node's ids, increasing

 private:
  std::vector<int> robots_;
};

class DgsNode {
 public:
  // `subgraph`: every factor touching a variable of `robot` (its g2o file); `initial`: at least
  // its own variables. Throws InvalidInputError (bad options, a factor without the robot's
  // variables, a journal of another run), UnderdeterminedError (robot owns no variable).
  DgsNode(int robot, PoseGraph subgraph, Values initial, Transport& transport,
          DgsNodeOptions options = {});
  ~DgsNode();
  DgsNode(const DgsNode&) = delete;
  DgsNode& operator=(const DgsNode&) = delete;

  // Runs the protocol to the end, once. Throws moslam::Error on a timeout (team not formed, no
  // progress) or a solver failure; a failed status is published first.
  DgsNodeResult run();

 private:
  class Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace moslam
