// One robot of a simulated scenario as its own process: its object SLAM, its rendezvous over a
// Transport, then its part of the team's distributed solve (DgsNode). The multi-robot pipeline of
// slam/multi_robot.h (RunMultiRobotObjectSlam + AssembleJointProblem + RunDgs in Jacobi order),
// split so that each robot runs only its own part and learns the others' only from the messages
// it receives.
//
// Data: every process simulates the same seeded scenario (SimulateScenario) and keeps only its
// slice (SliceForRobot): its own odometry and detections, the initial poses of all robots (used
// only to match object maps at a rendezvous, as in-process; none with unknown initial poses) and
// the scenario's rendezvous events. The event list stands for "the radios are in range": a
// process does not detect its peers by distance, it meets the peer named by the event at the
// event's time step, and the exchange waits (up to rendezvous_timeout) until that peer answers.
//
// Per time step t the robot adds pose t to its ObjectSlam; when it takes part in events at t it
// refreshes its estimate (as RunMultiRobotObjectSlam does before an event) and then, for each of
// its events in the list's order:
//   alpha: its object list (landmark index, label, pose in its own frame; one ObjectListPacket of
//          step t, published once per step on the shared objects topic) is answered by beta with
//          a SharedObjectsPacket of step t: the pairs it adds;
//   beta:  waits for alpha's list of step t, rounds the poses to float32 exactly as the
//          in-process message encoding does (EncodeObjectMap / DecodeObjectMap), matches with
//          AnswerObjectMap (slam/rendezvous.h, the in-process code: under the known initial poses,
//          or, with options.slam.known_initial_poses false, by aligning the two object maps and
//          checking the pairs of earlier rendezvous again) and sends the answer: the new pairs
//          and the pairs shared before that it drops.
// Both add one object-object factor per new pair (ObjectObjectFactor) and drop the removed ones.
// After the last step: the final Gauss-Newton iterations, then DgsNode on the robot's subgraph
// (its odometry and object-pose factors, then its object-object factors in the order found) from
// its own estimate. The result equals the in-process pipeline's (same shared objects, same DGS
// estimate: the tests check 1e-9).
//
// Faults. Received packets are validated by the transport (unknown robots, malformed content);
// the session also rejects (logs and ignores) answers naming objects this robot does not have
// and lists that the in-process encoding refuses. A peer that does not answer within
// rendezvous_timeout, and has not left for good (below), makes the robot fail (moslam::Error):
// the exchange is not skipped, since skipping would change the result.
// Leaving for good (the rules: team_membership.h): every robot publishes a presence status when
// it starts (kPresenceSolve), so its liveliness is known before its first solve. A robot waited
// for (at a rendezvous, or for its joining status) that is not alive for dgs.leave_timeout has
// left for good, by the DgsNode's rule, whether it was seen alive before or never (one that died
// before this robot's transport heard from it, as DDS delivers a transient-local sample only
// while its writer lives, cannot be told from one that never started: so every robot of a team
// must be started within leave_timeout of its first rendezvous): the robot journals it and
// skips its rendezvous with it from then on (SessionRendezvous::skipped; nothing exchanged).
// Online, no group solve includes it (its pairs with it become held factors); the others find
// the same group, since a robot that left publishes no joining status. The twin:
// MultiRobotSlamConfig::leave_after. Batch: before the solve, every robot with shared pairs
// publishes a joining status listing all the robots it shares pairs with, gone or not, and waits
// for those of the closure, so every robot of the closure finds the same departures; when a robot
// of it left, the others solve without it: its pairs dropped, the robots re-labelled so that the
// lowest holds the gauge (it may be robot 0), as the twin solves the joint graph of the robots
// that stay (BuildGroupProblem with no held estimates; its DgsNode journals in
// state_dir/solves/batch, the result in state_dir/result.g2o in the robots' own ids); with no
// departure, the batch solve as before. The joining statuses form the team of every solve (batch
// and online: DgsNodeOptions::team), so a robot that dies after its joining status and before
// its first step of the solve is waited for at that first step; every other robot of the team
// finds it gone there (DgsNode's TeamChangedError), journals it as gone for good and forms the
// team again without it, as if it had left before: attempt a of the solve runs as solve
// AttemptSolve(s, a) = s + a 2^24, its own packets (the stopped attempt's are dropped), node
// journal in solves/step_<t>_attempt_<a> (batch: solves/batch_attempt_<a>), and a group record
// per attempt (a restarted robot resumes the last). The twin: OnlineOptions::dies_in_solve;
// batch, the solve without it. A robot found gone lists the robots it found gone in its presence
// status (sent again at every departure it finds, and when a robot it found gone sends its own:
// one back after leave_timeout); a robot that reads its own id there has been found gone by the
// team: it leaves the team (journaled as a departure of itself), takes part in no rendezvous or
// solve from then on (batch: its own map is its result) and says so in its presence status (state
// kFailed), so that every robot waiting for it takes it as gone at once. A group that forms
// applies every member's list (presence statuses precede joining statuses, in order per robot):
// a robot found gone by one member is gone for all of them, so all form the same group.
// Restart (state_dir): the rendezvous phase is deterministic given the answers, so the journal
// `rendezvous.bin` (journal.h) records only each finished event's pairs (added and removed:
// event_record.h). A restarted process re-runs its SLAM from its measurements, takes finished
// events from the journal without waiting, re-sends the answers it gave as beta (the old process
// may have died before they left) and continues; the DGS phase has its own journal (dgs_node.h).
// Packets of the DGS protocol that arrive during the rendezvous phase are kept and handed to the
// DGS node.
// Online, the journal also holds each group solve: the group when it formed (its robots and held
// factors: a robot restarted in the solve cannot hear the joining statuses again) and, when the
// solve is over, the robot's map and the partner landmarks it holds (solve_record.h); the solve's
// DgsNode journals in state_dir/solves/step_<t>/ meanwhile. A restarted robot takes its finished
// solves from the journal without the network, and resumes the solve it was in from the node's
// journal, while its partners wait for it (lock-step; a robot not back within the DgsNode's
// leave_timeout has left the solve for them). Not covered: a robot restarted while it waited
// for the joining statuses, when a partner's status has since left the transports' history
// (kTransportHistoryDepth statuses later): it fails at join_timeout.
#pragma once

