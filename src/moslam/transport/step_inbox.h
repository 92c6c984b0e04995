// What a DGS node (dgs_node.h) has received for the steps of its solve, checked on receipt: each
// robot's most advanced status and its status of every step, and the estimates, coarse shares,
// weights and covariances of every (step, sender). It says what a step still lacks from a robot
// (its status, or the packets that status announces to this robot), assembles the step's TeamStep
// once nothing is missing, and forgets the steps before one. Internal to the transport module.
#pragma once

#include <cstdint>
#include <map>
#include <set>
#include <string>
#include <utility>
#include <vector>

#include "moslam/distributed/robot_program.h"
#include "moslam/transport/transport.h"

namespace moslam::transport_detail {

// What one ingest() did beside filing packets: the packets it turned away, and a line for each of
// them and for each failure a robot reported (the node logs them).
struct IngestNotes {
  int rejected = 0;
  std::vector<std::string> lines;
};

class StepInbox {
 public:
  // `robot`: the node's; `solve`: the packets taken (others are ignored); `neighbours`: the
  // robots its subgraph's separators reach, the only senders of estimates, weights and
  // covariances it accepts; `neighbour_keys`: the only variables it accepts estimates of.
  StepInbox(int robot, std::uint32_t solve, std::set<int> neighbours, std::set<Key> neighbour_keys);

  // Files the packets of the solve. A status of a robot replaces the one kept when it is more
  // advanced (a higher incarnation; else a later round, or `done`, which is final) and is kept
  // as the robot's status of its step when it is one (a stage's round, not failed nor done).
  // Estimates from a robot that is not a neighbour, or for a variable this robot does not use,
  // weights and covariances from a robot that is not a neighbour, are turned away. Object lists
  // and answers are not the protocol's: ignored.
  IngestNotes ingest(std::vector<Received> packets);

  // The robots heard from (a status of the solve).
  const std::set<int>& heard() const { return heard_; }
  // Per robot heard from: its most advanced status.
  const std::map<int, StatusPacket>& latest() const { return latest_; }
  // Its most advanced status reports a failure (it may be restarted) / says it is done.
  bool failed(int r) const;
  bool done(int r) const;
  // A status of a step (round >= 1) of robot r arrived.
  bool stepped(int r) const { return stepped_.count(r) > 0; }

  // The neighbours of the node's agent at work (its status lists them; a step waits for their
  // packets): at first every neighbour of the subgraph.
  void setStepNeighbours(std::set<int> neighbours) { step_neighbours_ = std::move(neighbours); }
  const std::set<int>& stepNeighbours() const { return step_neighbours_; }

  // What of robot r's step s it still lacks ("": nothing): "status", or the packets its status
  // announces to this robot ("estimates", "coarse share", "weights", "covariance", comma-joined).
  std::string missing(int r, std::uint32_t s) const;
  // Step s with nothing missing from any robot of `others`: their reports and the packets their
  // statuses announce, with `mine` (and `share`, if any) as this robot's. Throws
  // InvalidInputError when something is missing (the caller's bug: wait for missing() first).
  TeamStep collect(std::uint32_t s, const std::vector<int>& others, const TeamReport& mine,
                   const CoarseMessage* share) const;
  // Drops what the steps before s received (late packets of robots that left included).
  void prune(std::uint32_t s);

 private:
  // ingest() of a status and of estimates of this solve.
  void takeStatus(int sender, const StatusPacket& st, IngestNotes& notes);
  void takeEstimates(const EstimatesPacket& e, IngestNotes& notes);
  const StatusPacket* statusOf(int r, std::uint32_t s) const;
  // Robot r, whose step status is `st`, sends this robot per-neighbour packets in the step: the
  // two are neighbours of each other's agents at work.
  bool neighbourOf(int r, const StatusPacket& st) const;

  int robot_;
  std::uint32_t solve_;
  std::set<int> neighbours_;
  std::set<Key> neighbour_keys_;
  std::set<int> step_neighbours_;
  std::set<int> heard_;
  std::set<int> stepped_;
  std::map<int, StatusPacket> latest_;
  std::map<int, std::map<std::uint32_t, StatusPacket>> statuses_;  // per robot, per step
  std::map<std::pair<std::uint32_t, int>, Message> estimates_;     // (step, sender)
  std::map<std::pair<std::uint32_t, int>, CoarseMessage> coarse_;
  std::map<std::pair<std::uint32_t, int>, WeightMessage> weights_;
  std::map<std::pair<std::uint32_t, int>, CovarianceMessage> covariances_;
};

// The report a status carries for its step, and the status fields that carry it (the others
// untouched): ReportOf(status) is `report` after SetReport(report, status).
TeamReport ReportOf(const StatusPacket& s);
void SetReport(const TeamReport& report, StatusPacket& s);

}  // namespace moslam::transport_detail
