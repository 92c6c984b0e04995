// What the parts of a robot session (robot_session.h) share to talk with the team: the robot's
// transport and the packets received but not used yet (SessionInbox), which robots it still
// counts on (TeamMembership), and its journal with what the journal held when the session
// started, from which a restarted session takes its answers, groups and solves. The rendezvous,
// the batch solve and the online group solves (online_group_solves.h) use it; how a solve's group
// forms from the robots' joining statuses is here, as both kinds of solve form one. Internal to
// the transport module.
#pragma once

#include <chrono>
#include <cstddef>
#include <cstdint>
#include <functional>
#include <map>
#include <memory>
#include <set>
#include <string>
#include <vector>

#include "moslam/online/group_solve.h"
#include "moslam/transport/session_inbox.h"
#include "moslam/transport/session_journal.h"
#include "moslam/transport/team_membership.h"
#include "moslam/transport/transport.h"

namespace moslam::transport_detail {

// A solve formed again without robots that left before its first step (DgsNode's
// TeamChangedError): attempt a of solve s is s + a * 2^24 (solves of steps < 2^24).
std::uint32_t AttemptSolve(std::uint32_t solve, int attempt);
// Whether packets of solve `a` are of a solve before `b` (of an earlier step, or an earlier
// attempt of the same step); presence statuses are of none.
bool SolveBefore(std::uint32_t a, std::uint32_t b);
// The ids 0..n-1 of a group's robots as its DgsNode sees them (GroupTransport).
std::vector<int> GroupIds(std::size_t n);

class SessionChannel {
 public:
  struct Options {
    std::chrono::milliseconds join_timeout{60000};   // a solve's group forming
    std::chrono::milliseconds leave_timeout{15000};  // TeamMembership's rule
    std::function<void(const std::string&)> log;     // required
  };

  // `journal`: the session's, or null (no state directory); what it held is taken here, the
  // departures it lists restored.
  SessionChannel(int robot, int num_robots, Transport& transport, Options options,
                 std::unique_ptr<SessionJournal> journal);

  int robot() const { return robot_; }
  Transport& transport() { return transport_; }
  SessionInbox& inbox() { return inbox_; }
  TeamMembership& membership() { return *membership_; }

  // Received packets: their senders were alive (membership), the packets wait in the inbox.
  void ingest(std::vector<Received> packets);
  // Appends one record to the journal, if there is one.
  template <typename Record>
  void record(const Record& r) {
    if (journal_) journal_->append(r);
  }

  // What the journal held when the session started (empty without one).
  const SessionJournalContents& journaled() const;
  // The attempt of the solve of step t whose group the journal holds last (0: none).
  int journaledAttempt(int t) const;
  // The group of attempt `attempt` of the solve of step t, when the journal held it: a session
  // restarted in that solve takes it instead of forming it again.
  const GroupRecord* journaledGroup(int t, int attempt) const;
  // Journals the group a solve of step `group.step` formed (one record per attempt).
  void recordGroup(const GroupRecord& group);

  bool hasLeft(int robot, int t) const { return membership_->hasLeft(robot, t); }
  bool foundLeft(int robot, int t, std::map<int, std::chrono::steady_clock::time_point>& since) {
    return membership_->foundLeft(robot, t, since);
  }
  void markLeft(int robot, int t, const std::string& why) { membership_->markLeft(robot, t, why); }

  // Waits for the joining statuses of the closure of `partners` within `range` (after publishing
  // `join`) for solve `solve` of step t; the group's robots (those that left out) and its held
  // factors from every member's status. `closure` (optional): the robots of the closure,
  // increasing, those that left included. Throws moslam::Error when the group does not form
  // within the join timeout.
  void formGroup(const StatusPacket& join, const std::set<int>& partners,
                 const std::set<int>& range, std::uint32_t solve, int t, std::vector<int>& robots,
                 std::vector<TeamPair>& team, std::vector<int>* closure = nullptr);

 private:
  int robot_;
  Transport& transport_;
  Options options_;
  std::unique_ptr<SessionJournal> journal_;
  std::map<int, int> group_records_;  // by step: group records journaled (one per attempt)
  SessionInbox inbox_;
  std::unique_ptr<TeamMembership> membership_;
};

}  // namespace moslam::transport_detail
