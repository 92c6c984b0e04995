// The journal record of one completed protocol step of a DgsNode (dgs_node.h): what the step
// returned to the robot program (robot_program.h, TeamStep). Internal to the transport module;
// fuzzed by fuzz/journal_fuzz.cc. Little-endian, after the record type byte:
//
//   u32 step | u8 stage | u16 reports | reports x (u16 robot | u8 flags | f64 change |
//   f64 bound | f64 value0 | f64 value1) | u32 estimates | estimates x (u32 length | Message) |
//   u16 shares | shares x (u32 length | CoarseMessage) |
//   u16 weights | weights x (u32 length | WeightMessage) |
//   u16 covariances | covariances x (u32 length | CovarianceMessage)
//
// flags: 1 sent, 2 initialised, 4 coarse ready, 8 has a share, 16 sent weights, 32 sent
// covariances.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "moslam/distributed/robot_program.h"

namespace moslam::transport_detail {

struct StepRecord {
  std::uint32_t step = 0;
  DgsStage stage = DgsStage::kRotation;
  TeamStep result;
};

// Appends the record's fields to `out`.
void AppendStepRecord(const StepRecord& record, std::vector<std::uint8_t>& out);
// Reads the fields from `bytes` at `offset` (just after the type byte) to the end. Throws
// InvalidInputError "<what>: ..." on truncated or trailing bytes, an unknown stage or flag, a
// report robot out of order, a change or bound that is NaN or negative, a value that is not
// finite, a message, share, weight or covariance message the decoders of messages.h reject, a
// share whose sender has no report saying it has one, or weights (covariances) whose sender's
// report does not say weights (covariance), or twice from one sender.
StepRecord ReadStepRecord(const std::vector<std::uint8_t>& bytes, std::size_t offset,
                          const std::string& what);

}  // namespace moslam::transport_detail
