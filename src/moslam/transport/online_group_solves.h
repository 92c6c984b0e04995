// A robot session's online group solves (RobotSessionOptions::online; OnlineTeam::onRendezvous
// is the in-process twin): after the rendezvous events of step t, the robots connected to this
// one through the step's events, split by the shared pairs among them, solve their joint graph
// with a DgsNode, each from its own part, as solve 1 + t. Each robot knows only its own pairs, so
// the group is found as the DgsNode forms a team: every robot publishes a joining status of the
// solve listing its partners in range, and the group is the closure of those lists
// (SessionChannel::formGroup). With dgs.gnc the solve is robust and each robot keeps the verdicts
// on its own pairs and factors. Every finished solve is journaled; a restarted robot takes it
// from the journal without the network and resumes the one it was in from that solve's own
// DgsNode journal (<state_dir>/solves/step_<t>). Internal to the transport module.
#pragma once

#include <optional>
#include <set>
#include <string>
#include <vector>

#include "moslam/online/group_solve.h"
#include "moslam/transport/dgs_node.h"
#include "moslam/transport/robot_session.h"
#include "moslam/transport/session_channel.h"
#include "moslam/transport/session_pairs.h"

namespace moslam::transport_detail {

class OnlineGroupSolves {
 public:
  // `channel`, `pairs`, `events` and `options` (validated by the session) must outlive it.
  OnlineGroupSolves(SessionChannel& channel, SessionPairs& pairs,
                    const std::vector<RendezvousEvent>& events, const RobotSessionOptions& options);

  // The group solve of step t (after its events): the robot's map, its copies of the partners'
  // landmarks and (robust) its verdicts updated, the map saved (SaveSessionMap, "step_<t>").
  // None when it solved with no one: no partner in range, or all of them gone.
  std::optional<SessionSolve> solve(ObjectSlam& slam, int t);

 private:
  bool joinGroup(int t, const std::set<int>& range, std::uint32_t solve, int attempt,
                 std::vector<int>& robots, std::vector<TeamPair>& team);
  SolveRecord recordSolved(ObjectSlam& slam, int t, const std::vector<int>& robots,
                           const RobotGroupPart& part, const DgsNodeResult& solved);
  SessionSolve finish(ObjectSlam& slam, int t, const std::vector<int>& robots,
                      const SolveRecord& done, const TransportStats& sent,
                      std::chrono::steady_clock::time_point t0, bool replayed);
  void judge(const ObjectSlam& slam, const std::vector<int>& robots, const RobotGroupPart& part,
             const RobustProgramResult& solved, SolveRecord& done) const;
  void applyVerdicts(ObjectSlam& slam, const SolveRecord& done, int t);

  SessionChannel& channel_;
  SessionPairs& pairs_;
  const std::vector<RendezvousEvent>& events_;
  const RobotSessionOptions& options_;
  int robot_;
  HeldEstimates held_;  // the partner landmarks it holds (online/group_solve.h)
};

// The robot's map (its graph and estimate, g2o with objects, and TUM) in
// <state_dir>/maps/<name>/, written to a temporary folder first and swapped in place of the last
// version in one step (ReplaceDirectory, common/whole_file.h); nothing without a state_dir.
void SaveSessionMap(const std::string& state_dir, const ObjectSlam& slam, const std::string& name);

}  // namespace moslam::transport_detail
