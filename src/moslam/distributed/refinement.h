// The robot's side of the distributed refinement (beyond DGS.md; robot_agent.h): Gauss-Newton on
// the SE(3) cost F = sum 1/2 r^T Omega r (graph/factors.h) from the two-stage estimate. It holds
// the robot's estimate x (the anchor included) and its copies of the neighbours' poses, builds the
// linear terms of a Gauss-Newton step at x (A = dr/dx, C = r, W = Omega) into the robot's
// LocalSystem, applies accepted steps x <- x Exp(delta) to its own variables and to the copies
// (the same operation on the same numbers as their owners, so poses are never re-sent), and
// computes its share of F. Separators to a neighbour whose pose never arrived are left out.
#pragma once

#include <Eigen/Core>
#include <functional>
#include <map>
#include <set>
#include <vector>

#include "moslam/distributed/local_graph.h"
#include "moslam/distributed/local_system.h"

namespace moslam {

class Refinement {
 public:
  // `graph` must outlive it.
  explicit Refinement(const LocalGraph& graph) : graph_(graph) {}

  // Starts at `own` (every own variable, the anchor included) with the neighbours' poses in
  // `neighbours` (by slot; null: never received).
  void start(Values own, const std::vector<const SE3*>& neighbours);
  bool started() const { return started_; }

  const Values& estimate() const { return pose_; }
  // Own or a neighbour's copy; nullptr if unknown.
  const SE3* knownPose(const Key& key) const;
  bool knows(int slot) const { return known_[static_cast<std::size_t>(slot)] != 0; }

  // The Gauss-Newton terms at the current estimate into `system` (the factorization forgotten),
  // and the diagonal of each unknown's block of H (for damping()).
  void linearize(LocalSystem& system);
  const std::vector<Eigen::VectorXd>& hessianDiagonal() const { return hessian_diagonal_; }

  // x <- x Exp(delta) for the own unknowns and the known neighbour copies.
  void accept(const std::function<Vector6(std::size_t unknown)>& own_increment,
              const std::function<Vector6(int slot)>& neighbour_increment);

  // This robot's share of F (every inner factor and prior; each separator counted once, by the
  // robot with the lower id, or by this one when the other is unresponsive) at the estimate
  // moved by the increments (null functions: at the estimate).
  double costShare(const std::function<Vector6(std::size_t unknown)>& own_increment,
                   const std::function<Vector6(int slot)>& neighbour_increment) const;
  // From now on this robot counts its separators to `robot` in costShare().
  void setUnresponsive(int robot) { unresponsive_.insert(robot); }

 private:
  const LocalGraph& graph_;
  bool started_ = false;
  Values pose_;
  std::vector<SE3> neighbour_pose_;  // by slot
  std::vector<char> known_;
  std::vector<Eigen::VectorXd> hessian_diagonal_;
  std::set<int> unresponsive_;
};

}  // namespace moslam
