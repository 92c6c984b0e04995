#include "moslam/distributed/coarse_correction.h"

#include <algorithm>
#include <string>
#include <tuple>

#include "moslam/common/errors.h"
#include "moslam/geometry/so3.h"

namespace moslam {

Eigen::MatrixXd StageCoarseSpace::Basis(DgsStage stage, const Eigen::VectorXd& x,
                                        const Matrix3* R_hat, const Eigen::Vector3d& lever) {
  if (stage == DgsStage::kRotation) return Eigen::Map<const Eigen::Matrix3d>(x.data());
  Eigen::MatrixXd P = Eigen::MatrixXd::Zero(6, 6);
  P.topLeftCorner<3, 3>() = R_hat->transpose();
  P.bottomLeftCorner<3, 3>() = -SO3::Hat(lever);  // w x d = -d^ w
  P.bottomRightCorner<3, 3>().setIdentity();
  return P;
}

Eigen::MatrixXd StageCoarseSpace::basisOf(DgsStage stage, const Key& key,
                                          const Eigen::VectorXd& x,
                                          const Eigen::Vector3d& frozen,
                                          const std::map<Key, Matrix3>& R_hat) const {
  if (stage == DgsStage::kRotation) {
    return Basis(DgsStage::kRotation, x, nullptr, Eigen::Vector3d::Zero());
  }
  return Basis(DgsStage::kPose, x, &R_hat.at(key), frozen - centre_);
}

void StageCoarseSpace::freeze(const std::vector<Eigen::VectorXd>& x, const NeighbourInbox& inbox) {
  ref_.clear();
  centre_.setZero();
  for (const Eigen::VectorXd& xi : x) {
    ref_.push_back(xi.tail<3>());
    centre_ += xi.tail<3>();
  }
  if (!x.empty()) centre_ /= static_cast<double>(x.size());
  const std::size_t n = graph_.neighbours().size();
  ref_copy_.assign(n, Eigen::Vector3d::Zero());
  for (std::size_t j = 0; j < n; ++j) {
    const Eigen::VectorXd* v = inbox.get(DgsStage::kPose, static_cast<int>(j));
    if (v) ref_copy_[j] = v->tail<3>();
  }
  frozen_ = true;
}

CoarseShare StageCoarseSpace::share(DgsStage stage, const std::vector<Eigen::VectorXd>& x,
                                    const Eigen::MatrixXd& rhs, const LocalSystem& system,
                                    const NeighbourInbox& inbox,
                                    const std::map<Key, Matrix3>& R_hat) {
  const bool rotation = stage == DgsStage::kRotation;
  const int bs = rotation ? 3 : 6, k = rotation ? 3 : 6, ncols = rotation ? 3 : 1;
  const auto& unknowns = graph_.unknowns();
  const Eigen::Index n = static_cast<Eigen::Index>(unknowns.size()) * bs;
  if (!rotation && !frozen_) freeze(x, inbox);
  CoarseShare share;
  share.center = rotation ? Eigen::Vector3d::Zero() : centre_;
  // P (n x k) and x (n x ncols), stacked in the system's order.
  Eigen::MatrixXd P(n, k), X(n, ncols);
  const Eigen::Vector3d none = Eigen::Vector3d::Zero();  // stage 1 has no lever arms
  for (std::size_t i = 0; i < unknowns.size(); ++i) {
    const Eigen::Index row = system.row(unknowns[i]);
    P.middleRows(row, bs) = basisOf(stage, unknowns[i], x[i], rotation ? none : ref_[i], R_hat);
    X.middleRows(row, bs) = Eigen::Map<const Eigen::MatrixXd>(x[i].data(), bs, ncols);
  }
  Eigen::MatrixXd HP(n, k);
  for (int c = 0; c < k; ++c) HP.col(c) = system.multiply(P.col(c));
  share.diagonal = P.transpose() * HP;
  Eigen::MatrixXd residual = rhs;
  for (int c = 0; c < ncols; ++c) residual.col(c) -= system.multiply(X.col(c));
  share.residual = P.transpose() * residual;
  const auto& separators = graph_.separators();
  for (std::size_t s = 0; s < separators.size(); ++s) {
    const Eigen::Index row = system.separatorRow(s);
    if (row < 0) continue;
    const Separator& sep = separators[s];
    if (sep.foreign == graph_.anchor()) continue;  // fixed: not in its owner's coarse space
    const Eigen::VectorXd* foreign = inbox.get(stage, sep.slot);
    if (!foreign) continue;  // stage 2: no increment yet, P_j unknown (and the coupling unused)
    const Eigen::Vector3d& frozen =
        rotation ? none : ref_copy_[static_cast<std::size_t>(sep.slot)];
    const Eigen::MatrixXd block = P.middleRows(row, bs).transpose() * system.coupling(s) *
                                  basisOf(stage, sep.foreign, *foreign, frozen, R_hat);
    auto [it, inserted] = share.coupling.try_emplace(sep.foreign_robot, block);
    if (!inserted) it->second += block;
  }
  return share;
}

void StageCoarseSpace::apply(DgsStage stage, const std::map<int, Eigen::MatrixXd>& y,
                             std::vector<Eigen::VectorXd>& x, NeighbourInbox& inbox,
                             const std::map<Key, Matrix3>& R_hat) const {
  const bool rotation = stage == DgsStage::kRotation;
  const int bs = rotation ? 3 : 6, ncols = rotation ? 3 : 1;
  if (!rotation && !frozen_) {
    throw InvalidInputError("DGS robot " + std::to_string(graph_.robot()) +
                            ": applyCoarse() in stage 2 before coarseShare()");
  }
  auto move = [&](const Key& key, Eigen::VectorXd& value, const Eigen::MatrixXd& yr,
                  const Eigen::Vector3d& frozen) {
    const Eigen::MatrixXd dx = basisOf(stage, key, value, frozen, R_hat) * yr;
    value += Eigen::Map<const Eigen::VectorXd>(dx.data(), bs * ncols);
  };
  const Eigen::Vector3d none = Eigen::Vector3d::Zero();  // stage 1 has no lever arms
  const auto own = y.find(graph_.robot());
  if (own != y.end()) {
    const auto& unknowns = graph_.unknowns();
    for (std::size_t i = 0; i < unknowns.size(); ++i) {
      move(unknowns[i], x[i], own->second, rotation ? none : ref_[i]);
    }
  }
  const auto& neighbours = graph_.neighbours();
  for (std::size_t j = 0; j < neighbours.size(); ++j) {
    const Key& key = neighbours[j];
    const auto it = y.find(key.robot);
    if (it == y.end() || key == graph_.anchor()) continue;  // the anchor never moves
    Eigen::VectorXd* value = inbox.mutableValue(stage, static_cast<int>(j));
    if (!value) continue;
    if (!rotation && R_hat.count(key) == 0) continue;
    move(key, *value, it->second, rotation ? none : ref_copy_[j]);
  }
}

}  // namespace moslam

