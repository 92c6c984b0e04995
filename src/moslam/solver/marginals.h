// Marginal covariances of a pose graph's variables at an estimate (its Laplace approximation):
// blocks of the inverse of the Gauss-Newton Hessian H = sum_f J_f^T Omega_f J_f, in the tangent
// order and right perturbations of CONVENTIONS.md (x Exp(dx), dx ~ N(0, Sigma)). The gauge is the
// optimizer's: the anchor (GaugeAnchor) is held fixed, so its blocks are zero and every other
// covariance is relative to it; covariances of relative quantities (x_i^-1 x_j) do not depend on
// that choice. As GTSAM's Marginals::jointMarginalCovariance.
//
//   Marginals m(graph, estimate);                 // one sparse Cholesky factorization
//   Eigen::MatrixXd S = m.jointCovariance({a, b});  // 12 x 12: [S_aa S_ab; S_ba S_bb]
#pragma once

#include <Eigen/Core>
#include <memory>
#include <vector>

#include "moslam/graph/pose_graph.h"

namespace moslam {

class Marginals {
 public:
  // Throws InvalidInputError (a variable without an estimate), UnderdeterminedError (a part of
  // the graph nothing anchors) or NumericalError (H not positive definite at this estimate).
  Marginals(const PoseGraph& graph, const Values& values);
  ~Marginals();
  Marginals(const Marginals&) = delete;
  Marginals& operator=(const Marginals&) = delete;

  // The 6k x 6k joint covariance of `keys` (in that order; repeats allowed). One back-solve per
  // column: cost grows with 6k, not with the graph's size squared. Throws InvalidInputError for
  // a key not in the graph.
  Eigen::MatrixXd jointCovariance(const std::vector<Key>& keys) const;
  Matrix6 covariance(const Key& key) const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace moslam
