#include "moslam/distributed/dgs_types.h"

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

StageStopping StageStoppingFromString(const std::string& text) {
  if (text == "change") return StageStopping::kChange;
  if (text == "error-bound") return StageStopping::kErrorBound;
  throw InvalidInputError("unknown stage stopping rule '" + text +
                          "' (expected change or error-bound)");
}

}  // namespace moslam
