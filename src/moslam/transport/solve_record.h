// The journal records of an online robot session's group solves (robot_session.h, online): what a
// restarted robot needs to take a group solve without the network. Internal to the transport
// module; fuzzed by fuzz/journal_fuzz.cc. Little-endian, after the record type byte; a key is
// u16 robot | u8 kind (0 pose, 1 object) | u64 index, a pose 9 f64 (rotation matrix, column
// major) then 3 f64 (translation), bit for bit:
//
//   group:  u32 step | u16 n | n x u16 robot | u32 m | m x (key mine | key other | u8 flags |
//           [held: u32 copy step | pose])                    flags: 1 mine is alpha, 2 held
//   solve:  u32 step | u32 n | n x (key | pose) | u32 m | m x (key | u32 step | pose) |
//           u32 rotation rounds | u32 pose rounds | u32 refine steps | u32 protocol steps |
//           u32 object-object | u32 team factors | u8 refine status |
//           u8 flags (1: unlinked) | u32 k | k x (key alpha | key beta) | u32 f | f x u32 index
//
// The group record is written when the group has formed, before its DGS starts (a robot restarted
// in the solve cannot hear the joining statuses again: they left the transports' history); the
// solve record when the solve is over: the robot's map and the partner landmarks it holds then;
// robust (RobotSessionOptions: dgs.gnc), the verdicts that stand after it: the robot's shared
// pairs set aside (alpha and beta landmarks, in its order) and the indices of the factors of its
// own graph rejected (increasing), or that the check left the group unlinked (nothing changed).
#pragma once

#include <cstdint>
#include <string>
#include <utility>
#include <vector>

#include "moslam/distributed/dgs_driver.h"
#include "moslam/graph/pose_graph.h"
#include "moslam/online/group_solve.h"

namespace moslam::transport_detail {

struct GroupRecord {
  std::uint32_t step = 0;
  std::vector<int> robots;     // the group, increasing
  std::vector<TeamPair> team;  // the held factors of the group problem (BuildRobotGroupPart)
};

struct SolveRecord {
  std::uint32_t step = 0;
  Values estimate;       // the robot's map after the solve (its own frame)
  HeldEstimates held;    // the held copies the solve updated
  std::uint32_t rotation_rounds = 0, pose_rounds = 0, refine_steps = 0, protocol_steps = 0;
  std::uint32_t object_object = 0, team_factors = 0;
  StageStatus refine_status = StageStatus::kNotRun;
  bool unlinked = false;                      // robust: not solved, nothing changed
  std::vector<std::pair<Key, Key>> set_aside;  // robust: its pairs set aside after the solve
  std::vector<std::uint32_t> rejected;         // robust: its own graph's factors rejected
};

// Append the record's fields to `out`.
void AppendGroupRecord(const GroupRecord& record, std::vector<std::uint8_t>& out);
void AppendSolveRecord(const SolveRecord& record, std::vector<std::uint8_t>& out);
// Read the fields from `bytes` at `offset` (just after the type byte) to the end. Throw
// InvalidInputError "<what>: ..." on truncated or trailing bytes, robots not increasing or out of
// 0..65535, a key of another kind or an index beyond 2^56 - 1, a pose that is not finite or whose
// rotation is not orthonormal (1e-6), keys repeated or not increasing, an unknown flag or refine
// status, a pair set aside that is not two landmarks of two robots, rejected factor indices not
// increasing.
GroupRecord ReadGroupRecord(const std::vector<std::uint8_t>& bytes, std::size_t offset,
                            const std::string& what);
SolveRecord ReadSolveRecord(const std::vector<std::uint8_t>& bytes, std::size_t offset,
                            const std::string& what);

}  // namespace moslam::transport_detail
