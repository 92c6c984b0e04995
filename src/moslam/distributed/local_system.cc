#include "moslam/distributed/local_system.h"

#include <utility>

namespace moslam {
namespace {

std::vector<std::pair<Key, Key>> InnerPairs(const LocalGraph& graph) {
  std::vector<std::pair<Key, Key>> pairs;
  for (std::size_t i : graph.inner()) {
    pairs.emplace_back(graph.factors()[i].a(), graph.factors()[i].b());
  }
  return pairs;
}

}  // namespace

LocalSystem::LocalSystem(const LocalGraph& graph, int block_size, int num_cols)
    : graph_(graph),
      problem_(std::make_unique<BlockLeastSquares>(graph.unknowns(), block_size, num_cols,
                                                   InnerPairs(graph))),
      block_size_(block_size),
      num_cols_(num_cols),
      separator_row_(graph.separators().size(), -1) {}

LocalSystem::~LocalSystem() = default;

void LocalSystem::setTerms(std::vector<LinearTerm> factor_terms, std::vector<bool> built,
                           std::vector<LinearTerm> prior_terms, Eigen::MatrixXd anchor_value) {
  terms_ = std::move(factor_terms);
  built_ = std::move(built);
  prior_terms_ = std::move(prior_terms);
  anchor_value_ = std::move(anchor_value);
  const auto& separators = graph_.separators();
  coupling_.assign(separators.size(), Eigen::MatrixXd());
  for (std::size_t s = 0; s < separators.size(); ++s) {
    const Separator& sep = separators[s];
    if (!built_[sep.factor]) continue;
    const LinearTerm& t = terms_[sep.factor];
    const bool own_is_a = graph_.factors()[sep.factor].a() == sep.own;
    const Eigen::MatrixXd& A_own = own_is_a ? t.A_a : t.A_b;
    const Eigen::MatrixXd& A_foreign = own_is_a ? t.A_b : t.A_a;
    coupling_[s] = A_own.transpose() * t.W * A_foreign;
  }
  use_.clear();
  factorized_ = false;
}

void LocalSystem::setDamping(double lambda, std::vector<Eigen::VectorXd> diagonal) {
  if (lambda != lambda_) factorized_ = false;
  lambda_ = lambda;
  damping_diagonal_ = std::move(diagonal);
}

void LocalSystem::assemble(const std::vector<bool>& use, const std::vector<bool>& held) {
  if (factorized_ && use == use_ && held == held_) return;
  const Key& anchor = graph_.anchor();
  const Eigen::MatrixXd* anchor_value = graph_.ownsAnchor() ? &anchor_value_ : nullptr;
  auto fixedValue = [&](const Key& k) -> const Eigen::MatrixXd* {
    return k == anchor ? anchor_value : nullptr;
  };
  // Normal matrix and the constant part of the right-hand side (neighbours at zero).
  problem_->setZero();
  const auto& factors = graph_.factors();
  for (std::size_t i : graph_.inner()) {
    const RelativePoseFactor& f = factors[i];
    if (f.a() == anchor && f.b() == anchor) continue;
    problem_->add(terms_[i], fixedValue(f.a()), fixedValue(f.b()));
  }
  const Eigen::MatrixXd zero = Eigen::MatrixXd::Zero(block_size_, num_cols_);
  const auto& separators = graph_.separators();
  for (std::size_t s = 0; s < separators.size(); ++s) {
    if (!use[s] || graph_.unknownIndex(separators[s].own) < 0) continue;
    const bool foreign_is_a = factors[separators[s].factor].a() == separators[s].foreign;
    problem_->add(terms_[separators[s].factor], foreign_is_a ? &zero : nullptr,
                  foreign_is_a ? nullptr : &zero);
  }
  for (std::size_t p = 0; p < graph_.priors().size(); ++p) {
    if (graph_.priors()[p].key() == anchor) continue;
    problem_->add(prior_terms_[p], nullptr, nullptr);
  }
  if (lambda_ > 0.0) {
    // Levenberg-Marquardt damping of the robot's own diagonal blocks: + lambda diag(H_rr).
    LinearTerm damping;
    damping.unary = true;
    damping.C = Eigen::VectorXd::Zero(6);
    damping.W = Eigen::MatrixXd::Identity(6, 6);
    const auto& unknowns = graph_.unknowns();
    for (std::size_t i = 0; i < unknowns.size(); ++i) {
      damping.a = unknowns[i];
      damping.A_a = (lambda_ * damping_diagonal_[i]).cwiseSqrt().asDiagonal();
      problem_->add(damping, nullptr, nullptr);
    }
  }
  if (!held.empty()) {
    LinearTerm hold;
    hold.unary = true;
    hold.A_a = Eigen::MatrixXd::Identity(block_size_, block_size_);
    hold.C = Eigen::MatrixXd::Zero(block_size_, num_cols_);
    hold.W = Eigen::MatrixXd::Identity(block_size_, block_size_);
    const auto& unknowns = graph_.unknowns();
    for (std::size_t i = 0; i < unknowns.size(); ++i) {
      if (!held[i]) continue;
      hold.a = unknowns[i];
      problem_->add(hold, nullptr, nullptr);
    }
  }
  problem_->factorize();
  G0_ = problem_->rhs();
  use_ = use;
  held_ = held;
  factorized_ = true;
  separator_row_.assign(separators.size(), -1);
  for (std::size_t s = 0; s < separators.size(); ++s) {
    if (use[s] && graph_.unknownIndex(separators[s].own) >= 0) {
      separator_row_[s] = problem_->row(separators[s].own);
    }
  }
}

std::vector<Eigen::MatrixXd> LocalSystem::solve(const Eigen::MatrixXd& rhs) const {
  return problem_->backSolve(rhs);
}

Eigen::VectorXd LocalSystem::multiply(const Eigen::VectorXd& x) const {
  return problem_->multiply(x);
}

Eigen::Index LocalSystem::row(const Key& unknown) const { return problem_->row(unknown); }

}  // namespace moslam
