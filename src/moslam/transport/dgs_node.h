// One robot of a distributed Gauss-Seidel solve that runs over a Transport (transport.h): the
// protocol between robot processes, with no central server. It wraps a RobotAgent
// (distributed/robot_agent.h) and its persistent journal.
//
// Protocol (every robot runs the same rules on the same information, so all decide alike):
//   1. Join: publish a status listing its neighbours (the robots its separators reach); collect
//      statuses until every robot of the closure (itself, its neighbours, theirs, ...) has been
//      heard. That closure is the team; robot 0 (owner of the gauge anchor) must be in it.
//   2. Stages rotation then pose, each in rounds (Jacobi sweeps). Round 0 starts the stage (and
//      without flagged initialisation sends the initial estimates). Round k >= 1 waits until it
//      holds every live team robot's status of round k-1 and the estimates of round k-1 of every
//      neighbour whose status says it sent some; then, when every live robot's status of round
//      k-1 says initialised and change <= eta (or k-1 = max_iterations), the stage ends;
//      otherwise it delivers exactly those round k-1 estimates to the agent, solves once
//      (RobotAgent::iterate), sends its estimates to its neighbours and publishes its status of
//      round k. Estimates of round k-1 only: the result is the in-process driver's with
//      SweepOrder::kJacobi (dgs_driver.h), whatever the timing.
//   3. After the pose stage: finish, save, publish `done`, wait (bounded) until every live
//      robot is done or gone, return.
// Leaving: a team robot whose liveliness is lost for leave_timeout while it is waited for has
// left: the others drop it from the stage (its last estimates stay in use, as a silent robot of
// the driver) and never wait for it again. A robot seen in a later stage than ours moved on
// (decided without us): it is not waited for in this stage.
//
// Persistence (state_dir): the journal (journal.h) records the team and, per round, the exact
// estimates delivered to the agent, the stage starts, the robots that left and the end. A
// restarted process replays it (the agent is deterministic: the same state, bit for bit),
// re-sends its last round's estimates and status (duplicates are ignored by the receivers) and
// continues; the peers wait for it meanwhile (lock-step rounds), and their transports deliver
// the recent history it missed. Snapshots: estimate.g2o (the robot's variables and subgraph, at
// most once a second and at every stage end), result.g2o when done. A journal written for other
// data or options is refused (InvalidInputError). Snapshots of a subgraph with object landmarks
// are written with KeyScheme::kWithObjects (robots 0..25 only: io/g2o.h).
#pragma once

#include <chrono>
#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include "moslam/distributed/dgs_driver.h"
#include "moslam/graph/pose_graph.h"
#include "moslam/transport/transport.h"

namespace moslam {

struct DgsNodeRound {
  DgsStage stage = DgsStage::kRotation;
  std::uint32_t round = 0;
  bool sent = false;
  double change = 0.0;
  bool replayed = false;  // restored from the journal rather than computed now
};

struct DgsNodeOptions {
  double eta_rotation = 1e-2;
  double eta_pose = 1e-2;
  int max_iterations = 1000;  // rounds per stage
  double gamma = 1.0;
  bool flagged_initialisation = true;
  bool weight_by_information = false;

  std::chrono::milliseconds join_timeout{60000};    // forming the team
  std::chrono::milliseconds leave_timeout{15000};   // a waited-for robot not alive this long left
  std::chrono::milliseconds stall_timeout{300000};  // no round completed for this long: fail
  std::chrono::milliseconds finish_timeout{10000};  // waiting for the others to be done
  std::string state_dir;  // journal.bin, estimate.g2o, result.g2o; empty: nothing persisted
  std::function<void(const DgsNodeRound&)> on_round;  // after every round (also replayed ones)

  // Throws InvalidInputError naming the first bad field.
  void validate() const;
};

// The in-process driver options that give the same result (Jacobi order).
DgsOptions DriverOptions(const DgsNodeOptions& options);

struct DgsNodeResult {
  Values estimate;              // the robot's own variables, final
  int rotation_rounds = 0;      // sweeps of each stage (as DgsStageReport::iterations)
  int pose_rounds = 0;
  bool rotation_converged = false;
  bool pose_converged = false;
  std::vector<int> team;        // robots of the solve, this one included
  std::vector<int> left;        // robots that left during the solve
  std::uint32_t incarnation = 0;  // earlier starts of this robot found in the journal
  int replayed_rounds = 0;
  std::int64_t journal_truncated_bytes = 0;
  std::int64_t estimate_messages = 0;      // DGS estimates sent by this process
  std::int64_t estimate_binary_bytes = 0;  // their size in the binary encoding (messages.h)
  std::int64_t rejected_estimates = 0;     // valid samples the protocol refused (not a neighbour,
                                           // keys it does not need)
  TransportStats transport;
  double seconds = 0.0;
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
