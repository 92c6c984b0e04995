#include "moslam/solver/marginals.h"

#include <unordered_map>

#include "moslam/common/errors.h"
#include "moslam/solver/block_sparse_system.h"

namespace moslam {

struct Marginals::Impl {
  std::unordered_map<Key, int> block;  // -1: the anchor
  std::unique_ptr<BlockSparseSystem> system;
};

Marginals::Marginals(const PoseGraph& graph, const Values& values)
    : impl_(std::make_unique<Impl>()) {
  const Key anchor = GaugeAnchor(graph);
  RequireAnchored(graph, anchor);
  int n = 0;
  for (const Key& k : graph.keys()) {
    if (values.find(k) == values.end()) {
      throw InvalidInputError("Marginals: no estimate for variable " + ToString(k));
    }
    impl_->block[k] = k == anchor ? -1 : n++;
  }
  std::vector<std::pair<int, int>> pairs;
  for (const RelativePoseFactor& f : graph.factors()) {
    const int a = impl_->block.at(f.a()), b = impl_->block.at(f.b());
    if (a >= 0 && b >= 0 && a != b) pairs.emplace_back(a, b);
  }
  impl_->system = std::make_unique<BlockSparseSystem>(n, 6, pairs);
  BlockSparseSystem& H = *impl_->system;
  H.setZero();
  Matrix6 Ja, Jb;
  for (const RelativePoseFactor& f : graph.factors()) {
    f.residual(values.at(f.a()), values.at(f.b()), &Ja, &Jb);
    const Matrix6 Wa = f.sqrtInformation() * Ja, Wb = f.sqrtInformation() * Jb;
    const int a = impl_->block.at(f.a()), b = impl_->block.at(f.b());
    if (a >= 0) H.addDiagonal(a, Wa.transpose() * Wa);
    if (b >= 0) H.addDiagonal(b, Wb.transpose() * Wb);
    if (a >= 0 && b >= 0 && a != b) H.add(H.slot(a, b), Wa.transpose() * Wb);
  }
  for (const PriorFactor& p : graph.priors()) {
    const int v = impl_->block.at(p.key());
    if (v < 0) continue;
    Matrix6 J;
    p.residual(values.at(p.key()), &J);
    const Matrix6 W = p.sqrtInformation() * J;
    H.addDiagonal(v, W.transpose() * W);
  }
  H.factorize();
}

Marginals::~Marginals() = default;

Eigen::MatrixXd Marginals::jointCovariance(const std::vector<Key>& keys) const {
  const int k = static_cast<int>(keys.size());
  std::vector<int> blocks;
  for (const Key& key : keys) {
    const auto it = impl_->block.find(key);
    if (it == impl_->block.end()) {
      throw InvalidInputError("Marginals: variable " + ToString(key) + " is not in the graph");
    }
    blocks.push_back(it->second);
  }
  const BlockSparseSystem& H = *impl_->system;
  Eigen::MatrixXd E = Eigen::MatrixXd::Zero(H.dim(), 6 * k);
  for (int i = 0; i < k; ++i) {
    if (blocks[i] >= 0) E.block<6, 6>(6 * blocks[i], 6 * i).setIdentity();
  }
  const Eigen::MatrixXd X = H.dim() > 0 ? H.backSolve(E) : E;  // columns of H^-1
  Eigen::MatrixXd S = Eigen::MatrixXd::Zero(6 * k, 6 * k);
  for (int i = 0; i < k; ++i) {
    if (blocks[i] < 0) continue;
    S.middleRows(6 * i, 6) = X.middleRows(6 * blocks[i], 6);
  }
  return (S + S.transpose()) / 2;  // symmetric to rounding
}

Matrix6 Marginals::covariance(const Key& key) const { return jointCovariance({key}); }

}  // namespace moslam
