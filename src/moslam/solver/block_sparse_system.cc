#include "moslam/solver/block_sparse_system.h"

#include <Eigen/CholmodSupport>
#include <Eigen/SparseCore>
#include <algorithm>
#include <stdexcept>
#include <string>
#include <unordered_map>

#include "moslam/common/errors.h"

namespace moslam {

// The upper triangle of H is stored in compressed columns. A stored block (i <= j) occupies, in
// each of its block_size columns, a contiguous run of rows; `offsets[s * bs + c]` is where that
// run starts in the value array for column c of slot s (for a diagonal block the run has c + 1
// entries: the upper triangle only).
struct BlockSparseSystem::Impl {
  Eigen::SparseMatrix<double> H;  // upper triangle
  std::vector<int> slot_i, slot_j;
  std::vector<Eigen::Index> offsets;
  std::unordered_map<long long, int> slot_of;
  std::vector<Eigen::Index> diagonal_index;  // value index of H(k, k)
  Eigen::CholmodSupernodalLLT<Eigen::SparseMatrix<double>, Eigen::Upper> llt;
  bool analyzed = false;
  bool factorized = false;

  long long PairKey(int i, int j) const {
    return static_cast<long long>(std::min(i, j)) * (1LL << 31) + std::max(i, j);
  }
};

namespace {

// Upper-triangle block pattern: per column block, its row blocks (row <= column, the diagonal
// included), increasing and distinct.
std::vector<std::vector<int>> UpperBlockPattern(int num_blocks,
                                                const std::vector<std::pair<int, int>>& pairs) {
  std::vector<std::vector<int>> rows_of_col(num_blocks);
  for (int k = 0; k < num_blocks; ++k) rows_of_col[k].push_back(k);
  for (const auto& [i, j] : pairs) {
    if (i < 0 || j < 0 || i >= num_blocks || j >= num_blocks || i == j) {
      throw std::invalid_argument("BlockSparseSystem: bad block pair");
    }
    rows_of_col[std::max(i, j)].push_back(std::min(i, j));
  }
  for (auto& rows : rows_of_col) {
    std::sort(rows.begin(), rows.end());
    rows.erase(std::unique(rows.begin(), rows.end()), rows.end());
  }
  return rows_of_col;
}

// Compressed columns built directly: in scalar column cb * bs + c, the blocks of rows_of_col[cb]
// in increasing order, each a run of bs rows (c + 1 for the diagonal block, whose upper
// triangle only is stored), so block (rb, cb) starts its run in column c at a known offset. The
// start of every scalar column in the value array, and the total last.
std::vector<int> ColumnStarts(const std::vector<std::vector<int>>& rows_of_col, int bs) {
  const int num_blocks = static_cast<int>(rows_of_col.size());
  const int n = num_blocks * bs;
  std::vector<int> col_nnz(static_cast<std::size_t>(n) + 1, 0);
  for (int cb = 0; cb < num_blocks; ++cb) {
    const auto& rows = rows_of_col[cb];
    for (int c = 0; c < bs; ++c) {
      col_nnz[static_cast<std::size_t>(cb * bs + c) + 1] =
          static_cast<int>(rows.size() - 1) * bs + c + 1;
    }
  }
  for (int k = 0; k < n; ++k) col_nnz[k + 1] += col_nnz[k];
  return col_nnz;
}

}  // namespace

BlockSparseSystem::BlockSparseSystem(int num_blocks, int block_size,
                                     const std::vector<std::pair<int, int>>& pairs)
    : num_blocks_(num_blocks), block_size_(block_size), impl_(std::make_unique<Impl>()) {
  if (num_blocks < 0 || block_size <= 0) {
    throw std::invalid_argument("BlockSparseSystem: bad dimensions");
  }
  const int bs = block_size;
  const int n = dim();
  b_ = Eigen::VectorXd::Zero(n);
  Impl& im = *impl_;

  const std::vector<std::vector<int>> rows_of_col = UpperBlockPattern(num_blocks, pairs);
  const std::vector<int> col_nnz = ColumnStarts(rows_of_col, bs);
  im.H.resize(n, n);
  im.H.resizeNonZeros(col_nnz[static_cast<std::size_t>(n)]);
  std::copy(col_nnz.begin(), col_nnz.end(), im.H.outerIndexPtr());
  int* inner = im.H.innerIndexPtr();
  for (int cb = 0; cb < num_blocks; ++cb) {
    for (int c = 0; c < bs; ++c) {
      int* row = inner + col_nnz[static_cast<std::size_t>(cb * bs + c)];
      for (int rb : rows_of_col[cb]) {
        const int rmax = (rb == cb) ? c + 1 : bs;
        for (int r = 0; r < rmax; ++r) *row++ = rb * bs + r;
      }
    }
  }
  std::fill(im.H.valuePtr(), im.H.valuePtr() + im.H.nonZeros(), 0.0);

  // Each block's runs: block number i of column block cb starts at i * bs in every column.
  for (int cb = 0; cb < num_blocks; ++cb) {
    const auto& rows = rows_of_col[cb];
    for (std::size_t i = 0; i < rows.size(); ++i) {
      const int s = static_cast<int>(im.slot_i.size());
      im.slot_i.push_back(rows[i]);
      im.slot_j.push_back(cb);
      im.slot_of[im.PairKey(rows[i], cb)] = s;
      for (int c = 0; c < bs; ++c) {
        im.offsets.push_back(col_nnz[static_cast<std::size_t>(cb * bs + c)] +
                             static_cast<Eigen::Index>(i) * bs);
      }
    }
  }
  auto find = [&](int row, int col) {
    const int* begin = inner + col_nnz[static_cast<std::size_t>(col)];
    const int* end = inner + col_nnz[static_cast<std::size_t>(col) + 1];
    return static_cast<Eigen::Index>(std::lower_bound(begin, end, row) - inner);
  };
  im.diagonal_index.resize(n);
  for (int k = 0; k < n; ++k) im.diagonal_index[k] = find(k, k);

  cholmod_common& cm = im.llt.cholmod();
  cm.print = 0;  // failures are reported through NumericalError, not printed
  cm.error_handler = nullptr;
}

BlockSparseSystem::~BlockSparseSystem() = default;

BlockSparseSystem::Slot BlockSparseSystem::slot(int i, int j) const {
  const auto it = impl_->slot_of.find(impl_->PairKey(i, j));
  if (it == impl_->slot_of.end()) {
    throw std::out_of_range("BlockSparseSystem: block (" + std::to_string(i) + ", " +
                            std::to_string(j) + ") is not in the pattern");
  }
  return Slot{it->second, i > j};
}

void BlockSparseSystem::add(Slot slot, const Eigen::Ref<const Eigen::MatrixXd>& M) {
  Impl& im = *impl_;
  const int s = slot.index;
  const bool transposed = slot.transposed;
  const int bs = block_size_;
  double* values = im.H.valuePtr();
  const Eigen::Index* off = &im.offsets[static_cast<size_t>(s) * bs];
  if (im.slot_i[s] == im.slot_j[s]) {
    // Diagonal block: the stored upper triangle gets the symmetric part of M.
    for (int c = 0; c < bs; ++c) {
      for (int r = 0; r < c; ++r) values[off[c] + r] += 0.5 * (M(r, c) + M(c, r));
      values[off[c] + c] += M(c, c);
    }
    return;
  }
  // Stored block is (row block slot_i < column block slot_j). M was given for (i, j) as asked:
  // when asked as (j, i) (transposed), the stored block receives M^T.
  for (int c = 0; c < bs; ++c) {
    double* col = values + off[c];
    if (!transposed) {
      for (int r = 0; r < bs; ++r) col[r] += M(r, c);
    } else {
      for (int r = 0; r < bs; ++r) col[r] += M(c, r);
    }
  }
}

void BlockSparseSystem::setZero() {
  std::fill(impl_->H.valuePtr(), impl_->H.valuePtr() + impl_->H.nonZeros(), 0.0);
  b_.setZero();
}

Eigen::VectorXd BlockSparseSystem::diagonal() const {
  Eigen::VectorXd d(dim());
  for (int k = 0; k < dim(); ++k) d(k) = impl_->H.valuePtr()[impl_->diagonal_index[k]];
  return d;
}

Eigen::VectorXd BlockSparseSystem::multiply(const Eigen::VectorXd& x) const {
  return impl_->H.selfadjointView<Eigen::Upper>() * x;
}

void BlockSparseSystem::factorize(const Eigen::VectorXd& damping) {
  Impl& im = *impl_;
  im.factorized = false;
  if (dim() == 0) {
    im.factorized = true;
    return;
  }
  double* values = im.H.valuePtr();
  const bool damped = damping.size() > 0;
  if (damped) {
    for (int k = 0; k < dim(); ++k) values[im.diagonal_index[k]] += damping(k);
  }
  if (!im.analyzed) {
    im.llt.analyzePattern(im.H);
    im.analyzed = true;
  }
  im.llt.factorize(im.H);
  if (damped) {
    for (int k = 0; k < dim(); ++k) values[im.diagonal_index[k]] -= damping(k);
  }
  if (im.llt.info() != Eigen::Success) {
    throw NumericalError(
        "sparse Cholesky failed: the normal equations are not positive definite (a part of the "
        "graph that nothing anchors, or a degenerate information matrix?)");
  }
  im.factorized = true;
}

Eigen::MatrixXd BlockSparseSystem::backSolve(const Eigen::MatrixXd& B) const {
  const Impl& im = *impl_;
  if (!im.factorized) throw NumericalError("BlockSparseSystem::backSolve called before factorize()");
  if (dim() == 0) return Eigen::MatrixXd(0, B.cols());
  Eigen::MatrixXd X = im.llt.solve(B);
  if (im.llt.info() != Eigen::Success || !X.allFinite()) {
    throw NumericalError("sparse Cholesky solve produced non-finite values (ill-conditioned "
                         "system: check information matrices and initial estimates)");
  }
  return X;
}

Eigen::VectorXd BlockSparseSystem::solve(const Eigen::VectorXd& damping) {
  factorize(damping);
  return backSolve(b_);
}

}  // namespace moslam
