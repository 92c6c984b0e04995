// Robot trajectories through a world and the rendezvous events between robots.
//
// Trajectories: robot r starts at a distinct navigation node (drawn at random, seeded), heading
// to a random neighbour, and drives a random walk on the navigation graph (sim/world.h): at each
// node it turns to a random neighbour other than the one it came from (it turns back only at a
// dead end). A pose is recorded every `step_length` metres of path (the first at the start node),
// `poses_per_robot` poses in all, at height `camera_height`, heading along the current edge
// (yaw only; x forward, y left, z up). All robots move synchronously: pose i of every robot is
// time step i. Poses are world_T_body ground truth; the known initial pose of robot r is its
// trajectory's first pose.
//
// Rendezvous: two robots meet at time step t when their ground-truth positions are within
// `communication_range` at that step and the pair has not met in the last
// `min_steps_between_events` steps (so a pair that stays together meets again every that many
// steps). Alternatively a fixed schedule of (step, robot, robot) events is given: then the
// schedule is used as is (planned meetings, or communication through a relay: distances are not
// checked).
#pragma once

#include <vector>

#include "moslam/geometry/se3.h"
#include "moslam/sim/world.h"

namespace moslam {

using Trajectory = std::vector<SE3>;  // world_T_body at time steps 0, 1, ...

struct TrajectoryConfig {
  int num_robots = 6;
  int poses_per_robot = 100;
  double step_length = 0.75;   // m of path between consecutive poses
  double camera_height = 0.5;  // m above the floor
  unsigned seed = 1;
  // Throws InvalidInputError naming the first bad field.
  void validate() const;
};

// Throws InvalidInputError when the config is bad, or the world's navigation graph has fewer
// nodes than robots or a node without neighbours.
std::vector<Trajectory> GenerateTrajectories(const World& world, const TrajectoryConfig& config);

struct RendezvousEvent {
  int step = 0;  // time step (pose index) at which the two robots communicate
  int alpha = 0;  // the robot that sends its objects (the lower id when detected by range)
  int beta = 0;   // the robot that matches them and answers with the shared-object list
  friend bool operator==(const RendezvousEvent& a, const RendezvousEvent& b) {
    return a.step == b.step && a.alpha == b.alpha && a.beta == b.beta;
  }
};

struct RendezvousDetectionConfig {
  double communication_range = 4.0;  // m
  int min_steps_between_events = 10;  // per pair of robots
  // When not empty: these events, used as given (validated), instead of detection by range.
  std::vector<RendezvousEvent> schedule;
  // Throws InvalidInputError naming the first bad field.
  void validate() const;
};

// The events ordered by step, then alpha, then beta. Throws InvalidInputError when the config is
// bad, the trajectories differ in length, or a scheduled event names a robot or a step that
// does not exist or a robot meeting itself.
std::vector<RendezvousEvent> DetectRendezvous(const std::vector<Trajectory>& trajectories,
                                              const RendezvousDetectionConfig& config);

}  // namespace moslam
