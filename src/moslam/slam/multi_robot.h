// Multi-robot object SLAM over a simulation, and the joint graph it produces.
//
// RunMultiRobotObjectSlam drives one ObjectSlam per robot through the simulated measurements, time
// step by time step (all robots add pose t, then the rendezvous events of step t run in order).
// Before a rendezvous both robots refresh their estimate (ObjectSlamConfig::iterations_per_update
// Gauss-Newton iterations); the shared objects found are kept in one team-wide list (each pair
// once; in a deployment both robots hold its factor). After the last step every robot runs
// `final_iterations` Gauss-Newton iterations on its own graph.
//
// AssembleJointProblem builds the team's joint graph: the union of the robots' graphs (odometry and
// object-pose factors, keys carrying the robot) and one object-object factor per shared object.
// Its initial values are each robot's own estimate in its own frame (its first pose at the
// identity); robot 0's first pose is the gauge, so the solution is expressed in robot 0's frame.
// The graph is ready for the centralized solver (solver/optimizer.h) and for the distributed one
// (distributed/, partitioned by the robot in each key). The initial values of robots other than
// 0 are far from the joint solution (their frames differ by the initial poses): Gauss-Newton
// from them recovers noise-free problems exactly, but with noise it can stop in a worse local
// minimum (house, 6 robots: 7301 against 6554) or diverge (generated, 64 robots); start the
// centralized solve from ChordalInitialization(graph), as the DGS starts with its rotation stage.
//
// JointGroundTruth gives the true value of every variable in robot 0's frame:
//   x*_{r,i} = (world_T_{0,0})^-1 world_T_{r,i},   o*_{r,k} = (world_T_{0,0})^-1 world_T_object
// where the object of a landmark is the one of the detection that created it.
#pragma once

#include <cstdint>
#include <functional>
#include <map>
#include <optional>
#include <utility>
#include <vector>

#include "moslam/graph/pose_graph.h"
#include "moslam/sim/sensing.h"
#include "moslam/slam/object_slam.h"
#include "moslam/slam/rendezvous.h"

