#include "moslam/distributed/sweep_progress.h"

#include <algorithm>
#include <cmath>
#include <cstddef>

namespace moslam {

void SweepProgress::reset() {
  solves_ = 0;
  last_change_ = std::numeric_limits<double>::infinity();
  recent_changes_.clear();
  zero_changes_ = 0;
}

void SweepProgress::record(double change) {
  last_change_ = change;
  if (std::isinf(change)) {
    recent_changes_.clear();
    zero_changes_ = 0;
  } else if (change == 0.0) {
    ++zero_changes_;
  } else {
    zero_changes_ = 0;
    if (recent_changes_.size() == static_cast<std::size_t>(kMaxWindow) + 2) {
      recent_changes_.erase(recent_changes_.begin());
    }
    recent_changes_.push_back(change);
  }
  ++solves_;
}

double SweepProgress::errorBound(int window, double gamma) const {
  constexpr double kInf = std::numeric_limits<double>::infinity();
  // Stationary: the last window + 2 solves changed nothing.
  if (zero_changes_ >= window + 2) return 0.0;
  const std::size_t n = recent_changes_.size();
  if (n < static_cast<std::size_t>(window) + 2) return kInf;
  // Two-solve ratios: Jacobi sweeps alternate between modes of eigenvalues +mu and -mu, so the
  // change oscillates from solve to solve while c_k / c_{k-2} = mu^2 (Gauss-Seidel is monotone).
  double rho = 0.0;
  for (std::size_t k = n - static_cast<std::size_t>(window); k < n; ++k) {
    rho = std::max(rho, std::sqrt(recent_changes_[k] / recent_changes_[k - 2]));
  }
  if (!(rho < 1.0)) return kInf;
  return gamma * recent_changes_.back() * rho / (1.0 - rho);
}

}  // namespace moslam
