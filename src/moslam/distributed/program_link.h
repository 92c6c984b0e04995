// The robust program's steps over the team channel, counted in its result (robust_program.h):
// every step, the weight messages and their bytes, the separator check's messages and bytes.
// Internal to the robust program (robust_program.cc, robust_robot.cc, retest_program.cc,
// separator_check_program.cc).
#pragma once

#include <cstdint>
#include <utility>
#include <vector>

#include "moslam/distributed/messages.h"
#include "moslam/distributed/robot_program.h"
#include "moslam/distributed/robust_program.h"

namespace moslam {

class ProgramLink {
 public:
  ProgramLink(int robot, TeamChannel& channel, RobustProgramResult& counts)
      : robot_(robot), channel_(channel), counts_(counts) {}

  // One refinement-stage step of the channel.
  TeamStep step(const TeamReport& report, const std::vector<WeightMessage>& weights = {},
                const std::vector<OutgoingMessage>& estimates = {},
                const std::vector<CovarianceMessage>& covariances = {}) {
    ++counts_.channel_steps;
    return channel_.step(DgsStage::kRefine, estimates, report, nullptr, weights, covariances);
  }

  // A step whose report carries `value` (value[0]) for the team's sums and maxima.
  TeamStep reduce(double value) {
    TeamReport mine;
    mine.value[0] = value;
    return step(mine);
  }

  // A weight message to `other`, counted.
  WeightMessage weightMessage(int other, std::uint32_t round, std::vector<double> weights) {
    WeightMessage m;
    m.sender = robot_;
    m.receiver = other;
    m.round = round;
    m.weights = std::move(weights);
    counts_.weight_bytes += static_cast<std::int64_t>(EncodeWeightMessage(m).size());
    ++counts_.weight_messages;
    return m;
  }

  // A message of 6-vectors (stage kPose) to `other`, with no variable yet.
  OutgoingMessage emptyMessageTo(int other) const {
    OutgoingMessage o;
    o.to = other;
    o.message.stage = DgsStage::kPose;
    o.message.sender = robot_;
    return o;
  }

  // One message of the separator check, of `bytes`.
  void countCheck(std::size_t bytes) {
    ++counts_.check_messages;
    counts_.check_bytes += static_cast<std::int64_t>(bytes);
  }

 private:
  int robot_;
  TeamChannel& channel_;
  RobustProgramResult& counts_;
};

}  // namespace moslam