#include <chrono>
#include <cstdint>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "moslam/sim/sensing.h"
#include "moslam/slam/multi_robot.h"
#include "moslam/transport/dgs_node.h"
#include "moslam/transport/transport.h"

namespace moslam {

// A simulated scenario, built as the experiments build run 0 of a config
// (experiments/simulation_experiment.h): the world of `scenario` with `seed`, `robots`
// trajectories of `poses_per_robot` poses, odometry and object noise (sigma_rotation_deg,
// sigma_translation), rendezvous by range; SLAM gates and Lambda from the noise
// (MultiRobotSlamConfigForNoise).
struct ScenarioSpec {
  std::string scenario = "chairs25";  // chairs25 | house | generated
  int robots = 6;
  unsigned seed = 1;
  double sigma_rotation_deg = 5.0;
  double sigma_translation = 0.2;  // m
  int poses_per_robot = 100;
  // false: the robots do not know one another's initial poses; beta aligns the two object maps
  // at a rendezvous (slam/rendezvous.h), and the robot processes are not given the poses.
  bool known_initial_poses = true;
  // The robots' own association (ObjectSlamConfig; both off: the paper's rule, as `moslam
  // simulate` without --exclusion-radius and --leave-one-out-check): the landmark exclusion
  // radius (m, 0: off) and the leave-one-out check of a pose's matches.
  double exclusion_radius = 0.0;
  bool leave_one_out_check = false;
  // A match nearly as near another landmark of its label refused (ObjectSlamConfig::
  // ambiguity_ratio, in [0, 1); 0: off), and the association gated by the robot's marginal
  // covariance (ObjectSlamConfig::covariance_gate, a chi-square bound with 6 degrees of freedom;
  // 0: off, the paper's fixed gate), as `moslam simulate` with --ambiguity-ratio and
  // --covariance-gate.
  double ambiguity_ratio = 0.0;
  double covariance_gate = 0.0;
  // The robots' loop closure by object constellations (ObjectSlamConfig::loop_closure; off, as
  // `moslam simulate` without --loop-closure).
  bool loop_closure = false;
  // Known initial poses: a rendezvous also aligns the two object maps by their constellation
  // (RendezvousConfig::refine_by_constellation; off, as `moslam simulate` with sampled
  // measurements and without --rendezvous-constellation).
  bool rendezvous_constellation = false;
  // Throws InvalidInputError naming the first bad field.
  void validate() const;
};

SimulationData SimulateScenario(const ScenarioSpec& spec);
MultiRobotSlamConfig ScenarioSlamConfig(const ScenarioSpec& spec);

// What one robot process keeps of a simulation.
struct RobotScenarioData {
  int robot = 0;
  int num_robots = 0;
  RobotMeasurements measurements;       // its own
  std::vector<SE3> initial_poses;       // world_T_{r,0} of every robot r; empty when unknown
  std::vector<RendezvousEvent> events;  // every event of the scenario, ordered by step
  int numSteps() const { return static_cast<int>(measurements.detections.size()); }
};

// Throws InvalidInputError when `robot` is not one of the simulation's robots. Without
// `known_initial_poses` the slice holds no initial pose.
RobotScenarioData SliceForRobot(const SimulationData& data, int robot,
                                bool known_initial_poses = true);

struct SessionRendezvous {
  RendezvousEvent event;
  bool alpha = false;  // this robot's role
  int objects_sent = 0;          // alpha's landmarks in the list
  int new_shared = 0;            // pairs the event added
  int removed_shared = 0;        // pairs shared before that it removed (unknown initial poses)
  std::int64_t binary_bytes = 0;  // in-process encoding of what this robot sent for it
  bool replayed = false;         // taken from the journal
  bool skipped = false;          // the peer had left for good; nothing exchanged
  double seconds = 0.0;          // waiting for the peer
};

// One group solve of online mapping, as this robot took part in it.
struct SessionSolve {
  int step = 0;
  std::vector<int> robots;        // the group (real ids, increasing)
  int object_object = 0;          // this robot's shared pairs with robots of the group
  int team_factors = 0;           // its held factors (pairs with robots out of range)
  int rotation_rounds = 0, pose_rounds = 0, refine_steps = 0, protocol_steps = 0;
  StageStatus refine_status = StageStatus::kNotRun;
  Values estimate;                // its map after the solve (its own frame)
  // Robust (dgs.gnc): the check left the group unlinked (nothing changed: OnlineTeam alike); the
  // robot's pairs set aside and the factors of its own graph rejected, after the solve.
  bool unlinked = false;
  int set_aside = 0;
  int observation_outliers = 0;
  TransportStats sent;            // what this robot sent for the solve (join included)
  bool replayed = false;          // taken from the journal (restart): nothing sent
  double seconds = 0.0;
};

struct RobotSessionOptions {
  MultiRobotSlamConfig slam;
  DgsNodeOptions dgs;  // dgs.state_dir also holds rendezvous.bin; with dgs.gnc and no mask, the
                       // factors touching an object landmark are robust (as in the simulation);
                       // online, every group solve is robust (below)
  // Online mapping (online/group_solve.h; the in-process twin: online/online_team.h): after the
  // rendezvous events of a step, the robots connected through them and linked by shared objects
  // solve their joint graph with DgsNode (dgs.solver, which must refine: the partners' landmarks
  // a robot holds afterwards are its refined copies), each from its own part, as solve 1 + step;
  // no batch solve at the end. dgs.state_dir then receives the map after every solve
  // (maps/step_<t>/map.g2o and robot_<r>.tum) and the journal: a restarted online robot takes
  // the finished solves from it and resumes the one it was in (Restart, above).
  // With dgs.gnc, every group solve is OnlineTeam's robust one (online_team.h; its twin:
  // OnlineOptions::robust): DgsNode with the robust and checked masks of RobustGroupFactors on the
  // robot's part (dgs.robust and dgs.checked must be empty), dgs.separator_check as the check.
  // Each robot keeps the verdicts on its own pairs (JudgePairs: a pair's weight is its lower
  // robot's, so both robots of a pair hold the same) and on its own factors, journaled with the
  // solve; a group the check leaves unlinked (RobustProgramResult::unlinked, which every member
  // finds alike) changes nothing.
  bool online = false;
  std::function<void(const SessionSolve&)> on_solve;  // after each group solve
  std::chrono::milliseconds rendezvous_timeout{60000};  // per event
  std::function<void(const std::string&)> log;          // default: stderr
  std::function<void(const SessionRendezvous&)> on_rendezvous;  // after each event
  // Throws InvalidInputError naming the first bad field (ground-truth association cannot cross
  // the network: it reads the other robot's landmarks).
  void validate() const;
};

struct RobotSessionResult {
  std::vector<SessionRendezvous> rendezvous;  // this robot's events, in order
  std::vector<SharedObject> shared;           // pairs involving this robot, in the order found
  PoseGraph subgraph;                         // what the DGS ran on
  Values initial;                             // its own estimate after the SLAM
  int poses = 0;
  int landmarks = 0;
  std::int64_t rendezvous_binary_bytes = 0;   // sum of binary_bytes
  TransportStats rendezvous_transport;        // counters when the rendezvous phase ended
  double slam_seconds = 0.0;                  // SLAM and rendezvous phase
  DgsNodeResult dgs;                          // the batch solve (not online)
  std::vector<SessionSolve> solves;           // online: the group solves, in order
  Values final_estimate;                      // online: its map at the end (own frame)
  std::vector<SharedObject> set_aside;        // online robust: its pairs set aside at the end
  // The team had found this robot gone (it came back): it left the team at left_team_step and
  // mapped alone from then on (team_membership.h).
  bool left_team = false;
  int left_team_step = -1;
  double seconds = 0.0;
};

// The subgraph of one robot in the joint problem: its graph, then one object-object factor per
// shared object (AssembleJointProblem's factors touching the robot, in the same order).
PoseGraph SessionSubgraph(const ObjectSlam& slam, const std::vector<SharedObject>& shared,
                          const Matrix6& lambda);

class RobotSession {
 public:
  // Throws InvalidInputError on bad options, a transport of another robot or inconsistent data;
  // opening the state directory: as DgsNode.
  RobotSession(RobotScenarioData data, Transport& transport, RobotSessionOptions options);
  ~RobotSession();
  RobotSession(const RobotSession&) = delete;
  RobotSession& operator=(const RobotSession&) = delete;

  // Runs SLAM, rendezvous and DGS, once. Throws moslam::Error on a timeout (a peer that never
  // answers, the DGS errors of DgsNode::run) and InvalidInputError on a journal of another run.
  RobotSessionResult run();

 private:
  class Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace moslam
