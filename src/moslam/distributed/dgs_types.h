// Shared vocabulary of the distributed Gauss-Seidel (DGS) solver (shared/DGS.md).
//
// A solve runs in stages; in each stage every robot estimates a fixed number of numbers per
// variable it owns and exchanges the estimates of its separator variables:
//   kRotation: the chordal relaxation, 9 numbers per variable (the rotation matrix row by row);
//   kPose:     the single Gauss-Newton pose step, 6 numbers (dtheta, dt), tangent order (w, v);
//   kRefine:   distributed Gauss-Newton refinement on the SE(3) cost (beyond DGS.md), 6 numbers
//              per variable: the robot's current increment delta of one Gauss-Newton step
//              (x <- x Exp(delta)), tangent order (w, v).
#pragma once

#include <cstdint>
#include <string>

namespace moslam {

enum class DgsStage : std::uint8_t { kRotation = 1, kPose = 2, kRefine = 3 };

// Numbers per variable that a message of `stage` carries (9, 6, 6).
int StageDimension(DgsStage stage);
std::string ToString(DgsStage stage);

// The explicit state of a robot agent. kIdle: constructed, no stage started. kRotation / kPose /
// kRefine: iterating that stage. kDone: the pose stage (or the refinement after it) was finished;
// estimate() is final.
enum class AgentState { kIdle, kRotation, kPose, kRefine, kDone };
std::string ToString(AgentState state);

// How the robots of one sweep see each other's updates.
enum class SweepOrder {
  kGaussSeidel,  // a robot's update is delivered before the next robot solves
  kJacobi,       // every update is delivered at the end of the sweep (parallel)
};
std::string ToString(SweepOrder order);

// When a stage (1 or 2) stops: after the first sweep in which every live robot has solved and its
// stopping measure is at most eta.
//   kChange      the measure is the robot's change ||x_new - x_old||_2 (shared/DGS.md, the
//                paper). The sweeps contract linearly, so this stops about eta * rho / (1 - rho)
//                from the fixed point (rho the per-sweep contraction: up to 0.9996 on
//                blocks_world, where eta = 1e-6 leaves 6.8e-4 m).
//   kErrorBound  the measure is the a-posteriori bound of a contraction with rate rho,
//                ||x_k - x*|| <= rho / (1 - rho) ||x_k - x_{k-1}||, with the robot's own step
//                ||x_k - x_{k-1}|| = gamma * change and rho estimated by the robot as the largest
//                sqrt(c_k / c_{k-2}) of its changes c over its last `window` solves (two-solve
//                ratios: Jacobi changes oscillate; +infinity until it has window + 2 solves in the
//                stage, or while a ratio is >= 1). Asymptotically every
//                robot's ratio tends to the spectral radius of the sweep, so this stops about eta
//                from the fixed point. Beyond DGS.md; needs nothing more on the network (each robot
//                still reports one number).
enum class StageStopping { kChange, kErrorBound };
std::string ToString(StageStopping stopping);
// "change" | "error-bound"; throws InvalidInputError otherwise.
StageStopping StageStoppingFromString(const std::string& text);

// The rule above over one sweep's live robots: each adds whether it has solved in the stage, its
// change and its error bound (+infinity before it solved). The in-process driver and every robot
// of a network team (robot_program.h) stop a stage with it.
class StageStopRule {
 public:
  StageStopRule(StageStopping stopping, double eta) : stopping_(stopping), eta_(eta) {}
  void add(bool initialised, double change, double bound);
  // Every robot added has solved and its measure is at most eta; false when none was added.
  bool converged() const { return robots_ > 0 && converged_; }
  double maxChange() const { return max_change_; }
  double maxBound() const { return max_bound_; }
  int robots() const { return robots_; }
  int initialisedRobots() const { return initialised_; }  // those that have solved in the stage

 private:
  StageStopping stopping_;
  double eta_;
  int robots_ = 0, initialised_ = 0;
  bool converged_ = true;
  double max_change_ = 0.0, max_bound_ = 0.0;
};

// The pose stage by conjugate gradients with flagged initialisation (dgs_driver.h) sweeps until
// this is true after a sweep, then starts the conjugate gradients: every robot of `rule` has
// solved, or the sweep initialised none beyond the `initialised_before` of the sweep before (the
// others are not linked to the anchor). The driver and the robot programs decide with it.
bool FlaggedSweepsDone(const StageStopRule& rule, int initialised_before);

}  // namespace moslam
