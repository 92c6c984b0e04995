// The coordinator's side of a coarse correction (the two-level DGS and the refinement's
// preconditioner, dgs_driver.h): the coarse system assembled from the robots' rows
// (CoarseMessage kShare or kMatrix), each robot's unknowns in the basis centred on its own c_r,
// and its solution sent back to each robot in that robot's basis.
//
// Centres (6 unknowns per robot, a rigid motion (w, tau) about c): unknowns about c_s are, about
// c_r, T(c_s - c_r) y with T(d) = [I 0; d^ I] (w x (t - c_s) + tau = w x (t - c_r) + tau +
// (c_s - c_r) x w); robot r's coupling block to s, computed in r's basis, becomes s's basis by
// right-multiplying T(c_s - c_r). k = 3 (stage 1, no centre): the identity.
//
// The matrix is symmetrised (the two robots of a separator computed its blocks from their own
// copies) and factorized by Cholesky after Jacobi scaling (rotations and translations have
// different units).
#pragma once

#include <Eigen/Cholesky>
#include <Eigen/Core>
#include <map>
#include <memory>
#include <set>
#include <utility>
#include <vector>

#include "moslam/distributed/messages.h"

namespace moslam {

struct CoarseShare;       // coarse_correction.h
class BlockSparseSystem;  // solver/block_sparse_system.h

// CoarseSystem's solve: the symmetric part of A, Jacobi-scaled (rotations and translations
// have different units) and factorized by dense Cholesky.
class ScaledCholesky {
 public:
  // False when a diagonal entry is not positive or the matrix is not positive definite.
  bool factorize(const Eigen::MatrixXd& A);
  bool factorized() const { return factorized_; }
  // Y = A^-1 B; false when not factorized or not finite.
  bool solve(const Eigen::MatrixXd& B, Eigen::MatrixXd* Y) const;

 private:
  Eigen::VectorXd scale_;
  Eigen::LLT<Eigen::MatrixXd> llt_;
  bool factorized_ = false;
};

// The message carrying robot `sender`'s coarse rows to the coordinator: kShare (a stage's
// correction, with its residual) or kMatrix (the refinement preconditioner's matrix, without);
// k = 3 and 3 columns in stage 1, k = 6 and 1 column after it, where the centre is sent too.
CoarseMessage ShareMessage(CoarseKind kind, DgsStage stage, int sender, std::uint32_t iteration,
                           const CoarseShare& share);

class CoarseSystem {
 public:
  // The robots whose coarse unknowns form the system (k each), in this order.
  CoarseSystem(const std::vector<int>& robots, int k);

  // Adds robot r's rows from its share (kShare or kMatrix: centre, diagonal, coupling blocks;
  // blocks to robots outside the system are dropped: their variables stay fixed). Returns the
  // share's residual (kShare), k x ncols, or an empty matrix.
  Eigen::MatrixXd addShare(const CoarseMessage& share);
  // Symmetrises and factorizes, once every robot's share was added; false when the matrix is not
  // positive definite (then no correction).
  bool factorize();
  // Y = A^-1 B for B stacked by robot (k rows each); false (and no Y) when not finite.
  bool solve(const Eigen::MatrixXd& B, Eigen::MatrixXd* Y) const;
  // The kSolution for robot r: the rows of Y of r and of each robot of `neighbours` in the
  // system, moved to r's centre.
  CoarseMessage solutionFor(int robot, const std::set<int>& neighbours, const Eigen::MatrixXd& Y,
                            DgsStage stage, int sender, std::uint32_t iteration) const;

  int k() const { return k_; }
  Eigen::Index rows() const { return static_cast<Eigen::Index>(robots_.size()) * k_; }
  // Row of robot r's first unknown; -1 when r is not in the system.
  Eigen::Index index(int robot) const;

 private:
  Eigen::MatrixXd shift(int from, int to) const;  // T(c_from - c_to)

  std::vector<int> robots_;
  int k_;
  std::map<int, Eigen::Index> index_;
  std::map<int, Eigen::Vector3d> centre_;
  std::map<int, std::vector<std::pair<int, std::vector<double>>>> blocks_;
  Eigen::MatrixXd A_;
  ScaledCholesky cholesky_;
};

// The coordinator's side of the refinement's coarse space by pieces (coarse_correction.h,
// RefineCoarseSpace): one rigid motion y_u = (w, tau) per piece u = (robot, piece) about the
// piece's centre c_u. A robot's kPieceMatrix blocks are about its reference c_r; block (u, v)
// becomes T(c_u - c_r)^T B T(c_v - c_r) (T as above), a residual T(c_u - c_r)^T b, and the
// solution sent to robot r is T(c_v - c_r) y_v for its pieces and its neighbours'. Symmetrised,
// Jacobi-scaled and factorized by sparse Cholesky (BlockSparseSystem, 6 x 6 blocks: a piece is
// coupled only to the pieces its factors reach, a few along a chain).
class PieceCoarseSystem {
 public:
  PieceCoarseSystem();
  ~PieceCoarseSystem();

  // Pieces of the whole team at most (as many as one message may carry).
  static constexpr std::size_t kMaxPieces = kMaxCoarsePieces;

  // A robot's kPieceMatrix; its pieces join the system. InvalidInputError on another kind, a
  // message EncodeCoarseMessage refuses, a second matrix of the same robot, or more than
  // kMaxPieces pieces in all.
  void addMatrix(const CoarseMessage& matrix);
  // Once every matrix is added; false when the matrix is not positive definite (no correction).
  // Blocks to pieces no robot declared (a robot outside the system) are dropped.
  bool factorize();
  // Y from the robots' kPieceResidual messages (a robot or piece without one: zero); false when
  // not factorized or not finite. InvalidInputError on a residual of a robot outside the system.
  bool solve(const std::vector<CoarseMessage>& residuals, Eigen::VectorXd* Y) const;
  // The kPieceSolution for `robot`: the pieces of it and of `neighbours`, about its reference.
  CoarseMessage solutionFor(int robot, const std::set<int>& neighbours, const Eigen::VectorXd& Y,
                            int sender, std::uint32_t iteration) const;

  bool has(int robot) const { return reference_.count(robot) > 0; }
  Eigen::Index rows() const { return 6 * static_cast<Eigen::Index>(index_.size()); }

 private:
  using Piece = std::pair<int, std::uint32_t>;  // (robot, piece)
  using Block = Eigen::Matrix<double, 6, 6>;
  Block toPiece(const Piece& u, int reference_robot) const;
  // The symmetric part of the matrix about the pieces' centres: the blocks (i, j), i <= j, by
  // block index.
  std::map<std::pair<int, int>, Block> symmetricBlocks() const;

  std::map<int, Eigen::Vector3d> reference_;  // c_r per robot
  std::map<Piece, Eigen::Vector3d> centre_;   // c_u
  std::map<Piece, int> index_;                // block index, set by factorize()
  std::vector<CoarseMessage> matrices_;
  Eigen::VectorXd scale_;                      // Jacobi scaling of the unknowns
  std::unique_ptr<BlockSparseSystem> scaled_;  // the scaled matrix, factorized
};

// Matrices to and from a message's column-major doubles.
std::vector<double> FlattenMatrix(const Eigen::MatrixXd& m);
Eigen::MatrixXd UnflattenMatrix(const std::vector<double>& v, int rows, int cols);

}  // namespace moslam
