#include "moslam/distributed/conjugate_gradients.h"

namespace moslam {

void ConjugateGradients::start(const Eigen::VectorXd& residual, std::size_t neighbour_slots) {
  const Eigen::Index n = residual.size();
  delta_ = Eigen::VectorXd::Zero(n);
  res_ = residual;
  p_ = Eigen::VectorXd::Zero(n);
  q_ = Eigen::VectorXd::Zero(n);
  neighbour_p_.assign(neighbour_slots, Vector6::Zero());
  neighbour_delta_.assign(neighbour_slots, Vector6::Zero());
}

void ConjugateGradients::nextDirection(double beta, const Eigen::VectorXd& z,
                                       const std::vector<const Eigen::VectorXd*>& neighbour_z) {
  p_ = z + beta * p_;
  for (std::size_t i = 0; i < neighbour_p_.size(); ++i) {
    neighbour_p_[i] = beta * neighbour_p_[i];
    if (neighbour_z[i]) neighbour_p_[i] += neighbour_z[i]->head<6>();
  }
}

double ConjugateGradients::curvature(const LocalGraph& graph, const LocalSystem& system) {
  q_ = system.multiply(p_);
  const auto& separators = graph.separators();
  for (std::size_t s = 0; s < separators.size(); ++s) {
    const Eigen::Index row = system.separatorRow(s);
    if (row < 0) continue;
    q_.segment<6>(row).noalias() +=
        Matrix6(system.coupling(s)) * neighbour_p_[static_cast<std::size_t>(separators[s].slot)];
  }
  return p_.dot(q_);
}

void ConjugateGradients::advance(double alpha) {
  delta_ += alpha * p_;
  res_ -= alpha * q_;
  for (std::size_t i = 0; i < neighbour_p_.size(); ++i) {
    neighbour_delta_[i] += alpha * neighbour_p_[i];
  }
}

}  // namespace moslam
