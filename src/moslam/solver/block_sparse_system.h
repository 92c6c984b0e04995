// A symmetric positive-definite block-sparse linear system H x = b with a fixed pattern,
// assembled in place and solved by CHOLMOD's supernodal Cholesky (through Eigen's CholmodSupport).
// The symbolic analysis (fill-reducing ordering) is done once; every solve() refactorizes
// numerically. Used by the centralized solver (6x6 blocks), the chordal relaxation (3x3 blocks)
// and the distributed solver's per-robot systems.
#pragma once

#include <Eigen/Core>
#include <memory>
#include <utility>
#include <vector>

namespace moslam {

class BlockSparseSystem {
 public:
  // Handle to one stored block, from slot(i, j); remembers whether (i, j) is the stored block or
  // its transpose, so add() can be called with the block as the caller sees it.
  struct Slot {
    int index = 0;
    bool transposed = false;
  };

  // `pairs` lists the off-diagonal blocks (i, j), i != j, in any order, duplicates allowed;
  // every diagonal block exists.
  BlockSparseSystem(int num_blocks, int block_size, const std::vector<std::pair<int, int>>& pairs);
  ~BlockSparseSystem();
  BlockSparseSystem(const BlockSparseSystem&) = delete;
  BlockSparseSystem& operator=(const BlockSparseSystem&) = delete;

  int numBlocks() const { return num_blocks_; }
  int blockSize() const { return block_size_; }
  int dim() const { return num_blocks_ * block_size_; }

  // The slot of block (i, j); (i, j) and (j, i) name the same stored block. Throws
  // std::out_of_range for a pair not in the pattern.
  Slot slot(int i, int j) const;
  // H(i, j) += M (and H(j, i) += M^T: the system stays symmetric). For a diagonal block only the
  // symmetric part of M counts.
  void add(Slot s, const Eigen::Ref<const Eigen::MatrixXd>& M);
  void addDiagonal(int i, const Eigen::Ref<const Eigen::MatrixXd>& M) { add(slot(i, i), M); }
  Eigen::VectorXd& rhs() { return b_; }
  const Eigen::VectorXd& rhs() const { return b_; }
  void setZero();

  // The diagonal of H (for Levenberg-Marquardt damping) and H * x (for the model decrease).
  Eigen::VectorXd diagonal() const;
  Eigen::VectorXd multiply(const Eigen::VectorXd& x) const;
  // Factorizes H + diag(damping) (damping may be empty). Throws NumericalError when the matrix is
  // not positive definite (a part of the graph nothing anchors, a degenerate information matrix).
  void factorize(const Eigen::VectorXd& damping = Eigen::VectorXd());
  // Solves with the last factorization, one column per right-hand side. Throws NumericalError
  // when called before factorize() or when the solution is not finite.
  Eigen::MatrixXd backSolve(const Eigen::MatrixXd& B) const;
  // factorize(damping), then backSolve(rhs()).
  Eigen::VectorXd solve(const Eigen::VectorXd& damping = Eigen::VectorXd());

 private:
  struct Impl;
  int num_blocks_, block_size_;
  Eigen::VectorXd b_;
  std::unique_ptr<Impl> impl_;
};

}  // namespace moslam
