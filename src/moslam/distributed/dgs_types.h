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

}  // namespace moslam
