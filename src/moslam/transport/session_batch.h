// A robot session's batch solve (RobotSessionOptions::online false): after the mission, the
// team's DGS solve of the joint graph, each robot from its own map and its shared pairs. A robot
// that left for good is found by every robot of the team in the same way (a joining status of
// solve 1 + T listing the robot's partners, T its number of steps; SessionChannel::formGroup), and
// the others solve without it; a robot that leaves before the solve's first step stops it
// (DgsNode's TeamChangedError) and the team is formed again without it. The groups are
// journaled, so a robot restarted in the solve takes the same way. Internal to the transport
// module.
#pragma once

#include <vector>

#include "moslam/slam/object_slam.h"
#include "moslam/transport/robot_session.h"
#include "moslam/transport/session_channel.h"
#include "moslam/transport/session_pairs.h"

namespace moslam::transport_detail {

class SessionBatchSolve {
 public:
  // `channel`, `pairs` and `options` (validated by the session) must outlive it.
  SessionBatchSolve(SessionChannel& channel, const SessionPairs& pairs, int num_robots,
                    int num_steps, const RobotSessionOptions& options);

  // Solves the team's graph from the robot's map `slam` (its estimate: result.initial): sets
  // result.subgraph (the robot's part of the graph that was solved) and result.dgs (in the
  // robots' own ids), and with a state_dir writes <state_dir>/result.g2o. Throws
  // UnderdeterminedError when a robust solve's separator check left a robot unlinked.
  void run(const ObjectSlam& slam, RobotSessionResult& result);

 private:
  bool formGroup(std::vector<int>& closure, std::vector<int>& robots, int attempt);
  void solveTeam(const std::vector<int>& closure, RobotSessionResult& result);
  void solveWithoutTheRobotsThatLeft(const ObjectSlam& slam, const std::vector<int>& closure,
                                     const std::vector<int>& robots, int attempt,
                                     RobotSessionResult& result);
  void save(const RobotSessionResult& result) const;

  SessionChannel& channel_;
  const SessionPairs& pairs_;
  int num_robots_;
  int num_steps_;
  const RobotSessionOptions& options_;
  int robot_;
};

}  // namespace moslam::transport_detail
