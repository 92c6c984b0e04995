// A robot's block of one linear least-squares stage of the distributed solver (robot_agent.h):
// the stage's terms (two_stage_terms.h) of its inner factors, priors and usable separators, the
// normal equations of its unknowns with the neighbour variables at zero (H_rr, factorized, and
// the constant right-hand side G0), and per separator the coupling block H_rs = A_own^T W
// A_foreign, through which the neighbour values enter the right-hand side:
//   H_rr x_r = G0 - sum_s H_rs x_s.
// Shared by the rotation stage (3x3 blocks, 3 columns), the pose stage and the refinement (6x6
// blocks, one column). The factorization is kept while the separators used and the damping stay
// the same.
#pragma once

#include <Eigen/Core>
#include <memory>
#include <vector>

#include "moslam/distributed/local_graph.h"
#include "moslam/distributed/two_stage_terms.h"

namespace moslam {

class LocalSystem {
 public:
  // `graph` must outlive the system.
  LocalSystem(const LocalGraph& graph, int block_size, int num_cols);
  ~LocalSystem();
  LocalSystem(const LocalSystem&) = delete;
  LocalSystem& operator=(const LocalSystem&) = delete;

  // The terms of a stage: one per factor of the graph (a separator whose term is not built, e.g.
  // its neighbour's rotation is unknown in stage 2, marked false in `built`: it stays unused), one
  // per prior, and the anchor's value in the stage's unknowns (when the robot owns it). Builds the
  // coupling blocks; forgets the factorization.
  void setTerms(std::vector<LinearTerm> factor_terms, std::vector<bool> built,
                std::vector<LinearTerm> prior_terms, Eigen::MatrixXd anchor_value);
  // From the next assembly on, H_rr gets + lambda diag(H_rr) (Levenberg-Marquardt), with the
  // diagonal given per unknown (6 numbers each); lambda = 0: none. Forgets the factorization when
  // lambda changes.
  void setDamping(double lambda, std::vector<Eigen::VectorXd> diagonal);

  bool built(std::size_t factor) const { return built_[factor]; }
  const LinearTerm& term(std::size_t factor) const { return terms_[factor]; }
  const Eigen::MatrixXd& coupling(std::size_t separator) const { return coupling_[separator]; }

  // Assembles and factorizes the normal equations with the separators s with use[s] (unless the
  // factorization for exactly these is kept). `held` (empty, or one flag per unknown): unknowns
  // not solved now, groups no term ties down yet (flagged initialisation); each gets an identity
  // block so that H_rr stays positive definite, and its solution means nothing. Inner factors
  // never join a held unknown to a solved one, so the solved ones are exact. Throws NumericalError
  // when H_rr is not positive definite.
  void assemble(const std::vector<bool>& use, const std::vector<bool>& held = {});
  bool factorized() const { return factorized_; }
  // The separators of the factorization (empty before the first).
  const std::vector<bool>& use() const { return use_; }
  // Row of the own end of separator s in the stacked unknowns; -1 when not used.
  Eigen::Index separatorRow(std::size_t separator) const { return separator_row_[separator]; }
  const Eigen::MatrixXd& constantRhs() const { return G0_; }  // n*bs x ncols

  std::vector<Eigen::MatrixXd> solve(const Eigen::MatrixXd& rhs) const;
  Eigen::VectorXd multiply(const Eigen::VectorXd& x) const;  // H_rr x (one column)
  Eigen::Index row(const Key& unknown) const;

 private:
  const LocalGraph& graph_;
  std::unique_ptr<BlockLeastSquares> problem_;
  int block_size_, num_cols_;
  std::vector<LinearTerm> terms_, prior_terms_;
  std::vector<bool> built_;
  std::vector<Eigen::MatrixXd> coupling_;  // per separator
  Eigen::MatrixXd anchor_value_;
  double lambda_ = 0.0;
  std::vector<Eigen::VectorXd> damping_diagonal_;
  std::vector<bool> use_, held_;
  bool factorized_ = false;
  Eigen::MatrixXd G0_;
  std::vector<Eigen::Index> separator_row_;
};

}  // namespace moslam
