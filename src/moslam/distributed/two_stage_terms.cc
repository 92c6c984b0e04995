#include "moslam/distributed/two_stage_terms.h"

#include <Eigen/Dense>
#include <memory>
#include <string>

#include "moslam/common/errors.h"
#include "moslam/solver/block_sparse_system.h"

namespace moslam {

namespace {

double RotationWeight(const Matrix6& information, bool weighted) {
  return weighted ? information.topLeftCorner<3, 3>().trace() / 3.0 : 1.0;
}

Eigen::MatrixXd PoseWeight(const Matrix6& information, const Matrix3& R_frame, bool weighted) {
  Eigen::MatrixXd W = Eigen::MatrixXd::Identity(12, 12);
  if (weighted) {
    W.topLeftCorner(9, 9) *= RotationWeight(information, true);
    W.bottomRightCorner(3, 3) =
        R_frame * information.bottomRightCorner<3, 3>() * R_frame.transpose();
  }
  return W;
}

}  // namespace

Eigen::VectorXd RowMajor(const Matrix3& M) {
  Eigen::VectorXd r(9);
  for (int k = 0; k < 3; ++k) r.segment<3>(3 * k) = M.row(k).transpose();
  return r;
}

Matrix3 FromRowMajor(const Eigen::VectorXd& r) {
  Matrix3 M;
  for (int k = 0; k < 3; ++k) M.row(k) = r.segment<3>(3 * k).transpose();
  return M;
}

Matrix3 ProjectToRotation(const Eigen::VectorXd& r) {
  return SO3::FromMatrixNormalized(FromRowMajor(r)).matrix();
}

LinearTerm RotationTerm(const RelativePoseFactor& factor, bool weighted) {
  LinearTerm t;
  t.a = factor.a();
  t.b = factor.b();
  t.A_a = factor.measured().rotation().matrix().transpose();
  t.A_b = -Eigen::MatrixXd::Identity(3, 3);
  t.C = Eigen::MatrixXd::Zero(3, 3);
  t.W = RotationWeight(factor.information(), weighted) * Eigen::MatrixXd::Identity(3, 3);
  return t;
}

LinearTerm RotationPriorTerm(const PriorFactor& prior, bool weighted) {
  LinearTerm t;
  t.a = prior.key();
  t.unary = true;
  t.A_a = Eigen::MatrixXd::Identity(3, 3);
  t.C = -prior.prior().rotation().matrix().transpose();
  t.W = RotationWeight(prior.information(), weighted) * Eigen::MatrixXd::Identity(3, 3);
  return t;
}

LinearTerm PoseTerm(const RelativePoseFactor& factor, const Matrix3& Ra, const Matrix3& Rb,
                    bool weighted) {
  const Matrix3 Rab = factor.measured().rotation().matrix();
  const Vector3 tab = factor.measured().translation();
  LinearTerm t;
  t.a = factor.a();
  t.b = factor.b();
  t.A_a = Eigen::MatrixXd::Zero(12, 6);
  t.A_b = Eigen::MatrixXd::Zero(12, 6);
  t.C = Eigen::MatrixXd::Zero(12, 1);
  const Matrix3 E = Ra * Rab - Rb;
  for (int k = 0; k < 3; ++k) {
    // Row k of R_hat_a [dtheta]x R_ab, as a column: R_ab^T [a_k]x dtheta (a_k: row k of R_hat_a);
    // row k of R_hat_b [dtheta]x: [b_k]x dtheta, entering with a minus sign.
    t.A_a.block<3, 3>(3 * k, 0) = Rab.transpose() * SO3::Hat(Ra.row(k).transpose());
    t.A_b.block<3, 3>(3 * k, 0) = -SO3::Hat(Rb.row(k).transpose());
    t.C.block<3, 1>(3 * k, 0) = E.row(k).transpose();
  }
  // t_b - t_a - R_hat_a Exp(dtheta_a) t_ab ~ t_b - t_a - R_hat_a t_ab + R_hat_a [t_ab]x dtheta_a.
  t.A_a.block<3, 3>(9, 0) = Ra * SO3::Hat(tab);
  t.A_a.block<3, 3>(9, 3) = -Matrix3::Identity();
  t.A_b.block<3, 3>(9, 3) = Matrix3::Identity();
  t.C.block<3, 1>(9, 0) = -Ra * tab;
  t.W = PoseWeight(factor.information(), Ra, weighted);
  return t;
}

LinearTerm PosePriorTerm(const PriorFactor& prior, const Matrix3& R, bool weighted) {
  const Matrix3 Rz = prior.prior().rotation().matrix();
  LinearTerm t;
  t.a = prior.key();
  t.unary = true;
  t.A_a = Eigen::MatrixXd::Zero(12, 6);
  t.C = Eigen::MatrixXd::Zero(12, 1);
  const Matrix3 E = R - Rz;
  for (int k = 0; k < 3; ++k) {
    t.A_a.block<3, 3>(3 * k, 0) = SO3::Hat(R.row(k).transpose());
    t.C.block<3, 1>(3 * k, 0) = E.row(k).transpose();
  }
  t.A_a.block<3, 3>(9, 3) = Matrix3::Identity();
  t.C.block<3, 1>(9, 0) = -prior.prior().translation();
  t.W = PoseWeight(prior.information(), R, weighted);
  return t;
}

// Systems up to this dimension (10 poses of 6 unknowns, 20 rotations of 3) are solved densely
// (Eigen LLT), where CHOLMOD's per-call overhead dominates; above, the sparse factor of a robot's
// mostly chain-like block is far cheaper than a dense one (measured: the refinement of torus3D in
// 64 robots of 78 poses ran 16 s sparse, 44 s with dense systems up to 600 unknowns).
constexpr Eigen::Index kMaxDenseDimension = 60;

struct BlockLeastSquares::Impl {
  std::unique_ptr<BlockSparseSystem> system;  // sparse path
  Eigen::MatrixXd H;                          // dense path (full symmetric matrix)
  Eigen::LLT<Eigen::MatrixXd> llt;
  bool dense = false;
  bool factorized = false;
  Eigen::MatrixXd G;  // right-hand sides, n*bs x ncols
};

BlockLeastSquares::BlockLeastSquares(const std::vector<Key>& unknowns, int block_size,
                                     int num_cols, const std::vector<std::pair<Key, Key>>& coupled)
    : unknowns_(unknowns), bs_(block_size), ncols_(num_cols), impl_(std::make_unique<Impl>()) {
  for (std::size_t i = 0; i < unknowns_.size(); ++i) {
    if (!index_.emplace(unknowns_[i], static_cast<int>(i)).second) {
      throw InvalidInputError("BlockLeastSquares: unknown " + ToString(unknowns_[i]) +
                              " listed twice");
    }
  }
  std::vector<std::pair<int, int>> pairs;
  pairs.reserve(coupled.size());
  for (const auto& [a, b] : coupled) {
    const auto ia = index_.find(a);
    const auto ib = index_.find(b);
    if (ia == index_.end() || ib == index_.end() || ia->second == ib->second) continue;
    pairs.emplace_back(ia->second, ib->second);
  }
  const Eigen::Index dim = static_cast<Eigen::Index>(unknowns_.size()) * bs_;
  impl_->dense = dim <= kMaxDenseDimension;
  if (impl_->dense) {
    impl_->H = Eigen::MatrixXd::Zero(dim, dim);
  } else {
    impl_->system =
        std::make_unique<BlockSparseSystem>(static_cast<int>(unknowns_.size()), bs_, pairs);
  }
  impl_->G = Eigen::MatrixXd::Zero(static_cast<Eigen::Index>(unknowns_.size()) * bs_, ncols_);
}

BlockLeastSquares::~BlockLeastSquares() = default;

void BlockLeastSquares::setZero() {
  if (impl_->dense) {
    impl_->H.setZero();
  } else {
    impl_->system->setZero();
  }
  impl_->G.setZero();
  impl_->factorized = false;
}

void BlockLeastSquares::add(const LinearTerm& term, const Eigen::MatrixXd* x_a,
                            const Eigen::MatrixXd* x_b) {
  struct End {
    int index;  // -1: fixed
    const Eigen::MatrixXd* A;
  };
  std::vector<End> ends;
  Eigen::MatrixXd C = term.C;
  auto take = [&](const Key& key, const Eigen::MatrixXd& A, const Eigen::MatrixXd* x) {
    const auto it = index_.find(key);
    if (it != index_.end()) {
      ends.push_back({it->second, &A});
      return;
    }
    if (x == nullptr) {
      throw InvalidInputError("BlockLeastSquares: no value for the fixed variable " +
                              ToString(key));
    }
    C.noalias() += A * (*x);
  };
  take(term.a, term.A_a, x_a);
  if (!term.unary) take(term.b, term.A_b, x_b);
  Impl& im = *impl_;
  auto addBlock = [&](int u, int v, const Eigen::MatrixXd& M) {
    if (!im.dense) {
      im.system->add(im.system->slot(u, v), M);
      return;
    }
    const Eigen::Index ru = static_cast<Eigen::Index>(u) * bs_;
    const Eigen::Index rv = static_cast<Eigen::Index>(v) * bs_;
    if (u == v) {
      im.H.block(ru, ru, bs_, bs_) += 0.5 * (M + M.transpose());
    } else {
      im.H.block(ru, rv, bs_, bs_) += M;
      im.H.block(rv, ru, bs_, bs_) += M.transpose();
    }
  };
  for (const End& u : ends) {
    const Eigen::MatrixXd AtW = u.A->transpose() * term.W;
    impl_->G.middleRows(static_cast<Eigen::Index>(u.index) * bs_, bs_).noalias() -= AtW * C;
    for (const End& v : ends) {
      // Each ordered pair once: (u, v) with u < v fills the stored block (its transpose is
      // implied); u == v (the diagonal, or both ends of a self-loop) adds the symmetric part.
      if (v.index < u.index) continue;
      addBlock(u.index, v.index, AtW * (*v.A));
    }
  }
}

std::vector<Eigen::MatrixXd> BlockLeastSquares::solve() {
  factorize();
  return backSolve(impl_->G);
}

const Eigen::MatrixXd& BlockLeastSquares::rhs() const { return impl_->G; }

void BlockLeastSquares::factorize() {
  Impl& im = *impl_;
  im.factorized = false;
  if (!im.dense) {
    im.system->factorize();
  } else if (im.H.size() > 0) {
    im.llt.compute(im.H);
    if (im.llt.info() != Eigen::Success) {
      throw NumericalError(
          "linear system not positive definite: some variable is not anchored by any term");
    }
  }
  im.factorized = true;
}

std::vector<Eigen::MatrixXd> BlockLeastSquares::backSolve(const Eigen::MatrixXd& G) const {
  const Impl& im = *impl_;
  if (!im.factorized) throw NumericalError("BlockLeastSquares: backSolve before factorize");
  Eigen::MatrixXd X;
  if (!im.dense) {
    X = im.system->backSolve(G);
  } else if (im.H.size() > 0) {
    if (G.cols() == 1) {
      // A vector solve: the matrix path repacks the whole factor on every call.
      const Eigen::VectorXd g = G.col(0);
      const Eigen::VectorXd x = im.llt.solve(g);
      X = x;
    } else {
      X = im.llt.solve(G);
    }
    if (!X.allFinite()) throw NumericalError("BlockLeastSquares: non-finite solution");
  } else {
    X = G;
  }
  std::vector<Eigen::MatrixXd> out(unknowns_.size());
  for (std::size_t i = 0; i < unknowns_.size(); ++i) {
    out[i] = X.middleRows(static_cast<Eigen::Index>(i) * bs_, bs_);
  }
  return out;
}

Eigen::VectorXd BlockLeastSquares::multiply(const Eigen::VectorXd& x) const {
  const Eigen::Index dim = static_cast<Eigen::Index>(unknowns_.size()) * bs_;
  if (x.size() != dim) {
    throw InvalidInputError("BlockLeastSquares::multiply: vector of size " +
                            std::to_string(x.size()) + ", expected " + std::to_string(dim));
  }
  if (!impl_->dense) return impl_->system->multiply(x);
  if (dim == 0) return x;
  return impl_->H.selfadjointView<Eigen::Lower>() * x;
}

Eigen::Index BlockLeastSquares::row(const Key& key) const {
  const auto it = index_.find(key);
  if (it == index_.end()) {
    throw InvalidInputError("BlockLeastSquares: " + ToString(key) + " is not an unknown");
  }
  return static_cast<Eigen::Index>(it->second) * bs_;
}

}  // namespace moslam
