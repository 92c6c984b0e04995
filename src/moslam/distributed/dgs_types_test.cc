#include "moslam/distributed/dgs_types.h"

#include <gtest/gtest.h>

#include <limits>

namespace moslam {
namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();

TEST(StageStopRule, EveryRobotSolvedWithinEtaByTheChosenMeasure) {
  StageStopRule change(StageStopping::kChange, 1e-2);
  change.add(true, 5e-3, 0.5);
  change.add(true, 1e-2, kInf);  // at eta: within
  EXPECT_TRUE(change.converged());
  EXPECT_EQ(change.maxChange(), 1e-2);
  EXPECT_EQ(change.maxBound(), kInf);
  // The same reports under the error-bound rule: the bounds are far from eta.
  StageStopRule bound(StageStopping::kErrorBound, 1e-2);
  bound.add(true, 5e-3, 0.5);
  bound.add(true, 1e-2, kInf);
  EXPECT_FALSE(bound.converged());
  StageStopRule tight(StageStopping::kErrorBound, 1e-2);
  tight.add(true, 0.3, 4e-3);
  EXPECT_TRUE(tight.converged());
}

TEST(StageStopRule, ARobotThatHasNotSolvedOrNoRobotAtAllKeepsTheStageGoing) {
  StageStopRule waiting(StageStopping::kChange, 1e-2);
  waiting.add(true, 0.0, 0.0);
  waiting.add(false, 0.0, 0.0);  // flagged initialisation: not yet solved in the stage
  EXPECT_FALSE(waiting.converged());
  EXPECT_FALSE(StageStopRule(StageStopping::kChange, 1e-2).converged());
}

}  // namespace
}  // namespace moslam
