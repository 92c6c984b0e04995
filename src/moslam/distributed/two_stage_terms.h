// The linear least-squares terms of the two-stage relaxation (shared/DGS.md), shared by the robot
// agents and the centralized two-stage solve so that both minimise exactly the same function.
//
// Every term couples one or two variables a, b through a linear residual
//     E = A_a X_a + A_b X_b + C        (m x ncols),   cost  tr(E^T W E),
// with the unknowns X_v of block size bs and ncols columns:
//
// Stage 1 (chordal relaxation), bs = 3, ncols = 3: X_v = R_v^T, an unconstrained 3x3 matrix whose
//   column k is row k of R_v (so the row-by-row 9-vector r_v is X_v flattened column-major, and
//   the three rows share one matrix). Edge (a, b, R_ab): E = R_ab^T X_a - X_b, i.e. the transpose
//   of R_a R_ab - R_b. Prior (x, R_z): E = X_x - R_z^T.
// Stage 2 (one Gauss-Newton pose step), bs = 6, ncols = 1: X_v = delta_v = (dtheta_v, t_v),
//   the pose being R = R_hat_v Exp(dtheta_v), t = t_v (t = dt: linearised at t = 0). Edge
//   (a, b, R_ab, t_ab): the 12-D residual [vec(R_a R_ab - R_b); t_b - t_a - R_a t_ab] (vec row by
//   row) linearised at (R_hat, 0); prior (x, z): [vec(R_x - R_z); t_x - t_z].
//
// Weights: unit (the DGS reference) or, with weight_by_information, trace(Omega_rot)/3 on the
// rotation rows and R_hat_a Omega_trans R_hat_a^T on the translation rows (Omega_trans is
// expressed in the frame of the edge's first pose).
#pragma once

#include <Eigen/Core>
#include <map>
#include <memory>
#include <utility>
#include <vector>

#include "moslam/graph/pose_graph.h"

namespace moslam {

struct LinearTerm {
  Key a, b;              // b is unused when unary
  bool unary = false;
  Eigen::MatrixXd A_a, A_b;  // m x bs
  Eigen::MatrixXd C;         // m x ncols
  Eigen::MatrixXd W;         // m x m, symmetric positive semi-definite
};

LinearTerm RotationTerm(const RelativePoseFactor& factor, bool weight_by_information);
LinearTerm RotationPriorTerm(const PriorFactor& prior, bool weight_by_information);
LinearTerm PoseTerm(const RelativePoseFactor& factor, const Matrix3& R_hat_a,
                    const Matrix3& R_hat_b, bool weight_by_information);
LinearTerm PosePriorTerm(const PriorFactor& prior, const Matrix3& R_hat,
                         bool weight_by_information);

// The stage-1 unknown of a rotation (X = R^T) and the 9-vector (row by row) it flattens to.
inline Eigen::Matrix3d RotationUnknown(const Matrix3& R) { return R.transpose(); }
Eigen::VectorXd RowMajor(const Matrix3& M);
Matrix3 FromRowMajor(const Eigen::VectorXd& r);
// The nearest rotation to a relaxed 9-vector: R = U diag(1, 1, det(U V^T)) V^T (DGS.md).
Matrix3 ProjectToRotation(const Eigen::VectorXd& r);

// Minimises the sum of terms over a fixed set of unknown variables; terms may also reference
// fixed variables, whose values are passed to add(). The sparsity pattern (pairs of unknowns
// some term couples) is given once; every solve refactorizes (CHOLMOD via BlockSparseSystem).
class BlockLeastSquares {
 public:
  BlockLeastSquares(const std::vector<Key>& unknowns, int block_size, int num_cols,
                    const std::vector<std::pair<Key, Key>>& coupled);
  ~BlockLeastSquares();
  BlockLeastSquares(const BlockLeastSquares&) = delete;
  BlockLeastSquares& operator=(const BlockLeastSquares&) = delete;

  bool isUnknown(const Key& key) const { return index_.count(key) > 0; }
  const std::vector<Key>& unknowns() const { return unknowns_; }

  void setZero();
  // Adds the normal equations of `term`. For an end that is not an unknown, its value
  // (bs x ncols) must be given (x_a / x_b), else InvalidInputError; for an unknown end the
  // pointer is ignored. Throws std::out_of_range when two unknowns are coupled outside the
  // pattern.
  void add(const LinearTerm& term, const Eigen::MatrixXd* x_a, const Eigen::MatrixXd* x_b);
  // The minimiser, block by block in the order of unknowns(). Throws NumericalError when the
  // normal matrix is not positive definite (some unknown is not anchored by any term).
  std::vector<Eigen::MatrixXd> solve();

  // The same in two steps, to reuse one factorization for several right-hand sides:
  // factorize() the assembled normal matrix, then backSolve(G) for G of the shape of rhs().
  const Eigen::MatrixXd& rhs() const;  // the assembled right-hand side, n*bs x ncols
  void factorize();
  std::vector<Eigen::MatrixXd> backSolve(const Eigen::MatrixXd& G) const;
  // H x for the assembled normal matrix H and a stacked x (one column, n*bs rows).
  Eigen::VectorXd multiply(const Eigen::VectorXd& x) const;
  // Row of the first entry of `key`'s block in rhs() (InvalidInputError if not an unknown).
  Eigen::Index row(const Key& key) const;

 private:
  struct Impl;
  std::vector<Key> unknowns_;
  std::map<Key, int> index_;
  int bs_, ncols_;
  std::unique_ptr<Impl> impl_;
};

}  // namespace moslam