namespace moslam {
namespace {

// Ad(x^-1) [I 0; c^ I]: a robot's rigid motion about c as the right increment of x.
Matrix6 RefineBasis(const SE3& x, const Eigen::Vector3d& centre) {
  Matrix6 S = Matrix6::Identity();
  S.bottomLeftCorner<3, 3>() = SO3::Hat(centre);
  return x.inverse().Adjoint() * S;
}

}  // namespace

std::uint32_t CoarsePieceOf(const Key& key, std::uint64_t piece_poses) {
  if (key.isObject()) return kObjectCoarsePiece;
  if (piece_poses == 0) return 0;
  return static_cast<std::uint32_t>(
      std::min<std::uint64_t>(key.index / piece_poses, kObjectCoarsePiece - 1));
}

void RefineCoarseSpace::build(const LocalGraph& graph, const Refinement& refinement,
                              std::uint64_t piece_poses) {
  const auto& unknowns = graph.unknowns();
  centre_.setZero();
  for (const Key& k : unknowns) centre_ += refinement.knownPose(k)->translation();
  if (!unknowns.empty()) centre_ /= static_cast<double>(unknowns.size());
  own_.clear();
  for (const Key& k : unknowns) own_.push_back(RefineBasis(*refinement.knownPose(k), centre_));
  const auto& neighbours = graph.neighbours();
  neighbour_.assign(neighbours.size(), Matrix6::Zero());
  neighbour_known_.assign(neighbours.size(), 0);
  for (std::size_t j = 0; j < neighbours.size(); ++j) {
    const SE3* x = refinement.knownPose(neighbours[j]);
    if (!x || neighbours[j] == graph.anchor()) continue;  // the anchor is in no coarse space
    neighbour_[j] = RefineBasis(*x, centre_);
    neighbour_known_[j] = 1;
  }
  piece_poses_ = piece_poses;
  own_piece_.clear();
  neighbour_piece_.clear();
  piece_centre_.clear();
  if (piece_poses == 0) return;
  std::map<std::uint32_t, int> members;
  for (const Key& k : unknowns) {
    const std::uint32_t p = CoarsePieceOf(k, piece_poses);
    own_piece_.push_back(p);
    auto [it, added] = piece_centre_.try_emplace(p, Eigen::Vector3d::Zero());
    it->second += refinement.knownPose(k)->translation();
    ++members[p];
  }
  for (auto& [p, c] : piece_centre_) c /= static_cast<double>(members.at(p));
  for (const Key& k : neighbours) neighbour_piece_.push_back(CoarsePieceOf(k, piece_poses));
}

void RefineCoarseSpace::requirePieces(const char* what) const {
  if (!byPieces()) {
    throw InvalidInputError(std::string("refinement coarse space: ") + what +
                            " without pieces (build() with piece_poses > 0 first)");
  }
}

CoarseMessage RefineCoarseSpace::pieceMatrix(const LocalGraph& graph, const LocalSystem& system,
                                             std::uint32_t iteration) const {
  requirePieces("pieceMatrix()");
  CoarseMessage m = PieceMessage(CoarseKind::kPieceMatrix, graph.robot(), iteration);
  m.center = {centre_.x(), centre_.y(), centre_.z()};
  for (const auto& [p, c] : piece_centre_) m.pieces.push_back({p, {c.x(), c.y(), c.z()}});
  const auto& unknowns = graph.unknowns();
  const Eigen::Index n = static_cast<Eigen::Index>(6 * unknowns.size());
  // (row piece, robot, piece) -> P_p^T H P_q, the own pieces' columns one piece at a time.
  std::map<std::tuple<std::uint32_t, int, std::uint32_t>, Matrix6> blocks;
  auto add = [&](std::uint32_t p, int robot, std::uint32_t q, const Matrix6& b) {
    auto [it, added] = blocks.try_emplace({p, robot, q}, b);
    if (!added) it->second += b;
  };
  for (const auto& [q, centre] : piece_centre_) {
    Eigen::MatrixXd Pq = Eigen::MatrixXd::Zero(n, 6);
    for (std::size_t i = 0; i < unknowns.size(); ++i) {
      if (own_piece_[i] == q) Pq.middleRows<6>(system.row(unknowns[i])) = own_[i];
    }
    Eigen::MatrixXd HPq(n, 6);
    for (int c = 0; c < 6; ++c) HPq.col(c) = system.multiply(Pq.col(c));
    for (std::size_t i = 0; i < unknowns.size(); ++i) {
      const auto rows = HPq.middleRows<6>(system.row(unknowns[i]));
      if (rows.isZero(0.0)) continue;  // no term between the unknown and piece q
      add(own_piece_[i], graph.robot(), q, own_[i].transpose() * rows);
    }
  }
  std::map<Eigen::Index, std::size_t> unknown_at;  // the own unknown of each system row
  for (std::size_t i = 0; i < unknowns.size(); ++i) unknown_at[system.row(unknowns[i])] = i;
  const auto& separators = graph.separators();
  for (std::size_t s = 0; s < separators.size(); ++s) {
    const Eigen::Index row = system.separatorRow(s);
    const std::size_t slot = static_cast<std::size_t>(separators[s].slot);
    if (row < 0 || !neighbour_known_[slot]) continue;
    const std::size_t i = unknown_at.at(row);
    add(own_piece_[i], separators[s].foreign_robot, neighbour_piece_[slot],
        own_[i].transpose() * system.coupling(s) * neighbour_[slot]);
  }
  for (const auto& [where, b] : blocks) {
    const auto& [p, robot, q] = where;
    m.piece_blocks.push_back({p, robot, q, std::vector<double>(b.data(), b.data() + 36)});
  }
  return m;
}

CoarseMessage RefineCoarseSpace::pieceResidual(const LocalGraph& graph, const LocalSystem& system,
                                               const Eigen::VectorXd& r,
                                               std::uint32_t iteration) const {
  requirePieces("pieceResidual()");
  std::map<std::uint32_t, Vector6> sums;
  for (const auto& [p, c] : piece_centre_) sums[p].setZero();
  const auto& unknowns = graph.unknowns();
  for (std::size_t i = 0; i < unknowns.size(); ++i) {
    sums[own_piece_[i]].noalias() += own_[i].transpose() * r.segment<6>(system.row(unknowns[i]));
  }
  CoarseMessage m = PieceMessage(CoarseKind::kPieceResidual, graph.robot(), iteration);
  for (const auto& [p, v] : sums)
    m.pieces.push_back({p, std::vector<double>(v.data(), v.data() + 6)});
  return m;
}

void RefineCoarseSpace::applyPieces(const LocalGraph& graph, DgsStage stage,
                                    const CoarseMessage& solution, std::vector<Eigen::VectorXd>& z,
                                    NeighbourInbox& inbox) const {
  requirePieces("applyPieces()");
  if (solution.kind != CoarseKind::kPieceSolution) {
    throw InvalidInputError("refinement coarse space: applyPieces() takes a piece solution");
  }
  std::map<std::pair<int, std::uint32_t>, Vector6> y;
  for (const CoarsePieceBlock& b : solution.piece_blocks) {
    y[{b.robot, b.piece}] = Eigen::Map<const Vector6>(b.values.data());
  }
  for (std::size_t i = 0; i < z.size() && i < own_.size(); ++i) {
    const auto it = y.find({graph.robot(), own_piece_[i]});
    if (it != y.end()) z[i] += own_[i] * it->second;
  }
  const auto& neighbours = graph.neighbours();
  for (std::size_t j = 0; j < neighbours.size(); ++j) {
    if (!neighbour_known_[j]) continue;
    const auto it = y.find({neighbours[j].robot, neighbour_piece_[j]});
    if (it != y.end()) inbox.add(stage, static_cast<int>(j), neighbour_[j] * it->second);
  }
}

void RefineCoarseSpace::buildPoseStage(const LocalGraph& graph,
                                       const std::map<Key, Matrix3>& R_hat) {
  auto basis = [](const Matrix3& R) {
    Matrix6 P = Matrix6::Identity();
    P.topLeftCorner<3, 3>() = R.transpose();
    return P;
  };
  centre_.setZero();
  piece_poses_ = 0;  // the pose stage moves whole robots
  own_.clear();
  for (const Key& k : graph.unknowns()) own_.push_back(basis(R_hat.at(k)));
  const auto& neighbours = graph.neighbours();
  neighbour_.assign(neighbours.size(), Matrix6::Zero());
  neighbour_known_.assign(neighbours.size(), 0);
  for (std::size_t j = 0; j < neighbours.size(); ++j) {
    const auto R = R_hat.find(neighbours[j]);
    if (R == R_hat.end() || neighbours[j] == graph.anchor()) continue;
    neighbour_[j] = basis(R->second);
    neighbour_known_[j] = 1;
  }
}

CoarseShare RefineCoarseSpace::matrix(const LocalGraph& graph, const LocalSystem& system) const {
  const auto& unknowns = graph.unknowns();
  const Eigen::Index n = static_cast<Eigen::Index>(6 * unknowns.size());
  Eigen::MatrixXd P(n, 6);
  for (std::size_t i = 0; i < unknowns.size(); ++i) {
    P.middleRows<6>(system.row(unknowns[i])) = own_[i];
  }
  Eigen::MatrixXd HP(n, 6);
  for (int c = 0; c < 6; ++c) HP.col(c) = system.multiply(P.col(c));
  CoarseShare share;
  share.diagonal = P.transpose() * HP;
  share.center = centre_;
  const auto& separators = graph.separators();
  for (std::size_t s = 0; s < separators.size(); ++s) {
    const Eigen::Index row = system.separatorRow(s);
    const Separator& sep = separators[s];
    if (row < 0 || !neighbour_known_[static_cast<std::size_t>(sep.slot)]) continue;
    const Eigen::MatrixXd block = P.middleRows<6>(row).transpose() * system.coupling(s) *
                                  neighbour_[static_cast<std::size_t>(sep.slot)];
    auto [it, inserted] = share.coupling.try_emplace(sep.foreign_robot, block);
    if (!inserted) it->second += block;
  }
  return share;
}

Eigen::VectorXd RefineCoarseSpace::project(const LocalGraph& graph, const LocalSystem& system,
                                           const Eigen::VectorXd& r) const {
  Eigen::VectorXd out = Eigen::VectorXd::Zero(6);
  const auto& unknowns = graph.unknowns();
  for (std::size_t i = 0; i < unknowns.size(); ++i) {
    out.noalias() += own_[i].transpose() * r.segment<6>(system.row(unknowns[i]));
  }
  return out;
}

void RefineCoarseSpace::apply(const LocalGraph& graph, DgsStage stage,
                              const std::map<int, Eigen::MatrixXd>& y,
                              std::vector<Eigen::VectorXd>& z, NeighbourInbox& inbox) const {
  const auto own = y.find(graph.robot());
  if (own != y.end()) {
    for (std::size_t i = 0; i < z.size(); ++i) z[i] += own_[i] * own->second.col(0);
  }
  const auto& neighbours = graph.neighbours();
  for (std::size_t j = 0; j < neighbours.size(); ++j) {
    const auto it = y.find(neighbours[j].robot);
    if (it == y.end() || !neighbour_known_[j]) continue;
    inbox.add(stage, static_cast<int>(j), neighbour_[j] * it->second.col(0));
  }
}

}  // namespace moslam
