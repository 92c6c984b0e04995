#include "moslam/distributed/refinement.h"

#include <utility>

namespace moslam {

void Refinement::start(Values own, const std::vector<const SE3*>& neighbours) {
  pose_ = std::move(own);
  neighbour_pose_.assign(neighbours.size(), SE3());
  known_.assign(neighbours.size(), 0);
  for (std::size_t i = 0; i < neighbours.size(); ++i) {
    if (!neighbours[i]) continue;
    neighbour_pose_[i] = *neighbours[i];
    known_[i] = 1;
  }
  started_ = true;
}

const SE3* Refinement::knownPose(const Key& key) const {
  const auto own = pose_.find(key);
  if (own != pose_.end()) return &own->second;
  const int slot = graph_.slot(key);
  if (slot < 0) return nullptr;
  const auto i = static_cast<std::size_t>(slot);
  return known_[i] ? &neighbour_pose_[i] : nullptr;
}

void Refinement::linearize(LocalSystem& system) {
  const auto& factors = graph_.factors();
  std::vector<LinearTerm> terms(factors.size());
  std::vector<bool> built(factors.size(), false);
  hessian_diagonal_.assign(graph_.unknowns().size(), Eigen::VectorXd::Zero(6));
  auto accumulateDiagonal = [&](const Key& k, const Eigen::MatrixXd& A, const Eigen::MatrixXd& W) {
    const int i = graph_.unknownIndex(k);
    if (i >= 0) hessian_diagonal_[static_cast<std::size_t>(i)] += (A.transpose() * W * A).diagonal();
  };
  auto build = [&](std::size_t i) {
    const RelativePoseFactor& f = factors[i];
    Matrix6 Ha, Hb;
    const Vector6 r = f.residual(*knownPose(f.a()), *knownPose(f.b()), &Ha, &Hb);
    LinearTerm& t = terms[i];
    t.a = f.a();
    t.b = f.b();
    t.A_a = Ha;
    t.A_b = Hb;
    t.C = r;
    t.W = f.information();
    built[i] = true;
    accumulateDiagonal(f.a(), t.A_a, t.W);
    if (f.b() != f.a()) accumulateDiagonal(f.b(), t.A_b, t.W);
  };
  for (std::size_t i : graph_.inner()) build(i);
  for (const Separator& sep : graph_.separators()) {
    if (knows(sep.slot)) build(sep.factor);  // never received: left out
  }
  std::vector<LinearTerm> prior_terms;
  for (const PriorFactor& p : graph_.priors()) {
    Matrix6 H;
    const Vector6 r = p.residual(pose_.at(p.key()), &H);
    LinearTerm t;
    t.a = p.key();
    t.unary = true;
    t.A_a = H;
    t.C = r;
    t.W = p.information();
    accumulateDiagonal(p.key(), t.A_a, t.W);
    prior_terms.push_back(std::move(t));
  }
  system.setTerms(std::move(terms), std::move(built), std::move(prior_terms),
                  Eigen::VectorXd::Zero(6));  // the anchor's increment
}

void Refinement::accept(const std::function<Vector6(std::size_t)>& own_increment,
                        const std::function<Vector6(int)>& neighbour_increment) {
  const auto& unknowns = graph_.unknowns();
  for (std::size_t i = 0; i < unknowns.size(); ++i) {
    SE3& x = pose_.at(unknowns[i]);
    x = x * SE3::Exp(own_increment(i));
  }
  for (std::size_t i = 0; i < neighbour_pose_.size(); ++i) {
    if (!known_[i]) continue;
    neighbour_pose_[i] = neighbour_pose_[i] * SE3::Exp(neighbour_increment(static_cast<int>(i)));
  }
}

double Refinement::costShare(const std::function<Vector6(std::size_t)>& own_increment,
                             const std::function<Vector6(int)>& neighbour_increment) const {
  const bool candidate = static_cast<bool>(own_increment);
  auto value = [&](const Key& k) {
    const SE3& x = *knownPose(k);
    if (!candidate) return x;
    const int own = graph_.unknownIndex(k);
    if (own >= 0) return SE3(x * SE3::Exp(own_increment(static_cast<std::size_t>(own))));
    const int slot = graph_.slot(k);
    if (slot >= 0) return SE3(x * SE3::Exp(neighbour_increment(slot)));
    return x;  // the anchor
  };
  const auto& factors = graph_.factors();
  double cost = 0.0;
  for (std::size_t i : graph_.inner()) cost += factors[i].cost(value(factors[i].a()), value(factors[i].b()));
  const int robot = graph_.robot();
  for (const Separator& s : graph_.separators()) {
    if (!knows(s.slot)) continue;
    if (s.foreign_robot < robot && unresponsive_.count(s.foreign_robot) == 0) continue;
    const RelativePoseFactor& f = factors[s.factor];
    cost += f.cost(value(f.a()), value(f.b()));
  }
  for (const PriorFactor& p : graph_.priors()) cost += p.cost(value(p.key()));
  return cost;
}

}  // namespace moslam
