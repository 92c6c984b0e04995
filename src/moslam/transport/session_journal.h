// The rendezvous journal of a robot session (robot_session.h), `rendezvous.bin` in its state
// directory: a header naming the robot and the run, then one record per rendezvous answered
// (event_record.h), group formed and online group solve finished (solve_record.h) and partner
// found gone for good. A restarted session reads it back whole here, checked against the run
// that opens it, and takes every answer, group and solve from it instead of redoing them.
// Internal to the transport module.
#pragma once

#include <cstddef>
#include <cstdint>
#include <map>
#include <memory>
#include <string>
#include <vector>

#include "moslam/transport/event_record.h"
#include "moslam/transport/journal.h"
#include "moslam/transport/solve_record.h"

namespace moslam::transport_detail {

// What the run that opens a journal is: a record of another run, or out of its range, is refused.
struct SessionJournalRun {
  int robot = 0;
  std::uint64_t fingerprint = 0;  // of everything the session's results depend on
  int num_robots = 0;
  std::uint32_t num_steps = 0;  // a batch run's group forms at the end, step num_steps
  std::size_t num_events = 0;
  bool online = false;  // only an online run solves groups during the mission
};

// The records a journal held when it was opened.
struct SessionJournalContents {
  std::map<std::uint32_t, EventRecord> events;  // by event index
  std::map<int, GroupRecord> groups;            // by step: the last attempt's group
  std::map<int, int> group_records;             // by step: how many attempts were journaled
  std::map<int, SolveRecord> solves;            // online, by step: the group solves finished
  std::vector<LeftRecord> left;                 // partners found gone (self: left), in order
};

class SessionJournal {
 public:
  // Opens (creating if missing) the journal at `path`. An empty one gets the run's header; a
  // journal of another run (robot, fingerprint), a record out of the run's range, a group solve
  // in a batch run or without its group throws InvalidInputError, naming `state_dir` or `path`.
  SessionJournal(const std::string& path, const SessionJournalRun& run,
                 const std::string& state_dir);

  const SessionJournalContents& contents() const { return contents_; }
  const std::string& path() const { return journal_->path(); }

  // Each appends one record, written whole before it returns (journal.h).
  void append(const EventRecord& record);
  void append(const GroupRecord& record);
  void append(const SolveRecord& record);
  void append(const LeftRecord& record);

 private:
  void read(const SessionJournalRun& run, const std::string& state_dir);

  std::unique_ptr<Journal> journal_;
  SessionJournalContents contents_;
};

}  // namespace moslam::transport_detail
