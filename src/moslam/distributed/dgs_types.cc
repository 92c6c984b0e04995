#include "moslam/distributed/dgs_types.h"

#include <algorithm>
#include <string>

#include "moslam/common/errors.h"

namespace moslam {

int StageDimension(DgsStage stage) {
  switch (stage) {
    case DgsStage::kRotation:
      return 9;
    case DgsStage::kPose:
    case DgsStage::kRefine:
      return 6;
  }
  throw InvalidInputError("unknown DGS stage " + std::to_string(static_cast<int>(stage)));
}

std::string ToString(DgsStage stage) {
  switch (stage) {
    case DgsStage::kRotation:
      return "rotation";
    case DgsStage::kPose:
      return "pose";
    case DgsStage::kRefine:
      return "refine";
  }
  return "unknown";
}

std::string ToString(AgentState state) {
  switch (state) {
    case AgentState::kIdle:
      return "idle";
    case AgentState::kRotation:
      return "rotation";
    case AgentState::kPose:
      return "pose";
    case AgentState::kRefine:
      return "refine";
    case AgentState::kDone:
      return "done";
  }
  return "unknown";
}

std::string ToString(SweepOrder order) {
  return order == SweepOrder::kGaussSeidel ? "gauss-seidel" : "jacobi";
}

std::string ToString(StageStopping stopping) {
  return stopping == StageStopping::kChange ? "change" : "error-bound";
}

void StageStopRule::add(bool initialised, double change, double bound) {
  ++robots_;
  initialised_ += initialised ? 1 : 0;
  const double measure = stopping_ == StageStopping::kChange ? change : bound;
  max_change_ = std::max(max_change_, change);
  max_bound_ = std::max(max_bound_, bound);
  converged_ = converged_ && initialised && measure <= eta_;
}

bool FlaggedSweepsDone(const StageStopRule& rule, int initialised_before) {
  return rule.initialisedRobots() == rule.robots() ||
         rule.initialisedRobots() == initialised_before;
}

StageStopping StageStoppingFromString(const std::string& text) {
  if (text == "change") return StageStopping::kChange;
  if (text == "error-bound") return StageStopping::kErrorBound;
  throw InvalidInputError("unknown stage stopping rule '" + text +
                          "' (expected change or error-bound)");
}

}  // namespace moslam
