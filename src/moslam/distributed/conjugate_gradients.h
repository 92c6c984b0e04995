// The robot's side of conjugate gradients on a refinement step's system H delta = -g
// (dgs_driver.h, RefineSolver::kConjugateGradient), preconditioned by the robot-by-robot sweeps:
// the robot keeps its parts of the increment delta, the residual res = -g - H delta, the search
// direction p and q = (H p)_r, and its copies of the neighbours' p and delta, rebuilt from the z
// they sent and the broadcast coefficients (no extra message). Vectors are stacked over the
// robot's unknowns, 6 numbers each.
#pragma once

#include <Eigen/Core>
#include <vector>

#include "moslam/distributed/local_graph.h"
#include "moslam/distributed/local_system.h"

namespace moslam {

class ConjugateGradients {
 public:
  // A new linear solve: delta = 0, res = `residual` (-g; zero when the robot cannot solve), p and
  // the copies 0.
  void start(const Eigen::VectorXd& residual, std::size_t neighbour_slots);

  const Eigen::VectorXd& residual() const { return res_; }
  const Eigen::VectorXd& direction() const { return p_; }
  const Eigen::VectorXd& increment() const { return delta_; }
  Vector6 increment(std::size_t unknown) const {
    return delta_.segment<6>(static_cast<Eigen::Index>(6 * unknown));
  }
  Vector6 neighbourIncrement(int slot) const {
    return neighbour_delta_[static_cast<std::size_t>(slot)];
  }

  // p = z + beta p; the neighbours' p likewise from their z (nullptr: not received, 0).
  void nextDirection(double beta, const Eigen::VectorXd& z,
                     const std::vector<const Eigen::VectorXd*>& neighbour_z);
  // p_r . (H p)_r with (H p)_r = H_rr p_r + sum_s H_rs p_s over the separators `system` uses.
  double curvature(const LocalGraph& graph, const LocalSystem& system);
  // delta += alpha p, res -= alpha H p, the neighbours' delta copies += alpha p.
  void advance(double alpha);
  void clearCurvature() { q_.setZero(); }

 private:
  Eigen::VectorXd delta_, res_, p_, q_;
  std::vector<Vector6> neighbour_p_, neighbour_delta_;  // by slot
};

}  // namespace moslam