namespace moslam {

struct MultiRobotSlamResult;

// The robots in range at one time step: connected through that step's rendezvous events.
struct RendezvousGroup {
  int step = 0;
  std::vector<int> robots;  // increasing ids, 2 or more
  // Robots of `robots` that have left the team (MultiRobotSlamConfig::leave_after): in range by
  // the events, but they take part in nothing (no solve includes them).
  std::vector<int> gone;
};

struct MultiRobotSlamConfig {
  ObjectSlamConfig slam;
  RendezvousConfig rendezvous;
  // Known (the paper's idealisation): a rendezvous relates the two frames by the robots' initial
  // poses, SimulationData::trajectories[r][0]. Unknown: it aligns the two object maps from the
  // objects alone (rendezvous.h); nothing reads the initial poses then.
  bool known_initial_poses = true;
  // Experiments: wrong associations injected at every rendezvous, the realistic failure of a
  // matcher: for the n pairs a rendezvous adds, k more with k = P / (1 - P) n in expectation
  // (randomly rounded), each an object of alpha paired with an object of beta of the same label
  // that is another world object (none when beta has no such object). Seeded; 0: none.
  double outlier_fraction = 0.0;
  std::uint32_t outlier_seed = 1;
  int final_iterations = 10;  // Gauss-Newton iterations per robot after the last step
  // Fault experiments: robots that leave the team for good (robot id -> the last step they take
  // part in), as the robot processes handle them (transport/robot_session.h). At a later step a
  // rendezvous event with such a robot is skipped: both robots still refresh before it, no pair is
  // exchanged (none injected), and the groups in range list it in `gone`. The batch solve of the
  // processes then leaves it out with its pairs (the joint graph of the others, BuildGroupProblem
  // of online/group_solve.h with no held estimates).
  std::map<int, int> leave_after;
  // Called after the rendezvous events of a time step, once per group of robots in range
  // (groups in the order of their lowest robot id), with the team as it is then: online
  // mapping solves the group's joint graph here (online/online_team.h), an evaluation can
  // measure the maps. Null: nothing (the batch mode).
  using OnRendezvous = std::function<void(const RendezvousGroup&, MultiRobotSlamResult&)>;
  OnRendezvous on_rendezvous;
  // Throws InvalidInputError naming the first bad field.
  void validate() const;
};

// The config whose gates and Lambda follow the object-measurement noise of a simulation: both
// gates AssociationGateForNoise(sigma_R, sigma_t); Lambda from the object noise sigmas (floored
// at the sensing config's information floor, like the measurements' information). The default
// MultiRobotSlamConfig is this for the paper's 5 deg / 0.2 m.
MultiRobotSlamConfig MultiRobotSlamConfigForNoise(const SensingConfig& sensing);

struct RendezvousRecord {
  RendezvousEvent event;
  int objects_sent = 0;          // alpha's landmarks
  int new_shared = 0;            // pairs added by this event
  int new_shared_correct = 0;    // ... whose landmarks have the same true object
  int removed = 0;               // pairs shared before, removed as inconsistent
  int removed_correct = 0;       // ... that were right
  int injected = 0;              // wrong pairs injected (MultiRobotSlamConfig::outlier_fraction)
  int truly_shared = 0;          // objects both robots had mapped then (ground truth)
  bool skipped = false;          // one of the two had left (MultiRobotSlamConfig::leave_after)
  // Unknown initial poses: the alignment's outcome; `wrong`: accepted with most pairs wrong.
  std::optional<AlignmentStatus> alignment;
  int alignment_support = 0, alignment_rival = 0;  // ConstellationAlignment::support / rival
  bool alignment_wrong = false;
  std::size_t bytes_alpha_to_beta = 0;
  std::size_t bytes_beta_to_alpha = 0;
};

// Inter-robot association against ground truth. For each pair of robots that met: `possible`
// counts the objects both had mapped at one of their rendezvous (distinct true objects), `found`
// those among them with a correct shared pair. precision = correct / pairs, recall = found /
// possible.
struct InterRobotAssociationStats {
  int pairs = 0;
  int correct = 0;
  int possible = 0;
  int found = 0;
  double precision() const { return pairs > 0 ? double(correct) / pairs : 1.0; }
  double recall() const { return possible > 0 ? double(found) / possible : 1.0; }
};

struct MultiRobotSlamResult {
  std::vector<ObjectSlam> robots;
  std::vector<SharedObject> shared;  // every shared object, once, in the order found
  int injected = 0;                  // wrong pairs injected, still in `shared`
  std::vector<RendezvousRecord> rendezvous;
  AssociationStats intra;            // summed over the robots
  InterRobotAssociationStats inter;
  std::int64_t bytes = 0;            // all rendezvous messages
  double seconds = 0.0;
};

// Throws InvalidInputError on a bad config or inconsistent simulation data.
MultiRobotSlamResult RunMultiRobotObjectSlam(const SimulationData& data,
                                             const MultiRobotSlamConfig& config);

struct JointProblem {
  PoseGraph graph;
  Values initial;              // each robot's own estimate, in its own frame
  int num_robots = 0;
  int num_poses = 0;
  int num_landmarks = 0;
  int num_object_object = 0;   // factors, = shared objects
  // Evaluation only, per factor of `graph`: ObjectSlam::factorObjects() of the robots' factors,
  // ObjectSlam::kNoObservation for the object-object ones.
  std::vector<int> factor_objects;
  // Robots with no chain of factors to robot 0 (empty when the graph is anchored).
  std::vector<int> unanchored_robots;
};

// Throws InvalidInputError when a shared object names a landmark no robot has.
JointProblem AssembleJointProblem(const std::vector<ObjectSlam>& robots,
                                  const std::vector<SharedObject>& shared, const Matrix6& lambda);

// Ground truth of every pose and landmark of `robots`, in robot 0's frame. Landmarks whose true
// object is unknown are left out. Throws InvalidInputError when `robots` does not match `data`.
Values JointGroundTruth(const SimulationData& data, const std::vector<ObjectSlam>& robots);

}  // namespace moslam
