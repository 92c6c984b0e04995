// The journal of one robot's DgsNode (dgs_node.h), <state_dir>/journal.bin: a header naming the
// robot and the run (a fingerprint of everything the result depends on), then one record per
// process start, the team formed, each completed protocol step (step_record.h), each robot found
// gone, and the end. A restarted node opens it, refuses another run's, takes the team and counts
// the starts, and replays the steps, the departures and the end in the order they happened, as
// the protocol asks for the steps again. Internal to the transport module.
#pragma once

#include <cstddef>
#include <cstdint>
#include <optional>
#include <set>
#include <string>
#include <vector>

#include "moslam/distributed/robot_program.h"
#include "moslam/transport/journal.h"

namespace moslam::transport_detail {

class NodeJournal {
 public:
  // Opens (creates) `path` for `robot`'s run `fingerprint`. Throws InvalidInputError when it
  // holds another run's journal (naming `state_dir`, the folder a user chose) or an unknown
  // record; moslam::Error when the file cannot be read or written.
  NodeJournal(const std::string& path, int robot, std::uint64_t fingerprint,
              const std::string& state_dir);

  int starts() const { return starts_; }               // process starts journaled before
  const std::set<int>& team() const { return team_; }  // empty: no team journaled
  std::int64_t truncatedBytes() const { return journal_.truncatedBytes(); }

  // The journaled step `s` of `stage`, after the departures and the end journaled before it
  // (added to `left`; `done` set); none when the journal holds no more steps. Throws
  // InvalidInputError when the next journaled step is another one (a damaged journal).
  std::optional<TeamStep> replay(std::uint32_t s, DgsStage stage, std::set<int>& left, bool& done);
  // Whether records are left to replay.
  bool replaying() const { return next_ < pending_.size(); }

  void recordStart();
  void recordTeam(const std::set<int>& team);
  void recordStep(std::uint32_t s, DgsStage stage, const TeamStep& got);
  void recordLeft(int robot, std::uint32_t s);
  void recordDone();

 private:
  Journal journal_;
  int starts_ = 0;
  std::set<int> team_;
  std::vector<std::size_t> pending_;  // records still to replay (steps, departures, the end)
  std::size_t next_ = 0;
};

}  // namespace moslam::transport_detail
