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

// The flagged sweeps before the pose stage's conjugate gradients go on while robots are left to
// initialise and the last sweep initialised some.
TEST(FlaggedSweepsDone, WhenEveryRobotSolvedOrTheSweepInitialisedNone) {
  StageStopRule some(StageStopping::kChange, 1e-2);
  some.add(true, 1.0, 1.0);
  some.add(true, 1.0, 1.0);
  some.add(false, kInf, kInf);
  EXPECT_EQ(some.robots(), 3);
  EXPECT_EQ(some.initialisedRobots(), 2);
  EXPECT_FALSE(FlaggedSweepsDone(some, 1));
  EXPECT_TRUE(FlaggedSweepsDone(some, 2));  // none more this sweep: not linked to the anchor
  StageStopRule all(StageStopping::kChange, 1e-2);
  all.add(true, 1.0, 1.0);
  all.add(true, 1.0, 1.0);
  EXPECT_TRUE(FlaggedSweepsDone(all, 1));
}

}  // namespace
}  // namespace moslam
