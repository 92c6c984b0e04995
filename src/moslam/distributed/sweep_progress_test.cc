#include "moslam/distributed/sweep_progress.h"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>

namespace moslam {
namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();

// Changes shrinking by rho per solve: the bound is gamma * c * rho / (1 - rho) once window + 2
// of them are known, +infinity before.
TEST(SweepProgress, ErrorBoundOfAGeometricSequence) {
  SweepProgress p;
  EXPECT_FALSE(p.initialised());
  EXPECT_EQ(p.lastChange(), kInf);
  const double rho = 0.5;
  double c = 1.0;
  for (int k = 0; k < 4; ++k, c *= rho) {
    p.record(c);
    EXPECT_EQ(p.errorBound(3, 1.0), kInf) << k;
  }
  p.record(c);
  EXPECT_TRUE(p.initialised());
  EXPECT_NEAR(p.errorBound(3, 1.0), c * rho / (1.0 - rho), 1e-15);
  EXPECT_NEAR(p.errorBound(3, 0.5), 0.5 * c * rho / (1.0 - rho), 1e-15);
}

// A solve of part of the unknowns (the others still waiting for a neighbour) reports +infinity:
// the changes before it say nothing about the stage's convergence, so the window starts over and
// the bound needs window + 2 finite changes after it. Without the reset, ratios c_k / inf = 0
// let the bound come out finite from a single real ratio.
TEST(SweepProgress, APartialSolveStartsTheErrorBoundOver) {
  SweepProgress p;
  for (double c : {1.0, 0.5, 0.25, 0.125, 0.0625}) p.record(c);
  ASSERT_LT(p.errorBound(3, 1.0), kInf);
  p.record(kInf);
  EXPECT_EQ(p.lastChange(), kInf);
  EXPECT_EQ(p.errorBound(3, 1.0), kInf);
  p.record(kInf);
  for (double c : {0.9, 0.8, 0.7, 0.6}) {
    p.record(c);
    EXPECT_EQ(p.errorBound(3, 1.0), kInf) << c;
  }
  p.record(0.5);
  const double rho = std::sqrt(0.7 / 0.9);  // the largest two-solve ratio of the last three
  EXPECT_NEAR(p.errorBound(3, 1.0), 0.5 * rho / (1.0 - rho), 1e-12);
}

// Solves that change nothing (no new input) are skipped by the ratios; window + 2 of them in a
// row mean the robot is stationary: bound 0.
TEST(SweepProgress, ZeroChangesAreSkippedAndStationaryIsZero) {
  SweepProgress p;
  for (double c : {1.0, 0.0, 0.5, 0.0, 0.25, 0.125}) p.record(c);
  EXPECT_EQ(p.errorBound(3, 1.0), kInf);  // four non-zero changes: one short
  p.record(0.0625);
  EXPECT_NEAR(p.errorBound(3, 1.0), 0.0625, 1e-15);  // rho = 0.5
  for (int k = 0; k < 4; ++k) p.record(0.0);
  EXPECT_NE(p.errorBound(3, 1.0), 0.0);
  p.record(0.0);
  EXPECT_EQ(p.errorBound(3, 1.0), 0.0);
  p.reset();
  EXPECT_FALSE(p.initialised());
  EXPECT_EQ(p.errorBound(3, 1.0), kInf);
}

}  // namespace
}  // namespace moslam
