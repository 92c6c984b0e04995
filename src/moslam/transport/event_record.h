// The journal record of one finished rendezvous event of a RobotSession (robot_session.h): the
// pairs of shared objects it added and the pairs shared before that it removed (the consistency
// check across rendezvous, unknown initial poses). Internal to the transport module; fuzzed by
// fuzz/journal_fuzz.cc. Little-endian, after the record type byte:
//
//   u32 event | u32 n | n x (u32 alpha object | u32 beta object) | u32 m | m x (the same)
//
// And the record of a partner found gone for good (online mapping: robot_session.h), from which
// on the robot skips its rendezvous and leaves it out of its group solves:
//
//   u16 robot | u32 step (the time step at which it was found gone)
#pragma once

#include <cstdint>
#include <string>
#include <utility>
#include <vector>

namespace moslam::transport_detail {

using ObjectPairs = std::vector<std::pair<std::uint32_t, std::uint32_t>>;

struct EventRecord {
  std::uint32_t event = 0;  // index in the scenario's event list
  ObjectPairs pairs;        // (alpha landmark, beta landmark) added
  ObjectPairs removed;      // shared before, dropped
};

// Appends the record's fields to `out`.
void AppendEventRecord(const EventRecord& record, std::vector<std::uint8_t>& out);
// Reads the fields from `bytes` at `offset` (just after the type byte) to the end. Throws
// InvalidInputError "<what>: ..." on truncated or trailing bytes, or a list that uses an object
// twice (what a rendezvous answer never does).
EventRecord ReadEventRecord(const std::vector<std::uint8_t>& bytes, std::size_t offset,
                            const std::string& what);

struct LeftRecord {
  std::uint16_t robot = 0;
  std::uint32_t step = 0;
};

void AppendLeftRecord(const LeftRecord& record, std::vector<std::uint8_t>& out);
// As ReadEventRecord: throws InvalidInputError "<what>: ..." on truncated or trailing bytes.
LeftRecord ReadLeftRecord(const std::vector<std::uint8_t>& bytes, std::size_t offset,
                          const std::string& what);

}  // namespace moslam::transport_detail
