#include "moslam/distributed/coarse_system.h"

#include "moslam/common/errors.h"
#include "moslam/distributed/coarse_correction.h"
#include "moslam/geometry/so3.h"
#include "moslam/solver/block_sparse_system.h"

namespace moslam {

std::vector<double> FlattenMatrix(const Eigen::MatrixXd& m) {
  return std::vector<double>(m.data(), m.data() + m.size());
}

CoarseMessage ShareMessage(CoarseKind kind, DgsStage stage, int sender, std::uint32_t iteration,
                           const CoarseShare& share) {
  const bool rotation = stage == DgsStage::kRotation;
  CoarseMessage m;
  m.kind = kind;
  m.stage = stage;
  m.sender = sender;
  m.iteration = iteration;
  m.k = rotation ? 3 : 6;
  m.ncols = rotation ? 3 : 1;
  if (!rotation) m.center = FlattenMatrix(share.center);
  m.diagonal = FlattenMatrix(share.diagonal);
  if (kind == CoarseKind::kShare) m.residual = FlattenMatrix(share.residual);
  for (const auto& [s, block] : share.coupling) m.blocks.emplace_back(s, FlattenMatrix(block));
  return m;
}

Eigen::MatrixXd UnflattenMatrix(const std::vector<double>& v, int rows, int cols) {
  return Eigen::Map<const Eigen::MatrixXd>(v.data(), rows, cols);
}

CoarseSystem::CoarseSystem(const std::vector<int>& robots, int k)
    : robots_(robots), k_(k), A_(Eigen::MatrixXd::Zero(static_cast<Eigen::Index>(robots.size()) * k,
                                                      static_cast<Eigen::Index>(robots.size()) * k)) {
  for (std::size_t i = 0; i < robots_.size(); ++i) {
    index_[robots_[i]] = static_cast<Eigen::Index>(i) * k_;
    centre_[robots_[i]] = Eigen::Vector3d::Zero();
  }
}

Eigen::Index CoarseSystem::index(int robot) const {
  const auto it = index_.find(robot);
  return it == index_.end() ? -1 : it->second;
}

Eigen::MatrixXd CoarseSystem::shift(int from, int to) const {
  Eigen::MatrixXd T = Eigen::MatrixXd::Identity(k_, k_);
  if (k_ == 6) T.bottomLeftCorner<3, 3>() = SO3::Hat(centre_.at(from) - centre_.at(to));
  return T;
}

Eigen::MatrixXd CoarseSystem::addShare(const CoarseMessage& m) {
  const Eigen::Index ir = index(m.sender);
  if (ir < 0 || m.k != k_) {
    throw InvalidInputError("coarse system: a share from robot " + std::to_string(m.sender) +
                            " that is not in the system (or of another size)");
  }
  if (m.center.size() == 3) centre_[m.sender] = Eigen::Vector3d(m.center[0], m.center[1], m.center[2]);
  A_.block(ir, ir, k_, k_) += UnflattenMatrix(m.diagonal, k_, k_);
  blocks_[m.sender] = m.blocks;
  cholesky_ = ScaledCholesky();  // a new share: factorize again
  if (m.residual.empty()) return Eigen::MatrixXd();
  return UnflattenMatrix(m.residual, k_, m.ncols);
}

bool CoarseSystem::factorize() {
  // Couplings, now that every centre is known.
  for (const auto& [r, blocks] : blocks_) {
    const Eigen::Index ir = index_.at(r);
    for (const auto& [s, block] : blocks) {
      const Eigen::Index is = index(s);  // a silent neighbour's variables stay fixed
      if (is < 0) continue;
      A_.block(ir, is, k_, k_) += UnflattenMatrix(block, k_, k_) * shift(s, r);
    }
  }
  blocks_.clear();
  return cholesky_.factorize(A_);
}

bool CoarseSystem::solve(const Eigen::MatrixXd& B, Eigen::MatrixXd* Y) const {
  return cholesky_.solve(B, Y);
}

bool ScaledCholesky::factorize(const Eigen::MatrixXd& A) {
  const Eigen::MatrixXd S = 0.5 * (A + A.transpose());
  scale_ = S.diagonal().cwiseMax(0.0).cwiseSqrt().cwiseInverse();
  factorized_ = false;
  if (!scale_.allFinite()) return false;
  llt_.compute(scale_.asDiagonal() * S * scale_.asDiagonal());
  factorized_ = llt_.info() == Eigen::Success;
  return factorized_;
}

bool ScaledCholesky::solve(const Eigen::MatrixXd& B, Eigen::MatrixXd* Y) const {
  if (!factorized_) return false;
  *Y = scale_.asDiagonal() * llt_.solve(scale_.asDiagonal() * B);
  return Y->allFinite();
}

CoarseMessage CoarseSystem::solutionFor(int robot, const std::set<int>& neighbours,
                                        const Eigen::MatrixXd& Y, DgsStage stage, int sender,
                                        std::uint32_t iteration) const {
  CoarseMessage m;
  m.kind = CoarseKind::kSolution;
  m.stage = stage;
  m.sender = sender;
  m.iteration = iteration;
  m.k = k_;
  m.ncols = static_cast<int>(Y.cols());
  std::set<int> needed = neighbours;
  needed.insert(robot);
  for (int s : needed) {  // y_s about c_s, sent about c_r (the receiver's basis)
    const Eigen::Index is = index(s);
    if (is < 0) continue;
    m.blocks.emplace_back(s, FlattenMatrix(shift(s, robot) * Y.middleRows(is, k_)));
  }
  return m;
}

namespace {

Eigen::Vector3d Vec3(const std::vector<double>& v) { return Eigen::Vector3d(v[0], v[1], v[2]); }

}  // namespace

PieceCoarseSystem::PieceCoarseSystem() = default;
PieceCoarseSystem::~PieceCoarseSystem() = default;

void PieceCoarseSystem::addMatrix(const CoarseMessage& m) {
  if (m.kind != CoarseKind::kPieceMatrix) {
    throw InvalidInputError("piece coarse system: a message of robot " + std::to_string(m.sender) +
                            " that is not a piece matrix");
  }
  (void)EncodeCoarseMessage(m);  // the layout's rules (sizes, order, row pieces, finite values)
  if (reference_.count(m.sender)) {
    throw InvalidInputError("piece coarse system: a second matrix of robot " +
                            std::to_string(m.sender));
  }
  if (centre_.size() + m.pieces.size() > kMaxPieces) {
    throw InvalidInputError("piece coarse system: the team's pieces exceed " +
                            std::to_string(kMaxPieces) + " with robot " + std::to_string(m.sender) +
                            "'s: choose longer pieces (--refine-coarse-piece-poses)");
  }
  reference_.emplace(m.sender, Vec3(m.center));
  for (const CoarsePiece& p : m.pieces) centre_[{m.sender, p.id}] = Vec3(p.values);
  matrices_.push_back(m);
  scaled_.reset();  // a new matrix: factorize again
}

Eigen::Matrix<double, 6, 6> PieceCoarseSystem::toPiece(const Piece& u, int reference_robot) const {
  Eigen::Matrix<double, 6, 6> T = Eigen::Matrix<double, 6, 6>::Identity();
  T.bottomLeftCorner<3, 3>() = SO3::Hat(centre_.at(u) - reference_.at(reference_robot));
  return T;
}

std::map<std::pair<int, int>, PieceCoarseSystem::Block> PieceCoarseSystem::symmetricBlocks() const {
  std::map<std::pair<int, int>, Block> S;
  auto add = [&S](int i, int j, const Block& M) {
    S.try_emplace({i, j}, Block::Zero()).first->second += M;
  };
  for (const CoarseMessage& m : matrices_) {
    for (const CoarsePieceBlock& b : m.piece_blocks) {
      const Piece u{m.sender, b.row_piece}, v{b.robot, b.piece};
      const auto iv = index_.find(v);
      if (iv == index_.end()) continue;  // a silent robot's variables stay fixed
      const int i = index_.at(u), j = iv->second;
      const Block M = toPiece(u, m.sender).transpose() * Eigen::Map<const Block>(b.values.data()) *
                      toPiece(v, m.sender);
      if (i == j) {
        add(i, i, 0.5 * (M + M.transpose()));
      } else if (i < j) {
        add(i, j, 0.5 * M);
      } else {
        add(j, i, 0.5 * M.transpose());
      }
    }
  }
  return S;
}

bool PieceCoarseSystem::factorize() {
  index_.clear();
  scaled_.reset();
  for (const auto& [u, c] : centre_) {
    const int next = static_cast<int>(index_.size());
    index_[u] = next;
  }
  if (index_.empty()) return false;
  const std::map<std::pair<int, int>, Block> S = symmetricBlocks();
  scale_ = Eigen::VectorXd::Zero(rows());  // a piece without a diagonal block: not definite
  std::vector<std::pair<int, int>> pairs;
  for (const auto& [ij, M] : S) {
    if (ij.first == ij.second) {
      scale_.segment<6>(6 * ij.first) = M.diagonal().cwiseMax(0.0).cwiseSqrt().cwiseInverse();
    } else {
      pairs.push_back(ij);
    }
  }
  if (!scale_.allFinite()) return false;
  auto scaled = std::make_unique<BlockSparseSystem>(static_cast<int>(index_.size()), 6, pairs);
  for (const auto& [ij, M] : S) {
    const auto [i, j] = ij;
    scaled->add(scaled->slot(i, j),
                scale_.segment<6>(6 * i).asDiagonal() * M * scale_.segment<6>(6 * j).asDiagonal());
  }
  try {
    scaled->factorize();
  } catch (const NumericalError&) {
    return false;  // not positive definite: no correction
  }
  scaled_ = std::move(scaled);
  return true;
}

bool PieceCoarseSystem::solve(const std::vector<CoarseMessage>& residuals,
                              Eigen::VectorXd* Y) const {
  if (!scaled_) return false;
  Eigen::VectorXd B = Eigen::VectorXd::Zero(rows());
  for (const CoarseMessage& m : residuals) {
    if (m.kind != CoarseKind::kPieceResidual || !has(m.sender)) {
      throw InvalidInputError("piece coarse system: a residual of robot " +
                              std::to_string(m.sender) + " outside the system (or not a residual)");
    }
    for (const CoarsePiece& p : m.pieces) {
      const auto it = index_.find({m.sender, p.id});
      if (it == index_.end()) continue;  // a piece the robot's matrix did not declare
      B.segment<6>(6 * it->second) +=
          toPiece({m.sender, p.id}, m.sender).transpose() *
          Eigen::Map<const Eigen::Matrix<double, 6, 1>>(p.values.data());
    }
  }
  if (!B.allFinite()) return false;
  const Eigen::VectorXd scaled_b = scale_.cwiseProduct(B);
  Eigen::VectorXd y;
  try {
    y = scaled_->backSolve(scaled_b);
  } catch (const NumericalError&) {
    return false;  // not finite
  }
  *Y = scale_.cwiseProduct(y);
  return Y->allFinite();
}

CoarseMessage PieceCoarseSystem::solutionFor(int robot, const std::set<int>& neighbours,
                                             const Eigen::VectorXd& Y, int sender,
                                             std::uint32_t iteration) const {
  CoarseMessage m = PieceMessage(CoarseKind::kPieceSolution, sender, iteration);
  if (!has(robot)) return m;
  std::set<int> needed = neighbours;
  needed.insert(robot);
  for (const auto& [u, i] : index_) {  // (robot, piece) order
    if (!needed.count(u.first)) continue;
    const Eigen::Matrix<double, 6, 1> y = toPiece(u, robot) * Y.segment<6>(6 * i);
    m.piece_blocks.push_back({0, u.first, u.second, std::vector<double>(y.data(), y.data() + 6)});
  }
  return m;
}

}  // namespace moslam
