#include "moslam/distributed/cg_decisions.h"

#include <algorithm>
#include <cmath>

namespace moslam {

bool CgDecisions::start(double rz0) {
  rz0_ = rz_ = rz0;
  converged_ = !(rz0 > 0.0);
  return !converged_;
}

std::optional<double> CgDecisions::stepLength(double pq, double max_direction) {
  if (!(pq > 0.0)) {
    converged_ = true;
    return std::nullopt;
  }
  const double alpha = rz_ / pq;
  change_ = std::abs(alpha) * max_direction;
  model_decrease_ += 0.5 * alpha * rz_;
  return alpha;
}

CgDecisions::Next CgDecisions::next(double rz, int sweeps) {
  Next n;
  n.relative = std::sqrt(std::max(rz, 0.0) / rz0_);
  converged_ = (goal_.tolerance > 0.0 && n.relative <= goal_.tolerance) ||
               (goal_.eta_change > 0.0 && change_ <= goal_.eta_change);
  n.stop = converged_ || sweeps + 2 > goal_.max_sweeps;
  n.beta = rz / rz_;
  rz_ = rz;
  return n;
}

}  // namespace moslam
