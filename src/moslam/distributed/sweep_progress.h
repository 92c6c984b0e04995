// How far a robot's sweeps of the current stage (or refinement step) have come: its solves, the
// change of its last one, and the recent non-zero changes the a-posteriori error bound of
// StageStopping::kErrorBound (dgs_types.h) is estimated from.
#pragma once

#include <limits>
#include <vector>

namespace moslam {

class SweepProgress {
 public:
  static constexpr int kMaxWindow = 64;  // errorBound(): the longest window of change ratios

  // A new stage or step: not solved, nothing measured.
  void reset();
  // A solve that changed the robot's stacked unknowns by `change` (2-norm). +infinity: a solve
  // of part of them, the others still waiting (robot_agent.h); the error bound then starts over.
  void record(double change);

  int solves() const { return solves_; }
  bool initialised() const { return solves_ > 0; }
  // +infinity before the first solve.
  double lastChange() const { return last_change_; }
  // gamma * c * rho / (1 - rho) over the non-zero changes c (a solve that changes nothing had no
  // new input and is skipped), c the last of them, rho the largest sqrt(c_k / c_{k-2}) over the
  // last `window` of them (two-solve ratios: Jacobi changes oscillate); +infinity with fewer than
  // window + 2 of them or a ratio >= 1; 0 when the last window + 2 solves changed nothing.
  // `window` must be in [1, kMaxWindow] (the caller checks).
  double errorBound(int window, double gamma) const;

 private:
  int solves_ = 0;
  double last_change_ = std::numeric_limits<double>::infinity();
  std::vector<double> recent_changes_;  // the last non-zero changes, oldest first (<= 66)
  int zero_changes_ = 0;                // solves since the last non-zero change
};

}  // namespace moslam
