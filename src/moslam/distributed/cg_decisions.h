// The team-wide decisions of distributed preconditioned conjugate gradients (dgs_driver.h: the
// refinement's RefineSolver::kConjugateGradient and the pose stage's PoseSolver::
// kConjugateGradient): the step length alpha, the next direction's beta and when to stop, taken
// on the team's sums. The in-process driver's coordinator and every robot of a network team
// (robot_program.h) take them with this one class, so the two decide alike on the same numbers.
//
// With res = -g - H delta, z = M^-1 res (the preconditioner: the robots' sweeps) and p the search
// direction, each robot holding its parts of them (conjugate_gradients.h):
//
//   CgDecisions cg(goal);
//   z = M^-1 res;                     if (!cg.start(sum res.z)) stop: delta = 0 solves it
//   p = z;
//   loop:
//     alpha = cg.stepLength(sum p.Hp, max ||p_r||);   nullopt: stop, no curvature left along p
//     delta += alpha p, res -= alpha H p;  z = M^-1 res;
//     next = cg.next(sum res.z, sweeps so far);       next.stop: stop
//     p = z + next.beta p;
//
// It stops converged when sqrt(res.z / res0.z0) <= goal.tolerance or |alpha| max ||p_r|| (the
// largest change of any robot in the iteration) <= goal.eta_change (a goal of 0 is not used),
// and unconverged when another iteration would pass goal.max_sweeps (an iteration costs two
// sweeps of the preconditioner at most).
//
// It also keeps the decrease of the quadratic model m(delta) = -res0.delta + 1/2 delta.H delta
// (the refinement: H and res0 = -g of the damped Gauss-Newton system) that delta achieves: each
// iteration lowers m by alpha res.z / 2 (p.res = res.z), so the sum over the iterations is
// m(0) - m(delta), from the same team sums, with no other message. The refinement compares it
// with the decrease of F the step achieves (the gain ratio of trust-region methods).
#pragma once

#include <optional>

namespace moslam {

struct CgGoal {
  double tolerance = 0.0;   // on sqrt(res.z / res0.z0); 0: none
  double eta_change = 0.0;  // on the largest change of a robot in one iteration; 0: none
  int max_sweeps = 1000;
};

struct CgOutcome {
  int sweeps = 0;
  bool converged = false;
  double model_decrease = 0.0;  // CgDecisions::modelDecrease() at the end
};

class CgDecisions {
 public:
  explicit CgDecisions(const CgGoal& goal) : goal_(goal) {}

  // After the first preconditioning, on the team's res0.z0: false when it is not positive (the
  // gradient is zero, delta = 0 solves the system: converged).
  bool start(double rz0);
  // alpha = res.z / p.Hp on the team's p.Hp and largest ||p_r||; nullopt when p.Hp is not
  // positive (no curvature left along p, rounding: keep delta; converged).
  std::optional<double> stepLength(double pq, double max_direction);

  struct Next {
    bool stop = false;
    double beta = 0.0;      // p = z + beta p, when not stopping
    double relative = 0.0;  // sqrt(res.z / res0.z0)
  };
  // After preconditioning the new residual, on the team's res.z and the sweeps done so far.
  Next next(double rz, int sweeps);

  bool converged() const { return converged_; }
  // |alpha| max ||p_r|| of the last step length.
  double change() const { return change_; }
  // m(0) - m(delta) for the delta of the step lengths taken so far (see the top); >= 0.
  double modelDecrease() const { return model_decrease_; }

 private:
  CgGoal goal_;
  double rz0_ = 0.0, rz_ = 0.0, change_ = 0.0, model_decrease_ = 0.0;
  bool converged_ = false;
};

}  // namespace moslam
